"""Stage 3 of the throwing experiment, the searches on the grid: learning curves at K = ``curve_k`` (CMA-ES
tabula rasa, from the template with each of its explorations, and from the nearest training theta), and
contextual policy search (:mod:`besman.learning.contextual_search`: one policy over the box, its mean thrown
on the grid at every checkpoint)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.learning.contextual_search import CREPS, ContextBox, ContextualCMAES, contextual_search
from besman.learning.policy_search import WarmStart
from besman.learning.throwing_bench import ThrowingBench
from besman.learning.throwing_config import CURVE_METHODS
from besman.learning.throwing_output import RunFolder
from besman.learning.throwing_spreads import Spreads
from besman.learning.throwing_templates import Templates
from besman.learning.throwing_training import TrainingSets


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
                spread = float(self.spreads.nearest_start(self.training)["chosen"])
                starts = [WarmStart(mean, spread) for mean in means]
            else:
                template = self.templates.template(seed, k).with_exploration(method)
                starts = [WarmStart(*template.distribution(tau)) for tau in bench.grid]
            offset = 1000 + CURVE_METHODS.index(method)
            return {
                "distances": bench.curves(f"seed {seed}: {method}", starts, bench.grid, seed * 7919 + offset)
            }

        return self.folder.stage(f"seed{seed}_curve_{method}", compute)["distances"]

    def contextual(self, seed: int, method: str) -> dict[str, np.ndarray]:
        """The mean policy's grid distances at every checkpoint of a contextual search."""

        def compute():
            bench, bounds = self.bench, self.bench.task.bounds
            kind = {"creps": CREPS, "contextual_cmaes": ContextualCMAES}[method]
            box = ContextBox(np.array(bounds.low), np.array(bounds.high))
            optimizer = kind(
                bench.theta0, self.spreads.tabula_rasa_spread, seed=seed * 131 + 17, context_box=box
            )
            rows, checkpoints = [], []

            def on_checkpoint(rollouts, policy):
                checkpoints.append(rollouts)
                rows.append(bench.distances(policy.policy_mean(bench.grid), bench.grid))

            with bench.bar(f"seed {seed}: {method}", bench.config.contextual_rollouts) as bar:
                contextual_search(
                    bench.rewards,
                    optimizer,
                    budget=bench.config.contextual_rollouts,
                    sample_contexts=lambda rng, count: rng.uniform(
                        bounds.low, bounds.high, (count, bounds.size)
                    ),
                    seed=seed * 977 + 3,
                    checkpoint_every=bench.config.contextual_checkpoint,
                    on_checkpoint=on_checkpoint,
                    progress=bar.update,
                )
            return {"rollouts": np.array(checkpoints), "distances": np.array(rows)}

        return self.folder.stage(f"seed{seed}_{method}", compute)
