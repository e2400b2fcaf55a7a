"""What a pick-and-place plan is, apart from planning it: its numbers (:class:`PickPlacePlan`, their valid
ranges, the subgoals a grasp and a place hand over at), its steps (:data:`PICK_STEPS`, :data:`PLACE_STEPS`)
and where a placement sets an object down (:class:`Target`). Planning itself (:mod:`besman.sim.manipulation`)
needs MuJoCo; these do not, so tree files build, show and list their nodes without it.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, fields, replace

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array

# The plan's valid ranges (m, s).
PLAN_RANGES = {
    "approach_height": (0.03, 0.3),
    "clearance": (0.0, 0.3),
    "grasp_height": (-0.03, 0.03),
    "release_height": (0.0, 0.05),
    "carry_time": (0.3, np.inf),
    "descend_time": (0.3, np.inf),
}


@dataclass(frozen=True)
class PickPlacePlan:
    """The parameters of the scripted plan; theta is these numbers in this order."""

    approach_height: float = 0.10  # m above the grasp point before descending
    clearance: float = 0.06  # m between the box's bottom and the shelf top at the ends of the carry
    grasp_height: float = 0.01  # m above the box's centre where the fingers close (the tips clear the table)
    release_height: float = 0.003  # m above the shelf where the box is let go
    carry_time: float = 2.0  # s
    descend_time: float = 1.0  # s for each descent, lift and retreat at least (longer where the arm needs)

    @classmethod
    def from_theta(cls, theta) -> PickPlacePlan:
        theta = finite_array("theta", theta)
        if theta.shape != (len(fields(cls)),):
            raise InputError(
                f"theta must have {len(fields(cls))} entries "
                f"({', '.join(f.name for f in fields(cls))}), got shape {theta.shape}"
            )
        plan = cls(*(float(v) for v in theta))
        if not all(low <= getattr(plan, name) <= high for name, (low, high) in PLAN_RANGES.items()):
            raise InputError(f"theta is outside the plan's valid ranges: {plan}")
        return plan

    def theta(self) -> np.ndarray:
        return np.array(astuple(self))

    def with_subgoals(self, **subgoals: float) -> PickPlacePlan:
        """This plan with some numbers changed, checked against the valid ranges."""
        return PickPlacePlan.from_theta(replace(self, **subgoals).theta())


DEFAULT_PLAN = PickPlacePlan()
# The plan's numbers that set where a grasp's and a place's blocks hand over to the next (their subgoals):
# what a tree's Grasp and Place take, and what refining a whole sequence tunes with each block.
GRASP_SUBGOALS = ("approach_height", "grasp_height", "descend_time")
PLACE_SUBGOALS = ("clearance", "release_height", "descend_time")


@dataclass(frozen=True)
class Step:
    """One step of pick and place - the sequence is written once, here, and the simulated task, the building
    blocks that learning refines and the tree idioms all run it.

    Attributes:
        name: the step's name (motions, tree leaves and logs use it).
        move: the planned primitive it follows (a field of :class:`~besman.sim.manipulation.PickMotions` or
            :class:`~besman.sim.manipulation.PlaceMotions`), or
        gripper: what it does with the gripper instead: "open", "close" (a grasp of the object is required)
            or "release".
        holding: the object is in the hand when it starts and must stay there (a slip fails it; trees guard
            it while it runs).
        guarded: the robot must not touch the object while it runs (a touch fails it: the object is not
            where it was perceived, and going on would push it over).
    """

    name: str
    move: str | None = None
    gripper: str | None = None
    holding: bool = False
    guarded: bool = False


# Grasp: open, move above the object, down around it, close on it, lift it (then check that it is held).
PICK_STEPS = (
    Step("open", gripper="open"),
    Step("reach", move="reach"),
    Step("descend", move="descend", guarded=True),
    Step("close", gripper="close"),
    Step("lift", move="lift"),
)
# Place: carry it above the target, set it down, let go, move the hand up and away.
PLACE_STEPS = (
    Step("carry", move="carry", holding=True),
    Step("set down", move="place", holding=True),
    Step("release", gripper="release"),
    Step("retreat", move="retreat"),
)

# The planned moves that run guarded (planned slow enough to stop within legs.STOP_DISTANCE).
GUARDED_MOVES = frozenset(step.move for step in (*PICK_STEPS, *PLACE_STEPS) if step.guarded)


@dataclass(frozen=True)
class Target:
    """Where a placement sets an object down: ``xy`` (m), the ``yaw`` (rad) it should stand at (None: any)
    and the height ``top`` of what it is set on (None: the shelf)."""

    xy: np.ndarray
    yaw: float | None = None
    top: float | None = None

    @classmethod
    def read(cls, numbers) -> Target:
        """A target as trees and tasks write it: (x, y) on the shelf, (x, y, yaw in deg), or (x, y, yaw in
        deg, z) onto a top at height z (another object's: a stack)."""
        numbers = finite_array("target", numbers, ndim=1)
        if len(numbers) not in (2, 3, 4):
            raise InputError(f"a target is x, y[, yaw in deg[, z of a top]], got {numbers.tolist()}")
        yaw = None if len(numbers) < 3 else float(np.radians(numbers[2]))
        return cls(numbers[:2].copy(), yaw, None if len(numbers) < 4 else float(numbers[3]))
