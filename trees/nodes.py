"""The node types of tree files: how each is built and which parameters it takes, derived from the code.

A leaf class declares its tree-file parameters (:attr:`~besman.trees.base.RoleBehaviour.parameters`) and
blackboard roles once; its defaults are its constructor's. Roles add ``namespace`` and ``remap``. Subtree
idioms are functions that declare their node type and parameters (:mod:`besman.trees.idioms`); py_trees'
composites and decorators get a line each. Parameter kinds: ``str``, ``float``, ``int``, ``bool``,
``floats`` (a list of numbers), ``keys`` (a mapping of roles or keys to keys), ``primitive`` (a primitive's
JSON file), ``template`` and ``pool`` (``MODULE:NAME``, registered or of an allowed module:
:mod:`besman.trees.registry`; or a pool directory). A kind may carry a rule that the loader checks with the
file and line: ``>0`` or ``>=1`` (bounds of a number), ``[2|3]`` (allowed lengths of a list), ``{all|one}``
(allowed values of a string); numbers are always finite.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import py_trees

from besman.trees.base import RoleBehaviour
from besman.trees.conditions import ArmsApart, AtPose, ObjectAt, ObjectGrasped
from besman.trees.guards import KeepApart
from besman.trees.idioms import grasp, grasp_then_place, place, return_home
from besman.trees.leaves import ExecutePrimitive, Gripper, InstantiateSkillTemplate
from besman.trees.loops import ForEach
from besman.trees.manipulation import PerceiveObject, PlanGrasp, PlanMove, PlanPlace, PlanReturn, RiseClear
from besman.trees.throwing import AimThrow, Throw
from besman.trees.timing import SimTimeout, Wait

WIRING = {"namespace": "str", "remap": "keys"}


@dataclass(frozen=True)
class Param:
    """A node parameter: its kind, whether it is required, its default (from the constructor), and the rule
    its value must meet ("" for none; see the module documentation)."""

    kind: str
    required: bool = False
    default: Any = None
    rule: str = ""

    @classmethod
    def of(cls, declared: str, required: bool = False, default: Any = None) -> Param:
        """A parameter from a declared kind with its rule, e.g. ``"int>=1"`` or ``"floats[2|3]"``."""
        kind, rule = re.fullmatch(r"([a-z]+)(.*)", declared).groups()
        return cls(kind, required, default, rule)

    def violation(self, value: Any) -> str | None:
        """Why ``value`` breaks the rule, or None."""
        rule = self.rule
        if not rule:
            return None
        if rule.startswith(">="):
            return None if value >= float(rule[2:]) else f"must be at least {rule[2:]}, got {value!r}"
        if rule.startswith(">"):
            return None if value > float(rule[1:]) else f"must be greater than {rule[1:]}, got {value!r}"
        allowed = rule[1:-1].split("|")
        if rule.startswith("["):
            return (
                None
                if str(len(value)) in allowed
                else f"needs {' or '.join(allowed)} numbers, got {len(value)}"
            )
        return None if value in allowed else f"must be one of {', '.join(allowed)}, got {value!r}"


@dataclass(frozen=True)
class NodeType:
    """How to build one node type from its parameters.

    Attributes:
        build: the class or factory, called with ``name``, the parameters and the children.
        params: parameter -> :class:`Param`.
        children: "none", "one" (decorators: ``child``) or "many" (composites: ``children``).
        roles: the class whose blackboard roles the node has (the planning leaf, for a subtree), if any.
    """

    build: Callable[..., py_trees.behaviour.Behaviour]
    params: dict[str, Param] = field(default_factory=dict)
    children: str = "none"
    roles: type[RoleBehaviour] | None = None


def _params(build: Callable, kinds: Mapping[str, str]) -> dict[str, Param]:
    """Parameters of the given kinds, required or defaulted as ``build``'s signature says."""
    signature = inspect.signature(build)
    params = {}
    for name, kind in kinds.items():
        default = signature.parameters[name].default
        required = default is inspect.Parameter.empty
        params[name] = Param.of(kind, required, None if required else default)
    return params


def leaf(cls: type[RoleBehaviour]) -> NodeType:
    """The node type of a behaviour class, from what it declares."""
    kinds = dict(cls.parameters) | (WIRING if cls.roles else {})
    return NodeType(cls, _params(cls, kinds), roles=cls if cls.roles else None)


def subtree(factory: Callable) -> NodeType:
    """The node type of a subtree idiom, from what it declares: its parameters and the planning leaf whose
    blackboard roles it has (if it takes a remap)."""
    return NodeType(factory, _params(factory, factory.parameters), roles=factory.planner)


_POLICIES = {
    "all": py_trees.common.ParallelPolicy.SuccessOnAll,
    "one": py_trees.common.ParallelPolicy.SuccessOnOne,
}


def _decorator(cls) -> NodeType:
    return NodeType(lambda name, child: cls(name, child), {}, "one")


NODE_TYPES: dict[str, NodeType] = {
    "Sequence": NodeType(
        lambda name, memory, children: py_trees.composites.Sequence(name, memory, children),
        {"memory": Param("bool", default=True)},
        "many",
    ),
    "Selector": NodeType(
        lambda name, memory, children: py_trees.composites.Selector(name, memory, children),
        {"memory": Param("bool", default=True)},
        "many",
    ),
    "Parallel": NodeType(
        lambda name, policy, children: py_trees.composites.Parallel(name, _POLICIES[policy](), children),
        {"policy": Param.of("str{all|one}", default="all")},
        "many",
    ),
    "Retry": NodeType(
        lambda name, attempts, child: py_trees.decorators.Retry(name, child, attempts),
        {"attempts": Param.of("int>=1", required=True)},
        "one",
    ),
    "Repeat": NodeType(
        lambda name, times, child: py_trees.decorators.Repeat(name, child, times),
        {"times": Param.of("int>=1", required=True)},
        "one",
    ),
    "Inverter": _decorator(py_trees.decorators.Inverter),
    "SuccessIsFailure": _decorator(py_trees.decorators.SuccessIsFailure),
    "FailureIsSuccess": _decorator(py_trees.decorators.FailureIsSuccess),
    "SuccessIsRunning": _decorator(py_trees.decorators.SuccessIsRunning),
    "Timeout": NodeType(
        lambda name, duration, child: SimTimeout(name, child, duration=duration),
        {"duration": Param.of("float>0", required=True)},
        "one",
    ),
    "ForEach": NodeType(ForEach, _params(ForEach, {"items": "str", "namespace": "str"}), "one"),
    "KeepApart": NodeType(
        KeepApart, _params(KeepApart, {"other": "str", "margin": "float>0", "arm": "str"}), "one"
    ),
    **{
        cls.__name__: leaf(cls)
        for cls in (
            ExecutePrimitive,
            InstantiateSkillTemplate,
            Gripper,
            ObjectGrasped,
            ObjectAt,
            AtPose,
            ArmsApart,
            Wait,
            RiseClear,
            PerceiveObject,
            PlanGrasp,
            PlanPlace,
            PlanReturn,
            PlanMove,
            AimThrow,
            Throw,
        )
    },
    **{factory.node_type: subtree(factory) for factory in (grasp, place, return_home, grasp_then_place)},
}
