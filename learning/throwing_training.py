"""Stage 1 of the throwing experiment: a seed's training sets. The paper's ("training": each of the max(ks)
targets learned by CMA-ES from theta_0 with the tabula-rasa spread) and the two variants beyond the paper:
"bootstrapped" (the same targets learned in sequence, each from the template of the tasks before it,
Queisser and Steil 2018) and "goal_only" (learned over the DMP's goals and goal velocities alone)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.learning.policy_search import WarmStart
from besman.learning.throwing_bench import ThrowingBench
from besman.learning.throwing_output import RunFolder
from besman.learning.throwing_spreads import Spreads
from besman.learning.throwing_templates import TemplateBuilder
from besman.skills import zero_shot
from besman.skills.shared_kernel import SharedKernel


def training_set(taus: np.ndarray, results) -> dict[str, np.ndarray]:
    """The targets ``taus`` with the best theta and reward of each one's search, and its rollouts."""
    return {
        "taus": taus,
        "thetas": np.array([r.best_theta for r in results]),
        "rewards": np.array([r.best_reward for r in results]),
        "rollouts": np.array([r.rollouts + 1 for r in results]),  # the start mean's rollout included
    }


@dataclass
class TrainingSets:
    """A seed's training sets: targets, best thetas and rewards, and the rollouts each took."""

    bench: ThrowingBench
    folder: RunFolder
    spreads: Spreads
    builder: TemplateBuilder

    def of(self, seed: int, source: str) -> dict[str, np.ndarray]:
        """The training set of ``source``: "training" (the paper's), "bootstrapped" or "goal_only"."""
        stages = {"training": self.paper, "bootstrapped": self.bootstrapped, "goal_only": self.goal_only}
        return stages[source](seed)

    def paper(self, seed: int) -> dict[str, np.ndarray]:
        """Each training target learned by CMA-ES from theta_0."""
        return self.folder.stage(
            f"seed{seed}_training", lambda: self._learn_each(seed, "training", self.bench.theta0)
        )

    def bootstrapped(self, seed: int) -> dict[str, np.ndarray]:
        """The training tasks in sequence, each started from the template of the tasks before it."""

        def compute():
            taus, spread = self.bench.training_taus(seed), self.spreads.tabula_rasa_spread
            runs = []
            for i, tau in enumerate(taus):
                if i == 0:
                    start = WarmStart(self.bench.theta0, spread)
                else:
                    done = training_set(taus[:i], runs)
                    start = WarmStart(
                        *self.builder.build(done["taus"], done["thetas"], SharedKernel()).distribution(tau)
                    )
                runs += self.bench.search(
                    f"seed {seed}: bootstrapped {i + 1}/{len(taus)}",
                    [start],
                    tau[None],
                    self.bench.config.training_rollouts,
                    seed * 7 + i,
                )
            return training_set(taus, runs)

        return self.folder.stage(f"seed{seed}_bootstrapped_training", compute)

    def goal_only(self, seed: int) -> dict[str, np.ndarray]:
        """The training tasks learned over the goals and goal velocities alone (16 numbers)."""

        def compute():
            bench = self.bench
            goals = bench.theta0[bench.goal_entries]
            trained = self._learn_each(seed, "goal-only training", goals, embed=bench.embed_goals)
            trained["thetas"] = bench.embed_goals(trained["thetas"])
            return trained

        return self.folder.stage(f"seed{seed}_goal_only_training", compute)

    def _learn_each(
        self,
        seed: int,
        what: str,
        start_mean: np.ndarray,
        embed: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> dict[str, np.ndarray]:
        """Every training target of the seed searched from ``start_mean`` with the tabula-rasa spread, in
        lockstep; ``embed`` maps a searched vector to theta."""
        taus = self.bench.training_taus(seed)
        start = WarmStart(start_mean, self.spreads.tabula_rasa_spread)
        results = self.bench.search(
            f"seed {seed}: {what}",
            [start] * len(taus),
            taus,
            self.bench.config.training_rollouts,
            seed,
            embed,
        )
        return training_set(taus, results)

    def nearest_thetas(self, seed: int, k: int, targets: np.ndarray) -> np.ndarray:
        """For each target, the theta of the nearest of the seed's first k training targets."""
        training, bounds = self.paper(seed), self.bench.task.bounds
        return zero_shot.nearest_neighbour(
            bounds.normalise(training["taus"][:k]), training["thetas"][:k], bounds.normalise(targets)
        )
