"""The refinement stage of :func:`~besman.learning.pipeline.end_to_end.learn` when the blocks are refined as a
sequence (``refinement="sequence"`` jointly, ``"sequence-by-block"`` one after the other for comparison): per
training task, every block's parameters - its primitive's forcing weights and its subgoals - are refined on
rollouts of the whole task (:func:`~besman.learning.search.hierarchical.refine_sequence`), each rollout with
its own perturbations (the task's, drawn from a seed per rollout; every other rollout pushed). The budget
counts whole-task rollouts.

Each training task's result is cached in ``work/refined/sequence-<k>.json`` and given to the templates as
the per-block stage gives its own: per block the refined theta, the block's template input at the task (the
hand's planned move), and the block's reward and success before and after, measured on
:data:`EVALUATION_ROLLOUTS` rollouts with the same perturbations (not counted in the budget). Those paired
rollouts judge the refinement (:mod:`~besman.learning.search.acceptance`): where the whole task's reward did
not improve by more than its noise, the start is kept ("after" is then "before"; "refined" keeps what the
search found). The subgoals go to the task's tree (:func:`subgoals`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.core.seeds import child_seed
from besman.core.storage import read_json
from besman.learning.pipeline.building_blocks import BuildingBlocks
from besman.learning.pipeline.record import (
    SCHEMA_VERSION,
    LearnError,
    LearnSettings,
    progress_bar,
    write_json,
)
from besman.learning.pipeline.refinement import plannable
from besman.learning.search.acceptance import judge
from besman.learning.search.hierarchical import refine_sequence
from besman.learning.search.policy_search import WarmStart

POPULATION = 8  # candidates per generation: 6 generations of 48 rollouts jointly, 2 per block one by one
EVALUATION_ROLLOUTS = 6  # rollouts (half pushed) that measure the start and the result of each task
EVALUATION_STREAM = 1  # the child of a task's seed that draws the evaluation rollouts' perturbations


def refine_sequences(
    shapes: dict[str, Path], blocks: BuildingBlocks, settings: LearnSettings, folder: Path, shown: bool
) -> dict[str, list[dict]]:
    """The K training tasks' sequences refined (see the module documentation), cached in ``folder``;
    per block, its K results as :func:`~besman.learning.pipeline.refinement.refine_blocks` gives them."""
    folder.mkdir(exist_ok=True)
    config = blocks.sequence(tuple(str(shapes[block]) for block in blocks.names))
    task = None  # built (worlds, models) only if a training task is left to refine
    inputs = None
    documents = []
    taus = blocks.draw(settings.tasks, child_seed(settings.seed, len(blocks.names)))
    done = sum((folder / f"sequence-{k}.json").is_file() for k in range(settings.tasks))
    with progress_bar(settings.tasks, "refining the sequence", "task", shown) as tasks_bar:
        tasks_bar.update(done)
        for k, tau in enumerate(taus):
            path = folder / f"sequence-{k}.json"
            if not path.is_file():
                task = task or config.build()
                inputs = inputs or {b: blocks.refinement(b, str(shapes[b])).build() for b in blocks.names}
                tau, block_inputs = plannable(
                    lambda t, tasks=inputs: {b: [float(v) for v in tasks[b].input(t)] for b in tasks},
                    tau,
                    blocks,
                    child_seed(settings.seed, len(blocks.names), k),
                )
                with progress_bar(
                    settings.budget, f"sequence {k + 1}/{settings.tasks}", "rollout", shown
                ) as bar:
                    document = _refine_task(
                        task, tau, settings, child_seed(settings.seed, len(blocks.names), k), bar.update
                    )
                document["inputs"] = block_inputs
                write_json(path, {"schema_version": SCHEMA_VERSION, "task": k, **document})
                tasks_bar.update()
            documents.append(read_json(path, LearnError))
    return {
        block: [_block_result(document, index, block) for document in documents]
        for index, block in enumerate(blocks.names)
    }


def subgoals(refined: dict[str, list[dict]]) -> dict[str, dict[str, float]]:
    """Per block, the median over the training tasks of each refined subgoal (the plan's numbers): one
    value for the tree, which runs every task."""
    found = {}
    for block, runs in refined.items():
        names = list(runs[0].get("subgoals", {}))
        found[block] = {name: float(np.median([run["subgoals"][name] for run in runs])) for name in names}
    return found


class _Objective:
    """Whole-task rollouts of a training task ``tau`` for the blocks' parameters: each call's rollouts
    with perturbation seeds from ``seed`` and the call's number, every other one pushed; (N, K) costs."""

    def __init__(self, task, tau: np.ndarray, seed: int, backend: str, progress) -> None:
        self.task, self.tau, self.seed, self.backend, self.progress = task, tau, seed, backend, progress
        self.calls = 0

    def rollouts(self, thetas: list[np.ndarray], seeds: list[int]):
        n = len(thetas[0])
        taus = np.array([np.r_[self.tau, seeds[i], i % 2] for i in range(n)])
        return self.task.evaluate(np.hstack(thetas), taus, backend=self.backend)

    def __call__(self, thetas: list[np.ndarray]) -> np.ndarray:
        self.calls += 1
        n = len(thetas[0])
        seeds = [child_seed(self.seed, self.calls, i) % 2**31 for i in range(n)]
        details = self.rollouts(thetas, seeds).details
        self.progress(n)
        return impute(np.array([detail.costs for detail in details], dtype=float), self.task.config.reward)


def impute(costs: np.ndarray, reward) -> np.ndarray:
    """Costs (N, K) with a block that did not run (NaN: one before it failed) given the mean cost of the
    block where it ran in this batch (the failure's cost if it ran nowhere): its parameters had no part in
    that rollout."""
    filled = costs.copy()
    for column in range(costs.shape[1]):
        ran = np.isfinite(costs[:, column])
        filled[~ran, column] = costs[ran, column].mean() if ran.any() else -reward.failure
    return filled


def _refine_task(task, tau: np.ndarray, settings: LearnSettings, seed: int, progress) -> dict:
    objective = _Objective(task, tau, seed, settings.backend, progress)
    starts = [WarmStart(mean, settings.spread) for mean in task.start()]
    result = refine_sequence(
        objective,
        starts,
        jointly=settings.refinement == "sequence",
        budget=settings.budget,
        method=settings.optimizer,
        seed=seed,
        population_size=POPULATION,
        evaluate_start=False,
    )
    seeds = [child_seed(seed, EVALUATION_STREAM, i) % 2**31 for i in range(EVALUATION_ROLLOUTS)]
    evaluated = objective.rollouts([np.tile(s.mean, (len(seeds), 1)) for s in starts], seeds)
    refined = objective.rollouts([np.tile(t, (len(seeds), 1)) for t in result.thetas], seeds)
    acceptance = judge(evaluated.rewards, refined.rewards)  # each rollout's: minus the costs of its blocks
    before, after = evaluated.details, refined.details
    thetas = result.thetas if acceptance.accepted else [s.mean for s in starts]
    return {
        "tau": [float(v) for v in tau],
        "refinement": settings.refinement,
        "thetas": [theta.tolist() for theta in thetas],
        "primitive_thetas": [p.tolist() for p in task.primitive_thetas(thetas)],
        "subgoals": task.subgoals(thetas),
        "rollouts": result.rollouts,
        "costs": result.costs,
        "before": _measured(before),
        "after": _measured(after if acceptance.accepted else before),
        "refined": _measured(after),
        "acceptance": acceptance.to_json(),
        "stopped": result.stopped,
    }


def _measured(details) -> dict:
    """Per block, the mean cost and the share of the rollouts in which it succeeded (NaN costs: not run)."""
    costs = np.array([detail.costs for detail in details], dtype=float)
    blocks = len(costs[0])
    failed = [detail.failed_block for detail in details]
    return {
        "task_success": float(np.mean([detail.success for detail in details])),
        "cost": [
            float(np.nanmean(costs[:, k])) if np.isfinite(costs[:, k]).any() else None for k in range(blocks)
        ],
        "ran": [int(np.isfinite(costs[:, k]).sum()) for k in range(blocks)],
        "failed": failed,
    }


def _block_result(document: dict, index: int, block: str) -> dict:
    """A training task's result for ``block``, in the form of the per-block stage's."""
    before, after = document["before"], document["after"]

    def outcome(measured: dict) -> dict:
        ran = measured["ran"][index]
        failures = sum(found == block for found in measured["failed"])
        return {"success": bool(ran and failures == 0), "ran": ran, "failed": failures}

    rewards = -np.array(document["costs"])  # the whole task's, per rollout (no start row: not evaluated)
    curve = np.column_stack([np.arange(1, len(rewards) + 1), rewards, np.maximum.accumulate(rewards)])
    return {
        "tau": document["tau"],
        "input": document["inputs"][block],
        "theta": document["primitive_thetas"][index],
        "subgoals": document["subgoals"].get(block, {}),
        "reward": -(after["cost"][index] if after["cost"][index] is not None else 1.0),
        "start_reward": -(before["cost"][index] if before["cost"][index] is not None else 1.0),
        "curve": curve.tolist(),  # as the per-block stage's: rollout, reward, best so far
        "outcome": outcome(after),
        "start_outcome": outcome(before),
        **({"acceptance": document["acceptance"]} if "acceptance" in document else {}),
    }
