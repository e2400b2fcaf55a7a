"""Demonstrations cut into movements and holds: :func:`segment` and how it is scored.

:func:`segment` smooths the hand's marker (Kalman/RTS, :mod:`besman.learning.segmentation.preprocessing`),
resamples its velocity (or speed) and, where the recording has them, the contact signals of
:mod:`besman.learning.segmentation.contact` (the object's velocity, the grip aperture's rate), and runs the
change-point inference of
:mod:`besman.learning.segmentation.changepoints` on them jointly: exact up to a minute of recording, pruned
beyond. The prior's segment length and the weight of holds are chosen per recording by the marginal likelihood
that the inference computes anyway (:func:`choose_prior`), so a new person's recordings need no labels and no
tuning. The model's change points then follow the conventions of people who annotate recordings
(:mod:`besman.learning.segmentation.boundaries`). :func:`boundary_f1` scores boundaries against annotated
ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import CALLABLE, SEED, checked, instance, optional, positive, text
from besman.learning.segmentation.boundaries import (
    fold_minor_movements,
    merge_holds,
    movement_onsets,
    turning_points,
)
from besman.learning.segmentation.changepoints import (
    SPEED_MODELS,
    VELOCITY_MODELS,
    JointModel,
    SegmentationPrior,
    SegmentModel,
    change_probabilities,
    combined_evidence,
    joint_evidences,
    length_prior,
    log_marginal_likelihood,
    map_segmentation,
    pruned_map_segmentation,
    samples,
)
from besman.learning.segmentation.contact import GRIP, ContactMarkers, contact_signals, joint_models
from besman.learning.segmentation.demonstration import DEMONSTRATION, Demonstration, DemonstrationError
from besman.learning.segmentation.preprocessing import SmoothingConfig, resample, smooth

EXACT_UP_TO = 1200  # samples (a minute at 20 Hz): exact inference's evidences take Q x 12 MB (16 models:
# 190 MB with the grip); beyond, pruned inference is linear in T
AUTO_PARTICLES = 50  # beyond that: as close to exact as the benchmark shows (F1 unchanged), linear in T
STILL_SPEED = 1e-3  # m/s: a marker never faster than this has not moved
# A demonstrating hand reaches most of a metre from the capture's origin and peaks at 1-2 m/s (the shared
# recordings: 0.77 m and 0.9 m/s at least); a recording in metres read as millimetres is a thousand times
# nearer and slower: within a few mm of the origin, at 1-2 mm/s. A hand held still moves that little too,
# but is as far away as ever (and a synthetic one at the origin has noise faster than that).
NEAR_ORIGIN = 0.01  # m
MIN_PEAK_SPEED = 0.02  # m/s
# The hyperparameters chosen by marginal likelihood: the mean segment length beyond the minimum (s) and the
# weight of a hold model over a movement model. Both change only the priors, not the segment evidences, so
# trying them all costs one forward recursion each.
PRIOR_CHOICES = {"expected_length": (0.7, 1.4, 2.8), "hold_weight": (1.0, 3.0, 9.0)}


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
        holding: whether the hand holds the object in each segment by the contact signals (from the grip
            alone: whether the grip is steady; all False without contact signals).
        signal_times, signal: the hand's signal that was segmented (the smoothed hand velocity (T, 3) or speed
            (T,), resampled).
        signals: every signal observed, the hand's first (names with their markers).
        notes: why a contact signal was left out (its markers are absent or could not be bridged).
        prior: the hyperparameters used (chosen by marginal likelihood unless given).
        log_evidence: the log marginal likelihood of the recording under ``prior`` (None with pruned
            inference).
        change_probability: posterior probability of a change point at each sample of ``signal``, when asked.
    """

    boundaries: np.ndarray
    times: np.ndarray
    frames: np.ndarray
    models: tuple[str, ...]
    holds: tuple[bool, ...]
    holding: tuple[bool, ...]
    signal_times: np.ndarray
    signal: np.ndarray
    signals: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    prior: SegmentationPrior = SegmentationPrior()
    log_evidence: float | None = None
    change_probability: np.ndarray | None = field(default=None)

    def __len__(self) -> int:
        return len(self.models)

    @property
    def speed(self) -> np.ndarray:
        """The segmented signal's magnitude at each sample (the hand speed)."""
        return np.abs(self.signal) if self.signal.ndim == 1 else np.linalg.norm(self.signal, axis=1)


SIGNALS = ("velocity", "speed")


@checked(
    demo=DEMONSTRATION,
    marker=text("a marker name"),
    rate=positive,
    models=optional(instance(tuple, "a tuple of SegmentModels")),
    smoothing=optional(instance(SmoothingConfig, "a SmoothingConfig")),
    posterior=instance(bool, "True or False"),
    seed=SEED,
    progress=optional(CALLABLE),
)
def segment(
    demo: Demonstration,
    *,
    marker: str = "Hand top",
    signal: str = "velocity",
    rate: float = 20.0,
    models: tuple[SegmentModel, ...] | None = None,
    prior: SegmentationPrior | str = "auto",
    contact: ContactMarkers | None = GRIP,
    smoothing: SmoothingConfig | None = None,
    posterior: bool = False,
    max_particles: int | str | None = "auto",
    seed: int = 0,
    onset_threshold: float | None = 0.1,
    progress: Callable[[int], None] | None = None,
) -> Segmentation:
    """Segments a demonstration by the Kalman/RTS-smoothed ``marker``'s ``signal`` ("velocity" or "speed"),
    resampled at ``rate`` (Hz), observed jointly with the ``contact`` signals the recording has (None: the
    hand alone; a missing marker leaves its signal out with a note in ``Segmentation.notes``): the MAP
    segmentation under ``models`` (default: ``VELOCITY_MODELS`` or ``SPEED_MODELS``, by signal);
    ``posterior`` adds the change-point probabilities. ``prior`` "auto" takes the defaults of
    :class:`SegmentationPrior` with the segment length and hold weight of the highest marginal likelihood
    (:func:`choose_prior`); the noise scales come from the data. A boundary lies halfway between the last
    sample of one segment and the first of the next. Then (:mod:`besman.learning.segmentation.boundaries`)
    minor movements are folded into their neighbours and consecutive holds merged; where a movement meets a
    hold, the boundary moves to where the movement's speed crosses ``onset_threshold`` x its peak
    (``movement_onsets``), and between two movements to the speed minimum between their peaks unless the
    contact changes farther from it (``turning_points``); ``onset_threshold`` None leaves the boundaries at
    the model's change points.

    Exact inference takes O(T^2) time and memory (about 0.5 s for 20 s at 20 Hz); ``max_particles`` bounds
    the candidate change points (``pruned_map_segmentation``; randomised: ``seed``) and is linear in T. The
    default, "auto", is exact up to :data:`EXACT_UP_TO` samples (a minute at 20 Hz) and 50 particles
    beyond (unless ``posterior`` asks for exact inference); None is always exact. With pruned inference the
    prior is chosen on the first :data:`EXACT_UP_TO` samples. ``progress`` is called with the number of
    samples done (pruned inference).
    """
    if signal not in SIGNALS:
        raise InputError(f"signal must be one of {SIGNALS}, got {signal!r}")
    if not (prior == "auto" or isinstance(prior, SegmentationPrior)):
        raise InputError(f"prior must be 'auto' or a SegmentationPrior, got {prior!r}")
    if not (contact is None or isinstance(contact, ContactMarkers)):
        raise InputError(f"contact must be None or ContactMarkers(...), got {contact!r}")
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
    smoothing = smoothing or SmoothingConfig()
    smoothed = smooth(demo, marker, smoothing)
    signal_times, values = resample(
        demo.times, smoothed.velocities if signal == "velocity" else smoothed.speed, rate
    )
    base = prior if isinstance(prior, SegmentationPrior) else SegmentationPrior()
    minimum = samples(base.min_length, rate)
    if len(values) < 2 * minimum:
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: the recording lasts {demo.duration:.2f} s, shorter than two "
            f"segments of the minimum length {base.min_length:g} s"
        )
    farthest = float(np.max(np.linalg.norm(smoothed.positions, axis=1)))
    peak = float(np.max(smoothed.speed))
    if farthest < NEAR_ORIGIN and peak < MIN_PEAK_SPEED:
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: marker {marker!r} stays within {1000 * farthest:.1f} mm of "
            f"the origin and moves at most {1000 * peak:.1f} mm/s over {demo.duration:.0f} s: is the "
            "recording in metres? besman reads a .tsv in millimetres"
        )
    if not np.max(smoothed.speed) >= STILL_SPEED:  # constant positions make every segment model singular
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: marker {marker!r} does not move "
            f"(below {1000 * STILL_SPEED:g} mm/s throughout); there is nothing to segment"
        )
    if contact:
        hand = values if signal == "velocity" else resample(demo.times, smoothed.velocities, rate)[1]
        extra, notes = contact_signals(demo, contact, smoothing, hand, rate, base.noise_factor)
    else:
        extra, notes = [], []
    joint = joint_models(models, extra)
    shortest = min(model.min_samples(rate) for model in joint)
    if len(values) < shortest:
        raise DemonstrationError(
            f"{demo.source or 'demonstration'}: the recording lasts {demo.duration:.2f} s, shorter than the "
            f"shortest segment any model allows ({shortest / rate:g} s)"
        )
    signals = [values, *(contact_signal.values for contact_signal in extra)]
    priors = [base, *(replace(base, noise=c.noise) for c in extra)]
    if automatic and len(values) > EXACT_UP_TO:
        max_particles = AUTO_PARTICLES
    probability = log_evidence = None
    if max_particles is not None:
        if prior == "auto":
            head = [y[:EXACT_UP_TO] for y in signals]
            base, _ = choose_prior(joint_evidences(head, rate, joint, priors), joint, rate, base)
        points, choices = pruned_map_segmentation(
            signals, rate, joint, priors, base, base.log_model_prior(joint), max_particles, seed, progress
        )
    else:
        evidences = joint_evidences(signals, rate, joint, priors)
        if prior == "auto":
            base, log_evidence = choose_prior(evidences, joint, rate, base)
        log_g, log_survival = length_prior(len(values), rate, base)
        model_prior = base.log_model_prior(joint)
        points, choices = map_segmentation(evidences, log_g, log_survival, model_prior)
        if posterior:
            probability, log_evidence, _ = change_probabilities(evidences, log_g, log_survival, model_prior)
        elif log_evidence is None:
            combined = combined_evidence(evidences, model_prior)
            log_evidence = log_marginal_likelihood(combined, log_g, log_survival)
    boundary_times = np.r_[signal_times, demo.times[-1]][points]
    boundary_times[1:-1] -= 0.5 / rate
    indices = demo.nearest_indices(boundary_times)
    chosen = [joint[q] for q in choices]
    indices, chosen = merge_holds(*fold_minor_movements(indices, chosen, smoothed.speed))
    holds = tuple(model.hold for model in chosen)
    if onset_threshold is not None:
        indices = movement_onsets(indices, holds, smoothed.speed, onset_threshold)
        indices = turning_points(indices, chosen, smoothed.speed, demo.rate)
    return Segmentation(
        boundaries=indices,
        times=demo.times[indices],
        frames=demo.frames[indices],
        models=tuple(model.name for model in chosen),
        holds=holds,
        holding=tuple(model.holding for model in chosen),
        signal_times=signal_times,
        signal=values,
        signals=(f"hand {signal} ({marker})", *dict.fromkeys(c.name for c in extra)),
        notes=tuple(notes),
        prior=base,
        log_evidence=None if log_evidence is None else float(log_evidence),
        change_probability=probability,
    )


def choose_prior(
    evidences: list[np.ndarray], models: tuple[JointModel, ...], rate: float, base: SegmentationPrior
) -> tuple[SegmentationPrior, float]:
    """``base`` with the expected segment length and hold weight of :data:`PRIOR_CHOICES` under which the
    signal is most probable, and that log marginal likelihood (empirical Bayes, type-II maximum likelihood:
    the Fearnhead-Liu filter's normalisers give log p(y | hyperparameters)). No labels are used.

    The hold weight w only rescales the holds' share of the model prior, so with H and M the holds' and the
    movements' evidences summed over their models (each with its own weight), a segment's evidence is
    log(w e^H + e^M) - log(sum of the weights under w): two sums over the models serve every candidate."""
    n_samples = evidences[0].shape[0] - 1
    own = replace(base, hold_weight=1.0).model_weights(models)
    hold_part = move_part = np.full(evidences[0].shape, -np.inf)
    for model, evidence, weight in zip(models, evidences, own, strict=True):
        if model.hold:
            hold_part = np.logaddexp(hold_part, evidence + math.log(weight))
        else:
            move_part = np.logaddexp(move_part, evidence + math.log(weight))
    hold_weights = PRIOR_CHOICES["hold_weight"] if any(m.hold for m in models) else (base.hold_weight,)
    best, best_log = base, -np.inf
    for hold_weight in hold_weights:
        normaliser = math.log(replace(base, hold_weight=hold_weight).model_weights(models).sum())
        combined = np.logaddexp(math.log(hold_weight) + hold_part, move_part) - normaliser
        for expected in PRIOR_CHOICES["expected_length"]:
            candidate = replace(base, expected_length=expected, hold_weight=hold_weight)
            log_g, log_survival = length_prior(n_samples, rate, candidate)
            marginal = log_marginal_likelihood(combined, log_g, log_survival)
            if marginal > best_log:
                best, best_log = candidate, marginal
    return best, float(best_log)


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
