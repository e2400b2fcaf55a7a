"""Tree files: behaviour trees written in YAML, validated before anything runs.

py_trees has no file format of its own. A besman tree file is::

    besman_tree: 1                 # the format's version
    task: pick-place               # the task it runs on (besman tasks lists them; a subtree may leave it out)
    root:                          # one node
      Sequence:                    # a node is a mapping with one key, its type ...
        name: tidy up              # ... whose value holds its parameters
        memory: true
        children:
          - Wait: {name: settle, duration: 0.5}
          - include: grasp.yaml    # a subtree from another file (relative to this one)
            remap: {/grasp/object_position: /perception/box}   # blackboard keys, renamed inside it
          - GraspThenPlace: {name: move the box, object: box, target: /task/place}

Node types (:data:`~besman.trees.nodes.NODE_TYPES`, derived from the classes): the py_trees composites
(``Sequence``, ``Selector``, ``Parallel``) and decorators (``Retry``, ``Repeat``, ``Inverter``,
``SuccessIsFailure``, ``FailureIsSuccess``, ``SuccessIsRunning``, ``Timeout`` in simulated time), the loop
``ForEach``, besman's leaves (``ExecutePrimitive``, ``InstantiateSkillTemplate``, ``Gripper``,
``ObjectGrasped``, ``ObjectAt``, ``AtPose``, ``ArmsApart``, ``Wait``, ``RiseClear``, ``PerceiveObject``,
``PlanGrasp``, ``PlanPlace``, ``PlanReturn``, ``PlanMove``), subtree idioms (``Grasp``, ``Place``,
``ReturnHome``, ``GraspThenPlace``) and the node types tasks and other distributions register (the throwing
task's ``AimThrow`` and ``Throw``); ``besman tree nodes`` lists them all with their
parameters (:mod:`besman.trees.reference`). Primitives are referenced by the path of their JSON file;
templates by ``MODULE:NAME`` (an object with ``instantiate(tau)``), or a pool and a ``template_name``:
``pool:`` names a skill template pool directory (relative to the tree file,
:class:`~besman.skills.pool.SkillTemplatePool`; ``{robot}`` in it is the name of the robot the tree runs on,
``../pools/pick_place_{robot}``) or a ``MODULE:NAME`` mapping of names to templates. A
``MODULE:NAME`` is registered in Python or in a module the user allows (``allow_modules``); a file alone
never makes anything import (:mod:`besman.trees.registry`). Leaves with blackboard roles take ``namespace``
and ``remap`` (role -> key).

:func:`load_tree` checks the whole file first - unknown node types, missing or mistyped parameters, missing
files, cycles of includes, includes or trees too deep - and reports the file, line and path of the first
problem (:class:`TreeFileError`). :func:`check_tree` does the same without importing any module.
:func:`describe` and :func:`dump_tree` turn a tree back into the same format, so a file round-trips.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import py_trees
import yaml

from besman.core.errors import BesmanError
from besman.core.reading import read_bytes
from besman.core.validation import PATH, checked, instance, optional, text
from besman.skills import MovementPrimitive
from besman.skills.pool import SkillTemplatePool
from besman.trees.base import BEHAVIOUR
from besman.trees.nodes import NODE_TYPES, NodeType, Param
from besman.trees.registry import UNIMPORTED, allowed_modules, resolve
from besman.trees.timing import SimTimeout

FORMAT_VERSION = 1
ROBOT_FIELD = "{robot}"  # in a pool's path: the name of the robot the tree is built for
# Bounds checked before a file is built: a tree file is a few kilobytes; these leave room for generated ones
# and refuse what would hang or exhaust memory (deep nesting overflows Python's stack).
MAX_FILE_BYTES = 1_000_000
MAX_NESTING = 200  # YAML levels (a tree level takes about four)
# Across includes, where no one file's nesting bounds them: files included within one another, and the
# tree's levels (building, ticking and describing a tree take a few frames of Python's stack a level).
MAX_INCLUDES = 32
MAX_DEPTH = 100
# Nodes in all, counted through includes: a file that includes the next one twice, 32 files deep, would
# otherwise build 2^32 nodes. The shipped trees have at most a few hundred.
MAX_NODES = 10_000


class TreeFileError(BesmanError):
    """A tree file is invalid; the message starts with ``file:line: path:``."""


@checked(path=PATH, pool=optional(PATH), robot=optional(text("a robot's name")))
def load_tree(
    path: str | Path,
    *,
    pool: str | Path | None = None,
    allow_modules: Iterable[str] = (),
    robot: str | None = None,
) -> py_trees.behaviour.Behaviour:
    """Builds the tree of a file; a :class:`TreeFileError` names the file, line and path of any problem.
    ``pool`` (a pool directory) replaces every pool the file names (``besman run --pool``); ``robot``, the
    name of the robot it is built for, replaces ``{robot}`` in the pool paths it names; the file's
    ``MODULE:NAME`` references are registered ones or in ``allow_modules``, imported here."""
    builder = _Builder(_pool_override(pool), allowed_modules(allow_modules), imports=True, robot=robot)
    return builder.file(Path(path), remap={}, stack=())


@checked(text=instance(str | bytes, "YAML text (str)"), base=PATH, source=text("a name"), pool=optional(PATH))
def loads_tree(
    text: str,
    *,
    base: str | Path = ".",
    source: str = "<text>",
    pool: str | Path | None = None,
    allow_modules: Iterable[str] = (),
) -> py_trees.behaviour.Behaviour:
    """Builds a tree from YAML text (includes are relative to ``base``; ``pool`` and ``allow_modules`` as
    for :func:`load_tree`)."""
    builder = _Builder(_pool_override(pool), allowed_modules(allow_modules), imports=True)
    return builder.document(text, Path(base) / source, remap={}, stack=())


@checked(path=PATH, tasks=optional(instance(Iterable, "task names")))
def check_tree(
    path: str | Path, *, allow_modules: Iterable[str] = (), tasks: Iterable[str] | None = None
) -> list[str]:
    """Checks a file as :func:`load_tree` does, but imports nothing: a ``MODULE:NAME`` of an allowed module
    is checked for its form only; with ``tasks`` (the registry's names), the task the file names must be one
    of them. Returns the references left to be imported when the tree is built."""
    builder = _Builder(None, allowed_modules(allow_modules), imports=False, tasks=tasks)
    builder.file(Path(path), remap={}, stack=())
    return list(dict.fromkeys(builder.unimported))


@checked(path=PATH)
def tree_task(path: str | Path) -> str | None:
    """The task a tree file names (its top-level ``task``), None if it names none (a subtree)."""
    path = Path(path)
    text = read_bytes(path, MAX_FILE_BYTES, what="tree file", error=TreeFileError).decode("utf-8", "replace")
    builder = _Builder(None, frozenset(), imports=False)
    top = builder.top(text, path)
    return None if "task" not in top else builder._scalar(top["task"], path, "task")


def _pool_override(pool: str | Path | None) -> Path | None:
    if pool is not None and not Path(pool).is_dir():
        raise TreeFileError(f"--pool {pool}: no such pool directory")
    return None if pool is None else Path(pool)


class _Builder:
    def __init__(
        self,
        pool: Path | None,
        allowed: frozenset[str],
        imports: bool,
        tasks: Iterable[str] | None = None,
        robot: str | None = None,
    ) -> None:
        self.pool = pool  # replaces every pool the files name
        self.allowed, self.imports = allowed, imports  # modules that MODULE:NAME may name; import them?
        self.tasks = None if tasks is None else tuple(tasks)  # the names a file's task may have (None: any)
        self.robot = robot  # the robot's name that replaces {robot} in pool paths
        self.unimported: list[str] = []  # the references left to import (not self.imports)
        self.depth = 0  # the levels of the node being built, counted through includes
        self.nodes = 0  # the nodes built so far, counted through includes
        self._tops: dict[tuple[Path, str], dict] = {}  # each file parsed once, however often included

    def file(self, path: Path, remap: Mapping[str, str], stack: tuple[Path, ...]):
        resolved = path.resolve()
        if resolved in stack:
            chain = " -> ".join(str(p) for p in (*stack, resolved))
            raise TreeFileError(f"{path}: includes form a cycle: {chain}")
        where = f"{stack[-1]}: " if stack else ""
        try:
            text = read_bytes(path, MAX_FILE_BYTES, what="tree file", error=TreeFileError).decode("utf-8")
        except TreeFileError as error:
            raise TreeFileError(f"{where}{error}") from None
        except UnicodeDecodeError as error:
            raise TreeFileError(f"{where}{path}: not a text file (byte {error.start} is not UTF-8)") from None
        return self.document(text, path, remap, (*stack, resolved))

    def document(self, text: str, path: Path, remap: Mapping[str, str], stack: tuple[Path, ...]):
        top = self.top(text, path)
        if "task" in top:
            task = self._scalar(top["task"], path, "task")
            if self.tasks is not None and task not in self.tasks:
                raise TreeFileError(
                    f"{path}:{self._line(top['task'])}: task: no task {task!r}; tasks: "
                    + ", ".join(self.tasks)
                )
        return self.node(top["root"], path, "root", remap, stack)

    def top(self, text: str, path: Path) -> dict:
        """The top-level mapping of a file's text, checked: its version, known fields and a root."""
        if (path, text) not in self._tops:
            self._tops[path, text] = self._top(text, path)
        return self._tops[path, text]

    def _top(self, text: str, path: Path) -> dict:
        if len(text) > MAX_FILE_BYTES:
            raise TreeFileError(f"{path}: larger than {MAX_FILE_BYTES} characters; not a tree file")
        try:
            self._check_events(text, path)
            node = yaml.compose(text, Loader=yaml.SafeLoader)
        except yaml.YAMLError as error:
            mark = getattr(error, "problem_mark", None)
            line = f":{mark.line + 1}" if mark else ""
            raise TreeFileError(
                f"{path}{line}: not valid YAML ({getattr(error, 'problem', error)})"
            ) from None
        if not isinstance(node, yaml.MappingNode):
            raise TreeFileError(f"{path}:1: a tree file is a mapping with 'besman_tree' and 'root'")
        top = self._mapping(node, path, "")
        version = top.get("besman_tree")
        if version is None or self._scalar(version, path, "besman_tree") != str(FORMAT_VERSION):
            raise TreeFileError(
                f"{path}:{self._line(version or node)}: besman_tree: expected {FORMAT_VERSION}"
            )
        unknown = set(top) - {"besman_tree", "task", "root"}
        if unknown:
            key = sorted(unknown)[0]
            raise TreeFileError(f"{path}:{self._line(top[key])}: unknown top-level field {key!r}")
        if "root" not in top:
            raise TreeFileError(f"{path}:{self._line(node)}: missing 'root'")
        return top

    @staticmethod
    def _check_events(text: str, path: Path) -> None:
        """Refuses anchors and aliases (a few lines of them expand to gigabytes: "billion laughs") and
        nesting deeper than :data:`MAX_NESTING`, in one pass over the parser's events."""
        depth = 0
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise TreeFileError(
                    f"{path}:{event.start_mark.line + 1}: anchors and aliases (& and *) are not supported "
                    "in tree files; use include to reuse a subtree"
                )
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_NESTING:
                    raise TreeFileError(
                        f"{path}:{event.start_mark.line + 1}: nested deeper than {MAX_NESTING} levels"
                    )
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1

    # -- YAML helpers --------------------------------------------------------------------------------------

    @staticmethod
    def _line(node) -> int:
        return node.start_mark.line + 1

    def _error(self, node, path: Path, where: str, message: str) -> TreeFileError:
        return TreeFileError(f"{path}:{self._line(node)}: {where}: {message}")

    def _mapping(self, node, path: Path, where: str) -> dict[str, Any]:
        if not isinstance(node, yaml.MappingNode):
            raise self._error(node, path, where or "document", "expected a mapping")
        result = {}
        for key, value in node.value:
            name = self._scalar(key, path, where)
            if name in result:
                raise self._error(key, path, where, f"{name!r} appears twice")
            result[name] = value
        return result

    def _scalar(self, node, path: Path, where: str) -> str:
        if not isinstance(node, yaml.ScalarNode):
            raise self._error(node, path, where, "expected a single value")
        return node.value

    # -- nodes ---------------------------------------------------------------------------------------------

    def node(self, node, path: Path, where: str, remap: Mapping[str, str], stack: tuple[Path, ...]):
        self.depth += 1
        self.nodes += 1
        try:
            if self.nodes > MAX_NODES:
                raise self._error(
                    node, path, where, f"the tree has more than {MAX_NODES} nodes (with its included files)"
                )
            if self.depth > MAX_DEPTH:
                raise self._error(
                    node, path, where, f"the tree is deeper than {MAX_DEPTH} levels (with its included files)"
                )
            return self._node(node, path, where, remap, stack)
        finally:
            self.depth -= 1

    def _node(self, node, path: Path, where: str, remap: Mapping[str, str], stack: tuple[Path, ...]):
        entries = self._mapping(node, path, where)
        if "include" in entries:
            return self.include(entries, node, path, where, remap, stack)
        if len(entries) != 1:
            raise self._error(node, path, where, f"a node has exactly one type, got {sorted(entries)}")
        ((type_name, body),) = entries.items()
        here = f"{where}.{type_name}"
        if type_name not in NODE_TYPES:
            raise self._error(
                node, path, where, f"unknown node type {type_name!r}; known: {', '.join(NODE_TYPES)}"
            )
        spec = NODE_TYPES[type_name]
        fields = (
            self._mapping(body, path, here)
            if not (isinstance(body, yaml.ScalarNode) and body.value == "")
            else {}
        )
        if "name" not in fields:
            raise self._error(body, path, here, "missing parameter 'name'")
        arguments = {"name": self._scalar(fields.pop("name"), path, f"{here}.name")}
        if spec.children == "many":
            children = fields.pop("children", None)
            if not isinstance(children, yaml.SequenceNode) or not children.value:
                raise self._error(body, path, here, "'children' must be a non-empty list of nodes")
            arguments["children"] = [
                self.node(child, path, f"{here}.children[{i}]", remap, stack)
                for i, child in enumerate(children.value)
            ]
        elif spec.children == "one":
            child = fields.pop("child", None)
            if child is None:
                raise self._error(body, path, here, "missing 'child'")
            arguments["child"] = self.node(child, path, f"{here}.child", remap, stack)
        references = {}  # how the file named primitives and templates, for describe()
        for param_name, param in spec.params.items():
            if param_name in fields:
                value_node = fields.pop(param_name)
                arguments[param_name] = self.value(value_node, param, path, f"{here}.{param_name}")
                if param.kind == "primitive":
                    references[param_name] = str((path.parent / value_node.value).resolve())
                elif param.kind in ("template", "pool"):
                    references[param_name] = value_node.value
            elif param.required:
                raise self._error(body, path, here, f"missing parameter {param_name!r}")
            elif param.default is not None:
                arguments[param_name] = param.default
        if fields:
            extra = sorted(fields)[0]
            known = ", ".join(["name", *spec.params]) or "name"
            raise self._error(
                fields[extra], path, f"{here}.{extra}", f"unknown parameter; {type_name} takes {known}"
            )
        if remap and "remap" in spec.params:
            arguments["remap"] = self._apply_remap(spec, arguments, remap)
        if remap and isinstance(arguments.get("target"), str):
            arguments["target"] = remap.get(arguments["target"], arguments["target"])
        try:
            behaviour = spec.build(**arguments)
        except (ValueError, KeyError) as error:
            raise self._error(body, path, here, str(error)) from None
        behaviour.besman_spec = {
            "type": type_name,
            **{k: v for k, v in arguments.items() if k not in ("children", "child")},
            **references,
        }
        return behaviour

    @staticmethod
    def _apply_remap(spec: NodeType, arguments: dict, remap: Mapping[str, str]) -> dict[str, str]:
        """Include remappings rename keys: each role's key (its own remap applied first) is renamed."""
        own = dict(arguments.get("remap") or {})
        keys = spec.roles.role_keys(str(arguments.get("namespace", "")), own)
        return own | {role: remap[key] for role, key in keys.items() if key in remap}

    def include(self, entries, node, path: Path, where: str, remap: Mapping[str, str], stack):
        extra = set(entries) - {"include", "remap"}
        if extra:
            key = sorted(extra)[0]
            raise self._error(
                entries[key], path, f"{where}.{key}", "an include takes only 'include' and 'remap'"
            )
        target = path.parent / self._scalar(entries["include"], path, f"{where}.include")
        inner = dict(remap)
        if "remap" in entries:
            own = self.value(entries["remap"], Param("keys"), path, f"{where}.remap")
            inner = {key: remap.get(value, value) for key, value in own.items()} | {
                key: value for key, value in remap.items() if key not in own
            }
        if not target.exists():
            raise self._error(entries["include"], path, f"{where}.include", f"no such file {target}")
        if len(stack) >= MAX_INCLUDES:
            raise self._error(
                entries["include"],
                path,
                f"{where}.include",
                f"files included deeper than {MAX_INCLUDES} levels",
            )
        behaviour = self.file(target, inner, stack)
        behaviour.besman_include = {"include": str(target), "remap": inner}
        return behaviour

    def value(self, node, param: Param, path: Path, where: str):
        value = self._value(node, param, path, where)
        problem = param.violation(value)
        if problem is not None:
            raise self._error(node, path, where, problem)
        return value

    def _value(self, node, param: Param, path: Path, where: str):
        kind = param.kind
        if kind == "keys":
            mapping = self._mapping(node, path, where)
            return {key: self._scalar(value, path, f"{where}.{key}") for key, value in mapping.items()}
        if kind == "floats":
            if not isinstance(node, yaml.SequenceNode):
                raise self._error(node, path, where, "expected a list of numbers")
            return [self._number(item, path, f"{where}[{i}]", float) for i, item in enumerate(node.value)]
        text = self._scalar(node, path, where)
        if kind == "str":
            return text
        if kind == "float":
            return self._number(node, path, where, float)
        if kind == "int":
            return self._number(node, path, where, int)
        if kind == "bool":
            if text.lower() not in ("true", "false"):
                raise self._error(node, path, where, f"expected true or false, got {text!r}")
            return text.lower() == "true"
        if kind == "primitive":
            file = path.parent / text
            try:
                primitive = MovementPrimitive.load(file)
            except ValueError as error:
                raise self._error(node, path, where, str(error)) from None
            return primitive
        if kind == "pool" and (self.pool is not None or ":" not in text):
            if ROBOT_FIELD in text and self.pool is None:
                if self.robot is None:
                    if not self.imports:  # checked for its form: which robot's pool is known when it runs
                        return UNIMPORTED
                    raise self._error(
                        node, path, where, f"{text!r} names {ROBOT_FIELD}: build it for a robot"
                    )
                text = text.replace(ROBOT_FIELD, self.robot)
            directory = self.pool or path.parent / text  # a pool directory, relative to the tree file
            if not directory.is_dir():
                raise self._error(node, path, where, f"no pool directory {str(directory)!r}")
            return SkillTemplatePool(directory)
        if kind in ("template", "pool"):
            try:
                found = resolve(text, kind, self.allowed, imports=self.imports)
            except BesmanError as error:
                raise self._error(node, path, where, str(error)) from None
            if found is UNIMPORTED:
                self.unimported.append(text)
            return found
        raise AssertionError(kind)

    def _number(self, node, path: Path, where: str, kind: type):
        text = self._scalar(node, path, where)
        try:
            number = kind(text) if kind is int else float(text)
        except ValueError:
            raise self._error(
                node, path, where, f"expected {'an integer' if kind is int else 'a number'}, got {text!r}"
            ) from None
        if not math.isfinite(number):
            raise self._error(node, path, where, f"expected a finite number, got {text!r}")
        return number


@checked(node=BEHAVIOUR)
def describe(node: py_trees.behaviour.Behaviour) -> dict:
    """A tree as plain data in the file format (node types with their parameters, nested)."""
    spec = dict(getattr(node, "besman_spec", None) or _spec_of(node))
    type_name = spec.pop("type")
    body: dict[str, Any] = {}
    for key, value in spec.items():
        if not isinstance(value, str) and key in ("primitive", "template", "pool"):
            raise TreeFileError(
                f"{spec.get('name')}: a {key} given as an object has no file form; name it in a file"
            )
        if value not in ({}, None):
            body[key] = value
    kind = NODE_TYPES[type_name].children
    if kind == "many":
        body["children"] = [describe(child) for child in node.children]
    elif kind == "one":
        body["child"] = describe(node.decorated)
    return {type_name: body}


def _spec_of(node: py_trees.behaviour.Behaviour) -> dict:
    """The file spec of a behaviour built in code rather than from a file."""
    name = node.name
    if isinstance(node, py_trees.composites.Sequence):
        return {"type": "Sequence", "name": name, "memory": node.memory}
    if isinstance(node, py_trees.composites.Selector):
        return {"type": "Selector", "name": name, "memory": node.memory}
    if isinstance(node, py_trees.composites.Parallel):
        policy = "all" if isinstance(node.policy, py_trees.common.ParallelPolicy.SuccessOnAll) else "one"
        if isinstance(node.policy, py_trees.common.ParallelPolicy.SuccessOnSelected):
            raise TreeFileError(
                f"{name}: a Parallel with a SuccessOnSelected policy has no file form; "
                "use the subtree node that made it"
            )
        return {"type": "Parallel", "name": name, "policy": policy}
    simple = {
        py_trees.decorators.Inverter: "Inverter",
        py_trees.decorators.SuccessIsFailure: "SuccessIsFailure",
        py_trees.decorators.FailureIsSuccess: "FailureIsSuccess",
        py_trees.decorators.SuccessIsRunning: "SuccessIsRunning",
    }
    for cls, type_name in simple.items():
        if type(node) is cls:
            return {"type": type_name, "name": name}
    if isinstance(node, py_trees.decorators.Retry):
        return {"type": "Retry", "name": name, "attempts": node.num_failures}
    if isinstance(node, py_trees.decorators.Repeat):
        return {"type": "Repeat", "name": name, "times": node.num_success}
    if isinstance(node, SimTimeout):
        return {"type": "Timeout", "name": name, "duration": node.duration}
    raise TreeFileError(f"{name}: {type(node).__name__} has no file form")


@checked(root=BEHAVIOUR)
def dump_tree(root: py_trees.behaviour.Behaviour) -> str:
    """The tree file text of a tree (subtrees made by file nodes are written as those nodes)."""
    return yaml.safe_dump({"besman_tree": FORMAT_VERSION, "root": describe(root)}, sort_keys=False)


__all__ = [
    "NODE_TYPES",
    "TreeFileError",
    "check_tree",
    "describe",
    "dump_tree",
    "load_tree",
    "loads_tree",
]
