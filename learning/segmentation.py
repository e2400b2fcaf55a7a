"""Bayesian multiple change-point segmentation (Fearnhead and Liu, JRSS B 2007), exact and offline.

A recording y (T samples, d dimensions) is cut into segments; each segment follows one of several linear
regression models q (polynomials in the time since the segment started: a hold is degree 0, a movement
degree 3 or 5) with conjugate priors: coefficients beta | Sigma ~ MN(0, D, Sigma), noise Sigma ~ IW(nu,
Gamma). The segment evidence then has the closed form (matrix-normal / inverse-Wishart; for d = 1 it is a
multivariate Student-t density)::

    log P = -(n d / 2) log pi + (d / 2)(log|M| - log|D|) + (nu / 2) log|Gamma| - ((n + nu) / 2) log|Gamma + S|
            + sum_i [lnGamma((n + nu + 1 - i) / 2) - lnGamma((nu + 1 - i) / 2)]

with M = (H^T H + D^-1)^-1, B = H^T Y, S = Y^T Y - B^T M B. Because the basis depends only on the time since
the segment's start, H^T H depends only on the length and H^T Y grows by rank-1 updates, so the evidence of
every segment [j, t) is computed for all j at once as t advances (O(T^2) evidences, vectorised over j).

Segment lengths have a geometric prior with hazard ``1 / expected length`` beyond a minimum length. From the
evidences: the MAP segmentation (Viterbi), the posterior probability of a change point at every sample
(forward-backward), and exact samples from the posterior (backward filtering, forward sampling).
Hyperparameters default to data-driven values: the noise scale from the first differences of the data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln, logsumexp


@dataclass(frozen=True)
class SegmentModel:
    """A polynomial regression of ``degree`` in the time since the segment began (seconds)."""

    name: str
    degree: int


HOLD = SegmentModel("hold", 0)
MOVE = SegmentModel("move", 3)
DEFAULT_MODELS = (HOLD, SegmentModel("move", 3), SegmentModel("move quintic", 5))
# Prior standard deviations of the polynomial coefficients (units of y per s^a), before the noise scale:
# position ~1, velocity ~1/s, acceleration/2 ~5/s^2, jerk/6 ~20/s^3, ...
COEFFICIENT_SCALES = (1.0, 1.0, 5.0, 20.0, 50.0, 100.0)


@dataclass(frozen=True)
class SegmentationPrior:
    """Hyperparameters. ``noise`` None means: estimated from the data's first differences."""

    noise: float | None = None  # expected noise standard deviation per dimension
    nu: float | None = None  # inverse-Wishart degrees of freedom (default d + 2)
    expected_length: float = 1.0  # s, mean segment length beyond the minimum (geometric prior)
    min_length: float = 0.15  # s, shortest segment


def noise_scale(y: np.ndarray) -> float:
    """White-noise standard deviation estimated from first differences (median absolute deviation)."""
    differences = np.diff(y, axis=0)
    mad = np.median(np.abs(differences - np.median(differences, axis=0)), axis=0)
    return float(max(np.mean(mad) * 1.4826 / math.sqrt(2.0), 1e-12))


def segment_evidences(
    y: np.ndarray, rate: float, model: SegmentModel, prior: SegmentationPrior
) -> np.ndarray:
    """E (T+1, T+1): E[j, t] = log P(y[j:t] | one segment of ``model``) for j < t (-inf elsewhere)."""
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_samples, d = y.shape
    sigma = prior.noise if prior.noise is not None else noise_scale(y)
    nu = prior.nu if prior.nu is not None else d + 2.0
    gamma = nu * sigma**2  # Gamma = gamma I: Sigma is a priori of the order of sigma^2 I
    m = model.degree + 1
    scales = np.array(COEFFICIENT_SCALES[:m]) / sigma  # beta ~ N(0, Sigma D): D in units of the noise
    log_det_d = float(np.sum(np.log(scales**2)))
    offsets = np.arange(n_samples) / rate
    basis = offsets[:, None] ** np.arange(m)[None, :]  # h(tau) at tau = i / rate
    gram = np.cumsum(basis[:, :, None] * basis[:, None, :], axis=0)  # H^T H for lengths 1..T
    inverse_prior = np.diag(1.0 / scales**2)
    posterior = np.linalg.inv(gram + inverse_prior)  # M for lengths 1..T
    log_det_m = np.linalg.slogdet(posterior)[1]
    lengths = np.arange(1, n_samples + 1)
    constant = (
        -(lengths * d / 2.0) * math.log(math.pi)
        + (d / 2.0) * (log_det_m - log_det_d)
        + (nu / 2.0) * d * math.log(gamma)
        + sum(gammaln((lengths + nu + 1 - i) / 2.0) - gammaln((nu + 1 - i) / 2.0) for i in range(1, d + 1))
    )
    evidences = np.full((n_samples + 1, n_samples + 1), -np.inf)
    cross = np.zeros((n_samples, m, d))  # H^T Y of the segments [j, t) for every start j
    squares = np.zeros((n_samples, d, d))  # Y^T Y
    identity = gamma * np.eye(d)
    for t in range(1, n_samples + 1):
        starts = np.arange(t)
        row = y[t - 1]
        cross[:t] += basis[t - 1 - starts][:, :, None] * row[None, None, :]
        squares[:t] += np.outer(row, row)[None]
        n = t - starts  # segment lengths
        b = cross[:t]
        residual = squares[:t] - np.einsum("jmd,jmk,jke->jde", b, posterior[n - 1], b)
        log_det = np.linalg.slogdet(identity[None] + residual)[1]
        evidences[:t, t] = constant[n - 1] - ((n + nu) / 2.0) * log_det
    return evidences


def length_prior(n_samples: int, rate: float, prior: SegmentationPrior) -> tuple[np.ndarray, np.ndarray]:
    """log g(n) and log(1 - G(n - 1)) (the survival, for the last segment) for n = 0..T."""
    n = np.arange(n_samples + 1)
    minimum = max(1, round(prior.min_length * rate))
    hazard = min(1.0, 1.0 / max(prior.expected_length * rate, 1.0))
    extra = n - minimum
    log_g = np.where(
        extra >= 0, math.log(hazard) + extra * math.log1p(-hazard) if hazard < 1 else 0.0, -np.inf
    )
    if hazard >= 1:
        log_g = np.where(extra == 0, 0.0, -np.inf)
    log_survival = np.where(extra >= 0, extra * math.log1p(-hazard) if hazard < 1 else 0.0, -np.inf)
    return log_g, log_survival


@dataclass(frozen=True)
class SegmentationResult:
    """Change points (sample indices, starting with 0 and ending with T), the model of each segment, and
    optionally the posterior probability of a change point at every sample."""

    boundaries: np.ndarray
    models: tuple[str, ...]
    change_probability: np.ndarray | None = None
    log_evidence: float | None = None


def _combined(evidences: list[np.ndarray], model_prior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    stacked = np.stack(evidences) + model_prior[:, None, None]
    return logsumexp(stacked, axis=0), stacked


def map_segmentation(
    evidences: list[np.ndarray], log_g: np.ndarray, log_survival: np.ndarray, model_prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Viterbi over change points: boundaries and the index of each segment's model."""
    stacked = np.stack(evidences) + model_prior[:, None, None]
    n_samples = stacked.shape[1] - 1
    best = np.full(n_samples + 1, -np.inf)
    best[0] = 0.0
    back = np.zeros(n_samples + 1, dtype=int)
    choice = np.zeros(n_samples + 1, dtype=int)
    for t in range(1, n_samples + 1):
        lengths = t - np.arange(t)
        lengths_prior = log_survival[lengths] if t == n_samples else log_g[lengths]
        scores = best[:t, None] + stacked[:, :t, t].T + lengths_prior[:, None]  # (j, q)
        j, q = np.unravel_index(np.argmax(scores), scores.shape)
        best[t], back[t], choice[t] = scores[j, q], j, q
    boundaries, models, t = [n_samples], [], n_samples
    while t > 0:
        models.append(choice[t])
        t = back[t]
        boundaries.append(t)
    return np.array(boundaries[::-1]), np.array(models[::-1])


def change_probabilities(
    evidences: list[np.ndarray], log_g: np.ndarray, log_survival: np.ndarray, model_prior: np.ndarray
) -> tuple[np.ndarray, float, np.ndarray]:
    """Posterior probability of a change point at each sample (forward-backward), the log marginal
    likelihood, and the backward messages Q (log P(y[t:] | change point at t))."""
    combined, _ = _combined(evidences, model_prior)
    n_samples = combined.shape[0] - 1
    n = np.arange(n_samples + 1)
    lengths = n[None, :] - n[:, None]  # t - j
    valid = lengths > 0
    prior = np.where(valid, log_g[np.clip(lengths, 0, n_samples)], -np.inf)
    last = np.where(valid, log_survival[np.clip(lengths, 0, n_samples)], -np.inf)
    forward = np.full(n_samples + 1, -np.inf)
    forward[0] = 0.0
    for t in range(1, n_samples):
        forward[t] = logsumexp(forward[:t] + combined[:t, t] + prior[:t, t])
    backward = np.full(n_samples + 1, -np.inf)
    backward[n_samples] = 0.0
    for j in range(n_samples - 1, -1, -1):
        ends = np.arange(j + 1, n_samples + 1)
        terms = combined[j, ends] + np.where(
            ends == n_samples, last[j, ends], prior[j, ends] + backward[ends]
        )
        backward[j] = logsumexp(terms)
    marginal = float(backward[0])
    probability = np.exp(forward + backward - marginal)
    probability[0] = probability[n_samples] = 1.0
    return probability, marginal, backward


def sample_segmentations(
    evidences: list[np.ndarray],
    log_g: np.ndarray,
    log_survival: np.ndarray,
    model_prior: np.ndarray,
    count: int,
    seed: int,
) -> list[np.ndarray]:
    """Exact samples of the change points from the posterior (backward filtering, forward sampling)."""
    combined, _ = _combined(evidences, model_prior)
    n_samples = combined.shape[0] - 1
    _, _, backward = change_probabilities(evidences, log_g, log_survival, model_prior)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(count):
        points, j = [0], 0
        while j < n_samples:
            ends = np.arange(j + 1, n_samples + 1)
            lengths = ends - j
            terms = combined[j, ends] + np.where(
                ends == n_samples, log_survival[lengths], log_g[lengths] + backward[ends]
            )
            weights = np.exp(terms - logsumexp(terms))
            j = int(rng.choice(ends, p=weights / weights.sum()))
            points.append(j)
        samples.append(np.array(points))
    return samples
