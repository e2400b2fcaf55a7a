"""The reference of tree-file nodes and the JSON Schema of tree files, both made from the loader's own table.

:data:`besman.trees.nodes.NODE_TYPES` is what the loader builds nodes from; everything here is derived from
it, so the reference (``besman tree nodes``, the node section of ``docs/trees.md``) and the schema
(``besman tree schema``) can never say something the loader does not do:

- :func:`node_reference` - per node type: a one-line description (the first line of its class's or
  factory's docstring), its children, its parameters (kind, required, default, range) and its blackboard
  roles (read or write; subtrees report their planning leaf's);
- :func:`markdown_reference` - the same as Markdown tables;
- :func:`tree_schema` - a JSON Schema (draft 2020-12) of tree files, for editors that validate and complete
  YAML as it is typed. It checks the structure, names, kinds and ranges; what only the loader can check
  (included files exist, a pool has the named template, numbers are finite) it leaves to
  ``besman tree check``.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Iterable
from typing import Any

from py_trees.common import Access

from besman.core.errors import UnknownNameError
from besman.trees.files import FORMAT_VERSION
from besman.trees.nodes import NODE_TYPES, NodeType, Param

SCHEMA_ID = "https://besman.invalid/schemas/tree-file-1.json"
_CHILDREN = {"none": "no children", "one": "one child (child:)", "many": "children (a list)"}
_KINDS = {
    "str": "string",
    "float": "number",
    "int": "integer",
    "bool": "true or false",
    "floats": "list of numbers",
    "keys": "mapping of roles or keys to keys",
    "primitive": "a primitive's JSON file (relative to the tree file)",
    "template": "MODULE:NAME of an object with instantiate(tau): registered (register_template) or in a "
    "module allowed with --allow-module",
    "pool": "a skill template pool directory (relative to the tree file) or MODULE:NAME of a mapping of "
    "names to templates: registered (register_pool) or in a module allowed with --allow-module",
}


def _description(spec: NodeType) -> str:
    doc = inspect.getdoc(spec.build) or ""
    if not doc or spec.build.__name__ == "<lambda>":
        return ""
    paragraph = plain(doc.split("\n\n")[0].replace("\n", " "))
    sentence = re.split(r"(?<=[.?])\s+(?=[A-Z])", paragraph)[0]  # the first sentence
    return sentence if sentence.endswith((".", "?")) else sentence + "."


_ROLE = re.compile(r":(?:py:)?(\w+):`(~?)([^`<]*?)(?:\s*<([^`>]+)>)?`")


def plain(text: str) -> str:
    """A docstring's reStructuredText as people read it in a terminal or an editor's tooltip, as Sphinx shows
    it: ``name`` -> name, :data:`~a.b.LIMIT` -> LIMIT, :meth:`~a.B.read` -> B.read(), :class:`a.B` -> a.B,
    :func:`title <a.f>` -> title."""

    def shown(match: re.Match) -> str:
        role, short, target, title_target = match.groups()
        if title_target is not None:  # :role:`title <target>`
            return target.strip()
        parts = target.split(".")
        if short:  # ~: the last name, a method's with its class
            parts = parts[-2:] if role == "meth" else parts[-1:]
        return ".".join(parts) + ("()" if role in ("func", "meth") else "")

    return _ROLE.sub(shown, text).replace("``", "")


def _range(param: Param) -> str:
    rule = param.rule
    if rule.startswith(">="):
        return f">= {rule[2:]}"
    if rule.startswith(">"):
        return f"> {rule[1:]}"
    if rule.startswith("["):
        return "length " + " or ".join(rule[1:-1].split("|"))
    if rule.startswith("{"):
        return "one of " + ", ".join(rule[1:-1].split("|"))
    return ""


def _default(param: Param) -> Any:
    value = param.default
    return value if value is None or isinstance(value, bool | int | float | str) else repr(value)


# Descriptions of py_trees' own composites and decorators (their docstrings are py_trees').
_BUILT_IN = {
    "Sequence": "Ticks its children in order; fails at the first failure, succeeds when all succeed.",
    "Selector": "Ticks its children in order until one does not fail (a fallback).",
    "Parallel": "Ticks all children every tick; succeeds when all (policy all) or one (policy one) succeed.",
    "Retry": "Ticks its child again after a failure, up to attempts failures in all.",
    "Repeat": "Ticks its child again after each success, times times in all.",
    "Inverter": "Success becomes failure and failure success.",
    "SuccessIsFailure": "Its child's success becomes failure.",
    "FailureIsSuccess": "Its child's failure becomes success.",
    "SuccessIsRunning": "Its child's success becomes running (a guard that keeps checking).",
    "Timeout": "Fails its child when it runs longer than duration seconds of simulated time.",
}


def node_reference(name: str | None = None) -> dict[str, dict]:
    """Every node type (or ``name`` alone) as plain data; an unknown name lists the known types."""
    if name is not None and name not in NODE_TYPES:
        raise UnknownNameError(f"unknown node type {name!r}; known: {', '.join(NODE_TYPES)}")
    reference = {}
    for type_name, spec in NODE_TYPES.items():
        if name is not None and type_name != name:
            continue
        roles = spec.roles.roles if spec.roles is not None else {}
        reference[type_name] = {
            "description": _BUILT_IN.get(type_name) or _description(spec),
            "children": spec.children,
            "parameters": {
                "name": {"kind": "str", "required": True, "default": None, "range": ""},
                **{
                    param_name: {
                        "kind": param.kind,
                        "required": param.required,
                        "default": _default(param),
                        "range": _range(param),
                    }
                    for param_name, param in spec.params.items()
                },
            },
            "blackboard": {
                role: "read" if access is Access.READ else "write" for role, access in roles.items()
            },
        }
    return reference


def markdown_reference() -> str:
    """The node reference as Markdown: a section per node type."""
    lines = []
    for type_name, entry in node_reference().items():
        lines += [f"### {type_name}", "", entry["description"] or "(no description)", ""]
        lines.append(f"Children: {_CHILDREN[entry['children']]}.")
        if entry["blackboard"]:
            roles = ", ".join(f"`{role}` ({access})" for role, access in entry["blackboard"].items())
            lines.append(f"Blackboard roles: {roles}.")
        lines += ["", "| parameter | kind | required | default | range |", "|---|---|---|---|---|"]
        for param_name, param in entry["parameters"].items():
            default = "" if param["default"] is None else f"`{param['default']}`"
            required = "yes" if param["required"] else ""
            lines.append(f"| `{param_name}` | {param['kind']} | {required} | {default} | {param['range']} |")
        lines.append("")
    return "\n".join(lines)


def _value_schema(param: Param) -> dict:
    rule = param.rule
    schema: dict[str, Any] = {"description": _KINDS[param.kind]}
    if param.kind in ("str", "primitive", "template", "pool"):
        schema["type"] = "string"
        if rule.startswith("{"):
            schema["enum"] = rule[1:-1].split("|")
    elif param.kind in ("float", "int"):
        schema["type"] = "number" if param.kind == "float" else "integer"
        if rule.startswith(">="):
            schema["minimum"] = float(rule[2:])
        elif rule.startswith(">"):
            schema["exclusiveMinimum"] = float(rule[1:])
    elif param.kind == "bool":
        schema["type"] = "boolean"
    elif param.kind == "floats":
        schema["type"] = "array"
        schema["items"] = {"type": "number"}
        if rule.startswith("["):
            lengths = [int(n) for n in rule[1:-1].split("|")]
            schema["minItems"], schema["maxItems"] = min(lengths), max(lengths)
    elif param.kind == "keys":
        schema["type"] = "object"
        schema["additionalProperties"] = {"type": "string"}
    return schema


def _node_schema(type_name: str, spec: NodeType) -> dict:
    properties: dict[str, Any] = {"name": {"type": "string", "description": "the node's name"}}
    required = ["name"]
    if spec.children == "many":
        properties["children"] = {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/node"}}
        required.append("children")
    elif spec.children == "one":
        properties["child"] = {"$ref": "#/$defs/node"}
        required.append("child")
    for param_name, param in spec.params.items():
        properties[param_name] = _value_schema(param)
        if param.required:
            required.append(param_name)
    body = {"type": "object", "properties": properties, "required": required, "additionalProperties": False}
    description = _BUILT_IN.get(type_name) or _description(spec)
    return {
        "type": "object",
        "description": description,
        "properties": {type_name: body},
        "required": [type_name],
        "additionalProperties": False,
    }


def tree_schema(tasks: Iterable[str] | None = None) -> dict:
    """The JSON Schema of tree files (see the module documentation); ``tasks``: the names a file's
    ``task`` may have (the registry's; None: any name)."""
    task = {"type": "string", "description": "the task the tree runs on (besman tasks lists them)"}
    if tasks is not None:
        task["enum"] = list(tasks)
    include = {
        "type": "object",
        "description": "another tree file's root here, its keys renamed by remap",
        "properties": {
            "include": {"type": "string"},
            "remap": {"type": "object", "additionalProperties": {"type": "string"}},
        },
        "required": ["include"],
        "additionalProperties": False,
    }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCHEMA_ID,
        "title": "besman behaviour-tree file",
        "type": "object",
        "properties": {
            "besman_tree": {"const": FORMAT_VERSION},
            "task": task,
            "root": {"$ref": "#/$defs/node"},
        },
        "required": ["besman_tree", "root"],
        "additionalProperties": False,
        "$defs": {
            "node": {"oneOf": [include, *(_node_schema(n, spec) for n, spec in NODE_TYPES.items())]},
        },
    }
