"""An open-loop motion executed in a running simulation: a theta of a task's batched open-loop rollouts
(:class:`~besman.sim.open_loop.OpenLoopRollouts`), one physics step at a time.

The dynamic tasks that policy search runs open loop (ball-in-a-cup, the puck strike) learn theta, the arm's
joint-space DMP from rest in the task's start pose, tracked with the robot's velocity feedforward while the
other actuators keep their commands. An :class:`OpenLoopExecutor` runs such a theta in the run's world
exactly as the task's rollouts do (:func:`mujoco.rollout`): before each physics step the rollouts' control
row for it (:meth:`~besman.sim.open_loop.OpenLoopRollouts.controls`), for the rollout's whole duration (the
motion, then what it set going: a ball's flight, a puck's slide), from a zero warm start; after each step it
records the full physics state (``mj_getState`` with the rollouts' own state spec, the time counted from
the motion's start) and the sensor data, as MuJoCo's rollout records them. A state that is not finite ends
the motion at once as diverged; otherwise it runs to its end, where MuJoCo's own resets after a bad
acceleration (time starting again) make it diverged as they make a rollout (the rollouts' one rule). At the
end the motion is judged by the rollouts' own rule (:meth:`~besman.sim.open_loop.OpenLoopRollouts.judged`) for
the run's tau, so the reward and detail a behaviour tree sees are those the template was learned and refined
for: from the rollouts' start state, the same bit for bit (tested). Ruckig does not smooth the motion: the
rollouts already refuse a reference beyond the joint ranges or the speed limits, and smoothing a dynamic
motion changes where the object goes.

A detail of such rollouts has ``success`` (bool) and ``failure`` (why it did not run to its end, or None).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, finite_array, instance
from besman.sim.executor import Executor
from besman.sim.motions import MotionStatus
from besman.sim.open_loop import DIVERGED, FAILURE_REWARD, OpenLoopRollouts
from besman.sim.world import World

START_TOLERANCE = 1e-3  # rad: how far from the start pose the arm may be when a motion starts


@dataclass
class OpenLoopMotion:
    """An open-loop motion under way: its control rows (n_steps, nu) and tau, the states (n_steps, nstate)
    and sensor data (n_steps, nsensordata) recorded so far (``step`` rows of them), and how it ended
    (``reward`` and ``detail``, the rollouts'; None while it runs)."""

    controls: np.ndarray
    tau: np.ndarray
    states: np.ndarray
    sensors: np.ndarray
    timestep: float
    started: float  # the world's time at the start (s)
    step: int = 0
    reward: float | None = None
    detail: Any = None

    @property
    def status(self) -> MotionStatus:
        if self.detail is None:
            return MotionStatus.RUNNING
        return MotionStatus.SUCCEEDED if self.detail.success else MotionStatus.FAILED

    @property
    def elapsed(self) -> float:
        """Simulated seconds since the start."""
        return self.step * self.timestep

    @property
    def last_sensors(self) -> np.ndarray:
        """The sensor data after the last step run (before any: the first row, not yet written)."""
        return self.sensors[max(self.step - 1, 0)]


class OpenLoopExecutor(Executor):
    """The robot's executor in a task's world (``world``, whose physics are those of tau), which also runs
    the thetas of the task's open-loop ``rollouts`` and judges them for ``tau`` (the run's task
    parameters)."""

    @checked(rollouts=instance(OpenLoopRollouts, "an OpenLoopRollouts (the task's batched rollouts)"))
    def __init__(self, world: World, rollouts: OpenLoopRollouts, tau) -> None:
        super().__init__(world)
        self.rollouts = rollouts
        self.tau = rollouts.bounds.check(tau, n=1)[0]
        model = world.model
        if (model.nu, model.nsensordata) != (rollouts.model.nu, rollouts.model.nsensordata):
            raise InputError(
                f"the world has {model.nu} actuators and {model.nsensordata} sensor values; the rollouts' "
                f"model {rollouts.model.nu} and {rollouts.model.nsensordata}: not the task's world"
            )
        self.open_loop: OpenLoopMotion | None = None

    def start_motion(self, theta) -> OpenLoopMotion:
        """Starts ``theta`` (the rollouts' parameters) from where the arm is, which must be the start pose
        (the DMP starts there); a theta of the wrong size, an arm elsewhere or a reference the rollouts
        refuse raises an :class:`~besman.core.errors.InputError` that says why."""
        rollouts = self.rollouts
        theta = finite_array("theta", theta, shape=(rollouts.n_params,))
        measured = self.arm.measured()
        if not np.allclose(measured, rollouts.start, atol=START_TOLERANCE):
            raise InputError(
                "an open-loop motion starts with the arm at rest in the task's start pose "
                f"{np.round(rollouts.start, 4).tolist()}; the arm is at {np.round(measured, 4).tolist()}"
            )
        positions, velocities = rollouts.references(theta[None])
        failures, _ = rollouts.check_references(positions)
        if failures[0] is not None:
            raise InputError(f"theta cannot be executed: {failures[0]}")
        model, data = self.world.model, self.world.data
        controls = rollouts.controls(positions, velocities)[0]
        nstate = mujoco.mj_stateSize(model, rollouts.state_spec)
        self.motion = None
        data.qacc_warmstart[:] = 0.0  # as the rollouts start
        self.open_loop = OpenLoopMotion(
            controls,
            self.tau,
            np.empty((len(controls), nstate)),
            np.empty((len(controls), model.nsensordata)),
            float(model.opt.timestep),
            float(data.time),
        )
        return self.open_loop

    def advance(self, cycles: int) -> MotionStatus:
        motion = self.open_loop
        if motion is None or motion.status is not MotionStatus.RUNNING:
            return super().advance(cycles)
        model, data, spec = self.world.model, self.world.data, self.rollouts.state_spec
        for _ in range(cycles * self.substeps):
            row = motion.step
            data.ctrl[:] = motion.controls[row]
            mujoco.mj_step(model, data)
            mujoco.mj_getState(model, data, motion.states[row], spec)
            motion.states[row, 0] -= motion.started  # the motion's clock, as a rollout's
            motion.sensors[row] = data.sensordata
            motion.step += 1
            if not np.isfinite(motion.states[row]).all():
                motion.reward, motion.detail = FAILURE_REWARD, self.rollouts.failed(DIVERGED)
                break
            if motion.step == len(motion.controls):
                motion.reward, motion.detail = self.rollouts.judged(motion.states, motion.sensors, motion.tau)
                break
        if motion.status is not MotionStatus.RUNNING:
            self.sync()  # the tree's next motion starts where this one left the arm
        return motion.status
