"""Stage 2 of the throwing experiment: the paper's skill templates of the first K tasks of a training set -
the shared-kernel model (:mod:`besman.skills.template_models`), its kernel chosen by throws at the held-out
validation targets, half on the box's edges (:mod:`besman.learning.template_selection`; each prediction
guarded, the rollouts counted), its prior exploration the tabula-rasa spread."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.output import RunFolder
from besman.experiments.throwing.template_builder import TemplateBuilder
from besman.experiments.throwing.training import TrainingSets
from besman.learning.search.policy_search import WarmStart
from besman.learning.template_selection import choose_kernel
from besman.skills.shared_kernel import SharedKernel
from besman.skills.template import SkillTemplate


@dataclass
class Templates:
    """A seed's template of the first k tasks of a training set, with its kernel choice."""

    bench: ThrowingBench
    folder: RunFolder
    training: TrainingSets
    builder: TemplateBuilder

    def kernel_choice(self, seed: int, k: int, source: str = "training") -> dict[str, np.ndarray]:
        """The shared kernel for the first k tasks of ``source``, by throws at the validation targets; and
        how many of those predictions the guard pulled back."""

        def compute():
            bench, data = self.bench, self.training.of(seed, source)
            taus, thetas = data["taus"][:k], data["thetas"][:k]
            pulled_back = 0

            def loss(predicted, targets):
                nonlocal pulled_back
                guarded, moved = bench.guarded_by_training(predicted, taus, thetas, targets)
                pulled_back += moved
                return bench.distances(guarded, targets)

            choice = choose_kernel(taus, thetas, bench.task.bounds, bench.validation, loss)
            return {
                "kernel": np.array(json.dumps(asdict(choice.kernel))),
                "losses": np.array(choice.losses),
                "rollouts": np.array(choice.rollouts),
                "pulled_back": np.array(pulled_back),
            }

        return self.folder.stage(f"seed{seed}_{source}_k{k}_kernel", compute)

    def starts(self, template: SkillTemplate, seed: int, k: int, targets: np.ndarray) -> list[WarmStart]:
        """CMA-ES starts at ``targets`` from ``template`` (of the seed's first k training tasks): its mean,
        guarded toward the nearest training theta, and its exploration."""
        training = self.training.paper(seed)
        means, _ = self.bench.guarded_by_training(
            template.predict(targets)[0], training["taus"][:k], training["thetas"][:k], targets
        )
        return [
            WarmStart(mean, template.distribution(tau)[1]) for mean, tau in zip(means, targets, strict=True)
        ]

    def template(self, seed: int, k: int, source: str = "training") -> SkillTemplate:
        data = self.training.of(seed, source)
        kernel = SharedKernel(**json.loads(str(self.kernel_choice(seed, k, source)["kernel"])))
        template = self.builder.build(data["taus"][:k], data["thetas"][:k], kernel, source)
        template.provenance = {"experiment": "throwing", "seed": seed, "training_tasks": k, "source": source}
        return template
