"""Inverse kinematics: joint values of one or more groups that bring a site to a position and orientation.

A damped least-squares (Levenberg-Marquardt) iteration on MuJoCo's site Jacobians with the error-dependent
damping of Sugihara ("Solvability-unconcerned inverse kinematics by the Levenberg-Marquardt method", IEEE
T-RO 2011), which converges fast near a solution and stays well-behaved near singularities and for
unreachable targets. One iteration, in steps:

1. :func:`_residual` - the site's position error and rotation-vector error (MuJoCo's quaternion helpers).
2. :func:`_joint_step` - the weighted LM step with an active set: a joint at a limit whose step would push
   it further out is frozen and the step solved again without it.
3. :func:`_trust_region` - no joint moves more than 0.3 rad (or m) per iteration, so that far targets do
   not throw the arm around; every iterate is clipped into the range.

When the first attempt stalls in a local minimum (it stops moving, or its error stops shrinking: an
unreachable target would otherwise creep for all ``max_iterations``), :func:`solve_ik` restarts from seeded
random configurations and keeps the best result. An unreachable target is not an exception: the result says
``success=False`` and carries the remaining error.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg.lapack import dposv as _cholesky_solve

from besman.core.errors import InputError
from besman.core.validation import COUNT, SEED, checked, instance, integer, numeric, optional, text
from besman.robots.kinematics import site_id
from besman.robots.robot import Robot
from besman.skills import quaternion

MAX_JOINT_STEP = 0.3  # rad or m per iteration (trust region)
STALL = 1e-9  # an iterate that moves no joint by more than this has stalled
PROGRESS, PATIENCE = 0.01, 10  # an attempt whose error shrinks by < 1 % in 10 iterations has stalled


@dataclass(frozen=True)
class IKResult:
    """The outcome of :func:`solve_ik`.

    Attributes:
        qpos: the groups' joint values (in the groups' joint order), always finite and within the limits.
        success: whether both errors are within the requested tolerances.
        position_error: remaining distance between the site and the target (m).
        orientation_error: remaining rotation angle between the site and the target (rad); 0 when no
            orientation was asked for.
        iterations: iterations used over all attempts.
        message: a human-readable summary (why it failed, when it did).
    """

    qpos: np.ndarray
    success: bool
    position_error: float
    orientation_error: float
    iterations: int
    message: str


@dataclass(frozen=True)
class Tolerances:
    """Success thresholds: position (m) and orientation (rad)."""

    position: float = 1e-4
    orientation: float = 1e-3

    def met(self, error: np.ndarray) -> bool:
        position, orientation = error[:3], error[3:]
        if position @ position > self.position**2:
            return False
        return len(error) == 3 or orientation @ orientation <= self.orientation**2


@dataclass(frozen=True)
class _Problem:
    """What an attempt needs: the moving joints, their limits and weights, the site and the target."""

    model: mujoco.MjModel
    data: mujoco.MjData  # scratch: holds the full configuration, the moving joints are overwritten
    site: int
    qpos_indices: np.ndarray
    dof_indices: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    weights: np.ndarray
    position: np.ndarray
    orientation: np.ndarray | None

    @property
    def rows(self) -> int:
        return 3 if self.orientation is None else 6


def _residual(problem: _Problem, q: np.ndarray) -> np.ndarray:
    """Target minus site: position (m) and, with an orientation, the rotation vector of target * site^-1."""
    model, data = problem.model, problem.data
    data.qpos[problem.qpos_indices] = q
    mujoco.mj_kinematics(model, data)
    error = np.empty(problem.rows)
    error[:3] = problem.position - data.site_xpos[problem.site]
    if problem.orientation is not None:
        site_quaternion, difference = np.empty(4), np.empty(4)
        mujoco.mju_mat2Quat(site_quaternion, data.site_xmat[problem.site])
        mujoco.mju_negQuat(difference, site_quaternion)
        mujoco.mju_mulQuat(difference, problem.orientation, difference)
        mujoco.mju_quat2Vel(error[3:], difference, 1.0)
    return error


def _jacobian(problem: _Problem) -> np.ndarray:
    """The site Jacobian over the moving joints (rows as the residual) at the last residual's
    configuration."""
    model, data = problem.model, problem.data
    jacobian = np.zeros((6, model.nv))
    mujoco.mj_comPos(model, data)
    mujoco.mj_jacSite(model, data, jacobian[:3], jacobian[3:], problem.site)
    return jacobian[: problem.rows, problem.dof_indices]


def _lm_step(jacobian: np.ndarray, error: np.ndarray) -> np.ndarray:
    """A Levenberg-Marquardt step with Sugihara's damping E + w_N (E = e^T e / 2, w_N = 1e-3): the damped
    normal equations are symmetric positive definite, so LAPACK's Cholesky solver (dposv) solves them."""
    damping = 0.5 * float(error @ error) + 1e-3
    hessian = jacobian.T @ jacobian
    hessian.flat[:: len(hessian) + 1] += damping  # the diagonal
    _, step, info = _cholesky_solve(hessian, jacobian.T @ error, overwrite_a=True, overwrite_b=True)
    if info != 0:
        raise ArithmeticError(f"the damped normal equations are not positive definite (LAPACK info {info})")
    return step


def _joint_step(problem: _Problem, q: np.ndarray, jacobian: np.ndarray, error: np.ndarray) -> np.ndarray:
    """The weighted LM step with joints that would leave their range frozen (an active set)."""
    weights, lower, upper = problem.weights, problem.lower, problem.upper
    # Solve for dq / weight: joints with small weights (slow, heavy ones) move less.
    step = _lm_step(jacobian * weights, error) * weights
    pushing_out = ((q <= lower) & (step < 0)) | ((q >= upper) & (step > 0))
    free = ~pushing_out
    while pushing_out.any() and free.any():
        step = np.zeros(len(q))
        step[free] = _lm_step(jacobian[:, free] * weights[free], error) * weights[free]
        pushing_out = ((q <= lower) & (step < 0)) | ((q >= upper) & (step > 0))
        free &= ~pushing_out
    return step


def _trust_region(step: np.ndarray) -> np.ndarray:
    largest = np.max(np.abs(step))
    return step * (MAX_JOINT_STEP / largest) if largest > MAX_JOINT_STEP else step


def _attempt(
    problem: _Problem, q: np.ndarray, tolerances: Tolerances, max_iterations: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """Iterates from ``q``; returns the last configuration, its error and the iterations used. An attempt
    that stops moving, or whose error has not shrunk by :data:`PROGRESS` in :data:`PATIENCE` iterations,
    has stalled in a local minimum or against the limits (it would only creep there): a restart tries."""
    error = _residual(problem, q)
    best, since_best = math.inf, 0
    for iteration in range(1, max_iterations + 1):
        if tolerances.met(error):
            return q, error, iteration - 1
        squared = float(error @ error)
        if squared < best * (1.0 - PROGRESS) ** 2:
            best, since_best = squared, 0
        else:
            since_best += 1
            if since_best >= PATIENCE:
                break
        step = _trust_region(_joint_step(problem, q, _jacobian(problem), error))
        q_next = np.minimum(np.maximum(q + step, problem.lower), problem.upper)  # np.clip, cheaper
        if np.max(np.abs(q_next - q)) < STALL:
            break
        q = q_next
        error = _residual(problem, q)
    return q, error, iteration


def _target(position, orientation) -> tuple[np.ndarray, np.ndarray | None]:
    position = numeric("robots.solve_ik: position", position)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise InputError(f"target position must be 3 finite numbers, got {position!r}")
    if orientation is None:
        return position, None
    orientation = numeric("robots.solve_ik: quaternion", orientation)
    if orientation.shape != (4,) or not np.all(np.isfinite(orientation)):
        raise InputError(f"target quaternion must be 4 finite numbers (w, x, y, z), got {orientation!r}")
    return position, quaternion.normalized("target quaternion", orientation)


def _weights(joint_weights, size: int) -> np.ndarray:
    if joint_weights is None:
        return np.ones(size)
    weights = np.asarray(joint_weights, dtype=float)
    if weights.shape != (size,) or not np.all(np.isfinite(weights)) or np.any(weights <= 0):
        raise InputError(f"joint_weights must be {size} positive numbers, got {joint_weights!r}")
    return weights


# rad or m inside each joint's range that solutions keep: motions that imitate them (a straight move's
# fit through its solutions) then pass no limit where a solution touches one.
RANGE_INSET = 3e-3


# Per robot (for as long as it lives: a robot holds its compiled model, megabytes), per groups: _joints.
_JOINTS: weakref.WeakKeyDictionary[Robot, dict] = weakref.WeakKeyDictionary()


def _joints(robot: Robot, groups: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """qpos and dof indices and the limits of the groups' joints, in their order (computed once per robot
    and groups: planning solves many IK problems for one arm)."""
    known = _JOINTS.setdefault(robot, {})
    if groups not in known:
        known[groups] = _joint_arrays(robot, groups)
    return known[groups]


def _joint_arrays(robot: Robot, groups: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    members = [robot.group(name) for name in groups]
    qpos, dofs, lower, upper = (
        np.concatenate([getattr(g, field) for g in members])
        for field in ("qpos_indices", "dof_indices", "lower", "upper")
    )
    inset = np.minimum(RANGE_INSET, (upper - lower) / 4)
    arrays = (qpos, dofs, lower + inset, upper - inset)
    for array in arrays:
        array.flags.writeable = False  # shared by every solve
    return arrays


@checked(
    robot=instance(Robot, "a Robot (robots.load)"),
    group=instance(str | list | tuple, "a joint group's name or a list of them"),
    site=optional(text("a site name")),
    max_iterations=COUNT,
    restarts=integer(0),
    seed=SEED,
    data=optional(instance(mujoco.MjData, "an MjData of the robot's model")),
)
def solve_ik(
    robot: Robot,
    group: str | Sequence[str],
    position: ArrayLike,
    quaternion: ArrayLike | None = None,
    *,
    site: str | None = None,
    initial_qpos: np.ndarray | None = None,
    position_tolerance: float = 1e-4,
    orientation_tolerance: float = 1e-3,
    max_iterations: int = 200,
    restarts: int = 10,
    seed: int = 0,
    joint_weights: ArrayLike | None = None,
    data: mujoco.MjData | None = None,
) -> IKResult:
    """Joint values of ``group`` that bring ``site`` to ``position`` (and ``quaternion``, w-x-y-z, if given).

    Args:
        robot: the robot.
        group: the joint group to move (e.g. ``"right_arm"``), or several (``("torso", "right_arm")``) whose
            joints move together; all other joints keep ``initial_qpos``. ``qpos`` of the result follows
            the groups' joint order.
        position: target position in the world frame (m).
        quaternion: target orientation (w, x, y, z) in the world frame, or None for position only.
        site: the site to move; defaults to the (last) group's end-effector site.
        initial_qpos: full configuration to start from (default: the robot's keyframe).
        position_tolerance: success threshold on the position error (m).
        orientation_tolerance: success threshold on the orientation error (rad).
        max_iterations: iterations per attempt.
        restarts: attempts from random configurations after the first one fails.
        seed: seed of the restart configurations (same seed, same result).
        joint_weights: per joint (in the groups' order), how freely it moves relative to the others in the
            least-squares step (default: all equal); e.g. acceleration limits, so that a heavy torso joint
            takes a small share of a redundant motion.
        data: scratch ``MjData`` of ``robot.model`` to compute in (its state is overwritten); default: a
            new one.
    """
    model = robot.model
    groups = [robot.group(name) for name in ((group,) if isinstance(group, str) else group)]
    if not groups:
        raise InputError("solve_ik needs at least one joint group")
    site_name = site or groups[-1].site
    if site_name is None:
        raise InputError(f"group {groups[-1].name!r} has no end-effector site; pass site=...")
    target_position, target_orientation = _target(position, quaternion)
    data = mujoco.MjData(model) if data is None else data
    if initial_qpos is None:
        data.qpos[:] = model.key(robot.keyframe).qpos
    else:
        initial_qpos = np.asarray(initial_qpos, dtype=float)
        if initial_qpos.shape != (model.nq,) or not np.all(np.isfinite(initial_qpos)):
            raise InputError(f"initial_qpos must be {model.nq} finite numbers")
        data.qpos[:] = initial_qpos
    qpos_indices, dof_indices, lower, upper = _joints(robot, tuple(g.name for g in groups))
    problem = _Problem(
        model,
        data,
        site_id(model, site_name),
        qpos_indices,
        dof_indices,
        lower,
        upper,
        _weights(joint_weights, len(qpos_indices)),
        target_position,
        target_orientation,
    )
    for name, value in (
        ("position_tolerance", position_tolerance),
        ("orientation_tolerance", orientation_tolerance),
    ):
        if not (isinstance(value, int | float) and 0 < value < math.inf):
            raise InputError(f"{name} must be a positive number, got {value!r}")
    tolerances = Tolerances(position_tolerance, orientation_tolerance)

    start = np.clip(data.qpos[problem.qpos_indices].copy(), problem.lower, problem.upper)
    best_q, best_error, total = _attempt(problem, start, tolerances, max_iterations)
    rng = None
    for _ in range(restarts):
        if tolerances.met(best_error):
            break
        rng = rng or np.random.default_rng(seed)  # made only when needed: most solves need no restart
        q, error, used = _attempt(
            problem, rng.uniform(problem.lower, problem.upper), tolerances, max_iterations
        )
        total += used
        if error @ error < best_error @ best_error:
            best_q, best_error = q, error
    return _result(best_q, best_error, total, tolerances, site_name)


def _result(q: np.ndarray, error: np.ndarray, iterations: int, tolerances: Tolerances, site: str) -> IKResult:
    position_error = float(np.linalg.norm(error[:3]))
    orientation_error = float(np.linalg.norm(error[3:])) if len(error) == 6 else 0.0
    success = tolerances.met(error)
    message = (
        "reached"
        if success
        else f"unreachable: site {site!r} remains {position_error:.4g} m and "
        f"{np.degrees(orientation_error):.3g} deg from the target"
    )
    return IKResult(q.copy(), success, position_error, orientation_error, iterations, message)
