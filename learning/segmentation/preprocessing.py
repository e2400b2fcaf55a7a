"""Cleaning recorded motion: Kalman filtering with RTS smoothing, gap bridging, resampling, hand poses.

Each coordinate of a marker is tracked by a constant-acceleration Kalman filter (filterpy's
``KalmanFilter`` with ``Q_discrete_white_noise``: white jerk) and smoothed backwards by the
Rauch-Tung-Striebel smoother, which gives smoothed position, velocity and acceleration. Missing samples are
predicted through: gaps up to ``max_gap`` seconds are bridged by the smoother; a longer gap is an error that
names the marker and its frames (bridging it would invent motion).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

from besman.core.errors import InputError
from besman.core.validation import checked, instance, numeric, positive, shaped, text
from besman.learning.segmentation.demonstration import DEMONSTRATION, Demonstration, DemonstrationError
from besman.skills.quaternion import from_matrix, make_continuous


@checked(measurement_noise=positive, jerk_noise=positive, max_gap=positive)
@dataclass(frozen=True)
class SmoothingConfig:
    """Noise model of the filter and the longest gap it may bridge.

    Attributes:
        measurement_noise: standard deviation of a marker coordinate (m); motion capture is ~1 mm.
        jerk_noise: standard deviation of the white jerk driving the model (m/s^3); human arm motion
            reaches a few hundred m/s^3 at most.
        max_gap: longest run of missing samples that is bridged (s).
    """

    measurement_noise: float = 0.001
    jerk_noise: float = 50.0
    max_gap: float = 0.25


@dataclass(frozen=True)
class SmoothedChannel:
    """Smoothed position, velocity and acceleration (T, 3) of one marker."""

    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def speed(self) -> np.ndarray:
        return np.linalg.norm(self.velocities, axis=1)


# Each recording's smoothed markers while the recording lives: filterpy filters sample by sample (about 0.3 s
# a marker of a 15 s recording), and segmentation, its contact signals, labelling and every setting a
# benchmark tries ask for the same markers again. The arrays are read-only, so that no caller changes
# another's.
_SMOOTHED: weakref.WeakKeyDictionary[Demonstration, dict[tuple[str, SmoothingConfig], SmoothedChannel]] = (
    weakref.WeakKeyDictionary()
)


@checked(
    demo=DEMONSTRATION,
    marker=text("a marker name"),
    config=instance(SmoothingConfig, "a SmoothingConfig"),
)
def smooth(demo: Demonstration, marker: str, config: SmoothingConfig = SmoothingConfig()) -> SmoothedChannel:
    """Kalman filter + RTS smoother of one marker (see the module documentation); computed once per
    recording, marker and config."""
    known = _SMOOTHED.setdefault(demo, {})
    if (marker, config) not in known:
        known[marker, config] = _smooth(demo, marker, config)
    return known[marker, config]


def _smooth(demo: Demonstration, marker: str, config: SmoothingConfig) -> SmoothedChannel:
    values = demo.channel(marker)
    dt = float(np.median(np.diff(demo.times)))
    for first, last in demo.gaps(marker):
        length = (demo.frame_index(last) - demo.frame_index(first) + 1) * dt
        if length > config.max_gap:
            raise DemonstrationError(
                f"{demo.source}: marker {marker!r} is missing for {length:.2f} s (frames "
                f"{first}-{last}), longer than the {config.max_gap:g} s that are bridged"
            )
    first_valid = int(np.flatnonzero(~np.isnan(values).any(axis=1))[0])
    result = np.empty((3, len(values), 3))
    for axis in range(3):
        kalman = KalmanFilter(dim_x=3, dim_z=1)
        kalman.F = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        kalman.H = np.array([[1.0, 0.0, 0.0]])
        kalman.R *= config.measurement_noise**2
        kalman.Q = Q_discrete_white_noise(dim=3, dt=dt, var=config.jerk_noise**2 * dt)
        kalman.x = np.array([[values[first_valid, axis]], [0.0], [0.0]])
        kalman.P = np.diag([config.measurement_noise**2, 1.0, 100.0])
        measurements = [None if np.isnan(v) else np.array([[v]]) for v in values[:, axis]]
        means, covariances, _, _ = kalman.batch_filter(measurements)
        smoothed, _, _, _ = kalman.rts_smoother(means, covariances)
        result[:, :, axis] = smoothed[:, :, 0].T
    result.setflags(write=False)
    return SmoothedChannel(*result)


@checked(times=shaped(ndim=1), values=numeric, rate=positive)
def resample(times: np.ndarray, values: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Values (T, ...) linearly interpolated at ``rate`` Hz over the same time span (values may hold NaN)."""
    if values.ndim == 0 or len(values) != len(times) or len(times) == 0:
        raise InputError(
            f"learning.resample: values need one row per time ({len(times)}), got shape {values.shape}"
        )
    new_times = np.arange(times[0], times[-1] + 1e-9, 1.0 / rate)
    flat = values.reshape(len(times), -1)
    resampled = np.column_stack([np.interp(new_times, times, flat[:, i]) for i in range(flat.shape[1])])
    return new_times, resampled.reshape(len(new_times), *values.shape[1:])


@checked(
    demo=DEMONSTRATION,
    top=text("a marker name"),
    left=text("a marker name"),
    right=text("a marker name"),
    config=instance(SmoothingConfig, "a SmoothingConfig"),
)
def hand_pose(
    demo: Demonstration,
    top: str = "Hand top",
    left: str = "Hand left",
    right: str = "Hand right",
    config: SmoothingConfig = SmoothingConfig(),
) -> tuple[np.ndarray, np.ndarray]:
    """Position (T, 3, the markers' centroid) and orientation (T, 4, w-x-y-z) of a hand from three markers:
    y points from the right marker to the left one, z is the normal of the three markers' plane."""
    top_, left_, right_ = (smooth(demo, name, config).positions for name in (top, left, right))
    y = left_ - right_
    z = np.cross(top_ - right_, y)
    lengths = np.linalg.norm(y, axis=1) * np.linalg.norm(z, axis=1)
    if np.any(lengths < 1e-9):
        raise DemonstrationError(f"{demo.source}: the hand markers {top}, {left}, {right} are collinear")
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    x = np.cross(y, z)
    quaternions = from_matrix(np.stack([x, y, z], axis=2))
    return (top_ + left_ + right_) / 3.0, make_continuous(quaternions)
