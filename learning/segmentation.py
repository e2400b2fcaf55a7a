"""Demonstrations cut into movements and holds: :func:`segment` and how it is scored.

:func:`segment` smooths a marker (Kalman/RTS, :mod:`besman.learning.preprocessing`), resamples its velocity
(or speed) and runs the change-point inference of :mod:`besman.learning.changepoints` on it: exact up to a
minute of recording, pruned beyond. Where a movement meets a hold, the boundary then moves to the movement's
onset or offset at 10 % of its peak speed (:func:`movement_onsets`), the convention of human reaching
studies (and of people who annotate recordings). :func:`boundary_f1` scores boundaries against annotated ones.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from besman.learning.changepoints import (
    SPEED_MODELS,
    VELOCITY_MODELS,
    SegmentationPrior,
    SegmentModel,
    change_probabilities,
    length_prior,
    map_segmentation,
    pruned_map_segmentation,
    samples,
    segment_evidences,
)
from besman.learning.demonstration import Demonstration, DemonstrationError
from besman.learning.preprocessing import SmoothingConfig, resample, smooth
from besman.skills.errors import InputError

EXACT_UP_TO = 1200  # samples (a minute at 20 Hz): exact inference's O(T^2) memory stays around 100 MB
AUTO_PARTICLES = 50  # beyond that: as close to exact as the benchmark shows (F1 unchanged), linear in T
STILL_SPEED = 1e-3  # m/s: a marker never faster than this has not moved


@dataclass(frozen=True)
class Segmentation:
    """A demonstration cut into segments.

    Attributes:
        boundaries: sample indices of the demonstration, from 0 to T - 1; segment k runs from
            ``boundaries[k]`` to ``boundaries[k + 1]`` (consecutive segments share their boundary sample).
        times: the demonstration's times at the boundaries (s).
        frames: the demonstration's frame numbers at the boundaries.
        models: the name of each segment's model.
        holds: whether each segment is a pause (its model is a hold).
        signal_times, signal: the signal that was segmented (the smoothed hand velocity (T, 3) or speed (T,),
            resampled).
        change_probability: posterior probability of a change point at each sample of ``signal``, when asked.
    """

    boundaries: np.ndarray
    times: np.ndarray
    frames: np.ndarray
    models: tuple[str, ...]
    holds: tuple[bool, ...]
    signal_times: np.ndarray
    signal: np.ndarray
    change_probability: np.ndarray | None = field(default=None)

    def __len__(self) -> int:
        return len(self.models)

    @property
    def speed(self) -> np.ndarray:
        """The segmented signal's magnitude at each sample (the hand speed)."""
        return np.abs(self.signal) if self.signal.ndim == 1 else np.linalg.norm(self.signal, axis=1)


SIGNALS = ("velocity", "speed")


def segment(
    demo: Demonstration,
    *,
    marker: str = "Hand top",
    signal: str = "velocity",
    rate: float = 20.0,
    models: tuple[SegmentModel, ...] | None = None,
    prior: SegmentationPrior = SegmentationPrior(),
    smoothing: SmoothingConfig | None = None,
    posterior: bool = False,
    max_particles: int | str | None = "auto",
    seed: int = 0,
    onset_threshold: float | None = 0.1,
    progress: Callable[[int], None] | None = None,
) -> Segmentation:
    """Segments a demonstration by the Kalman/RTS-smoothed ``marker``'s ``signal`` ("velocity" or "speed"),
    resampled at ``rate`` (Hz): the MAP segmentation under ``models`` (default: ``VELOCITY_MODELS`` or
    ``SPEED_MODELS``, by signal) with their weights as model priors; ``posterior`` adds the change-point
    probabilities. A boundary lies halfway between the last sample of one segment and the first of the next.
    Where a movement meets a hold, the boundary then moves to where the movement's speed crosses
    ``onset_threshold`` x its peak (``movement_onsets``; None keeps the change points of the model). The
    defaults need no tuning per recording (the noise scale is estimated from the data).

    Exact inference takes O(T^2) time and memory (about 0.5 s for 20 s at 20 Hz); ``max_particles`` bounds
    the candidate change points (``pruned_map_segmentation``; randomised: ``seed``) and is linear in T. The
    default, "auto", is exact up to :data:`EXACT_UP_TO` samples (a minute at 20 Hz) and 50 particles
    beyond (unless ``posterior`` asks for exact inference); None is always exact. ``progress`` is called
    with the number of samples done (pruned inference).
    """
    if signal not in SIGNALS:
        raise InputError(f"signal must be one of {SIGNALS}, got {signal!r}")
    if max_particles == "auto":
        max_particles = None  # decided below, once the signal's length is known
        automatic = not posterior
    elif max_particles is None or (isinstance(max_particles, int) and not isinstance(max_particles, bool)):
        automatic = False
    else:
        raise InputError(f"max_particles must be 'auto', None or an integer, got {max_particles!r}")
    if posterior and max_particles is not None:
        raise InputError("posterior change-point probabilities need exact inference (max_particles=None)")
    if models is None:
        models = VELOCITY_MODELS if signal == "velocity" else SPEED_MODELS
    smoothed = smooth(demo, marker, smoothing or SmoothingConfig())
    signal_times, values = resample(
        demo.times, smoothed.velocities if signal == "velocity" else smoothed.speed, rate
    )
    if not np.max(smoothed.speed) >= STILL_SPEED:  # constant positions make every segment model singular
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: marker {marker!r} does not move "
            f"(below {1000 * STILL_SPEED:g} mm/s throughout); there is nothing to segment"
        )
    minimum = samples(prior.min_length, rate)
    if len(values) < 2 * minimum:
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: the recording lasts {demo.duration:.2f} s, shorter than two "
            f"segments of the minimum length {prior.min_length:g} s"
        )
    if automatic and len(values) > EXACT_UP_TO:
        max_particles = AUTO_PARTICLES
    weights = np.array([model.weight for model in models], dtype=float)
    model_prior = np.log(weights / weights.sum())
    probability = None
    if max_particles is not None:
        points, choices = pruned_map_segmentation(
            values, rate, models, prior, model_prior, max_particles, seed, progress
        )
    else:
        evidences = [segment_evidences(values, rate, model, prior) for model in models]
        log_g, log_survival = length_prior(len(values), rate, prior)
        points, choices = map_segmentation(evidences, log_g, log_survival, model_prior)
        if posterior:
            probability = change_probabilities(evidences, log_g, log_survival, model_prior)[0]
    boundary_times = np.r_[signal_times, demo.times[-1]][points]
    boundary_times[1:-1] -= 0.5 / rate
    indices = demo.nearest_indices(boundary_times)
    holds = tuple(models[q].hold for q in choices)
    if onset_threshold is not None:
        indices = movement_onsets(indices, holds, smoothed.speed, onset_threshold)
    return Segmentation(
        boundaries=indices,
        times=demo.times[indices],
        frames=demo.frames[indices],
        models=tuple(models[q].name for q in choices),
        holds=holds,
        signal_times=signal_times,
        signal=values,
        change_probability=probability,
    )


def movement_onsets(
    boundaries: np.ndarray, holds: tuple[bool, ...], speed: np.ndarray, fraction: float
) -> np.ndarray:
    """Boundaries between holds and movements moved to the movement's onset and offset: the first sample at
    which its speed reaches ``fraction`` x its peak after a hold, the first below it before a hold (the usual
    definition in studies of human reaching, with 5-10 % of the peak speed; people annotating recordings
    see a movement begin there, not where it becomes statistically distinguishable from a hold).
    ``boundaries`` are sample indices of ``speed``; a hold keeps at least one sample."""
    if not 0.0 < fraction < 1.0:
        raise InputError(
            f"the onset threshold must be a fraction of the peak speed in (0, 1), got {fraction!r}"
        )
    moved = np.array(boundaries)
    for k, hold in enumerate(holds):
        if hold:
            continue
        start, end = boundaries[k], boundaries[k + 1]
        peak = start + int(np.argmax(speed[start:end]))
        slow = speed < fraction * speed[peak]
        if k > 0 and holds[k - 1]:
            before = np.flatnonzero(slow[boundaries[k - 1] + 1 : peak])
            if len(before):
                moved[k] = boundaries[k - 1] + 1 + before[-1] + 1
        if k + 1 < len(holds) and holds[k + 1]:
            after = np.flatnonzero(slow[peak : boundaries[k + 2]])
            if len(after):
                moved[k + 1] = peak + after[0]
    return moved


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
