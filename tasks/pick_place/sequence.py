"""Pick and place as one sequence of learned blocks, for refining them together on whole-task rollouts.

A rollout runs the whole task the way the learned tree does (``POOL/tree.yaml``): the object perceived
(with the task's perception error), the grasp planned with the reach block's primitive and subgoals, the
pick steps (open, reach, descend guarded, close, lift), the place planned with the carry block's primitive
and subgoals, the place steps (carry, set down, release, retreat), then the return home with the return
block's primitive; the object may be pushed during the reach (:data:`~besman.tasks.pick_place.PERTURBATIONS`)
and its mass and friction are drawn from the family's ranges. Every rollout draws its own perturbations
from the seed in its tau, so the refinement meets the variety the skill must stand.

A block's parameters (:class:`SequenceRollouts`, per block in :data:`~besman.sim.block_simulation.BLOCKS`
order): the forcing weights of its primitive, then its subgoals (:data:`SUBGOALS`: the plan's numbers where it
hands over to the next block, as offsets from the default plan in units of :data:`SUBGOAL_SCALE`). Its cost:
its own motion's (duration, path, peak jerk, joint-limit margin, collisions:
:class:`~besman.sim.block_simulation.Reward`) and the failure's if the task failed in it: the reach where the
grasp fails (planning it, the pick steps, the lift), the carry where the place fails (planning it, the place
steps, the task's placement rule), the return where it does not arrive. A block after the one that failed did
not run: its cost is NaN.

tau: the pick-and-place tau, then the rollout's seed and whether the object is pushed (0 or 1).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from besman.core.moved import old_names
from besman.learning.pipeline.refinement import forcing_weights
from besman.sim.block_simulation import BLOCKS, OBJECT, BlockOutcome, Reward, motion_measures, step_motion
from besman.sim.evaluation import BatchedRollouts, Evaluation
from besman.sim.executor import Executor
from besman.sim.manipulation import PlanningError, plan_pick, plan_place
from besman.sim.motions import FollowPrimitive, MotionStatus
from besman.sim.objects import yaw_of
from besman.sim.outcomes import lifted, placement
from besman.sim.plans import (
    DEFAULT_PLAN,
    GRASP_SUBGOALS,
    PICK_STEPS,
    PLACE_STEPS,
    PLACE_SUBGOALS,
    PLAN_RANGES,
    PickPlacePlan,
)
from besman.sim.primitives import shaped
from besman.sim.world import World
from besman.skills import MovementPrimitive
from besman.skills.task_bounds import TaskBounds

SUBGOALS = {"reach": GRASP_SUBGOALS, "carry": PLACE_SUBGOALS, "return": ()}
# Plan units per unit of a subgoal parameter: an exploration of 0.1 (the forcing weights' spread) moves the
# heights by 1 cm (the release height by 2 mm) and the descent's time by 0.2 s.
SUBGOAL_SCALE = {
    "approach_height": 0.1,
    "grasp_height": 0.05,
    "descend_time": 2.0,
    "clearance": 0.1,
    "release_height": 0.02,
}
TIMEOUT = 15.0  # s of simulated time for one motion
SEED_RANGE = 2**31


def subgoal_plan(block: str, offsets) -> PickPlacePlan:
    """The default plan with ``block``'s subgoals moved by ``offsets`` (units of :data:`SUBGOAL_SCALE`),
    clipped to their valid ranges."""
    values = {
        name: float(np.clip(getattr(DEFAULT_PLAN, name) + SUBGOAL_SCALE[name] * offset, *PLAN_RANGES[name]))
        for name, offset in zip(SUBGOALS[block], offsets, strict=True)
    }
    return DEFAULT_PLAN.with_subgoals(**values)


@dataclass(frozen=True)
class SequenceOutcome:
    """One whole-task rollout: whether the task succeeded, the block that failed (None), the message, the
    cost of each block (NaN: it did not run) and each block's outcome (None where it could not be
    planned)."""

    success: bool
    failed_block: str | None
    message: str
    costs: tuple[float, ...]
    outcomes: tuple[BlockOutcome | None, ...] = field(default=())


@dataclass(frozen=True)
class SequenceConfig:
    """The whole-task rollouts of a pick-and-place sequence: the robot, each block's primitive file (in
    :data:`BLOCKS` order), the reward that prices a block's motion."""

    robot: str
    shapes: tuple[str, ...]
    reward: Reward = field(default_factory=Reward)

    def build(self) -> SequenceRollouts:
        return SequenceRollouts(self)


class SequenceRollouts(BatchedRollouts):
    """Whole-task rollouts for the blocks' parameters (see the module documentation); rewards are minus the
    total cost, details :class:`SequenceOutcome`."""

    def __init__(self, config: SequenceConfig) -> None:
        from besman.tasks import task

        self.config = config
        self.task = task("pick-place")
        task_bounds = self.task.bounds(config.robot)
        self.bounds = TaskBounds(
            (*task_bounds.names, "rollout_seed", "pushed"),
            (*task_bounds.low, 0, 0),
            (*task_bounds.high, SEED_RANGE - 1, 1),
        )
        self.shapes = [MovementPrimitive.load(path) for path in config.shapes]
        self.masks = [forcing_weights(shape) for shape in self.shapes]
        self.sizes = [
            int(mask.sum()) + len(SUBGOALS[block]) for mask, block in zip(self.masks, BLOCKS, strict=True)
        ]
        self._worlds: dict = {}

    @property
    def n_params(self) -> int:
        return sum(self.sizes)

    def split(self, theta: np.ndarray) -> list[np.ndarray]:
        """theta cut into the blocks' parameters."""
        return np.split(np.asarray(theta, dtype=float), np.cumsum(self.sizes)[:-1])

    def start(self) -> list[np.ndarray]:
        """The blocks' parameters at the shapes as they are and the default plan."""
        return [
            np.r_[shape.theta[mask], np.zeros(len(SUBGOALS[block]))]
            for shape, mask, block in zip(self.shapes, self.masks, BLOCKS, strict=True)
        ]

    def primitive_thetas(self, parts: list[np.ndarray]) -> list[np.ndarray]:
        """Each block's whole primitive theta for its parameters ``parts``: its shape's, with the forcing
        weights replaced."""
        thetas = []
        for shape, mask, part in zip(self.shapes, self.masks, parts, strict=True):
            theta = shape.theta.copy()
            theta[mask] = part[: mask.sum()]
            thetas.append(theta)
        return thetas

    def subgoals(self, parts: list[np.ndarray]) -> dict[str, dict[str, float]]:
        """Each block's subgoals (the plan's numbers) for its parameters ``parts``."""
        found = {}
        for block, mask, part in zip(BLOCKS, self.masks, parts, strict=True):
            plan = subgoal_plan(block, part[mask.sum() :])
            found[block] = {name: getattr(plan, name) for name in SUBGOALS[block]}
        return found

    def world(self, values) -> World:
        from besman.tasks.pick_place.scene import the_object

        item = the_object(self.config.robot, values, None)
        if item not in self._worlds:
            self._worlds[item] = self.task.world(self.config.robot, item)
        return self._worlds[item]

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        details = tuple(self.rollout(theta, tau) for theta, tau in zip(thetas, taus, strict=True))
        totals = [np.nansum(d.costs) for d in details]
        return Evaluation(-np.array(totals), details)

    def rollout(self, theta: np.ndarray, tau: np.ndarray) -> SequenceOutcome:
        parts = self.split(theta)
        primitives, plans = {}, {}
        thetas = self.primitive_thetas(parts)
        for block, shape, mask, part, full in zip(
            BLOCKS, self.shapes, self.masks, parts, thetas, strict=True
        ):
            primitive = copy.deepcopy(shape)
            primitive.dmp.set_params(full)
            primitives[block] = primitive
            plans[block] = subgoal_plan(block, part[mask.sum() :])
        values = self.task.split(tau[:-2])
        rng = np.random.default_rng(int(tau[-2]))
        return run_sequence(
            self.world(values), values, primitives, plans, rng, bool(tau[-1] > 0.5), self.config.reward
        )


def run_sequence(
    world: World,
    values: dict,
    primitives: dict[str, MovementPrimitive],
    plans: dict[str, PickPlacePlan],
    rng: np.random.Generator,
    pushed: bool,
    reward: Reward,
) -> SequenceOutcome:
    """One whole-task rollout in ``world`` for the task ``values``, the blocks' ``primitives`` and plans,
    perturbed by draws from ``rng`` (pushed if ``pushed``); see the module documentation."""
    from besman.tasks.pick_place.scene import PERTURBATIONS, family

    world.reset()
    item = world.objects[OBJECT]
    objects = family(world.robot.name)
    _set_properties(world, item.name, rng.uniform(*objects.mass), rng.uniform(*objects.friction))
    (x, y, yaw), place = values["object"], values["place"]
    world.place_on(item.name, "table", x, y, np.radians(yaw))
    world.perception = PERTURBATIONS.perception(rng)
    push = PERTURBATIONS.push_of(item.name, rng) if pushed else None
    executor = Executor(world)
    arm, settings = executor.arm, executor.reference_settings
    home = executor.position.copy()
    outcomes: list[BlockOutcome | None] = []

    def pushing() -> None:
        push(executor)

    observe = None if push is None else pushing  # cycle by cycle only while a push may come

    def block_done(block, measures, success, message, error=None):
        outcomes.append(BlockOutcome(success, message, **measures, placement_error=error))
        if success:
            return None
        costs = [-reward.score(o) for o in outcomes] + [np.nan] * (len(BLOCKS) - len(outcomes))
        return SequenceOutcome(False, block, message, tuple(costs), tuple(outcomes))

    def planning_failed(block, message):
        outcomes.append(None)
        costs = [-reward.score(o) for o in outcomes[:-1]] + [-reward.failure]
        costs += [np.nan] * (len(BLOCKS) - len(costs))
        return SequenceOutcome(False, block, f"{block}: {message}", tuple(costs), tuple(outcomes))

    # Reach: the grasp planned from what perception sees, then the pick steps.
    seen = world.perceive(item.name)
    try:
        pick = plan_pick(
            arm,
            home,
            item,
            seen.position,
            plans["reach"],
            settings,
            primitives["reach"],
            yaw_of(seen.rotation),
            place,
        )
    except PlanningError as error:
        return planning_failed("reach", str(error))
    ends = (home, pick.reach.dmp.goal)
    measures, message = _run_block(executor, PICK_STEPS, pick, item.name, "reach", observe, ends, ())
    ok = message is None and lifted(world, executor.hand, item.name)
    message = message or ("reach: succeeded" if ok else "reach: the object was not grasped and lifted")
    result = block_done("reach", measures, ok, message)
    if result is not None:
        return result
    # Carry: the place planned with the object as it is held, then the place steps and the rule.
    lifted_at = executor.position.copy()
    hand = arm.site_pose(arm.measured()).position
    held = world.object_pose(item.name).position[:2] - hand[:2]
    try:
        put = plan_place(arm, lifted_at, item, place, plans["carry"], settings, primitives["carry"], held)
    except PlanningError as error:
        return planning_failed("carry", str(error))
    ends = (lifted_at, put.carry.dmp.goal)
    measures, message = _run_block(executor, PLACE_STEPS, put, item.name, "carry", None, ends, (item.name,))
    error = None
    if message is None:
        placed = placement(world, item.name, place[:2], yaw=np.radians(place[2]))
        ok, message, error = placed.success, f"carry: {placed.message}", placed.error
    else:
        ok = False
    result = block_done("carry", measures, ok, message, error)
    if result is not None:
        return result
    # Return home from where the retreat left the arm.
    start = executor.position.copy()
    first, began = len(executor.log), executor.time
    motion = executor.run(FollowPrimitive(shaped(primitives["return"], "return", start, home, arm)), TIMEOUT)
    ok = motion.status is MotionStatus.SUCCEEDED
    message = "return: succeeded" if ok else f"return: {motion.message}"
    measures = motion_measures(executor, first, first + motion.ended, began, (start, home), ())
    result = block_done("return", measures, ok, message)
    if result is not None:
        return result
    costs = tuple(-reward.score(o) for o in outcomes)
    return SequenceOutcome(True, None, "placed and returned home", costs, tuple(outcomes))


def _run_block(executor: Executor, steps, planned, item: str, block: str, observe, ends, allowed):
    """Runs a block's pick-and-place ``steps``: the block's own motion (the step named ``block``) measured
    as soon as it ends (:func:`~besman.sim.block_simulation.motion_measures`, between the configurations
    ``ends``, touching ``allowed`` objects), then the steps that decide it. Returns the measures and the
    failure's message (None if every step succeeded and the object stayed in the hand where it must)."""
    first, began = len(executor.log), executor.time
    measures = motion_measures(executor, first, first, began, ends, allowed)  # if it never starts
    for step in steps:
        if step.move == block:
            first, began = len(executor.log), executor.time
        run = executor.run(step_motion(step, planned, item), TIMEOUT, observe=observe)
        if step.move == block:
            measures = motion_measures(executor, first, first + run.ended, began, ends, allowed)
        if run.status is not MotionStatus.SUCCEEDED:
            return measures, f"{block}: {run.name}: {run.message}"
        if (step.holding or step.name == "lift") and not executor.hand.holds(item):
            return measures, f"{block}: {run.name}: the object slipped out of the hand"
    return measures, None


def _set_properties(world: World, name: str, mass: float, friction: float) -> None:
    """The object's mass (its inertia scaled alike) and sliding friction."""
    model = world.model
    body = world.object_body(name)
    ratio = mass / model.body_mass[body]
    model.body_mass[body] = mass
    model.body_inertia[body] *= ratio
    model.geom_friction[model.body_geomadr[body], 0] = friction


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
