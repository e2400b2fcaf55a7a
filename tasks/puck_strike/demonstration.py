"""The puck-strike demonstration: a synthetic, kinesthetic-style strike, its file and its imitation.

No person demonstrated this strike: :func:`synthetic_strike` writes it analytically, as a joint-space spline
(piecewise polynomials through three knots, ``scipy.interpolate.BPoly.from_derivatives``) of the three pitch
joints (shoulder lift, elbow, wrist 1; pan and the wrist's other joints stay still): at rest, with zero
acceleration, in the start pose - the backswing - forwards and down through the contact pose
:data:`CONTACT_POSE` (the blade upright, its axis at the puck's mid-height, 5 mm behind the puck) at
t = 0.4 s with the pitch joints' velocity :data:`CONTACT_VELOCITY` (the blade then moves horizontally along
+x at 1.48 m/s: the direction is the one that moves it fastest for the joints' speeds, a small linear
program, its size picked by hand), and on to rest in a follow-through that lifts the blade
(:data:`FOLLOW_THROUGH_LIFT`). The start pose is the contact pose less the contact velocity times 0.2 s,
raised by 0.05 rad of shoulder lift (:data:`~besman.tasks.puck_strike.rollouts.START`, rounded). At rest
with zero acceleration at both ends, so that the task's DMP, which starts so, imitates it closely (0.006
rad). It drives the puck straight along the arm's plane (y = 0.134 m). The contact velocity's size was
picked by hand (four tries) so that the puck stops short of the middle of the task's box, as a first human
demonstration misses: replayed as recorded, and imitated by the task's DMP, its puck comes to rest at about
(1.34, 0.13) m, 0.21 m before the middle target and 6 cm before the box's near edge, so it succeeds for no
target of the box (the tests check it).

The file (``examples/data/puck_strike_demo.json``) is :mod:`besman.sim.joint_demonstrations`' JSON (never
pickle): ``schema_version``, ``kind``, the robot and its joints, ``synthetic: true`` with how it was made, and
the samples (``times``, s, and ``positions``, rad, at 500 Hz, the robot's control rate).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.sim.joint_demonstrations import imitate as imitate  # the task's DMP from its demonstration
from besman.sim.joint_demonstrations import read_demonstration, sample_held, write_demonstration

KIND = "besman puck-strike demonstration"
SAMPLE_RATE = 500.0  # Hz, the robot's control rate
ROBOT = "ur5e"
# The contact pose (the blade upright, its axis at the puck's mid-height, 5 mm behind the puck) and the
# pitch joints' velocity there (rad/s: shoulder lift, elbow, wrist 1; the blade moves horizontally forwards).
CONTACT_POSE = (-1.5708, -1.5078, 1.8427, -1.9058, -1.5708, -1.5708)
CONTACT_VELOCITY = (1.9, -1.604, -1.9)
# The knots' times (s): start (the top of the backswing), contact, end.
TIMES = (0.0, 0.4, 1.0)
PITCH_JOINTS = (1, 2, 3)
FOLLOW_THROUGH_LIFT = -0.3  # rad of shoulder lift added at the end: the follow-through lifts the head
FILE = "puck_strike_demo.json"


def _knots(start) -> list[np.ndarray]:
    """The spline's knots: per knot its joint positions, velocities and (at rest) accelerations."""
    start = np.asarray(start, dtype=float)
    contact = np.asarray(CONTACT_POSE, dtype=float)
    velocity = np.zeros(6)
    velocity[list(PITCH_JOINTS)] = CONTACT_VELOCITY
    # From the contact to rest over the follow-through with about a constant deceleration covers half the
    # contact velocity times the time; the shoulder lifts the head on top of it.
    end = contact + velocity * (TIMES[2] - TIMES[1]) / 2
    end[PITCH_JOINTS[0]] += FOLLOW_THROUGH_LIFT
    rest = np.zeros(6)
    return [np.array([start, rest, rest]), np.array([contact, velocity]), np.array([end, rest, rest])]


def synthetic_strike(start, times=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The strike sampled at ``times`` (default: :data:`SAMPLE_RATE` over its 1 s): times (T,), joint
    positions and velocities (T, 6) from ``start`` (6 joint values); after its end it holds still."""
    from scipy.interpolate import BPoly

    spline = BPoly.from_derivatives(TIMES, _knots(start))
    return sample_held(spline, TIMES[-1], SAMPLE_RATE, times)


def save_demonstration(path, start, joints) -> Path:
    """Writes the synthetic strike from ``start`` to ``path`` (JSON, see the module documentation)."""
    times, positions, _ = synthetic_strike(start)
    made_by = (
        "besman.tasks.puck_strike.demonstration.synthetic_strike (written by benchmarks/puck_strike.py "
        "--write-demo): an analytic joint-space spline in the manner of a kinesthetic demonstration, "
        "not a recording of a person; its puck stops short of the middle target on purpose"
    )
    return write_demonstration(
        path, kind=KIND, robot=ROBOT, joints=joints, made_by=made_by, times=times, positions=positions
    )


def load_demonstration(path) -> tuple[np.ndarray, np.ndarray]:
    """Times (T,) and joint positions (T, 6) of a demonstration file; a file of another kind or schema is
    refused by name."""
    return read_demonstration(path, KIND)
