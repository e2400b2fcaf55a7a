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

More node types come from :func:`register_node_type`, or from other installed distributions: a module named
under the entry-point group ``besman.node_types`` (:data:`ENTRY_POINTS`) whose ``NODE_TYPES`` is a tuple of
leaf classes and subtree idioms, registered as this module is imported (the documentation's "Add a node
type" page). Besman's own names are never taken over.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import py_trees

from besman.core.errors import InputError
from besman.core.plugins import plugin_modules, warn_plugin
from besman.trees.base import RoleBehaviour
from besman.trees.conditions import ArmsApart, AtPose, ObjectAt, ObjectGrasped
from besman.trees.guards import KeepApart
from besman.trees.idioms import grasp, grasp_then_place, place, return_home
from besman.trees.leaves import ExecutePrimitive, Gripper, InstantiateSkillTemplate
from besman.trees.loops import ForEach
from besman.trees.manipulation import PerceiveObject, PlanGrasp, PlanMove, PlanPlace, PlanReturn, RiseClear
from besman.trees.timing import SimTimeout, Wait

WIRING = {"namespace": "str", "remap": "keys"}
KINDS = ("str", "float", "int", "bool", "floats", "keys", "primitive", "template", "pool")
ENTRY_POINTS = "besman.node_types"  # the group under which other distributions name their node-type modules


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
        if name not in signature.parameters:
            raise InputError(f"{_named(build)}: declares the parameter {name!r}, which it does not take")
        if not re.fullmatch(rf"({'|'.join(KINDS)})(>=?-?[0-9.]+|\[[0-9|]+\]|\{{[^{{}}]+\}})?", kind):
            raise InputError(
                f"{_named(build)}: parameter {name!r} is of kind {kind!r}; the kinds: {', '.join(KINDS)} "
                "(with an optional rule, e.g. float>0, floats[2|3], str{a|b})"
            )
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
        )
    },
    **{factory.node_type: subtree(factory) for factory in (grasp, place, return_home, grasp_then_place)},
}


def _named(build: Callable) -> str:
    return f"{getattr(build, '__module__', '?')}.{getattr(build, '__qualname__', build)}"


def register_node_type(node: type[RoleBehaviour] | Callable) -> str:
    """Adds a node type that tree files may use, and returns its name: a leaf class (a
    :class:`~besman.trees.base.RoleBehaviour`, named by its class name, its parameters and roles as it
    declares them) or a subtree idiom (a function with ``node_type``, ``parameters`` and ``planner``, as
    :mod:`besman.trees.idioms`'). The tree loader, ``besman tree nodes`` and the tree files' JSON Schema all
    read the one table, so the new type is checked, documented and described like besman's own. A name
    already taken is refused."""
    if isinstance(node, type) and issubclass(node, RoleBehaviour):
        name, spec = node.__name__, leaf(node)
    elif callable(node) and all(hasattr(node, a) for a in ("node_type", "parameters", "planner")):
        name, spec = node.node_type, subtree(node)
    else:
        raise InputError(
            f"{node!r}: a node type is a leaf class (a subclass of besman.trees.base.RoleBehaviour) or a "
            "subtree idiom (a function with node_type, parameters and planner)"
        )
    if not re.fullmatch(r"[A-Z][A-Za-z0-9]*", name):
        raise InputError(f"{_named(node)}: a node type's name is CamelCase, got {name!r}")
    if name in NODE_TYPES:
        raise InputError(
            f"{_named(node)}: the node type {name!r} exists already ({_named(NODE_TYPES[name].build)})"
        )
    NODE_TYPES[name] = spec
    return name


def _register_plugins() -> None:
    """The node types of other distributions' modules (:data:`ENTRY_POINTS`); what cannot be registered is
    warned of and left out, the rest of its module kept."""
    for who, module in plugin_modules(ENTRY_POINTS, "node-type"):
        for node in getattr(module, "NODE_TYPES", ()):
            try:
                register_node_type(node)
            except InputError as error:
                warn_plugin(f"{who}: {error} (left out)")


_register_plugins()
