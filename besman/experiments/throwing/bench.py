"""What every stage of the throwing experiment throws on: the task, theta_0, the grid of evaluation targets,
the validation targets (never on the grid, half of them on the box's edges) and a seed's training targets,
the free feasibility guard (:mod:`besman.learning.search.feasibility`), and the rollouts themselves - thrown
in batches, or as CMA-ES searches in lockstep behind a progress bar."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from besman.experiments.throwing.config import TASK_OF_VARIANT, ExperimentConfig
from besman.learning.search.acceptance import reevaluated_searches
from besman.learning.search.feasibility import pull_back
from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.skills import zero_shot
from besman.tasks import task
from besman.tasks.throwing.rollouts import ThrowingRollouts

BATCH = 256  # rollouts per evaluate() call: the rollout's state buffers grow with the batch
REEVALUATIONS = 2  # more throws of a refinement's start and best theta, for its verdict
VALIDATION_SEED = 20_141_000  # the validation targets: their own seed, never a grid


def distances_of(rewards: np.ndarray) -> np.ndarray:
    """Distance to target, sqrt(-reward): the landing's distance for a valid throw."""
    return np.sqrt(np.maximum(-np.asarray(rewards, dtype=float), 0.0))


@dataclass
class ThrowingBench:
    """The rollouts of the registry's task of ``config.variant``
    (:data:`~besman.experiments.throwing.config.TASK_OF_VARIANT`) and its targets; ``backend`` is the
    rollouts' ("threads" or "ray")."""

    config: ExperimentConfig
    backend: str = "threads"
    progress: bool = True
    task: ThrowingRollouts = field(init=False)

    def __post_init__(self) -> None:
        throwing = task(TASK_OF_VARIANT[self.config.variant])  # its batched rollouts: what policy search uses
        self.task = throwing.batched(throwing.robot)
        self.theta0 = self.task.default_theta()
        bounds = self.task.bounds
        axes = [np.linspace(lo, hi, self.config.grid) for lo, hi in zip(bounds.low, bounds.high, strict=True)]
        self.grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T
        self.validation = validation_targets(bounds, self.config.validation_targets)
        # The goal-only variant searches each DMP dimension's goal and goal velocity (the last two of its
        # N weights + 2 entries).
        per_dimension = self.task.dmp.n_params // self.task.dmp.n_dims
        self.goal_entries = np.array(
            [
                d * per_dimension + i
                for d in range(self.task.dmp.n_dims)
                for i in (per_dimension - 2, per_dimension - 1)
            ]
        )

    def training_taus(self, seed: int) -> np.ndarray:
        """The seed's max(ks) training targets, drawn uniformly from the box."""
        bounds = self.task.bounds
        rng = np.random.default_rng(seed)
        return rng.uniform(bounds.low, bounds.high, size=(max(self.config.ks), len(bounds.names)))

    def embed_goals(self, goals: np.ndarray) -> np.ndarray:
        """Thetas with the goal entries ``goals`` and every other entry theta_0's."""
        thetas = np.tile(self.theta0, (len(goals), 1))
        thetas[:, self.goal_entries] = goals
        return thetas

    def bar(self, description: str, total: int):
        return tqdm(total=total, desc=description, unit="rollout", disable=not self.progress, leave=False)

    def throws(self, thetas: np.ndarray, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rewards (N,) and landings (N, 2) of thetas thrown at taus; NaN landings for failed throws."""
        rewards, landings = np.empty(len(thetas)), np.full((len(thetas), 2), np.nan)
        for start in range(0, len(thetas), BATCH):
            part = slice(start, start + BATCH)
            evaluation = self.task.evaluate(thetas[part], taus[part], backend=self.backend, nan="penalize")
            rewards[part] = evaluation.rewards
            for i, detail in enumerate(evaluation.details, start):
                if detail.landing is not None:
                    landings[i] = detail.landing
        return rewards, landings

    def rewards(self, thetas: np.ndarray, taus: np.ndarray) -> np.ndarray:
        return self.throws(thetas, taus)[0]

    def guarded(self, thetas: np.ndarray, anchors: np.ndarray) -> tuple[np.ndarray, int]:
        """``thetas`` with every one whose reference fails pulled back toward its (feasible) anchor, and how
        many were pulled back: no rollout is spent."""
        thetas, moved = pull_back(thetas, anchors, self.task.feasible)
        return thetas, int(moved.sum())

    def guarded_by_training(
        self, predicted: np.ndarray, taus: np.ndarray, thetas: np.ndarray, targets: np.ndarray
    ) -> tuple[np.ndarray, int]:
        """:meth:`guarded` with each prediction's anchor the training theta (of ``thetas`` learned at
        ``taus``) nearest its target: a method built on training tasks falls back on its own data."""
        bounds = self.task.bounds
        anchors = zero_shot.nearest_neighbour(bounds.normalise(taus), thetas, bounds.normalise(targets))
        return self.guarded(predicted, anchors)

    def distances(self, thetas: np.ndarray, taus: np.ndarray) -> np.ndarray:
        return distances_of(self.rewards(thetas, taus))

    def search(
        self,
        description: str,
        starts: list[WarmStart],
        taus: np.ndarray,
        budget: int,
        seed: int,
        embed: Callable[[np.ndarray], np.ndarray] | None = None,
        outcomes: list | None = None,
    ):
        """CMA-ES from each start at its tau, in lockstep; ``embed`` maps a searched vector to theta. Each
        batch's (thetas, landings, owners) is appended to ``outcomes`` if given."""
        optimizers = [
            make_optimizer(self.config.method, start, seed=seed * 100_003 + i)
            for i, start in enumerate(starts)
        ]
        size = optimizers[0].population_size
        total = len(starts) * (1 + math.ceil(budget / size) * size)

        def objective(thetas, owners):
            thetas = thetas if embed is None else embed(thetas)
            rewards, landings = self.throws(thetas, taus[owners])
            if outcomes is not None:
                outcomes.append((thetas, landings, np.asarray(owners)))
            return rewards

        with self.bar(description, total) as bar:
            bar.update(len(starts))
            return policy_search(objective, optimizers, budget=budget, progress=bar.update)

    def verdicts(
        self, starts: list[WarmStart], results, taus: np.ndarray, budget: int
    ) -> dict[str, np.ndarray]:
        """Each search's verdict (:func:`~besman.learning.search.acceptance.judge`): its start mean and its
        best theta within ``budget`` rollouts (:meth:`~besman.learning.search.policy_search.SearchResult.
        best_within`) thrown :data:`REEVALUATIONS` more times at its tau (one batch), beside the search's
        own rewards of them. Arrays of the improvement, the noise and whether the best is kept."""
        bests = [r.best_within(budget) for r in results]
        verdicts = reevaluated_searches(
            lambda thetas, owners: self.rewards(thetas, taus[owners]),
            np.array([start.mean for start in starts]),
            np.array([theta for theta, _ in bests]),
            [(r.start_reward, best) for r, (_, best) in zip(results, bests, strict=True)],
            REEVALUATIONS,
        )
        return {
            "refinement_improvement": np.array([v.improvement for v in verdicts]),
            "refinement_noise": np.array([v.noise for v in verdicts]),
            "refinement_accepted": np.array([v.accepted for v in verdicts]),
        }

    def curves(self, description: str, starts: list[WarmStart], taus: np.ndarray, seed: int) -> np.ndarray:
        """(targets, curve_rollouts + 1) distances of the best rollout so far."""
        results = self.search(description, starts, taus, self.config.curve_rollouts, seed)
        return distances_of(np.array([r.curve()[: self.config.curve_rollouts + 1, 2] for r in results]))


def validation_targets(bounds, count: int) -> np.ndarray:
    """``count`` targets drawn uniformly from the box and ``count`` on its faces (each with one coordinate at
    its low or its high end, in turn), from their own seed: the held-out targets on which every setting is
    chosen. The edges are where a model extrapolates, so they are validated too."""
    rng = np.random.default_rng(VALIDATION_SEED)
    low, high = np.array(bounds.low), np.array(bounds.high)
    inside = rng.uniform(low, high, size=(count, low.size))
    edges = rng.uniform(low, high, size=(count, low.size))
    for i in range(count):
        coordinate, end = i % low.size, (i // low.size) % 2
        edges[i, coordinate] = (low, high)[end][coordinate]
    return np.concatenate([inside, edges])
