"""Disturbances: what the world does to a run that the robot did not plan for.

A tree that claims to recover from a slip has to be shown one. :class:`TakeFromHand` is the slip a demo
can repeat: while the hand holds the object and the arm's motion ``during`` (the carry, say) has run
``after`` seconds, the object is taken out of the hand and set down upright on the table elsewhere, as a
person taking it would. Nothing tells the robot: its guard sees the object leave the hand, and the tree
must notice and recover (grasp it again where it now lies).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from besman.sim.executor import Executor


@dataclass
class TakeFromHand:
    """Takes ``object`` out of the hand ``after`` seconds into the motion named ``during`` and puts it on
    the table at ``where`` (x, y); once. Call it after every tick with the executor."""

    object: str
    where: tuple[float, float]
    during: str = "carry"
    after: float = 0.5
    done: bool = field(default=False)

    def __call__(self, executor: Executor) -> bool:
        """Whether it acted now."""
        motion = executor.motion
        if self.done or motion is None or motion.name != self.during:
            return False
        if motion.cycles * executor.config.control_period < self.after or not executor.hand.holds(
            self.object
        ):
            return False
        executor.world.place_on(self.object, "table", *self.where)
        self.done = True
        return True
