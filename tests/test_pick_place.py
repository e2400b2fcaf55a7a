"""AILA's scripted pick-and-place: real contact grasps, Ruckig-limited commands, measured placement."""

import numpy as np
import pytest

from besman.sim.manipulation import PickPlacePlan
from besman.tasks import task as find_task
from besman.tasks.pick_place.episode import PickPlaceTask

PICK_PLACE_BOUNDS = find_task("pick-place").bounds("aila")


@pytest.fixture(scope="module")
def task():
    return PickPlaceTask()


def grid_taus():
    """3 x 3 object positions over the object box, each paired with one of 3 x 3 place positions."""
    low, high = np.array(PICK_PLACE_BOUNDS.low), np.array(PICK_PLACE_BOUNDS.high)
    fractions = [(a, b) for a in (0.0, 0.5, 1.0) for b in (0.0, 0.5, 1.0)]
    return [low + (high - low) * np.array([a, b, 1 - b, a]) for a, b in fractions]


@pytest.mark.slow
def test_scripted_primitives_grasp_and_place_over_both_boxes(task):
    """9 grasps spread over the object box and 9 placements over the place box: >= 17 of 18 succeed, with
    every commanded joint trajectory within the velocity, acceleration and jerk limits."""
    details = [task.episode(tau) for tau in grid_taus()]
    grasps = sum(d.grasped for d in details)
    places = sum(d.success for d in details)
    assert grasps + places >= 17, [d.message for d in details]
    for detail in details:
        assert detail.limit_violations == (), detail.limit_violations
        if detail.success:
            assert detail.placement_error < 0.02
            assert detail.tilt_degrees < 10
            assert 0.5 < detail.max_contact_force < 200.0, "a real pinch, not a crush"


def test_one_episode_is_measured_from_the_simulation(task):
    tau = np.array([0.54, -0.08, 0.54, -0.41])
    detail = task.episode(tau)
    assert detail.success, detail.message
    box = task.world.object_pose("box").position
    assert detail.placement_error == pytest.approx(np.linalg.norm(box[:2] - tau[2:]))
    assert detail.sim_time == pytest.approx(task.world.data.time)


@pytest.mark.slow
def test_evaluate_runs_episodes_in_parallel_and_returns_rewards(task):
    taus = [[0.5, -0.1, 0.5, -0.4], [0.6, -0.05, 0.58, -0.45]]
    result = task.evaluate(np.tile(task.default_theta(), (2, 1)), taus)
    assert all(d.success for d in result.details), [d.message for d in result.details]
    np.testing.assert_allclose(result.rewards, [-d.placement_error for d in result.details])


def test_a_theta_that_carries_too_low_fails_in_planning(task):
    plan = PickPlacePlan(clearance=0.0)
    detail = task.episode([0.54, -0.08, 0.54, -0.41], plan.theta())
    assert not detail.success
    assert detail.failed_step == "plan"
    assert "low over the shelf" in detail.message


@pytest.mark.parametrize(
    ("tau", "theta", "message"),
    [
        ([0.3, -0.1, 0.5, -0.4], None, r"tau object_x = 0.3 is outside the task's bounds \[0.45, 0.62\]"),
        ([0.5, -0.1, 0.5, -0.1], None, r"tau place_y = -0.1 is outside the task's bounds \[-0.48, -0.34\]"),
        ([0.5, -0.1, 0.5], None, "tau must have 4 entries"),
        ([0.5, -0.1, 0.5, -0.4], np.zeros(3), "theta must have 6 entries"),
        ([0.5, -0.1, 0.5, -0.4], [0.1, 0.06, 0.0, 0.003, -2.0, 1.0], "outside the plan's valid ranges"),
    ],
)
def test_bad_input_is_a_clear_value_error(task, tau, theta, message):
    with pytest.raises(ValueError, match=message):
        task.episode(tau, theta)
