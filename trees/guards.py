"""A guard around a subtree: two arms keep apart while it runs.

Motions of two arms that run in parallel were each planned with the other arm where it stood, so nothing
planned keeps them apart while both move. :class:`KeepApart` wraps such a subtree: every tick, before its
child runs, it measures the distance between the arms (:class:`~besman.sim.proximity.ArmProximity`) and
fails the subtree - stopping its motions, which brake within the limits - if they are closer than
``margin``; otherwise it is what its child is. (A ``SuccessIsRunning`` condition beside the motions would
do the same in code, but needs a parallel policy that tree files do not have.)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status

from besman.core.validation import checked, optional, positive, text
from besman.trees.base import BEHAVIOUR, executor_of
from besman.trees.conditions import apart, proximity_of

if TYPE_CHECKING:
    from besman.sim.proximity import ArmProximity


class KeepApart(py_trees.decorators.Decorator):
    """Runs ``child`` while the executor's ``arm`` and the ``other`` arm stay ``margin`` (m) apart; see the
    module documentation."""

    @checked(
        name=text("a behaviour name"),
        child=BEHAVIOUR,
        other=text("an arm name"),
        margin=positive,
        arm=optional(text("an arm name")),
    )
    def __init__(
        self,
        name: str,
        child: py_trees.behaviour.Behaviour,
        *,
        other: str,
        margin: float = 0.03,
        arm: str | None = None,
    ) -> None:
        super().__init__(name=name, child=child)
        self.other, self.margin, self.arm = other, margin, arm
        self.proximity: ArmProximity | None = None

    def setup(self, **kwargs: Any) -> None:
        executor = executor_of(self.name, kwargs).arm_executor(self.arm)
        self.proximity = proximity_of(self.name, executor, self.other)

    def tick(self):
        # The check comes first: a child is never ticked with the arms too close.
        if apart(self, self.proximity, self.margin) is Status.FAILURE:
            self.stop(Status.FAILURE)
            yield self
            return
        yield from super().tick()

    def update(self) -> Status:
        if self.decorated.status is not Status.RUNNING:
            self.feedback_message = self.decorated.feedback_message
        return self.decorated.status
