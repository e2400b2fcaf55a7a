"""The throwing experiment's settings: the protocol's numbers (:class:`ExperimentConfig`, fixed before a run)
and the names of the methods it compares, in the order ``results.json`` lists them."""

from __future__ import annotations

from dataclasses import dataclass

from besman.core.errors import InputError

SCHEMA_VERSION = 5  # 5: each refinement's verdict in the stages of K
# "template" is the paper's (Metzen et al. 2014), "outcome_template" besman's own.
ZERO_SHOT_METHODS = (
    "template",
    "outcome_template",
    "per_dimension",
    "training_mean",
    "nearest_neighbour",
    "affine",
    "crkr",
)
CURVE_METHODS = ("tabula_rasa", "weight_proportional", "uncertainty", "isotropic", "nearest_start")
CONTEXTUAL_METHODS = ("creps", "contextual_cmaes")
VARIANTS = ("bootstrapped", "goal_only")
# The registry's task that the experiment throws in, by ExperimentConfig.variant.
TASK_OF_VARIANT = {"paper": "throwing", "hardware": "throwing-hardware"}


@dataclass(frozen=True)
class ExperimentConfig:
    """The protocol's numbers (the defaults are the full run)."""

    seeds: int = 3
    ks: tuple[int, ...] = (1, 2, 4, 6, 8, 10, 14, 20)
    training_rollouts: int = 200
    grid: int = 8
    refine_rollouts: int = 25
    curve_k: int = 10
    curve_rollouts: int = 68
    spreads: tuple[float, ...] = (0.1, 0.2, 0.3, 0.5, 1.0)
    validation_targets: int = 8
    jacobian_step: float = 0.05
    outcome_throws: int = 4
    contextual_rollouts: int = 3600
    contextual_checkpoint: int = 400
    selection_searches: int = 3  # per contextual candidate (throwing_contextual)
    method: str = "cmaes"
    variant: str = "paper"

    def __post_init__(self) -> None:
        if self.variant not in TASK_OF_VARIANT:
            raise InputError(f"variant must be one of {', '.join(TASK_OF_VARIANT)}, got {self.variant!r}")
        if self.seeds < 1 or self.grid < 2 or min(self.ks, default=0) < 1:
            raise InputError("need at least one seed, a grid of at least 2 x 2 and training sets of K >= 1")
        if list(self.ks) != sorted(set(self.ks)):
            raise InputError(f"ks must be increasing, got {self.ks}")
        if self.curve_k not in self.ks:
            raise InputError(f"curve_k {self.curve_k} must be one of ks {self.ks}")
        if not self.spreads or min(self.spreads) <= 0 or self.validation_targets < 1:
            raise InputError("need positive candidate spreads and at least one validation target")
        budgets = (self.training_rollouts, self.refine_rollouts, self.curve_rollouts, self.outcome_throws)
        if min(budgets) < 1:
            raise InputError("rollout budgets must be at least 1")
        if not 1 <= self.contextual_checkpoint <= self.contextual_rollouts:
            raise InputError("contextual_checkpoint must be between 1 and contextual_rollouts")
        if self.selection_searches < 1:
            raise InputError(f"selection_searches must be at least 1, got {self.selection_searches}")
        if not self.jacobian_step > 0:
            raise InputError(f"jacobian_step must be > 0, got {self.jacobian_step!r}")

    @classmethod
    def quick(cls, seeds: int = 1) -> ExperimentConfig:
        """A small run for tests (under a minute): 3 x 3 grid, K in (1, 2, 4), short searches, one validation
        target inside the box and one on its edge."""
        return cls(
            seeds=seeds,
            ks=(1, 2, 4),
            training_rollouts=17,
            grid=3,
            refine_rollouts=12,  # passed by CMA-ES's one generation of 17: the best within the budget counts
            curve_k=4,
            curve_rollouts=17,
            spreads=(0.1, 1.0),
            validation_targets=1,
            outcome_throws=2,
            contextual_rollouts=102,
            contextual_checkpoint=51,
            selection_searches=2,
        )
