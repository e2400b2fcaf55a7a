"""Stage 0 of the throwing experiment: the spread of each method that starts its searches with a spread of
its own (tabula rasa, and CMA-ES from the nearest training theta), chosen by one procedure on the validation
targets, never on the grid (protocol step 0 in :mod:`besman.experiments.throwing.experiment`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.output import RunFolder
from besman.learning.search.policy_search import WarmStart


@dataclass
class Spreads:
    """The chosen spreads, with every candidate's area under the curve and the rollouts spent."""

    bench: ThrowingBench
    folder: RunFolder

    def tabula_rasa(self) -> dict[str, np.ndarray]:
        """theta_0's spread, which the training searches, the templates' prior exploration and the
        contextual methods' start use too."""
        return self._choose(
            "tabula_rasa", lambda: np.tile(self.bench.theta0, (len(self.bench.validation), 1))
        )

    @property
    def tabula_rasa_spread(self) -> float:
        return float(self.tabula_rasa()["chosen"])

    def nearest_start(
        self, nearest_thetas: Callable[[int, int, np.ndarray], np.ndarray]
    ) -> dict[str, np.ndarray]:
        """The spread of CMA-ES from the nearest of seed 0's first ``curve_k`` training thetas
        (``nearest_thetas``: the training sets', which start with tabula rasa's spread)."""
        return self._choose(
            "nearest_start", lambda: nearest_thetas(0, self.bench.config.curve_k, self.bench.validation)
        )

    def _choose(self, method: str, start_means: Callable[[], np.ndarray]) -> dict[str, np.ndarray]:
        """For each candidate spread, CMA-ES from ``start_means`` at the validation targets; the lowest area
        under the learning curve wins."""

        def compute():
            config, means = self.bench.config, start_means()
            scores, rollouts = [], 0
            for i, spread in enumerate(config.spreads):
                starts = [WarmStart(mean, spread) for mean in means]
                curves = self.bench.curves(
                    f"{method} spread {spread:g}", starts, self.bench.validation, 31 * i + 7
                )
                scores.append(curves[:, 1:].mean())
                rollouts += len(starts) * config.curve_rollouts
            return {
                "spreads": np.array(config.spreads),
                "scores": np.array(scores),
                "chosen": np.array(config.spreads[int(np.argmin(scores))]),
                "rollouts": np.array(rollouts),
            }

        return self.folder.stage(f"spread_{method}", compute)
