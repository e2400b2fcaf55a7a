"""Simulation faults: what makes a simulated run untrustworthy, found after every step.

MuJoCo does not stop on trouble: on a bad acceleration it warns and resets the state, on instability the
state fills with NaN, and joint limits are soft. A :class:`FaultMonitor` turns those into one reason string
per run ("mujoco warning BADQACC at t=0.412 s", "joint J_Elbow_r left its range by 0.031 rad", ...), so a run
can fail cleanly and the world can be reset.
"""

from __future__ import annotations

import mujoco
import numpy as np

# Warnings that mean the physics can no longer be trusted (others, e.g. buffer growth, are harmless).
SERIOUS_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_CONTACTFULL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL,
)


class FaultMonitor:
    """Checks a simulation for faults since the last :meth:`reset`.

    Args:
        model: the model.
        joint_margin: how far (rad or m) a limited joint may pass its range before it counts as leaving it;
            soft limits let joints press slightly beyond.
        max_speed: a joint speed (rad/s or m/s) above which the simulation counts as diverging.
    """

    def __init__(
        self, model: mujoco.MjModel, *, joint_margin: float = 0.02, max_speed: float = 100.0
    ) -> None:
        self.model = model
        self.joint_margin = joint_margin
        self.max_speed = max_speed
        limited = np.flatnonzero(model.jnt_limited & (model.jnt_type >= mujoco.mjtJoint.mjJNT_SLIDE.value))
        self._limited_joints = limited
        self._addresses = model.jnt_qposadr[limited]
        self._warnings = np.zeros(len(SERIOUS_WARNINGS), dtype=int)

    def reset(self, data: mujoco.MjData) -> None:
        """Forgets warnings that happened before now."""
        self._warnings = self._counts(data)

    def _counts(self, data: mujoco.MjData) -> np.ndarray:
        return np.array([data.warning[w].number for w in SERIOUS_WARNINGS])

    def check(self, data: mujoco.MjData) -> str | None:
        """The first fault found in ``data`` since :meth:`reset`, or None."""
        counts = self._counts(data)
        new = np.flatnonzero(counts > self._warnings)
        if new.size:
            name = SERIOUS_WARNINGS[int(new[0])].name.removeprefix("mjWARN_")
            return f"mujoco warning {name} at t={data.time:.3f} s"
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return f"the simulation diverged (NaN or inf in the state) at t={data.time:.3f} s"
        speed = np.abs(data.qvel)
        if speed.max() > self.max_speed:
            dof = int(speed.argmax())
            joint = self.model.joint(self.model.dof_jntid[dof]).name
            return f"the simulation diverged: joint {joint} moves at {speed.max():.3g} at t={data.time:.3f} s"
        positions = data.qpos[self._addresses]
        ranges = self.model.jnt_range[self._limited_joints]
        excess = np.maximum(ranges[:, 0] - positions, positions - ranges[:, 1])
        if excess.size and excess.max() > self.joint_margin:
            worst = int(excess.argmax())
            joint = self.model.joint(self._limited_joints[worst]).name
            return f"joint {joint} left its range by {excess[worst]:.3g} at t={data.time:.3f} s"
        return None
