"""Stage 1 of the throwing experiment: a seed's training sets. The paper's ("training": each of the max(ks)
targets learned by CMA-ES from theta_0 with the tabula-rasa spread; every valid rollout's theta and landing
kept too, the data of besman's outcome template) with the landing's Jacobian at each training theta (by
central differences in the goal coordinates, for outcome-space refinement), and the two variants beyond the
paper: "bootstrapped" (the same targets learned in sequence, each from the template of the tasks before it,
Queisser and Steil 2018) and "goal_only" (learned over the DMP's goals and goal velocities alone)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.output import RunFolder
from besman.experiments.throwing.spreads import Spreads
from besman.experiments.throwing.template_builder import TemplateBuilder
from besman.learning.search.policy_search import WarmStart
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
        """Each training target learned by CMA-ES from theta_0, with every valid rollout's theta, landing and
        training task ("outcome_thetas", "outcome_landings", "outcome_tasks")."""

        def compute():
            outcomes: list = []
            trained = self._learn_each(seed, "training", self.bench.theta0, outcomes=outcomes)
            thetas, landings, tasks = (np.concatenate(parts) for parts in zip(*outcomes, strict=True))
            valid = np.isfinite(landings).all(axis=1)
            return {
                **trained,
                "outcome_thetas": thetas[valid],
                "outcome_landings": landings[valid],
                "outcome_tasks": tasks[valid],
            }

        return self.folder.stage(f"seed{seed}_training", compute)

    def jacobians(self, seed: int) -> dict[str, np.ndarray]:
        """Each training theta's landing (2,) and its Jacobian (2, goal coordinates) with respect to the DMP's
        goals and goal velocities, by central differences of ``jacobian_step``; a side whose throw fails is
        replaced by the centre (a one-sided difference). 1 + 2 x 16 rollouts per training task."""

        def compute():
            bench, training = self.bench, self.paper(seed)
            thetas, taus = training["thetas"], training["taus"]
            step, entries = bench.config.jacobian_step, bench.goal_entries
            probes = np.repeat(thetas[:, None, None], 2, axis=1).repeat(len(entries), axis=2)  # (K, 2, c, n)
            for c, entry in enumerate(entries):
                probes[:, 0, c, entry] += step
                probes[:, 1, c, entry] -= step
            everything = np.concatenate([thetas, probes.reshape(-1, thetas.shape[1])])
            targets = np.concatenate([taus, np.repeat(taus, 2 * len(entries), axis=0)])
            with bench.bar(f"seed {seed}: Jacobians", len(everything)) as bar:
                _, landings = bench.throws(everything, targets)
                bar.update(len(everything))
            centre, sides = landings[: len(thetas)], landings[len(thetas) :].reshape(len(thetas), 2, -1, 2)
            landed = np.isfinite(sides).all(axis=-1)  # (K, 2, c)
            plus = np.where(landed[:, 0, :, None], sides[:, 0], centre[:, None])
            minus = np.where(landed[:, 1, :, None], sides[:, 1], centre[:, None])
            width = step * landed.sum(axis=1)
            jacobians = (plus - minus) / np.maximum(width, step)[..., None]  # (K, c, 2)
            return {
                "landings": centre,
                "jacobians": np.ascontiguousarray(np.nan_to_num(jacobians.transpose(0, 2, 1))),
                "rollouts": np.full(len(thetas), 1 + 2 * len(entries)),
            }

        return self.folder.stage(f"seed{seed}_jacobians", compute)

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
                    mean, spread = self.builder.build(
                        done["taus"], done["thetas"], SharedKernel()
                    ).distribution(tau)
                    guarded, _ = self.bench.guarded_by_training(
                        mean[None], done["taus"], done["thetas"], tau[None]
                    )
                    start = WarmStart(guarded[0], spread)
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
        outcomes: list | None = None,
    ) -> dict[str, np.ndarray]:
        """Every training target of the seed searched from ``start_mean`` with the tabula-rasa spread, in
        lockstep; ``embed`` maps a searched vector to theta; ``outcomes`` collects every batch's rollouts."""
        taus = self.bench.training_taus(seed)
        start = WarmStart(start_mean, self.spreads.tabula_rasa_spread)
        results = self.bench.search(
            f"seed {seed}: {what}",
            [start] * len(taus),
            taus,
            self.bench.config.training_rollouts,
            seed,
            embed,
            outcomes,
        )
        return training_set(taus, results)

    def outcome_template(self, seed: int, k: int, targets: np.ndarray) -> np.ndarray:
        """besman's outcome template of the first k tasks: for each target, the index (into the training
        stage's ``outcome_*`` arrays) of the rollout whose landing is nearest it."""
        training, bounds = self.paper(seed), self.bench.task.bounds
        own = np.flatnonzero(training["outcome_tasks"] < k)
        return zero_shot.nearest_outcome(
            bounds.normalise(training["outcome_landings"][own]), own[:, None], bounds.normalise(targets)
        )[:, 0]

    def nearest_thetas(self, seed: int, k: int, targets: np.ndarray) -> np.ndarray:
        """For each target, the theta of the nearest of the seed's first k training targets."""
        training, bounds = self.paper(seed), self.bench.task.bounds
        return zero_shot.nearest_neighbour(
            bounds.normalise(training["taus"][:k]), training["thetas"][:k], bounds.normalise(targets)
        )
