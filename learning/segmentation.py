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
from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammaln, logsumexp

from besman.learning.demonstration import Demonstration, DemonstrationError
from besman.learning.preprocessing import SmoothingConfig, resample, smooth


@dataclass(frozen=True)
class SegmentModel:
    """A linear regression model of one segment.

    Attributes:
        name: what the model stands for ("hold", "reach", ...).
        degree: polynomial terms 1, t, ..., t^degree in the time t since the segment began (s); -1: none.
        bumps: speed-bump terms s^a (1 - s)^b, each peaking at 1, in the normalised time s = (i + 1/2) / n
            of a segment of n samples; they stretch with the segment (a bell-shaped speed profile).
        bump_scale: prior standard deviation of a bump's height (units of y).
    """

    name: str
    degree: int = 0
    bumps: tuple[tuple[float, float], ...] = ()
    bump_scale: float = 2.0

    def basis(self, n: int, rate: float) -> np.ndarray:
        """H (n, m): the regressors of a segment of n samples."""
        offsets = np.arange(n) / rate
        columns = [offsets**power for power in range(self.degree + 1)]
        s = (np.arange(n) + 0.5) / n
        for a, b in self.bumps:
            peak = a / (a + b)
            columns.append(s**a * (1.0 - s) ** b / (peak**a * (1.0 - peak) ** b))
        return np.column_stack(columns)

    def scales(self) -> np.ndarray:
        """Prior standard deviations of the coefficients (units of y per s^power)."""
        return np.array(COEFFICIENT_SCALES[: self.degree + 1] + (self.bump_scale,) * len(self.bumps))


# Prior standard deviations of the polynomial coefficients (units of y per s^power, before the noise scale):
# position ~1, velocity ~1/s, acceleration/2 ~5/s^2, jerk/6 ~20/s^3, ...
COEFFICIENT_SCALES = (1.0, 1.0, 5.0, 20.0, 50.0, 100.0)

# Models of a position signal: a hold and smooth movements (minimum-jerk paths are quintic in time).
POLYNOMIAL_MODELS = (
    SegmentModel("hold", degree=0),
    SegmentModel("move", degree=3),
    SegmentModel("move quintic", degree=5),
)
# The vMCI velocity model: one bell-shaped speed bump on a constant.
VMCI = SegmentModel("vmci", degree=0, bumps=((2.0, 2.0),))
# Models of a speed signal (the default for hand recordings): a hold (constant speed) and single reaching
# movements whose speed rises from and falls back to zero, peaking in the middle, early or late; the last
# one's width adapts (two symmetric bumps of different sharpness).
SPEED_MODELS = (
    SegmentModel("hold", degree=0),
    SegmentModel("reach", degree=-1, bumps=((2.0, 2.0),)),
    SegmentModel("reach early peak", degree=-1, bumps=((2.0, 3.0),)),
    SegmentModel("reach late peak", degree=-1, bumps=((3.0, 2.0),)),
    SegmentModel("reach variable width", degree=-1, bumps=((2.0, 2.0), (3.0, 3.0))),
)


@dataclass(frozen=True)
class SegmentationPrior:
    """Hyperparameters. ``noise`` None means: estimated from the data's first differences."""

    noise: float | None = None  # expected noise standard deviation per dimension
    # With noise None: noise_factor x the first-difference estimate, because segments also deviate from
    # their model (a human's speed is not exactly a bump), not only by sensor noise.
    noise_factor: float = 2.0
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
    """E (T+1, T+1): E[j, t] = log P(y[j:t] | one segment of ``model``) for j < t (-inf elsewhere).

    For every segment length n the regressors H are fixed, so H^T Y of all segments of that length is a
    correlation of y with the columns of H, and Y^T Y a difference of cumulative sums.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_samples, d = y.shape
    sigma = prior.noise if prior.noise is not None else prior.noise_factor * noise_scale(y)
    nu = prior.nu if prior.nu is not None else d + 2.0
    gamma = nu * sigma**2  # Gamma = gamma I: Sigma is a priori of the order of sigma^2 I
    scales = model.scales() / sigma  # beta ~ N(0, Sigma D): D in units of the noise
    log_det_d = float(np.sum(np.log(scales**2)))
    inverse_prior = np.diag(1.0 / scales**2)
    outer = np.einsum("ta,tb->tab", y, y)
    cumulative = np.concatenate([np.zeros((1, d, d)), np.cumsum(outer, axis=0)])
    gamma_terms = sum(gammaln((nu + 1 - i) / 2.0) for i in range(1, d + 1))
    evidences = np.full((n_samples + 1, n_samples + 1), -np.inf)
    for n in range(1, n_samples + 1):
        basis = model.basis(n, rate)
        posterior = np.linalg.inv(basis.T @ basis + inverse_prior)  # M
        windows = np.lib.stride_tricks.sliding_window_view(y, n, axis=0)  # (T - n + 1, d, n)
        cross = np.einsum("jdn,nm->jmd", windows, basis)  # H^T Y of every segment of length n
        residual = cumulative[n:] - cumulative[:-n] - np.einsum("jmd,mk,jke->jde", cross, posterior, cross)
        log_det = np.linalg.slogdet(gamma * np.eye(d)[None] + residual)[1]
        constant = (
            -(n * d / 2.0) * math.log(math.pi)
            + (d / 2.0) * (np.linalg.slogdet(posterior)[1] - log_det_d)
            + (nu / 2.0) * d * math.log(gamma)
            + sum(gammaln((n + nu + 1 - i) / 2.0) for i in range(1, d + 1))
            - gamma_terms
        )
        starts = np.arange(n_samples - n + 1)
        evidences[starts, starts + n] = constant - ((n + nu) / 2.0) * log_det
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


def _stacked(evidences: list[np.ndarray], model_prior: np.ndarray) -> np.ndarray:
    """log P(y[j:t], model q) (Q, T+1, T+1)."""
    return np.stack(evidences) + model_prior[:, None, None]


def _end_terms(
    combined: np.ndarray, backward: np.ndarray, log_g: np.ndarray, log_survival: np.ndarray, j: int
) -> tuple[np.ndarray, np.ndarray]:
    """Every end t > j of a segment starting at change point j, and log P(y[j:t] as one segment, then the
    rest | change point at j)."""
    n_samples = combined.shape[0] - 1
    ends = np.arange(j + 1, n_samples + 1)
    lengths = ends - j
    terms = combined[j, ends] + np.where(
        ends == n_samples, log_survival[lengths], log_g[lengths] + backward[ends]
    )
    return ends, terms


def _backward(combined: np.ndarray, log_g: np.ndarray, log_survival: np.ndarray) -> np.ndarray:
    """Q[j] = log P(y[j:] | change point at j), from the end backwards."""
    n_samples = combined.shape[0] - 1
    backward = np.full(n_samples + 1, -np.inf)
    backward[n_samples] = 0.0
    for j in range(n_samples - 1, -1, -1):
        backward[j] = logsumexp(_end_terms(combined, backward, log_g, log_survival, j)[1])
    return backward


def map_segmentation(
    evidences: list[np.ndarray], log_g: np.ndarray, log_survival: np.ndarray, model_prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Viterbi over change points: boundaries and the index of each segment's model."""
    stacked = _stacked(evidences, model_prior)
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
    combined = logsumexp(_stacked(evidences, model_prior), axis=0)
    n_samples = combined.shape[0] - 1
    forward = np.full(n_samples + 1, -np.inf)
    forward[0] = 0.0
    for t in range(1, n_samples):
        forward[t] = logsumexp(forward[:t] + combined[:t, t] + log_g[t - np.arange(t)])
    backward = _backward(combined, log_g, log_survival)
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
    combined = logsumexp(_stacked(evidences, model_prior), axis=0)
    n_samples = combined.shape[0] - 1
    backward = _backward(combined, log_g, log_survival)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(count):
        points, j = [0], 0
        while j < n_samples:
            ends, terms = _end_terms(combined, backward, log_g, log_survival, j)
            weights = np.exp(terms - logsumexp(terms))
            j = int(rng.choice(ends, p=weights / weights.sum()))
            points.append(j)
        samples.append(np.array(points))
    return samples


@dataclass(frozen=True)
class Segmentation:
    """A demonstration cut into segments.

    Attributes:
        boundaries: sample indices of the demonstration, from 0 to T - 1; segment k runs from
            ``boundaries[k]`` to ``boundaries[k + 1]`` (consecutive segments share their boundary sample).
        times: the demonstration's times at the boundaries (s).
        frames: the demonstration's frame numbers at the boundaries.
        models: the name of each segment's model.
        signal_times, signal: the signal that was segmented (the smoothed hand speed, resampled).
        change_probability: posterior probability of a change point at each sample of ``signal``, when asked.
    """

    boundaries: np.ndarray
    times: np.ndarray
    frames: np.ndarray
    models: tuple[str, ...]
    signal_times: np.ndarray
    signal: np.ndarray
    change_probability: np.ndarray | None = field(default=None)

    def __len__(self) -> int:
        return len(self.models)


def segment(
    demo: Demonstration,
    *,
    marker: str = "Hand top",
    rate: float = 20.0,
    models: tuple[SegmentModel, ...] = SPEED_MODELS,
    prior: SegmentationPrior = SegmentationPrior(),
    smoothing: SmoothingConfig | None = None,
    posterior: bool = False,
) -> Segmentation:
    """Segments a demonstration by its hand speed: Kalman/RTS-smoothed ``marker`` speed, resampled at ``rate``
    (Hz), MAP segmentation under ``models`` with equal model priors; ``posterior`` adds the change-point
    probabilities. The defaults need no tuning per recording (the noise scale is estimated from the data).
    """
    speed = smooth(demo, marker, smoothing or SmoothingConfig()).speed
    signal_times, signal = resample(demo.times, speed, rate)
    minimum = max(1, round(prior.min_length * rate))
    if len(signal) < 2 * minimum:
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: the recording lasts {demo.duration:.2f} s, shorter than two "
            f"segments of the minimum length {prior.min_length:g} s"
        )
    evidences = [segment_evidences(signal, rate, model, prior) for model in models]
    log_g, log_survival = length_prior(len(signal), rate, prior)
    model_prior = np.full(len(models), -math.log(len(models)))
    points, choices = map_segmentation(evidences, log_g, log_survival, model_prior)
    probability = change_probabilities(evidences, log_g, log_survival, model_prior)[0] if posterior else None
    boundary_times = np.r_[signal_times, demo.times[-1]][points]
    indices = np.clip(np.searchsorted(demo.times, boundary_times - 0.5 / demo.rate), 0, len(demo.times) - 1)
    return Segmentation(
        boundaries=indices,
        times=demo.times[indices],
        frames=demo.frames[indices],
        models=tuple(models[q].name for q in choices),
        signal_times=signal_times,
        signal=signal,
        change_probability=probability,
    )


def boundary_f1(truth: np.ndarray, predicted: np.ndarray, margin: float) -> float:
    """F1 score of predicted change points against the true ones: one-to-one matching, closest pairs first;
    a hit is a pair closer than ``margin`` (same units as the points)."""
    truth, predicted = np.asarray(truth, dtype=float), np.asarray(predicted, dtype=float)
    if len(truth) == 0 or len(predicted) == 0:
        return float(len(truth) == len(predicted))
    distances = np.abs(truth[:, None] - predicted[None, :])
    used_true, used_predicted, hits = set(), set(), 0
    for flat in np.argsort(distances, axis=None, kind="stable"):
        i, k = np.unravel_index(flat, distances.shape)
        if distances[i, k] >= margin:
            break
        if i not in used_true and k not in used_predicted:
            used_true.add(i)
            used_predicted.add(k)
            hits += 1
    precision, recall = hits / len(predicted), hits / len(truth)
    return 0.0 if hits == 0 else 2 * precision * recall / (precision + recall)
