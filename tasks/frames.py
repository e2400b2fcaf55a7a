"""What one frame of a task run is, for the datasets besman records (:mod:`besman.tasks.recording`) and the
Gymnasium environments (:mod:`besman.tasks.environment`) alike: the robot's state, tau and the action, each
named. Every driven arm in turn: the executor's, then those in lockstep with it.

- ``state``: the arms' joint positions and their fingers' joint positions, then the same joints'
  velocities, as measured (``<joint>.pos``, ``<joint>.vel``; rad, m, rad/s, m/s);
- ``environment_state``: tau, the task's values (``besman tasks show TASK``);
- ``action``: each arm's commanded joint positions and, for an arm with a gripper, its opening (m per
  finger): ``<joint>.pos``, ``<arm>.gripper``.
"""

from __future__ import annotations

import numpy as np


class RobotFrames:
    """The state and action of ``executor``'s arms, read from its world and its commands."""

    def __init__(self, executor) -> None:
        self.arms = [executor, *executor.companions.values()]
        model = executor.world.model
        self.data = executor.world.data
        joints = [
            name
            for arm in self.arms
            for name in (*arm.arm.joints, *(() if arm.hand is None else arm.hand.fingers.joints))
        ]
        self._qpos = np.array([model.jnt_qposadr[model.joint(name).id] for name in joints])
        self._qvel = np.array([model.jnt_dofadr[model.joint(name).id] for name in joints])
        self.state_names = [f"{j}.pos" for j in joints] + [f"{j}.vel" for j in joints]
        self.action_names = [
            name
            for arm in self.arms
            for name in (
                *(f"{joint}.pos" for joint in arm.arm.joints),
                *((f"{arm.name}.gripper",) if arm.hand is not None else ()),
            )
        ]
        self.action_low = np.concatenate([self._limits(arm)[0] for arm in self.arms])
        self.action_high = np.concatenate([self._limits(arm)[1] for arm in self.arms])

    @staticmethod
    def _limits(arm) -> tuple[np.ndarray, np.ndarray]:
        gripper = arm.arm.gripper
        extra = ([], []) if arm.hand is None else ([gripper.lower], [gripper.upper])
        return np.r_[arm.arm.lower, extra[0]], np.r_[arm.arm.upper, extra[1]]

    def state(self) -> np.ndarray:
        return np.concatenate([self.data.qpos[self._qpos], self.data.qvel[self._qvel]])

    def commanded(self) -> np.ndarray:
        """The arms' commanded joint positions and gripper openings now."""
        return np.concatenate(
            [np.r_[arm.position, [] if arm.hand is None else [arm.gripper_opening]] for arm in self.arms]
        )

    def split(self, action: np.ndarray) -> list[tuple[object, np.ndarray, float | None]]:
        """An action as each arm's (executor, joint targets, gripper opening or None)."""
        parts, start = [], 0
        for arm in self.arms:
            joints = action[start : start + arm.arm.dofs]
            start += arm.arm.dofs
            opening = None
            if arm.hand is not None:
                opening, start = float(action[start]), start + 1
            parts.append((arm, joints, opening))
        return parts


class SceneCamera:
    """A free camera aimed at the scene's centre, rendered offscreen (``MUJOCO_GL=egl``) at ``size``
    (height, width) without multisampling, shadows and reflections: 0.47 -> 0.04 s a frame in software (no
    GPU)."""

    def __init__(self, world, size: tuple[int, int]) -> None:
        import mujoco

        self.data, model = world.data, world.model
        samples, model.vis.quality.offsamples = model.vis.quality.offsamples, 0
        try:
            self.renderer = mujoco.Renderer(model, *size)
        finally:
            model.vis.quality.offsamples = samples
        self.camera = mujoco.MjvCamera()
        mujoco.mjv_defaultFreeCamera(model, self.camera)
        self._plain = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION)

    def render(self) -> np.ndarray:
        """The scene now, (height, width, 3) uint8."""
        self.renderer.update_scene(self.data, self.camera)
        for flag in self._plain:
            self.renderer.scene.flags[flag] = False
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()
