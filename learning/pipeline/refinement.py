"""The last stages of :func:`~besman.learning.pipeline.end_to_end.learn`: each building block imitated
(``work/imitated/``) and retargeted onto the robot (``work/shapes/``), refined by CMA-ES for its training
tasks (``work/refined/``), and stored as a skill template in the pool.

What is task-specific comes from the task's :class:`~besman.learning.pipeline.building_blocks.BuildingBlocks`:
the blocks and their order, the two anchors of the workspace map, the training tasks, where each block begins,
the template's input (the block's move in the frame that makes it generic) and the batched rollouts that
refine it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

import besman.robots as robots
from besman.core.seeds import child_seed
from besman.core.storage import read_json
from besman.learning.pipeline.building_blocks import BuildingBlocks
from besman.learning.pipeline.imitation import imitate
from besman.learning.pipeline.record import (
    SCHEMA_VERSION,
    LearnError,
    LearnSettings,
    progress_bar,
    write_json,
)
from besman.learning.pipeline.retargeting import fit_workspace_map, retarget
from besman.learning.search.acceptance import reevaluated
from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.learning.segmentation.demonstration import Demonstration
from besman.learning.segmentation.labelling import DemonstrationSegment
from besman.sim.evaluation import BatchedRollouts
from besman.sim.executor import Executor
from besman.sim.manipulation import PlanningError
from besman.skills import DMP, MovementPrimitive, SkillTemplate, SkillTemplatePool
from besman.skills.dmp_core import DMPSettings
from besman.skills.task_bounds import TaskBounds


def block_shapes(
    instances: dict[str, list[dict]],
    demos: dict[str, Demonstration],
    blocks: BuildingBlocks,
    n_weights: int,
    work: Path,
) -> dict[str, Path]:
    """Each block imitated (Cartesian, the person's frame) from its ``instances`` in the recordings
    (``demos`` by file name) and retargeted to the robot (joint space, ``n_weights`` per joint); the
    workspace map, fitted on the anchors' goals, goes with each shape's provenance."""
    shapes = {block: work / "shapes" / f"{block}.json" for block in blocks.names}
    if all(path.is_file() for path in shapes.values()):
        return shapes
    imitated = {}
    for block, found in instances.items():
        path = work / "imitated" / f"{block}.json"
        if not path.is_file():
            segments = [DemonstrationSegment(demos[i["file"]], i["start"], i["end"], block) for i in found]
            imitate(segments, name=block).save(path)
        imitated[block] = MovementPrimitive.load(path)
    world = blocks.world(blocks.centre)
    arm = Executor(world).arm
    starts = {block: blocks.start(world, block, blocks.centre) for block in blocks.names}
    first, second = blocks.anchors
    mapping = fit_workspace_map(
        imitated[first].dmp.position.goal,
        imitated[second].dmp.position.goal,
        arm.site_pose(starts[first].goal).position,
        arm.site_pose(starts[second].goal).position,
    )
    for block, path in shapes.items():
        if not path.is_file():
            start = starts[block]
            shape = retarget(imitated[block], mapping, arm, start.start, start.goal, n_weights=n_weights)
            shape.provenance["segments"] = instances[block]
            shape.save(path)
    return shapes


RESTING = 0.02  # a sample moving at less than this share of its instance's peak joint speed is at rest


def joint_shapes(
    instances: dict[str, list[dict]],
    joints: dict[str, tuple[np.ndarray, np.ndarray]],
    blocks: BuildingBlocks,
    n_weights: int,
    work: Path,
) -> dict[str, Path]:
    """Each block imitated in the robot's own joint space from its ``instances`` in a robot's recordings
    (``joints`` by recording name: its times and joint positions): one joint-space primitive of the mean
    shape, at rest at both ends (the rest before and after each instance cut off), set between the block's
    planned start and goal at the task's centre. No workspace map: the recordings are the robot's."""
    shapes = {block: work / "shapes" / f"{block}.json" for block in blocks.names}
    if all(path.is_file() for path in shapes.values()):
        return shapes
    world = blocks.world(blocks.centre)
    arm = Executor(world).arm
    for block, path in shapes.items():
        if path.is_file():
            continue
        demonstrations = [_moving(*joints[i["file"]], i["start"], i["end"]) for i in instances[block]]
        times = [t - t[0] for t, _ in demonstrations]
        positions = [q for _, q in demonstrations]
        velocities = [np.gradient(q, t, axis=0, edge_order=2) for t, q in demonstrations]
        for v in velocities:
            v[[0, -1]] = 0.0
        accelerations = [
            np.gradient(v, t, axis=0, edge_order=2)
            for v, (t, _) in zip(velocities, demonstrations, strict=True)
        ]
        for a in accelerations:
            a[[0, -1]] = 0.0
        dmp = DMP(arm.dofs, settings=DMPSettings(n_weights=n_weights))
        dmp.imitate(times, positions, velocities=velocities, accelerations=accelerations)
        start = blocks.start(world, block, blocks.centre)
        dmp.configure(
            start=start.start, goal=start.goal, start_velocity=0.0, start_acceleration=0.0, goal_velocity=0.0
        )
        provenance = {
            "imitation": "the robot's recorded joint positions, in joint space (no retargeting)",
            "segments": instances[block],
        }
        shape = MovementPrimitive(
            dmp, block, robot=arm.world.robot.name, group=arm.name, provenance=provenance
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        shape.save(path)
    return shapes


def _moving(times: np.ndarray, joints: np.ndarray, start: int, end: int) -> tuple[np.ndarray, np.ndarray]:
    """An instance's samples without the rest at its ends (a reach that begins while the gripper opens)."""
    times, joints = times[start : end + 1], joints[start : end + 1]
    speed = np.linalg.norm(np.gradient(joints, times, axis=0), axis=1)
    moving = np.flatnonzero(speed > RESTING * speed.max())
    first, last = max(int(moving[0]) - 1, 0), min(int(moving[-1]) + 1, len(times) - 1)
    return times[first : last + 1], joints[first : last + 1]


def refine_blocks(
    shapes: dict[str, Path], blocks: BuildingBlocks, settings: LearnSettings, folder: Path, shown: bool
) -> dict[str, list[dict]]:
    """Each block refined by CMA-ES in the K training tasks (a Latin hypercube over the task's whole box; a
    task whose planned motions cannot be made is drawn again), each task's result cached in ``folder``;
    every search seeded by the run's seed, the block's index and the task's."""
    results = {}
    folder.mkdir(exist_ok=True)
    total = len(blocks.names) * settings.tasks
    done = sum((folder / f"{b}-{k}.json").is_file() for b in blocks.names for k in range(settings.tasks))
    with progress_bar(total, "refining", "task", shown) as tasks_bar:
        tasks_bar.update(done)
        for index, block in enumerate(blocks.names):
            taus = blocks.draw(settings.tasks, child_seed(settings.seed, index))
            shape = MovementPrimitive.load(shapes[block])
            task = None  # built (a world, its model) only if a training task is left to refine
            results[block] = []
            for k, tau in enumerate(taus):
                path = folder / f"{block}-{k}.json"
                if not path.is_file():
                    task = task or blocks.refinement(block, str(shapes[block])).build()
                    tau, _ = plannable(task.input, tau, blocks, child_seed(settings.seed, index, k))
                    with progress_bar(
                        settings.budget + 1, f"{block} {k + 1}/{settings.tasks}", "rollout", shown
                    ) as bar:
                        document = _refine_task(
                            task,
                            shape,
                            tau,
                            settings,
                            seed=child_seed(settings.seed, index, k),
                            progress=bar.update,
                        )
                    write_json(
                        path, {"schema_version": SCHEMA_VERSION, "block": block, "task": k, **document}
                    )
                    tasks_bar.update()
                results[block].append(read_json(path, LearnError))
    return results


def store_templates(
    out: Path,
    shapes: dict[str, Path],
    refined: dict[str, list[dict]],
    blocks: BuildingBlocks,
    settings: LearnSettings,
    record: dict,
) -> tuple[str, ...]:
    """One skill template per block in the pool ``out``, over its tau: the refined thetas of its training
    tasks, the refinement's spread as the prior exploration of the forcing weights (all that was searched),
    and the provenance (``record``'s recordings and settings, instances, workspace map, training)."""
    pool = SkillTemplatePool(out)
    robot = robots.describe(blocks.robot).name  # a run on a folder (./my_arm) names the robot, not the path
    for block in blocks.names:
        prototype = MovementPrimitive.load(shapes[block])
        runs = refined[block]
        inputs = np.array([run["input"] for run in runs])
        template = SkillTemplate(
            block,
            prototype,
            inputs,
            np.array([run["theta"] for run in runs]),
            input_box(blocks.input_names, inputs),
            prior_spread=np.where(forcing_weights(prototype), settings.spread, 0.0),
            seed=settings.seed,
            task=f"{blocks.task}/{robot}",
            provenance={
                "learner": "besman.learning.pipeline.end_to_end.learn",
                "robot": robot,
                "recordings": record["recordings"],
                "instances": prototype.provenance.get("segments", []),
                # None for a robot's own recordings (imitated in its joint space, no map).
                "workspace_map": prototype.provenance.get("retargeting", {}).get("map"),
                "training": [
                    {
                        "task_tau": run["tau"],
                        "tau": run["input"],
                        "reward": run["reward"],
                        "start_reward": run["start_reward"],
                        "success": run["outcome"]["success"],
                    }
                    for run in runs
                ],
                "settings": record["settings"],
            },
        )
        pool.add(template, overwrite=True)
    return blocks.names


def _refine_task(
    task: BatchedRollouts,
    shape: MovementPrimitive,
    tau: np.ndarray,
    settings: LearnSettings,
    seed: int,
    progress: Callable[[int], None],
) -> dict:
    """The settings' optimiser (CMA-ES by default) over the forcing weights of ``shape`` for one tau by
    rollouts of ``task`` (the shape's thetas); the best theta, its outcome (the rollout's details) and the
    curve."""
    theta0 = shape.theta.copy()
    weights = forcing_weights(shape)
    outcomes = {}

    def objective(candidates: np.ndarray, owners: np.ndarray) -> np.ndarray:
        thetas = np.tile(theta0, (len(candidates), 1))
        thetas[:, weights] = candidates
        evaluation = task.evaluate(thetas, np.tile(tau, (len(candidates), 1)), backend=settings.backend)
        for candidate, detail in zip(candidates, evaluation.details, strict=True):
            outcomes[candidate.tobytes()] = detail
        progress(len(candidates))
        return evaluation.rewards

    search = make_optimizer(settings.optimizer, WarmStart(theta0[weights], settings.spread), seed=seed)
    result = policy_search(objective, [search], budget=settings.budget)[0]
    best = theta0.copy()
    best[weights] = result.best_theta
    acceptance = reevaluated(
        lambda thetas: task.evaluate(thetas, tau, backend=settings.backend).rewards,
        theta0,
        best,
        REPEATS,
    )
    kept = best if acceptance.accepted else theta0
    return {
        "tau": [float(v) for v in tau],
        "input": [float(v) for v in task.input(tau)],
        "theta": kept.tolist(),
        "reward": result.best_reward if acceptance.accepted else result.start_reward,
        "start_reward": result.start_reward,
        "acceptance": acceptance.to_json(),
        "rollouts": result.rollouts + 1 + 2 * REPEATS,
        "curve": result.curve().tolist(),
        "outcome": dataclasses.asdict(outcomes[kept[weights].tobytes()]),
        "start_outcome": dataclasses.asdict(outcomes[theta0[weights].tobytes()]),
    }


# Evaluations of the start and of the best theta again, which measure the reward's noise (the block's
# rollouts reproduce bit for bit: it is 0, and the search's own rewards are checked by it).
REPEATS = 2


def forcing_weights(shape: MovementPrimitive) -> np.ndarray:
    """A mask of theta's forcing weights (each DMP dimension's N weights, not its goal and goal velocity):
    what refinement searches."""
    mask = np.zeros((shape.dmp.n_dims, shape.dmp.n_weights + 2), dtype=bool)
    mask[:, : shape.dmp.n_weights] = True
    return mask.ravel()


# Where a template's input box reaches beyond its training inputs: a quarter of their range on each side,
# at least these (m, m, m, deg: the hand's move), so that near inputs are not extrapolated.
INPUT_MARGIN = 0.25
SMALLEST_SPAN = 0.02


def input_box(names: tuple[str, ...], inputs: np.ndarray) -> TaskBounds:
    """A template's input box: its training inputs' range, widened by :data:`INPUT_MARGIN` of it on
    each side (by half of :data:`SMALLEST_SPAN` at least)."""
    low, high = inputs.min(axis=0), inputs.max(axis=0)
    margin = np.maximum(INPUT_MARGIN * (high - low), SMALLEST_SPAN / 2)
    return TaskBounds(tuple(names), tuple(low - margin), tuple(high + margin))


REDRAWS = 20  # training tasks drawn at most in place of one whose planned motions cannot be made


def plannable(check, tau: np.ndarray, blocks: BuildingBlocks, seed: int) -> tuple[np.ndarray, object]:
    """``tau`` and ``check(tau)``, or if that cannot be planned (a :class:`PlanningError`) a task drawn in
    its place with ``seed`` and what ``check`` gives there."""
    for attempt in range(REDRAWS + 1):
        try:
            return tau, check(tau)
        except PlanningError as error:
            failure = error
            tau = blocks.draw(1, child_seed(seed, attempt))[0]
    raise LearnError(f"no training task of {blocks.task} could be planned: {failure}")
