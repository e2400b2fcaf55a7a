"""Dynamical movement primitives with goal velocity, generated exactly and for whole populations at once.

A :class:`DMP` has ``n_dims`` independent dimensions (joints, or any coordinates) that share an execution
time tau and a phase. Each dimension follows the goal-velocity transformation system of Muelling et al.
(IJRR 2013), see :mod:`besman.skills.transformation`: a quintic "moving goal" from the start state to
(goal, goal velocity) plus the response of a critically damped system (alpha_y = 25, beta_y = 6.25) to a
forcing term of N normalised radial basis functions (:mod:`besman.skills.forcing`).

The trajectory is linear in the weights, the goal and the goal velocity, so it is computed as a matrix
product with precomputed responses: exact (no Euler steps) and, for a population of parameter vectors,
one matrix product for all candidates and time steps.

Parameter vector theta
----------------------
``theta`` has ``n_dims * (n_weights + 2)`` entries; ``theta.reshape(n_dims, n_weights + 2)`` gives, per
dimension, the N weights, then the goal position, then the goal velocity (a 7-joint DMP with 10 weights is
84-D). Every entry is scaled so that a step of 1 changes the movement by about ``scale`` (in the dimension's
units, default 0.1 rad or m) - a sensible exploration step for an optimiser in every block:

- weight i: theta_i = w_i * peak_i / scale, where peak_i is the largest displacement (in normalised time) a
  unit weight i causes. A unit step of any weight moves the path by at most ``scale``; raw weights differ
  in effect by two orders of magnitude because the phase gate z decays to 0.01.
- goal: theta_g = g / scale; a unit step moves the goal by ``scale``.
- goal velocity: theta_gd = gd * tau / scale; a unit step changes the final velocity by ``scale`` per
  execution time.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import broadcast_vector, checked, finite_array, increasing_times, positive
from besman.skills.dmp_core import DMPSettings, fit_weights
from besman.skills.forcing import ForcingBasis
from besman.skills.transformation import TransformationSystem, moving_goal_basis

DEFAULT_SETTINGS = DMPSettings()
MAX_STEPS = 20_000  # time steps of one generated trajectory (20 s at 1 ms)


@dataclass(frozen=True)
class Trajectory:
    """Sampled trajectories: ``times`` (T,); positions, velocities, accelerations (T, D), or (N, T, D) for a
    population of N parameter vectors (velocities and accelerations may be None when not asked for)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None


@dataclass(frozen=True)
class _LinearMap:
    """Trajectory = raw_block @ by_parameters.T + start_state @ by_start.T, per dimension and derivative."""

    times: np.ndarray
    by_parameters: tuple[np.ndarray, np.ndarray, np.ndarray]  # (T, N + 2) for weights, goal, goal velocity
    by_start: tuple[np.ndarray, np.ndarray, np.ndarray]  # (T, 3) for y0, yd0, ydd0


@functools.lru_cache(maxsize=32)
def linear_map(settings: DMPSettings, tau: float, dt: float, run_time: float) -> _LinearMap:
    """The responses of a DMP of these settings, execution time ``tau`` and step ``dt`` from 0 to
    ``run_time``: shared by every DMP of the same timing (planning and execution make many), and read-only."""
    system = settings.system
    steps = max(1, round(run_time / dt))
    times = np.linspace(0.0, run_time, steps + 1)
    s = times / tau
    e, de, dde = system.forced_response(settings.basis, s)
    goal_position, goal_velocity, goal_acceleration = moving_goal_basis(s)
    # The quintic's boundary vector is (y0, tau yd0, tau^2 ydd0, g, tau gd, 0) in normalised time.
    normalise = np.array([1.0, tau, tau**2, 1.0, tau, 0.0])
    by_derivative = []
    for order, (forced, quintic) in enumerate(
        [(e, goal_position), (de, goal_velocity), (dde, goal_acceleration)]
    ):
        to_time = tau**-order  # d/dt = (1 / tau) d/ds
        quintic = quintic * normalise * to_time
        parameters = np.column_stack([forced * to_time, quintic[:, 3], quintic[:, 4]])
        by_derivative.append((parameters, quintic[:, :3]))
    after = s > 1.0
    if after.any():
        # After tau the goal stops while y keeps its velocity: the free response to a jump of tau*gd.
        free, dfree = system.free_response(s[after] - 1.0)
        ddfree = -system.alpha_y * system.beta_y * free - system.alpha_y * dfree
        for order, response in enumerate((free, dfree, ddfree)):
            by_derivative[order][0][after, -1] += tau * response * tau**-order
    arrays = [times, *(p for p, _ in by_derivative), *(q for _, q in by_derivative)]
    for array in arrays:
        array.flags.writeable = False
    return _LinearMap(times, tuple(p for p, _ in by_derivative), tuple(q for _, q in by_derivative))


@checked()  # an unknown keyword is named, with the nearest known one
class DMP:
    """An n-dimensional DMP with goal velocity (Muelling et al. 2013).

    Args:
        n_dims: number of dimensions.
        settings: the forcing term's basis functions and the gains
            (:class:`~besman.skills.dmp_core.DMPSettings`).
        execution_time: tau, the duration of the movement (s).
        dt: time step of generated trajectories (s); the samples end exactly at the run time.
        scale: per-dimension (or one) exploration scale of theta, in the dimension's units.
        start, start_velocity, start_acceleration: the start state (defaults: zeros).
        goal, goal_velocity: the end state at tau (defaults: zeros).
    """

    def __init__(
        self,
        n_dims: int,
        *,
        settings: DMPSettings = DEFAULT_SETTINGS,
        execution_time: float = 1.0,
        dt: float = 0.01,
        scale=0.1,
        start=None,
        start_velocity=None,
        start_acceleration=None,
        goal=None,
        goal_velocity=None,
    ) -> None:
        if not isinstance(n_dims, int | np.integer) or n_dims < 1:
            raise InputError(f"n_dims must be a positive integer, got {n_dims!r}")
        if not isinstance(settings, DMPSettings):
            raise InputError(f"settings must be a DMPSettings, got {type(settings).__name__}")
        self.n_dims = int(n_dims)
        self.settings = settings
        self._execution_time = positive("execution_time", execution_time)
        self._dt = positive("dt", dt)
        self.scale = self._scale(scale)
        self.start = broadcast_vector("start", start, self.n_dims)
        self.start_velocity = broadcast_vector("start_velocity", start_velocity, self.n_dims)
        self.start_acceleration = broadcast_vector("start_acceleration", start_acceleration, self.n_dims)
        self.goal = broadcast_vector("goal", goal, self.n_dims)
        self.goal_velocity = broadcast_vector("goal_velocity", goal_velocity, self.n_dims)
        self.weights = np.zeros((self.n_dims, self.n_weights))

    # -- configuration -------------------------------------------------------------------------------------

    @property
    def basis(self) -> ForcingBasis:
        return self.settings.basis

    @property
    def system(self) -> TransformationSystem:
        return self.settings.system

    @property
    def n_weights(self) -> int:
        return self.settings.n_weights

    @property
    def n_params(self) -> int:
        """Length of theta: n_dims * (n_weights + 2)."""
        return self.n_dims * (self.n_weights + 2)

    @property
    def execution_time(self) -> float:
        return self._execution_time

    @execution_time.setter
    def execution_time(self, value: float) -> None:
        self._execution_time = positive("execution_time", value)

    @property
    def dt(self) -> float:
        return self._dt

    @dt.setter
    def dt(self, value: float) -> None:
        self._dt = positive("dt", value)

    def _scale(self, scale) -> np.ndarray:
        scale = broadcast_vector("scale", scale, self.n_dims)
        if np.any(scale <= 0):
            raise InputError(f"scale must be positive, got {scale}")
        return scale

    def configure(self, **meta_parameters) -> DMP:
        """Sets meta-parameters by name (start, start_velocity, start_acceleration, goal, goal_velocity,
        execution_time, dt, scale) and returns the DMP."""
        vectors = ("start", "start_velocity", "start_acceleration", "goal", "goal_velocity")
        known = (*vectors, "scale", "execution_time", "dt")
        for name, value in meta_parameters.items():
            if name in vectors:
                setattr(self, name, broadcast_vector(name, value, self.n_dims))
            elif name == "scale":
                self.scale = self._scale(value)
            elif name in ("execution_time", "dt"):
                setattr(self, name, value)
            else:
                raise InputError(f"unknown meta-parameter {name!r}; known: {', '.join(known)}")
        return self

    # -- the parameter vector ------------------------------------------------------------------------------

    def _units(self) -> np.ndarray:
        """(n_dims, N + 2): raw value = theta * units (weights, goal, goal velocity)."""
        unscaled = np.concatenate([self.settings.weight_units, [1.0, 1.0 / self._execution_time]])
        return self.scale[:, None] * unscaled[None, :]

    def get_params(self) -> np.ndarray:
        """theta (see the module documentation for the layout and scaling)."""
        raw = np.column_stack([self.weights, self.goal, self.goal_velocity])
        return (raw / self._units()).ravel()

    def set_params(self, theta) -> DMP:
        """Sets weights, goal and goal velocity from theta; returns the DMP."""
        raw = self._raw(self._check_theta(theta))
        self.weights = raw[:, : self.n_weights].copy()
        self.goal = raw[:, self.n_weights].copy()
        self.goal_velocity = raw[:, self.n_weights + 1].copy()
        return self

    def _check_theta(self, theta) -> np.ndarray:
        theta = finite_array("theta", theta)
        if theta.ndim != 1 or theta.shape[0] != self.n_params:
            raise InputError(
                f"theta must have {self.n_params} entries "
                f"(n_dims {self.n_dims} x (n_weights {self.n_weights} + 2)), "
                f"got shape {theta.shape}"
            )
        return theta

    def _raw(self, thetas: np.ndarray) -> np.ndarray:
        """(..., n_dims, N + 2) raw parameters from (..., n_params) scaled ones."""
        shape = (*thetas.shape[:-1], self.n_dims, self.n_weights + 2)
        return thetas.reshape(shape) * self._units()

    # -- generation ----------------------------------------------------------------------------------------

    def _linear_map(self, run_time: float) -> _LinearMap:
        return linear_map(self.settings, self._execution_time, self._dt, run_time)

    def _run_time(self, run_time: float | None) -> float:
        run_time = self._execution_time if run_time is None else positive("run_time", run_time)
        if run_time / self.dt > MAX_STEPS:  # the response tables grow with the steps: refuse, do not swap
            raise InputError(
                f"run_time {run_time:g} s at dt {self.dt:g} s is {run_time / self.dt:.3g} steps; at most "
                f"{MAX_STEPS} (a longer dt or a shorter run)"
            )
        return run_time

    def trajectory(self, theta=None, *, run_time: float | None = None) -> Trajectory:
        """Times (T,) and positions, velocities, accelerations (T, n_dims) for theta (default: the DMP's own
        parameters), from t = 0 to ``run_time`` (default: the execution time)."""
        thetas = self.get_params() if theta is None else self._check_theta(theta)
        batch = self.trajectories(thetas[None], run_time=run_time)
        return Trajectory(batch.times, batch.positions[0], batch.velocities[0], batch.accelerations[0])

    def trajectories(self, thetas, *, run_time: float | None = None, derivatives: int = 2) -> Trajectory:
        """Trajectories of a whole population: thetas (N, n_params) -> arrays (N, T, n_dims), computed as one
        product per derivative (no loop over candidates or time steps); every candidate's trajectory is
        bit-identical to generating it alone. ``derivatives`` < 2 skips the accelerations (and < 1 the
        velocities), which are then None."""
        thetas = finite_array("thetas", thetas)
        if thetas.ndim != 2 or thetas.shape[1] != self.n_params:
            raise InputError(f"thetas must have shape (N, {self.n_params}), got {thetas.shape}")
        if derivatives not in (0, 1, 2):
            raise InputError(f"derivatives must be 0, 1 or 2, got {derivatives!r}")
        linear_map = self._linear_map(self._run_time(run_time))
        raw = self._raw(thetas)  # (N, n_dims, n_weights + 2)
        start_state = np.column_stack([self.start, self.start_velocity, self.start_acceleration])
        outputs: list[np.ndarray | None] = [None, None, None]
        for order in range(derivatives + 1):
            # einsum rather than BLAS: each candidate's numbers then do not depend, in the last bit, on which
            # other candidates share the batch (BLAS blocking does), so results are the same however a
            # population is split across threads or machines.
            values = np.einsum("ndk,tk->ntd", raw, linear_map.by_parameters[order], optimize=False)
            values += (linear_map.by_start[order] @ start_state.T)[None]
            outputs[order] = values
        return Trajectory(linear_map.times, *outputs)

    # -- imitation -----------------------------------------------------------------------------------------

    def imitate(
        self,
        times,
        positions,
        *,
        velocities=None,
        accelerations=None,
        regularization: float = 1e-8,
    ) -> DMP:
        """Fits weights, start, goal, goal velocity and execution time to one or several demonstrations.

        ``times`` (T,) and ``positions`` (T, n_dims) give one demonstration; sequences of them give several
        (each may have its own length and duration). Derivatives default to second-order finite differences.
        Each demonstration is normalised to its own duration, its forcing-term targets are computed against
        its own moving goal, and all are stacked in one ridge regression (Muelling et al. 2013) in which each
        demonstration weighs the same, so several demonstrations yield their mean shape. Start, goal and the
        boundary velocities are the demonstrations' means (in normalised time), and the execution time is
        their mean duration.
        """
        demos = self._demonstrations(times, positions, velocities, accelerations)
        tau = float(np.mean([t[-1] - t[0] for t, *_ in demos]))
        features, targets, boundaries = [], [], []
        for t, y, yd, ydd in demos:
            duration = t[-1] - t[0]
            s = (t - t[0]) / duration
            dy, ddy = yd * duration, ydd * duration**2  # normalised-time derivatives
            boundary = np.stack([y[0], dy[0], ddy[0], y[-1], dy[-1], np.zeros(self.n_dims)])
            goal_position, goal_velocity, goal_acceleration = (
                basis @ boundary for basis in moving_goal_basis(s)
            )
            alpha, beta = self.system.alpha_y, self.system.beta_y
            target = ddy - goal_acceleration - alpha * (beta * (goal_position - y) + (goal_velocity - dy))
            # Every demonstration weighs the same in the regression, however many samples it has.
            weight = 1.0 / np.sqrt(len(t))
            targets.append(weight * target)
            features.append(weight * self.basis.features(s))
            boundaries.append(boundary)
        self.weights = fit_weights(features, targets, regularization)
        mean = np.mean(boundaries, axis=0)
        self.execution_time = tau
        self.start, self.start_velocity, self.start_acceleration = mean[0], mean[1] / tau, mean[2] / tau**2
        self.goal, self.goal_velocity = mean[3], mean[4] / tau
        return self

    def _demonstrations(self, times, positions, velocities, accelerations):
        several = isinstance(positions, list | tuple)
        if not several:
            times, positions = [times], [positions]
            velocities = None if velocities is None else [velocities]
            accelerations = None if accelerations is None else [accelerations]
        if not isinstance(times, list | tuple) or len(times) != len(positions) or not positions:
            raise InputError("give as many time arrays as position arrays (one demonstration or a list)")
        demos = []
        for k, (t, y) in enumerate(zip(times, positions, strict=True)):
            name = f"demonstration {k}" if several else "demonstration"
            t = increasing_times(f"{name}: times", t, minimum_length=3)
            y = finite_array(f"{name}: positions", y)
            if y.ndim == 1 and self.n_dims == 1:
                y = y[:, None]
            if y.shape != (len(t), self.n_dims):
                raise InputError(
                    f"{name}: positions must have shape ({len(t)}, {self.n_dims}), got {y.shape}"
                )
            yd = self._derivative(name, "velocities", velocities, k, t, y)
            ydd = self._derivative(name, "accelerations", accelerations, k, t, yd)
            demos.append((t, y, yd, ydd))
        return demos

    @staticmethod
    def _derivative(name: str, what: str, given: Sequence | None, k: int, t: np.ndarray, y: np.ndarray):
        if given is None:
            return np.gradient(y, t, axis=0, edge_order=2)
        value = finite_array(f"{name}: {what}", given[k])
        if value.shape != y.shape:
            raise InputError(f"{name}: {what} must have shape {y.shape}, got {value.shape}")
        return value
