"""Forward kinematics on MuJoCo models: world poses of sites (MuJoCo's own ``mj_kinematics``).

Inverse kinematics is in :mod:`besman.robots.ik`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, instance, optional, text
from besman.robots.robot import Robot
from besman.skills.quaternion import from_matrix

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


def site_id(model: mujoco.MjModel, site: str) -> int:
    """The id of the site ``site``; an error listing the model's sites if there is none."""
    index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if index < 0:
        names = [model.site(i).name for i in range(model.nsite)]
        raise InputError(f"no site {site!r} in the model; sites: {', '.join(names)}")
    return index


def site_pose(model: mujoco.MjModel, data: mujoco.MjData, site: str | int) -> Pose:
    """The world pose of ``site`` (name or id) in ``data`` as last computed (after ``mj_kinematics``)."""
    index = site if isinstance(site, int) else site_id(model, site)
    return Pose(data.site_xpos[index].copy(), from_matrix(data.site_xmat[index].reshape(3, 3)))


@checked(
    robot=instance(Robot, "a Robot (robots.load)"),
    site=text("a site name"),
    data=optional(instance(mujoco.MjData, "an MjData of the robot's model")),
)
def forward_kinematics(robot: Robot, qpos: np.ndarray, site: str, data: mujoco.MjData | None = None) -> Pose:
    """The world pose of ``site`` for a full configuration ``qpos`` (length ``model.nq``), computed in the
    scratch ``data`` if given (its state is overwritten), else in a new one."""
    qpos = np.asarray(qpos, dtype=float)
    if qpos.shape != (robot.model.nq,):
        raise InputError(f"qpos must have shape ({robot.model.nq},), got {qpos.shape}")
    if not np.all(np.isfinite(qpos)):
        raise InputError("qpos contains NaN or inf")
    data = mujoco.MjData(robot.model) if data is None else data
    data.qpos[:] = qpos
    mujoco.mj_kinematics(robot.model, data)
    return site_pose(robot.model, data, site)


def bodies_below(model: mujoco.MjModel, roots) -> np.ndarray:
    """Per body: whether it is one of ``roots`` (body ids) or hangs from one."""
    below = np.zeros(model.nbody, dtype=bool)
    below[roots] = True
    for body in range(1, model.nbody):  # parents come before their children
        below[body] |= below[model.body_parentid[body]]
    return below
