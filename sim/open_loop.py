"""Batched open-loop rollouts of a joint-space DMP on one arm, in MuJoCo's C rollout (``mujoco.rollout``).

:class:`OpenLoopRollouts` is what the dynamic tasks that policy search runs open loop share (ball-in-a-cup,
the puck strike): theta is the arm's DMP (weights, goal and goal velocity per joint) from rest in the task's
start pose; the joints follow its reference with the robot's velocity feedforward (each position command
leads by the commanded velocity x kv/kp); the other actuators keep their keyframe commands. A reference
that leaves the joint ranges or the joints' speed limits is not simulated: it gets
``FAILURE_REWARD * (1 + violation)`` (rad and relative overspeed, capped at :data:`VIOLATION_CAP`), a
diverged simulation ``FAILURE_REWARD``.

A task subclasses it with its world, its start pose and what is specific to it: which model parameters tau
sets (:meth:`~OpenLoopRollouts._physics_key`, :meth:`~OpenLoopRollouts._configure`), where its objects start
(:meth:`~OpenLoopRollouts._place`) and how a rollout's recorded states and sensors score
(:meth:`~OpenLoopRollouts._score`, :meth:`~OpenLoopRollouts.failed`). Rollouts run on a few copies of the
model, each set to one tau's parameters for a batch of the rollouts that share them (never a copy per tau);
each rollout is independent of the others (its own start state, zero warm start), so the same theta and tau
give the same reward bit for bit, whatever else is in the batch and in whatever order.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Hashable
from typing import Any, ClassVar

import mujoco
import numpy as np
from mujoco import rollout

from besman.core.errors import InputError
from besman.core.validation import finite_array
from besman.sim.evaluation import BatchedRollouts, Evaluation, check_backend
from besman.skills import DMP, DMPSettings

FAILURE_REWARD = -10.0
# The tasks' rewards: every success scores at least SUCCESS, every miss less.
SUCCESS = float(np.nextafter(0.0, np.inf))
VIOLATION_CAP = 1e3
MAX_THREADS = 4  # rollout threads, and model copies
MAX_START_STATES = 4096  # start states kept, by tau's physics
DIVERGED = "the simulation diverged"


class OpenLoopRollouts(BatchedRollouts):
    """Open-loop rollouts of the arm's joint-space DMP on a task's world; see the module documentation.

    ``config`` has ``execution_time`` (s, the DMP's), ``duration`` (s simulated per rollout) and
    ``n_weights``; ``start_steps`` is how many steps the world settles in the start pose before a rollout's
    initial state is taken."""

    in_processes: ClassVar[bool] = False  # open loop: MuJoCo's rollouts on its own threads, here
    start_steps: ClassVar[int] = 0

    def _set_up(self, config, bounds, world, start) -> None:
        """The parts every such task has: its config, tau's box, the world and the arm's start pose."""
        self.config = config
        self.bounds = bounds
        self.world = world
        self.model = model = world.model
        self.robot = world.robot
        self.arm = self.robot.group("arm")
        self.timestep = float(model.opt.timestep)
        self.n_steps = round(config.duration / self.timestep)
        actuators = self.arm.actuator_indices
        self.lead = -model.actuator_biasprm[actuators, 2] / model.actuator_gainprm[actuators, 0]
        self.speed_limits = np.asarray(self.arm.velocity, dtype=float)
        self.start = np.asarray(start, dtype=float)
        self.dmp = DMP(
            self.arm.size,
            settings=DMPSettings(n_weights=config.n_weights),
            execution_time=config.execution_time,
            dt=self.timestep,
            start=self.start,
            goal=self.start,
        )
        self._hold = model.key(self.robot.keyframe).ctrl.copy()  # the gripper's command stays
        self._threads = max(1, min(MAX_THREADS, os.cpu_count() or 1))
        self._copies: list[mujoco.MjModel] = []  # one per thread, each set to one tau's physics of a batch
        self._states: dict[Hashable, np.ndarray] = {}  # start states by tau's physics
        self.state_spec = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
        self._pool: rollout.Rollout | None = None
        self._datas: list[mujoco.MjData] = []

    @property
    def n_params(self) -> int:
        """72 with the defaults: 6 joints x (10 weights + goal + goal velocity)."""
        return self.dmp.n_params

    def still_theta(self) -> np.ndarray:
        """The DMP that holds the start pose (no motion)."""
        return self.dmp.get_params()

    # -- what a task says ----------------------------------------------------------------------------------

    def _physics_key(self, tau: np.ndarray) -> Hashable:
        """What of tau (d,) changes the physics, as a key of the model's parameters (None: nothing)."""
        return None

    def _configure(self, model: mujoco.MjModel, key: Hashable) -> None:
        """Sets ``model``'s parameters to those of ``key`` (default: none to set)."""

    def _place(self, model: mujoco.MjModel, data: mujoco.MjData, key: Hashable) -> None:
        """Places the task's objects in ``data``, the arm posed at the start (default: the keyframe's)."""

    def failed(self, reason: str) -> Any:
        """The detail of a rollout that failed before or during simulation, for ``reason``."""
        raise NotImplementedError

    def _score(self, states: np.ndarray, sensors: np.ndarray, tau: np.ndarray) -> tuple[float, Any]:
        """The reward and detail of one sound rollout: its states (n_steps, nstate), sensor data (n_steps,
        nsensordata) and tau (d,)."""
        raise NotImplementedError

    def _sound(self, states: np.ndarray, sensors: np.ndarray) -> np.ndarray:
        """Whether each rollout (N, n_steps, ...) stayed sound: finite, and its time never started again."""
        steps = np.arange(1, self.n_steps + 1) * self.timestep
        finite = np.isfinite(states).all(axis=(1, 2))
        # After a bad acceleration MuJoCo resets the state, and time starts again from zero.
        return finite & (np.abs(states[:, :, 0] - steps[None]) <= 0.5 * self.timestep).all(axis=1)

    # -- the physics per tau -------------------------------------------------------------------------------

    def _copy(self, index: int, key: Hashable) -> mujoco.MjModel:
        """Model copy ``index`` set to ``key``'s physics (and that physics' start state made)."""
        while len(self._copies) <= index:
            self._copies.append(copy.copy(self.model))
        model = self._copies[index]
        self._configure(model, key)
        if key not in self._states:
            if len(self._states) >= MAX_START_STATES:
                self._states.clear()
            self._states[key] = self._start_state(model, key)
        return model

    def _start_for(self, key: Hashable) -> np.ndarray:
        """A copy of the start state of ``key``'s physics."""
        self._copy(0, key)
        return self._states[key].copy()

    def _start_state(self, model: mujoco.MjModel, key: Hashable) -> np.ndarray:
        """The arm at rest in the start pose and the objects settled for ``start_steps`` steps, time 0."""
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key(self.robot.keyframe).id)
        data.qpos[self.arm.qpos_indices] = self.start
        ctrl = self._hold.copy()
        ctrl[self.arm.actuator_indices] = self.start
        data.ctrl[:] = ctrl
        self._place(model, data, key)
        mujoco.mj_forward(model, data)
        for _ in range(self.start_steps):
            mujoco.mj_step(model, data)
        data.time = 0.0
        state = np.empty(mujoco.mj_stateSize(model, self.state_spec))
        mujoco.mj_getState(model, data, state, self.state_spec)
        return state

    # -- references ----------------------------------------------------------------------------------------

    def references(self, thetas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and velocities (N, n_steps + 1, 6) of the thetas' DMPs over the whole rollout."""
        with np.errstate(over="ignore", invalid="ignore"):
            trajectory = self.dmp.trajectories(thetas, run_time=self.config.duration, derivatives=1)
        return trajectory.positions, trajectory.velocities

    def check_references(self, positions: np.ndarray) -> tuple[list[str | None], np.ndarray]:
        """Per reference (N, T, 6): why it cannot run (None if it can) and how far it violates the joint
        ranges (rad) and speed limits (relative), summed."""
        failures: list[str | None] = []
        violations = np.zeros(len(positions))
        finite = np.isfinite(positions).all(axis=(1, 2))
        for i in range(len(positions)):
            if not finite[i]:
                failures.append("the reference overflows (theta too large)")
                violations[i] = VIOLATION_CAP
                continue
            q = positions[i]
            overshoot = np.maximum(self.arm.lower - q.min(axis=0), q.max(axis=0) - self.arm.upper)
            overspeed = np.abs(np.diff(q, axis=0)).max(axis=0) / self.timestep / self.speed_limits - 1.0
            violations[i] = min(
                VIOLATION_CAP, float(np.maximum(overshoot, 0).sum() + np.maximum(overspeed, 0).sum())
            )
            reason = None
            for j, joint in enumerate(self.arm.joints):
                if overshoot[j] > 0:
                    reason = f"the reference leaves the range of joint {joint} by {overshoot[j]:.3g} rad"
                    break
                if overspeed[j] > 0:
                    speed = (1.0 + overspeed[j]) * self.speed_limits[j]
                    reason = (
                        f"the reference exceeds the speed limit of joint {joint}: {speed:.3g} > "
                        f"{self.speed_limits[j]:.3g} rad/s"
                    )
                    break
            failures.append(reason)
        return failures, violations

    def feasible(self, thetas) -> np.ndarray:
        """Whether each theta's reference keeps the joint ranges and speed limits (no rollout)."""
        thetas = np.array(thetas, dtype=float, ndmin=2)
        positions, _ = self.references(thetas)
        failures, _ = self.check_references(positions)
        return np.array([failure is None for failure in failures])

    # -- evaluation ----------------------------------------------------------------------------------------

    def evaluate(self, thetas, taus, *, backend: str = "threads") -> Evaluation:
        """Rewards (N,) and a detail per rollout for thetas (N, n_params) or (n_params,) and taus (N, d) or
        (d,); the same inputs give the same results, bit for bit."""
        check_backend(backend)
        return super().evaluate(thetas, taus, backend=backend)

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        positions, velocities = self.references(thetas)
        return self.evaluate_references(positions, velocities, taus)

    def evaluate_references(self, positions, velocities, taus) -> Evaluation:
        """Rewards and details for joint references given directly: positions and velocities (N, n_steps + 1,
        6) sampled every timestep from t = 0 (a scripted baseline's motions, a recording's), taus (N, d)."""
        positions = np.asarray(positions, dtype=float)
        velocities = np.asarray(velocities, dtype=float)
        expected = (self.n_steps + 1, self.arm.size)
        if positions.ndim != 3 or positions.shape[1:] != expected or velocities.shape != positions.shape:
            raise InputError(
                f"references must have shape (N, {expected[0]}, {expected[1]}), got {positions.shape}"
            )
        taus = self.bounds.check(taus, n=len(positions))
        failures, violations = self.check_references(positions)
        rewards = FAILURE_REWARD * (1.0 + violations)
        details = [self.failed(failure) for failure in failures]
        run = [i for i, failure in enumerate(failures) if failure is None]
        if run:
            states, sensors = self._run(positions[run], velocities[run], taus[run])
            for row, i in enumerate(run):
                rewards[i], details[i] = self.judged(states[row], sensors[row], taus[i])
        return Evaluation(rewards, tuple(details))

    def judged(self, states: np.ndarray, sensors: np.ndarray, tau: np.ndarray) -> tuple[float, Any]:
        """The reward and detail of one rollout that ran: its states (n_steps, nstate) and sensor data
        (n_steps, nsensordata) as MuJoCo's rollout records them (the time from the rollout's start), for tau
        (d,); a rollout that did not stay sound gets ``FAILURE_REWARD``. A run's executor judges a motion by
        it too (:mod:`besman.sim.open_loop_executor`)."""
        if not self._sound(states[None], sensors[None])[0]:
            return FAILURE_REWARD, self.failed(DIVERGED)
        reward, detail = self._score(states, sensors, tau)
        return float(reward), detail

    def simulate(self, theta, tau) -> tuple[np.ndarray | None, Any]:
        """One rollout, step by step: ``qpos`` (n_steps, nq) of the whole model and its detail (None instead
        of the positions for a reference that cannot run or a simulation that diverged)."""
        theta = finite_array("theta", theta, ndim=1)
        tau = self.bounds.check(tau, n=1)
        positions, velocities = self.references(theta[None])
        failures, _ = self.check_references(positions)
        if failures[0] is not None:
            return None, self.failed(failures[0])
        states, sensors = self._run(positions, velocities, tau)
        _, detail = self.judged(states[0], sensors[0], tau[0])
        return (None if detail.failure == DIVERGED else states[0, :, 1 : 1 + self.model.nq].copy()), detail

    def controls(self, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """Actuator commands (N, n_steps, nu): the reference at the step's end, led by its velocity."""
        controls = np.repeat(self._hold[None, None], len(positions), axis=0).repeat(self.n_steps, axis=1)
        controls[:, :, self.arm.actuator_indices] = positions[:, 1:] + self.lead * velocities[:, 1:]
        return controls

    def _run(self, positions, velocities, taus) -> tuple[np.ndarray, np.ndarray]:
        """States (N, n_steps, nstate) and sensor data (N, n_steps, nsensordata) of the references' rollouts
        in taus (N, d)."""
        keys = [self._physics_key(tau) for tau in taus]
        if self._pool is None:
            self._pool = rollout.Rollout(nthread=self._threads)
            self._datas = [mujoco.MjData(self.model) for _ in range(self._threads)]
        controls = self.controls(positions, velocities)
        nstate = mujoco.mj_stateSize(self.model, self.state_spec)
        states = np.empty((len(keys), self.n_steps, nstate))
        sensors = np.empty((len(keys), self.n_steps, self.model.nsensordata))
        distinct = list(dict.fromkeys(keys))
        # Rollouts of up to one physics per model copy at a time; each rollout is independent of the others
        # (its own state, zero warm start), so how a batch is cut does not change a bit of it.
        for first in range(0, len(distinct), self._threads):
            chunk = {key: self._copy(j, key) for j, key in enumerate(distinct[first : first + self._threads])}
            rows = [i for i, key in enumerate(keys) if key in chunk]
            states[rows], sensors[rows] = self._pool.rollout(
                [chunk[keys[i]] for i in rows],
                self._datas,
                np.stack([self._states[keys[i]] for i in rows]),
                controls[rows],
                control_spec=mujoco.mjtState.mjSTATE_CTRL.value,
                initial_warmstart=np.zeros((len(rows), self.model.nv)),
            )
        return states, sensors

    def close(self) -> None:
        """Shuts the rollout thread pool down now (otherwise it goes with the task)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None
