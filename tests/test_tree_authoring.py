"""Authoring aids: the node reference, the JSON Schema of tree files, `besman tree check`, and the guide's
tutorial tree - each checked against the loader itself."""

from __future__ import annotations

import inspect
import json
import re
from pathlib import Path

import jsonschema
import pytest
import yaml
from helpers import run_cli

from besman.tasks import task_names
from besman.tasks.running import run
from besman.trees.files import TreeFileError, loads_tree
from besman.trees.idioms import grasp
from besman.trees.manipulation import PlanGrasp
from besman.trees.nodes import NODE_TYPES
from besman.trees.reference import markdown_reference, tree_schema

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples" / "trees").glob("*.yaml"))
GUIDE = ROOT / "docs" / "trees.md"

# Files the loader refuses, each for another reason the schema can see too.
BAD_FILES = {
    "unknown node type": "besman_tree: 1\nroot:\n  Sequenze: {name: s, children: [{Wait: {name: w}}]}\n",
    "missing name": "besman_tree: 1\nroot:\n  Wait: {duration: 1}\n",
    "unknown parameter": "besman_tree: 1\nroot:\n  Wait: {name: w, duration: 1, speed: 2}\n",
    "missing parameter": "besman_tree: 1\nroot:\n  Wait: {name: w}\n",
    "wrong kind": "besman_tree: 1\nroot:\n  Grasp: {name: g, attempts: two}\n",
    "out of range": "besman_tree: 1\nroot:\n  Grasp: {name: g, attempts: 0}\n",
    "not an allowed value": "besman_tree: 1\nroot:\n  Gripper: {name: g, action: grab}\n",
    "wrong list length": (  # a position is x, y[, yaw[, z]]
        "besman_tree: 1\nroot:\n  ObjectAt: {name: o, object: box, position: [1, 2, 3, 4, 5]}"
    ),
    "no children": "besman_tree: 1\nroot:\n  Sequence: {name: s, children: []}\n",
    "two types in a node": "besman_tree: 1\nroot:\n  Wait: {name: w, duration: 1}\n  Gripper: {name: g}\n",
    "wrong version": "besman_tree: 2\nroot:\n  Wait: {name: w, duration: 1}\n",
    "unknown top-level field": "besman_tree: 1\nroot:\n  Wait: {name: w, duration: 1}\nextra: 1\n",
    "include with other fields": "besman_tree: 1\nroot:\n  include: grasp.yaml\n  name: g\n",
}


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = tree_schema(task_names())  # as besman tree schema prints it: a file's task is a registry name
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_the_node_list_is_the_loaders_table(capsys):
    code, out, _ = run_cli(capsys, "tree", "nodes")
    assert code == 0
    assert [line.split(":")[0] for line in out.splitlines()] == list(NODE_TYPES)
    assert all(line.split(": ", 1)[1].strip() for line in out.splitlines())  # every type is described


def test_one_nodes_parameters_and_roles_come_from_its_code(capsys):
    code, out, _ = run_cli(capsys, "tree", "nodes", "Grasp", "--json")
    entry = json.loads(out)["Grasp"]
    signature = inspect.signature(grasp)
    assert entry["parameters"]["attempts"] == {
        "kind": "int",
        "required": False,
        "default": signature.parameters["attempts"].default,
        "range": ">= 1",
    }
    assert entry["parameters"]["object"]["default"] == signature.parameters["object"].default
    assert entry["parameters"]["refine_above"]["range"] == ">= 0"
    assert entry["blackboard"] == {role: access.name.lower() for role, access in PlanGrasp.roles.items()}
    code, _, err = run_cli(capsys, "tree", "nodes", "Grab")
    assert code == 2 and "unknown node type 'Grab'" in err and "Grasp" in err


def test_node_descriptions_read_as_text_without_the_docstrings_markup(capsys):
    """``besman tree nodes`` prints each node type's first docstring sentence as Sphinx would show it."""
    from besman.trees.reference import node_reference, plain

    descriptions = [entry["description"] for entry in node_reference().values()]
    assert not [text for text in descriptions if re.search(r"``|:\w+:`", text)]
    assert plain("``object`` at :data:`~a.b.LIMIT` (:meth:`~a.b.Target.read`, :class:`a.B`)") == (
        "object at LIMIT (Target.read(), a.B)"
    )
    code, out, _ = run_cli(capsys, "tree", "nodes")
    assert code == 0 and "TILT_LIMIT)" in out and "`" not in out


def test_the_guides_node_reference_is_the_generated_one(capsys):
    text = GUIDE.read_text()
    section = text.split("<!-- node-reference -->\n", 1)[1].split("<!-- end node-reference -->", 1)[0]
    assert section == markdown_reference()
    code, out, _ = run_cli(capsys, "tree", "nodes", "--markdown")
    assert code == 0 and out == markdown_reference() + "\n"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_file_validates_against_the_schema_and_passes_check(path, validator, capsys):
    assert list(validator.iter_errors(yaml.safe_load(path.read_text()))) == []
    code, out, _ = run_cli(capsys, "tree", "check", str(path))
    assert code == 0 and out == f"{path}: ok\n"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_file_is_shown_and_rendered(path, tmp_path, capsys):
    """A learned tree's pools name ``{robot}``: shown for the robot of its task unless --robot says."""
    code, out, err = run_cli(capsys, "tree", "show", str(path))
    assert code == 0 and err == "" and len(out.splitlines()) > 2, err
    code, out, err = run_cli(capsys, "tree", "render", str(path), "--out", str(tmp_path / "tree.dot"))
    assert code == 0 and (tmp_path / "tree.dot").read_text().startswith("digraph"), err


def test_a_learned_tree_is_shown_for_the_robot_asked_and_refused_for_one_without_its_pool(capsys):
    tree = str(ROOT / "examples" / "trees" / "stack_learned.yaml")
    code, out, err = run_cli(capsys, "tree", "show", tree, "--robot", "ur5e")
    assert code == 0 and "put the box on the stack" in out, err
    code, _, err = run_cli(capsys, "tree", "show", tree, "--robot", "pa10")
    assert code == 2 and "no pool directory" in err and "pick_place_pa10" in err


@pytest.mark.parametrize("reason", BAD_FILES)
def test_the_schema_refuses_what_the_loader_refuses(reason, validator):
    text = BAD_FILES[reason]
    with pytest.raises(TreeFileError):
        loads_tree(text, base=ROOT / "examples" / "trees")
    assert list(validator.iter_errors(yaml.safe_load(text))), reason


def test_check_prints_one_line_per_file_with_its_problems_line_and_fails(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(BAD_FILES["out of range"])
    good = EXAMPLES[0]
    code, out, _ = run_cli(capsys, "tree", "check", str(bad), str(good), str(tmp_path / "missing.yaml"))
    lines = out.splitlines()
    assert code == 1 and len(lines) == 3
    assert lines[0] == f"{bad}:3: root.Grasp.attempts: must be at least 1, got 0"
    assert lines[1] == f"{good}: ok"
    assert lines[2] == f"{tmp_path / 'missing.yaml'}: no such file"


def test_check_and_the_schema_refuse_a_task_the_registry_does_not_have(tmp_path, validator, capsys):
    text = "besman_tree: 1\ntask: nosuch\nroot:\n  Wait: {name: w, duration: 1}\n"
    path = tmp_path / "nosuch.yaml"
    path.write_text(text)
    code, out, _ = run_cli(capsys, "tree", "check", str(path))
    assert code == 1 and out.startswith(f"{path}:2: task: no task 'nosuch'; tasks: ") and "pick-place" in out
    assert list(validator.iter_errors(yaml.safe_load(text)))
    known = path.with_name("known.yaml")
    known.write_text(text.replace("nosuch", "pick-place"))
    assert run_cli(capsys, "tree", "check", str(known))[:2] == (0, f"{known}: ok\n")
    assert list(validator.iter_errors(yaml.safe_load(known.read_text()))) == []


def test_schema_prints_or_writes_json_and_refuses_a_bad_output(tmp_path, capsys):
    code, out, _ = run_cli(capsys, "tree", "schema")
    assert code == 0 and json.loads(out) == tree_schema(task_names())
    assert json.loads(out)["properties"]["task"]["enum"] == task_names()
    code, _, _ = run_cli(capsys, "tree", "schema", "--out", str(tmp_path / "tree.schema.json"))
    assert code == 0 and json.loads((tmp_path / "tree.schema.json").read_text()) == tree_schema(task_names())
    code, _, err = run_cli(capsys, "tree", "schema", "--out", str(tmp_path / "tree.txt"))
    assert code == 2 and "must end in .json" in err and not (tmp_path / "tree.txt").exists()


def test_the_guides_tutorial_tree_runs():
    block = re.search(r"<!-- tutorial-tree -->\n```yaml\n(.*?)```", GUIDE.read_text(), re.S).group(1)
    tree = loads_tree(block, base=ROOT / "examples" / "trees", source="grasp_hold_place.yaml")
    summary = run("pick-place", tree, values={"object": (0.55, -0.08, 0.0), "place": (0.54, -0.41, 0.0)})
    assert summary.status == "SUCCESS" and summary.success and summary.task == "pick-place"
    assert summary.measurements["placement_error_m"] < 0.02
