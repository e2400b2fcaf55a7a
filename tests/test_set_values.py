"""``--set`` on the command line: numbers, or a choice's name for a task value with choices (``shape``),
passed to the task, which converts and checks them; the run's scene is built with what was set."""

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import py_trees
import pytest
from helpers import run_cli

from besman.cli import build_parser, commands, main
from besman.tasks.pick_place import PickPlace
from besman.tasks.running import prepare

TREE = Path(__file__).resolve().parents[1] / "examples" / "trees" / "grasp_then_place.yaml"
COMMANDS = [["run", str(TREE)], ["demo", "pick-place"]]


class _Built(Exception):
    """Ends a command once its scene is built: what it was built with is all a test needs."""


@pytest.mark.parametrize("command", COMMANDS)
def test_a_shape_set_by_name_reaches_the_scene(monkeypatch, command):
    built = []
    scene = PickPlace.scene

    def build(self, robot, values, seed):
        built.append(scene(self, robot, values, seed))
        raise _Built

    monkeypatch.setattr(PickPlace, "scene", build)
    sets = ["shape=cylinder", "size=0.05,0.04,0.07", "object=0.5,-0.1,30"]
    with pytest.raises(_Built):
        main([*command, *(arg for pair in sets for arg in ("--set", pair))])
    (made,) = built
    world = made.executor.world
    geom = world.model.geom("box")  # the task's object keeps its name, whatever its shape
    assert world.objects["box"].shape == "cylinder" and geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER
    np.testing.assert_allclose(geom.size[:2], (0.025, 0.035))  # radius, half height
    assert made.settings["shape"] == [1.0] and made.settings["size"] == [0.05, 0.05, 0.07]
    np.testing.assert_allclose(world.object_pose("box").position[:2], (0.5, -0.1))


@pytest.mark.parametrize("command", COMMANDS)
def test_an_unknown_shape_is_refused_with_the_choices_before_any_work(monkeypatch, capsys, command):
    def no_work(*_):
        raise AssertionError("the scene was built")

    monkeypatch.setattr(PickPlace, "scene", no_work)
    code, out, err = run_cli(capsys, *command, "--set", "shape=sphere")
    assert code == 2 and out == "" and "Traceback" not in err
    assert err.strip() == "besman: error: --set shape: 'sphere' is not one of box, cylinder"
    code, out, err = run_cli(capsys, *command, "--set", "shape=1.5")
    assert code == 2 and "--set shape: shape must be whole numbers" in err


def test_parsing_needs_neither_the_task_nor_the_simulation():
    code = (
        "import sys\n"
        "from besman.commands.trees import _parse_sets\n"
        "print(_parse_sets(['shape=cylinder', 'object=0.5, -0.1,30', 'size=a,b']))\n"
        "print([m for m in ('mujoco', 'numpy', 'besman.sim', 'besman.tasks') if m in sys.modules])\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    values, imported = result.stdout.splitlines()
    assert values == "{'shape': 'cylinder', 'object': (0.5, -0.1, 30.0), 'size': ('a', 'b')}"
    assert imported == "[]"


def test_the_help_says_yaws_are_in_degrees_and_a_shape_takes_a_name():
    found = {path: command for path, command in commands(build_parser())}
    for path in (("run",), ("demo",)):
        text = " ".join(found[path].format_help().split())
        assert "yaws in degrees" in text and "a name (e.g. shape=cylinder)" in text, path
    assert "yaws in degrees" in " ".join(found[("tasks",)].format_help().split())  # what show shows


def test_a_hand_pose_the_tree_reads_is_set_as_x_y_z_and_a_yaw_in_degrees(capsys):
    """``--set present=x,y,z[,yaw]`` sets the handover's hand pose as the tree reads it; a pose of two
    numbers is refused with what it takes, before the run."""
    prepare("handover", values={"present": [0.44, 0.06, 0.9, 90]})
    pose = py_trees.blackboard.Blackboard.get("/task/present")
    assert pose["position"] == [0.44, 0.06, 0.9] and pose["yaw"] == pytest.approx(np.pi / 2)
    prepare("handover", values={"present": [0.44, 0.06, 0.9]})
    assert py_trees.blackboard.Blackboard.get("/task/present")["yaw"] is None
    tree = TREE.parent / "handover.yaml"
    code, out, err = run_cli(capsys, "run", str(tree), "--set", "present=0.44,0.06")
    assert code == 2 and out == "" and "Traceback" not in err
    expected = "--set present: a hand pose, x, y, z in m and a yaw in degrees if it turns the hand; got "
    assert expected + "[0.44, 0.06]" in err
