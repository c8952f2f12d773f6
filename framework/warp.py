"""Time warp: more fixed steps per presented frame, never a longer step.

Warp ``W`` runs ``W`` times as many fixed steps of ``world.dt`` per frame (in
``play``: per wall-clock step the loop owes; in ``record``: per recorded
frame). The steps themselves are the same steps at every warp, so the state
after a given simulated time — orbits, contacts, events, the state hash — is
the same at 1x and at 100,000x: warp changes only the wall time it takes
(and how much of it each frame shows). What it costs is CPU: a frame at
warp W does W steps' work, so a scene reaches the warp its step cost allows
(on rails, ``benchmarks/orbit_accuracy.py`` gives the cost per body-step).

The warp a frame runs at is the *requested* level (one of :data:`LEVELS`,
changed by the ``warp_up`` / ``warp_down`` actions) capped by a *limit* that
systems set each step (``systems/warp.py`` drops it before a predicted
surface contact or a scheduled burn, so the player sees it happen), with the
reason for the HUD.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from driftframe.framework import validate

if TYPE_CHECKING:
    from driftframe.framework.world import World

#: The warp levels, as in most space games: x1 to x100,000 in factors of ten.
LEVELS = (1, 10, 100, 1_000, 10_000, 100_000)


class TimeWarp:
    """Requested warp, the limit systems put on it, and why. One per world, ``world.resources[TimeWarp]``:
    :func:`of`."""

    #: Who makes it (named when a world has none: :meth:`World.resource`).
    published_by = "made at 1x by driftframe.framework.warp.of(world) (the play loop and record() call it)"

    def __init__(self, factor: int = 1) -> None:
        self.requested = 1
        self.request(factor)
        #: Largest warp allowed now (set each step by the warp governor); None = no limit.
        self.limit: int | None = None
        #: Why the limit is there (for the HUD), or "".
        self.reason = ""

    def request(self, factor: int) -> None:
        """Ask for warp ``factor`` (one of :data:`LEVELS`)."""
        if isinstance(factor, bool) or factor not in LEVELS:
            raise ValueError(f"warp factor must be one of {LEVELS}, got {validate.shown(factor)}")
        self.requested = int(factor)

    def up(self) -> None:
        """The next level up (stays at the top)."""
        i = LEVELS.index(self.requested)
        self.requested = LEVELS[min(i + 1, len(LEVELS) - 1)]

    def down(self) -> None:
        """The next level down (stays at 1x)."""
        i = LEVELS.index(self.requested)
        self.requested = LEVELS[max(i - 1, 0)]

    @property
    def factor(self) -> int:
        """Steps per frame multiplier in force now: the request, capped by the limit."""
        if self.limit is None:
            return self.requested
        return max(1, min(self.requested, self.limit))

    @property
    def dropped(self) -> bool:
        """True while the limit holds the warp below the request."""
        return self.factor < self.requested

    def __repr__(self) -> str:
        return f"TimeWarp(requested={self.requested}, factor={self.factor}, reason={self.reason!r})"


def of(world: World) -> TimeWarp:
    """The world's time warp (made at 1x on first use, kept in ``world.resources[TimeWarp]``)."""
    warp = world.resources.get(TimeWarp)
    if warp is None:
        warp = world.resources[TimeWarp] = TimeWarp()
    return warp


def factor(world: World) -> int:
    """The warp factor in force for ``world`` (1 when nothing asked for warp)."""
    warp = world.resources.get(TimeWarp)
    return 1 if warp is None else warp.factor
