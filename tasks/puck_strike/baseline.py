"""The scripted baseline: the best puck strike written by hand, without learning.

A planner's way of doing it, for a target tau:

1. Aim along the line from the puck to the target (angle phi): the contact pose has the blade upright and
   square to that line (the tool's closing axis along it, so the blade's long axis lies across it), its
   axis at the puck's mid-height, :data:`CLEARANCE` behind the puck (inverse kinematics).
2. Speed from the textbook model: a puck sliding on the table stops after v^2 / (2 mu g), so it must leave
   at v = sqrt(2 mu g d) for the distance d from the puck to the target (mu: the puck's sliding friction,
   known to the planner); a massive blade and a plastic impact give the puck the blade's speed
   (``exit_ratio`` 1), so the blade moves at v along the line at contact. The joint velocity there is the
   least one (pseudo-inverse) that moves the blade's centre so and keeps its axis across the line (it may
   turn about its own axis, about which it is round); one that breaks a joint's speed limit is scaled down
   to the limit.
3. Motion: time-optimal joint moves under the arm's own limits (Ruckig; the UR5e's 3.1416 rad/s, 8 rad/s^2
   and 80 rad/s^3 - about what the demonstration's swing uses): from the start pose to a pre-strike pose
   (the contact pose less the contact velocity times :data:`RUN_UP_TIME`, raised by :data:`LIFT` of
   shoulder lift) at rest; from there to the contact pose at the contact velocity; from there to rest at a
   follow-through pose (the contact pose plus the velocity times :data:`FOLLOW_THROUGH_TIME`, raised).

No number of it was fitted on rollouts. :func:`calibrated_exit_ratio` measures the one number the textbook
model gets wrong (the puck leaves faster than the blade: the contact is compliant) from one strike, for the
benchmark's second, calibrated planner - which is no longer a planner without learning.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import ruckig

from besman.core.errors import InputError
from besman.robots import solve_ik
from besman.sim.primitives import top_down
from besman.tasks.puck_strike.rollouts import GRAVITY
from besman.tasks.puck_strike.world import (
    HEAD_RADIUS,
    PUCK_FRICTION,
    PUCK_HEIGHT,
    PUCK_RADIUS,
    PUCK_START,
    TABLE,
)

RUN_UP_TIME = 0.25  # s: the pre-strike pose is the contact pose less the contact velocity times this
FOLLOW_THROUGH_TIME = 0.15  # s: the follow-through pose is the contact pose plus the velocity times this
LIFT = 0.1  # rad of shoulder lift that raises the pre-strike and follow-through poses
CLEARANCE = 0.005  # m between the blade and the puck in the contact pose


def _aim(target) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The contact point (x, y), the line's direction, its angle phi and the puck's distance to ``target``."""
    target = np.asarray(target, dtype=float)
    puck = np.asarray(PUCK_START, dtype=float)
    line = target - puck
    distance = float(np.linalg.norm(line))
    direction = line / distance
    contact = puck - (PUCK_RADIUS + HEAD_RADIUS + CLEARANCE) * direction
    return contact, direction, math.atan2(direction[1], direction[0]), distance


def contact_speed(target) -> float:
    """The planner's blade speed at contact for ``target``: sqrt(2 mu g d)."""
    return math.sqrt(2 * PUCK_FRICTION[0] * GRAVITY * _aim(target)[3])


def _ruckig(dofs, current, current_velocity, goal, goal_velocity, velocity, acceleration, jerk):
    otg, trajectory = ruckig.Ruckig(dofs), ruckig.Trajectory(dofs)
    inputs = ruckig.InputParameter(dofs)
    inputs.current_position, inputs.target_position = list(current), list(goal)
    inputs.current_velocity, inputs.target_velocity = list(current_velocity), list(goal_velocity)
    inputs.current_acceleration = inputs.target_acceleration = [0.0] * dofs
    inputs.max_velocity, inputs.max_acceleration = list(velocity), list(acceleration)
    inputs.max_jerk = list(jerk)
    result = otg.calculate(inputs, trajectory)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise InputError(f"the scripted strike cannot be planned ({result})")
    return trajectory


def _blade_jacobian(task, data, direction) -> tuple[np.ndarray, np.ndarray]:
    """The blade's task Jacobian (5, 6) at ``data``'s pose - its centre's velocity and the rotations that
    would tilt its axis off across the line - and the matching error to the blade across ``direction``."""
    model, arm = task.model, task.arm
    site = model.site("head").id
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_jacSite(model, data, jacp, jacr, site)
    across = np.array([[*direction, 0.0], [0.0, 0.0, 1.0]])
    jacobian = np.vstack([jacp[:, arm.dof_indices], across @ jacr[:, arm.dof_indices]])
    axis = np.array([-direction[1], direction[0], 0.0])
    blade = data.site_xmat[site].reshape(3, 3)[:, 0]
    return jacobian, across @ np.cross(blade, axis)


def strike_plan(task, target, exit_ratio: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The planner's poses (pre-strike, contact, follow-through: (3, 6) joint values) and the joint velocity
    (6,) at contact for ``target`` (x, y); ``exit_ratio``: the puck's speed after the impact per the blade's
    (1: the textbook's plastic impact)."""
    contact, direction, phi, _ = _aim(target)
    speed = contact_speed(target) / exit_ratio
    model, arm = task.model, task.arm
    data = mujoco.MjData(model)
    data.qpos[:] = model.key(task.robot.keyframe).qpos
    data.qpos[arm.qpos_indices] = task.start
    point = [*contact, TABLE.height + PUCK_HEIGHT / 2]
    result = solve_ik(
        task.robot, "arm", point, top_down(phi), site="head", initial_qpos=data.qpos.copy(), restarts=0
    )
    if result.position_error > 1e-3:
        raise InputError(f"the contact pose for target {list(target)} is out of the arm's reach")
    pose = np.asarray(result.qpos, dtype=float)
    data.qpos[arm.qpos_indices] = pose
    jacobian, _ = _blade_jacobian(task, data, direction)
    # The least joint velocity that moves the blade at the speed along the line, its axis kept across it
    # (it may turn about its own axis: the blade is round about it).
    velocity = np.linalg.pinv(jacobian) @ np.r_[speed * direction, 0.0, 0.0, 0.0]
    worst = float(np.max(np.abs(velocity) / (0.98 * task.speed_limits)))
    if worst > 1.0:
        velocity /= worst
    pre = pose - RUN_UP_TIME * velocity
    pre[1] -= LIFT  # the run-up starts a little higher (shoulder lift), clear of the table
    end = pose + FOLLOW_THROUGH_TIME * velocity
    end[1] -= LIFT
    return np.array([pre, pose, end]), velocity


def scripted_strike(task, target, exit_ratio: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities (n_steps + 1, 6), every timestep from t = 0, of the planner's strike at
    ``target`` (see the module documentation; ``exit_ratio`` as :func:`strike_plan`'s), then holding
    still."""
    poses, contact_velocity = strike_plan(task, target, exit_ratio)
    arm, dt = task.arm, task.timestep
    limits = (0.995 * task.speed_limits, np.asarray(arm.acceleration, float), np.asarray(arm.jerk, float))
    times = np.arange(task.n_steps + 1) * dt
    positions = np.repeat(task.start[None], len(times), axis=0)
    velocities = np.zeros_like(positions)
    rest = np.zeros(arm.size)
    current, current_velocity, begin = task.start.copy(), rest, 0.0
    for goal, goal_velocity in ((poses[0], rest), (poses[1], contact_velocity), (poses[2], rest)):
        leg = _ruckig(arm.size, current, current_velocity, goal, goal_velocity, *limits)
        for k in np.flatnonzero(times >= begin):
            if times[k] > begin + leg.duration:
                positions[k], velocities[k] = goal, 0.0
                continue
            positions[k], velocities[k], _ = leg.at_time(times[k] - begin)
        current, current_velocity, begin = goal, goal_velocity, begin + leg.duration
    if begin > task.config.duration - 1.0:
        raise InputError(
            f"the scripted strike takes {begin:.2f} s, too long for a {task.config.duration} s rollout"
        )
    return positions, velocities


def calibrated_exit_ratio(task, target) -> float:
    """The puck's exit speed per the blade's, measured from one textbook strike at ``target`` (one rollout):
    sqrt(the distance the puck slid / the distance the plan meant), the sliding model's inverse. A planner
    that measures this once is a planner with one learned number."""
    positions, velocities = scripted_strike(task, target)
    detail = task.evaluate_references(positions[None], velocities[None], np.asarray(target)[None]).details[0]
    if detail.rest is None:
        raise InputError(f"the calibration strike failed: {detail.failure}")
    slid = float(np.linalg.norm(np.asarray(detail.rest) - np.asarray(PUCK_START)))
    return math.sqrt(slid / _aim(target)[3])


def scripted_baseline(task, taus, exit_ratio: float = 1.0):
    """The scripted strikes for targets ``taus`` (N, 2), each planned for its own target, evaluated: the
    rollouts' :class:`~besman.sim.evaluation.Evaluation` (``exit_ratio`` as :func:`strike_plan`'s)."""
    motions = [scripted_strike(task, tau, exit_ratio) for tau in taus]
    positions, velocities = np.array([q for q, _ in motions]), np.array([v for _, v in motions])
    return task.evaluate_references(positions, velocities, taus)


def calibrated_baseline(task, taus):
    """:func:`scripted_baseline` with the exit ratio measured from one strike at the box's middle
    (:func:`calibrated_exit_ratio`): a planner with one learned number."""
    middle = (np.asarray(task.bounds.low) + np.asarray(task.bounds.high)) / 2
    return scripted_baseline(task, taus, calibrated_exit_ratio(task, middle))
