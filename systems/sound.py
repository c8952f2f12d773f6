"""Sound cues from the frame's events: impacts from contacts, the engine from the player's throttle.

The system only *describes* sounds: it adds cues to the world's
:class:`~framework.audio.Soundtrack` (``world.resources[Soundtrack]``,
added by :func:`attach`). Who hears them takes the samples: the recorder
muxes them into the MP4 as an AAC track, the window plays them
(:mod:`driftframe.window`). Nothing here touches the simulation.
"""
from __future__ import annotations

import esper
import numpy as np

from driftframe.components.autopilot import Autopilot
from driftframe.components.body import Mass, Transform
from driftframe.components.camera import Camera
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.control import FlightInput, Player
from driftframe.components.gravity import GravityWell, SurfaceContact
from driftframe.framework.audio import Soundtrack
from driftframe.framework.warp import TimeWarp


class SoundSystem(esper.Processor):
    """Reads the frame's CollisionEvent and SurfaceContact, Mass, SphereCollider, the player's FlightInput;
    writes cues into its :class:`~framework.audio.Soundtrack`.

    A contact's loudness is the closing speed its impulse took out,
    ``J (1/m_a + 1/m_b)`` m/s (an immovable body's ``1/m`` is 0), its pitch
    from the smaller collider radius; a surface contact's loudness is twice its
    ``normal_speed`` (an elastic bounce reverses it), its size the well's
    radius; both quieter with their distance from the active camera's eye
    (:func:`framework.audio.hearing`). The engine follows ``|throttle|``. The HUD's alerts sound as they appear: a warning when
    the time warp is held below the request or the camera loses its target, a chime when the player's
    autopilot finishes a task (``Autopilot.done``: a burn, an arrival). Runs once per presented frame;
    a frame rendered again without a step between (motion blur's sub-frames)
    adds nothing.
    """

    stage = "render"
    reads = (CollisionEvent, SurfaceContact, Mass, SphereCollider, FlightInput, Player, GravityWell, Autopilot,
             Camera, Transform, TimeWarp)
    writes = (Soundtrack,)

    def __init__(self, soundtrack: Soundtrack):
        self.soundtrack = soundtrack
        self._heard_step = -1
        self._was = {"dropped": False, "lost": False}      # what the last frame's alerts saw
        self._chimed: dict[int, tuple] = {}               # player entity -> the autopilot task last chimed

    def process(self, dt: float) -> None:
        world = self.world
        if world.step_count == self._heard_step:
            return
        self._heard_step = world.step_count
        track = self.soundtrack
        ear = _ear()
        for ev in world.events:
            if isinstance(ev, CollisionEvent):
                inv = sum(_inverse_mass(e) for e in (ev.a, ev.b))
                track.impact(ev.time, ev.impulse * inv, min(_radius(ev.a), _radius(ev.b)),
                             _distance(ear, np.asarray(ev.point, float)))
            elif isinstance(ev, SurfaceContact):
                well = esper.try_component(ev.well, GravityWell) if esper.entity_exists(ev.well) else None
                body = esper.try_component(ev.entity, Transform) if esper.entity_exists(ev.entity) else None
                track.impact(ev.time, 2.0 * abs(ev.normal_speed), 1.0 if well is None else float(well.radius),
                             _distance(ear, None if body is None else body.position))
        level = 0.0
        for _, (_, flight) in esper.get_components(Player, FlightInput):
            level = max(level, abs(float(flight.throttle)))
        track.thrust(level)
        self._alerts(world, track)

    def _alerts(self, world, track: Soundtrack) -> None:
        """The HUD's alerts as they appear: the warp held below the request, the camera's target lost (a
        warning); the player's autopilot arriving or finishing a burn (done)."""
        warp = world.resources.get(TimeWarp)
        now = {"dropped": bool(warp is not None and warp.dropped),
               "lost": any(cam.target_lost for _, cam in esper.get_component(Camera))}
        was = self._was
        if (now["dropped"] and not was["dropped"]) or (now["lost"] and not was["lost"]):
            track.alert(world.time, "warning")
        self._was = now
        for ent, (_, ap) in esper.get_components(Player, Autopilot):
            # once a task: its parameters name it (a flight plan may reuse the component for the next)
            task = (ap.mode, ap.target, ap.point, ap.dv, ap.along, ap.at, ap.standoff)
            if ap.done and self._chimed.get(ent) != task:
                self._chimed[ent] = task
                track.alert(world.time, "done")


def _ear():
    """Where the listener is: the eye of the first active camera (its Transform, once placed), or None."""
    cams = sorted(e for e, c in esper.get_component(Camera) if c.active)
    tf = esper.try_component(cams[0], Transform) if cams else None
    return None if tf is None else tf.position.copy()


def _distance(ear, point) -> float:
    return 0.0 if ear is None or point is None else float(np.linalg.norm(np.asarray(point) - ear))


def _inverse_mass(ent: int) -> float:
    m = esper.try_component(ent, Mass) if esper.entity_exists(ent) else None
    return 1.0 if m is None else m.inverse          # (no Mass: 1 kg, the contact solver's default)


def _radius(ent: int) -> float:
    c = esper.try_component(ent, SphereCollider) if esper.entity_exists(ent) else None
    return 1.0 if c is None else float(c.radius)


def attach(world) -> Soundtrack:
    """Add a :class:`SoundSystem` and its soundtrack (``world.resources[Soundtrack]``, starting at the
    world's time); returns the soundtrack. Attaching twice returns the one there."""
    track = world.resources.get(Soundtrack)
    if track is None:
        track = Soundtrack(world.time)
        world.resources[Soundtrack] = track
        world.add_system(SoundSystem(track))
    return track
