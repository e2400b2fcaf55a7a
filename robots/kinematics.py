"""Forward and inverse kinematics on MuJoCo models.

Forward kinematics is MuJoCo's own (``mj_kinematics``). Inverse kinematics moves the joints of one group so
that the group's site reaches a position and, optionally, an orientation. It is a damped least-squares
(Levenberg-Marquardt) iteration on MuJoCo's site Jacobians with the error-dependent damping of
Sugihara ("Solvability-unconcerned inverse kinematics by the Levenberg-Marquardt method", IEEE T-RO 2011),
which converges fast near a solution and stays well-behaved near singularities and for unreachable targets.
Joint limits are respected by an active set: a joint at a limit whose step would push it further out is
frozen for that step, and every iterate is clipped into the range. When the first attempt stalls in a local
minimum the solver restarts from seeded random configurations and keeps the best result.

An unreachable target is not an exception: the result says ``success=False`` and carries the remaining error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from besman.robots.robot import Robot

QUATERNION_ORDER = "wxyz"


@dataclass(frozen=True)
class Pose:
    """A position (m) and a unit quaternion in (w, x, y, z) order, both in the world frame."""

    position: np.ndarray
    quaternion: np.ndarray

    @property
    def rotation(self) -> np.ndarray:
        """The 3x3 rotation matrix of ``quaternion``."""
        matrix = np.empty(9)
        mujoco.mju_quat2Mat(matrix, self.quaternion)
        return matrix.reshape(3, 3)


@dataclass(frozen=True)
class IKResult:
    """The outcome of :func:`solve_ik`.

    Attributes:
        qpos: the group's joint values (in the group's joint order), always finite and within the limits.
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


def _site_id(model: mujoco.MjModel, site: str) -> int:
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if site_id < 0:
        names = [model.site(i).name for i in range(model.nsite)]
        raise ValueError(f"no site {site!r} in the model; sites: {', '.join(names)}")
    return site_id


def site_pose(model: mujoco.MjModel, data: mujoco.MjData, site: str) -> Pose:
    """The world pose of ``site`` in ``data`` as last computed (after ``mj_kinematics`` or ``mj_forward``)."""
    site_id = _site_id(model, site)
    quaternion = np.empty(4)
    mujoco.mju_mat2Quat(quaternion, data.site_xmat[site_id])
    return Pose(data.site_xpos[site_id].copy(), quaternion)


def forward_kinematics(robot: Robot, qpos: np.ndarray, site: str) -> Pose:
    """The world pose of ``site`` for a full configuration ``qpos`` (length ``model.nq``)."""
    qpos = np.asarray(qpos, dtype=float)
    if qpos.shape != (robot.model.nq,):
        raise ValueError(f"qpos must have shape ({robot.model.nq},), got {qpos.shape}")
    if not np.all(np.isfinite(qpos)):
        raise ValueError("qpos contains NaN or inf")
    data = mujoco.MjData(robot.model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(robot.model, data)
    return site_pose(robot.model, data, site)


def _as_unit_quaternion(quaternion) -> np.ndarray:
    quaternion = np.asarray(quaternion, dtype=float)
    if quaternion.shape != (4,) or not np.all(np.isfinite(quaternion)):
        raise ValueError(f"target quaternion must be 4 finite numbers (w, x, y, z), got {quaternion!r}")
    norm = np.linalg.norm(quaternion)
    if norm < 1e-9:
        raise ValueError("target quaternion has zero norm")
    return quaternion / norm


def solve_ik(
    robot: Robot,
    group: str | Sequence[str],
    position,
    quaternion=None,
    *,
    site: str | None = None,
    initial_qpos: np.ndarray | None = None,
    position_tolerance: float = 1e-4,
    orientation_tolerance: float = 1e-3,
    max_iterations: int = 200,
    restarts: int = 10,
    seed: int = 0,
    joint_weights=None,
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
    """
    model = robot.model
    groups = [robot.group(name) for name in ((group,) if isinstance(group, str) else group)]
    if not groups:
        raise ValueError("solve_ik needs at least one joint group")
    site_name = site or groups[-1].site
    if site_name is None:
        raise ValueError(f"group {groups[-1].name!r} has no end-effector site; pass site=...")
    site_id = _site_id(model, site_name)
    target_position = np.asarray(position, dtype=float)
    if target_position.shape != (3,) or not np.all(np.isfinite(target_position)):
        raise ValueError(f"target position must be 3 finite numbers, got {position!r}")
    target_quaternion = None if quaternion is None else _as_unit_quaternion(quaternion)

    data = mujoco.MjData(model)
    if initial_qpos is None:
        data.qpos[:] = model.key(robot.keyframe).qpos
    else:
        initial_qpos = np.asarray(initial_qpos, dtype=float)
        if initial_qpos.shape != (model.nq,) or not np.all(np.isfinite(initial_qpos)):
            raise ValueError(f"initial_qpos must be {model.nq} finite numbers")
        data.qpos[:] = initial_qpos

    qpos_idx = np.concatenate([g.qpos_indices for g in groups])
    dof_idx = np.concatenate([g.dof_indices for g in groups])
    lower = np.concatenate([g.lower for g in groups])
    upper = np.concatenate([g.upper for g in groups])
    if joint_weights is None:
        weights = np.ones(len(qpos_idx))
    else:
        weights = np.asarray(joint_weights, dtype=float)
        if weights.shape != (len(qpos_idx),) or not np.all(np.isfinite(weights)) or np.any(weights <= 0):
            raise ValueError(f"joint_weights must be {len(qpos_idx)} positive numbers, got {joint_weights!r}")
    rows = 6 if target_quaternion is not None else 3
    jacobian = np.zeros((6, model.nv))
    site_quaternion, error_quaternion, error = np.empty(4), np.empty(4), np.empty(6)

    def residual(q: np.ndarray) -> np.ndarray:
        data.qpos[qpos_idx] = q
        mujoco.mj_kinematics(model, data)
        error[:3] = target_position - data.site_xpos[site_id]
        if target_quaternion is not None:
            mujoco.mju_mat2Quat(site_quaternion, data.site_xmat[site_id])
            mujoco.mju_negQuat(error_quaternion, site_quaternion)
            mujoco.mju_mulQuat(error_quaternion, target_quaternion, error_quaternion)
            mujoco.mju_quat2Vel(error[3:], error_quaternion, 1.0)
        return error[:rows]

    def attempt(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        e = residual(q)
        for iteration in range(1, max_iterations + 1):
            if _within(e, position_tolerance, orientation_tolerance):
                return q, e.copy(), iteration - 1
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, jacobian[:3], jacobian[3:], site_id)
            J = jacobian[:rows, dof_idx]
            free = np.ones(len(q), dtype=bool)
            for _ in range(len(q)):
                # Solve for dq / weight: joints with small weights (slow, heavy ones) move less.
                step = _lm_step(J[:, free] * weights[free], e) * weights[free]
                dq = np.zeros(len(q))
                dq[free] = step
                pushing_out = ((q <= lower) & (dq < 0)) | ((q >= upper) & (dq > 0))
                if not pushing_out.any():
                    break
                free &= ~pushing_out
                if not free.any():
                    break
            # Trust region on joint steps keeps far-away targets from throwing the arm around.
            largest = np.max(np.abs(dq))
            if largest > 0.3:
                dq *= 0.3 / largest
            q_next = np.clip(q + dq, lower, upper)
            if np.max(np.abs(q_next - q)) < 1e-9:
                break  # stalled in a local minimum or against the limits: let a restart try
            q = q_next
            e = residual(q)
        return q, e.copy(), iteration

    rng = np.random.default_rng(seed)
    start = np.clip(data.qpos[qpos_idx].copy(), lower, upper)
    best_q, best_e, used = attempt(start)
    total = used
    for _ in range(restarts):
        if _within(best_e, position_tolerance, orientation_tolerance):
            break
        q, e, used = attempt(rng.uniform(lower, upper))
        total += used
        if _cost(e) < _cost(best_e):
            best_q, best_e = q, e

    position_error = float(np.linalg.norm(best_e[:3]))
    orientation_error = float(np.linalg.norm(best_e[3:])) if rows == 6 else 0.0
    success = _within(best_e, position_tolerance, orientation_tolerance)
    if success:
        message = "reached"
    else:
        message = (
            f"unreachable: site {site_name!r} remains {position_error:.4g} m and "
            f"{np.degrees(orientation_error):.3g} deg from the target"
        )
    return IKResult(best_q.copy(), success, position_error, orientation_error, total, message)


def _lm_step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """A Levenberg-Marquardt step with Sugihara's damping E + w_N (E = e^T e / 2, w_N = 1e-3)."""
    damping = 0.5 * float(e @ e) + 1e-3
    hessian = J.T @ J
    hessian[np.diag_indices_from(hessian)] += damping
    return np.linalg.solve(hessian, J.T @ e)


def _within(e: np.ndarray, position_tolerance: float, orientation_tolerance: float) -> bool:
    if np.linalg.norm(e[:3]) > position_tolerance:
        return False
    return len(e) == 3 or np.linalg.norm(e[3:]) <= orientation_tolerance


def _cost(e: np.ndarray) -> float:
    return float(e @ e)
