"""Pick and place's building blocks as learning takes them: reach, carry and return
(:mod:`besman.sim.blocks` simulates each on its own), their tau boxes on a robot, and rollouts of one block
for many thetas as a batched task for policy search (:class:`BlockTask`, local processes or Ray).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from besman.learning.blocks import BuildingBlocks
from besman.sim.blocks import (
    BLOCK_PARAMETERS,
    BLOCKS,
    BlockStart,
    Reward,
    check_block,
    prepare,
    restore,
    rollout,
)
from besman.sim.evaluation import BatchedTask, Evaluation
from besman.sim.executor import Executor
from besman.sim.world import World, tabletop_world
from besman.skills import MovementPrimitive
from besman.skills.tasks import TaskBounds


def block_bounds(block: str, robot: str = "aila") -> TaskBounds:
    """The box of a block's tau on ``robot``: its columns of the task's bounds."""
    from besman.tasks.pick_place import PickPlace

    check_block(block)
    return PickPlace().bounds(robot).columns(BLOCK_PARAMETERS[block])


def full_tau(block: str, tau, robot: str = "aila") -> np.ndarray:
    """The pick-and-place tau of a block's tau; the parameters it does not use sit at the bounds' centre."""
    from besman.tasks.pick_place import PickPlace

    check_block(block)
    bounds = PickPlace().bounds(robot)
    tau = bounds.columns(BLOCK_PARAMETERS[block]).check(tau)[0]
    full = (np.asarray(bounds.low) + np.asarray(bounds.high)) / 2
    for value, name in zip(tau, BLOCK_PARAMETERS[block], strict=True):
        full[bounds.names.index(name)] = value
    return full


def start(world: World, block: str, tau) -> BlockStart:
    """Where ``block`` begins for its ``tau`` on the world's robot (:func:`~besman.sim.blocks.prepare`)."""
    full = full_tau(block, tau, str(world.robot.folder))
    return prepare(world, block, full[:2], full[2:])


def held_above_table(world: World, object_xy, place_xy) -> Executor:
    """``world`` with the box picked from ``object_xy`` by the planned motions, in the hand where the carry
    to ``place_xy`` begins (5 cm above where it stood), and an executor to go on from there."""
    restore(world, prepare(world, "carry", object_xy, place_xy).state)
    return Executor(world)


@dataclass(frozen=True)
class BlockTaskConfig:
    """A block's refinement task: the block, its learned joint-space primitive (a primitive file, so that
    worker processes can load it) and the reward."""

    block: str
    shape: str
    reward: Reward = field(default_factory=Reward)
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
            self._starts[key] = start(self.world, self.config.block, key)
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


ROLES = {  # which recorded label plays each block: clusters named in the order of the task, or annotations
    "clustered": {"reach": "block4", "carry": "block5", "return": "block6"},
    "examples": {"reach": "approach_right", "carry": "move_obj_shelf", "return": "move_to_rest_down"},
}


def building_blocks(task, robot: str) -> BuildingBlocks:
    """Pick and place's blocks on ``robot`` as learning takes them: reach, carry and return, played on the
    shared recordings by the person's second pick and place (clusters 4-6 of six, or the annotations'
    ``approach_right``, ``move_obj_shelf`` and ``move_to_rest_down``); the reach's and the carry's goals
    anchor the map from the person's workspace to the robot's."""
    return BuildingBlocks(
        task=task.name,
        robot=robot,
        names=BLOCKS,
        roles=ROLES,
        anchors=("reach", "carry"),
        bounds=lambda block: block_bounds(block, robot),
        world=lambda: tabletop_world(robot=robot),
        start=start,
        refinement=lambda block, shape: BlockTaskConfig(block, shape, robot=robot),
    )
