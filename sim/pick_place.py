"""A robot picks a box from the table and places it on the shelf with its first arm (AILA: the right arm
and the waist).

tau = (object x, object y, place x, place y): where the box stands on the table and where it must end up
on the shelf board, inside :func:`pick_place_bounds` - the object and place areas of the robot's tabletop
layout. AILA's (:data:`PICK_PLACE_BOUNDS`):

- object box: x in [0.45, 0.62] m, y in [-0.15, 0.00] m on the table (top 0.78 m), in front of the robot;
- place box: x in [0.45, 0.62] m, y in [-0.48, -0.34] m on the shelf board (top 0.90 m) to its right.

Both boxes lie where the right arm, turning the waist, reaches top-down grasps and the poses above them
with every joint at least 5 % of its range away from its limits for some grasp yaw (scanned on a grid).

The episode is the pick-and-place sequence (:data:`~besman.sim.manipulation.PICK_STEPS` and
``PLACE_STEPS``) of joint-space movement primitives planned by :mod:`besman.sim.manipulation` and executed
by the Ruckig executor: open the gripper, reach above the object, descend, close (a grasp is required),
lift, carry above the place, set down, release, retreat. theta tunes the plan
(:class:`~besman.sim.manipulation.PickPlacePlan`); ``default_theta()`` is the hand-made plan.

Success: the box was lifted at least 5 cm and carried in the hand until the release (not dropped), then
stands upright (tilt < 10 deg) on the shelf within 2 cm of the place target. Metrics per episode: placement
error, simulated time, largest contact force on the box, and which step failed and why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields

import mujoco
import numpy as np

import besman.robots as robots
from besman.robots.description import TabletopLayout
from besman.robots.robot import ROBOT
from besman.sim.evaluation import BatchedTask, Evaluation
from besman.sim.executor import Executor, limit_violations
from besman.sim.manipulation import (
    PICK_STEPS,
    PLACE_STEPS,
    PickMotions,
    PickPlacePlan,
    PlaceMotions,
    PlanningError,
    Step,
    plan_pick,
    plan_place,
)
from besman.sim.motions import FollowPrimitive, GripperMotion, Motion, MotionStatus
from besman.sim.world import DEFAULT_BOX, GraspableObject, World, tabletop_world
from besman.skills.errors import InputError
from besman.skills.tasks import TaskBounds
from besman.skills.validation import checked, instance


def pick_place_bounds(robot: str | TabletopLayout = "aila") -> TaskBounds:
    """The box of tau for ``robot`` (a name, a robot folder or its tabletop layout): its layout's object area
    (table) and place area (shelf)."""
    layout = robot if isinstance(robot, TabletopLayout) else robots.describe(robot).tabletop
    if layout is None:
        raise InputError(f"robot {robot!r} has no tabletop layout: it cannot pick and place")
    (ox, oy), (px, py) = layout.objects, layout.places
    return TaskBounds(
        ("object_x", "object_y", "place_x", "place_y"),
        (ox[0], oy[0], px[0], py[0]),
        (ox[1], oy[1], px[1], py[1]),
    )


PICK_PLACE_BOUNDS = pick_place_bounds("aila")
FAILURE_REWARD = -1.0
LIFT_HEIGHT = 0.05  # m the box must rise above its resting height for a grasp to count


@dataclass(frozen=True)
class PickPlaceDetail:
    """One episode's outcome and metrics."""

    success: bool
    grasped: bool  # the box was grasped and lifted
    placement_error: float | None  # m, horizontal distance of the box from the place target after release
    tilt_degrees: float | None
    sim_time: float
    max_contact_force: float  # N, largest normal force on the box
    failed_step: str | None
    message: str
    limit_violations: tuple[str, ...] = ()  # commanded joint states beyond a limit (from the command log)


@checked(item=instance(GraspableObject, "a GraspableObject"), robot=ROBOT)
@dataclass(frozen=True)
class PickPlaceConfig:
    """Everything that defines the task; ``build()`` makes it (also on Ray workers)."""

    item: GraspableObject = DEFAULT_BOX
    robot: str = "aila"

    def build(self) -> PickPlaceTask:
        return PickPlaceTask(self)


class PickPlaceTask(BatchedTask):
    """The pick-and-place task; see the module documentation. ``evaluate(thetas (N, 6), taus (N, 4))``:
    reward = -placement error (m) on success, else -1; details are :class:`PickPlaceDetail`; the episodes
    run in worker processes (the control loop is Python: threads would wait on each other)."""

    @checked(config=instance(PickPlaceConfig, "a PickPlaceConfig"))
    def __init__(self, config: PickPlaceConfig = PickPlaceConfig()) -> None:
        self.config = config
        self.bounds = pick_place_bounds(config.robot)
        self.world = tabletop_world((config.item,), config.robot)

    @staticmethod
    def default_theta() -> np.ndarray:
        return PickPlacePlan().theta()

    @property
    def n_params(self) -> int:
        return len(fields(PickPlacePlan))

    # -- one episode ---------------------------------------------------------------------------------------

    def episode(self, tau, theta=None, *, world: World | None = None) -> PickPlaceDetail:
        """Runs one pick-and-place episode in ``world`` (default: the task's own) and measures it."""
        tau = self.bounds.check(tau)[0]
        plan = PickPlacePlan.from_theta(self.default_theta() if theta is None else theta)
        return run_episode(world or self.world, self.config.item, tau, plan)

    def check_theta(self, theta: np.ndarray) -> None:
        PickPlacePlan.from_theta(theta)  # a plan outside its valid ranges is refused before any work

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        """The episodes one after the other in this process, in the task's own world."""
        details = tuple(
            run_episode(self.world, self.config.item, tau, PickPlacePlan.from_theta(theta))
            for theta, tau in zip(thetas, taus, strict=True)
        )
        rewards = np.array([-d.placement_error if d.success else FAILURE_REWARD for d in details])
        return Evaluation(rewards, details)


def step_motion(step: Step, planned: PickMotions | PlaceMotions, item: str) -> Motion:
    """The motion that runs a pick-and-place ``step``: the ``planned`` primitive it follows, or its gripper
    action on the object ``item``."""
    if step.move is not None:
        return FollowPrimitive(getattr(planned, step.move), name=step.name)
    closing = step.gripper == "close"
    return GripperMotion(step.name, opening=0.0 if closing else None, expect_grasp=closing, grasp_object=item)


def run_episode(world: World, item: GraspableObject, tau: np.ndarray, plan: PickPlacePlan) -> PickPlaceDetail:
    """Resets ``world``, places the box at tau's object position, plans and runs the scripted sequence."""
    world.reset()
    object_xy, place_xy = tau[:2], tau[2:]
    world.place_on(item.name, "table", *object_xy)
    executor = Executor(world)
    try:
        settings = executor.reference_settings
        pick = plan_pick(executor.arm, executor.position, item, object_xy, plan, settings)
        put = plan_place(executor.arm, pick.lifted, item, place_xy, plan, settings)
    except PlanningError as error:
        return _failure(world, "plan", str(error))
    monitor = _BoxMonitor(world, item.name, executor)
    lifted = world.surface("table").height + item.half_height + LIFT_HEIGHT
    for step, planned in [(step, pick) for step in PICK_STEPS] + [(step, put) for step in PLACE_STEPS]:
        # Primitives start where the previous motion left the robot.
        motion = executor.run(step_motion(step, planned, item.name), timeout=15.0, observe=monitor.update)
        if motion.status is not MotionStatus.SUCCEEDED:
            return _failure(world, step.name, motion.message, monitor)
        if (step.holding or step.name == "lift") and not executor.hand.holds(item.name):
            return _failure(world, step.name, "the box slipped out of the hand", monitor)
        if step.name == "lift":  # the grasp, checked
            if monitor.highest < lifted:
                return _failure(world, step.name, "the box was not lifted", monitor)
            monitor.grasped = True
    placed = settle_and_measure(world, item, place_xy, monitor.update)
    violations = tuple(limit_violations(executor.log, executor))
    return PickPlaceDetail(
        placed.success,
        True,
        placed.error,
        placed.tilt_degrees,
        float(world.data.time),
        monitor.max_force,
        None if placed.success else "place",
        placed.message,
        violations,
    )


@dataclass(frozen=True)
class Placement:
    """Where a released box came to rest: success (upright on the shelf within 2 cm of the target),
    horizontal error (m), tilt and a message."""

    success: bool
    error: float
    tilt_degrees: float
    message: str


SETTLE_TIME = 0.3  # s the box is left to settle after its release before it is measured
PLACE_TOLERANCE = 0.02  # m


def settle_and_measure(
    world: World, item: GraspableObject, place_xy, observe: Callable[[], None] | None = None
) -> Placement:
    """Lets the released ``item`` settle for :data:`SETTLE_TIME` (``observe`` after each step) and judges
    where it stands against the target ``place_xy``."""
    for _ in range(round(SETTLE_TIME / world.model.opt.timestep)):
        mujoco.mj_step(world.model, world.data)
        if observe is not None:
            observe()
    pose = world.object_pose(item.name)
    error = float(np.linalg.norm(pose.position[:2] - np.asarray(place_xy, dtype=float)))
    tilt = math.degrees(math.acos(min(1.0, abs(pose.rotation[2, 2]))))
    on_shelf = abs(pose.position[2] - (world.surface("shelf").height + item.half_height)) < 0.01
    success = bool(error <= PLACE_TOLERANCE and tilt < 10.0 and on_shelf)
    message = (
        "placed"
        if success
        else (
            f"placed {error * 100:.1f} cm from the target, tilted {tilt:.1f} deg"
            + ("" if on_shelf else ", off the shelf")
        )
    )
    return Placement(success, error, tilt, message)


class _BoxMonitor:
    """Tracks the box's highest point, the largest normal contact force on it, and whether it was grasped."""

    def __init__(self, world: World, name: str, executor: Executor) -> None:
        self.world, self.executor = world, executor
        self.grasped = False
        self.body = world.model.body(name).id
        self.highest = float(world.data.xpos[self.body][2])
        self.max_force = 0.0
        self._force = np.empty(6)

    def update(self) -> None:
        model, data = self.world.model, self.world.data
        self.highest = max(self.highest, float(data.xpos[self.body][2]))
        # Every control cycle: find the box's contacts in one vectorised pass, then measure only those.
        bodies = model.geom_bodyid[data.contact.geom]  # (ncon, 2)
        for i in np.flatnonzero((bodies == self.body).any(axis=1)):
            mujoco.mj_contactForce(model, data, int(i), self._force)
            self.max_force = max(self.max_force, float(self._force[0]))


def _failure(world: World, step: str, message: str, monitor: _BoxMonitor | None = None) -> PickPlaceDetail:
    time = float(world.data.time)
    if monitor is None:
        return PickPlaceDetail(False, False, None, None, time, 0.0, step, f"{step}: {message}")
    violations = tuple(limit_violations(monitor.executor.log, monitor.executor))
    return PickPlaceDetail(
        False, monitor.grasped, None, None, time, monitor.max_force, step, f"{step}: {message}", violations
    )
