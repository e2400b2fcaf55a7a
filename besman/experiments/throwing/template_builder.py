"""The throwing experiment's template maker: a skill template from training targets and thetas, its prior
exploration the spread of the set's source (used by the training sets, which bootstrap from templates of
their first tasks, and by stage 2, :mod:`besman.experiments.throwing.templates`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.spreads import Spreads
from besman.skills import MovementPrimitive
from besman.skills.shared_kernel import SharedKernel
from besman.skills.template import SkillTemplate


@dataclass
class TemplateBuilder:
    """Makes a template from training targets and thetas, its prior the spread of the set's source."""

    bench: ThrowingBench
    spreads: Spreads

    def build(self, taus, thetas, kernel: SharedKernel, source: str = "training") -> SkillTemplate:
        prototype = MovementPrimitive(self.bench.task.dmp, "throw", robot="pa10", group="arm")
        return SkillTemplate(
            "throw",
            prototype,
            taus,
            thetas,
            self.bench.task.bounds,
            kernel=kernel,
            prior_spread=self._prior_spread(source),
            task=f"throwing/{self.bench.config.variant}",
        )

    def _prior_spread(self, source: str) -> np.ndarray:
        theta0, spread = self.bench.theta0, self.spreads.tabula_rasa_spread
        prior = np.full(theta0.size, spread)
        if source == "goal_only":  # nothing else is ever searched
            prior = np.zeros(theta0.size)
            prior[self.bench.goal_entries] = spread
        return prior
