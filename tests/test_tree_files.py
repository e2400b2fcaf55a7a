"""Tree files: precise errors before anything runs, includes with remapping, round trips."""

import textwrap
from pathlib import Path

import py_trees
import pytest

from besman.skills import DMP, MovementPrimitive
from besman.trees import (
    TreeFileError,
    describe,
    dump_tree,
    grasp,
    grasp_then_place,
    load_tree,
    loads_tree,
    place,
)

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "trees"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text).lstrip())
    return path


def test_the_example_loads_with_its_includes():
    root = load_tree(EXAMPLES / "grasp_then_place.yaml")
    described = describe(root)
    place = described["Retry"]["child"]["Sequence"]["children"][1]["Place"]
    assert place["target"] == "/task/place", "the included subtree reads the run's place target"
    grasp = described["Retry"]["child"]["Sequence"]["children"][0]["Selector"]["children"][1]
    assert grasp["Grasp"]["attempts"] == 2


@pytest.mark.parametrize("name", ["grasp_then_place.yaml", "grasp.yaml", "place.yaml"])
def test_valid_files_round_trip_to_the_same_tree(name):
    root = load_tree(EXAMPLES / name)
    again = loads_tree(dump_tree(root), base=EXAMPLES)
    assert describe(again) == describe(root)
    assert dump_tree(again) == dump_tree(root)


def test_subtrees_built_in_code_are_written_as_the_nodes_they_declare():
    root = py_trees.composites.Sequence(
        "hand over",
        memory=True,
        children=[
            grasp("take", object="bar", remap={"reach": "/shared/reach"}, arm="left", offset=[0.0, -0.08]),
            place("put", object="bar", target="/task/place", arm="left"),
            grasp_then_place(attempts=4),
        ],
    )
    take, put, both = describe(root)["Sequence"]["children"]
    assert take == {
        "Grasp": {
            "name": "take",
            "object": "bar",
            "namespace": "grasp",
            "attempts": 2,
            "remap": {"reach": "/shared/reach"},
            "arm": "left",
            "offset": [0.0, -0.08],
        }
    }
    assert put == {
        "Place": {
            "name": "put",
            "object": "bar",
            "namespace": "place",
            "target": "/task/place",
            "arm": "left",
        }
    }
    assert both == {
        "GraspThenPlace": {
            "name": "grasp then place",
            "object": "box",
            "target": "/task/place",
            "attempts": 4,
        }
    }
    assert dump_tree(loads_tree(dump_tree(root))) == dump_tree(root)


def test_primitives_are_referenced_by_file_and_round_trip(tmp_path):
    MovementPrimitive(DMP(8, goal=0.1), "wave").save(tmp_path / "wave.json")
    path = write(
        tmp_path,
        "wave.yaml",
        """
        besman_tree: 1
        root:
          Sequence:
            name: greet
            children:
              - ExecutePrimitive: {name: wave, primitive: wave.json, timeout: 5}
              - Wait: {name: pause, duration: 0.5}
    """,
    )
    root = load_tree(path)
    leaf = root.children[0]
    assert leaf.primitive.name == "wave" and leaf.timeout == 5.0
    assert describe(loads_tree(dump_tree(root), base=tmp_path)) == describe(root)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            """
         besman_tree: 1
         root:
           Sequnce: {name: oops, children: [{Wait: {name: w, duration: 1}}]}
         """,
            r"bad.yaml:3: root: unknown node type 'Sequnce'; known: Sequence, Selector",
        ),
        (
            """
         besman_tree: 1
         root:
           Sequence:
             name: s
             children:
               - Wait: {name: w}
         """,
            r"bad.yaml:6: root.Sequence.children\[0\].Wait: missing parameter 'duration'",
        ),
        (
            """
         besman_tree: 1
         root:
           Sequence:
             name: s
             children:
               - Wait:
                   name: w
                   duration: soon
         """,
            r"bad.yaml:8: root.Sequence.children\[0\].Wait.duration: expected a number, got 'soon'",
        ),
        (
            """
         besman_tree: 1
         root:
           Retry: {name: r, attempts: 2.5, child: {Wait: {name: w, duration: 1}}}
         """,
            r"bad.yaml:3: root.Retry.attempts: expected an integer, got '2.5'",
        ),
        (
            """
         besman_tree: 1
         root:
           Wait: {name: w, duration: 1, color: red}
         """,
            r"bad.yaml:3: root.Wait.color: unknown parameter; Wait takes name, duration",
        ),
        (
            """
         besman_tree: 1
         root:
           Sequence:
             name: s
             children:
               - include: nowhere.yaml
         """,
            r"bad.yaml:6: root.Sequence.children\[0\].include: no such file .*nowhere.yaml",
        ),
        (
            """
         besman_tree: 1
         root:
           Gripper: {name: g, action: squeeze}
         """,
            r"bad.yaml:3: root.Gripper.action: must be one of open, close, got 'squeeze'",
        ),
        (
            """
         besman_tree: 1
         root:
           ExecutePrimitive: {name: e, primitive: missing.json}
         """,
            r"bad.yaml:3: root.ExecutePrimitive.primitive: .*missing.json: no such file",
        ),
        (
            """
         besman_tree: 2
         root:
           Wait: {name: w, duration: 1}
         """,
            r"bad.yaml:1: besman_tree: expected 1",
        ),
        (
            """
         besman_tree: 1
         root: [
         """,
            r"bad.yaml:\d+: not valid YAML",
        ),
        (
            """
         besman_tree: 1
         root:
           InstantiateSkillTemplate: {name: t, template: "nowhere:thing"}
         """,
            r"bad.yaml:3: root.InstantiateSkillTemplate.template: 'nowhere:thing': module 'nowhere' is not "
            r"allowed",
        ),
    ],
)
def test_every_problem_names_file_line_and_path(tmp_path, text, message):
    path = write(tmp_path, "bad.yaml", text)
    with pytest.raises(TreeFileError, match=message):
        load_tree(path)


def test_a_cycle_of_includes_is_reported(tmp_path):
    write(
        tmp_path,
        "a.yaml",
        """
        besman_tree: 1
        root:
          Sequence:
            name: a
            children:
              - include: b.yaml
    """,
    )
    write(
        tmp_path,
        "b.yaml",
        """
        besman_tree: 1
        root:
          include: a.yaml
    """,
    )
    with pytest.raises(TreeFileError, match=r"includes form a cycle: .*a.yaml -> .*b.yaml -> .*a.yaml"):
        load_tree(tmp_path / "a.yaml")


def test_a_missing_tree_file():
    with pytest.raises(TreeFileError, match=r"nothing\.yaml: no such file"):
        load_tree("nothing.yaml")


def test_templates_and_pools_are_referenced_by_module_attribute_of_an_allowed_module(tmp_path, monkeypatch):
    (tmp_path / "my_skills.py").write_text(
        textwrap.dedent("""
        from besman.skills import DMP, MovementPrimitive

        class Reach:
            def instantiate(self, tau):
                return MovementPrimitive(DMP(8, goal=0.1 * float(tau[0])), "reach")

        REACH = Reach()
        POOL = {"reach": REACH}
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    path = write(
        tmp_path,
        "skills.yaml",
        """
        besman_tree: 1
        root:
          Sequence:
            name: both
            children:
              - InstantiateSkillTemplate: {name: from pool, pool: "my_skills:POOL", template_name: reach}
              - InstantiateSkillTemplate: {name: direct, template: "my_skills:REACH", namespace: direct}
    """,
    )
    root = load_tree(path, allow_modules=["my_skills"])
    assert root.children[0].pool["reach"] is root.children[1].template
    again = loads_tree(dump_tree(root), base=tmp_path, allow_modules=["my_skills"])
    assert describe(again) == describe(root)
    bad = write(
        tmp_path,
        "bad.yaml",
        """
        besman_tree: 1
        root:
          InstantiateSkillTemplate: {name: t, pool: "my_skills:REACH", template_name: reach}
    """,
    )
    with pytest.raises(TreeFileError, match="is not a pool"):
        load_tree(bad, allow_modules=["my_skills"])


def test_an_include_remaps_the_keys_of_the_included_subtree(tmp_path):
    write(
        tmp_path,
        "sub.yaml",
        """
        besman_tree: 1
        root:
          Place: {name: place the box, object: box, namespace: place}
    """,
    )
    main_file = write(
        tmp_path,
        "main.yaml",
        """
        besman_tree: 1
        root:
          Sequence:
            name: main
            children:
              - include: sub.yaml
                remap: {/place/target: /task/place}
    """,
    )
    place = describe(load_tree(main_file))["Sequence"]["children"][0]["Place"]
    assert place["remap"] == {"target": "/task/place"}, "the include's remap reached the subtree"
