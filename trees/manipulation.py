"""Grasp-then-place as behaviour trees: perception, planning and execution leaves, and the subtrees.

Leaves:

- :class:`PerceiveObject` writes an object's current position (simulated perception) to ``object_position``.
- :class:`PlanGrasp` reads ``object_position`` and writes the ``approach``, ``descend`` and ``lift``
  primitives planned from the robot's current state (:func:`besman.sim.manipulation.plan_pick`).
- :class:`PlanPlace` reads the ``target`` (x, y) and writes ``transport``, ``place`` and ``retreat``.

Subtrees (building blocks that compose hierarchically), all in one skill namespace:

- :func:`grasp` - perceive, plan, open, approach, descend, close on the object (a grasp is required), lift,
  check the grasp; retried from fresh perception when it fails.
- :func:`place` - plan, transport and set down while a guard checks that the object stays in the hand, open,
  retreat, check that the object is at the target.
- :func:`grasp_then_place` - the two, retried: if the object slips out of the hand, the retry finds it not
  grasped and grasps it again where it now lies.
"""

from __future__ import annotations

from collections.abc import Mapping

import py_trees
from py_trees.common import Access, Status

from besman.sim.manipulation import PickPlacePlan, PlanningError, plan_pick, plan_place
from besman.trees.base import SimulationBehaviour
from besman.trees.conditions import ObjectAt, ObjectGrasped
from besman.trees.leaves import ExecutePrimitive, Gripper

DEFAULT_PLAN = PickPlacePlan()


class PerceiveObject(SimulationBehaviour):
    """Writes the current position of ``object`` to the role ``object_position``."""

    def __init__(
        self, name: str, *, object: str, namespace: str = "", remap: Mapping[str, str] | None = None
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.object = object
        self.use("object_position", Access.WRITE)

    def update(self) -> Status:
        position = self.executor.world.object_pose(self.object).position
        self.write("object_position", position)
        self.feedback_message = f"{self.object} at {position.round(3).tolist()}"
        return Status.SUCCESS


class _Plan(SimulationBehaviour):
    """A planning leaf: computes primitives in one tick and writes them to their roles."""

    outputs: tuple[str, ...] = ()

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
        for role in self.outputs:
            self.use(role, Access.WRITE)

    def update(self) -> Status:
        item = self.executor.world.objects.get(self.object)
        if item is None:
            self.feedback_message = f"no object {self.object!r} in the world"
            return Status.FAILURE
        try:
            motions = self.make(item)
        except PlanningError as error:
            self.feedback_message = str(error)
            return Status.FAILURE
        for role in self.outputs:
            self.write(role, getattr(motions, role))
        self.feedback_message = "planned " + ", ".join(self.outputs)
        return Status.SUCCESS


class PlanGrasp(_Plan):
    """Plans approach, descend and lift for the object at ``object_position``."""

    outputs = ("approach", "descend", "lift")

    def __init__(self, name: str, **kwargs):
        super().__init__(name, **kwargs)
        self.use("object_position", Access.READ)

    def make(self, item):
        return plan_pick(self.executor, item, self.read("object_position")[:2], self.plan)


class PlanPlace(_Plan):
    """Plans transport, place and retreat to the ``target`` (x, y) from the current configuration."""

    outputs = ("transport", "place", "retreat")

    def __init__(self, name: str, **kwargs):
        super().__init__(name, **kwargs)
        self.use("target", Access.READ)

    def make(self, item):
        return plan_place(self.executor, item, self.executor.position, self.read("target"), self.plan)


def grasp(
    name: str = "grasp",
    *,
    object: str = "box",
    namespace: str = "grasp",
    attempts: int = 2,
    plan: PickPlacePlan = DEFAULT_PLAN,
    remap: Mapping[str, str] | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that grasps ``object`` and lifts it; up to ``attempts`` tries from fresh perception."""
    wiring = {"namespace": namespace, "remap": remap}
    steps = py_trees.composites.Sequence(
        f"{name} steps",
        memory=True,
        children=[
            PerceiveObject("perceive", object=object, **wiring),
            PlanGrasp("plan grasp", object=object, plan=plan, **wiring),
            Gripper("open", action="open"),
            ExecutePrimitive("approach", remap={"primitive": _key(namespace, remap, "approach")}),
            ExecutePrimitive("descend", remap={"primitive": _key(namespace, remap, "descend")}),
            Gripper("close", action="close", expect_grasp=True, object=object),
            ExecutePrimitive("lift", remap={"primitive": _key(namespace, remap, "lift")}),
            ObjectGrasped("grasped?", object=object),
        ],
    )
    tree = py_trees.decorators.Retry(name, steps, num_failures=attempts)
    tree.besman_spec = {
        "type": "Grasp",
        "name": name,
        "object": object,
        "namespace": namespace,
        "attempts": attempts,
        "remap": dict(remap or {}),
    }
    return tree


def place(
    name: str = "place",
    *,
    object: str = "box",
    namespace: str = "place",
    target: str | None = None,
    plan: PickPlacePlan = DEFAULT_PLAN,
    remap: Mapping[str, str] | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that puts the held ``object`` down at the target (role ``target``, or the key ``target``)."""
    remap = dict(remap or {})
    if target is not None:
        remap["target"] = target
    wiring = {"namespace": namespace, "remap": remap}
    tree = py_trees.composites.Sequence(
        name,
        memory=True,
        children=[
            PlanPlace("plan place", object=object, plan=plan, **wiring),
            _while_holding("transport", object, namespace, remap),
            _while_holding("set down", object, namespace, remap, role="place"),
            Gripper("release", action="open"),
            ExecutePrimitive("retreat", remap={"primitive": _key(namespace, remap, "retreat")}),
            ObjectAt("placed?", object=object, **wiring),
        ],
    )
    tree.besman_spec = {
        "type": "Place",
        "name": name,
        "object": object,
        "namespace": namespace,
        "target": target,
        "remap": {k: v for k, v in remap.items() if k != "target" or target is None},
    }
    return tree


def grasp_then_place(
    name: str = "grasp then place",
    *,
    object: str = "box",
    target: str = "/task/place",
    attempts: int = 3,
    plan: PickPlacePlan = DEFAULT_PLAN,
) -> py_trees.behaviour.Behaviour:
    """Grasp ``object`` (unless already held) and place it at the blackboard key ``target``; a failure
    anywhere (a slip, a missed grasp) retries from the top, up to ``attempts`` times."""
    holding = py_trees.composites.Selector(
        "hold the object",
        memory=True,
        children=[
            ObjectGrasped("holding?", object=object),
            grasp("grasp", object=object, plan=plan),
        ],
    )
    sequence = py_trees.composites.Sequence(
        f"{name} steps",
        memory=True,
        children=[
            holding,
            place("place", object=object, target=target, plan=plan),
        ],
    )
    tree = py_trees.decorators.Retry(name, sequence, num_failures=attempts)
    tree.besman_spec = {
        "type": "GraspThenPlace",
        "name": name,
        "object": object,
        "target": target,
        "attempts": attempts,
    }
    return tree


def _key(namespace: str, remap: Mapping[str, str] | None, role: str) -> str:
    remap = remap or {}
    return remap.get(role, f"/{namespace.strip('/')}/{role}")


def _while_holding(name: str, object: str, namespace: str, remap, role: str | None = None):
    """Executes a primitive while a guard checks that ``object`` stays in the hand; a slip fails it."""
    motion = ExecutePrimitive(name, remap={"primitive": _key(namespace, remap, role or name)})
    guard = py_trees.decorators.SuccessIsRunning("keep holding", ObjectGrasped("holding?", object=object))
    return py_trees.composites.Parallel(
        f"{name} holding {object}",
        policy=py_trees.common.ParallelPolicy.SuccessOnSelected(children=[motion]),
        children=[motion, guard],
    )
