"""How a compiled model treats one joint under its position servos: the stiffness and damping its actuators
add, the force they may give, the joint's inertia, its steady lag behind a command moving at a speed, and
how one step of MuJoCo's integrator amplifies its motion. Computed from the model alone, nothing simulated:
``besman robots check`` (:mod:`besman.tasks.robot_check`) tells a joint's trouble by these numbers.
"""

from __future__ import annotations

import mujoco
import numpy as np


def _joint_actuators(model: mujoco.MjModel, joint: int):
    """The actuators that drive ``joint`` directly (not through a tendon)."""
    return (
        a
        for a in range(model.nu)
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and model.actuator_trnid[a, 0] == joint
    )


def servo_gains(model: mujoco.MjModel, joint: int) -> tuple[float, float]:
    """The stiffness and damping (per rad or m) that the actuators acting on ``joint`` alone add to it: an
    affine bias, ``biasprm[1]`` x position + ``biasprm[2]`` x velocity, through the gear twice."""
    stiffness = damping = 0.0
    for actuator in _joint_actuators(model, joint):
        if model.actuator_biastype[actuator] == mujoco.mjtBias.mjBIAS_AFFINE:
            gear = model.actuator_gear[actuator, 0]
            stiffness -= model.actuator_biasprm[actuator, 1] * gear * gear
            damping -= model.actuator_biasprm[actuator, 2] * gear * gear
    return stiffness, damping


def force_limit(model: mujoco.MjModel, joint: int) -> float:
    """The most force the actuators on ``joint`` may give (their force range through the gear; inf: none)."""
    return min(
        (
            float(np.abs(model.actuator_forcerange[a]).max() * abs(model.actuator_gear[a, 0]))
            for a in _joint_actuators(model, joint)
            if model.actuator_forcelimited[a]
        ),
        default=np.inf,
    )


def joint_inertia(model: mujoco.MjModel, data: mujoco.MjData, joint: int) -> float:
    """``joint``'s own entry of the mass matrix in ``data``'s configuration (its armature included)."""
    dof = model.jnt_dofadr[joint]
    unit, column = np.zeros(model.nv), np.zeros(model.nv)
    unit[dof] = 1.0
    mujoco.mj_mulM(model, data, column, unit)
    return float(column[dof])


def steady_lag(kp: float, kv: float, damping: float, friction: float, speed: float) -> float:
    """How far a joint steadily lags a command moving at ``speed`` under a servo of stiffness ``kp`` and
    damping ``kv`` that must give the joint's ``friction`` loss and ``damping`` x speed: (f + (d + kv) v) /
    kp; 0 without a servo."""
    return (friction + (damping + kv) * speed) / kp if kp > 0 else 0.0


def growth_per_step(
    integrator: int,
    timestep: float,
    inertia: float,
    stiffness: float,
    damping: float,
    implicit_damping: float,
) -> float:
    """How much a joint's motion grows in a step (above 1: it diverges): a mass ``inertia`` on a spring
    ``stiffness`` and a damper ``damping`` of which ``implicit_damping`` MuJoCo's Euler integrates implicitly
    (the joint's own damping, unless ``eulerdamp`` is off; implicit and implicitfast integrate all of it;
    RK4, all explicitly)."""
    h, k, d = timestep, stiffness / inertia, damping / inertia
    if integrator == mujoco.mjtIntegrator.mjINT_RK4:
        a = np.array([[0.0, 1.0], [-k, -d]]) * h
        step = np.eye(2) + a + a @ a / 2 + a @ a @ a / 6 + a @ a @ a @ a / 24
    else:  # semi-implicit Euler: the velocity (the damping's implicit share implicitly), then the position
        implicit = d if integrator != mujoco.mjtIntegrator.mjINT_EULER else implicit_damping / inertia
        c = 1.0 / (1.0 + h * implicit)
        explicit = 1.0 - h * (d - implicit)
        step = np.array([[1.0 - c * h * h * k, c * h * explicit], [-c * h * k, c * explicit]])
    return float(np.abs(np.linalg.eigvals(step)).max())
