"""A grasp that cannot be planned says which check failed, for which candidate, with its numbers, and what to
change in the robot's description: each cause is provoked on a shipped robot or a copy changed in one place
(the tool frame 7.5 cm above the UR5e's fingertips, AILA's wrist given a 0.2 rad range)."""

import json
import re
import shutil

import pytest

from besman.robots.catalogue import ROBOTS_DIR
from besman.sim.arm import Arm
from besman.sim.manipulation import plan_pick
from besman.sim.misses import PlanningError
from besman.sim.objects import GraspableObject
from besman.sim.plans import PickPlacePlan
from besman.sim.world import tabletop_world

CUBE = GraspableObject("box", size=(0.03, 0.03, 0.03))


def planning_error(robot: str, item: GraspableObject, xy) -> str:
    arm = Arm(tabletop_world((item,), robot=robot))
    with pytest.raises(PlanningError) as failed:
        plan_pick(arm, arm.home, item, xy, PickPlacePlan())
    return str(failed.value)


def copied(tmp_path, robot: str, name: str, change) -> str:
    """The shipped robot's folder copied under another name, its description changed by ``change``."""
    folder = tmp_path / name
    shutil.copytree(ROBOTS_DIR / robot, folder)
    raw = json.loads((folder / "description.json").read_text())
    raw["name"] = name
    change(raw, folder)
    (folder / "description.json").write_text(json.dumps(raw))
    return str(folder)


def test_an_object_out_of_reach_names_the_distance_and_the_reach_area():
    message = planning_error("ur5e", CUBE, (1.3, 0.0))
    assert "no top-down grasp of box at [1.3, 0.0]: reach failed" in message
    distance = float(re.search(r"the hand stays ([\d.]+) m", message).group(1))
    assert 0.2 < distance < 0.6  # the UR5e reaches about 0.85 m from its base
    assert "ur5e/description.json: tabletop.reach" in message and "mount" in message
    # Every candidate (hand yaw, approach height) failed one of the inverse-kinematics checks, counted.
    counts = re.search(r"checks failed over all candidates: (.*)\)$", message).group(1)
    tally = {check: int(n) for check, n in (part.rsplit(" ", 1) for part in counts.split(", "))}
    assert set(tally) <= {"reach", "joint limits"} and sum(tally.values()) >= 8


def test_an_object_wider_than_the_open_gripper_names_both_widths():
    wide = GraspableObject("box", size=(0.06, 0.06, 0.03))
    message = planning_error("ur5e", wide, (0.45, 0.0))
    assert "gripper width failed" in message
    assert "the object is 0.120 m across its narrowest grasp and needs 0.130 m" in message
    assert "they open 0.080 m" in message and "too narrow for the object" in message


def test_a_tool_frame_above_the_fingertips_names_the_table_and_how_far_to_move_it(tmp_path):
    def raise_tool_frame(raw, folder):  # 7.5 cm short of Menagerie's pinch site, 14.5 cm from the base
        raw["arms"]["arm"]["tcp"] = {"site": "tool", "body": "gripper/base", "position": [0.0, 0.0, 0.07]}
        for group in raw["groups"].values():
            group.pop("site", None)
        raw["tasks"] = {"pick-place": {"places": {"x": [0.32, 0.49], "y": [-0.45, -0.31]}}}

    robot = copied(tmp_path, "ur5e", "ur5e_high_tool", raise_tool_frame)
    message = planning_error(robot, CUBE, (0.45, 0.0))
    assert "collision failed; nearest candidate: where descend ends" in message
    assert "world/gripper/" in message and "(geoms table/" in message
    assert "the tool frame must sit between the fingertips" in message
    shift = float(re.search(r"arms\.arm\.tcp at least ([\d.]+) m further along its z axis", message).group(1))
    assert 0.03 < shift < 0.09
    assert "ur5e_high_tool/description.json: arms.arm.tcp" in message


def test_a_joint_limit_in_the_way_names_the_joints_at_their_limits(tmp_path):
    def stiffen_wrist(raw, folder):  # the model's own file: one joint's range -0.2 to 0 (was -1.57 to 0)
        model = folder / "aila.xml"
        wrist = r'(<joint name="J_Wrist1_r"[^>]*?)range="[^"]*"'
        xml, count = re.subn(wrist, r'\1range="-0.2 0"', model.read_text())
        assert count == 1
        model.write_text(xml)

    robot = copied(tmp_path, "aila", "aila_stiff_wrist", stiffen_wrist)
    arm = Arm(tabletop_world((CUBE,), robot=robot))
    xy = arm.world.object_pose("box").position[:2]
    message = planning_error(robot, CUBE, xy)
    assert "joint limits failed" in message
    assert "J_Wrist1_r at -0.19" in message and "(range -0.200 to +0.000)" in message
    assert "beyond their ranges" in message and "aila_stiff_wrist/description.json: tabletop.reach" in message
