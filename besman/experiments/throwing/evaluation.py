"""Stage 3 of the throwing experiment on the grid, at each K: "No Learning" (theta_0 everywhere), every
zero-shot method (:mod:`besman.skills.zero_shot`: the paper's shared-kernel template, besman's outcome
template, the per-dimension template and the baselines; each prediction guarded, and thrown at the
validation targets too), the paper's template refined by CMA-ES, and the variants' templates zero shot.
Each is a stage of distances, one per grid target."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench, distances_of
from besman.experiments.throwing.config import ZERO_SHOT_METHODS
from besman.experiments.throwing.output import RunFolder
from besman.experiments.throwing.templates import Templates
from besman.experiments.throwing.training import TrainingSets
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
        """Every zero-shot method's distances at K = k on the grid and (``validation_*``) at the validation
        targets, each prediction guarded (``pulled_back_*``: how many the guard moved), and the template
        refined by CMA-ES from its guarded prediction, each refinement judged (``refinement_*``:
        :meth:`~besman.experiments.throwing.bench.ThrowingBench.verdicts`)."""

        def compute():
            bench, grid = self.bench, self.bench.grid
            targets = np.concatenate([grid, bench.validation])
            training = self.training.paper(seed)
            taus, thetas = training["taus"][:k], training["thetas"][:k]
            template = self.templates.template(seed, k)
            predictions = self._zero_shot_predictions(seed, k, template, targets)
            arrays, guarded = {}, {}
            for method in ZERO_SHOT_METHODS:
                guarded[method], arrays[f"pulled_back_{method}"] = bench.guarded_by_training(
                    predictions[method], taus, thetas, targets
                )
            distances = bench.distances(
                np.concatenate([guarded[m] for m in ZERO_SHOT_METHODS]),
                np.tile(targets, (len(ZERO_SHOT_METHODS), 1)),
            ).reshape(len(ZERO_SHOT_METHODS), len(targets))
            for method, row in zip(ZERO_SHOT_METHODS, distances, strict=True):
                arrays[f"zero_shot_{method}"], arrays[f"validation_{method}"] = (
                    row[: len(grid)],
                    row[len(grid) :],
                )
            starts = self.templates.starts(template, seed, k, grid)
            budget = bench.config.refine_rollouts
            results = bench.search(f"seed {seed}: K={k} refinement", starts, grid, budget, seed + 7 * k)
            refined = [r.curve()[min(budget, r.rollouts), 2] for r in results]
            verdicts = bench.verdicts(starts, results, grid, budget)
            return {**arrays, "refined": distances_of(np.array(refined)), **verdicts}

        return self.folder.stage(f"seed{seed}_k{k}", compute)

    def _zero_shot_predictions(
        self, seed: int, k: int, template: SkillTemplate, targets: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Every zero-shot method's thetas (before the guard) for ``targets`` from the first k training tasks,
        ``template`` the paper's of them (besman's outcome template: from every valid rollout of their
        searches)."""
        bench = self.bench
        training = self.training.paper(seed)
        taus, thetas = training["taus"][:k], training["thetas"][:k]
        inputs, queries = bench.task.bounds.normalise(taus), bench.task.bounds.normalise(targets)
        per_dimension = SkillTemplate(
            "throw", template.prototype, taus, thetas, bench.task.bounds, model="per_dimension", seed=seed
        )
        chosen = self.training.outcome_template(seed, k, targets)
        return {
            "template": template.predict(targets)[0],
            "outcome_template": training["outcome_thetas"][chosen],
            "per_dimension": per_dimension.predict(targets)[0],
            "training_mean": zero_shot.training_mean(inputs, thetas, queries),
            "nearest_neighbour": zero_shot.nearest_neighbour(inputs, thetas, queries),
            "affine": zero_shot.affine_regression(inputs, thetas, queries),
            "crkr": zero_shot.crkr(inputs, thetas, queries, np.exp(-distances_of(training["rewards"][:k]))),
        }

    def variant_zero_shot(self, seed: int, k: int, variant: str) -> np.ndarray:
        """The grid distances of the template of the first k tasks of the variant's training set."""
        return self.variant_stage(seed, k, variant)["distances"]

    def variant_stage(self, seed: int, k: int, variant: str) -> dict[str, np.ndarray]:
        """The variant's template's grid distances and how many of its predictions the guard pulled back."""
        grid = self.bench.grid

        def compute():
            data = self.training.of(seed, variant)
            predicted = self.templates.template(seed, k, variant).predict(grid)[0]
            guarded, moved = self.bench.guarded_by_training(
                predicted, data["taus"][:k], data["thetas"][:k], grid
            )
            return {"distances": self.bench.distances(guarded, grid), "pulled_back": np.array(moved)}

        return self.folder.stage(f"seed{seed}_{variant}_k{k}", compute)
