"""Stage 3 of the throwing experiment on the grid, at each K: "No Learning" (theta_0 everywhere), every
zero-shot method (:mod:`besman.skills.zero_shot`, the shared-kernel and the per-dimension template), the
template refined by CMA-ES, and the variants' templates zero shot. Each is a stage of distances, one per grid
target."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.learning.policy_search import WarmStart
from besman.learning.throwing_bench import ThrowingBench, distances_of
from besman.learning.throwing_config import ZERO_SHOT_METHODS
from besman.learning.throwing_output import RunFolder
from besman.learning.throwing_templates import Templates
from besman.learning.throwing_training import TrainingSets
from besman.skills import zero_shot
from besman.skills.template import SkillTemplate


@dataclass
class GridEvaluation:
    """The grid distances of no learning, the zero-shot methods and the refined template, per seed and K."""

    bench: ThrowingBench
    folder: RunFolder
    training: TrainingSets
    templates: Templates

    def no_learning(self) -> np.ndarray:
        grid = self.bench.grid
        return self.folder.stage(
            "no_learning",
            lambda: {"distances": self.bench.distances(np.tile(self.bench.theta0, (len(grid), 1)), grid)},
        )["distances"]

    def per_k(self, seed: int, k: int) -> dict[str, np.ndarray]:
        """Every zero-shot method's grid distances at K = k, and the template refined."""

        def compute():
            bench, grid = self.bench, self.bench.grid
            training = self.training.paper(seed)
            taus, thetas = training["taus"][:k], training["thetas"][:k]
            template = self.templates.template(seed, k)
            inputs, queries = bench.task.bounds.normalise(taus), bench.task.bounds.normalise(grid)
            per_dimension = SkillTemplate(
                "throw", template.prototype, taus, thetas, bench.task.bounds, model="per_dimension", seed=seed
            )
            predictions = {
                "template": template.predict(grid)[0],
                "per_dimension": per_dimension.predict(grid)[0],
                "training_mean": zero_shot.training_mean(inputs, thetas, queries),
                "nearest_neighbour": zero_shot.nearest_neighbour(inputs, thetas, queries),
                "affine": zero_shot.affine_regression(inputs, thetas, queries),
                "crkr": zero_shot.crkr(
                    inputs, thetas, queries, np.exp(-distances_of(training["rewards"][:k]))
                ),
            }
            distances = bench.distances(
                np.concatenate([predictions[m] for m in ZERO_SHOT_METHODS]),
                np.tile(grid, (len(ZERO_SHOT_METHODS), 1)),
            ).reshape(len(ZERO_SHOT_METHODS), len(grid))
            starts = [WarmStart(*template.distribution(tau)) for tau in grid]
            budget = bench.config.refine_rollouts
            results = bench.search(f"seed {seed}: K={k} refinement", starts, grid, budget, seed + 7 * k)
            refined = [r.curve()[min(budget, r.rollouts), 2] for r in results]
            return {
                **{f"zero_shot_{m}": d for m, d in zip(ZERO_SHOT_METHODS, distances, strict=True)},
                "refined": distances_of(np.array(refined)),
            }

        return self.folder.stage(f"seed{seed}_k{k}", compute)

    def variant_zero_shot(self, seed: int, k: int, variant: str) -> np.ndarray:
        """The grid distances of the template of the first k tasks of the variant's training set."""
        grid = self.bench.grid
        return self.folder.stage(
            f"seed{seed}_{variant}_k{k}",
            lambda: {
                "distances": self.bench.distances(
                    self.templates.template(seed, k, variant).predict(grid)[0], grid
                )
            },
        )["distances"]
