"""Pick and place as a scripted episode with numbers to tune: the task's batched evaluate for policy search.

theta tunes the plan (:class:`~besman.sim.plans.PickPlacePlan`: heights, clearances), tau is the
task's (:class:`~besman.tasks.pick_place.PickPlace`: object and place positions and yaws, shape, size; the
object's mass and friction the middles of their ranges). An episode runs the pick-and-place sequence
(:data:`~besman.sim.plans.PICK_STEPS` and ``PLACE_STEPS``) of joint-space movement primitives planned
by :mod:`besman.sim.manipulation` and executed by the Ruckig executor: open the gripper, reach above the
object, descend, close (a grasp is required), lift, carry above the place, set down, release, retreat;
``default_theta()`` is the hand-made plan. It is judged by the task's rule
(:mod:`besman.tasks.pick_place.rule`): reward = -placement error (m) on success, else -1. Metrics per
episode: placement error, simulated time, largest contact force on the box, and which step failed and why.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import mujoco
import numpy as np

from besman.core.moved import old_names
from besman.core.validation import checked, instance
from besman.robots.catalogue import ROBOT
from besman.sim.block_simulation import OBJECT, step_motion
from besman.sim.evaluation import BatchedRollouts, Evaluation
from besman.sim.executor import Executor, limit_violations
from besman.sim.manipulation import PlanningError, plan_pick, plan_place
from besman.sim.motions import MotionStatus
from besman.sim.objects import GraspableObject
from besman.sim.outcomes import lifted, placement
from besman.sim.plans import PICK_STEPS, PLACE_STEPS, PickPlacePlan
from besman.sim.world import World

FAILURE_REWARD = -1.0


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


@checked(robot=ROBOT)
@dataclass(frozen=True)
class PickPlaceConfig:
    """Everything that defines the task; ``build()`` makes it (also on Ray workers)."""

    robot: str = "aila"

    def build(self) -> PickPlaceRollouts:
        return PickPlaceRollouts(self)


class PickPlaceRollouts(BatchedRollouts):
    """The pick-and-place task; see the module documentation. ``evaluate(thetas (N, 6), taus (N, 10))``:
    reward = -placement error (m) on success, else -1; details are :class:`PickPlaceDetail`; the episodes
    run in worker processes (the control loop is Python: threads would wait on each other)."""

    @checked(config=instance(PickPlaceConfig, "a PickPlaceConfig"))
    def __init__(self, config: PickPlaceConfig = PickPlaceConfig()) -> None:
        from besman.tasks import task

        self.config = config
        self.task = task("pick-place")
        self.bounds = self.task.bounds(config.robot)
        self._worlds: dict[GraspableObject, World] = {}

    def world(self, tau) -> World:
        """A world with the object of ``tau`` (built once per object, then kept)."""
        from besman.tasks.pick_place.scene import the_object

        item = the_object(self.config.robot, self.task.split(tau), None)
        if item not in self._worlds:
            self._worlds[item] = self.task.world(self.config.robot, item)
        return self._worlds[item]

    @staticmethod
    def default_theta() -> np.ndarray:
        return PickPlacePlan().theta()

    @property
    def n_params(self) -> int:
        return len(fields(PickPlacePlan))

    # -- one episode ---------------------------------------------------------------------------------------

    def episode(self, tau, theta=None, *, world: World | None = None) -> PickPlaceDetail:
        """Runs one pick-and-place episode in ``world`` (default: one with tau's object) and measures it."""
        tau = self.bounds.check(tau)[0]
        plan = PickPlacePlan.from_theta(self.default_theta() if theta is None else theta)
        return run_episode(world or self.world(tau), self.task.split(tau), plan)

    def check_theta(self, theta: np.ndarray) -> None:
        PickPlacePlan.from_theta(theta)  # a plan outside its valid ranges is refused before any work

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        """The episodes one after the other in this process, in worlds with their taus' objects."""
        details = tuple(
            run_episode(self.world(tau), self.task.split(tau), PickPlacePlan.from_theta(theta))
            for theta, tau in zip(thetas, taus, strict=True)
        )
        rewards = np.array([-d.placement_error if d.success else FAILURE_REWARD for d in details])
        return Evaluation(rewards, details)


def run_episode(world: World, values: dict, plan: PickPlacePlan) -> PickPlaceDetail:
    """Resets ``world``, places its object where the task ``values`` say, plans and runs the scripted
    sequence."""
    world.reset()
    item = world.objects[OBJECT]
    (x, y, yaw), place = values["object"], values["place"]
    world.place_on(item.name, "table", x, y, np.radians(yaw))
    executor = Executor(world)
    settings = executor.reference_settings
    try:
        pick = plan_pick(
            executor.arm, executor.position, item, (x, y), plan, settings, yaw=np.radians(yaw), then=place
        )
    except PlanningError as error:
        return _failure(world, "plan", str(error))
    monitor = _BoxMonitor(world, item.name, executor)
    steps = [(step, pick) for step in PICK_STEPS] + [(step, None) for step in PLACE_STEPS]
    for step, planned in steps:
        if step is PLACE_STEPS[0]:  # planned with the object in the hand, as it was grasped
            try:
                put = plan_place(executor.arm, executor.position, item, place, plan, settings)
            except PlanningError as error:
                return _failure(world, "plan", str(error), monitor)
        planned = planned or put
        # Primitives start where the previous motion left the robot.
        motion = executor.run(step_motion(step, planned, item.name), timeout=15.0, observe=monitor.update)
        if motion.status is not MotionStatus.SUCCEEDED:
            return _failure(world, step.name, motion.message, monitor)
        if (step.holding or step.name == "lift") and not executor.hand.holds(item.name):
            return _failure(world, step.name, "the box slipped out of the hand", monitor)
        if step.name == "lift":  # the grasp, checked
            if not lifted(world, executor.hand, item.name):
                return _failure(world, step.name, "the box was not lifted", monitor)
            monitor.grasped = True
    placed = placement(world, item.name, place[:2], monitor.update, yaw=np.radians(place[2]))
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


class _BoxMonitor:
    """Tracks the largest normal contact force on the box, and whether it was grasped."""

    def __init__(self, world: World, name: str, executor: Executor) -> None:
        self.world, self.executor = world, executor
        self.grasped = False
        self.body = world.model.body(name).id
        self.max_force = 0.0
        self._force = np.empty(6)

    def update(self) -> None:
        model, data = self.world.model, self.world.data
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


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
