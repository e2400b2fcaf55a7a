"""The scripted baseline: the best ball-in-a-cup motion written by hand, without learning.

A planner's way of doing it: point-to-point moves of the upright cup between hand-picked positions in the
arm's vertical plane, each from rest to rest and time-optimal under joint limits (Ruckig), then holding
still. :data:`JERK` pumps the pendulum (the cup forwards and a little down, then back), pulls the cup up and
back as hard as the limits allow (the ball is flung up and forwards) and brings it forwards under the
falling ball. The waypoints were picked by hand in about 15 tries at the middle string length (0.375 m,
where this one catches); no search chose them. A plain vertical jerk (down 12 cm, up 32 cm) never lifts the
ball above the rim.

The limits are the UR5e's speed limit (3.1416 rad/s, ``robots/ur5e/README.md``) and, in place of the
planner's assumed 8 rad/s^2 and 80 rad/s^3 (which keep the cup's acceleration below gravity: the string
would never go slack), :data:`ACCELERATION` and :data:`JERK_LIMIT`, about what the demonstration's swing
uses.
"""

from __future__ import annotations

import mujoco
import numpy as np
import ruckig

from besman.core.errors import InputError

ACCELERATION = 30.0  # rad/s^2 on every joint
JERK_LIMIT = 1500.0  # rad/s^3 on every joint
PITCH = (1, 2, 3)  # shoulder lift, elbow, wrist 1: their axes are parallel (the arm's vertical plane)
# The cup's waypoints: (dx, dz) in m from its start position (x forwards, z up), the cup upright throughout.
JERK = ((0.15, -0.05), (-0.15, 0.05), (-0.15, 0.3), (0.05, 0.15))


def upright_pose(task, dx: float, dz: float) -> np.ndarray:
    """The arm's joints with the cup moved by (dx, dz) m from its start position in the arm's vertical plane
    and still upright (Newton's method on shoulder lift and elbow; wrist 1 keeps the cup's pitch)."""
    model, data = task.model, mujoco.MjData(task.model)
    site = model.site("cup").id
    arms = task.arm.qpos_indices

    def cup(q):
        data.qpos[arms] = q
        mujoco.mj_kinematics(model, data)
        return data.site_xpos[site][[0, 2]].copy()

    q = task.start.copy()
    target = cup(q) + [dx, dz]
    pitch = q[list(PITCH)].sum()
    for _ in range(50):
        error = target - cup(q)
        if np.linalg.norm(error) < 1e-9:
            break
        jacobian = np.empty((2, 2))
        for column, joint in enumerate((1, 2)):
            step = q.copy()
            step[joint] += 1e-6
            step[3] = pitch - step[1] - step[2]
            jacobian[:, column] = (cup(step) - cup(q)) / 1e-6
        q[[1, 2]] += np.linalg.solve(jacobian, error)
        q[3] = pitch - q[1] - q[2]
    if np.linalg.norm(target - cup(q)) > 1e-6:
        raise InputError(f"the cup cannot be moved by ({dx}, {dz}) m in the arm's plane")
    return q


def scripted_swing(task, waypoints=JERK) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities (n_steps + 1, 6), every timestep from t = 0, of rest-to-rest moves
    through the cup's ``waypoints`` (see :data:`JERK`) under the limits, then holding still."""
    dofs, dt = task.arm.size, task.timestep
    otg, trajectory = ruckig.Ruckig(dofs), ruckig.Trajectory(dofs)
    times = np.arange(task.n_steps + 1) * dt
    positions = np.repeat(task.start[None], len(times), axis=0)
    velocities = np.zeros_like(positions)
    current, begin = task.start.copy(), 0.0
    for dx, dz in waypoints:
        goal = upright_pose(task, dx, dz)
        inputs = ruckig.InputParameter(dofs)
        inputs.current_position, inputs.target_position = current.tolist(), goal.tolist()
        inputs.current_velocity = inputs.current_acceleration = [0.0] * dofs
        inputs.target_velocity = inputs.target_acceleration = [0.0] * dofs
        inputs.max_velocity = (0.995 * task.speed_limits).tolist()  # sampled, it stays within
        inputs.max_acceleration = [ACCELERATION] * dofs
        inputs.max_jerk = [JERK_LIMIT] * dofs
        otg.calculate(inputs, trajectory)
        duration = trajectory.duration
        for k in np.flatnonzero(times >= begin):
            if times[k] > begin + duration:
                positions[k] = goal
                velocities[k] = 0.0
                continue
            position, velocity, _ = trajectory.at_time(times[k] - begin)
            positions[k], velocities[k] = position, velocity
        current, begin = goal, begin + duration
    if begin > task.config.duration - 0.5:
        raise InputError(
            f"the scripted moves take {begin:.2f} s, too long for a {task.config.duration} s rollout"
        )
    return positions, velocities


def scripted_baseline(task, taus):
    """The scripted swing (the same at every length) evaluated at each of ``taus`` (N, 1): the rollouts'
    :class:`~besman.sim.evaluation.Evaluation`."""
    q, v = scripted_swing(task)
    return task.evaluate_references(np.repeat(q[None], len(taus), 0), np.repeat(v[None], len(taus), 0), taus)
