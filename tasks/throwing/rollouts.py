"""The paper's task: a simulated PA-10 throws a ball at a target on the floor (Metzen et al., KI 2014).

theta drives the 7 joints through joint-space DMPs plus one more DMP dimension whose value releases the
ball: the weld between hand and ball switches off at the first control step at which that dimension
reaches ``release_threshold`` (and stays off). With 10 weights, goal and goal velocity per dimension, theta
is 8 x 12 = 96-D. The DMPs start in the task's fixed wind-up pose at rest.

tau is the target (x, y) on the floor. The landing point is the ball's first floor contact after the
release, interpolated linearly between simulation steps (the centre crossing the ball's radius above the
floor). The reward is -||tau - landing||^2. A throw that fails - the reference leaves the joint ranges or
the speed limits, the ball is never released, touches the robot between its release and its landing (the
hand or arm swept back into it: contact is real once the ball has left the hand, see
``robots/pa10/README.md``), never lands within the simulated time, the simulation diverges - gets
``FAILURE_REWARD`` (-1000) instead, far below any real throw, and a reference that violates
its constraints gets ``FAILURE_REWARD * (1 + violation)``, growing with the summed violation (rad, relative
overspeed, release shortfall) up to ``VIOLATION_CAP``, so that an optimiser is led back to feasible throws.
A broken candidate (NaN or inf in theta with ``nan="penalize"``, or a theta so large that its reference
overflows) gets ``BROKEN_REWARD``, the capped penalty: never better than any failing throw.

Variants (``variant=``):

- ``"paper"``: the paper's target box [-7, -1] x [-5, 1] m. Reaching ~8.6 m needs ~9 m/s at release, more
  than the PA-10's hardware speed limits allow (about 2 m). The 2014 simulation evidently did not enforce
  them; this variant relaxes every joint's speed limit to 6 rad/s (a documented deviation).
- ``"hardware"``: the robot's own speed limits (``robots/pa10/README.md``), a slower default execution time
  (1.2 s instead of 0.6 s) and a box that such throws reach, [-1.5, -0.6] x [-0.6, 0.6] m (CMA-ES found
  throws landing 1.5 m away; the limits allow about 3 m/s at the hand).

The whole batch of rollouts is open-loop, so it runs in MuJoCo's C rollout (``mujoco.rollout``) on a
persistent thread pool with one MjData per thread, or on Ray (see :mod:`besman.sim.evaluation`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import ClassVar

import mujoco
import numpy as np
from mujoco import rollout

from besman.core.errors import InputError
from besman.core.moved import old_names
from besman.core.validation import (
    checked,
    finite_array,
    instance,
    integer,
    number,
    optional,
    positive,
    text,
)
from besman.sim.evaluation import BatchedRollouts, Evaluation, check_backend
from besman.skills import DMP, DMPSettings, quaternion
from besman.skills.task_bounds import TaskBounds
from besman.tasks.throwing.world import throwing_world

FAILURE_REWARD = -1000.0
# Failures grow with their constraint violation up to this cap; a broken candidate (NaN or inf in theta, or a
# reference that overflows) gets the capped reward, so that it never scores better than a failing one.
VIOLATION_CAP = 1e6
BROKEN_REWARD = FAILURE_REWARD * (1.0 + VIOLATION_CAP)
PAPER_BOUNDS = TaskBounds(("x", "y"), (-7.0, -5.0), (-1.0, 1.0))
HARDWARE_BOUNDS = TaskBounds(("x", "y"), (-1.5, -0.6), (-0.6, 0.6))
RELAXED_SPEED_LIMIT = 6.0  # rad/s on every joint in the "paper" variant


@dataclass(frozen=True)
class _Variant:
    bounds: TaskBounds
    execution_time: float
    start: tuple[float, ...]  # wind-up pose: arm bent forward over +x, at rest
    goal: tuple[float, ...]  # hand-designed throw: 7 joints + the release dimension
    goal_velocity: tuple[float, ...]


VARIANTS = {
    # Turned by 0.8 rad so that the backward throw heads for the paper's initial target (-3.5, -3.6).
    "paper": _Variant(
        PAPER_BOUNDS,
        0.6,
        (0.8, 0.6, 0.0, 1.4, 0.0, 0.9, 0.0),
        (0.8, -0.55, 0.0, -0.2, 0.0, -0.25, 0.0, 0.515),
        (0.0, -3.9, 0.0, -5.4, 0.0, -5.1, 0.0, 0.0),
    ),
    # Within the hardware speed limits: a slower swing, mostly from the wrist; lands near (-1.15, 0).
    "hardware": _Variant(
        HARDWARE_BOUNDS,
        1.2,
        (0.0, 0.4, 0.0, 1.2, 0.0, 0.9, 0.0),
        (0.0, 0.1, 0.0, 0.3, 0.0, -0.6, 0.0, 0.5),
        (0.0, -0.8, 0.0, -1.6, 0.0, -5.8, 0.0, 0.0),
    ),
}


@checked(
    variant=text("a variant name"),
    execution_time=optional(positive),
    duration=positive,
    n_weights=integer(2),
    release_threshold=number,
)
@dataclass(frozen=True)
class ThrowingConfig:
    """Everything that defines a throwing task; ``build()`` makes the task (also on Ray workers)."""

    variant: str = "paper"
    execution_time: float | None = None  # DMP execution time (s); None: the variant's
    duration: float = 2.0  # simulated time per throw (s)
    n_weights: int = 10
    release_threshold: float = 0.5
    start: tuple[float, ...] | None = None  # wind-up pose (7 joint values); None: the variant's

    def build(self) -> ThrowingRollouts:
        return ThrowingRollouts(self)


@dataclass(frozen=True)
class ThrowDetail:
    """One rollout: where the ball landed (None if it did not), when it was released, why it failed."""

    landing: tuple[float, float] | None
    release_time: float | None
    failure: str | None


class ThrowingRollouts(BatchedRollouts):
    """The PA-10 ball-throwing task; see the module documentation."""

    in_processes: ClassVar[bool] = False  # open loop: MuJoCo's rollouts on its own threads, here

    @checked(config=optional(instance(ThrowingConfig, "a ThrowingConfig")))
    def __init__(self, config: ThrowingConfig | None = None, **overrides) -> None:
        config = replace(config or ThrowingConfig(), **overrides)  # overrides change a given config too
        if config.variant not in VARIANTS:
            raise InputError(f"variant must be one of {sorted(VARIANTS)}, got {config.variant!r}")
        self.variant = VARIANTS[config.variant]
        self.config = config
        self.execution_time = (
            self.variant.execution_time if config.execution_time is None else config.execution_time
        )
        self.world = throwing_world()
        self.robot = self.world.robot
        model = self.model = self.world.model
        self.arm = self.robot.group("arm")
        self.bounds = self.variant.bounds
        self.speed_limits = (
            np.full(self.arm.size, RELAXED_SPEED_LIMIT)
            if config.variant == "paper"
            else self.arm.velocity.copy()
        )
        self.timestep = model.opt.timestep
        self.n_steps = round(config.duration / self.timestep)
        self.weld = model.equality(self.robot.group("release").equalities[0]).id
        self.ball = model.body("ball").id
        self.ball_radius = float(model.geom_size[model.body_geomadr[self.ball], 0])
        start = np.asarray(self.variant.start if config.start is None else config.start, dtype=float)
        if (
            start.shape != (self.arm.size,)
            or np.any(start < self.arm.lower)
            or np.any(start > self.arm.upper)
        ):
            raise InputError(
                f"start must be {self.arm.size} joint values within the arm's ranges, got {start}"
            )
        self.dmp = DMP(
            self.arm.size + 1,
            settings=DMPSettings(n_weights=config.n_weights),
            execution_time=self.execution_time,
            dt=self.timestep,
            start=np.append(start, 0.0),
        )
        self._initial_state = self._start_state(start)
        self._control_spec = mujoco.mjtState.mjSTATE_CTRL.value | mujoco.mjtState.mjSTATE_EQ_ACTIVE.value
        self._pool: rollout.Rollout | None = None
        self._datas: list[mujoco.MjData] = []
        self._outputs: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def n_params(self) -> int:
        """96 with the defaults: 8 DMP dimensions x (10 weights + goal + goal velocity)."""
        return self.dmp.n_params

    def _start_state(self, start: np.ndarray) -> np.ndarray:
        """The full physics state with the arm at rest in ``start`` and the ball in the hand."""
        model, data = self.model, self.world.data
        self.world.reset()
        data.qpos[self.arm.qpos_indices] = start
        data.ctrl[self.arm.actuator_indices] = start
        mujoco.mj_kinematics(model, data)
        holder = data.site("ball_holder")
        ball_address = model.jnt_qposadr[model.body_jntadr[self.ball]]
        data.qpos[ball_address : ball_address + 3] = holder.xpos
        data.qpos[ball_address + 3 : ball_address + 7] = quaternion.from_matrix(holder.xmat.reshape(3, 3))
        mujoco.mj_forward(model, data)
        state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS.value))
        mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
        return state

    def default_theta(self) -> np.ndarray:
        """A hand-designed throw (no forcing term): swing shoulder, elbow and wrist backwards over the top and
        let go while the hand rises. In the paper variant it lands near (-3.5, -3.6), the paper's initial
        throw; in the hardware variant near (-1.15, 0)."""
        dmp = DMP(
            self.dmp.n_dims,
            settings=DMPSettings(n_weights=self.config.n_weights),
            execution_time=self.execution_time,
            dt=self.timestep,
            start=self.dmp.start,
        )
        return dmp.configure(goal=self.variant.goal, goal_velocity=self.variant.goal_velocity).get_params()

    # -- building the controls -----------------------------------------------------------------------------

    def controls(self, thetas: np.ndarray):
        """Per candidate: the control array (n_steps, nu + 1) of joint targets and the weld switch, the reason
        it fails before simulation (or None), the release step (-1: never) and how far the reference
        violates its constraints (0 if it does not)."""
        with np.errstate(over="ignore", invalid="ignore"):  # overflowing references fail below, by name
            return self._controls(thetas)

    def _controls(self, thetas: np.ndarray):
        references = self.dmp.trajectories(thetas, run_time=self.config.duration, derivatives=0)
        joints = references.positions[:, 1:, : self.arm.size]  # the target for step k is the reference at k+1
        release_signal = references.positions[:, 1:, -1]
        released = release_signal >= self.config.release_threshold
        release_step = np.where(released.any(axis=1), released.argmax(axis=1), -1)
        controls = np.empty((len(thetas), self.n_steps, self.model.nu + 1))
        controls[:, :, : self.model.nu] = joints
        controls[:, :, -1] = (
            np.arange(self.n_steps)[None, :] < np.where(release_step < 0, self.n_steps, release_step)[:, None]
        )
        failures: list[str | None] = []
        violations = np.zeros(len(thetas))
        positions = references.positions[:, :, : self.arm.size]
        overshoot = np.maximum(self.arm.lower - positions.min(axis=1), positions.max(axis=1) - self.arm.upper)
        # The speeds the actuators are asked for: changes of the commanded positions per step.
        speeds = (
            np.abs(np.diff(references.positions[:, :, : self.arm.size], axis=1)).max(axis=1) / self.timestep
        )
        overspeed = speeds / self.speed_limits - 1.0
        shortfall = self.config.release_threshold - release_signal.max(axis=1)
        finite = np.isfinite(references.positions).all(axis=(1, 2))
        for i in range(len(thetas)):
            if not finite[i]:  # theta so large that the reference overflows
                failures.append("the reference overflows (theta too large)")
                violations[i] = VIOLATION_CAP
                continue
            reason, violations[i] = self._reference_failure(overshoot[i], overspeed[i], shortfall[i])
            failures.append(reason)
        return controls, failures, release_step, np.minimum(violations, VIOLATION_CAP)

    def _reference_failure(self, overshoot: np.ndarray, overspeed: np.ndarray, shortfall: float):
        """Why the reference fails (or None) and by how much it violates all its constraints together."""
        violation = float(
            np.maximum(overshoot, 0).sum() + np.maximum(overspeed, 0).sum() + max(shortfall, 0.0)
        )
        if shortfall > 0:
            return "never released: the release dimension never reaches the threshold", violation
        for j, joint in enumerate(self.arm.joints):
            if overshoot[j] > 0:
                return f"the reference leaves the range of joint {joint} by {overshoot[j]:.3g} rad", violation
            if overspeed[j] > 0:
                speed = (1.0 + overspeed[j]) * self.speed_limits[j]
                return (
                    f"the reference exceeds the speed limit of joint {joint}: {speed:.3g} > "
                    f"{self.speed_limits[j]:.3g} rad/s"
                ), violation
        return None, 0.0

    def feasible(self, thetas) -> np.ndarray:
        """Whether each theta's reference keeps the joint ranges and speed limits and releases the ball: the
        checks :meth:`evaluate` makes before it simulates, without a rollout (a NaN or inf is infeasible)."""
        thetas = np.array(thetas, dtype=float, ndmin=2)
        finite = np.isfinite(thetas).all(axis=1)
        feasible = np.zeros(len(thetas), dtype=bool)
        if finite.any():
            _, failures, _, _ = self.controls(thetas[finite])
            feasible[finite] = [failure is None for failure in failures]
        return feasible

    # -- evaluation ----------------------------------------------------------------------------------------

    def evaluate(self, thetas, taus, *, backend: str = "threads", nan: str = "raise") -> Evaluation:
        """Rewards (N,) and :class:`ThrowDetail` per rollout for thetas (N, 96) or (96,) and taus (N, 2) or
        (2,); the same inputs give the same results, bit for bit, on every backend.

        A theta with NaN or inf is bad input (``ValueError``) unless ``nan="penalize"``: then that candidate
        is a failed throw with the failure penalty and the rest of the batch is evaluated (what an optimiser
        that may propose broken candidates wants).
        """
        check_backend(backend)
        if nan not in ("raise", "penalize"):
            raise InputError(f"nan must be 'raise' or 'penalize', got {nan!r}")
        if nan == "penalize":
            thetas = np.array(thetas, dtype=float, ndmin=2)
            broken = ~np.isfinite(thetas).all(axis=1) if thetas.ndim == 2 else np.zeros(0, dtype=bool)
            if broken.any():
                return self._with_broken(thetas, taus, broken, backend)
        return super().evaluate(thetas, taus, backend=backend)

    def _with_broken(self, thetas: np.ndarray, taus, broken: np.ndarray, backend: str) -> Evaluation:
        """Evaluates the finite candidates and gives the broken ones the failure penalty, in order."""
        taus = self.bounds.check(taus, n=len(thetas))
        rewards = np.full(len(thetas), BROKEN_REWARD)
        details: list[ThrowDetail] = [ThrowDetail(None, None, "theta contains NaN or inf")] * len(thetas)
        good = np.flatnonzero(~broken)
        if good.size:
            evaluated = self.evaluate(thetas[good], taus[good], backend=backend)
            rewards[good] = evaluated.rewards
            for index, detail in zip(good, evaluated.details, strict=True):
                details[index] = detail
        return Evaluation(rewards, tuple(details))

    def evaluate_locally(self, thetas: np.ndarray, taus: np.ndarray) -> Evaluation:
        """:meth:`evaluate` in this process (MuJoCo's rollout threads), for checked inputs."""
        landings, release_times, failures, violations = self.throw(thetas)
        # Failures cost more the further the reference is from feasible, so optimisers find their way back.
        rewards = FAILURE_REWARD * (1.0 + violations)
        details = []
        for i, failure in enumerate(failures):
            if failure is None:
                rewards[i] = -float(np.sum((taus[i] - landings[i]) ** 2))
            details.append(
                ThrowDetail(
                    None if failure else (float(landings[i, 0]), float(landings[i, 1])),
                    release_times[i],
                    failure,
                )
            )
        return Evaluation(rewards, tuple(details))

    def throw(self, thetas: np.ndarray):
        """Simulates the throws: landing points (N, 2) (zeros where none), release times, failure reasons and
        constraint violations of the references."""
        controls, failures, release_step, violations = self.controls(thetas)
        run = [i for i, failure in enumerate(failures) if failure is None]
        landings = np.zeros((len(thetas), 2))
        if run:
            states, ball, touches = self._rollout(controls if len(run) == len(controls) else controls[run])
            for row, (failure, landing) in enumerate(
                self._landings(states, ball, touches, release_step[run])
            ):
                failures[run[row]] = failure
                if landing is not None:
                    landings[run[row]] = landing
        release_times = [None if step < 0 else float((step + 1) * self.timestep) for step in release_step]
        return landings, release_times, failures, violations

    def simulate(self, theta) -> tuple[np.ndarray | None, ThrowDetail]:
        """One throw, step by step: the joint positions ``qpos`` (n_steps, nq) of the whole model (arm and
        ball) and the throw's detail; None instead of the positions for a throw that fails before
        simulation."""
        theta = finite_array("theta", theta, ndim=1)
        controls, failures, release_step, _ = self.controls(theta[None])
        if failures[0] is not None:
            return None, ThrowDetail(None, None, failures[0])
        states, ball, touches = self._rollout(controls)
        ((failure, landing),) = self._landings(states, ball, touches, release_step)
        # The full physics state is time, then qpos (mj_getState's documented order).
        qpos = states[0, :, 1 : 1 + self.model.nq].copy()
        release = float((release_step[0] + 1) * self.timestep)
        return qpos, ThrowDetail(None if landing is None else tuple(map(float, landing)), release, failure)

    def _rollout(self, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """States (N, T, nstate), ball positions (N, T, 3) and ball-robot contact counts (N, T) per step."""
        threads = min(len(controls), os.cpu_count() or 1)
        if self._pool is None or len(self._datas) < threads:
            self.close()
            self._pool = rollout.Rollout(nthread=threads)
            self._datas = [mujoco.MjData(self.model) for _ in range(threads)]
        count = len(controls)
        if self._outputs is None or len(self._outputs[0]) != count:
            # Reused between calls of the same size: allocating ~20 MB per batch costs more than copying.
            self._outputs = (
                np.empty((count, self.n_steps, len(self._initial_state))),
                np.empty((count, self.n_steps, self.model.nsensordata)),
            )
        states, sensors = self._pool.rollout(
            self.model,
            self._datas,
            np.repeat(self._initial_state[None], count, axis=0),
            controls,
            control_spec=self._control_spec,
            initial_warmstart=np.zeros((count, self.model.nv)),  # independent of what a thread ran before
            state=self._outputs[0],
            sensordata=self._outputs[1],
        )
        return states, sensors[:, :, :3], sensors[:, :, 3]

    def _landings(self, states: np.ndarray, ball: np.ndarray, touches: np.ndarray, release_step: np.ndarray):
        """(failure, landing) per rollout from its states (N, T, nstate), ball positions (N, T, 3) and
        ball-robot contacts (N, T)."""
        steps = np.arange(states.shape[1])
        diverged = ~np.isfinite(states).all(axis=(1, 2))
        # After a bad acceleration MuJoCo resets the state, and time starts again from zero.
        reset = (np.abs(states[:, :, 0] - (steps + 1) * self.timestep) > 0.5 * self.timestep).any(axis=1)
        flying = steps[None, :] >= release_step[:, None]
        on_floor = flying & (ball[:, :, 2] <= self.ball_radius)
        first = on_floor.argmax(axis=1)
        # A ball that touches the robot between its release and its landing was hit (or caught) by the arm.
        hit = (
            flying
            & (steps[None, :] < np.where(on_floor.any(axis=1), first, len(steps))[:, None])
            & (touches > 0)
        )
        results = []
        for i, k in enumerate(first):
            if diverged[i]:
                results.append(("the simulation diverged (NaN)", None))
            elif reset[i]:
                results.append(
                    ("the simulation diverged (MuJoCo reset the state after a bad acceleration)", None)
                )
            elif hit[i].any():
                after = (hit[i].argmax() - release_step[i]) * self.timestep
                results.append((f"the ball touches the robot {after:.3f} s after the release", None))
            elif not on_floor[i, k]:
                results.append((f"the ball never lands within {self.config.duration:g} s", None))
            elif k == 0:
                results.append(("the ball touches the floor at the release", None))
            else:
                above = ball[i, k - 1, 2] - self.ball_radius
                fraction = above / (above - (ball[i, k, 2] - self.ball_radius))
                results.append((None, ball[i, k - 1, :2] + fraction * (ball[i, k, :2] - ball[i, k - 1, :2])))
        return results

    def close(self) -> None:
        """Shuts the rollout thread pool down now (otherwise it goes with the task)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
