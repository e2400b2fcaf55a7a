"""Cartesian DMPs: a position DMP plus an orientation DMP on unit quaternions (Ude et al., ICRA 2014).

Position is a 3-D :class:`~besman.skills.dmp.DMP` (goal velocity, exact generation). Orientation follows
Ude, Nemec, Petric and Morimoto, "Orientation in Cartesian space dynamic movement primitives" (ICRA 2014),
with the world-frame angular velocity omega and the quaternion q in (w, x, y, z) order::

    tau^2 omega_dot = alpha_y (beta_y 2 log(g * conj(q)) - tau omega) + f(z)
    q_dot = 1/2 omega * q

The orientation system is nonlinear, so it is integrated in time: a symmetric kick-drift-kick splitting
(second order) that treats the damping exactly and rotates q by the exponential map,
q <- exp(h omega / 2) * q,
so q stays a unit quaternion (it is also renormalised at every output). The internal step is about tau / 1000
(each output step is split into a whole number of internal steps).

Parameter vector theta
----------------------
``theta`` = the position DMP's theta (3 x (N weights, goal, goal velocity)), followed by 3 x (N weights,
goal) for the rotation axes x, y, z, where the orientation goal is its rotation vector 2 log(g)
(angle * axis). Orientation entries are scaled like the position DMP's (see :mod:`besman.skills.dmp`) with
``rotation_scale`` (rad): a unit step turns the movement or the goal by about ``rotation_scale``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import broadcast_vector, checked, finite_array, increasing_times
from besman.skills import quaternion
from besman.skills.dmp import DEFAULT_SETTINGS, DMP
from besman.skills.dmp_core import DMPSettings, fit_weights

STEP_FRACTION = 1.0 / 1000.0  # internal orientation step ~ tau / 1000 (output steps are split evenly)


@dataclass(frozen=True)
class CartesianTrajectory:
    """Sampled Cartesian trajectories: ``times`` (T,); positions, velocities, accelerations, angular
    velocities and accelerations (T, 3); orientations (T, 4) as (w, x, y, z). A population adds a leading
    axis (N, T, ...)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    orientations: np.ndarray
    angular_velocities: np.ndarray
    angular_accelerations: np.ndarray


@checked()  # an unknown keyword is named, with the nearest known one
class CartesianDMP:
    """Position and orientation DMP; quaternions are (w, x, y, z).

    Args:
        settings: basis functions and gains, shared by position and orientation
            (:class:`~besman.skills.dmp_core.DMPSettings`).
        execution_time, dt: as for :class:`~besman.skills.dmp.DMP`.
        scale: exploration scale of the position entries of theta (m).
        rotation_scale: exploration scale of the orientation entries of theta (rad).
        start_position, start_velocity, goal_position, goal_velocity: position boundary values.
        start_orientation, goal_orientation: unit quaternions (w, x, y, z); default identity.
        start_angular_velocity: world-frame angular velocity at the start (rad/s).
    """

    def __init__(
        self,
        *,
        settings: DMPSettings = DEFAULT_SETTINGS,
        execution_time: float = 1.0,
        dt: float = 0.01,
        scale=0.1,
        rotation_scale=0.1,
        start_position=None,
        start_velocity=None,
        goal_position=None,
        goal_velocity=None,
        start_orientation=None,
        start_angular_velocity=None,
        goal_orientation=None,
    ) -> None:
        self.position = DMP(
            3,
            settings=settings,
            execution_time=execution_time,
            dt=dt,
            scale=scale,
            start=start_position,
            start_velocity=start_velocity,
            goal=goal_position,
            goal_velocity=goal_velocity,
        )
        self.rotation_scale = broadcast_vector("rotation_scale", rotation_scale, 3)
        if np.any(self.rotation_scale <= 0):
            raise InputError(f"rotation_scale must be positive, got {self.rotation_scale}")
        identity = np.array([1.0, 0.0, 0.0, 0.0])
        self.start_orientation = quaternion.normalized(
            "start_orientation", identity if start_orientation is None else start_orientation
        )
        self.goal_orientation = quaternion.normalized(
            "goal_orientation", identity if goal_orientation is None else goal_orientation
        )
        self.start_angular_velocity = broadcast_vector(
            "start_angular_velocity", start_angular_velocity, 3, 0.0
        )
        self.rotation_weights = np.zeros((3, self.n_weights))

    @property
    def settings(self) -> DMPSettings:
        return self.position.settings

    @property
    def n_weights(self) -> int:
        return self.settings.n_weights

    @property
    def execution_time(self) -> float:
        return self.position.execution_time

    @execution_time.setter
    def execution_time(self, value: float) -> None:
        self.position.execution_time = value

    @property
    def dt(self) -> float:
        return self.position.dt

    @dt.setter
    def dt(self, value: float) -> None:
        self.position.dt = value

    @property
    def n_params(self) -> int:
        """Length of theta: 3 (N + 2) for position plus 3 (N + 1) for orientation."""
        return self.position.n_params + 3 * (self.n_weights + 1)

    # -- the parameter vector ------------------------------------------------------------------------------

    def _rotation_units(self) -> np.ndarray:
        return self.rotation_scale[:, None] * np.concatenate([self.settings.weight_units, [1.0]])[None, :]

    def get_params(self) -> np.ndarray:
        rotation = np.column_stack([self.rotation_weights, quaternion.rotation_vector(self.goal_orientation)])
        return np.concatenate([self.position.get_params(), (rotation / self._rotation_units()).ravel()])

    def set_params(self, theta) -> CartesianDMP:
        theta = self._check_theta(theta)
        self.position.set_params(theta[: self.position.n_params])
        rotation = self._raw_rotation(theta[None])[0]
        self.rotation_weights = rotation[:, : self.n_weights].copy()
        self.goal_orientation = quaternion.from_rotation_vector(rotation[:, -1])
        return self

    def _check_theta(self, theta) -> np.ndarray:
        theta = finite_array("theta", theta)
        if theta.shape != (self.n_params,):
            raise InputError(f"theta must have {self.n_params} entries, got shape {theta.shape}")
        return theta

    def _raw_rotation(self, thetas: np.ndarray) -> np.ndarray:
        rotation = thetas[:, self.position.n_params :].reshape(len(thetas), 3, self.n_weights + 1)
        return rotation * self._rotation_units()

    # -- generation ----------------------------------------------------------------------------------------

    def trajectory(self, theta=None, *, run_time: float | None = None) -> CartesianTrajectory:
        """One trajectory for theta (default: the DMP's own parameters); arrays (T, 3) and (T, 4)."""
        thetas = (self.get_params() if theta is None else self._check_theta(theta))[None]
        batch = self.trajectories(thetas, run_time=run_time)
        return CartesianTrajectory(batch.times, *(getattr(batch, name)[0] for name in _FIELDS))

    def trajectories(self, thetas, *, run_time: float | None = None) -> CartesianTrajectory:
        """Trajectories of a population: thetas (N, n_params) -> arrays (N, T, 3) and (N, T, 4)."""
        thetas = finite_array("thetas", thetas)
        if thetas.ndim != 2 or thetas.shape[1] != self.n_params:
            raise InputError(f"thetas must have shape (N, {self.n_params}), got {thetas.shape}")
        translation = self.position.trajectories(thetas[:, : self.position.n_params], run_time=run_time)
        rotation = self._raw_rotation(thetas)
        goals = quaternion.from_rotation_vector(rotation[:, :, -1])
        orientations, angular_velocities, angular_accelerations = self._integrate_orientation(
            rotation[:, :, : self.n_weights], goals, translation.times
        )
        return CartesianTrajectory(
            translation.times,
            translation.positions,
            translation.velocities,
            translation.accelerations,
            orientations,
            angular_velocities,
            angular_accelerations,
        )

    def _integrate_orientation(self, weights: np.ndarray, goals: np.ndarray, times: np.ndarray):
        tau = self.execution_time
        alpha, beta = self.position.system.alpha_y, self.position.system.beta_y
        output_step = times[1] - times[0]
        substeps = max(1, round(output_step / (STEP_FRACTION * tau)))
        h = output_step / substeps
        internal = np.arange((len(times) - 1) * substeps + 1) * h
        forcing = np.einsum("kn,mdn->kdm", self.position.basis.features(internal / tau), weights) / tau**2
        start = np.broadcast_to(self.start_orientation, goals.shape)
        omega0 = np.broadcast_to(self.start_angular_velocity, (len(goals), 3))
        if len(goals) == 1:  # one candidate: plain floats are ~10x faster than numpy on 1-element arrays
            state = [float(v) for v in (*start[0], *omega0[0])]
            goal = [float(v) for v in goals[0]]
            components = [forcing[:, d, 0].tolist() for d in range(3)]
            functions = (math.sqrt, math.atan2, math.sin, math.cos, math.copysign)
        else:
            state = [start[:, i].copy() for i in range(4)] + [omega0[:, i].copy() for i in range(3)]
            goal = [goals[:, i] for i in range(4)]
            components = [forcing[:, d, :] for d in range(3)]
            functions = (np.sqrt, np.arctan2, np.sin, np.cos, np.copysign)
        rows = _kick_drift_kick(
            functions, state, goal, components, h, alpha / tau, alpha * beta / tau**2, substeps, len(times)
        )
        recorded = np.asarray(rows, dtype=float).reshape(len(times), 10, -1).transpose(2, 0, 1)
        return (
            np.ascontiguousarray(recorded[..., :4]),
            np.ascontiguousarray(recorded[..., 4:7]),
            np.ascontiguousarray(recorded[..., 7:]),
        )

    # -- imitation -----------------------------------------------------------------------------------------

    def imitate(self, times, positions, orientations, *, regularization: float = 1e-8) -> CartesianDMP:
        """Fits position and orientation to one demonstration, or to lists of several.

        ``positions`` (T, 3) and ``orientations`` (T, 4, w-x-y-z; normalised, signs made continuous) share
        ``times`` (T,). Several demonstrations are normalised in time and stacked as for
        :meth:`DMP.imitate`; the goal orientation is their average rotation.
        """
        several = isinstance(positions, list | tuple)
        if not several:
            times, positions, orientations = [times], [positions], [orientations]
        if not (isinstance(times, list | tuple) and len(times) == len(positions) == len(orientations) > 0):
            raise InputError(
                "give as many time, position and orientation arrays (one demonstration or lists)"
            )
        self.position.imitate(list(times), list(positions), regularization=regularization)
        tau = self.execution_time
        alpha, beta = self.position.system.alpha_y, self.position.system.beta_y
        features, targets, starts, goals, start_velocities = [], [], [], [], []
        for k, (t, q) in enumerate(zip(times, orientations, strict=True)):
            name = f"demonstration {k}" if several else "demonstration"
            t = increasing_times(f"{name}: times", t, minimum_length=3)
            q = quaternion.make_continuous(quaternion.normalized(f"{name}: orientations", q))
            if q.shape != (len(t), 4):
                raise InputError(f"{name}: orientations must have shape ({len(t)}, 4), got {q.shape}")
            duration = t[-1] - t[0]
            s = (t - t[0]) / duration
            omega = _angular_velocity(s, q)  # normalised time: d/ds
            omega_dot = np.gradient(omega, s, axis=0, edge_order=2)
            error = quaternion.rotation_vector(quaternion.multiply(q[-1], quaternion.conjugate(q)))
            weight = 1.0 / np.sqrt(len(t))  # each demonstration weighs the same, as in DMP.imitate
            targets.append(weight * (omega_dot - alpha * (beta * error - omega)))
            features.append(weight * self.position.basis.features(s))
            starts.append(q[0])
            goals.append(q[-1])
            start_velocities.append(omega[0] / tau)
        self.rotation_weights = fit_weights(features, targets, regularization)
        self.start_orientation = quaternion.mean(np.array(starts))
        self.goal_orientation = quaternion.mean(np.array(goals))
        self.start_angular_velocity = np.mean(start_velocities, axis=0)
        return self


_FIELDS = (
    "positions",
    "velocities",
    "accelerations",
    "orientations",
    "angular_velocities",
    "angular_accelerations",
)


def _angular_velocity(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """World-frame angular velocity of a quaternion sequence: second-order central differences of the
    relative rotations (one-sided at the ends)."""
    omega = np.empty((len(q), 3))
    omega[1:-1] = quaternion.rotation_vector(quaternion.multiply(q[2:], quaternion.conjugate(q[:-2])))
    omega[1:-1] /= (s[2:] - s[:-2])[:, None]
    forward = quaternion.rotation_vector(quaternion.multiply(q[1:], quaternion.conjugate(q[:-1])))
    forward /= np.diff(s)[:, None]
    omega[0] = 2 * forward[0] - omega[1]
    omega[-1] = 2 * forward[-1] - omega[-2]
    return omega


def _kick_drift_kick(functions, state, goal, forcing, h, damping, stiffness, substeps, n_outputs):
    """Integrates tau^2 omega_dot = alpha (beta 2 log(g q*) - tau omega) + f and q_dot = omega q / 2.

    Each step: half a step of the velocity equation with the damping solved exactly and the drive held
    constant, a rotation of q by h omega (exponential map), then the other half with the new drive.
    Components are floats (one candidate, ``math`` functions) or arrays (a population, numpy functions);
    the same arithmetic serves both. Returns one row (q, omega, omega_dot) per output time.
    """
    sqrt, atan2, sin, cos, copysign = functions
    qw, qx, qy, qz, wx, wy, wz = state
    gw, gx, gy, gz = goal
    fx, fy, fz = forcing
    decay = math.exp(-0.5 * damping * h)
    gain = (1.0 - decay) / damping
    rows = []
    step = 0
    ax = ay = az = None
    for output in range(n_outputs):
        for _ in range(substeps if output else 1):
            if ax is not None:  # not before the first drive: the first output is the start state
                wx, wy, wz = decay * wx + gain * ax, decay * wy + gain * ay, decay * wz + gain * az
                vx, vy, vz = h * wx, h * wy, h * wz
                angle = sqrt(vx * vx + vy * vy + vz * vz)
                rw, rs = cos(0.5 * angle), sin(0.5 * angle) / (angle + 1e-300)
                rx = rs * vx
                ry = rs * vy
                rz = rs * vz
                nw = rw * qw - rx * qx - ry * qy - rz * qz
                nx = rw * qx + rx * qw + ry * qz - rz * qy
                ny = rw * qy - rx * qz + ry * qw + rz * qx
                qz = rw * qz + rx * qy - ry * qx + rz * qw
                qw = nw
                qx = nx
                qy = ny
                step += 1
            # The drive: 2 log(g * conj(q)) on the shortest arc, scaled, plus the forcing term.
            pw = gw * qw + gx * qx + gy * qy + gz * qz
            px = -gw * qx + gx * qw - gy * qz + gz * qy
            py = -gw * qy + gx * qz + gy * qw - gz * qx
            pz = -gw * qz - gx * qy + gy * qx + gz * qw
            sine = sqrt(px * px + py * py + pz * pz)
            factor = stiffness * copysign(2.0, pw) * atan2(sine, abs(pw)) / (sine + 1e-300)
            ax, ay, az = factor * px + fx[step], factor * py + fy[step], factor * pz + fz[step]
            if step:
                wx, wy, wz = decay * wx + gain * ax, decay * wy + gain * ay, decay * wz + gain * az
        # Renormalise once per output: the exponential map keeps |q| = 1 up to rounding (~1e-16 per step).
        norm = 1.0 / sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw * norm, qx * norm, qy * norm, qz * norm
        rows.append((qw, qx, qy, qz, wx, wy, wz, ax - damping * wx, ay - damping * wy, az - damping * wz))
    return rows
