"""Joint references from movement primitives: what an arm's executor tracks, sampled at the control rate.

A joint-space primitive starts in the given joint state (the moving-goal DMP takes any start state, so a
primitive can begin while the arm still moves), its acceleration included (:func:`started`), and a learned
one ends at rest at its goal (:func:`at_rest_at_goal`). A Cartesian
primitive starts at the site's pose at rest and is turned into joints by inverse kinematics at knots every
``knot_period`` (each solved from the previous knot's solution), joined by a clamped cubic spline whose
derivatives are the reference's velocities and accelerations - free of the noise that differencing IK
solutions would amplify.

A reference faster than the joints' velocity, acceleration or jerk limits is slowed down by lengthening
the DMP's execution time (which keeps the path) by the factor the worst joint needs, up to ``max_slowdown``
in all; the primitive's DMP keeps the new execution time.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.skills import DMP, CartesianDMP, MovementPrimitive, Trajectory
from besman.skills.transformation import moving_goal_basis

SLOWDOWN_MARGIN = 1.02  # slow down a little more than the worst joint needs: the limits are then met
# The durations tried for a learned movement's stop at its goal (at_rest_at_goal), shortest first: up to 1 s.
SETTLE_DURATIONS = np.arange(0.02, 1.0 + 1e-9, 0.02)
# A reference this close to its goal at rest (rad, rad/s, rad/s^2) has arrived: a point-to-point movement
# ends 1e-15 off (rounding), and a stop that small would only trouble Ruckig (a move of 1e-11 in ~1e-11 s).
AT_GOAL = 1e-9


@dataclass(frozen=True)
class ReferenceSettings:
    """How primitives become joint references.

    Attributes:
        period: seconds between samples (the executor's control period).
        ik_tolerances: (position m, orientation rad) accuracy asked of the IK solutions at the knots.
        ik_acceptance: largest remaining (position, orientation) error that still counts as reached (a joint
            at its limit can slow the convergence below the tolerance).
        knot_period: seconds between the IK knots of a Cartesian reference.
        max_slowdown: the largest factor by which a too-fast primitive is lengthened.
    """

    period: float = 0.002
    ik_tolerances: tuple[float, float] = (1e-7, 1e-6)
    ik_acceptance: tuple[float, float] = (1e-5, 1e-4)
    knot_period: float = 0.01
    max_slowdown: float = 4.0


DEFAULT_SETTINGS = ReferenceSettings()


def joint_reference(
    arm: Arm,
    primitive: MovementPrimitive,
    state: tuple[np.ndarray, np.ndarray, np.ndarray],
    settings: ReferenceSettings = DEFAULT_SETTINGS,
) -> Trajectory:
    """The joint reference of ``primitive`` for ``arm``, started in ``state`` (position, velocity,
    acceleration); see the module documentation. An unreachable Cartesian pose or a joint primitive of the
    wrong size raises an :class:`~besman.core.errors.InputError` that says why."""
    dmp = primitive.dmp
    if not isinstance(dmp, CartesianDMP) and dmp.n_dims != arm.dofs:
        raise InputError(
            f"primitive {primitive.name!r} has {dmp.n_dims} dimensions; the executor drives "
            f"{arm.dofs} joints ({', '.join(arm.joints)})"
        )
    total = 1.0
    while True:
        if isinstance(dmp, CartesianDMP):
            reference = _cartesian_reference(arm, dmp, state[0], settings)
        else:
            reference = started(dmp, state, settings.period)
        factor = arm.slowdown(
            reference.positions, reference.velocities, reference.accelerations, settings.period
        )
        if factor <= 1.0 or total * factor > settings.max_slowdown:
            return reference if isinstance(dmp, CartesianDMP) else at_rest_at_goal(reference, dmp, arm)
        total *= factor * SLOWDOWN_MARGIN
        dmp.execution_time = dmp.execution_time * factor * SLOWDOWN_MARGIN


def started(dmp: DMP, state: tuple[np.ndarray, np.ndarray, np.ndarray], period: float) -> Trajectory:
    """The trajectory of the joint-space ``dmp`` started in ``state`` (position, velocity, acceleration),
    sampled every ``period`` s, its acceleration continuous there. The forcing term's response starts with
    an acceleration of its own (f at the phase's start), which would jump the reference away from the
    state's acceleration - an unbounded jerk at the start of every learned movement; it is taken out of the
    moving goal's start acceleration instead (the trajectory is linear in it, and at t = 0 the goal's
    acceleration is the whole of it), so the reference begins exactly in ``state``."""
    dmp.configure(start=state[0], start_velocity=state[1], start_acceleration=state[2], dt=period)
    reference = dmp.trajectory()
    jump = reference.accelerations[0] - state[2]
    if not jump.any():  # no forcing term at the start
        return reference
    dmp.configure(start_acceleration=state[2] - jump)
    return dmp.trajectory()


def at_rest_at_goal(reference: Trajectory, dmp: DMP, arm: Arm) -> Trajectory:
    """``reference`` (of ``dmp``, sampled every ``dmp.dt``) ending at rest at the DMP's goal. The forcing
    term's response has not died out at the execution time, so a learned movement ends a little off its goal
    and still moving; left so, the executor would brake it to rest at the joints' jerk limits. A quintic
    from its last state to the goal at rest is appended instead, as short as keeps the stop's jerk within
    the movement's own peak between its first and its last tenth (and the joints' velocity and acceleration
    limits): a stop no harsher than the movement's middle. A reference already at rest at its goal (a
    point-to-point movement) and a movement meant to end moving (a goal velocity) are left as they are."""
    position, velocity, acceleration = (
        reference.positions[-1],
        reference.velocities[-1],
        reference.accelerations[-1],
    )
    residual = max(np.abs(position - dmp.goal).max(), np.abs(velocity).max(), np.abs(acceleration).max())
    if dmp.goal_velocity.any() or residual <= AT_GOAL:
        return reference
    period = dmp.dt
    jerk = np.abs(np.diff(reference.accelerations, axis=0)).max(axis=1) / period
    own_peak = jerk[len(jerk) // 10 : -len(jerk) // 10 or None].max()  # between its start and its end
    for duration in SETTLE_DURATIONS:
        steps = max(1, round(duration / period))
        duration = steps * period
        shape = moving_goal_basis(np.arange(1, steps + 1) / steps)
        boundary = np.stack(
            [position, duration * velocity, duration**2 * acceleration, dmp.goal, 0 * position, 0 * position]
        )
        positions, velocities, accelerations = (
            (basis @ boundary) / duration**order for order, basis in enumerate(shape)
        )
        jerk = np.abs(np.diff(np.vstack([acceleration, accelerations]), axis=0)).max() / period
        if (
            jerk <= own_peak
            and (np.abs(velocities) <= arm.max_velocity).all()
            and (np.abs(accelerations) <= arm.max_acceleration).all()
        ):
            break
    times = reference.times[-1] + period * np.arange(1, steps + 1)
    return Trajectory(
        np.r_[reference.times, times],
        np.vstack([reference.positions, positions]),
        np.vstack([reference.velocities, velocities]),
        np.vstack([reference.accelerations, accelerations]),
    )


def at_rest(position: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint state at rest in ``position`` (to plan a primitive ahead of its execution)."""
    position = np.asarray(position, dtype=float)
    return position, np.zeros_like(position), np.zeros_like(position)


def hand_path(
    arm: Arm, primitive: MovementPrimitive, state: tuple[np.ndarray, np.ndarray, np.ndarray], period: float
) -> np.ndarray:
    """The hand's positions (K, 3) every ``period`` s along ``primitive`` started in the joint ``state``: a
    Cartesian primitive's own positions, a joint primitive's by forward kinematics (``primitive`` is left as
    it was)."""
    dmp = copy.deepcopy(primitive.dmp)
    if isinstance(dmp, CartesianDMP):
        _start_cartesian(dmp, arm, state[0], period)
        return dmp.trajectory().positions
    return arm.site_path(at_rest_at_goal(started(dmp, state, period), dmp, arm).positions)


def _start_cartesian(dmp: CartesianDMP, arm: Arm, start: np.ndarray, period: float) -> None:
    """A Cartesian DMP starts at the hand's pose at rest in the joint configuration ``start``."""
    pose = arm.site_pose(start)
    dmp.position.configure(start=pose.position, start_velocity=0.0, start_acceleration=0.0, dt=period)
    dmp.start_orientation = pose.quaternion
    dmp.start_angular_velocity = np.zeros(3)


def _cartesian_reference(
    arm: Arm, dmp: CartesianDMP, start: np.ndarray, settings: ReferenceSettings
) -> Trajectory:
    period = settings.period
    _start_cartesian(dmp, arm, start, period)
    cartesian = dmp.trajectory()
    stride = max(1, round(settings.knot_period / period))
    knots = np.unique(np.r_[np.arange(0, len(cartesian.times), stride), len(cartesian.times) - 1])
    joints = np.empty((len(knots), arm.dofs))
    accepted_position, accepted_orientation = settings.ik_acceptance
    for row, k in enumerate(knots):
        previous = joints[row - 1] if row else start
        result = arm.solve_ik(
            cartesian.positions[k],
            cartesian.orientations[k],
            initial=previous,
            tolerances=settings.ik_tolerances,
        )
        if result.position_error > accepted_position or result.orientation_error > accepted_orientation:
            raise InputError(
                f"unreachable pose at t={cartesian.times[k]:.3f} s of the primitive: {result.message}"
            )
        joints[row] = result.qpos
    from scipy.interpolate import CubicSpline  # here, not with the module, which tree leaves import (0.4 s)

    spline = CubicSpline(cartesian.times[knots], joints, axis=0, bc_type="clamped")
    positions = np.clip(spline(cartesian.times), arm.lower, arm.upper)
    return Trajectory(cartesian.times, positions, spline(cartesian.times, 1), spline(cartesian.times, 2))
