"""Skill templates: Psi = (Theta, Omega), a primitive's parameters as a Gaussian over theta for any task tau.

Metzen et al. (KI 2014) generalise primitives learned in a few tasks tau_i (theta_i found by policy search)
into a skill template: Theta(tau) predicts theta for a new task of the class and Omega(tau) = Sigma_tau is
an exploration covariance for refining it further (CMA-ES started at N(Theta(tau), Sigma_tau)). Theta is
Gaussian-process regression (da Silva, Konidaris and Barto, ICML 2012 learn such "parameterised skills"
by regression).

One GP per theta dimension
--------------------------
A single GP with one kernel over all outputs (scikit-learn's multi-output ``GaussianProcessRegressor``)
gives every output the same predictive variance up to a constant factor: the variance depends only on the
kernel and the training inputs, never on the outputs. Every dimension would then be equally uncertain in
shape (the "shared-kernel trap"), although some parameters vary smoothly with tau, some erratically and
some not at all. Here each dimension j has its own GP - amplitude, length scales per tau coordinate and
noise level, fitted by maximum marginal likelihood - so var_j(tau) has its own shape: a parameter that
is the same in every training task has almost no variance anywhere, one that the training tasks disagree
about keeps a noise floor, and all of them grow towards their prior variance away from the training tasks
(extrapolation is allowed; its growing uncertainty is the point).

tau is normalised to the task box ([0, 1] per coordinate) before the GPs see it; outputs are standardised
(``normalize_y``). Kernel: C * RBF(anisotropic) + White, with bounds that keep the length scales between
1/20 and 20 box widths.

Exploration covariances (``exploration=``)
------------------------------------------
- ``"uncertainty"``: Sigma_jj = var_j(tau), the GP's predictive variance (noise included: the theta_i are
  themselves noisy outcomes of a stochastic search).
- ``"weight_proportional"``: Sigma_jj proportional to the typical |theta_j| of the training set (the mean
  of |theta_ij| over i), squared; scaled to the same total variance (trace) as the uncertainty kind at tau,
  so that the two differ in shape only.
- ``"correlated"`` (beyond the paper): the uncertainty kind's variances with the correlations of the
  training thetas (Ledoit-Wolf shrunk): Sigma = D R D. Parameters that moved together between the training
  tasks are explored together, along the directions that change the task outcome.

A template is rebuilt from its training data and its fitted hyperparameters (no pickles; see
:mod:`besman.skills.pool`).
"""

from __future__ import annotations

import copy
import warnings
from typing import Any

import numpy as np
from sklearn.covariance import LedoitWolf
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Kernel, WhiteKernel

from besman.skills.errors import InputError
from besman.skills.primitive import MovementPrimitive
from besman.skills.tasks import TaskBounds
from besman.skills.validation import finite_array

EXPLORATIONS = ("uncertainty", "weight_proportional", "correlated")
LENGTH_SCALE_BOUNDS = (0.05, 20.0)  # in box widths
AMPLITUDE_BOUNDS = (1e-4, 1e2)  # of the standardised outputs
NOISE_BOUNDS = (1e-8, 1.0)


def default_kernel(tau_dims: int) -> Kernel:
    """C * RBF (one length scale per tau coordinate) + White, on normalised tau and standardised theta."""
    return ConstantKernel(1.0, AMPLITUDE_BOUNDS) * RBF(
        np.full(tau_dims, 0.5), LENGTH_SCALE_BOUNDS
    ) + WhiteKernel(1e-2, NOISE_BOUNDS)


class SkillTemplate:
    """A skill template fitted from training pairs (tau_i, theta_i).

    Args:
        name: the template's name (its key in a pool).
        prototype: the primitive whose theta the template predicts (its DMP configuration: dimensions,
            execution time, start; and its metadata); instances are copies with theta = Theta(tau).
        taus: (K, m) training tasks; thetas: (K, n) the thetas learned for them.
        box: the names and box of the task parameters.
        exploration: the Omega kind (see the module documentation).
        hyperparameters: (n, p) fitted kernel parameters (log scale, scikit-learn's ``kernel.theta``) to
            rebuild a stored template without refitting; None fits them (maximum marginal likelihood).
        seed: seed of the optimiser restarts when fitting.
        task: what the template is for (e.g. "throwing/paper"); provenance: JSON-compatible facts.
    """

    def __init__(
        self,
        name: str,
        prototype: MovementPrimitive,
        taus,
        thetas,
        box: TaskBounds,
        *,
        exploration: str = "uncertainty",
        hyperparameters=None,
        seed: int = 0,
        task: str = "",
        provenance: dict[str, Any] | None = None,
    ) -> None:
        if exploration not in EXPLORATIONS:
            raise InputError(f"exploration must be one of {EXPLORATIONS}, got {exploration!r}")
        taus, thetas = finite_array("taus", taus, ndim=2), finite_array("thetas", thetas, ndim=2)
        if len(taus) != len(thetas) or len(taus) == 0:
            raise InputError(f"need as many taus as thetas (at least one), got {len(taus)} and {len(thetas)}")
        if any(high <= low for low, high in zip(box.low, box.high, strict=True)):
            raise InputError(f"the task box must have low < high in every parameter, got {box.as_dict()}")
        if taus.shape[1] != len(box.names):
            raise InputError(f"taus have {taus.shape[1]} columns, the task box {len(box.names)}")
        if thetas.shape[1] != prototype.theta.size:
            raise InputError(
                f"thetas have {thetas.shape[1]} entries, "
                f"the prototype {prototype.name!r} {prototype.theta.size}"
            )
        self.name, self.prototype, self.box, self.exploration = name, prototype, box, exploration
        self.taus, self.thetas, self.seed, self.task = taus, thetas, seed, task
        self.provenance = dict(provenance or {})
        inputs = box.normalise(taus)
        if hyperparameters is None:
            self._gps = [self._fit(inputs, thetas[:, j], seed + j) for j in range(thetas.shape[1])]
        else:
            hyperparameters = finite_array("hyperparameters", hyperparameters, ndim=2)
            kernel = default_kernel(taus.shape[1])
            if hyperparameters.shape != (thetas.shape[1], kernel.theta.size):
                raise InputError(
                    f"hyperparameters must have shape {(thetas.shape[1], kernel.theta.size)}, "
                    f"got {hyperparameters.shape}"
                )
            self._gps = [
                GaussianProcessRegressor(kernel.clone_with_theta(row), optimizer=None, normalize_y=True).fit(
                    inputs, thetas[:, j]
                )
                for j, row in enumerate(hyperparameters)
            ]
        typical = np.abs(thetas).mean(axis=0)
        self._typical = np.where(typical > 0, typical, 1e-12)
        self._correlation = _shrunk_correlation(thetas)

    @staticmethod
    def _fit(inputs: np.ndarray, values: np.ndarray, seed: int) -> GaussianProcessRegressor:
        gp = GaussianProcessRegressor(
            default_kernel(inputs.shape[1]), normalize_y=True, n_restarts_optimizer=2, random_state=seed
        )
        with warnings.catch_warnings():  # hyperparameters at a bound are expected (e.g. a constant theta_j)
            warnings.simplefilter("ignore", ConvergenceWarning)
            return gp.fit(inputs, values)

    @property
    def hyperparameters(self) -> np.ndarray:
        """(n, p): each dimension's fitted kernel parameters (log scale)."""
        return np.array([gp.kernel_.theta for gp in self._gps])

    def with_exploration(self, exploration: str) -> SkillTemplate:
        """The same template (same GPs) with another Omega kind."""
        other = copy.copy(self)
        if exploration not in EXPLORATIONS:
            raise InputError(f"exploration must be one of {EXPLORATIONS}, got {exploration!r}")
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
        """Theta(tau) and the per-dimension predictive variances, each (n,) for one tau or (N, n) for N."""
        taus = self._taus(tau)
        inputs = self.box.normalise(taus)
        means, variances = np.empty((len(taus), len(self._gps))), np.empty((len(taus), len(self._gps)))
        for j, gp in enumerate(self._gps):
            means[:, j], std = gp.predict(inputs, return_std=True)
            variances[:, j] = std**2
        variances = np.maximum(variances, 1e-300)  # a covariance must stay positive definite
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
        std = np.sqrt(variance)
        return mean, self._correlation * np.outer(std, std)

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
            f"theta={self.thetas.shape[1]}, exploration={self.exploration!r})"
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
    standardised = (thetas[:, varying] - thetas[:, varying].mean(axis=0)) / spread[varying]
    covariance = LedoitWolf(assume_centered=True).fit(standardised).covariance_
    scale = np.sqrt(np.diag(covariance))
    correlation[np.ix_(varying, varying)] = covariance / np.outer(scale, scale)
    return correlation
