"""Perturbed runs: perception errors, a push during the reach, and what the grasp does about them (a
guarded descent, rising clear and opening before it plans again), and the check that sees a fallen object."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from helpers import run_cli

from besman.core.errors import InputError
from besman.robots.kinematics import Pose
from besman.sim.block_simulation import step_motion
from besman.sim.executor import Executor
from besman.sim.manipulation import hand_yaw, plan_pick
from besman.sim.motions import MotionStatus
from besman.sim.objects import GraspableObject, yaw_of
from besman.sim.perturbations import Perception, Perturbations, push_free
from besman.sim.plans import DEFAULT_PLAN, PICK_STEPS
from besman.sim.world import tabletop_world
from besman.tasks.running import prepare

TREE = Path(__file__).resolve().parents[1] / "examples" / "trees" / "grasp_then_place.yaml"
UPRIGHT = Pose(np.array([0.5, -0.1, 0.83]), np.array([1.0, 0.0, 0.0, 0.0]))


def _looks(seed: int, count: int = 300) -> list[Pose]:
    perception = Perception(0.015, np.radians(5.0), np.random.default_rng(seed))
    return [perception.look(UPRIGHT, "box") for _ in range(count)]


def test_perception_errors_stay_within_their_bounds_and_the_seed_repeats_them():
    looks = _looks(3)
    offsets = np.array([look.position - UPRIGHT.position for look in looks])
    turns = np.degrees([yaw_of(look.rotation) for look in looks])
    assert np.linalg.norm(offsets[:, :2], axis=1).max() <= 0.015 and np.all(offsets[:, 2] == 0)
    assert np.abs(turns).max() <= 5.0 and np.abs(turns).max() > 4.0  # the whole range is drawn
    assert np.linalg.norm(offsets[:, :2], axis=1).max() > 0.013
    np.testing.assert_allclose([np.linalg.norm(look.quaternion) for look in looks], 1.0)
    again = _looks(3)
    assert all(np.array_equal(a.position, b.position) for a, b in zip(looks, again, strict=True))


def test_a_world_perceives_exactly_unless_a_run_perturbs_it():
    world = tabletop_world((GraspableObject("box", size=(0.03, 0.03, 0.03)),), "aila")
    world.place_on("box", "table", 0.55, -0.08, 0.3)
    exact = world.object_pose("box")
    assert np.array_equal(world.perceive("box").position, exact.position)
    world.perception = Perturbations().perception(np.random.default_rng(0))
    seen = world.perceive("box")
    assert 0 < np.linalg.norm(seen.position - exact.position) <= 0.015
    assert np.array_equal(world.perceived("box").position, seen.position)  # the latest look, not a new one


def _box_tilt(world) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(world.object_pose("box").rotation[2, 2])))))


def test_a_push_moves_the_object_once_half_way_through_the_reach():
    positions = []

    def watch(runner, _record):
        executor = runner.executor
        motion = executor.motion
        positions.append((motion.name if motion else None, executor.world.object_pose("box").position.copy()))

    prepared = prepare("pick-place", seed=4, perturb="push", observe=watch)
    shift = np.array(prepared.runner.run_info["perturbation"]["push"]["shift_m"])
    assert 0.01 <= np.linalg.norm(shift) <= 0.03
    summary = prepared.judge(prepared.runner.run())
    during = [position for name, position in positions if name == "reach"]
    jumps = np.linalg.norm(np.diff([p[:2] for p in during], axis=0), axis=1)
    assert np.sum(jumps > 0.005) == 1 and np.allclose(
        during[int(np.argmax(jumps)) + 1][:2] - during[int(np.argmax(jumps))][:2], shift, atol=2e-3
    )
    assert summary.success, summary.message  # the tree saw it (the descent or the grasp) and tried again


def test_a_guarded_descent_stops_where_the_hand_touches_an_object_it_did_not_expect():
    """The grasp planned 3 cm off the box across the fingers (a perception error beyond their clearance):
    the descent brakes as soon as a finger touches the box and fails at rest, with the reason, above where
    it would end, the box standing."""
    world = tabletop_world((GraspableObject("box", size=(0.03, 0.03, 0.03)),), "aila")
    world.place_on("box", "table", 0.55, -0.08)
    executor = Executor(world)
    arm = executor.arm
    item = world.objects["box"]
    planned = plan_pick(
        arm, executor.position, item, (0.55, -0.08), DEFAULT_PLAN, executor.reference_settings
    )
    across = hand_yaw(arm, planned.descend.dmp.goal)
    off = np.array([0.55, -0.08]) + 0.03 * np.array([np.cos(across), np.sin(across)])
    pick = plan_pick(arm, executor.position, item, off, DEFAULT_PLAN, executor.reference_settings)
    for step in PICK_STEPS[:3]:
        motion = executor.run(step_motion(step, pick, "box"), timeout=15.0)
        if step.name != "descend":
            assert motion.status is MotionStatus.SUCCEEDED, motion.message
    assert motion.status is MotionStatus.FAILED
    assert motion.message == "the robot touched box on the way: it is not where it was perceived"
    bottom = arm.site_pose(pick.descend.dmp.goal).position[2]
    assert arm.site_pose(executor.position).position[2] > bottom + 0.01
    assert np.abs(executor.velocity).max() < 1e-6, "it fails once it has braked to rest"
    assert _box_tilt(world) < 5.0


@dataclass
class _OffUntilClosed:
    """A perception that sees every object ``offset`` (m) off until the test zeroes it."""

    offset: np.ndarray
    seen: dict = field(default_factory=dict)

    def look(self, pose: Pose, name: str) -> Pose:
        self.seen[name] = type(pose)(pose.position + self.offset, pose.quaternion)
        return self.seen[name]

    def last(self, name: str) -> Pose | None:
        return self.seen.get(name)


@pytest.mark.parametrize("robot", ["ur5e", "aila"])
def test_a_retry_after_a_grasp_that_closed_on_nothing_rises_opens_and_grasps_again(robot):
    """The box perceived 8 cm beside where it is, until the fingers first close: they close on the air beside
    it (far enough that nothing touches it, so the same on every processor). The retry rises clear, opens
    before it plans (the grasp's checks would see the closed fingers where they come down open, and find no
    grasp), perceives again, reaches and succeeds."""
    perception = _OffUntilClosed(np.array([0.0, 0.08, 0.0]))
    motions = []

    def watch(runner, _record):
        motion = runner.executor.motion
        if motion is not None and (not motions or motions[-1] is not motion):
            motions.append(motion)
            if motion.name == "close":
                perception.offset = np.zeros(3)

    prepared = prepare("pick-place", robot=robot, observe=watch)
    prepared.runner.executor.world.perception = perception
    summary = prepared.judge(prepared.runner.run())
    assert summary.success, summary.message
    grasp = ["open", "reach", "descend", "close"]
    assert [motion.name for motion in motions] == [
        *grasp,
        "rise",
        *grasp,
        "lift",
        "carry",
        "place",
        "release",
        "retreat",
    ]
    assert motions[3].message == "the fingers closed on nothing"


def test_a_fallen_object_at_its_target_is_not_placed():
    from py_trees.common import Status

    from besman.trees.conditions import ObjectAt

    world = tabletop_world((GraspableObject("box", size=(0.03, 0.02, 0.03)),), "aila")
    executor = Executor(world)
    shelf = world.surface("shelf")
    lying = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # turned 90 deg about x
    world.set_object_pose("box", [0.54, -0.41, shelf.height + 0.02], lying)
    check = ObjectAt("placed?", object="box", position=(0.54, -0.41))
    check.setup(executor=executor)
    assert check.update() is Status.FAILURE
    assert "fallen over" in check.feedback_message


def test_perturbing_needs_a_seed_and_a_task_that_declares_perturbations(capsys):
    code, _, err = run_cli(capsys, "run", str(TREE), "--perturb", "push")
    assert code != 0 and "draws its perturbations with its seed: give --seed" in err
    with pytest.raises(InputError, match="declares no perturbations"):
        prepare("throwing", seed=1, perturb="push")
    with pytest.raises(InputError, match="perturb must be one of perception, push"):
        prepare("pick-place", seed=1, perturb="wind")


@pytest.mark.parametrize(
    ("gap", "share"),
    [(0.05, 1.0), (0.02, 0.5), (0.01, 0.25), (0.005, 0.0)],  # m between the 6 cm boxes before a 3 cm push
)
def test_a_push_moves_the_object_only_as_far_as_it_is_free(gap, share):
    """A push toward another object stops short of overlapping it (pushed into it, the contact's force would
    throw the object out of the simulation); where no share of it is free, the object stays, at its speed."""
    box, other = GraspableObject("box", size=(0.03,) * 3), GraspableObject("other", size=(0.03,) * 3)
    world = tabletop_world((box, other))
    world.place_on("box", "table", 0.5, 0.0)
    world.place_on("other", "table", 0.5 + 0.06 + gap, 0.0)
    before = world.object_pose("box").position
    assert push_free(world, "box", (0.03, 0.0)) == share
    moved = world.object_pose("box").position - before
    assert moved[0] == pytest.approx(0.03 * share, abs=1e-9) and abs(moved[1]) < 1e-9
    assert world.data.warning.number.sum() == 0
