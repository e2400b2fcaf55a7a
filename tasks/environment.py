"""Every registered task as a Gymnasium environment (``pip install 'besman[gym]'``): ``TaskEnv("pick-place")``
or ``gymnasium.make("besman/pick-place")`` (:func:`register_environments`).

- :meth:`~TaskEnv.reset` sets the task's scene up for tau drawn with the seed - the configuration ``besman
  run --seed`` gives - or for ``options={"values": {...}}`` (named as ``--set``); the same seed gives the
  same episode, step for step.
- Observations: ``{"state", "environment_state"}``, the robot's measured joints and tau, named as the
  datasets besman records name them (:mod:`besman.tasks.frames`, ``env.unwrapped.state_names``).
- Actions, by ``control``:

  - ``"joint"``: every arm's joint position targets and gripper opening (m per finger) - a dataset's
    ``action`` - held for one step (20 ms, the trees' tick) and reached through the executor's Ruckig
    streams, jerk-limited (a target beyond the limits is clipped);
  - ``"ee"``: per arm the tool-centre point's x, y, z (m, world) and yaw (rad) with the hand pointing down,
    then the gripper opening: inverse kinematics from the commanded joints (``info["ik_error_m"]``), then as
    ``"joint"``;
  - ``"throw"``, the throwing tasks' only control (a task declares the controls it takes,
    ``Task.controls``): one step per episode whose action is the throw's parameters theta (the paper's DMP
    weights and goal), run until the ball lands. The throw is not
    Ruckig-smoothed (smoothing moves where the ball lands: :mod:`besman.tasks.throwing.executor`).

- Reward 1 when the task is done by its own rule (as ``besman run`` judges a run), else 0; the episode then
  terminates. The rules let a released object settle (0.3 s), so the task is judged every ``judge_every``
  steps on the state saved beforehand and restored after: the episode's physics is untouched. A step whose
  motion fails (the robot blocked, a simulation fault) terminates the episode (``info["failure"]``); the
  task's simulated-time limit truncates it.
"""

from __future__ import annotations

import reprlib
from typing import ClassVar

import mujoco
import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as error:  # the optional extra
    raise ImportError("besman.tasks.environment needs gymnasium: pip install 'besman[gym]'") from error

from besman.core.errors import InputError
from besman.tasks import TASKS
from besman.tasks import task as find_task
from besman.tasks.frames import RobotFrames, SceneCamera

TICK_RATE = 50  # Hz: an environment step is one tick of the trees
CAMERA_SIZE = (240, 320)
ENTRY_POINT = "besman.tasks.environment:TaskEnv"


class TaskEnv(gymnasium.Env):
    """A task on a robot as an environment; see the module documentation."""

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": TICK_RATE}

    def __init__(
        self,
        task: str = "pick-place",
        robot: str | None = None,
        *,
        control: str | None = None,
        judge_every: int = 25,
        render_mode: str | None = None,
    ) -> None:
        self.task = find_task(task)
        self.robot = self.task.check_robot(robot)
        control = control or self.task.controls[0]
        if control not in self.task.controls:
            raise InputError(
                f"control {control!r}: task {self.task.name} takes {' or '.join(self.task.controls)}"
            )
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise InputError(f"render_mode {render_mode!r}: one of None, rgb_array")
        if not isinstance(judge_every, int) or judge_every < 1:
            raise InputError(f"judge_every must be a whole number >= 1, got {judge_every!r}")
        self.control, self.judge_every, self.render_mode = control, judge_every, render_mode
        self._build(self.task.resolve(self.robot, {}, None), None)
        frames, bounds = self.frames, self.task.bounds(self.robot)
        self.state_names = frames.state_names
        self.observation_space = spaces.Dict(
            {
                "state": spaces.Box(-np.inf, np.inf, (len(frames.state_names),), np.float64),
                "environment_state": spaces.Box(
                    np.asarray(bounds.low, dtype=np.float64),
                    np.asarray(bounds.high, dtype=np.float64),
                    dtype=np.float64,
                ),
            }
        )
        self.action_space = self._action_space()

    # -- the scene -----------------------------------------------------------------------------------------

    def _build(self, values: dict, seed: int | None) -> None:
        self.values = values
        self.scene = self.task.scene(self.robot, values, seed)
        self.executor = self.scene.executor  # what the task's observers read
        self.frames = RobotFrames(self.executor)
        self.world = self.executor.world
        self.camera = SceneCamera(self.world, CAMERA_SIZE) if self.render_mode == "rgb_array" else None
        self.steps = 0

    def _action_space(self) -> spaces.Box:
        if self.control == "throw":
            return spaces.Box(-np.inf, np.inf, (self.executor.task.n_params,), np.float64)
        if self.control == "joint":
            return spaces.Box(self.frames.action_low, self.frames.action_high, dtype=np.float64)
        table = self.world.surface("table")
        lows, highs = [], []
        for arm in self.frames.arms:
            if arm.hand is None:
                raise InputError(f"control ee: arm {arm.name} has no gripper")
            gripper = arm.arm.gripper
            (x0, x1), (y0, y1) = table.x, table.y
            lows += [x0, y0, table.height, -np.pi, gripper.lower]
            highs += [x1, y1, table.height + 0.6, np.pi, gripper.upper]
        return spaces.Box(np.array(lows), np.array(highs), dtype=np.float64)

    # -- Gymnasium -----------------------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        given = _given_values(options)
        super().reset(seed=seed)
        # The seed is the task's (besman run --seed's scene); later resets draw theirs from it.
        drawn = seed if seed is not None else int(self.np_random.integers(2**31))
        if self.camera is not None:
            self.camera.close()
        self._build(self.task.resolve(self.robot, given, drawn), drawn)
        return self._observation(), self._info()

    def step(self, action):
        size = self.action_space.shape[0]
        try:
            action = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"an action is {size} finite numbers, got {reprlib.repr(action)}") from None
        if action.shape != self.action_space.shape:
            raise InputError(f"an action is {size} finite numbers, got shape {action.shape}")
        broken = np.flatnonzero(~np.isfinite(action))
        if broken.size:
            entries = ", ".join(f"[{i}] = {action[i]}" for i in broken)
            raise InputError(f"an action is {size} finite numbers; not finite: {entries}")
        if self.control == "throw":
            return self._throw(action)
        info = {}
        if self.control == "ee":
            action, info["ik_error_m"] = self._joint_targets(action)
        from besman.sim.motions import MotionStatus, TrackTarget

        for arm, joints, opening in self.frames.split(action):
            arm.start(TrackTarget("env", joints, opening))
        self.executor.advance(round(1 / (TICK_RATE * self.executor.config.control_period)))
        self.steps += 1
        if self.scene.observe is not None:
            self.scene.observe(self, {})
        failed = [a.motion.message for a in self.frames.arms if a.motion.status is MotionStatus.FAILED]
        truncated = self.steps / TICK_RATE >= self.task.max_sim_time
        done = False
        if not failed and (truncated or self.steps % self.judge_every == 0):
            done, info["outcome"] = self._judged()
        if failed:
            info["failure"] = failed[0]
        terminated = done or bool(failed)
        return self._observation(), float(done), terminated, truncated and not terminated, self._info() | info

    def _throw(self, theta):
        from besman.sim.motions import MotionStatus

        if not self.executor.task.feasible(theta[None])[0]:  # the task of the executor's own world
            return self._observation(), 0.0, True, False, self._info() | {"failure": "infeasible throw"}
        self.executor.start_throw(theta)
        while self.executor.throw.status is MotionStatus.RUNNING:
            self.executor.advance(1)
        measured = self.scene.judge()
        info = {"outcome": measured.outcome, "measurements": measured.measurements}
        if self.executor.throw.failure is not None:
            info["failure"] = self.executor.throw.failure
        return self._observation(), float(measured.done), True, False, self._info() | info

    def _joint_targets(self, action: np.ndarray) -> tuple[np.ndarray, float]:
        from besman.sim.primitives import top_down

        targets, worst = [], 0.0
        for i, arm in enumerate(self.frames.arms):
            x, y, z, yaw, opening = action[5 * i : 5 * i + 5]
            result = arm.arm.solve_ik([x, y, z], top_down(yaw), initial=arm.position)
            worst = max(worst, float(result.position_error))
            targets.append(np.r_[result.qpos, opening])
        return np.concatenate(targets), worst

    def _judged(self) -> tuple[bool, str]:
        """The task's rule on the world as it stands, the physics saved before and restored after."""
        model, data = self.world.model, self.world.data
        kind = mujoco.mjtState.mjSTATE_INTEGRATION.value
        saved = np.empty(mujoco.mj_stateSize(model, kind))
        mujoco.mj_getState(model, data, saved, kind)
        try:
            measured = self.scene.judge()
        finally:
            mujoco.mj_setState(model, data, saved, kind)
            mujoco.mj_forward(model, data)
        return bool(measured.done), measured.outcome

    def _observation(self) -> dict:
        return {
            "state": self.frames.state(),
            "environment_state": self.task.join(self.values).astype(np.float64),
        }

    def _info(self) -> dict:
        return {"time_s": self.steps / TICK_RATE}

    def render(self):
        return None if self.camera is None else self.camera.render()

    def close(self) -> None:
        if self.camera is not None:
            self.camera.close()
            self.camera = None


def _given_values(options) -> dict:
    """The task values that :meth:`TaskEnv.reset`'s ``options`` give (``{"values": {NAME: numbers}}``)."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise InputError(
            f'reset options: expected a dict such as {{"values": {{...}}}}, got {reprlib.repr(options)}'
        )
    unknown = sorted(set(options) - {"values"}, key=str)
    if unknown:
        raise InputError(f"reset options: unknown option {unknown[0]!r}; the one option is 'values'")
    values = options.get("values", {})
    if not isinstance(values, dict):
        raise InputError(
            f'reset options["values"]: expected a dict of task values, named as --set names them '
            f'({{"object": [x, y]}}), got {reprlib.repr(values)}'
        )
    return dict(values)


def register_environments() -> list[str]:
    """Registers ``besman/<task>`` with Gymnasium for every task; their ids."""
    ids = []
    for name in TASKS:
        environment_id = f"besman/{name}"
        if environment_id not in gymnasium.registry:
            gymnasium.register(environment_id, entry_point=ENTRY_POINT, kwargs={"task": name})
        ids.append(environment_id)
    return ids
