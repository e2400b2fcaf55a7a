"""What learning needs of a task: its building blocks, where each begins and how a rollout of one is scored.

A task that learns from recordings (:mod:`besman.tasks`) hands
:func:`~besman.learning.pipeline.end_to_end.learn` a
:class:`BuildingBlocks`; the pipeline names no task and no block of its own.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class BuildingBlocks:
    """A task's building blocks on one robot.

    Attributes:
        task: the task's name (the pool's templates are for ``task/robot``).
        robot: the robot (a name or a folder).
        names: the blocks, in the order the task does them.
        roles: which label of the recordings plays each block, by how they are labelled: ``"clustered"``
            (clusters named ``block1``... in the order they come in the task), ``"examples"`` (the
            labels of annotated example recordings) and ``"gripper"`` (a robot's recordings, by its
            gripper's events: ``before`` the grasp, ``holding``, ``after`` the release).
        anchors: two blocks whose goals, in the person's workspace and in the robot's, fit the map between
            the two (:func:`~besman.learning.pipeline.retargeting.fit_workspace_map`), at the task tau
            ``centre``.
        centre: the task tau where the blocks are retargeted.
        draw: ``draw(count, seed)``: ``count`` training task taus spread over the task's box.
        world: ``world(tau)``: a new world of the task on the robot for task ``tau`` (its objects).
        start: ``start(world, block, tau)``: brings the world to where the block begins for ``tau``; the
            result has the arm's configurations at the block's planned ``start`` and ``goal``.
        input_names: the names of a block template's input (what :meth:`BatchedRollouts.input` gives for a
            tau: the block's move, in the frame that makes it generic).
        refinement: ``refinement(block, shape file)``: the task config (``build()`` makes a
            :class:`~besman.sim.evaluation.BatchedRollouts` with ``input(tau)``) whose rollouts refine the
            block's primitive.
        object: the object the blocks grasp and place (its name in the task's world): what the tree learned
            from the recordings holds (:mod:`besman.trees.learned`).
        target: the blackboard key of where the object goes (the task's target value, ``/task/...``).
        sequence: ``sequence(shape files)`` (one per block, in order): the config (``build()`` makes a
            batched task of whole-task rollouts with ``start()``, ``primitive_thetas(parts)`` and
            ``subgoals(parts)``, details with per-block ``costs``) that refines the blocks together
            (:mod:`besman.learning.pipeline.sequence_refinement`); None if the task has none.
    """

    task: str
    robot: str
    names: tuple[str, ...]
    roles: Mapping[str, Mapping[str, str]]
    anchors: tuple[str, str]
    centre: Any
    draw: Callable[[int, int], Any]
    world: Callable[[Any], Any]
    start: Callable[[Any, str, Any], Any]
    input_names: tuple[str, ...]
    refinement: Callable[[str, str], Any]
    object: str
    target: str
    sequence: Callable[[tuple[str, ...]], Any] | None = None
