"""What every stage of the throwing experiment throws on: the task, theta_0, the grid of evaluation targets,
the spreads' validation targets and a seed's training targets, and the rollouts themselves - thrown in
batches, or as CMA-ES searches in lockstep behind a progress bar."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from besman.learning.policy_search import WarmStart, make_optimizer, policy_search
from besman.learning.throwing_config import ExperimentConfig
from besman.sim.throwing import ThrowingConfig, ThrowingTask

BATCH = 256  # rollouts per evaluate() call: the rollout's state buffers grow with the batch
VALIDATION_SEED = 20_141_000  # the spreads' validation targets: their own seed, never a grid


def distances_of(rewards: np.ndarray) -> np.ndarray:
    """Distance to target, sqrt(-reward): the landing's distance for a valid throw."""
    return np.sqrt(np.maximum(-np.asarray(rewards, dtype=float), 0.0))


@dataclass
class ThrowingBench:
    """The task of ``config.variant`` and its targets; ``backend`` is the task's ("threads" or "ray")."""

    config: ExperimentConfig
    backend: str = "threads"
    progress: bool = True
    task: ThrowingTask = field(init=False)

    def __post_init__(self) -> None:
        self.task = ThrowingConfig(variant=self.config.variant).build()
        self.theta0 = self.task.default_theta()
        bounds = self.task.bounds
        axes = [np.linspace(lo, hi, self.config.grid) for lo, hi in zip(bounds.low, bounds.high, strict=True)]
        self.grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T
        self.validation = np.random.default_rng(VALIDATION_SEED).uniform(
            bounds.low, bounds.high, size=(self.config.validation_targets, len(bounds.names))
        )
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

    def rewards(self, thetas: np.ndarray, taus: np.ndarray) -> np.ndarray:
        rewards = np.empty(len(thetas))
        for start in range(0, len(thetas), BATCH):
            part = slice(start, start + BATCH)
            rewards[part] = self.task.evaluate(
                thetas[part], taus[part], backend=self.backend, nan="penalize"
            ).rewards
        return rewards

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
    ):
        """CMA-ES from each start at its tau, in lockstep; ``embed`` maps a searched vector to theta."""
        optimizers = [
            make_optimizer(self.config.method, start, seed=seed * 100_003 + i)
            for i, start in enumerate(starts)
        ]
        size = optimizers[0].population_size
        total = len(starts) * (1 + math.ceil(budget / size) * size)
        with self.bar(description, total) as bar:
            bar.update(len(starts))
            return policy_search(
                lambda thetas, owners: self.rewards(thetas if embed is None else embed(thetas), taus[owners]),
                optimizers,
                budget=budget,
                progress=bar.update,
            )

    def curves(self, description: str, starts: list[WarmStart], taus: np.ndarray, seed: int) -> np.ndarray:
        """(targets, curve_rollouts + 1) distances of the best rollout so far."""
        results = self.search(description, starts, taus, self.config.curve_rollouts, seed)
        return distances_of(np.array([r.curve()[: self.config.curve_rollouts + 1, 2] for r in results]))
