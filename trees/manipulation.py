"""Perception and planning leaves for pick and place: where the object is, and the primitives to move it.

- :class:`PerceiveObject` writes an object's current position (simulated perception) to ``object_position``.
- :class:`PlanGrasp` reads ``object_position`` and writes the ``approach``, ``descend`` and ``lift``
  primitives planned from the robot's current commanded state (:func:`besman.sim.manipulation.plan_pick`).
- :class:`PlanPlace` reads the ``target`` (x, y) and writes ``transport``, ``place`` and ``retreat``.

The subtrees that use them are in :mod:`besman.trees.idioms`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from py_trees.common import Access, Status

from besman.sim.manipulation import PickPlacePlan, PlanningError, plan_pick, plan_place
from besman.trees.base import SimulationBehaviour

DEFAULT_PLAN = PickPlacePlan()


class PerceiveObject(SimulationBehaviour):
    """Writes the current position of ``object`` to the role ``object_position``."""

    roles: ClassVar = {"object_position": Access.WRITE}
    parameters: ClassVar = {"object": "str"}

    def __init__(
        self, name: str, *, object: str, namespace: str = "", remap: Mapping[str, str] | None = None
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.object = object
        self.use("object_position")

    def update(self) -> Status:
        position = self.executor.world.object_pose(self.object).position
        self.blackboard.set("object_position", position, overwrite=True)
        self.feedback_message = f"{self.object} at {position.round(3).tolist()}"
        return Status.SUCCESS


class _Plan(SimulationBehaviour):
    """A planning leaf: in one tick, plans from the robot's commanded configuration and the (x, y) in its
    ``source`` role with its ``planner``, and writes the primitives to its other roles."""

    source = ""
    planner: ClassVar = None
    parameters: ClassVar = {"object": "str"}

    def __init__(
        self,
        name: str,
        *,
        object: str,
        plan: PickPlacePlan = DEFAULT_PLAN,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.object, self.plan = object, plan
        for role in self.roles:
            self.use(role)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(role for role in self.roles if role != self.source)

    def update(self) -> Status:
        executor = self.executor
        item = executor.world.objects.get(self.object)
        if item is None:
            self.feedback_message = f"no object {self.object!r} in the world"
            return Status.FAILURE
        where = np.asarray(self.blackboard.get(self.source), dtype=float)[:2]
        try:
            motions = type(self).planner(
                executor.arm, executor.position, item, where, self.plan, executor.reference_settings
            )
        except PlanningError as error:
            self.feedback_message = str(error)
            return Status.FAILURE
        for role in self.outputs:
            self.blackboard.set(role, getattr(motions, role), overwrite=True)
        self.feedback_message = "planned " + ", ".join(self.outputs)
        return Status.SUCCESS


class PlanGrasp(_Plan):
    """Plans approach, descend and lift for the object at ``object_position``."""

    source = "object_position"
    planner = plan_pick
    roles: ClassVar = {
        "object_position": Access.READ,
        "approach": Access.WRITE,
        "descend": Access.WRITE,
        "lift": Access.WRITE,
    }


class PlanPlace(_Plan):
    """Plans transport, place and retreat to the ``target`` (x, y) from the current configuration."""

    source = "target"
    planner = plan_place
    roles: ClassVar = {
        "target": Access.READ,
        "transport": Access.WRITE,
        "place": Access.WRITE,
        "retreat": Access.WRITE,
    }
