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
from typing import ClassVar

import mujoco
import numpy as np
from py_trees.common import Access, Status

from besman.skills.errors import InputError
from besman.trees.base import SimulationBehaviour


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
        touching = hand.touching(item)
        self.feedback_message = f"not holding {item} (finger pads touching: {touching[0]}, {touching[1]})"
        return Status.FAILURE


class ObjectAt(SimulationBehaviour):
    """Is ``object`` within ``tolerance`` (m) of ``position`` or of the blackboard's ``target``?"""

    roles: ClassVar = {"target": Access.READ}
    parameters: ClassVar = {"object": "str", "position": "floats[2|3]", "tolerance": "float>0"}

    def __init__(
        self,
        name: str,
        *,
        object: str,
        position: Sequence[float] | None = None,
        tolerance: float = 0.02,
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
        item = self.object
        where = self.executor.world.object_pose(item).position[: len(target)]
        distance = float(np.linalg.norm(where - target))
        self.feedback_message = f"{item} is {distance * 100:.1f} cm from {np.round(target, 3).tolist()}"
        return Status.SUCCESS if distance <= self.tolerance else Status.FAILURE


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
    """Are the executor's ``arm`` and ``other`` arm (their links, hands and fingers) at least ``margin`` (m)
    apart? A guard beside motions that run in parallel: it fails before two moving arms touch.

    The distance is MuJoCo's between every pair of collision geoms of the two arms (``mj_geomDistance``,
    searched only up to ``margin``), so it sees a near miss that no contact would show yet.
    """

    parameters: ClassVar = {"other": "str", "margin": "float>0", "arm": "str"}

    def __init__(self, name: str, *, other: str, margin: float = 0.02, arm: str | None = None) -> None:
        super().__init__(name, arm=arm)
        self.other, self.margin = other, margin
        self._pairs: list[tuple[int, int]] = []

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        other = self.executor.arm_executor(self.other) if self.other != self.executor.name else None
        if other is None:
            raise InputError(f"{self.name}: other must name another arm than {self.executor.name!r}")
        mine, theirs = _arm_geoms(self.executor), _arm_geoms(other)
        self._pairs = [(a, b) for a in mine for b in theirs]
        self._line = np.zeros(6)

    def update(self) -> Status:
        world = self.executor.world
        closest = self.margin
        for a, b in self._pairs:
            closest = min(
                closest, mujoco.mj_geomDistance(world.model, world.data, a, b, self.margin, self._line)
            )
        if closest < self.margin:
            self.feedback_message = (
                f"the arms are {closest * 100:.1f} cm apart (less than {self.margin * 100:g} cm)"
            )
            return Status.FAILURE
        self.feedback_message = f"the arms are at least {self.margin * 100:g} cm apart"
        return Status.SUCCESS


def _arm_geoms(executor) -> list[int]:
    """The collision geoms of the bodies an executor's joints move (its links from the first joint of its
    last group on, hand and fingers)."""
    model, arm = executor.world.model, executor.arm
    first = model.jnt_bodyid[model.joint(executor.world.robot.group(arm.groups[-1]).joints[0]).id]
    bodies = [body for body in range(model.nbody) if _descends(model, body, first)]
    return [
        geom
        for geom in range(model.ngeom)
        if model.geom_bodyid[geom] in bodies and (model.geom_contype[geom] or model.geom_conaffinity[geom])
    ]


def _descends(model, body: int, ancestor: int) -> bool:
    while body > 0:
        if body == ancestor:
            return True
        body = model.body_parentid[body]
    return False
