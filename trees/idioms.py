"""Subtree idioms for manipulation: grasp, place, and grasp-then-place, composed hierarchically.

Each subtree keeps its blackboard in one skill namespace; its planning leaf writes the primitives that its
:class:`~besman.trees.leaves.ExecutePrimitive` leaves read, wired by the planning leaf's own role keys.

- :func:`grasp` - rise clear of the table if the hand is down by it (after a failed try), open, perceive,
  plan, then the rest of pick and place's grasp steps (``PICK_STEPS`` of :mod:`besman.sim.plans`:
  reach, descend - guarded: touching the object on the way fails it - close on the object - a grasp is
  required - and lift), check the grasp; retried from fresh perception when it fails.
- :func:`place` - plan, then the place steps (``PLACE_STEPS``: carry and set down while a guard checks
  that the object stays in the hand, release, retreat), check that the object is at the target.
- :func:`return_home` - the learned return to the robot's home configuration.
- :func:`grasp_then_place` - the two, retried: if the object slips out of the hand, the retry finds it not
  grasped and grasps it again where it now lies.

Each factory declares the tree-file node it is (``Grasp``, ``Place``, ``ReturnHome``, ``GraspThenPlace``)
with its parameters, which :mod:`besman.trees.nodes` reads (its keywords take them in that order, then
``plan``, which only code gives); the subtrees it builds record how they were called (``besman_spec``), so
trees built in code can be written back as files.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from typing import Any

import py_trees

from besman.core.errors import InputError
from besman.core.validation import (
    COUNT,
    as_given,
    checked,
    instance,
    non_negative,
    number,
    optional,
    shaped,
    text,
)
from besman.sim.plans import GRASP_SUBGOALS, PICK_STEPS, PLACE_STEPS, PLACE_SUBGOALS, PickPlacePlan
from besman.trees.base import NAMES, RoleBehaviour, SimulationBehaviour
from besman.trees.conditions import ObjectAt, ObjectGrasped
from besman.trees.leaves import ExecutePrimitive, Gripper
from besman.trees.manipulation import (
    DEFAULT_PLAN,
    LEARNED,
    TEMPLATE_PARAMETERS,
    PerceiveObject,
    PlanGrasp,
    PlanPlace,
    PlanReturn,
    RiseClear,
)
from besman.trees.templates import check_template

# The subtrees' arguments, checked where each is called (each takes some of them).
SUBTREE_ARGUMENTS = {
    "name": text("a subtree name"),
    "object": text("an object name or a blackboard key"),
    "namespace": text("a namespace"),
    "target": optional(text("a blackboard key")),
    "attempts": COUNT,
    "approach_height": optional(number),
    "grasp_height": optional(number),
    "descend_time": optional(number),
    "clearance": optional(number),
    "release_height": optional(number),
    "remap": optional(NAMES),
    "pool": optional(instance(Mapping, "a pool (skills.SkillTemplatePool)")),
    "template": optional(text("a template name")),
    "refine_above": optional(non_negative),
    "arm": optional(text("an arm name")),
    "offset": optional(as_given(shaped(shape=(2,)))),
}


SUBGOAL_KINDS = {
    "approach_height": "float>0",
    "grasp_height": "float",
    "descend_time": "float>0",
    "clearance": "float>=0",
    "release_height": "float>=0",
}


def _plan(**subgoals: float | None) -> PickPlacePlan:
    """The default plan with the subgoals given (not None) instead of its own."""
    return DEFAULT_PLAN.with_subgoals(**{name: v for name, v in subgoals.items() if v is not None})


def _subgoals(names: tuple[str, ...]) -> dict[str, str]:
    """The tree-file parameters (name -> kind) of the plan's subgoals ``names``."""
    return {name: SUBGOAL_KINDS[name] for name in names}


def _node_type(type_name: str, parameters: Mapping[str, str], planner: type[RoleBehaviour] | None = None):
    """Declares a subtree factory as the tree-file node ``type_name`` with ``parameters`` beyond ``name``
    (parameter -> kind, see :mod:`besman.trees.nodes`), whose blackboard roles (if it takes a remap) are
    those of its planning leaf ``planner``. The subtrees it builds record the call as ``besman_spec``."""

    def declare(factory: Callable[..., py_trees.behaviour.Behaviour]):
        signature = inspect.signature(factory)

        @functools.wraps(factory)
        def build(*args, **kwargs) -> py_trees.behaviour.Behaviour:
            tree = factory(*args, **kwargs)
            call = signature.bind(*args, **kwargs)
            call.apply_defaults()
            tree.besman_spec = {"type": type_name, **_as_written(call.arguments, parameters)}
            return tree

        build.node_type, build.parameters, build.planner = type_name, dict(parameters), planner
        return build

    return declare


def _as_written(arguments: Mapping[str, Any], parameters: Mapping[str, str]) -> dict:
    """A subtree's name and ``parameters`` as a tree file gives them: a pool by its directory, a remap as a
    plain mapping, and the learned motion's arguments only with a pool (without one, the subtree plans its
    motions and does not use them)."""
    if arguments.get("pool") is None:
        parameters = {param: kind for param, kind in parameters.items() if param not in LEARNED}
    written = {"name": arguments["name"]}
    for param, kind in parameters.items():
        value = arguments[param]
        if kind == "pool" and value is not None:
            value = str(getattr(value, "directory", value))
        written[param] = dict(value or {}) if kind == "keys" else value
    return written


@checked(**SUBTREE_ARGUMENTS)
@_node_type(
    "Grasp",
    {
        "object": "str",
        "namespace": "str",
        "attempts": "int>=1",
        "remap": "keys",
        "arm": "str",
        "offset": "floats[2]",
        "target": "str",
        **LEARNED,
        **_subgoals(GRASP_SUBGOALS),
    },
    PlanGrasp,
)
def grasp(
    name: str = "grasp",
    *,
    object: str = "box",
    namespace: str = "grasp",
    attempts: int = 2,
    remap: Mapping[str, str] | None = None,
    arm: str | None = None,
    offset: tuple[float, float] | None = None,
    target: str | None = None,
    pool: Mapping[str, Any] | None = None,
    template: str | None = None,
    refine_above: float | None = None,
    approach_height: float | None = None,
    grasp_height: float | None = None,
    descend_time: float | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that grasps ``object`` (a name, or a key holding one) with ``arm`` (default: the executor's
    own), ``offset`` from its centre, and lifts it; up to ``attempts`` tries from fresh perception. Its
    subgoals (:class:`~besman.sim.plans.PickPlacePlan`'s numbers) set how high above the grasp it
    comes down from, where the fingers close and how long descending and lifting take. With
    ``target`` (the key of the placement the grasp is for), it grasps so that the object can be set down
    there at the target's yaw. With a ``pool`` and a ``template``, the reach is the template's (see
    :class:`PlanGrasp`)."""
    remap = _checked(name, remap or {}, PlanGrasp) | ({"target": target} if target is not None else {})
    plan = _plan(approach_height=approach_height, grasp_height=grasp_height, descend_time=descend_time)
    planning = PlanGrasp(
        "plan grasp",
        object=object,
        offset=offset,
        **_planning(plan, namespace, remap, arm, pool, template, refine_above),
    )
    steps = py_trees.composites.Sequence(
        f"{name} steps",
        memory=True,
        children=[
            RiseClear("rise clear", object=object, arm=arm),
            # Open before planning: after a try that closed on nothing, the grasp's checks must not see the
            # fingers closed where they will come down open.
            *_step_leaves(PICK_STEPS[:1], planning, object),
            PerceiveObject("perceive", object=object, **_wiring(PerceiveObject, namespace, remap)),
            planning,
            *_step_leaves(PICK_STEPS[1:], planning, object),
            ObjectGrasped("grasped?", object=object, arm=arm),
        ],
    )
    return py_trees.decorators.Retry(name, steps, num_failures=attempts)


@checked(**SUBTREE_ARGUMENTS)
@_node_type(
    "Place",
    {
        "object": "str",
        "namespace": "str",
        "target": "str",
        "remap": "keys",
        "arm": "str",
        **LEARNED,
        **_subgoals(PLACE_SUBGOALS),
    },
    PlanPlace,
)
def place(
    name: str = "place",
    *,
    object: str = "box",
    namespace: str = "place",
    target: str | None = None,
    remap: Mapping[str, str] | None = None,
    arm: str | None = None,
    pool: Mapping[str, Any] | None = None,
    template: str | None = None,
    refine_above: float | None = None,
    clearance: float | None = None,
    release_height: float | None = None,
    descend_time: float | None = None,
) -> py_trees.behaviour.Behaviour:
    """A subtree that puts the held ``object`` down at the target (role ``target``, or the key ``target``)
    with ``arm``. Its subgoals set how far above the shelf the carry ends, where the object is let go and
    how long setting down and retreating take. With a ``pool`` and a ``template``, the carry is the
    template's (see :class:`PlanPlace`)."""
    remap = _checked(name, remap or {}, PlanPlace) | ({"target": target} if target is not None else {})
    plan = _plan(clearance=clearance, release_height=release_height, descend_time=descend_time)
    planning = PlanPlace(
        "plan place", object=object, **_planning(plan, namespace, remap, arm, pool, template, refine_above)
    )
    return py_trees.composites.Sequence(
        name,
        memory=True,
        children=[
            planning,
            *_step_leaves(PLACE_STEPS, planning, object),
            ObjectAt("placed?", object=object, **_wiring(ObjectAt, namespace, remap)),
        ],
    )


@checked(**SUBTREE_ARGUMENTS)
@_node_type(
    "GraspThenPlace",
    {
        "object": "str",
        "target": "str",
        "attempts": "int>=1",
        "pool": "pool",
        "grasp_template": "str",
        "place_template": "str",
    },
)
def grasp_then_place(
    name: str = "grasp then place",
    *,
    object: str = "box",
    target: str = "/task/place",
    attempts: int = 3,
    pool: Mapping[str, Any] | None = None,
    grasp_template: str | None = None,
    place_template: str | None = None,
) -> py_trees.behaviour.Behaviour:
    """Grasp ``object`` (unless already held) and place it at the blackboard key ``target``; a failure
    anywhere (a slip, a missed grasp) retries from the top, up to ``attempts`` times. With a ``pool``, the
    grasp's reach is its ``grasp_template`` and the carry its ``place_template`` (each optional: planned
    without one), instantiated for the moves planned (zero-shot: whatever task the pool was learned in)."""
    if pool is None and (grasp_template or place_template):
        raise InputError(f"{name}: grasp_template and place_template need a pool")
    holding = py_trees.composites.Selector(
        "hold the object",
        memory=True,
        children=[
            ObjectGrasped("holding?", object=object),
            grasp("grasp", object=object, target=target, **_learned(pool, grasp_template)),
        ],
    )
    put = place("place", object=object, target=target, **_learned(pool, place_template))
    sequence = py_trees.composites.Sequence(f"{name} steps", memory=True, children=[holding, put])
    return py_trees.decorators.Retry(name, sequence, num_failures=attempts)


@checked(**SUBTREE_ARGUMENTS)
@_node_type("ReturnHome", {**TEMPLATE_PARAMETERS, "namespace": "str"})
def return_home(
    name: str = "return home",
    *,
    pool: Mapping[str, Any],
    template: str,
    namespace: str = "return",
) -> py_trees.behaviour.Behaviour:
    """A subtree that instantiates the ``template`` of ``pool`` for the move from where the arm is to the
    home configuration, fits the primitive between the two, and executes it."""
    check_template(name, pool, template)
    keys = PlanReturn.role_keys(namespace, {})
    return py_trees.composites.Sequence(
        name,
        memory=True,
        children=[
            PlanReturn("plan return", pool=pool, template=template, namespace=namespace),
            ExecutePrimitive("return", remap={"primitive": keys["return"]}),
        ],
    )


def _learned(pool: Mapping[str, Any] | None, template: str | None) -> dict:
    """A subtree's learned-motion arguments: the pool and the template, if a template is named."""
    return {} if template is None else {"pool": pool, "template": template}


def _planning(plan, namespace, remap, arm, pool, template, refine_above) -> dict:
    """The arguments of grasp's and place's planning leaf (the learned motion's only with a pool)."""
    learned = {} if pool is None else {"pool": pool, "template": template, "refine_above": refine_above}
    return {"plan": plan, "namespace": namespace, "remap": remap, "arm": arm, **learned}


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


def _step_leaves(steps, planning: SimulationBehaviour, object: str) -> list:
    """The leaves that run pick-and-place ``steps`` (:data:`~besman.sim.plans.PICK_STEPS`, ...) with
    the arm of the ``planning`` leaf: a gripper action, or a primitive that leaf writes, guarded while the
    object must stay in the hand."""
    arm = planning.arm
    leaves = []
    for step in steps:
        if step.gripper is not None:
            closing = step.gripper == "close"
            grasp = {"expect_grasp": True, "object": object} if closing else {}
            leaves.append(Gripper(step.name, action="close" if closing else "open", arm=arm, **grasp))
        elif step.holding:
            leaves.append(_while_holding(step.name, object, planning.key(step.move), arm))
        else:
            leaves.append(
                ExecutePrimitive(
                    step.name,
                    remap={"primitive": planning.key(step.move)},
                    arm=arm,
                    untouched=object if step.guarded else None,
                )
            )
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
