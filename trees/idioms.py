"""Subtree idioms for manipulation: grasp, place, and grasp-then-place, composed hierarchically.

Each subtree keeps its blackboard in one skill namespace; its planning leaf writes the primitives that its
:class:`~besman.trees.leaves.ExecutePrimitive` leaves read, wired by the planning leaf's own role keys.

- :func:`grasp` - perceive, plan, then pick and place's grasp steps (``PICK_STEPS`` of
  :mod:`besman.sim.manipulation`: open, reach, descend, close on the object - a grasp is required - and
  lift), check the grasp; retried from fresh perception when it fails.
- :func:`place` - plan, then the place steps (``PLACE_STEPS``: carry and set down while a guard checks
  that the object stays in the hand, release, retreat), check that the object is at the target.
- :func:`return_home` - the learned return to the robot's home configuration.
- :func:`grasp_then_place` - the two, retried: if the object slips out of the hand, the retry finds it not
  grasped and grasps it again where it now lies.

The factories record how they were called (``besman_spec``), so tree files can name them as nodes
(``Grasp``, ``Place``, ``GraspThenPlace``) and trees built in code can be written back as files.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import py_trees

from besman.sim.manipulation import PICK_STEPS, PLACE_STEPS, PickPlacePlan
from besman.skills.errors import InputError
from besman.skills.validation import COUNT, as_given, checked, instance, non_negative, optional, shaped, text
from besman.trees.base import NAMES, RoleBehaviour
from besman.trees.conditions import ObjectAt, ObjectGrasped
from besman.trees.leaves import ExecutePrimitive, Gripper, InstantiateSkillTemplate
from besman.trees.manipulation import (
    DEFAULT_PLAN,
    PerceiveObject,
    PlanGrasp,
    PlanPlace,
    PlanReturn,
)
from besman.trees.templates import check_template

# The subtrees' arguments, checked where each is called (each takes some of them).
SUBTREE_ARGUMENTS = {
    "name": text("a subtree name"),
    "object": text("an object name or a blackboard key"),
    "namespace": text("a namespace"),
    "target": optional(text("a blackboard key")),
    "attempts": COUNT,
    "plan": instance(PickPlacePlan, "a PickPlacePlan"),
    "remap": optional(NAMES),
    "pool": optional(instance(Mapping, "a pool (skills.SkillTemplatePool)")),
    "template": optional(text("a template name")),
    "refine_above": optional(non_negative),
    "arm": optional(text("an arm name")),
    "offset": optional(as_given(shaped(shape=(2,)))),
}


@checked(**SUBTREE_ARGUMENTS)
def grasp(
    name: str = "grasp",
    *,
    object: str = "box",
    namespace: str = "grasp",
    attempts: int = 2,
    plan: PickPlacePlan = DEFAULT_PLAN,
    remap: Mapping[str, str] | None = None,
    pool: Mapping[str, Any] | None = None,
    template: str | None = None,
    refine_above: float | None = None,
    arm: str | None = None,
    offset: tuple[float, float] | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that grasps ``object`` (a name, or a key holding one) with ``arm`` (default: the executor's
    own), ``offset`` from its centre, and lifts it; up to ``attempts`` tries from fresh perception. With a
    ``pool`` and a ``template``, the reach is the template's (see :class:`PlanGrasp`)."""
    remap = _checked(name, remap or {}, PlanGrasp)
    primitives = PlanGrasp.role_keys(namespace, remap)
    steps = py_trees.composites.Sequence(
        f"{name} steps",
        memory=True,
        children=[
            PerceiveObject("perceive", object=object, **_wiring(PerceiveObject, namespace, remap)),
            PlanGrasp(
                "plan grasp",
                object=object,
                offset=offset,
                plan=plan,
                namespace=namespace,
                remap=remap,
                arm=arm,
                **_learned(pool, template, refine_above),
            ),
            *_step_leaves(PICK_STEPS, object, primitives, arm),
            ObjectGrasped("grasped?", object=object, arm=arm),
        ],
    )
    tree = py_trees.decorators.Retry(name, steps, num_failures=attempts)
    tree.besman_spec = {
        "type": "Grasp",
        "name": name,
        "object": object,
        "namespace": namespace,
        "attempts": attempts,
        "remap": remap,
        "arm": arm,
        "offset": offset,
        **_learned_spec(pool, template, refine_above),
    }
    return tree


@checked(**SUBTREE_ARGUMENTS)
def place(
    name: str = "place",
    *,
    object: str = "box",
    namespace: str = "place",
    target: str | None = None,
    plan: PickPlacePlan = DEFAULT_PLAN,
    remap: Mapping[str, str] | None = None,
    pool: Mapping[str, Any] | None = None,
    template: str | None = None,
    refine_above: float | None = None,
    arm: str | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that puts the held ``object`` down at the target (role ``target``, or the key ``target``)
    with ``arm``. With a ``pool`` and a ``template``, the carry is the template's (see
    :class:`PlanPlace`)."""
    own_remap = _checked(name, remap or {}, PlanPlace)
    remap = own_remap | ({"target": target} if target is not None else {})
    primitives = PlanPlace.role_keys(namespace, remap)
    tree = py_trees.composites.Sequence(
        name,
        memory=True,
        children=[
            PlanPlace(
                "plan place",
                object=object,
                plan=plan,
                namespace=namespace,
                remap=remap,
                arm=arm,
                **_learned(pool, template, refine_above),
            ),
            *_step_leaves(PLACE_STEPS, object, primitives, arm),
            ObjectAt("placed?", object=object, **_wiring(ObjectAt, namespace, remap)),
        ],
    )
    tree.besman_spec = {
        "type": "Place",
        "name": name,
        "object": object,
        "namespace": namespace,
        "target": target,
        "remap": own_remap,
        "arm": arm,
        **_learned_spec(pool, template, refine_above),
    }
    return tree


@checked(**SUBTREE_ARGUMENTS)
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
        children=[ObjectGrasped("holding?", object=object), grasp("grasp", object=object, plan=plan)],
    )
    sequence = py_trees.composites.Sequence(
        f"{name} steps",
        memory=True,
        children=[holding, place("place", object=object, target=target, plan=plan)],
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


@checked(**SUBTREE_ARGUMENTS)
def return_home(
    name: str = "return home",
    *,
    pool: Mapping[str, Any],
    template: str,
    namespace: str = "return",
    target: str = "/task/place",
) -> py_trees.behaviour.Behaviour:
    """A subtree that instantiates the ``template`` of ``pool`` for the place ``target`` (its tau), fits the
    primitive between where the arm is and the home configuration, and executes it."""
    check_template(name, pool, template)
    keys = PlanReturn.role_keys(namespace, {})
    tree = py_trees.composites.Sequence(
        name,
        memory=True,
        children=[
            InstantiateSkillTemplate(
                "instantiate return",
                pool=pool,
                template_name=template,
                namespace=namespace,
                remap={"tau": target, "primitive": keys["shape"]},
            ),
            PlanReturn("plan return", namespace=namespace),
            ExecutePrimitive("return", remap={"primitive": keys["return"]}),
        ],
    )
    tree.besman_spec = {
        "type": "ReturnHome",
        "name": name,
        "namespace": namespace,
        "target": target,
        **_learned_spec(pool, template, None),
    }
    return tree


def _learned(pool, template, refine_above) -> dict:
    """A planning leaf's learned-motion arguments (none for the planned motions)."""
    return {} if pool is None else {"pool": pool, "template": template, "refine_above": refine_above}


def _learned_spec(pool, template, refine_above) -> dict:
    """How a subtree's learned motion is written back to a tree file (the pool by its directory)."""
    if pool is None:
        return {}
    spec = {"pool": str(getattr(pool, "directory", pool)), "template": template}
    return spec if refine_above is None else {**spec, "refine_above": refine_above}


def _checked(subtree: str, remap: Mapping[str, str], planner: type[RoleBehaviour]) -> dict[str, str]:
    """A subtree's remap, whose roles are its planning leaf's (the other leaves use a subset of them)."""
    unknown = sorted(set(remap) - set(planner.roles))
    if unknown:
        raise InputError(
            f"{subtree}: remap names unknown role {unknown[0]!r}; roles: {', '.join(planner.roles)}"
        )
    return dict(remap)


def _wiring(leaf: type[RoleBehaviour], namespace: str, remap: Mapping[str, str]) -> dict:
    """The namespace and the part of a subtree's remap that concerns ``leaf``'s roles."""
    return {"namespace": namespace, "remap": {role: key for role, key in remap.items() if role in leaf.roles}}


def _step_leaves(steps, object: str, primitives: Mapping[str, str], arm: str | None) -> list:
    """The leaves that run pick-and-place ``steps`` (:data:`~besman.sim.manipulation.PICK_STEPS`, ...) with
    ``arm``: a gripper action, or the planning leaf's primitive (its blackboard key in ``primitives``, by
    role), guarded while the object must stay in the hand."""
    leaves = []
    for step in steps:
        if step.gripper is not None:
            closing = step.gripper == "close"
            grasp = {"expect_grasp": True, "object": object} if closing else {}
            leaves.append(Gripper(step.name, action="close" if closing else "open", arm=arm, **grasp))
        elif step.holding:
            leaves.append(_while_holding(step.name, object, primitives[step.move], arm))
        else:
            leaves.append(ExecutePrimitive(step.name, remap={"primitive": primitives[step.move]}, arm=arm))
    return leaves


def _while_holding(
    name: str, object: str, primitive_key: str, arm: str | None = None
) -> py_trees.behaviour.Behaviour:
    """Executes the primitive at ``primitive_key`` with ``arm`` while a guard checks that ``object`` stays in
    its hand; a slip fails it."""
    motion = ExecutePrimitive(name, remap={"primitive": primitive_key}, arm=arm)
    guard = py_trees.decorators.SuccessIsRunning(
        "keep holding", ObjectGrasped("holding?", object=object, arm=arm)
    )
    return py_trees.composites.Parallel(
        f"{name} holding {object}",
        policy=py_trees.common.ParallelPolicy.SuccessOnSelected(children=[motion]),
        children=[motion, guard],
    )
