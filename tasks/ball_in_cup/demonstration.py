"""The ball-in-a-cup demonstration: a synthetic, kinesthetic-style swing-up, its file and its imitation.

No person demonstrated this swing: :func:`synthetic_swing` writes it analytically, as a joint-space cubic
spline (at rest at both ends) from the task's start pose through two via points of the three pitch joints
(shoulder lift, elbow, wrist 1) - the cup drops back and down (the ball swings forward), is pulled up and
forward (the ball flies up over it) and comes back under the ball. Its numbers (:data:`SWING`) came from
a coarse search of such splines on the task's rollouts; one of them (the last via point's elbow) was then
moved by 0.1 rad so that the swing misses, as a first human demonstration does: replayed as recorded it
catches the ball for no string length of the task's box, and neither does the DMP imitated from it (the
tests check both), but the ball comes down near the cup.

The file (``examples/data/ball_in_cup_demo.json``) is :mod:`besman.sim.joint_demonstrations`' JSON (never
pickle): ``schema_version``, ``kind``, the robot and its joints, ``synthetic: true`` with how it was made, and
the samples (``times``, s, and ``positions``, rad, at 100 Hz).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.sim.joint_demonstrations import imitate as imitate  # the task's DMP from its demonstration
from besman.sim.joint_demonstrations import read_demonstration, sample_held, write_demonstration

KIND = "besman ball-in-cup demonstration"
SAMPLE_RATE = 100.0  # Hz
# The spline's knots: times (s) and the pitch joints' offsets from the start pose (rad) at the two via
# points and at the end (shoulder lift, elbow, wrist 1).
SWING_TIMES = (0.0, 0.353, 0.654, 1.2)
SWING = ((0.049, 0.452, 0.48), (0.074, -0.15, -0.256), (0.169, -0.069, -0.138))
PITCH_JOINTS = (1, 2, 3)
FILE = "ball_in_cup_demo.json"


def synthetic_swing(start, times=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The swing sampled at ``times`` (default: 100 Hz over its 1.2 s): times (T,), joint positions and
    velocities (T, 6) from ``start`` (6 joint values); after its end it holds still."""
    from scipy.interpolate import CubicSpline

    start = np.asarray(start, dtype=float)
    knots = np.repeat(start[None], len(SWING_TIMES), axis=0)
    for row, offsets in enumerate(SWING, start=1):
        knots[row, list(PITCH_JOINTS)] += offsets
    spline = CubicSpline(SWING_TIMES, knots, bc_type="clamped")
    return sample_held(spline, SWING_TIMES[-1], SAMPLE_RATE, times)


def save_demonstration(path, start, joints) -> Path:
    """Writes the synthetic swing from ``start`` to ``path`` (JSON, see the module documentation)."""
    times, positions, _ = synthetic_swing(start)
    made_by = (
        "besman.tasks.ball_in_cup.demonstration.synthetic_swing (written by benchmarks/ball_in_cup.py "
        "--write-demo): "
        "an analytic joint-space spline in the manner of a kinesthetic demonstration, not a recording "
        "of a person; it misses on purpose"
    )
    return write_demonstration(
        path, kind=KIND, robot="ur5e", joints=joints, made_by=made_by, times=times, positions=positions
    )


def load_demonstration(path) -> tuple[np.ndarray, np.ndarray]:
    """Times (T,) and joint positions (T, 6) of a demonstration file; a file of another kind or schema is
    refused by name."""
    return read_demonstration(path, KIND)
