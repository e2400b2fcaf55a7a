"""Bayesian multiple change-point inference (Fearnhead and Liu, JRSS B 2007), exact or pruned, on any signal.

A signal y (T samples, d dimensions) is cut into segments; each segment follows one of several linear
regression models q with conjugate priors: coefficients beta | Sigma ~ MN(0, D, Sigma), noise Sigma ~ IW(nu,
Gamma). The segment evidence then has the closed form (matrix-normal / inverse-Wishart; for d = 1 it is a
multivariate Student-t density)::

    log P = -(n d / 2) log pi + (d / 2)(log|M| - log|D|) + (nu / 2) log|Gamma| - ((n + nu) / 2) log|Gamma + S|
            + sum_i [lnGamma((n + nu + 1 - i) / 2) - lnGamma((nu + 1 - i) / 2)]

with M = (H^T H + D^-1)^-1, B = H^T Y, S = Y^T Y - B^T M B. The regressors H of a segment depend only on its
length, so the evidence of every segment [j, t) of one length is computed for all j at once (O(T^2)
evidences, vectorised over j).

The models of a hand's velocity (``VELOCITY_MODELS``, what
:func:`besman.learning.segmentation.segmenter.segment` uses by default): the hand is still (zero velocity),
drifts slowly (constant velocity: fine positioning while grasping), or makes a movement whose velocity rises
from and falls back to zero along a bell-shaped profile (a reach, Flash and Hogan 1985; the vMCI model of
Senger et al., ICPR 2014, uses one such bump on the speed), possibly with a corrective sub-movement. Each
dimension has its own coefficients, so a straight reach is one bump in every coordinate.

Several signals can be observed together (:class:`JointModel`: one model per signal; their evidences add
in log space), for instance the hand's velocity with the grip aperture's rate
(:mod:`besman.learning.segmentation.contact`).

Segment lengths have a geometric prior with hazard ``1 / expected length`` beyond a minimum length; a model
may ask for a longer minimum (a pause shorter than that is a turning point, not a hold; a movement shorter
than that is part of a neighbour). From the evidences:
the MAP segmentation (Viterbi), the posterior probability of a change point at every sample
(forward-backward), and exact samples from the posterior (backward filtering, forward sampling). For long
signals the MAP can instead be found online over a bounded set of candidate change points, thinned by
stratified optimal resampling. Hyperparameters default to data-driven values: the noise scale comes from the
first differences of the data; the filter's normalisers give the marginal likelihood
(:func:`log_marginal_likelihood`), by which the segment length and the weight of holds can be chosen.

The module is longer than most (~560 lines) because the evidences, the filtering recursions, the pruned
online MAP and the sampling share one state layout and one set of per-length terms; its tests check them
against one another and against brute-force enumeration, which is easier to keep true in one file.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import gammaln

from besman.core.errors import InputError
from besman.core.validation import checked, instance, integer, non_negative, optional, positive, text

# log(sum(exp(x))) along an axis (default 0), as a numpy ufunc reduction: the recursions below call it once
# per sample on short vectors, where scipy.special.logsumexp's dispatch costs ~0.3 ms a call (35x more).
log_sum_exp = np.logaddexp.reduce


@checked(
    name=text("a model name"),
    degree=integer(-1),
    bump_scale=positive,
    min_length=non_negative,
    weight=positive,
    hold=instance(bool, "True or False"),
)
@dataclass(frozen=True)
class SegmentModel:
    """A linear regression model of one segment.

    Attributes:
        name: what the model stands for ("still", "reach", ...).
        degree: polynomial terms 1, t, ..., t^degree in the time t since the segment began (s); -1: none (a
            segment of this model is zero plus noise).
        bumps: bump terms s^a (1 - s)^b, each peaking at 1, in the normalised time s = (i + 1/2) / n of a
            segment of n samples; they stretch with the segment (a bell-shaped velocity or speed profile).
        bump_scale: prior standard deviation of a bump's height (units of y).
        min_length: shortest segment of this model (s); the prior's ``min_length`` applies too.
        weight: prior weight of the model (the prior probabilities of a set of models are their normalised
            weights, those of holds times ``SegmentationPrior.hold_weight``).
        hold: whether a segment of this model is a pause rather than a movement (holds get no label).
    """

    name: str
    degree: int = 0
    bumps: tuple[tuple[float, float], ...] = ()
    bump_scale: float = 2.0
    min_length: float = 0.0
    weight: float = 1.0
    hold: bool = False

    def basis(self, n: int, rate: float) -> np.ndarray:
        """H (n, m): the regressors of a segment of n samples."""
        return self.padded_basis(np.array([n]), rate)[0]

    def padded_basis(self, lengths: np.ndarray, rate: float) -> np.ndarray:
        """H (k, n_max, m): the regressors of k segments of the given lengths, zero beyond each length."""
        lengths = np.asarray(lengths)
        samples = np.arange(int(lengths.max()))
        inside = samples[None, :] < lengths[:, None]
        offsets = np.broadcast_to(samples / rate, inside.shape)
        columns = [offsets**power for power in range(self.degree + 1)]
        s = np.minimum((samples[None, :] + 0.5) / lengths[:, None], 1.0)
        for a, b in self.bumps:
            peak = a / (a + b)
            columns.append(s**a * (1.0 - s) ** b / (peak**a * (1.0 - peak) ** b))
        if not columns:
            return np.zeros((*inside.shape, 0))
        return np.stack(columns, axis=-1) * inside[..., None]

    def scales(self) -> np.ndarray:
        """Prior standard deviations of the coefficients (units of y per s^power)."""
        return np.array(COEFFICIENT_SCALES[: self.degree + 1] + (self.bump_scale,) * len(self.bumps))


# Prior standard deviations of the polynomial coefficients (units of y per s^power, before the noise scale):
# position ~1, velocity ~1/s, acceleration/2 ~5/s^2, jerk/6 ~20/s^3, ...
COEFFICIENT_SCALES = (1.0, 1.0, 5.0, 20.0, 50.0, 100.0)

# Models of a position signal: a hold and smooth movements (minimum-jerk paths are quintic in time).
POLYNOMIAL_MODELS = (
    SegmentModel("hold", degree=0, hold=True),
    SegmentModel("move", degree=3),
    SegmentModel("move quintic", degree=5),
)
# The vMCI velocity model: one bell-shaped speed bump on a constant.
VMCI = SegmentModel("vmci", degree=0, bumps=((2.0, 2.0),))
# Single movements whose speed (or velocity along a straight path) rises from and falls back to zero: peaking
# in the middle (a minimum-jerk reach, Flash and Hogan 1985), a little early or late (at 44 or 56 % of the
# movement: a stronger skew lets a reach start or end several samples into a hold); the last one's width
# adapts (two symmetric bumps of different sharpness).
REACHES = (
    SegmentModel("reach", degree=-1, bumps=((2.0, 2.0),)),
    SegmentModel("reach early peak", degree=-1, bumps=((2.0, 2.5),)),
    SegmentModel("reach late peak", degree=-1, bumps=((2.5, 2.0),)),
    SegmentModel("reach variable width", degree=-1, bumps=((2.0, 2.0), (3.0, 3.0))),
)
# Models of a speed signal: a hold (constant speed) and reaches.
SPEED_MODELS = (SegmentModel("hold", degree=0, hold=True), *REACHES)
# A movement of several sub-movements, the most flexible movement model.
SMOOTH_MOVEMENT = SegmentModel("smooth movement", degree=-1, bumps=((2.0, 2.0), (2.0, 3.0), (3.0, 2.0)))
# Models of a hand's velocity (the default). Pauses shorter than HOLD_MIN_LENGTH are turning points between
# movements, not holds: people who annotate recordings draw one boundary there, and a gap (two boundaries)
# only where the hand rests for about half a second or longer (on the shared recordings, the pauses below
# 0.1 m/s that were annotated as gaps last 0.45-1.8 s, those annotated as one boundary 0.07-0.57 s).
# A movement lasts at least MOVEMENT_MIN_LENGTH: a human point-to-point reach takes 0.3 s or more, so a
# shorter stretch is part of a neighbouring movement or pause. How much holds weigh against movements is
# ``SegmentationPrior.hold_weight``.
HOLD_MIN_LENGTH = 0.5
MOVEMENT_MIN_LENGTH = 0.3
VELOCITY_MODELS = (
    SegmentModel("still", degree=-1, min_length=HOLD_MIN_LENGTH, hold=True),
    SegmentModel("drift", degree=0, min_length=HOLD_MIN_LENGTH, hold=True),
    *(
        replace(model, min_length=MOVEMENT_MIN_LENGTH)
        for model in (
            *REACHES,
            SegmentModel("reach with correction", degree=-1, bumps=((2.0, 5.0), (5.0, 2.0))),
            SMOOTH_MOVEMENT,
        )
    ),
)
# The zero model: a signal that does not change (an object at rest, a grip that holds).
STILL = SegmentModel("still", degree=-1)


@dataclass(frozen=True)
class JointModel:
    """A segment model of several signals observed together (the hand's velocity, an object's velocity, the
    grip aperture's rate): ``parts[s]`` models signal s. Given the segment, the signals' noises are
    independent, so the joint evidence is the product of the parts' evidences. Two signals may be two views
    of one observation (an object's velocity, and its velocity relative to the hand's): then each model
    observes exactly one of them and has None for the other, so that every model explains the same data
    (the evidences are densities of the object's velocity, given the hand's). A part's minimum length
    applies to the whole segment. ``holding``: whether the hand holds the object in such a segment (for
    models of contact signals, :mod:`besman.learning.segmentation.contact`).
    """

    name: str
    parts: tuple[SegmentModel | None, ...]
    weight: float = 1.0
    hold: bool = False
    holding: bool = False

    def observed(self) -> list[tuple[int, SegmentModel]]:
        """(signal index, model) of each signal this model observes."""
        return [(s, part) for s, part in enumerate(self.parts) if part is not None]

    def min_samples(self, rate: float) -> int:
        """The shortest segment of this model (samples at ``rate``): the longest minimum of its parts."""
        return max(samples(part.min_length, rate) for _, part in self.observed())

    @classmethod
    def of(cls, model: SegmentModel) -> JointModel:
        """The model of a single signal."""
        return cls(model.name, (model,), model.weight, model.hold)


@checked(
    noise=optional(positive),
    noise_factor=positive,
    nu=positive,
    expected_length=positive,
    min_length=non_negative,
    hold_weight=positive,
)
@dataclass(frozen=True)
class SegmentationPrior:
    """Hyperparameters. ``noise`` None means: estimated from the data's first differences."""

    noise: float | None = None  # expected noise standard deviation per dimension
    # With noise None: noise_factor x the first-difference estimate, because segments also deviate from
    # their model (a human's velocity is not exactly a bump), not only by sensor noise.
    noise_factor: float = 3.0
    nu: float = 10.0  # inverse-Wishart degrees of freedom (> d - 1): the noise's pseudo-observations
    expected_length: float = 0.7  # s, mean segment length beyond the minimum (geometric prior)
    min_length: float = 0.15  # s, shortest segment
    hold_weight: float = 3.0  # prior weight of each hold model over that of each movement model

    def model_weights(self, models: Sequence[SegmentModel | JointModel]) -> np.ndarray:
        """The models' prior weights: their own, those of holds times ``hold_weight``."""
        return np.array([m.weight * (self.hold_weight if m.hold else 1.0) for m in models], dtype=float)

    def log_model_prior(self, models: Sequence[SegmentModel | JointModel]) -> np.ndarray:
        """log p(q): the normalised :meth:`model_weights`."""
        weights = self.model_weights(models)
        return np.log(weights / weights.sum())


def samples(duration: float, rate: float) -> int:
    """The number of samples (at least one) of a duration (s) at ``rate`` (Hz)."""
    return max(1, round(duration * rate))


def noise_scale(y: np.ndarray) -> float:
    """White-noise standard deviation estimated from first differences (median absolute deviation)."""
    differences = np.diff(y, axis=0)
    mad = np.median(np.abs(differences - np.median(differences, axis=0)), axis=0)
    return float(max(np.mean(mad) * 1.4826 / math.sqrt(2.0), 1e-12))


@dataclass(frozen=True)
class _EvidenceKernel:
    """The closed-form segment evidence of one model on one signal, for any batch of segments."""

    rate: float
    model: SegmentModel
    dimensions: int
    nu: float
    gamma: float  # Gamma = gamma I: Sigma is a priori of the order of sigma^2 I
    inverse_prior: np.ndarray  # D^-1, D in units of the noise
    log_det_prior: float  # log|D|

    @classmethod
    def of(cls, y: np.ndarray, rate: float, model: SegmentModel, prior: SegmentationPrior) -> _EvidenceKernel:
        d = y.shape[1]
        if not prior.nu > d - 1:
            raise InputError(
                f"SegmentationPrior.nu must exceed d - 1 = {d - 1} for {d}-dimensional data, got {prior.nu!r}"
            )
        sigma = prior.noise if prior.noise is not None else prior.noise_factor * noise_scale(y)
        scales = model.scales() / sigma  # beta ~ N(0, Sigma D)
        return cls(
            rate,
            model,
            d,
            prior.nu,
            prior.nu * sigma**2,
            np.diag(1.0 / scales**2),
            float(np.sum(np.log(scales**2))),
        )

    def __call__(
        self, lengths: np.ndarray, gram: np.ndarray, cross: np.ndarray, second: np.ndarray
    ) -> np.ndarray:
        """log P(y_k) for k segments of ``lengths`` with H^T H ``gram`` (k or 1, m, m), H^T Y ``cross`` (k, m,
        d) and Y^T Y ``second`` (k, d, d)."""
        d, nu = self.dimensions, self.nu
        posterior = np.linalg.inv(gram + self.inverse_prior)  # M
        residual = second - np.swapaxes(cross, 1, 2) @ (posterior @ cross)
        log_det = np.linalg.slogdet(self.gamma * np.eye(d)[None] + residual)[1]
        gamma_terms = sum(
            gammaln((lengths + nu + 1 - i) / 2.0) - gammaln((nu + 1 - i) / 2.0) for i in range(1, d + 1)
        )
        return (
            -(lengths * d / 2.0) * math.log(math.pi)
            + (d / 2.0) * (np.linalg.slogdet(posterior)[1] - self.log_det_prior)
            + (nu / 2.0) * d * math.log(self.gamma)
            + gamma_terms
            - ((lengths + nu) / 2.0) * log_det
        )

    def segments(self, windows: np.ndarray, lengths: np.ndarray, second: np.ndarray) -> np.ndarray:
        """log P(y_k) for k segments given as ``windows`` (k, max(lengths), d) that start with each segment
        (samples beyond its length are ignored), their ``lengths`` and Y^T Y ``second`` (k, d, d), whatever
        the model's minimum length (a segment may go on past one that is still too short to end)."""
        basis = self.model.padded_basis(lengths, self.rate)  # zero beyond each segment's end
        gram = np.einsum("kim,kin->kmn", basis, basis)
        cross = np.einsum("kim,kid->kmd", basis, windows)
        return self(lengths, gram, cross, second)


PROGRESS_STEP = 100  # samples between progress reports


def _as_columns(y: np.ndarray) -> np.ndarray:
    y = np.asarray(y, dtype=float)
    return y[:, None] if y.ndim == 1 else y


def _second_moments(y: np.ndarray) -> np.ndarray:
    """Cumulative sums of y y^T (T+1, d, d): Y^T Y of y[j:t] is the difference of two of them."""
    outer = np.einsum("ta,tb->tab", y, y)
    return np.concatenate([np.zeros((1, *outer.shape[1:])), np.cumsum(outer, axis=0)])


def segment_evidences(
    y: np.ndarray, rate: float, model: SegmentModel, prior: SegmentationPrior
) -> np.ndarray:
    """E (T+1, T+1): E[j, t] = log P(y[j:t] | one segment of ``model``) for j < t (-inf elsewhere and for
    segments shorter than the model's ``min_length``).

    For every segment length n the regressors H are fixed, so H^T Y of all segments of that length is a
    correlation of y with the columns of H, and Y^T Y a difference of cumulative sums.
    """
    y = _as_columns(y)
    n_samples = len(y)
    kernel = _EvidenceKernel.of(y, rate, model, prior)
    cumulative = _second_moments(y)
    evidences = np.full((n_samples + 1, n_samples + 1), -np.inf)
    for n in range(samples(model.min_length, rate), n_samples + 1):
        basis = model.basis(n, rate)
        windows = np.lib.stride_tricks.sliding_window_view(y, n, axis=0)  # (T - n + 1, d, n)
        cross = np.swapaxes(windows @ basis, 1, 2)  # H^T Y of every segment of length n
        starts = np.arange(n_samples - n + 1)
        evidences[starts, starts + n] = kernel(
            np.full(len(starts), n), (basis.T @ basis)[None], cross, cumulative[n:] - cumulative[:-n]
        )
    return evidences


def joint_evidences(
    signals: Sequence[np.ndarray],
    rate: float,
    models: Sequence[JointModel],
    priors: Sequence[SegmentationPrior],
) -> list[np.ndarray]:
    """E_q (T+1, T+1) of each joint model: the sum of its parts' :func:`segment_evidences` on their signals
    (each with its own prior's noise), every distinct (signal, part) computed once."""
    parts: dict[tuple[int, SegmentModel], np.ndarray] = {}
    for model in models:
        for s, part in model.observed():
            if (s, part) not in parts:
                parts[s, part] = segment_evidences(signals[s], rate, part, priors[s])
    return [sum(parts[key] for key in model.observed()) for model in models]


def length_prior(n_samples: int, rate: float, prior: SegmentationPrior) -> tuple[np.ndarray, np.ndarray]:
    """log g(n) and log(1 - G(n - 1)) (the survival, for the last segment) for n = 0..T."""
    n = np.arange(n_samples + 1)
    minimum = samples(prior.min_length, rate)
    hazard = min(1.0, 1.0 / max(prior.expected_length * rate, 1.0))
    extra = n - minimum
    log_g = np.where(
        extra >= 0, math.log(hazard) + extra * math.log1p(-hazard) if hazard < 1 else 0.0, -np.inf
    )
    if hazard >= 1:
        log_g = np.where(extra == 0, 0.0, -np.inf)
    log_survival = np.where(extra >= 0, extra * math.log1p(-hazard) if hazard < 1 else 0.0, -np.inf)
    return log_g, log_survival


def combined_evidence(evidences: list[np.ndarray], model_prior: np.ndarray) -> np.ndarray:
    """log P(y[j:t] as one segment) (T+1, T+1): the models' evidences summed with their prior."""
    return log_sum_exp(_stacked(evidences, model_prior), axis=0)


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
        backward[j] = log_sum_exp(_end_terms(combined, backward, log_g, log_survival, j)[1])
    return backward


def _trace_back(back: np.ndarray, choice: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundaries and models of the best segmentation from the Viterbi back pointers."""
    boundaries, models, t = [len(back) - 1], [], len(back) - 1
    while t > 0:
        models.append(choice[t])
        t = back[t]
        boundaries.append(t)
    return np.array(boundaries[::-1]), np.array(models[::-1])


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
    return _trace_back(back, choice)


def stratified_optimal_resampling(
    log_weights: np.ndarray, keep: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Thins particles to ``keep`` (Fearnhead and Clifford, JRSS B 2003): those with normalised weight at
    least alpha survive as they are; the rest are resampled in strata of width alpha and the survivors get
    weight alpha, which keeps the weights unbiased. Returns the kept indices (sorted) and the log factors
    that turn their old weights into the new ones."""
    weights = np.exp(log_weights - log_sum_exp(log_weights))
    positive = np.flatnonzero(weights > 0)
    if len(positive) <= keep:
        return positive, np.zeros(len(positive))
    # Split by rank (not by comparing values with alpha, which rounding can contradict): the `certain`
    # largest survive; alpha is then the mass of the rest over the strata left, larger than any of them.
    order = np.argsort(-weights, kind="stable")
    descending = weights[order]
    tails = np.cumsum(descending[::-1])[::-1]  # tails[a] = sum of all but the a largest
    # Falls through only when the rest rounds to nothing next to the keep-th largest.
    certain = next((a for a in range(keep) if descending[a] < tails[a] / (keep - a)), keep - 1)
    large, small = order[:certain], np.sort(order[certain:])
    strata = keep - certain
    cumulative = np.cumsum(weights[small])
    alpha = cumulative[-1] / strata
    points = (rng.uniform() + np.arange(strata)) * alpha
    drawn = small[np.minimum(np.searchsorted(cumulative, points, side="right"), len(small) - 1)]
    kept = np.union1d(large, drawn)
    factors = np.where(np.isin(kept, large), 0.0, math.log(alpha) - np.log(weights[kept]))
    return kept, factors


def pruned_map_segmentation(
    signals: Sequence[np.ndarray],
    rate: float,
    models: Sequence[JointModel],
    priors: Sequence[SegmentationPrior],
    lengths: SegmentationPrior,
    model_prior: np.ndarray,
    max_particles: int,
    seed: int,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """MAP segmentation of ``signals`` observed together (each with its prior's noise; the segment lengths of
    ``lengths``) with at most ``max_particles`` candidates for the last change point (Fearnhead and Liu 2007,
    section 3.3): after each sample the filter's candidates are thinned by stratified optimal resampling,
    and the online Viterbi recursion runs over the survivors. Costs O(T max_particles L) for segments of up
    to L samples instead of O(T^2) time and memory; with ``max_particles`` >= T it is exact. ``progress``
    is called with the number of samples done since its last call."""
    if max_particles < 2:
        raise InputError(f"max_particles must be at least 2, got {max_particles!r}")
    signals = [_as_columns(y) for y in signals]
    n_samples = len(signals[0])
    kernels = {
        (s, part): _EvidenceKernel.of(signals[s], rate, part, priors[s])
        for model in models
        for s, part in model.observed()
    }
    cumulative = [_second_moments(y) for y in signals]
    minimum_lengths = np.array([model.min_samples(rate) for model in models])
    log_g, log_survival = length_prior(n_samples, rate, lengths)
    # log P(a segment lasts at least n samples): 0 up to the minimum length.
    log_ongoing = np.where(np.isfinite(log_survival), log_survival, 0.0)
    forward, best = np.full(n_samples + 1, -np.inf), np.full(n_samples + 1, -np.inf)
    forward[0] = best[0] = 0.0
    back = np.zeros(n_samples + 1, dtype=int)
    choice = np.zeros(n_samples + 1, dtype=int)
    particles = np.array([0])
    rng = np.random.default_rng(seed)
    for t in range(1, n_samples + 1):
        if progress is not None and t % PROGRESS_STEP == 0:
            progress(PROGRESS_STEP)
        lengths = t - particles
        # The segments [j, t) of every candidate j, gathered once per signal for all models.
        rows = np.minimum(particles[:, None] + np.arange(lengths.max())[None, :], n_samples - 1)
        windows = [y[rows] for y in signals]
        second = [moments[t] - moments[particles] for moments in cumulative]
        parts = {
            key: kernel.segments(windows[key[0]], lengths, second[key[0]]) for key, kernel in kernels.items()
        }
        ongoing = np.stack([sum(parts[key] for key in model.observed()) for model in models])
        ongoing += model_prior[:, None]
        stacked = np.where(lengths[None, :] >= minimum_lengths[:, None], ongoing, -np.inf)  # may end at t
        lengths_prior = log_survival[lengths] if t == n_samples else log_g[lengths]
        scores = best[particles][None, :] + stacked + lengths_prior[None, :]  # (q, particle)
        q, k = np.unravel_index(np.argmax(scores), scores.shape)
        best[t], back[t], choice[t] = scores[q, k], particles[k], q
        if t == n_samples:
            break
        forward[t] = log_sum_exp(forward[particles] + log_sum_exp(stacked, axis=0) + log_g[lengths])
        # P(C_t+1 = j): the segment from j goes on past t (it ending at t is the new particle's weight).
        combined = log_sum_exp(ongoing, axis=0)
        weights = np.r_[forward[particles] + combined + log_ongoing[lengths + 1], forward[t]]
        particles = np.r_[particles, t]
        if len(particles) > max_particles:
            kept, factors = stratified_optimal_resampling(weights, max_particles, rng)
            particles = particles[kept]
            forward[particles] += factors
    return _trace_back(back, choice)


def _forward(combined: np.ndarray, log_g: np.ndarray) -> np.ndarray:
    """F[t] = log P(y[:t], change point at t) for t < T (Fearnhead and Liu's filter, unnormalised)."""
    n_samples = combined.shape[0] - 1
    forward = np.full(n_samples + 1, -np.inf)
    forward[0] = 0.0
    for t in range(1, n_samples):
        forward[t] = log_sum_exp(forward[:t] + combined[:t, t] + log_g[t - np.arange(t)])
    return forward


def log_marginal_likelihood(combined: np.ndarray, log_g: np.ndarray, log_survival: np.ndarray) -> float:
    """log P(y) from ``combined`` (T+1, T+1), log P(y[j:t] as one segment) summed over the models with
    their prior: the forward filter, and the last segment's survival."""
    n_samples = combined.shape[0] - 1
    forward = _forward(combined, log_g)
    starts = np.arange(n_samples)
    last = combined[starts, n_samples] + log_survival[n_samples - starts]
    return float(log_sum_exp(forward[starts] + last))


def change_probabilities(
    evidences: list[np.ndarray], log_g: np.ndarray, log_survival: np.ndarray, model_prior: np.ndarray
) -> tuple[np.ndarray, float, np.ndarray]:
    """Posterior probability of a change point at each sample (forward-backward), the log marginal
    likelihood, and the backward messages Q (log P(y[t:] | change point at t))."""
    combined = combined_evidence(evidences, model_prior)
    n_samples = combined.shape[0] - 1
    forward = _forward(combined, log_g)
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
    combined = combined_evidence(evidences, model_prior)
    n_samples = combined.shape[0] - 1
    backward = _backward(combined, log_g, log_survival)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(count):
        points, j = [0], 0
        while j < n_samples:
            ends, terms = _end_terms(combined, backward, log_g, log_survival, j)
            weights = np.exp(terms - log_sum_exp(terms))
            j = int(rng.choice(ends, p=weights / weights.sum()))
            points.append(j)
        samples.append(np.array(points))
    return samples
