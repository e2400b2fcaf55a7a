"""Forward and inverse kinematics of the shipped robots."""

import math

import mujoco
import numpy as np
import pytest
from helpers import rotation_angle

import besman.robots as robots

# Gripper pointing down (approach axis -z), fingers closing along the world x axis.
DOWN = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])


@pytest.fixture(scope="module")
def aila():
    return robots.load("aila")


def test_forward_kinematics_agrees_with_mujoco(aila):
    data = aila.make_data()
    pose = robots.forward_kinematics(aila, data.qpos, "right_grasp")
    np.testing.assert_allclose(pose.position, data.site("right_grasp").xpos, atol=1e-12)
    np.testing.assert_allclose(pose.rotation, data.site("right_grasp").xmat.reshape(3, 3), atol=1e-12)
    assert np.linalg.norm(pose.quaternion) == pytest.approx(1.0)


def test_forward_kinematics_rejects_bad_configurations(aila):
    with pytest.raises(ValueError, match="shape"):
        robots.forward_kinematics(aila, np.zeros(3), "right_grasp")
    with pytest.raises(ValueError, match="NaN"):
        robots.forward_kinematics(aila, np.full(aila.model.nq, np.nan), "right_grasp")
    with pytest.raises(ValueError, match="no site 'nose'"):
        robots.forward_kinematics(aila, aila.model.qpos0, "nose")


def test_inverse_kinematics_keeps_no_robot_alive():
    """What a solve remembers about a robot (its joints' indices and limits) goes with the robot: a run per
    task in one process (a benchmark's hundreds) grew by a compiled model per run while a cache held on."""
    import gc
    import weakref

    robot = robots.load("aila")
    assert robots.solve_ik(robot, "right_arm", [0.5, -0.2, 0.9], DOWN).success
    alive = weakref.ref(robot)
    del robot
    gc.collect()
    assert alive() is None


def test_ik_reaches_a_grid_of_top_down_grasps_above_a_table(aila):
    """20 grasp poses over a table in front of the robot, gripper down: < 1 mm and < 1 degree."""
    arm = aila.group("right_arm")
    targets = [(x, y, 0.90) for x in (0.40, 0.45, 0.50, 0.55) for y in (-0.40, -0.30, -0.20, -0.10, 0.0)]
    for target in targets:
        result = robots.solve_ik(aila, "right_arm", target, DOWN)
        assert result.success, (target, result.message)
        assert np.all(result.qpos >= arm.lower) and np.all(result.qpos <= arm.upper)
        qpos = aila.model.key("home").qpos.copy()
        qpos[arm.qpos_indices] = result.qpos
        pose = robots.forward_kinematics(aila, qpos, "right_grasp")
        assert np.linalg.norm(pose.position - target) < 1e-3
        assert math.degrees(rotation_angle(pose.quaternion, DOWN)) < 1.0
        assert result.position_error == pytest.approx(np.linalg.norm(pose.position - target), abs=1e-9)


def test_ik_reports_an_unreachable_target_without_nans(aila):
    result = robots.solve_ik(aila, "right_arm", [3.5, -0.2, 1.0], DOWN)
    assert not result.success
    assert "unreachable" in result.message
    assert np.all(np.isfinite(result.qpos))
    assert result.position_error > 2.0
    arm = aila.group("right_arm")
    assert np.all(result.qpos >= arm.lower) and np.all(result.qpos <= arm.upper)


def test_ik_position_only_and_other_groups(aila):
    result = robots.solve_ik(aila, "left_arm", [0.5, 0.3, 1.0])
    assert result.success and result.orientation_error == 0.0
    pa10 = robots.load("pa10")
    result = robots.solve_ik(pa10, "arm", [0.6, 0.2, 0.8], [0, 1, 0, 0])
    assert result.success, result.message


def test_ik_restarts_follow_the_seed(aila):
    """Two iterations per attempt cannot reach the target, so the best of the random restarts is what comes
    back: the same seed gives the same configuration, another seed another one."""
    target = [0.45, -0.2, 0.9]

    def solve(seed):
        return robots.solve_ik(aila, "right_arm", target, DOWN, seed=seed, max_iterations=2, restarts=3)

    first, again, other = solve(5), solve(5), solve(6)
    assert not first.success
    np.testing.assert_array_equal(first.qpos, again.qpos)
    assert np.abs(first.qpos - other.qpos).max() > 0.1, "the restarts must come from the seed"
    home = robots.solve_ik(aila, "right_arm", target, DOWN, max_iterations=2, restarts=0).qpos
    assert np.abs(first.qpos - home).max() > 0.1, "a restart, not the first attempt, was the best"


def test_ik_keeps_the_other_joints_of_the_initial_configuration(aila):
    initial = aila.model.key("home").qpos.copy()
    torso = aila.group("torso")
    initial[torso.qpos_indices[1]] = 2.3  # crouch a little: the arm must compensate
    result = robots.solve_ik(aila, "right_arm", [0.45, -0.2, 0.9], DOWN, initial_qpos=initial)
    assert result.success
    qpos = initial.copy()
    qpos[aila.group("right_arm").qpos_indices] = result.qpos
    assert (
        np.linalg.norm(robots.forward_kinematics(aila, qpos, "right_grasp").position - [0.45, -0.2, 0.9])
        < 1e-3
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"position": [np.nan, 0, 1]}, "position must be 3 finite numbers"),
        ({"position": [0, 1]}, "position must be 3 finite numbers"),
        ({"quaternion": [0, 0, 0, 0]}, "zero-norm"),
        ({"quaternion": [1, 0, 0]}, "quaternion must be 4 finite numbers"),
        ({"group": "tail"}, "no joint group 'tail'"),
        ({"site": "nose"}, "no site 'nose'"),
        ({"initial_qpos": np.zeros(2)}, "initial_qpos must be"),
    ],
)
def test_ik_rejects_bad_input(aila, kwargs, message):
    arguments = {"group": "right_arm", "position": [0.5, -0.2, 0.9], "quaternion": DOWN} | kwargs
    group = arguments.pop("group")
    with pytest.raises((ValueError, KeyError), match=message):
        robots.solve_ik(aila, group, **arguments)


def test_site_pose_matches_data(aila):
    data = aila.make_data()
    pose = robots.site_pose(aila.model, data, "left_ft")
    expected = np.empty(4)
    mujoco.mju_mat2Quat(expected, data.site("left_ft").xmat)
    np.testing.assert_allclose(pose.quaternion, expected)
