"""Issue 52, fourth round: arms users bring and planner failures. Stack runs on a brought robot (its
description's ``tasks.stack`` section, or the corners of its reach); a command Ruckig refuses says which
arm, joint and input, with the numbers; sort's seed 1102 lifts its first box within the joints' ranges."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from besman.robots.fields import DescriptionError
from besman.tasks import task
from besman.tasks.running import run_demo

ROOT = Path(__file__).resolve().parents[1]
WIDOWX = ROOT / "examples" / "robots" / "widowx_ai"


def _widowx_with(tmp_path, **tasks) -> str:
    folder = tmp_path / "widowx_ai"
    shutil.copytree(WIDOWX, folder)
    description = json.loads((folder / "description.json").read_text())
    description["tasks"].update(tasks)
    (folder / "description.json").write_text(json.dumps(description))
    return str(folder)


def test_stack_fits_a_brought_robot_in_the_corners_of_its_reach():
    import besman.robots as robots

    stack = task("stack")
    assert stack.fits(robots.describe(str(WIDOWX)))
    bounds = stack.bounds(str(WIDOWX))
    # reach x 0.25-0.38, y -0.08..0.08; the shelf at -y: the spot in the far +x +y corner
    assert (bounds.low[:2], bounds.high[:2]) == ((0.36, 0.06), (0.38, 0.08))
    assert tuple(stack.bounds("aila").low[:2]) == (0.51, 0.09)  # the built-in robots keep their numbers


def test_stack_reads_a_brought_robots_own_section(tmp_path):
    layout = {
        "spot": {"x": [0.25, 0.27], "y": [0.06, 0.08]},
        "starts": [[0.38, 0.08], [0.25, -0.08], [0.38, -0.08]],
    }
    robot = _widowx_with(tmp_path, stack=layout)
    bounds = task("stack").bounds(robot)
    assert (bounds.low[:2], bounds.high[:2]) == ((0.25, 0.06), (0.27, 0.08))
    broken = _widowx_with(tmp_path / "broken", stack={"spot": layout["spot"], "starts": [[0.3, 0.0]]})
    with pytest.raises(DescriptionError, match=r"description.json: tasks.stack.starts: expected 3"):
        task("stack").bounds(broken)


@pytest.mark.slow
def test_the_stack_stands_on_a_brought_robot():
    summary = run_demo("stack", 1, robot=str(WIDOWX))
    assert summary.success, summary.outcome


def test_a_command_ruckig_refuses_names_the_arm_the_joint_and_the_input():
    """A target that is not a number reaches Ruckig as such (the range's clip keeps it): the motion fails
    naming the arm, the joint and the input, not with Ruckig's own result."""
    from besman.sim.executor import Executor
    from besman.sim.motions import MotionStatus, MoveTo
    from besman.sim.world import tabletop_world

    executor = Executor(tabletop_world())
    target = executor.position.copy()
    target[2] = np.nan
    motion = executor.run(MoveTo("broken", target=target))
    assert motion.status is MotionStatus.FAILED
    joint = executor.arm.joints[2]
    assert motion.message == (
        f"Ruckig could not compute a command for arm {executor.name!r}: joint {joint}'s target position is "
        "nan (not a number): the motion's target is broken"
    )


def test_a_brought_robot_whose_limits_ruckig_cannot_plan_with_is_told_which_and_why(tmp_path):
    """A velocity limit of 1e-12 rad/s passes the description's checks (finite, positive); Ruckig raised
    on the first command, and the user read only its result's name."""
    from besman.sim.executor import Executor
    from besman.sim.motions import MotionStatus, MoveTo
    from besman.sim.world import tabletop_world

    robot = _widowx_with(tmp_path)
    description = json.loads(Path(robot, "description.json").read_text())
    description["limits"]["joint_0"]["velocity"] = 1e-12
    Path(robot, "description.json").write_text(json.dumps(description))
    executor = Executor(tabletop_world(robot=robot))
    motion = executor.run(MoveTo("turn", target=executor.position + np.r_[0.1, np.zeros(5)]))
    assert motion.status is MotionStatus.FAILED
    assert motion.message == (
        "Ruckig could not compute a command for arm 'arm': joint joint_0's limits (velocity 1e-12, "
        "acceleration 6, jerk 60; rad or m, per s, s^2, s^3) make its move of 0.1 last at least 1e+11 s "
        "(Ruckig plans at most 7600 s): check the limits in the robot's description"
    )


def test_a_move_too_long_for_ruckig_names_the_joint_and_its_limits():
    """Limits in the wrong units (0.0001 rad/s) make a move longer than Ruckig computes: its Python binding
    raised a ValueError for the result (-101) it cannot name; now the stream refuses and says why."""
    from besman.sim.streaming import WORKING, JerkLimitedStream

    stream = JerkLimitedStream([-3, -3], [3, 3], [1.0, 1e-4], [1.0, 1.0], [1.0, 1.0], 0.002)
    stream.reset([0.0, 0.0])
    assert stream.track([0.1, 0.8], synchronize=False, minimum_duration=0.01) not in WORKING
    assert stream.refusal(["shoulder", "elbow"]) == (
        "joint elbow's limits (velocity 0.0001, acceleration 1, jerk 1; rad or m, per s, s^2, s^3) make its "
        "move of 0.8 last at least 8000 s (Ruckig plans at most 7600 s): check the limits in the robot's "
        "description"
    )


@pytest.mark.slow
def test_sort_seed_1102_lifts_its_first_box_within_the_joints_ranges():
    """The blue box at x 0.61 m: lifted to carrying height the right upper arm left its range by 0.075 rad
    (the lift failed, and the carry from the table then swept the shelf); a lower lift stays in range."""
    summary = run_demo("sort", 1102)
    assert summary.success, (summary.outcome, summary.first_failure)
