"""The building blocks of a robot's pick and place (AILA's by default), each simulated on its own: reach,
carry and return.

Refining one block by policy search needs rollouts of that block only, from where the task stands when the
block begins. :func:`prepare` gets there once per task tau with the planned (inverse-kinematics) motions of
the blocks before it and keeps the simulation state; each :func:`rollout` restores that state, runs the
block's learned primitive moved to the block's planned end points (:func:`~besman.sim.primitives.shaped`),
then what decides the block's success, in full contact physics:

- ``reach`` (tau: object x, y): from the robot's home to above the box; then descend, close on the box and
  lift it. Success: the box is held and lifted 5 cm.
- ``carry`` (tau: object x, y, place x, y): the box in the hand, from above the table to above the place
  target; then set it down, release and retreat. Success: the box stands upright on the shelf within 2 cm
  of the target.
- ``return`` (tau: place x, y): from above the placed box back to the home configuration. Success: it
  arrives.

A rollout also measures the block's own motion - duration, hand path length, the hand's peak jerk, the
smallest joint-limit margin and the configurations in collision - and :class:`Reward` scores it.
:class:`BlockTask` evaluates batches of thetas like the other tasks (local processes or Ray).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from besman.robots.description import TabletopLayout
from besman.sim.arm import Arm
from besman.sim.evaluation import BatchedTask, Evaluation
from besman.sim.executor import Executor
from besman.sim.manipulation import (
    DEFAULT_PLAN,
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
from besman.sim.motions import FollowPrimitive, MotionStatus
from besman.sim.pick_place import LIFT_HEIGHT, pick_place_bounds, settle_and_measure, step_motion
from besman.sim.primitives import shaped
from besman.sim.world import DEFAULT_BOX, World, tabletop_world
from besman.skills import MovementPrimitive
from besman.skills.errors import InputError
from besman.skills.tasks import TaskBounds

# Each block's task parameters: the columns of the pick-and-place tau that move its end points.
BLOCK_PARAMETERS = {
    "reach": ("object_x", "object_y"),
    "carry": ("object_x", "object_y", "place_x", "place_y"),
    "return": ("place_x", "place_y"),
}
BLOCKS = tuple(BLOCK_PARAMETERS)
TIMEOUT = 15.0  # s of simulated time for one motion
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
PATH_STRIDE = 5  # control cycles between the hand positions that measure path length and jerk (100 Hz)
COLLISION_STRIDE = 10  # control cycles between the configurations checked for collisions


def block_bounds(block: str, robot: str | TabletopLayout = "aila") -> TaskBounds:
    """The box of a block's tau on ``robot`` (a name, folder or tabletop layout): its columns of the robot's
    pick-and-place bounds."""
    check_block(block)
    bounds = pick_place_bounds(robot)
    columns = [bounds.names.index(name) for name in BLOCK_PARAMETERS[block]]
    return TaskBounds(
        BLOCK_PARAMETERS[block],
        tuple(bounds.low[c] for c in columns),
        tuple(bounds.high[c] for c in columns),
    )


def full_tau(block: str, tau, robot: str | TabletopLayout = "aila") -> np.ndarray:
    """The pick-and-place tau of a block's tau; the parameters it does not use sit at the bounds' centre."""
    tau = block_bounds(block, robot).check(tau)[0]
    bounds = pick_place_bounds(robot)
    full = (np.asarray(bounds.low) + np.asarray(bounds.high)) / 2
    for value, name in zip(tau, BLOCK_PARAMETERS[block], strict=True):
        full[bounds.names.index(name)] = value
    return full


def check_block(block: str) -> None:
    if block not in BLOCK_PARAMETERS:
        raise InputError(f"unknown building block {block!r}; blocks: {', '.join(BLOCKS)}")


@dataclass(frozen=True)
class Reward:
    """How a rollout is scored: ``failure`` unless it succeeds, minus its costs - duration, hand path, the
    hand's peak jerk, how far the path comes closer to a joint limit than ``margin`` (a fraction of the
    range; or than its end points, which the block cannot choose) and configurations in collision. 1 s,
    1 m of path, 50 m/s^3 of peak jerk, 5 % of range below the margin and 2 colliding samples (40 ms of
    contact) each cost 0.05: a failure outweighs them all."""

    failure: float = -1.0
    per_second: float = 0.05
    per_metre: float = 0.05
    per_jerk: float = 1e-3  # per m/s^3
    margin: float = 0.1
    per_margin: float = 1.0  # per unit of range below the margin
    per_collision: float = 0.025

    def score(self, outcome: BlockOutcome) -> float:
        costs = (
            self.per_second * outcome.duration
            + self.per_metre * outcome.path_length
            + self.per_jerk * outcome.peak_jerk
            + self.per_margin * max(0.0, min(self.margin, outcome.end_margin) - outcome.limit_margin)
            + self.per_collision * outcome.collisions
        )
        return (0.0 if outcome.success else self.failure) - costs


@dataclass(frozen=True)
class BlockOutcome:
    """One rollout: whether the block succeeded (and why not), and its motion's measures."""

    success: bool
    message: str
    duration: float  # s of the block's own motion
    path_length: float  # m of the hand's path
    peak_jerk: float  # m/s^3, the hand's largest jerk
    limit_margin: (
        float  # smallest distance of a joint from a limit along the path, as a fraction of its range
    )
    end_margin: float  # the same at the block's start and end configurations
    collisions: int  # checked configurations (every 20 ms) in which the robot touches something
    placement_error: float | None = None  # m, for a carry that released the box


@dataclass(frozen=True, eq=False)
class BlockStart:
    """Where a block begins for one tau: the simulation state, the arm's configurations at the block's
    planned start and end, and the pick-and-place steps after it, each with its planned motions."""

    block: str
    state: np.ndarray
    start: np.ndarray
    goal: np.ndarray
    after: tuple[tuple[Step, PickMotions | PlaceMotions], ...]
    place_xy: np.ndarray


def snapshot(world: World) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(world.model, STATE))
    mujoco.mj_getState(world.model, world.data, state, STATE)
    return state


def restore(world: World, state: np.ndarray) -> None:
    mujoco.mj_setState(world.model, world.data, state, STATE)
    mujoco.mj_forward(world.model, world.data)


def _run(executor: Executor, steps, planned, what: str) -> None:
    """Runs pick-and-place ``steps`` with their ``planned`` motions; a failure is a planning error (the
    planned motions before a block must work for the block to be tried)."""
    for step in steps:
        motion = executor.run(step_motion(step, planned, DEFAULT_BOX.name), timeout=TIMEOUT)
        if motion.status is not MotionStatus.SUCCEEDED:
            raise PlanningError(f"the planned {what} failed at {motion.name}: {motion.message}")


# The step of pick and place that a learned block replaces, in its half of the sequence.
REPLACED_STEPS = {"reach": (PICK_STEPS, "reach"), "carry": (PLACE_STEPS, "carry")}


def steps_after(block: str, planned: PickMotions | PlaceMotions) -> tuple:
    """The pick-and-place steps after the one ``block`` replaces ("reach" or "carry"), each with its
    ``planned`` motions: what runs after the block to judge it."""
    steps, name = REPLACED_STEPS[block]
    index = [step.name for step in steps].index(name)
    return tuple((step, planned) for step in steps[index + 1 :])


def prepare(world: World, block: str, tau, plan: PickPlacePlan = DEFAULT_PLAN) -> BlockStart:
    """Brings ``world`` to where ``block`` begins for its ``tau`` with the planned motions before it (from
    the robot's home) and plans the block's end points and what follows it. Raises
    :class:`~besman.sim.manipulation.PlanningError` if that cannot be done."""
    full = full_tau(block, tau, world.layout)
    object_xy, place_xy = full[:2], full[2:]
    item = DEFAULT_BOX
    world.reset()
    world.place_on(item.name, "table", *object_xy)
    executor = Executor(world)
    home = executor.position.copy()
    settings = executor.reference_settings
    pick = plan_pick(executor.arm, home, item, object_xy, plan, settings)
    _run(executor, PICK_STEPS[:1], pick, "opening")

    def start(goal, after) -> BlockStart:
        return BlockStart(
            block,
            snapshot(world),
            executor.position.copy(),
            goal,
            after,
            place_xy.copy(),
        )

    if block == "reach":  # it replaces the planned reach
        return start(pick.reach.dmp.goal.copy(), steps_after(block, pick))
    _run(executor, PICK_STEPS[1:], pick, "grasp")
    put = plan_place(executor.arm, pick.lifted, item, place_xy, plan, settings)
    if block == "carry":  # it replaces the planned carry
        return start(put.carry.dmp.goal.copy(), steps_after(block, put))
    _run(executor, PLACE_STEPS, put, "placement")
    return start(home, ())


def rollout(world: World, start: BlockStart, shape: MovementPrimitive) -> BlockOutcome:
    """Runs the block from ``start`` with the joint-space primitive ``shape`` moved to the block's end
    points, then the planned motions after it; measures and judges it (see the module documentation)."""
    restore(world, start.state)
    executor = Executor(world)
    arm, item = executor.arm, DEFAULT_BOX
    primitive = shaped(shape, start.block, executor.position, start.goal, arm)
    began = executor.time
    motion = FollowPrimitive(primitive)
    try:
        executor.run(motion, timeout=TIMEOUT)
    except ValueError as error:  # a primitive that cannot start (e.g. of the wrong size)
        motion.finish(MotionStatus.FAILED, str(error))
    # The block's own cycles: up to the one that decided it (a failure's chunk may have run on).
    cycles = motion.ended
    commanded = executor.log.positions[:cycles].copy()
    allowed = (item.name,) if start.block == "carry" else ()
    measures = dict(
        duration=(executor.log.times[cycles - 1] if cycles else began) - began,
        **hand_measures(arm, commanded, executor.config.control_period),
        limit_margin=arm.limit_margin(commanded) if len(commanded) else 0.0,
        end_margin=arm.limit_margin(np.array([start.start, start.goal])),
        collisions=sum(bool(arm.collisions(q, allowed)) for q in commanded[::COLLISION_STRIDE]),
    )
    if motion.status is not MotionStatus.SUCCEEDED:
        return BlockOutcome(False, f"{start.block}: {motion.message}", **measures)
    if start.block == "carry" and not executor.hand.holds(item.name):
        return BlockOutcome(False, "carry: the box slipped out of the hand", **measures)
    resting = world.surface("table").height + item.half_height
    for step, planned in start.after:
        motion = executor.run(step_motion(step, planned, item.name), timeout=TIMEOUT)
        if motion.status is not MotionStatus.SUCCEEDED:
            return BlockOutcome(False, f"{motion.name} after the {start.block}: {motion.message}", **measures)
    if start.block == "reach":
        lifted = world.object_pose(item.name).position[2] >= resting + LIFT_HEIGHT - 0.005
        if not (executor.hand.holds(item.name) and lifted):
            return BlockOutcome(False, "reach: the box was not grasped and lifted", **measures)
    if start.block == "carry":
        placed = settle_and_measure(world, item, start.place_xy)
        return BlockOutcome(
            placed.success, f"carry: {placed.message}", **measures, placement_error=placed.error
        )
    return BlockOutcome(True, f"{start.block}: succeeded", **measures)


def hand_measures(arm: Arm, commanded: np.ndarray, period: float) -> dict[str, float]:
    """Length (m) and peak jerk (m/s^3) of the hand's path along commanded configurations (one per
    control ``period``), from the hand positions every :data:`PATH_STRIDE` cycles."""
    if len(commanded) < 4 * PATH_STRIDE:
        return {"path_length": 0.0, "peak_jerk": 0.0}
    path = arm.site_path(commanded[::PATH_STRIDE])
    step = PATH_STRIDE * period
    jerk = np.diff(path, 3, axis=0) / step**3
    return {
        "path_length": float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()),
        "peak_jerk": float(np.linalg.norm(jerk, axis=1).max()),
    }


@dataclass(frozen=True)
class BlockTaskConfig:
    """A block's refinement task: the block, its learned joint-space primitive (a primitive file, so that
    worker processes can load it) and the reward."""

    block: str
    shape: str
    reward: Reward = Reward()
    robot: str = "aila"

    def build(self) -> BlockTask:
        return BlockTask(self)


class BlockTask(BatchedTask):
    """Rollouts of one block for thetas of its primitive (the weights matter: the end points are planned
    per tau) in block taus; rewards by :class:`Reward`, details :class:`BlockOutcome`."""

    def __init__(self, config: BlockTaskConfig) -> None:
        check_block(config.block)
        self.config = config
        self.bounds = block_bounds(config.block, config.robot)
        self.shape = MovementPrimitive.load(config.shape)
        self.world = tabletop_world(robot=config.robot)
        self._starts: dict[tuple[float, ...], BlockStart] = {}

    def start(self, tau) -> BlockStart:
        """The block's start for ``tau`` (prepared once, then kept)."""
        key = tuple(float(v) for v in self.bounds.check(tau)[0])
        if key not in self._starts:
            self._starts[key] = prepare(self.world, self.config.block, key)
        return self._starts[key]

    @property
    def n_params(self) -> int:
        return self.shape.theta.size

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        details = []
        for theta, tau in zip(thetas, taus, strict=True):
            self.shape.dmp.set_params(theta)
            details.append(rollout(self.world, self.start(tau), self.shape))
        return Evaluation(np.array([self.config.reward.score(d) for d in details]), tuple(details))
