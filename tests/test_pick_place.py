"""AILA's scripted pick-and-place: real contact grasps, Ruckig-limited commands, measured placement."""

from dataclasses import replace

import numpy as np
import pytest

from besman.sim.arm import Arm
from besman.sim.manipulation import PickPlacePlan, grasp_yaws
from besman.sim.objects import GraspableObject, yaw_error, yaw_of
from besman.sim.world import tabletop_world
from besman.tasks import task as find_task
from besman.tasks.pick_place.episode import PickPlaceTask

PICK_PLACE_BOUNDS = find_task("pick-place").bounds("aila")
CUBE = (0.06, 0.06, 0.06)  # m: the 6 cm box of a run without a seed


def pick_place_tau(object_xy, place_xy, object_yaw=0.0, place_yaw=0.0, shape=0, size=CUBE) -> np.ndarray:
    """The task's tau (its bounds' columns in order): positions in m, yaws in deg, shape 0 a box, 1 a
    cylinder, size width, depth, height in m."""
    return np.array([*object_xy, object_yaw, *place_xy, place_yaw, shape, *size], dtype=float)


@pytest.fixture(scope="module")
def task():
    return PickPlaceTask()


def grid_taus():
    """3 x 3 object positions over the object box, each paired with one of 3 x 3 place positions."""

    def at(names, fractions):
        box = PICK_PLACE_BOUNDS.columns(names)
        return np.array(box.low) + (np.array(box.high) - np.array(box.low)) * np.array(fractions)

    fractions = [(a, b) for a in (0.0, 0.5, 1.0) for b in (0.0, 0.5, 1.0)]
    objects, places = ("object_x", "object_y"), ("place_x", "place_y")
    return [pick_place_tau(at(objects, (a, b)), at(places, (1 - b, a))) for a, b in fractions]


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
    tau = pick_place_tau((0.54, -0.08), (0.54, -0.41))
    detail = task.episode(tau)
    assert detail.success, detail.message
    world = task.world(tau)
    box = world.object_pose("box").position
    assert detail.placement_error == pytest.approx(np.linalg.norm(box[:2] - tau[3:5]))
    assert detail.sim_time == pytest.approx(world.data.time)


@pytest.mark.slow
def test_evaluate_runs_episodes_in_parallel_and_returns_rewards(task):
    taus = [pick_place_tau((0.5, -0.1), (0.5, -0.4)), pick_place_tau((0.6, -0.05), (0.58, -0.45))]
    result = task.evaluate(np.tile(task.default_theta(), (2, 1)), taus)
    assert all(d.success for d in result.details), [d.message for d in result.details]
    np.testing.assert_allclose(result.rewards, [-d.placement_error for d in result.details])


def test_a_box_standing_turned_is_set_down_at_the_places_yaw(task):
    """A 5 x 6.5 cm box (its yaw matters modulo 180 deg) standing at 37 deg ends within 5 deg of -120."""
    tau = pick_place_tau(
        (0.55, -0.08), (0.54, -0.41), object_yaw=37.0, place_yaw=-120.0, size=(0.05, 0.065, 0.06)
    )
    detail = task.episode(tau)
    assert detail.success, detail.message
    world = task.world(tau)
    turned = yaw_error(yaw_of(world.object_pose("box").rotation), np.radians(-120.0), world.objects["box"])
    assert np.degrees(turned) <= 5.0


def test_a_cylinder_standing_turned_is_placed(task):
    """The 6 cm cylinder standing at 37 deg, its place's yaw -120 deg: any yaw is that yaw for a cylinder,
    so the place's rule is the position's and the tilt's."""
    tau = pick_place_tau((0.55, -0.08), (0.54, -0.41), object_yaw=37.0, place_yaw=-120.0, shape=1, size=CUBE)
    detail = task.episode(tau)
    assert detail.success, detail.message
    assert task.world(tau).objects["box"].shape == "cylinder"


def test_a_box_is_grasped_only_across_the_side_the_open_gripper_fits():
    """A 5 x 6.5 cm box at 30 deg (5 cm along its x axis) in a gripper opening 6.9 cm: 5 cm plus the
    clearance on each side fits, 6.5 cm does not, so the fingers close along its x axis only: 30 and 210
    deg. The shipped gripper (9 cm) fits both sides: every square grasp."""
    arm = Arm(tabletop_world())
    box = GraspableObject("box", size=(0.025, 0.0325, 0.03))
    np.testing.assert_allclose(
        np.degrees(grasp_yaws(box, arm, np.radians(30.0))), [30.0, 120.0, 210.0, 300.0]
    )
    arm.gripper = replace(arm.gripper, open=0.0345)
    np.testing.assert_allclose(np.degrees(grasp_yaws(box, arm, np.radians(30.0))), [30.0, 210.0])


def test_a_cylinder_is_grasped_every_30_deg_when_the_open_gripper_fits_around_it():
    """A cylinder is as wide (its diameter) along every closing direction: a 6 cm one in the shipped 9 cm
    gripper at every grasp yaw, whatever its own yaw; one wider than the gripper allows at none."""
    arm = Arm(tabletop_world())
    cylinder = GraspableObject("box", "cylinder", size=(0.03, 0.03))
    np.testing.assert_allclose(
        np.degrees(grasp_yaws(cylinder, arm, np.radians(37.0))), np.arange(37, 397, 30)
    )
    assert grasp_yaws(GraspableObject("box", "cylinder", size=(0.042, 0.03)), arm).size == 0


def test_a_theta_that_carries_too_low_is_carried_higher_above_the_target(task):
    """With no clearance the carry would sweep the box over the shelf's edge; the planner ends it
    CARRY_RAISE higher above the target instead, and the box is placed."""
    from besman.sim.manipulation import CARRY_RAISE

    plan = PickPlacePlan(clearance=0.0)
    detail = task.episode(pick_place_tau((0.54, -0.08), (0.54, -0.41)), plan.theta())
    assert CARRY_RAISE > 0 and detail.success, detail.message
    assert detail.limit_violations == ()


@pytest.mark.parametrize(
    ("tau", "theta", "message"),
    [
        (
            pick_place_tau((0.3, -0.1), (0.5, -0.4)),
            None,
            r"tau object_x = 0.3 is outside the task's bounds \[0.45, 0.62\]",
        ),
        (
            pick_place_tau((0.5, -0.1), (0.5, -0.1)),
            None,
            r"tau place_y = -0.1 is outside the task's bounds \[-0.48, -0.34\]",
        ),
        (
            pick_place_tau((0.5, -0.1), (0.5, -0.4), place_yaw=200.0),
            None,
            r"tau place_yaw = 200 is outside the task's bounds \[-180, 180\]",
        ),
        (
            pick_place_tau((0.5, -0.1), (0.5, -0.4), size=(0.08, 0.06, 0.06)),
            None,
            r"tau object_width = 0.08 is outside the task's bounds \[0.04, 0.07\]",
        ),
        (pick_place_tau((0.5, -0.1), (0.5, -0.4))[:9], None, "tau must have 10 entries"),
        (pick_place_tau((0.5, -0.1), (0.5, -0.4)), np.zeros(3), "theta must have 6 entries"),
        (
            pick_place_tau((0.5, -0.1), (0.5, -0.4)),
            [0.1, 0.06, 0.0, 0.003, -2.0, 1.0],
            "outside the plan's valid ranges",
        ),
    ],
)
def test_bad_input_is_a_clear_value_error(task, tau, theta, message):
    with pytest.raises(ValueError, match=message):
        task.episode(tau, theta)
