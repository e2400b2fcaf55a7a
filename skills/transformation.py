"""The DMP transformation system with a moving goal, solved exactly as a linear system.

The goal-velocity DMP of Muelling, Kober, Kroemer and Peters ("Learning to select and generalize striking
movements in robot table tennis", IJRR 2013) drives each dimension y towards a moving goal g_p(t)::

    tau^2 ydd = alpha_y (beta_y (g_p - y) + tau (gd_p - yd)) + f(z) + tau^2 gdd_p

where g_p is the quintic from the start state (y0, yd0, ydd0) at t = 0 to (g, gd, 0) at t = tau, and
g_p = g, gd_p = gdd_p = 0 afterwards. Writing y = g_p + e turns this into a homogeneous linear system for
the deviation e that only the forcing term drives (in normalised time s = t / tau, ' = d/ds)::

    e'' = -alpha_y beta_y e - alpha_y e' + f(s),    e(0) = e'(0) = 0

(because g_p starts in the start state). So a DMP trajectory is the quintic plus the response of one fixed
second-order system to the forcing term, and it is linear in the weights, the goal and the goal velocity.
That response does not depend on tau, the goal or the start: it is computed once per basis and reused.

After tau, g_p stops with zero velocity while y keeps its velocity, so e' jumps by tau * gd at s = 1; the
free response of the system to that jump is added in closed form.

The forced response is computed on a fine grid (step 1/16384 of the movement) by the exact discretisation of
the system with a first-order hold on the forcing term (error ~1e-7 of the movement's amplitude), and read
at the requested times by cubic Hermite interpolation with exact derivatives.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from besman.core.errors import InputError
from besman.skills.forcing import ForcingBasis

FINE_STEPS_PER_MOVEMENT = 16384


def _quintic_coefficients() -> np.ndarray:
    """C (6, 6) such that the quintic with boundary values b = (p0, v0, a0, p1, v1, a1) on s in [0, 1] is
    sum_k (C @ b)[k] s^k."""
    conditions = np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [0, 1, 0, 0, 0, 0],
            [0, 0, 2, 0, 0, 0],
            [1, 1, 1, 1, 1, 1],
            [0, 1, 2, 3, 4, 5],
            [0, 0, 2, 6, 12, 20],
        ],
        dtype=float,
    )
    return np.linalg.inv(conditions)


_QUINTIC = _quintic_coefficients()


def minimum_jerk(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk profile 10 s^3 - 15 s^4 + 6 s^5: from 0 at rest (s = 0) to 1 at rest (s = 1)."""
    s = np.asarray(s, dtype=float)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


def moving_goal_basis(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, first and second s-derivative bases (len(s), 6) of the quintic moving goal.

    ``basis @ b`` with b = (y0, tau yd0, tau^2 ydd0, g, tau gd, 0) gives g_p, g_p' and g_p'' for s <= 1;
    for s > 1 the goal holds still at g (rows equal the basis of "g" alone).
    """
    s = np.asarray(s, dtype=float)
    inside = np.minimum(s, 1.0)[:, None]
    k = np.arange(6)
    powers = inside**k
    d_powers = np.where(k >= 1, k * inside ** np.maximum(k - 1, 0), 0.0)
    dd_powers = np.where(k >= 2, k * (k - 1) * inside ** np.maximum(k - 2, 0), 0.0)
    position, velocity, acceleration = powers @ _QUINTIC, d_powers @ _QUINTIC, dd_powers @ _QUINTIC
    after = s > 1.0
    if after.any():
        position[after] = np.eye(6)[3]
        velocity[after] = 0.0
        acceleration[after] = 0.0
    return position, velocity, acceleration


@dataclass(frozen=True)
class TransformationSystem:
    """e'' = -alpha_y beta_y e - alpha_y e' + f(s): the deviation dynamics of every DMP dimension."""

    alpha_y: float = 25.0
    beta_y: float = 6.25
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        for name in ("alpha_y", "beta_y"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a finite positive number, got {value!r}")

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[0.0, 1.0], [-self.alpha_y * self.beta_y, -self.alpha_y]])

    def forced_response(
        self, basis: ForcingBasis, s: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """e, e', e'' (len(s), N): the response to each basis function with unit weight, at times s >= 0."""
        s = np.asarray(s, dtype=float)
        grid_end = max(1.0, math.ceil(float(s.max()) * 4.0) / 4.0)
        nodes, values, slopes, accelerations = self._fine_response(basis, grid_end)
        h = nodes[1] - nodes[0]
        index = np.minimum((s / h).astype(int), len(nodes) - 2)
        u = (s - nodes[index])[:, None] / h
        # Cubic Hermite interpolation of e (with e') and of e' (with e'').
        h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
        e = (
            h00 * values[index]
            + h10 * h * slopes[index]
            + h01 * values[index + 1]
            + h11 * h * slopes[index + 1]
        )
        de = (
            h00 * slopes[index]
            + h10 * h * accelerations[index]
            + h01 * slopes[index + 1]
            + h11 * h * accelerations[index + 1]
        )
        dde = basis.features(s) - self.alpha_y * self.beta_y * e - self.alpha_y * de
        return e, de, dde

    @staticmethod
    @functools.cache
    def shared(alpha_y: float, beta_y: float) -> TransformationSystem:
        """The one system of these gains, shared by every DMP, so its responses are computed once per
        process rather than once per DMP (planning makes many DMPs of the same gains)."""
        return TransformationSystem(alpha_y, beta_y)

    def peak_displacements(self, basis: ForcingBasis) -> np.ndarray:
        """max |e(s)| over the movement (s in [0, 1]) for a unit weight on each basis function."""
        key = ("peaks", basis)
        if key not in self._cache:
            _, values, _, _ = self._fine_response(basis, 1.0)
            self._cache[key] = np.abs(values).max(axis=0)
        return self._cache[key]

    def free_response(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e(sigma), e'(sigma) of the unforced system started at e = 0, e' = 1 (closed form, Putzer)."""
        sigma = np.asarray(sigma, dtype=complex)
        trace, determinant = -self.alpha_y, self.alpha_y * self.beta_y
        root = np.sqrt(complex(trace * trace / 4.0 - determinant))
        l1, l2 = trace / 2.0 + root, trace / 2.0 - root
        if abs(root) < 1e-9 * self.alpha_y:  # critically damped (beta = alpha / 4): a double root
            e = sigma * np.exp(l1 * sigma)
            de = np.exp(l1 * sigma) * (1.0 + l1 * sigma)
        else:
            e = (np.exp(l1 * sigma) - np.exp(l2 * sigma)) / (l1 - l2)
            de = (l1 * np.exp(l1 * sigma) - l2 * np.exp(l2 * sigma)) / (l1 - l2)
        return e.real, de.real

    def _fine_response(self, basis: ForcingBasis, grid_end: float) -> tuple[np.ndarray, ...]:
        """Nodes and e, e', e'' on the fine grid over [0, grid_end], computed once per basis and length."""
        key = (basis, grid_end)
        if key not in self._cache:
            steps = round(grid_end * FINE_STEPS_PER_MOVEMENT)
            nodes = np.linspace(0.0, grid_end, steps + 1)
            inputs = basis.features(nodes)
            values, slopes = self._simulate(inputs, grid_end / steps)
            accelerations = inputs - self.alpha_y * self.beta_y * values - self.alpha_y * slopes
            self._cache[key] = (nodes, values, slopes, accelerations)
        return self._cache[key]

    def _simulate(self, inputs: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact first-order-hold discretisation of x' = A x + (0, 1) u from x(0) = 0, for each input column.

        x_{k+1} = Phi x_k + v_k with v_k = P u_k + R u_{k+1}; the recurrence runs as an IIR filter (scipy's
        lfilter, in C) over all columns at once.
        """
        # Imported at the first trajectory, not with the module: scipy.signal brings scipy.stats (0.5 s),
        # which reading a primitive or a pool need not wait for.
        from scipy.linalg import expm
        from scipy.signal import lfilter

        augmented = np.zeros((4, 4))
        augmented[:2, :2] = self.matrix * h
        augmented[1, 2] = h
        augmented[2, 3] = 1.0
        exponential = expm(augmented)
        phi, gamma1, gamma2 = exponential[:2, :2], exponential[:2, 2], exponential[:2, 3]
        hold_now, hold_next = gamma1 - gamma2, gamma2
        v = hold_now[:, None, None] * inputs[None, :-1] + hold_next[:, None, None] * inputs[None, 1:]
        v = np.concatenate([v, np.zeros((2, 1, inputs.shape[1]))], axis=1)  # x_0 = 0 needs no input
        denominator = [1.0, -np.trace(phi), np.linalg.det(phi)]
        # (zI - Phi)^-1 = adj(zI - Phi) / det(zI - Phi), written in powers of 1/z (strictly causal).
        values = lfilter([0.0, 1.0, -phi[1, 1]], denominator, v[0], axis=0) + lfilter(
            [0.0, 0.0, phi[0, 1]], denominator, v[1], axis=0
        )
        slopes = lfilter([0.0, 0.0, phi[1, 0]], denominator, v[0], axis=0) + lfilter(
            [0.0, 1.0, -phi[0, 0]], denominator, v[1], axis=0
        )
        return values, slopes
