"""Simulation faults: what makes a simulated run untrustworthy, found after every step.

MuJoCo does not stop on trouble: on a bad acceleration it warns and resets the state, on instability the
state fills with NaN, and joint limits are soft. A :class:`FaultMonitor` turns those into one reason string
per run ("mujoco warning BADQACC at t=0.412 s", "joint J_Elbow_r left its range by 0.031 rad", ...), so a run
can fail cleanly and the world can be reset.
"""

from __future__ import annotations

import math

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


def counted_warnings(data: mujoco.MjData) -> tuple[str, ...]:
    """Every warning MuJoCo has counted in ``data`` since its last reset, with its count (``"BADQACC: 1"``):
    what a worker process's simulation said, which its parent never sees printed."""
    return tuple(
        f"{warning.name.removeprefix('mjWARN_')}: {data.warning[warning].number}"
        for warning in mujoco.mjtWarning.__members__.values()
        if warning != mujoco.mjtWarning.mjNWARNING and data.warning[warning].number
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
        self._max_squared_speed = max_speed**2
        limited = np.flatnonzero(model.jnt_limited & (model.jnt_type >= mujoco.mjtJoint.mjJNT_SLIDE.value))
        self._limited_joints = limited
        self._addresses = model.jnt_qposadr[limited]
        self._lower, self._upper = model.jnt_range[limited, 0], model.jnt_range[limited, 1]
        self._serious = np.array([int(w) for w in SERIOUS_WARNINGS])
        self._warnings = np.zeros(len(SERIOUS_WARNINGS), dtype=int)

    def reset(self, data: mujoco.MjData) -> None:
        """Forgets warnings that happened before now."""
        self._warnings = self._counts(data)
        self._all_warnings = data.warning.number.tolist()

    def _counts(self, data: mujoco.MjData) -> np.ndarray:
        return data.warning.number[self._serious]

    def check(self, data: mujoco.MjData) -> str | None:
        """The first fault found in ``data`` since :meth:`reset`, or None."""
        # Runs every control cycle, so the common case (no fault) is decided by cheap bounds: any new warning
        # at all, |qvel|^2 (NaN with a NaN, at least the largest speed squared) and qpos . qpos (NaN with a
        # NaN); only when one trips are the exact checks made.
        warnings = data.warning.number.tolist()
        if warnings != self._all_warnings:
            counts = self._counts(data)
            new = np.flatnonzero(counts > self._warnings)
            if new.size:
                name = SERIOUS_WARNINGS[int(new[0])].name.removeprefix("mjWARN_")
                return f"mujoco warning {name} at t={data.time:.3f} s"
            self._all_warnings = warnings  # only harmless ones (e.g. buffer growth)
        qvel, qpos = data.qvel, data.qpos
        squared_speed, squared_position = float(qvel @ qvel), float(qpos @ qpos)
        if not (squared_speed <= self._max_squared_speed and math.isfinite(squared_position)):
            fault = self._divergence(data)
            if fault is not None:
                return fault
        return self._range_fault(data)

    def _divergence(self, data: mujoco.MjData) -> str | None:
        speed = np.abs(data.qvel)
        fastest = speed.max()  # NaN if any is NaN
        if not (np.isfinite(fastest) and np.all(np.isfinite(data.qpos))):
            return f"the simulation diverged (NaN or inf in the state) at t={data.time:.3f} s"
        if fastest > self.max_speed:
            dof = int(speed.argmax())
            joint = self.model.joint(self.model.dof_jntid[dof]).name
            return f"the simulation diverged: joint {joint} moves at {speed.max():.3g} at t={data.time:.3f} s"
        return None

    def _range_fault(self, data: mujoco.MjData) -> str | None:
        positions = data.qpos[self._addresses]
        excess = np.maximum(self._lower - positions, positions - self._upper)
        if excess.size and excess.max() > self.joint_margin:
            worst = int(excess.argmax())
            joint = self.model.joint(self._limited_joints[worst]).name
            return f"joint {joint} left its range by {excess[worst]:.3g} at t={data.time:.3f} s"
        return None
