"""``besman robots check``: each check provoked on a copy of the UR5e's or the WidowX AI's description
changed where a user's description goes wrong (or an inline model), its line naming what it measured and
what to change (every check passes on the WidowX as brought: tests/test_widowx.py)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import PINCER, install_plugin, pincer, run_cli

from besman.robots.catalogue import ROBOTS_DIR
from besman.tasks.robot_check import check_robot

WIDOWX = Path(__file__).resolve().parents[1] / "examples" / "robots" / "widowx_ai"
PAIR = WIDOWX.parent / "widowx_ai_pair"
UR5E_PLACES = {"x": [0.32, 0.49], "y": [-0.45, -0.31]}  # the task's numbers for the UR5e, given by the file


def ur5e_copy(tmp_path, name: str, change) -> str:
    folder = tmp_path / name
    shutil.copytree(ROBOTS_DIR / "ur5e", folder)
    raw = json.loads((folder / "description.json").read_text())
    raw["name"] = name
    raw["tasks"] = {"pick-place": {"places": UR5E_PLACES}}
    change(raw)
    (folder / "description.json").write_text(json.dumps(raw))
    return str(folder)


def tool_frame(raw, position, quaternion) -> None:
    """The tool frame as a new site on the gripper's base (Menagerie's pinch site is 0.145 m out)."""
    tcp = {"site": "tool", "body": "gripper/base", "position": position, "quaternion": quaternion}
    raw["arms"]["arm"]["tcp"] = tcp
    for group in raw["groups"].values():
        group.pop("site", None)


def findings(robot: str) -> dict:
    return {finding.check: finding for finding in check_robot(robot)}


def test_a_flipped_tool_frame_a_wrong_opening_table_slow_joints_and_a_far_area_are_each_named(tmp_path):
    def change(raw):
        tool_frame(raw, [0.0, 0.0, 0.145], [0.0, 1.0, 0.0, 0.0])  # z turned into the hand
        gripper = raw["arms"]["arm"]["gripper"]
        gripper["opening"], gripper["open"] = (
            [o * 0.8 for o in gripper["opening"]],
            0.032,
        )  # guessed 20 % short
        raw["velocity_feedforward"] = False  # the position actuators' damping then lags the joints
        raw["tabletop"]["table"]["x"] = [0.15, 1.4]
        raw["tabletop"]["reach"] = {"x": [1.1, 1.3], "y": [-0.1, 0.05]}  # beyond the arm's 0.85 m

    robot = ur5e_copy(tmp_path, "ur5e_faults", change)
    found = findings(robot)
    file = f"{robot}/description.json"
    home = found["home points the hand down"]
    assert not home.passed and "180 deg from straight down" in home.measured
    assert f"{file}: arms.arm.tcp" in home.fix
    tips = found["tool frame between the fingertips"]
    assert not tips.passed and "z axis points into the hand" in tips.fix
    table = found["opening table"]
    assert not table.passed and "commanded to open 32.0 mm per finger, the pads open 40.0" in table.measured
    assert "besman robots gripper" in table.fix and f"{file}: arms.arm.gripper" in table.fix
    limits = found["joints follow their limits"]
    assert (
        not limits.passed and "velocity limit of at most" in limits.fix and f"{file}: limits." in limits.fix
    )
    reach = found["reaches the object area top-down"]
    assert not reach.passed and "0 of its 5 corners and middle" in reach.measured
    assert f"{file}: tabletop" in reach.fix
    assert found["reaches the place area top-down"].passed
    pick = found["picks and places at the areas' middles"]
    assert not pick.passed and "reach failed" in pick.measured


def test_a_tool_frame_turned_and_short_of_the_fingertips_is_named_and_the_command_exits_1(tmp_path, capsys):
    half = 2**-0.5
    robot = ur5e_copy(tmp_path, "ur5e_short", lambda raw: tool_frame(raw, [0, 0, 0.07], [half, 0, 0, half]))
    code, out, _ = run_cli(capsys, "robots", "check", robot)
    assert code == 1 and out.strip().endswith("3 check(s) failed")
    lines = out.splitlines()
    turned = lines.index(next(line for line in lines if "tool frame's y axis along the closing" in line))
    assert lines[turned].startswith("FAIL arm: ") and "90 deg from the tool frame's y axis" in lines[turned]
    assert "turn the tool frame about its z axis" in lines[turned + 1]
    short = next(i for i, line in enumerate(lines) if "tool frame between the fingertips" in line)
    assert "the fingertips reach 79 mm past the tool frame (at most 40)" in lines[short]
    assert "move the tool frame 0.044 m further out along its z axis" in lines[short + 1]
    assert any(line.startswith("ok   arm: gripper moves both fingers") for line in lines)


def test_one_finger_driven_pads_that_miss_the_object_and_no_place_area_are_named(tmp_path):
    """The inline pincer with only its left finger's actuator named as the gripper's (the right one stays
    put) and the arm's link given as the right side's pads."""
    model = pincer(tmp_path, [0.0, 0.04], actuator="left_drive", pads=[["left_finger"], ["link1"]])
    named = PINCER.replace('<position joint="left"', '<position name="left_drive" joint="left"')
    (tmp_path / "pincer.xml").write_text(named)
    found = findings(model)
    areas = found["the task's areas"]
    assert not areas.passed and "tasks.pick-place.places" in areas.fix
    both = found["gripper moves both fingers"]
    assert not both.passed and both.measured.endswith(" and 0.0 mm")  # the right finger stays put
    assert "leave" in both.fix and "gripper.actuator out" in both.fix
    holds = found["pads close on the task's object"]
    assert not holds.passed and "the second side's pads do not" in holds.measured
    assert "reaches the object area top-down" not in found  # no area to reach


def test_a_grip_without_the_contact_options_that_hold_is_named(tmp_path):
    """The WidowX AI brought without its description's options (MuJoCo's pyramidal cones, impratio 1): the
    task's heaviest object creeps down between the pads, and nothing else is wrong."""
    folder = tmp_path / "loose_widowx"
    shutil.copytree(WIDOWX, folder)
    raw = json.loads((folder / "description.json").read_text())
    raw["name"], _ = "loose_widowx", raw.pop("options")
    (folder / "description.json").write_text(json.dumps(raw))
    found = findings(str(folder))
    held = found["holds the task's object up"]
    assert not held.passed and held.measured.startswith("0.30 kg, held for 1 s after 1 s to settle: it slid")
    assert "loose_widowx/description.json: options, e.g. impratio 10 and elliptic cones" in held.fix
    assert [check for check, f in found.items() if not f.passed] == ["holds the task's object up"]


def test_a_bar_that_turns_in_the_grip_without_the_no_slip_solver_is_named(tmp_path):
    """The two WidowX AI hold the handover's bar 10 cm from its middle: without MuJoCo's no-slip solver it
    keeps turning in the grip (2.8 deg/s, measured), with it it does not; the line says what to set."""
    from besman.sim.world import tabletop_world
    from besman.tasks.handover import BAR, BAR_TURN, holds_bar

    folder = tmp_path / "pair"
    shutil.copytree(PAIR, folder)
    raw = json.loads((folder / "description.json").read_text())
    del raw["options"]["noslip_iterations"]
    (folder / "description.json").write_text(json.dumps(raw))
    for robot, holds in ((str(PAIR), True), ("aila", True), (str(folder), False)):
        found = holds_bar(tabletop_world((BAR,), robot=robot), "left", 0.1, "FILE")
        assert found.passed is holds, (robot, found.measured)
    assert found.check == "holds the handover's bar by one end"
    turned = float(found.measured.split("turned ")[1].split(" deg")[0])
    assert turned > 2 * BAR_TURN and "held 10 cm from its middle" in found.measured
    assert "FILE: options.noslip_iterations" in found.fix and "tasks.handover.grip" in found.fix


def test_a_robot_without_a_tabletop_is_told_to_add_one(tmp_path):
    def change(raw):
        del raw["tabletop"], raw["tasks"]

    robot = ur5e_copy(tmp_path, "ur5e_no_table", change)
    sections, finding = check_robot(robot)
    assert sections.passed and sections.measured == "tasks: none"
    assert not finding.passed and finding.check == "the tabletop"
    assert f"add tabletop to {robot}/description.json" in finding.fix


@pytest.mark.parametrize(
    ("section", "told"),
    [("stak", "no task reads tasks.stak (did you mean stack?)"), ("sort", "no task reads tasks.sort")],
)
def test_a_task_section_no_task_reads_is_reported(tmp_path, section, told):
    def change(raw):
        raw["tasks"] = {section: {"spot": {"x": [0.4, 0.42], "y": [0.1, 0.12]}}}

    robot = ur5e_copy(tmp_path, "ur5e_misspelt", change)
    finding = next(check_robot(robot))
    assert (finding.check, finding.passed, finding.measured) == ("every task section is read", False, told)
    assert finding.fix.startswith(
        f"rename or remove it in {robot}/description.json; the sections tasks read: "
    )
    assert "stack (spot and starts: " in finding.fix and "pick-place (places: " in finding.fix


# A task plugin (docs/tasks.md) that declares a check of its own: the spot it wipes, on the pincer only.
WIPE = """
from besman.tasks.base import Task
from besman.tasks.robot_check import Finding


class Wipe(Task):
    name, title, randomised, success, robot = "wipe", "wipe the table", "nothing", "always", "aila"

    def fits(self, robot):
        return robot.name == "pincer"

    def robot_checks(self, robot, description):
        if self.fits(description):
            yield Finding("arm", "reaches the wiping spot", False, f"{description.name}: 2 cm short", "spot")


TASKS = (Wipe(),)
"""


def test_an_installed_tasks_own_check_is_run_after_the_arms_and_each_task_once(tmp_path):
    """``besman robots check`` runs the checks a plugin task declares (Task.robot_checks) after the arm and
    gripper checks; pick-place's own run once, though pick and place inherit them."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "besman_wipe.py").write_text(WIPE)
    install_plugin(site, "besman-wipe", "besman.tasks", "besman_wipe")
    robot = pincer(tmp_path, [[0.0, 0.04], [0.0, 0.04]])
    path = os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))
    result = subprocess.run(
        [sys.executable, "-m", "besman", "robots", "check", robot],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": path},
    )
    lines = result.stdout.splitlines()
    assert result.returncode == 1 and result.stderr == "", result.stderr
    assert lines[-1] == "3 check(s) failed"  # the pincer's grip slides; no place area; the plugin's spot
    wipe = lines.index("FAIL arm: reaches the wiping spot: pincer: 2 cm short")
    assert lines[wipe + 1] == "     to change: spot"
    assert wipe > next(i for i, line in enumerate(lines) if "joints follow their limits" in line)
    assert sum("the task's areas" in line for line in lines) == 1
