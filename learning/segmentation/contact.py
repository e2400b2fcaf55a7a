"""Contact: when the hand holds the object, read from the object's own marker and from the grip aperture.

People who annotate pick-and-place recordings put boundaries at grasp and release, and two signals besides
the hand's velocity tell where those are: the object moves exactly while it is held (it rests otherwise), and
the grip aperture (thumb-index distance) stays constant while the fingers hold the object (it opens and
closes otherwise). A segment is therefore either *free* or *holding*, and each contact signal has a model for
each case; :func:`joint_models` pairs every model of the hand's velocity with both cases
(:class:`besman.learning.segmentation.changepoints.JointModel`), so that the change-point inference observes
the hand and the contact signals jointly and puts a boundary where the contact changes even when the hand's
speed alone would put it elsewhere.

From the grip alone, "holding" means that the grip does not change, which a hand at rest with still
fingers also shows; what matters for the boundaries is where that state changes. With the object's marker,
it is the object moving with the hand.

A file may lack these markers, or have them missing for too long to bridge: that signal is then left out,
with a note that says why (the hand alone still segments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.learning.segmentation.changepoints import (
    SMOOTH_MOVEMENT,
    STILL,
    JointModel,
    SegmentModel,
    noise_scale,
)
from besman.learning.segmentation.demonstration import Demonstration, DemonstrationError
from besman.learning.segmentation.preprocessing import SmoothedChannel, SmoothingConfig, resample, smooth


@dataclass(frozen=True)
class ContactMarkers:
    """The markers that show contact: ``object`` on the manipulated object, ``grip`` the two fingertips
    whose distance is the grip aperture (None: not used; the names are the DFKI recordings' markers).

    The object is not observed by default: on the shared recordings (``benchmarks/segmentation.py``) its
    marker costs boundary F1 for both people, because the object goes on moving after the release (it
    settles on the table) and twitches when the fingers touch it before the grasp; the grip does not.
    ``ContactMarkers(object="Box back")`` observes it too."""

    object: str | None = None
    grip: tuple[str, str] | None = ("Thumb", "Index")

    def __post_init__(self) -> None:
        if not (self.object is None or isinstance(self.object, str)):
            raise InputError(f"ContactMarkers.object must be a marker name or None, got {self.object!r}")
        pair = isinstance(self.grip, tuple) and len(self.grip) == 2
        if not (self.grip is None or (pair and all(isinstance(marker, str) for marker in self.grip))):
            raise InputError(f"ContactMarkers.grip must be two marker names or None, got {self.grip!r}")


OBJECT_SIGNAL = "object velocity"
# m/s: the least noise a contact signal is scored with. A simulated robot's gripper is noise-free, and a
# zero noise scale makes the segment evidences' prior singular; people's markers are far noisier.
NOISE_FLOOR = 1e-3
GRIP = ContactMarkers()
OBJECT_AND_GRIP = ContactMarkers(object="Box back")


@dataclass(frozen=True)
class ContactSignal:
    """A resampled contact signal (T, d) and its model in a free and in a holding segment (None: a segment
    in that state observes another view of the same data, a signal of the same name)."""

    name: str
    values: np.ndarray
    free: SegmentModel | None
    holding: SegmentModel | None
    noise: float  # the prior noise scale of the observation (both views of one have the same)

    def model(self, holding: bool) -> SegmentModel | None:
        return self.holding if holding else self.free


def contact_signals(
    demo: Demonstration,
    markers: ContactMarkers,
    smoothing: SmoothingConfig,
    hand: np.ndarray,
    rate: float,
    noise_factor: float,
) -> tuple[list[ContactSignal], list[str]]:
    """The contact signals that ``demo`` has, resampled at ``rate``, and a note for each one it lacks:
    - the object's velocity: at rest while free; while held, it moves with the hand (``hand``: the hand's
      velocity (T, 3) at ``rate``), so its velocity relative to the hand's is zero. Both views are scored
      with the object marker's own noise (first differences), so that they compare on one scale; the
      relative view also carries the hand's velocity error and the grasp's lever arm, which this scale does
      not allow for;
    - the grip aperture's rate of change: constant grip (zero rate) while holding, free otherwise (a smooth
      movement of the fingers: a model that fits only roughly, hence ``noise_factor`` x the first-difference
      noise, as for the hand)."""
    signals, notes = [], []
    if markers.object is not None:
        name = f"{OBJECT_SIGNAL} ({markers.object})"
        velocities = _smoothed(demo, [markers.object], smoothing, notes, name)
        if velocities is not None:
            values = resample(demo.times, velocities[0].velocities, rate)[1]
            noise = max(noise_scale(values), NOISE_FLOOR)
            signals.append(ContactSignal(name, values, STILL, None, noise))
            signals.append(ContactSignal(name, values - hand, None, STILL, noise))  # relative to the hand
    if markers.grip is not None:
        first, second = markers.grip
        name = f"grip aperture rate ({first}-{second})"
        fingers = _smoothed(demo, [first, second], smoothing, notes, name)
        if fingers is not None:
            separation = fingers[0].positions - fingers[1].positions
            relative = fingers[0].velocities - fingers[1].velocities
            distance = np.maximum(np.linalg.norm(separation, axis=1), 1e-9)
            rate_of_change = np.einsum("ti,ti->t", separation, relative) / distance  # d|separation|/dt
            values = resample(demo.times, rate_of_change, rate)[1]
            noise = noise_factor * max(noise_scale(values), NOISE_FLOOR)
            signals.append(ContactSignal(name, values, SMOOTH_MOVEMENT, STILL, noise))
    return signals, notes


def _smoothed(
    demo: Demonstration, names: list[str], smoothing: SmoothingConfig, notes: list[str], signal_name: str
) -> list[SmoothedChannel] | None:
    """The smoothed markers, or None with a note naming the marker that is absent or cannot be bridged."""
    for marker in names:
        if marker not in demo.channels:
            notes.append(f"no {marker!r} marker in the recording: segmented without the {signal_name}")
            return None
    try:
        return [smooth(demo, marker, smoothing) for marker in names]
    except DemonstrationError as error:
        notes.append(f"{error}: segmented without the {signal_name}")
        return None


def joint_models(
    hand_models: tuple[SegmentModel, ...], signals: list[ContactSignal]
) -> tuple[JointModel, ...]:
    """Each hand model as a free and as a holding segment (half its weight each), with the contact signals'
    models; the hand models alone when there are no contact signals. A holding model's name says what shows
    it: ", holding" with the object's marker, ", steady grip" from the grip alone."""
    if not signals:
        return tuple(JointModel.of(model) for model in hand_models)
    state = "holding" if any(signal.name.startswith(OBJECT_SIGNAL) for signal in signals) else "steady grip"
    return tuple(
        JointModel(
            f"{model.name}, {state}" if holding else model.name,
            (model, *(signal.model(holding) for signal in signals)),
            model.weight / 2.0,
            model.hold,
            holding,
        )
        for model in hand_models
        for holding in (False, True)
    )
