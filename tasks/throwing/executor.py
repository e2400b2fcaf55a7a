"""A throw executed in a running simulation: the PA-10's learned throw, open loop, one physics step at a time.

A throw is what the throwing task (:mod:`besman.tasks.throwing.rollouts`) learns: a position reference for the
7 joints at the physics rate (1 ms) and the step at which the weld lets the ball go. A
:class:`ThrowingExecutor` runs it exactly as the task's rollouts do - the same control row before each
physics step, the weld switched off at the same step, the landing found the same way (the ball's centre
crossing its radius above the floor, interpolated between steps) - so the landing a behaviour tree sees is
the landing the template was learned and refined for. Ruckig does not smooth the throw: the task already
refuses a reference beyond the joint ranges or the variant's speed limits, and smoothing a throw moves
where the ball lands. Everything else (a move to the wind-up pose, say) goes through the executor's Ruckig
streams as usual.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array
from besman.sim.executor import Executor
from besman.sim.motions import MotionStatus
from besman.tasks.throwing.rollouts import ThrowingRollouts


@dataclass
class ThrowInFlight:
    """A throw under way: its controls (steps, nu + 1: joint targets and the weld switch), how far it has
    run, and how it ended (``landing`` (x, y), or the ``failure``)."""

    controls: np.ndarray
    release_step: int
    step: int = 0
    landing: np.ndarray | None = None
    failure: str | None = None
    ball_height: float | None = None  # the ball's centre above its radius after the last step
    ball_xy: np.ndarray | None = None  # and where it was

    @property
    def status(self) -> MotionStatus:
        if self.failure is not None:
            return MotionStatus.FAILED
        return MotionStatus.RUNNING if self.landing is None else MotionStatus.SUCCEEDED


class ThrowingExecutor(Executor):
    """The executor of the PA-10 (its one arm, no gripper) in ``task``'s world, which also throws."""

    def __init__(self, task: ThrowingRollouts) -> None:
        super().__init__(task.world)
        self.task = task
        self.throw: ThrowInFlight | None = None
        model = task.model
        self._touch = model.sensor_adr[model.sensor("ball_touches_robot").id]
        self._ball = model.sensor_adr[model.sensor("ball_position").id]

    def wind_up(self) -> None:
        """Puts the arm at rest in the task's wind-up pose with the ball in the hand (the throw's start)."""
        model, data = self.world.model, self.world.data
        mujoco.mj_setState(model, data, self.task._initial_state, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
        data.qacc_warmstart[:] = 0.0  # as the task's rollouts start
        mujoco.mj_forward(model, data)
        self.sync()

    def start_throw(self, theta) -> ThrowInFlight:
        """Starts the throw of ``theta`` (the task's parameters) from where the arm is; a reference that the
        task refuses raises an :class:`~besman.core.errors.InputError` with the reason."""
        theta = finite_array("theta", theta, ndim=1)
        if theta.shape != (self.task.n_params,):
            raise InputError(f"a throw has {self.task.n_params} parameters, got {theta.size}")
        controls, failures, release_step, _ = self.task.controls(theta[None])
        if failures[0] is not None:
            raise InputError(f"the throw cannot be executed: {failures[0]}")
        self.motion = None
        self.throw = ThrowInFlight(controls[0], int(release_step[0]))
        return self.throw

    def advance(self, cycles: int) -> MotionStatus:
        throw = self.throw
        if throw is None or throw.status is not MotionStatus.RUNNING:
            return super().advance(cycles)
        model, data, task = self.world.model, self.world.data, self.task
        nu, weld, radius = model.nu, task.weld, task.ball_radius
        for _ in range(cycles * self.substeps):
            row = throw.controls[min(throw.step, len(throw.controls) - 1)]
            data.ctrl[:nu] = row[:nu]
            data.eq_active[weld] = row[nu]
            mujoco.mj_step(model, data)
            height = float(data.sensordata[self._ball + 2]) - radius
            if throw.step >= throw.release_step:
                if height <= 0.0:
                    self._land(throw, height)
                    break
                if data.sensordata[self._touch] > 0:
                    after = (throw.step - throw.release_step) * model.opt.timestep
                    throw.failure = f"the ball touches the robot {after:.3f} s after the release"
                    break
            throw.ball_height = height
            throw.ball_xy = data.sensordata[self._ball : self._ball + 2].copy()
            throw.step += 1
            if throw.step >= task.n_steps:
                throw.failure = f"the ball never lands within {task.config.duration:g} s"
                break
        if throw.status is not MotionStatus.RUNNING:
            self.sync()  # the tree's next motion starts where the throw left the arm
        return throw.status

    def _land(self, throw: ThrowInFlight, height: float) -> None:
        ball = self.world.data.sensordata[self._ball : self._ball + 2]
        if throw.ball_height is None or throw.step == throw.release_step:
            throw.failure = "the ball touches the floor at the release"
            return
        # Linear between the last step above and this one (as the task finds landings).
        fraction = throw.ball_height / (throw.ball_height - height)
        throw.landing = throw.ball_xy + fraction * (ball - throw.ball_xy)
