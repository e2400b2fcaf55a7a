"""The building blocks of the pick and place skills, each simulated on its own: reach, carry and return.

Refining one block by policy search needs rollouts of that block only, from where the task stands when the
block begins. :func:`prepare` gets there once per task tau with the planned (inverse-kinematics) motions of
the blocks before it and keeps the simulation state; each :func:`rollout` restores that state, runs the
block's learned primitive moved to the block's planned end points (:func:`~besman.sim.primitives.shaped`),
then what decides the block's success, in full contact physics:

- ``reach``: from the robot's home to above the object; then descend, close on it and lift it. Success:
  the object is held and lifted 5 cm (:func:`~besman.sim.outcomes.lifted`).
- ``carry``: the object in the hand, from above the table to above the place target; then set it down,
  release and retreat. Success: the task's rule (:func:`~besman.sim.outcomes.placement`, with the yaw).
- ``return``: from above the placed object back to the home configuration. Success: it arrives.

A block's template input (:func:`block_input`, named :data:`INPUT_NAMES`) is the hand's move over the block
in the robot's frame: where its end pose is from its start pose (x, y, z in m) and how far the hand turns
about the vertical (deg). The planned end points differ with the object's position, yaw, size and shape,
the place and the task, but a block's shape depends on them only through this move: so a template learned
in pick and place gives a reach or a carry in any task that moves the hand alike (a stack, a sort, a
handover), and the same template holds for every object of the family.

A rollout also measures the block's own motion - duration, hand path length, the hand's peak jerk, the
smallest joint-limit margin and the configurations in collision - and :class:`Reward` scores it.
Tasks learn these blocks (:mod:`besman.tasks.pick_place.blocks`: a batched task of rollouts for policy
search) and the learned grasp and place leaves refine them online (:mod:`besman.learning.search.online`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.sim.executor import Executor
from besman.sim.manipulation import PickMotions, PlaceMotions, PlanningError, hand_yaw, plan_pick, plan_place
from besman.sim.motions import FollowPrimitive, GripperMotion, Motion, MotionStatus
from besman.sim.outcomes import lifted, placement
from besman.sim.plans import DEFAULT_PLAN, PICK_STEPS, PLACE_STEPS, PickPlacePlan, Step, Target
from besman.sim.primitives import shaped
from besman.sim.world import World
from besman.skills import MovementPrimitive

BLOCKS = ("reach", "carry", "return")
INPUT_NAMES = ("hand_dx", "hand_dy", "hand_dz", "hand_turn")  # a block template's input: m, m, m, deg
TIMEOUT = 15.0  # s of simulated time for one motion
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
PATH_STRIDE = 5  # control cycles between the hand positions that measure path length and jerk (100 Hz)
COLLISION_STRIDE = 10  # control cycles between the configurations checked for collisions
OBJECT = "box"  # the object of pick and place's world, whatever its shape


def check_block(block: str) -> None:
    if block not in BLOCKS:
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
    place: np.ndarray  # the target (:meth:`~besman.sim.plans.Target.read`)


def snapshot(world: World) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(world.model, STATE))
    mujoco.mj_getState(world.model, world.data, state, STATE)
    return state


def restore(world: World, state: np.ndarray) -> None:
    mujoco.mj_setState(world.model, world.data, state, STATE)
    mujoco.mj_forward(world.model, world.data)


def step_motion(step: Step, planned: PickMotions | PlaceMotions, item: str) -> Motion:
    """The motion that runs a pick-and-place ``step``: the ``planned`` primitive it follows, or its gripper
    action on the object ``item``."""
    if step.move is not None:
        return FollowPrimitive(getattr(planned, step.move), step.name, item if step.guarded else None)
    closing = step.gripper == "close"
    return GripperMotion(step.name, opening=0.0 if closing else None, expect_grasp=closing, grasp_object=item)


def block_input(arm: Arm, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """A block's template input for its move from the configuration ``start`` to ``goal``: the hand's end
    position less its start position (m) and its turn about the vertical (deg, in [-180, 180))."""
    begin, end = arm.site_pose(start), arm.site_pose(goal)
    turn = np.degrees(hand_yaw(arm, goal) - hand_yaw(arm, start))
    return np.r_[end.position - begin.position, (turn + 180.0) % 360.0 - 180.0]


def _run(executor: Executor, steps, planned, what: str) -> None:
    """Runs pick-and-place ``steps`` with their ``planned`` motions; a failure is a planning error (the
    planned motions before a block must work for the block to be tried)."""
    for step in steps:
        motion = executor.run(step_motion(step, planned, OBJECT), timeout=TIMEOUT)
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


def prepare(world: World, block: str, where, place, plan: PickPlacePlan = DEFAULT_PLAN) -> BlockStart:
    """Brings ``world`` (with its object :data:`OBJECT`) to where ``block`` begins for the object standing
    at ``where`` (x, y in m, yaw in deg) and its target ``place`` (the same), with the planned motions
    before it (from the robot's home), and plans the block's end points and what follows it. Raises
    :class:`~besman.sim.manipulation.PlanningError` if that cannot be done."""
    check_block(block)
    where, place = np.asarray(where, dtype=float), np.asarray(place, dtype=float)
    item = world.objects[OBJECT]
    world.reset()
    world.place_on(item.name, "table", where[0], where[1], np.radians(where[2]))
    executor = Executor(world)
    home = executor.position.copy()
    settings = executor.reference_settings
    pick = plan_pick(
        executor.arm, home, item, where[:2], plan, settings, yaw=np.radians(where[2]), then=place
    )
    _run(executor, PICK_STEPS[:1], pick, "opening")

    def start(goal, after) -> BlockStart:
        return BlockStart(
            block,
            snapshot(world),
            executor.position.copy(),
            goal,
            after,
            place.copy(),
        )

    if block == "reach":  # it replaces the planned reach
        return start(pick.reach.dmp.goal.copy(), steps_after(block, pick))
    _run(executor, PICK_STEPS[1:], pick, "grasp")
    put = plan_place(executor.arm, pick.lifted, item, place, plan, settings)
    if block == "carry":  # it replaces the planned carry
        return start(put.carry.dmp.goal.copy(), steps_after(block, put))
    _run(executor, PLACE_STEPS, put, "placement")
    return start(home, ())


def rollout(world: World, start: BlockStart, shape: MovementPrimitive) -> BlockOutcome:
    """Runs the block from ``start`` with the joint-space primitive ``shape`` moved to the block's end
    points, then the planned motions after it; measures and judges it (see the module documentation)."""
    restore(world, start.state)
    executor = Executor(world)
    arm, item = executor.arm, world.objects[OBJECT]
    primitive = shaped(shape, start.block, executor.position, start.goal, arm)
    began = executor.time
    motion = FollowPrimitive(primitive)
    try:
        executor.run(motion, timeout=TIMEOUT)
    except ValueError as error:  # a primitive that cannot start (e.g. of the wrong size)
        motion.finish(MotionStatus.FAILED, str(error))
    # The block's own cycles: up to the one that decided it (a failure's chunk may have run on).
    allowed = (item.name,) if start.block == "carry" else ()
    measures = motion_measures(executor, 0, motion.ended, began, (start.start, start.goal), allowed)
    if motion.status is not MotionStatus.SUCCEEDED:
        return BlockOutcome(False, f"{start.block}: {motion.message}", **measures)
    if start.block == "carry" and not executor.hand.holds(item.name):
        return BlockOutcome(False, "carry: the object slipped out of the hand", **measures)
    for step, planned in start.after:
        motion = executor.run(step_motion(step, planned, item.name), timeout=TIMEOUT)
        if motion.status is not MotionStatus.SUCCEEDED:
            return BlockOutcome(False, f"{motion.name} after the {start.block}: {motion.message}", **measures)
    success, message, error = judge_block(world, executor.hand, start.block, start.place)
    return BlockOutcome(success, message, **measures, placement_error=error)


def motion_measures(
    executor: Executor, first: int, last: int, began: float, ends: tuple, allowed: tuple[str, ...]
) -> dict[str, float]:
    """The measures of :class:`BlockOutcome` of a block's motion: the executor's logged commands
    ``first`` to ``last`` (cycles), begun at time ``began``, between the configurations ``ends``; touching
    ``allowed`` objects is no collision."""
    arm = executor.arm
    commanded = executor.log.positions[first:last].copy()
    return dict(
        duration=(executor.log.times[last - 1] if last > first else began) - began,
        **hand_measures(arm, commanded, executor.config.control_period),
        limit_margin=arm.limit_margin(commanded) if len(commanded) else 0.0,
        end_margin=arm.limit_margin(np.array(ends)),
        collisions=sum(bool(arm.collisions(q, allowed)) for q in commanded[::COLLISION_STRIDE]),
    )


def judge_block(world: World, hand, block: str, place) -> tuple[bool, str, float | None]:
    """Whether ``block`` succeeded, once it and the steps after it ran: the reach, if the object is in
    ``hand`` and lifted; the carry, by the place skill's rule (:func:`~besman.sim.outcomes.placement`, the
    one pick and place's runs are judged by) against the target ``place``, with the placement
    error; the return, by arriving. Returns success, a message and the placement error (None but for the
    carry)."""
    if block == "reach" and not lifted(world, hand, OBJECT):
        return False, "reach: the object was not grasped and lifted", None
    if block == "carry":
        target = Target.read(place)
        placed = placement(world, OBJECT, target.xy, yaw=target.yaw)
        return placed.success, f"carry: {placed.message}", placed.error
    return True, f"{block}: succeeded", None


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
