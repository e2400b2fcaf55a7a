"""Joint references from movement primitives: what an arm's executor tracks, sampled at the control rate.

A joint-space primitive starts in the given joint state (the moving-goal DMP takes any start state, so a
primitive can begin while the arm still moves). A Cartesian primitive starts at the site's pose at rest and
is turned into joints by inverse kinematics at knots every ``knot_period`` (each solved from the previous
knot's solution), joined by a clamped cubic spline whose derivatives are the reference's velocities and
accelerations - free of the noise that differencing IK solutions would amplify.

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
from besman.skills import CartesianDMP, MovementPrimitive, Trajectory

SLOWDOWN_MARGIN = 1.02  # slow down a little more than the worst joint needs: the limits are then met


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
            dmp.configure(
                start=state[0], start_velocity=state[1], start_acceleration=state[2], dt=settings.period
            )
            reference = dmp.trajectory()
        factor = arm.slowdown(
            reference.positions, reference.velocities, reference.accelerations, settings.period
        )
        if factor <= 1.0 or total * factor > settings.max_slowdown:
            return reference
        total *= factor * SLOWDOWN_MARGIN
        dmp.execution_time = dmp.execution_time * factor * SLOWDOWN_MARGIN


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
    dmp.configure(start=state[0], start_velocity=state[1], start_acceleration=state[2], dt=period)
    return arm.site_path(dmp.trajectory().positions)


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
