"""Stage 3 of the throwing experiment, the searches on the grid at K = ``curve_k``: learning curves of CMA-ES
(tabula rasa, from the paper's template with each of its explorations, from the nearest training theta),
every start mean guarded; and besman's outcome-space refinement
(:mod:`besman.learning.search.outcome_refinement`) from its outcome template's prediction, a few throws
each."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.config import CURVE_METHODS
from besman.experiments.throwing.output import RunFolder
from besman.experiments.throwing.spreads import Spreads
from besman.experiments.throwing.templates import Templates
from besman.experiments.throwing.training import TrainingSets
from besman.learning.search.outcome_refinement import refine_in_outcome_space
from besman.learning.search.policy_search import WarmStart

OUTCOME_STEP_CAP = 1.0  # m: how far one step may move the landing the linear model predicts


@dataclass
class LearningCurves:
    """The learning curves of a seed's searches on the grid, one method at a time."""

    bench: ThrowingBench
    folder: RunFolder
    spreads: Spreads
    training: TrainingSets
    templates: Templates

    def curves(self, seed: int, method: str) -> np.ndarray:
        """(grid targets, curve_rollouts + 1) distances of the best rollout so far."""

        def compute():
            bench, k = self.bench, self.bench.config.curve_k
            if method == "tabula_rasa":
                starts = [WarmStart(bench.theta0, self.spreads.tabula_rasa_spread)] * len(bench.grid)
            elif method == "nearest_start":
                means = self.training.nearest_thetas(seed, k, bench.grid)
                spread = float(self.spreads.nearest_start(self.training.nearest_thetas)["chosen"])
                starts = [WarmStart(mean, spread) for mean in means]
            else:
                template = self.templates.template(seed, k).with_exploration(method)
                starts = self.templates.starts(template, seed, k, bench.grid)
            offset = 1000 + CURVE_METHODS.index(method)
            return {
                "distances": bench.curves(f"seed {seed}: {method}", starts, bench.grid, seed * 7919 + offset)
            }

        return self.folder.stage(f"seed{seed}_curve_{method}", compute)["distances"]

    def outcome_refinement(self, seed: int) -> np.ndarray:
        """(grid targets, outcome_throws + 1) distances of the best landing so far: from the outcome
        template's prediction (column 0, its stored landing: no throw) with the Jacobian of the training task
        its rollout came from."""

        def compute():
            bench, k, grid = self.bench, self.bench.config.curve_k, self.bench.grid
            training, jacobians = self.training.paper(seed), self.training.jacobians(seed)
            chosen = self.training.outcome_template(seed, k, grid)
            throws = bench.config.outcome_throws
            with bench.bar(f"seed {seed}: outcome-space refinement", throws * len(grid)) as bar:

                def trial(thetas, targets):
                    bar.update(len(thetas))
                    return bench.throws(thetas, targets)[1]

                distances = refine_in_outcome_space(
                    trial,
                    lambda thetas, anchors: bench.guarded(thetas, anchors)[0],
                    training["outcome_thetas"][chosen],
                    training["outcome_landings"][chosen],
                    jacobians["jacobians"][training["outcome_tasks"][chosen]],
                    grid,
                    bench.goal_entries,
                    throws,
                    OUTCOME_STEP_CAP,
                )
            return {"distances": distances}

        return self.folder.stage(f"seed{seed}_outcome_refinement", compute)["distances"]
