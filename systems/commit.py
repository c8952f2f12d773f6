"""The step's commit: the one write of every body's end-of-step position and velocity."""
from __future__ import annotations

import esper

from driftframe.components.body import Transform, Velocity
from driftframe.framework.step import StepContext


class CommitSystem(esper.Processor):
    """Reads StepContext; writes Transform.position, Velocity.linear.  The predicted and corrected end of
    the step (:mod:`driftframe.framework.step`) into the components, every body at once.

    Added to a world by the systems that need it (movement, gravity, collision: their ``companions``);
    with no step context open (nothing moved this step) it does nothing.
    """

    stage = "commit"
    reads = (StepContext,)
    writes = (Transform, Velocity)

    def process(self, dt: float) -> None:
        ctx = self.world.resources.get(StepContext)
        if ctx is not None and ctx.step >= 0:
            ctx.end(self.world.table(Transform), self.world.table(Velocity))
