"""Conditions on the simulated world: SUCCESS when true, FAILURE (with the reason) when not.

- :class:`ObjectGrasped` - both finger pads touch the object and it moves with the hand (of ``arm``).
- :class:`ObjectAt` - an object's position is within a tolerance of a target (given, or read from the
  blackboard role ``target``; an (x, y) target ignores the height).
- :class:`ArmsApart` - two arms of the robot keep a distance from each other (a guard for parallel motions).
- :class:`AtPose` - the executor's joints are within a tolerance of a configuration (given, or role
  ``configuration``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from py_trees.common import Access, Status

from besman.core.errors import InputError
from besman.sim.objects import yaw_error, yaw_of
from besman.sim.outcomes import PLACE_TOLERANCE, TILT_LIMIT, YAW_TOLERANCE
from besman.sim.plans import Target
from besman.trees.base import SimulationBehaviour

if TYPE_CHECKING:
    from besman.sim.proximity import ArmProximity


class ObjectGrasped(SimulationBehaviour):
    """Is ``object`` held by the executor's gripper?"""

    parameters: ClassVar = {"object": "str", "arm": "str"}

    def __init__(self, name: str, *, object: str, arm: str | None = None) -> None:
        super().__init__(name, arm=arm)
        self.use_object(object)

    def update(self) -> Status:
        hand, item = self.executor.hand, self.object
        if hand.holds(item):
            self.feedback_message = f"holding {item}"
            return Status.SUCCESS
        self.feedback_message = f"not holding {item}: {hand.not_held(item)}"
        return Status.FAILURE


class ObjectAt(SimulationBehaviour):
    """Is ``object`` within ``tolerance`` (m) of ``position`` or of the blackboard's ``target``, standing
    (tilted less than :data:`~besman.sim.outcomes.TILT_LIMIT`), and turned to its yaw within
    :data:`~besman.sim.outcomes.YAW_TOLERANCE` if it has one? Either is a target as
    :meth:`~besman.sim.plans.Target.read` takes it: x, y, the yaw (deg), the height z of the top the
    object is set down on (its bottom is judged there)."""

    roles: ClassVar = {"target": Access.READ}
    parameters: ClassVar = {"object": "str", "position": "floats[2|3|4]", "tolerance": "float>0"}

    def __init__(
        self,
        name: str,
        *,
        object: str,
        position: Sequence[float] | None = None,
        tolerance: float = PLACE_TOLERANCE,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.tolerance = tolerance
        self.use_object(object)
        self.position = None if position is None else np.asarray(position, dtype=float)
        if self.position is None:
            self.use("target")

    def update(self) -> Status:
        target = (
            self.position if self.position is not None else np.asarray(self.blackboard.get("target"), float)
        )
        item, world = self.object, self.executor.world
        wanted, pose = Target.read(target), world.object_pose(item)
        offset = pose.position[:2] - wanted.xy
        if wanted.top is not None:
            bottom = pose.position[2] - world.objects[item].half_height
            offset = np.r_[offset, bottom - wanted.top]
        distance = float(np.linalg.norm(offset))
        turned = 0.0
        if wanted.yaw is not None:
            turned = yaw_error(yaw_of(pose.rotation), wanted.yaw, world.objects[item])
        tilt = float(np.degrees(np.arccos(min(1.0, abs(pose.rotation[2, 2])))))
        self.feedback_message = (
            f"{item} is {distance * 100:.1f} cm from {np.round(target, 3).tolist()}"
            + ("" if wanted.yaw is None else f", turned {np.degrees(turned):.1f} deg from its yaw")
            + ("" if tilt < TILT_LIMIT else f", tilted {tilt:.0f} deg (fallen over)")
        )
        aligned = np.degrees(turned) <= YAW_TOLERANCE
        standing = tilt < TILT_LIMIT
        return Status.SUCCESS if distance <= self.tolerance and aligned and standing else Status.FAILURE


class AtPose(SimulationBehaviour):
    """Are the executor's joints within ``tolerance`` (rad or m) of ``configuration`` (or its role)?"""

    roles: ClassVar = {"configuration": Access.READ}
    parameters: ClassVar = {"configuration": "floats", "tolerance": "float>0"}

    def __init__(
        self,
        name: str,
        *,
        configuration: Sequence[float] | None = None,
        tolerance: float = 0.01,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.tolerance = tolerance
        self.configuration = None if configuration is None else np.asarray(configuration, dtype=float)
        if self.configuration is None:
            self.use("configuration")

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        dofs = self.executor.arm.dofs  # a given configuration is checked before the run starts
        if self.configuration is not None and self.configuration.shape != (dofs,):
            given = len(self.configuration)
            raise InputError(f"{self.name}: configuration needs {dofs} values (one per joint), got {given}")

    def update(self) -> Status:
        goal = (
            self.configuration
            if self.configuration is not None
            else np.asarray(self.blackboard.get("configuration"), dtype=float)
        )
        arm = self.executor.arm
        if goal.shape != (arm.dofs,):
            self.feedback_message = f"configuration needs {arm.dofs} values, got {goal.shape}"
            return Status.FAILURE
        error = np.abs(self.executor.measured_position() - goal)
        joint = arm.joints[int(error.argmax())]
        self.feedback_message = f"largest joint error {error.max():.3g} ({joint})"
        return Status.SUCCESS if error.max() <= self.tolerance else Status.FAILURE


class ArmsApart(SimulationBehaviour):
    """Are the executor's ``arm`` and the ``other`` arm at least ``margin`` (m) apart
    (:class:`~besman.sim.proximity.ArmProximity`: every pair of their collision geoms)?"""

    parameters: ClassVar = {"other": "str", "margin": "float>0", "arm": "str"}

    def __init__(self, name: str, *, other: str, margin: float = 0.02, arm: str | None = None) -> None:
        super().__init__(name, arm=arm)
        self.other, self.margin = other, margin
        self.proximity: ArmProximity | None = None

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        self.proximity = proximity_of(self.name, self.executor, self.other)

    def update(self) -> Status:
        return apart(self, self.proximity, self.margin)


def proximity_of(name: str, executor, other: str) -> ArmProximity:
    """The proximity of ``executor``'s arm to the ``other`` arm; an error names a missing or same arm."""
    from besman.sim.proximity import ArmProximity  # with the executor: MuJoCo is loaded by then

    if other == executor.name:
        raise InputError(f"{name}: other must name another arm than {executor.name!r}")
    try:
        return ArmProximity(executor, executor.arm_executor(other))
    except KeyError as error:
        raise InputError(f"{name}: {error.args[0]}") from None


def apart(node, proximity: ArmProximity, margin: float) -> Status:
    """SUCCESS if the arms are at least ``margin`` apart, else FAILURE; says which in ``node``'s feedback."""
    distance = proximity.distance(margin)
    if distance < margin:
        node.feedback_message = f"the arms are {distance * 100:.1f} cm apart (less than {margin * 100:g} cm)"
        return Status.FAILURE
    node.feedback_message = f"the arms are at least {margin * 100:g} cm apart"
    return Status.SUCCESS
