"""The maths under linear-Gaussian upper-level policies pi(theta | s) = N(W phi(s), Sigma), which the
contextual optimisers of :mod:`besman.learning.search.contextual` fit:

- :func:`context_features` - phi(s), affine or quadratic in the context, the constant first;
- :func:`weighted_ridge` - weighted ridge regression toward a prior, the fit of W (and of reward baselines);
- :func:`solve_creps_dual` - C-REPS's dual (Kupcsik et al., AAAI 2013; Artificial Intelligence 247, 2017),
  whose minimiser weights rollouts by d_i = exp((R_i - V(s_i)) / eta) under a KL bound epsilon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array

FeatureKind = Literal["affine", "quadratic"]
FEATURE_KINDS = ("affine", "quadratic")


def context_features(contexts: np.ndarray, kind: FeatureKind) -> np.ndarray:
    """Features (N, k) of contexts (N, m): affine [1, s] (k = 1 + m) or quadratic [1, s, s_i s_j for i <= j]
    (k = 1 + m + m (m + 1) / 2). The constant comes first."""
    columns = [np.ones((len(contexts), 1)), contexts]
    if kind == "quadratic":
        rows, cols = np.triu_indices(contexts.shape[1])
        columns.append(contexts[:, rows] * contexts[:, cols])
    return np.hstack(columns)


def weighted_ridge(
    features: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    ridge: float,
    prior: np.ndarray | None = None,
) -> np.ndarray:
    """Coefficients B (k, ...) minimising sum_i w_i ||targets_i - features_i^T B||^2 + ridge ||B - prior||^2
    (prior zero if None).

    Weights should sum to one, so that ``ridge`` is relative to a unit of data weight.
    """
    weighted = features * weights[:, None]
    gram = weighted.T @ features + ridge * np.eye(features.shape[1])
    if prior is None:
        return np.linalg.solve(gram, weighted.T @ targets)
    return prior + np.linalg.solve(gram, weighted.T @ (targets - features @ prior))


@dataclass(frozen=True)
class DualSolution:
    """The C-REPS dual's minimiser, in the caller's reward units.

    Attributes:
        weights: d_i / sum(d) (N,), the rollouts' normalised weights.
        eta: the temperature.
        baseline: v (k,), the coefficients of the context baseline V(s) = v^T psi(s).
    """

    weights: np.ndarray
    eta: float
    baseline: np.ndarray


def solve_creps_dual(
    baseline_features: np.ndarray, rewards: np.ndarray, epsilon: float, min_eta: float = 1e-8
) -> DualSolution:
    """Minimises the C-REPS dual g(eta, v) over eta >= min_eta (in normalised reward units) and v.

    ``baseline_features`` psi(s_i) (N, k) must have the constant first. The minimiser is equivariant under
    positive affine reward transforms and under adding any v_0^T psi(s) to the rewards (v absorbs it), so the
    problem is solved for normalised rewards: minus a least-squares baseline fitted to the better half of the
    rollouts (rewards >= their median, so huge penalties do not pull it), divided by the standard deviation of
    the better half's residuals (of all, if those are tied; 1 if all are). That keeps eta near 1 also when
    the rewards mostly vary with the context, and failures far below get zero weight without overflow.
    """
    baseline_features = finite_array("baseline_features", baseline_features, ndim=2)
    count = len(baseline_features)
    rewards = finite_array("rewards", rewards, shape=(count,))
    if count < 2 or not epsilon > 0 or not min_eta > 0:
        raise InputError(
            f"the dual needs >= 2 rollouts, epsilon > 0 and min_eta > 0, got {count}, {epsilon}, {min_eta}"
        )
    better = rewards >= np.median(rewards)
    offset = np.linalg.lstsq(baseline_features[better], rewards[better])[0]
    residuals = rewards - baseline_features @ offset
    scale = next((s for s in (np.std(residuals[better]), np.std(residuals)) if s > 0), 1.0)
    normalised = residuals / scale
    feature_mean = baseline_features.mean(axis=0)

    def temperature(log_excess: float) -> float:
        return min_eta + math.exp(min(log_excess, 700.0))  # a line search may overshoot

    def weights_and_exponents(eta: float, baseline: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """softmax(exponents), exponents = (R - v^T psi) / eta, and log mean exp(exponents)."""
        exponents = (normalised - baseline_features @ baseline) / eta
        largest = exponents.max()
        weights = np.exp(exponents - largest)
        total = weights.sum()
        return weights / total, exponents, largest + math.log(total / count)

    def dual(x: np.ndarray) -> tuple[float, np.ndarray]:
        """g and its gradient in (log(eta - min_eta), v): unconstrained, so BFGS needs no bounds."""
        eta, baseline = temperature(x[0]), x[1:]
        weights, exponents, log_mean_exp = weights_and_exponents(eta, baseline)
        value = eta * (epsilon + log_mean_exp) + baseline @ feature_mean
        gradient_eta = epsilon + log_mean_exp - weights @ exponents
        gradient_baseline = feature_mean - weights @ baseline_features
        return value, np.concatenate([[gradient_eta * (eta - min_eta)], gradient_baseline])

    from scipy.optimize import minimize  # here, not with the module, which besman.learning imports (0.5 s)

    solution = minimize(dual, np.zeros(1 + baseline_features.shape[1]), jac=True, method="BFGS").x
    eta, baseline = temperature(solution[0]), solution[1:]
    weights = weights_and_exponents(eta, baseline)[0]
    return DualSolution(weights, float(eta * scale), offset + scale * baseline)
