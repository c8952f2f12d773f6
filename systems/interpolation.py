"""Smooth frames: draw every pose between the last two fixed steps, by the loop's ``alpha``.

A window shows frames at its own rate (75 Hz, 144 Hz, or whatever the GPU
manages), while the physics moves in fixed steps of ``dt``. Drawing the
state of the last step shows each pose for one, two, or no frames: judder.
Instead the window draws the pose ``alpha`` of the way from the state before
the last step to the state after it (``alpha`` from
:attr:`framework.loop.FixedStepLoop.alpha`)::

    p = p0 + alpha (p1 - p0)              position, m (exact for v constant over the step)
    q = slerp(q0, q1, alpha)              orientation: constant rate about one axis, as SpinSystem turns

That is at most one step (1/60 s) behind the simulation; in exchange every
frame shows a pose the body really passes through. Recordings draw no
interpolated poses: one frame per step (or per k steps), the state after it.

:class:`PoseSnapshotSystem` (stage ``"input"``: before anything moves)
copies every Transform's position and orientation at the start of each step;
:class:`Interpolator` is the render system's ``poses`` hook that blends them
with the current ones. Entities that did not exist at the start of the step
are drawn where they are.
"""
from __future__ import annotations

import esper
import numpy as np

from driftframe.components.body import Transform
from driftframe.framework.frame import slerp  # noqa: F401  (the one slerp; systems.interpolation.slerp kept)


class PoseSnapshotSystem(esper.Processor):
    """Reads Transform; writes nothing in the world: keeps every pose as it was at the start of the step.

    Runs after input (a camera switch places the eye there, and nothing
    should blend across that jump) and before control and anything that moves.
    """

    stage = None
    after = ("input",)
    before = ("control",)
    reads = (Transform,)
    writes = ()

    def __init__(self):
        self.entities = np.empty(0, np.int64)
        self.positions = np.empty((0, 3))
        self.orientations = np.empty((0, 4))
        #: world.step_count when the snapshot was taken (the step it precedes); -1 before the first.
        self.step = -1

    def take(self) -> None:
        """Snapshot the current poses (also after a change outside a step, so nothing blends across it)."""
        w = self.world
        q = w.query(Transform)
        q.refresh()
        data = w.table(Transform).data
        rows = q.rows(Transform)
        self.entities = q.entities.copy()                   # ascending ids: searchsorted in blend()
        self.positions = data["position"][rows].copy()
        self.orientations = data["orientation"][rows].copy()
        self.step = w.step_count

    def process(self, dt: float) -> None:
        self.take()


class Interpolator:
    """The render system's ``poses`` hook: blends the snapshot with the current poses by ``alpha``.

    ``alpha`` is set by the window before each frame (0: the pose before the
    last step, 1: the pose after it). The blend of every Transform is worked
    out once per frame, at the first :meth:`blend` (one lerp and one slerp over
    the whole column); each call then only picks its entities' rows.
    """

    def __init__(self, snapshot: PoseSnapshotSystem):
        self.snapshot = snapshot
        self._alpha = 1.0
        self._frame = 0
        self._key = None
        self._ents = np.empty(0, np.int64)
        self._pos = np.empty((0, 3))
        self._quat = np.empty((0, 4))
        self._picks: dict = {}

    @property
    def alpha(self) -> float:
        return self._alpha

    @alpha.setter
    def alpha(self, value: float) -> None:
        self._alpha = float(value)
        self._frame += 1                   # a new frame: blend afresh

    def _blend_all(self) -> None:
        snap = self.snapshot
        w = snap.world
        q = w.query(Transform)
        q.refresh()
        data = w.table(Transform).data
        rows = q.rows(Transform)
        ents = q.entities
        # copies: rows may be a slice, and a slice's view must never be written through
        pos, quat = np.array(data["position"][rows]), np.array(data["orientation"][rows])
        a = self._alpha
        if len(ents) == len(snap.entities) and np.array_equal(ents, snap.entities):
            k, i = slice(None), slice(None)                                 # the usual case: same bodies
        else:                                                               # born or gone since the step began
            j = np.minimum(np.searchsorted(snap.entities, ents), max(len(snap.entities) - 1, 0))
            found = snap.entities[j] == ents if len(snap.entities) else np.zeros(len(ents), bool)
            k = np.flatnonzero(found)
            i = j[k]
        p0 = snap.positions[i]
        pos[k] = p0 + a * (pos[k] - p0)
        quat[k] = slerp(snap.orientations[i], quat[k], a)
        self._ents, self._pos, self._quat = ents.copy(), pos, quat
        self._picks.clear()

    def blend(self, entities: np.ndarray, positions: np.ndarray, orientations: np.ndarray):
        """Poses to draw for ``entities`` (their current poses given, rows aligned): blended copies."""
        snap = self.snapshot
        a = self._alpha
        if a >= 1.0 or snap.step != snap.world.step_count - 1 or not len(snap.entities) or not len(entities):
            return positions, orientations          # no step since the snapshot, or nothing to blend from
        key = (self._frame, snap.world.step_count, snap.step)
        if key != self._key:
            self._blend_all()
            self._key = key
        pick = self._picks.get(id(entities))
        if pick is None or pick[0] is not entities:
            j = np.minimum(np.searchsorted(self._ents, entities), len(self._ents) - 1)
            ok = self._ents[j] == entities
            pick = self._picks[id(entities)] = (entities, j, bool(ok.all()), ok)
        _, j, all_ok, ok = pick
        if all_ok:
            return self._pos[j], self._quat[j]
        pos, quat = positions.copy(), orientations.copy()
        pos[ok], quat[ok] = self._pos[j[ok]], self._quat[j[ok]]
        return pos, quat

    def blend_one(self, entity: int, position: np.ndarray, orientation: np.ndarray):
        """:meth:`blend` for one entity (the camera's eye)."""
        pos, quat = self.blend(np.array([entity], np.int64), position[None], orientation[None])
        return pos[0], quat[0]


def attach_interpolation(world, render) -> Interpolator:
    """Snapshot poses at every step's start and let ``render`` draw blended ones; returns the hook."""
    snap = PoseSnapshotSystem()
    world.add_system(snap)
    hook = Interpolator(snap)
    render.poses = hook
    return hook
