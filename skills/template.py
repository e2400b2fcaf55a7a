"""Skill templates: Psi = (Theta, Omega), a primitive's parameters as a Gaussian over theta for any task tau.

Metzen et al. (KI 2014) generalise primitives learned in a few tasks tau_i (theta_i found by policy search)
into a skill template: Theta(tau) predicts theta for a new task of the class and Omega(tau) = Sigma_tau is
an exploration covariance for refining it further (CMA-ES started at N(Theta(tau), Sigma_tau)). Theta is
Gaussian-process regression (da Silva, Konidaris and Barto, ICML 2012 learn such "parameterised skills"
by regression).

Models of Theta and the per-coordinate variance (``model=``, :mod:`besman.skills.template_models`)
----------------------------------------------------------------------------------------------------
- ``"shared"`` (the default): one set of weights per query for whole training thetas (a GP with one
  correlation for every output and a constant mean), and a per-coordinate variance between the prior
  exploration (``prior_spread``, the spread a search without a template would use: far from the data and at
  K = 1 the template explores like that) and what the training thetas disagree about.
- ``"per_dimension"``: one GP per coordinate with its own hyperparameters by marginal likelihood, the model
  of the first reproduction, kept for comparisons.

tau is normalised to the task box ([0, 1] per coordinate) before a model sees it.

Exploration covariances (``exploration=``)
------------------------------------------
- ``"uncertainty"``: Sigma_jj = var_j(tau), the model's per-coordinate variance.
- ``"weight_proportional"``: Sigma_jj proportional to the typical |theta_j| of the training set (the mean
  of |theta_ij| over i), squared; scaled to the same total variance (trace) as the uncertainty kind at tau,
  so that the two differ in shape only.
- ``"isotropic"``: the same trace spread evenly over the coordinates (a baseline: the template's mean with
  an exploration that knows nothing of the coordinates).
- ``"correlated"`` (beyond the paper): the uncertainty kind's variances with the correlations of the
  training thetas (Ledoit-Wolf shrunk): Sigma = D R D.

A template is rebuilt from its training data and its hyperparameters (no pickles; see
:mod:`besman.skills.pool`). Its model is fitted, and its correlations estimated, when first used: reading a
template (listing a pool) checks its data but imports neither scipy nor scikit-learn.
"""

from __future__ import annotations

import copy
import functools
from typing import TYPE_CHECKING, Any

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import COUNT, SEED, checked, finite_array, instance, text
from besman.skills.primitive import MovementPrimitive
from besman.skills.shared_kernel import SharedKernel
from besman.skills.task_bounds import TaskBounds

if TYPE_CHECKING:
    from besman.skills.template_models import PerDimensionModel, SharedKernelModel

MODELS = ("shared", "per_dimension")
EXPLORATIONS = ("uncertainty", "weight_proportional", "isotropic", "correlated")


class SkillTemplate:
    """A skill template fitted from training pairs (tau_i, theta_i).

    Args:
        name: the template's name (its key in a pool).
        prototype: the primitive whose theta the template predicts (its DMP configuration: dimensions,
            execution time, start; and its metadata); instances are copies with theta = Theta(tau).
        taus: (K, m) training tasks; thetas: (K, n) the thetas learned for them.
        box: the names and box of the task parameters.
        model: ``"shared"`` or ``"per_dimension"`` (see the module documentation).
        kernel: the shared model's hyperparameters (default :class:`SharedKernel`).
        prior_spread: the shared model's prior exploration, a standard deviation per theta coordinate (n,)
            or one for all (>= 0; 0 for coordinates nobody explores); required for ``model="shared"``.
        exploration: the Omega kind (see the module documentation).
        hyperparameters: the per-dimension model's (n, p) fitted kernel parameters (log scale) to rebuild a
            stored template without refitting; None fits them (maximum marginal likelihood).
        seed: seed of the per-dimension model's optimiser restarts.
        task: what the template is for (e.g. "throwing/paper"); provenance: JSON-compatible facts.
    """

    @checked(
        name=text("a template name"),
        prototype=instance(MovementPrimitive, "a MovementPrimitive"),
        box=instance(TaskBounds, "a TaskBounds"),
        seed=SEED,
        task=text("a task name"),
    )
    def __init__(
        self,
        name: str,
        prototype: MovementPrimitive,
        taus,
        thetas,
        box: TaskBounds,
        *,
        model: str = "shared",
        kernel: SharedKernel | None = None,
        prior_spread=None,
        exploration: str = "uncertainty",
        hyperparameters=None,
        seed: int = 0,
        task: str = "",
        provenance: dict[str, Any] | None = None,
    ) -> None:
        if model not in MODELS:
            raise InputError(f"model must be one of {MODELS}, got {model!r}")
        if exploration not in EXPLORATIONS:
            raise InputError(f"exploration must be one of {EXPLORATIONS}, got {exploration!r}")
        taus, thetas = finite_array("taus", taus, ndim=2), finite_array("thetas", thetas, ndim=2)
        if len(taus) != len(thetas) or len(taus) == 0:
            raise InputError(f"need as many taus as thetas (at least one), got {len(taus)} and {len(thetas)}")
        if any(high <= low for low, high in zip(box.low, box.high, strict=True)):
            raise InputError(f"the task box must have low < high in every parameter, got {box.as_dict()}")
        if taus.shape[1] != len(box.names):
            raise InputError(f"taus have {taus.shape[1]} columns, the task box {len(box.names)}")
        if thetas.shape[1] != prototype.dmp.n_params:
            raise InputError(
                f"thetas have {thetas.shape[1]} entries, "
                f"the prototype {prototype.name!r} {prototype.dmp.n_params}"
            )
        self.name, self.prototype, self.box, self.exploration = name, prototype, box, exploration
        self.taus, self.thetas, self.seed, self.task = taus, thetas, seed, task
        self.provenance = dict(provenance or {})
        self.model_name = model
        if model == "shared":
            if hyperparameters is not None:
                raise InputError(
                    "hyperparameters= is the per-dimension model's; the shared one takes kernel="
                )
            if prior_spread is None:
                raise InputError("the shared model needs prior_spread (the exploration without a template)")
            spread = finite_array("prior_spread", prior_spread)
            spread = np.full(thetas.shape[1], float(spread)) if spread.ndim == 0 else spread
            if spread.shape != (thetas.shape[1],) or np.any(spread < 0):
                raise InputError(
                    f"prior_spread must be one standard deviation >= 0 or {thetas.shape[1]} of them, "
                    f"got shape {spread.shape}"
                )
            self.prior_spread = spread
            self.kernel: SharedKernel | None = kernel or SharedKernel()  # None for the per-dimension model
            self.kernel.check_inputs(taus)
        else:
            if kernel is not None or prior_spread is not None:
                raise InputError("kernel= and prior_spread= are the shared model's")
            self.prior_spread = None
            self.kernel = None
            self._given_hyperparameters = hyperparameters  # None: fitted with the model
        typical = np.abs(thetas).mean(axis=0)
        self._typical = np.where(typical > 0, typical, 1e-12)

    @functools.cached_property
    def model(self) -> SharedKernelModel | PerDimensionModel:
        """Theta's model (``model_name``), fitted on first use."""
        from besman.skills.template_models import PerDimensionModel, SharedKernelModel

        inputs = self.box.normalise(self.taus)
        if self.kernel is not None:
            return SharedKernelModel(inputs, self.thetas, self.kernel, self.prior_spread**2)
        return PerDimensionModel(inputs, self.thetas, self._given_hyperparameters, self.seed)

    @functools.cached_property
    def _correlation(self) -> np.ndarray:
        return _shrunk_correlation(self.thetas)

    @property
    def hyperparameters(self) -> np.ndarray:
        """The per-dimension model's (n, p) fitted kernel parameters (log scale)."""
        if self.kernel is not None:
            raise InputError(f"template {self.name!r}: the shared model has a kernel, not per-dimension GPs")
        return self.model.hyperparameters

    def with_exploration(self, exploration: str) -> SkillTemplate:
        """The same template (same GPs) with another Omega kind."""
        other = copy.copy(self)
        if exploration not in EXPLORATIONS:
            raise InputError(f"exploration must be one of {EXPLORATIONS}, got {exploration!r}")
        other.model = self.model  # fitted once, for both
        other.exploration = exploration
        return other

    def _taus(self, tau) -> np.ndarray:
        taus = finite_array("tau", tau)
        single = taus.ndim == 1
        taus = taus[None] if single else taus
        if taus.ndim != 2 or taus.shape[1] != len(self.box.names):
            raise InputError(
                f"tau must have {len(self.box.names)} entries ({', '.join(self.box.names)}), got {taus.shape}"
            )
        return taus

    def predict(self, tau) -> tuple[np.ndarray, np.ndarray]:
        """Theta(tau) and the per-coordinate variances, each (n,) for one tau or (N, n) for N."""
        means, variances = self.model.predict(self.box.normalise(self._taus(tau)))
        if np.ndim(tau) == 1:
            return means[0], variances[0]
        return means, variances

    def distribution(self, tau) -> tuple[np.ndarray, np.ndarray]:
        """(mean (n,), covariance (n, n)) over theta for one task tau."""
        if np.ndim(tau) != 1:
            raise InputError("distribution() takes one tau")
        mean, variance = self.predict(tau)
        if self.exploration == "uncertainty":
            return mean, np.diag(variance)
        if self.exploration == "weight_proportional":
            shape = self._typical**2
            return mean, np.diag(shape * variance.sum() / shape.sum())
        if self.exploration == "isotropic":
            return mean, np.diag(np.full(variance.size, variance.mean()))
        std = np.sqrt(variance)
        return mean, self._correlation * np.outer(std, std)

    @checked(count=COUNT, seed=SEED)
    def sample(self, tau, count: int, seed: int) -> np.ndarray:
        """``count`` thetas (count, n) drawn from N(Theta(tau), Omega(tau)); the same draws for the same
        template, tau and seed."""
        mean, covariance = self.distribution(tau)
        return np.random.default_rng(seed).multivariate_normal(mean, covariance, size=count, method="eigh")

    def instantiate(self, tau) -> MovementPrimitive:
        """A primitive for task tau: the prototype with theta = Theta(tau)."""
        mean, _ = self.predict(tau)
        return self.primitive(mean, tau)

    def primitive(self, theta, tau) -> MovementPrimitive:
        """The prototype with ``theta`` (e.g. a sample of :meth:`distribution`), labelled as made for tau."""
        primitive = copy.deepcopy(self.prototype)
        primitive.dmp.set_params(theta)
        primitive.provenance = {
            **primitive.provenance,
            "template": self.name,
            "tau": dict(zip(self.box.names, np.asarray(tau, float).tolist(), strict=True)),
        }
        return primitive

    def __repr__(self) -> str:
        return (
            f"SkillTemplate({self.name!r}, task={self.task!r}, K={len(self.taus)}, "
            f"theta={self.thetas.shape[1]}, model={self.model_name!r}, exploration={self.exploration!r})"
        )


def _shrunk_correlation(thetas: np.ndarray) -> np.ndarray:
    """The training thetas' correlation matrix, Ledoit-Wolf shrunk (identity with fewer than 3 tasks or
    for dimensions that never vary)."""
    n = thetas.shape[1]
    spread = thetas.std(axis=0)
    varying = spread > 1e-12 * max(1.0, float(np.abs(thetas).max()))
    correlation = np.eye(n)
    if len(thetas) < 3 or varying.sum() < 2:
        return correlation
    from sklearn.covariance import LedoitWolf  # 1 s to import: only for the "correlated" exploration

    standardised = (thetas[:, varying] - thetas[:, varying].mean(axis=0)) / spread[varying]
    covariance = LedoitWolf(assume_centered=True).fit(standardised).covariance_
    scale = np.sqrt(np.diag(covariance))
    correlation[np.ix_(varying, varying)] = covariance / np.outer(scale, scale)
    return correlation
