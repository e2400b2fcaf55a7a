"""Pick and place's building blocks as learning takes them: reach, carry and return
(:mod:`besman.sim.block_simulation` simulates each on its own), the training tasks they are refined in, and
rollouts of one block for many thetas as a batched task for policy search (:class:`BlockRollouts`, local
processes or Ray).

A training task is a whole pick-and-place tau (object position and yaw, place and yaw, shape, size) drawn
over the task's box; each block's template takes the hand's move over the block
(:func:`~besman.sim.block_simulation.block_input`), which is what makes it usable for objects, places and
tasks it was not learned in.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from besman.core.moved import old_names
from besman.learning.pipeline.building_blocks import BuildingBlocks
from besman.sim.block_simulation import (
    BLOCKS,
    INPUT_NAMES,
    OBJECT,
    BlockStart,
    Reward,
    block_input,
    check_block,
    prepare,
    restore,
    rollout,
)
from besman.sim.evaluation import BatchedRollouts, Evaluation
from besman.sim.executor import Executor
from besman.sim.world import World
from besman.skills import MovementPrimitive
from besman.tasks.pick_place.sequence import SequenceConfig


def _task():
    from besman.tasks import task

    return task("pick-place")


def world(robot: str, tau) -> World:
    """The tabletop world of ``robot`` with the object of the pick-and-place ``tau`` (its middle mass and
    friction)."""
    from besman.tasks.pick_place.scene import the_object

    task = _task()
    return task.world(robot, the_object(robot, task.split(tau), None))


def start(world: World, block: str, tau) -> BlockStart:
    """Where ``block`` begins for the pick-and-place ``tau`` in ``world`` (built for its object)."""
    values = _task().split(tau)
    return prepare(world, block, values["object"], values["place"])


def held_above_table(world: World, values) -> Executor:
    """``world`` with its object picked where the task ``values`` put it by the planned motions, in the
    hand where the carry to the place begins (5 cm above where it stood), and an executor to go on from
    there."""
    restore(world, prepare(world, "carry", values["object"], values["place"]).state)
    return Executor(world)


@dataclass(frozen=True)
class BlockTaskConfig:
    """A block's refinement task: the block, its learned joint-space primitive (a primitive file, so that
    worker processes can load it) and the reward."""

    block: str
    shape: str
    reward: Reward = field(default_factory=Reward)
    robot: str = "aila"

    def build(self) -> BlockRollouts:
        return BlockRollouts(self)


class BlockRollouts(BatchedRollouts):
    """Rollouts of one block for thetas of its primitive (the weights matter: the end points are planned
    per tau) in pick-and-place taus; rewards by :class:`Reward`, details :class:`BlockOutcome`."""

    def __init__(self, config: BlockTaskConfig) -> None:
        check_block(config.block)
        self.config = config
        self.bounds = _task().bounds(config.robot)
        self.shape = MovementPrimitive.load(config.shape)
        self._starts: dict[tuple[float, ...], tuple[World, BlockStart]] = {}

    def start(self, tau) -> tuple[World, BlockStart]:
        """The world of ``tau``'s object and the block's start in it (prepared once, then kept)."""
        key = tuple(float(v) for v in self.bounds.check(tau)[0])
        if key not in self._starts:
            built = world(self.config.robot, key)
            self._starts[key] = built, start(built, self.config.block, key)
        return self._starts[key]

    def input(self, tau) -> np.ndarray:
        """The block's template input for ``tau`` (the hand's move over it)."""
        built, begins = self.start(tau)
        return block_input(Executor(built).arm, begins.start, begins.goal)

    @property
    def n_params(self) -> int:
        return self.shape.theta.size

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        details = []
        for theta, tau in zip(thetas, taus, strict=True):
            self.shape.dmp.set_params(theta)
            details.append(rollout(*self.start(tau), self.shape))
        return Evaluation(np.array([self.config.reward.score(d) for d in details]), tuple(details))


ROLES = {  # which recorded label plays each block: clusters named in the order of the task, or annotations
    "clustered": {"reach": "block4", "carry": "block5", "return": "block6"},
    "examples": {"reach": "approach_right", "carry": "move_obj_shelf", "return": "move_to_rest_down"},
    "gripper": {"reach": "before", "carry": "holding", "return": "after"},  # a robot's recordings
}


def building_blocks(task, robot: str) -> BuildingBlocks:
    """Pick and place's blocks on ``robot`` as learning takes them: reach, carry and return, played on the
    shared recordings by the person's second pick and place (clusters 4-6 of six, or the annotations'
    ``approach_right``, ``move_obj_shelf`` and ``move_to_rest_down``); the reach's and the carry's goals
    anchor the map from the person's workspace to the robot's, at the task's default tau. Training tasks
    are drawn over the task's whole box."""
    return BuildingBlocks(
        task=task.name,
        robot=robot,
        names=BLOCKS,
        roles=ROLES,
        anchors=("reach", "carry"),
        centre=task.join(task.default_values(robot)),
        draw=lambda count, seed: task.spread(robot, count, seed),
        world=lambda tau: world(robot, tau),
        start=start,
        input_names=INPUT_NAMES,
        refinement=lambda block, shape: BlockTaskConfig(block, shape, robot=robot),
        object=OBJECT,
        target="/task/place",
        sequence=lambda shapes: SequenceConfig(robot, shapes),
    )


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
