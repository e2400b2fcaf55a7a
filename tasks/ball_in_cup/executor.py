"""A swing executed in a running simulation: the UR5e's ball-in-a-cup DMP, open loop, one physics step at a
time.

A swing is what the ball-in-a-cup task (:mod:`besman.tasks.ball_in_cup.rollouts`) learns: theta, a joint-space
DMP from the start pose, tracked with the robot's velocity feedforward while the gripper's command stays as it
is. A :class:`CatchExecutor` runs it exactly as the task's rollouts do - the same control row before each
physics step, for the rollout's whole duration (the motion, then the ball's flight and settling) - and
judges it by the same rule (:func:`~besman.tasks.ball_in_cup.rollouts.judge` on the ball's position in the
cup's frame at every step), so the catch a behaviour tree sees is the catch the template was learned and
refined for. Ruckig does not smooth the swing: the task already refuses a reference beyond the joint ranges
or the speed limits, and smoothing a swing changes where the ball goes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array
from besman.sim.executor import Executor
from besman.sim.motions import MotionStatus
from besman.sim.world import World
from besman.tasks.ball_in_cup.rollouts import BallInCupRollouts, CatchDetail, judge


@dataclass
class SwingInProgress:
    """A swing under way: its controls (steps, nu), how far it has run, the ball's positions in the cup's
    frame after every step so far, and how it ended (``detail``, None while it runs)."""

    controls: np.ndarray
    step: int = 0
    ball: list[np.ndarray] = field(default_factory=list)
    detail: CatchDetail | None = None

    @property
    def status(self) -> MotionStatus:
        if self.detail is None:
            return MotionStatus.RUNNING
        return MotionStatus.SUCCEEDED if self.detail.failure is None else MotionStatus.FAILED


class CatchExecutor(Executor):
    """The UR5e's executor in a ball-in-a-cup world (``world``, whose string is the run's), which also swings
    the task's DMPs (``task``: the rollouts, for their references and limits)."""

    def __init__(self, world: World, task: BallInCupRollouts) -> None:
        super().__init__(world)
        self.task = task
        self.swing: SwingInProgress | None = None
        self._sensor = world.model.sensor("ball_in_cup").adr[0]

    def start_swing(self, theta) -> SwingInProgress:
        """Starts the swing of ``theta`` (the task's 72 parameters) from where the arm is (the start pose: the
        swing's DMP starts there); a reference that the task refuses raises an
        :class:`~besman.core.errors.InputError` with the reason."""
        theta = finite_array("theta", theta, ndim=1)
        task = self.task
        if theta.shape != (task.n_params,):
            raise InputError(f"a swing has {task.n_params} parameters, got {theta.size}")
        if not np.allclose(self.arm.measured(), task.start, atol=1e-3):
            raise InputError("a swing starts with the arm at rest in the task's start pose")
        positions, velocities = task.references(theta[None])
        failures, _ = task.check_references(positions)
        if failures[0] is not None:
            raise InputError(f"the swing cannot be executed: {failures[0]}")
        self.motion = None
        self.world.data.qacc_warmstart[:] = 0.0  # as the task's rollouts start
        self.swing = SwingInProgress(task._controls(positions, velocities)[0])
        return self.swing

    def advance(self, cycles: int) -> MotionStatus:
        swing = self.swing
        if swing is None or swing.status is not MotionStatus.RUNNING:
            return super().advance(cycles)
        model, data, sensor = self.world.model, self.world.data, self._sensor
        for _ in range(cycles * self.substeps):
            data.ctrl[:] = swing.controls[swing.step]
            mujoco.mj_step(model, data)
            swing.ball.append(data.sensordata[sensor : sensor + 3].copy())
            swing.step += 1
            if not np.isfinite(data.qpos).all() or data.warning.number[mujoco.mjtWarning.mjWARN_BADQACC] > 0:
                swing.detail = CatchDetail(False, None, None, None, "the simulation diverged")
                break
            if swing.step >= len(swing.controls):
                success, caught, crossing, peak = judge(np.array(swing.ball), float(model.opt.timestep))
                swing.detail = CatchDetail(success, caught, crossing, peak, None)
                break
        if swing.status is not MotionStatus.RUNNING:
            self.sync()  # the tree's next motion starts where the swing left the arm
        return swing.status
