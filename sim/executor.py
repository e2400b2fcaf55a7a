"""Executing motions on a simulated robot: every command passes through Ruckig.

An :class:`Executor` drives a set of joint groups (e.g. AILA's waist and right arm) and a gripper of a
:class:`~besman.sim.world.World`. Each control cycle (500 Hz by default) Ruckig (community edition, one
state-to-state update per cycle, never intermediate waypoints) moves the commanded joint state towards the
motion's target state while respecting each joint's velocity, acceleration and jerk limits from the robot
description; the commanded positions go to the position actuators, and the physics runs until the next
cycle. Because Ruckig always starts from the last commanded position, velocity and acceleration, motions
chain with continuous position, velocity and acceleration, and a motion can be pre-empted at any cycle.

Motions (one at a time, started with :meth:`Executor.start`, advanced by :meth:`Executor.tick`):

- :class:`FollowReference` - track a joint reference (positions, velocities, accelerations at the control
  rate), e.g. a DMP; built from movement primitives by :meth:`Executor.primitive_reference`, which starts
  the primitive in the current commanded state (the moving-goal DMP takes any start state) and turns
  Cartesian primitives into joint references by inverse kinematics with continuity.
- :class:`MoveTo` - a time-optimal jerk-limited move to a joint configuration (Ruckig's own trajectory).
- :class:`GripperMotion` - open or close the gripper; closing can require a grasp (both finger pads touching
  an object that moves with the hand).
- :class:`Stop` - brake to rest within the limits (what pre-emption does).

Faults (MuJoCo warnings, NaN, joints leaving their ranges), an unreachable Cartesian pose, a commanded state
that lags the reference, or a robot that cannot follow its commands end the motion as FAILED with a reason.
Every cycle is logged (time, commanded joint states) so that limits can be checked afterwards.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum

import mujoco
import numpy as np
import ruckig
from scipy.interpolate import CubicSpline

import besman.robots as robots
from besman.sim.faults import FaultMonitor
from besman.sim.world import World
from besman.skills import CartesianDMP, MovementPrimitive, Trajectory


class MotionStatus(Enum):
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


@dataclass(frozen=True)
class ExecutorConfig:
    """Control rate and tolerances.

    Attributes:
        control_period: seconds per control cycle (a multiple of the model's timestep).
        arrival_tolerance: joint error (rad or m) at which a motion's final state counts as reached.
        lag_tolerance: largest commanded-vs-reference difference before a reference counts as infeasible.
        following_tolerance: largest actual-vs-commanded joint difference before the robot counts as blocked.
        ik_position_tolerance, ik_orientation_tolerance: accuracy of the IK solutions of Cartesian references.
        ik_acceptance: largest remaining (position, orientation) error of a sample that still counts as
            reached (a joint at its limit can slow the convergence below the tolerance).
        ik_knot_period: seconds between the IK solutions that a Cartesian reference's spline joins.
        settle_cycles: cycles a motion waits at its goal for the robot to settle before it succeeds.
        range_tolerance: how far (rad or m) a reference may pass a joint range (commands are clipped to the
            range) before it is rejected.
        lookahead_cycles: how far ahead on a reference each cycle's Ruckig target lies.
        arrival_timeout: seconds the robot may take to reach a goal after its command got there.
    """

    control_period: float = 0.002
    arrival_tolerance: float = 0.01
    lag_tolerance: float = 0.2
    following_tolerance: float = 0.15
    ik_position_tolerance: float = 1e-7
    ik_orientation_tolerance: float = 1e-6
    ik_acceptance: tuple[float, float] = (1e-5, 1e-4)
    ik_knot_period: float = 0.01
    settle_cycles: int = 25
    range_tolerance: float = 0.02
    lookahead_cycles: int = 10
    arrival_timeout: float = 1.0


@dataclass
class Motion:
    """Base of motions: a name for logs and messages, a status and a message when it ends."""

    name: str
    status: MotionStatus = field(default=MotionStatus.RUNNING, init=False)
    message: str = field(default="", init=False)
    cycles: int = field(default=0, init=False)
    settled: int = field(default=0, init=False)  # consecutive cycles at the goal
    waited: int = field(default=0, init=False)  # cycles the command has been at the goal

    def finish(self, status: MotionStatus, message: str = "") -> MotionStatus:
        self.status, self.message = status, message
        return status


@dataclass
class FollowReference(Motion):
    """Track ``reference`` (positions/velocities/accelerations of the executor's joints, sampled at the
    control period), then hold its last state until the robot arrives."""

    reference: Trajectory = None  # type: ignore[assignment]


@dataclass
class MoveTo(Motion):
    """Go to ``target`` (joint positions of the executor's joints) and stop there."""

    target: np.ndarray = None  # type: ignore[assignment]


@dataclass
class GripperMotion(Motion):
    """Drive the gripper to ``opening`` (m per finger); with ``expect_grasp`` it fails unless it ends up
    holding ``grasp_object``."""

    opening: float = 0.0
    expect_grasp: bool = False
    grasp_object: str | None = None


@dataclass
class Stop(Motion):
    """Brake to rest within the limits."""


@dataclass(frozen=True)
class LogEntry:
    """One control cycle: sim time, commanded joint positions, velocities, accelerations, gripper command."""

    time: float
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    gripper: float


class Executor:
    """Streams Ruckig-smoothed commands to a world's robot; see the module documentation."""

    def __init__(
        self,
        world: World,
        groups: Sequence[str] = ("waist", "right_arm"),
        gripper: str | None = "right_gripper",
        config: ExecutorConfig = ExecutorConfig(),
    ) -> None:
        self.world, self.config = world, config
        robot = world.robot
        self.groups = tuple(groups)
        members = [robot.group(name) for name in self.groups]
        self.joints = tuple(j for g in members for j in g.joints)
        self.qpos_indices = np.concatenate([g.qpos_indices for g in members])
        self.actuator_indices = np.concatenate([g.actuator_indices for g in members])
        self.lower = np.concatenate([g.lower for g in members])
        self.upper = np.concatenate([g.upper for g in members])
        self.max_velocity = np.concatenate([g.velocity for g in members])
        self.max_acceleration = np.concatenate([g.acceleration for g in members])
        self.max_jerk = np.concatenate([g.jerk for g in members])
        self.site = members[-1].site
        self.gripper = robot.group(gripper) if gripper else None
        steps = config.control_period / world.model.opt.timestep
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise ValueError(
                f"control_period {config.control_period} is not a multiple of the timestep "
                f"{world.model.opt.timestep}"
            )
        self.substeps = round(steps)
        self.dofs = len(self.joints)
        self._otg = ruckig.Ruckig(self.dofs, config.control_period)
        self._input = ruckig.InputParameter(self.dofs)
        self._output = ruckig.OutputParameter(self.dofs)
        self._input.max_velocity = self.max_velocity.tolist()
        self._input.max_acceleration = self.max_acceleration.tolist()
        self._input.max_jerk = self.max_jerk.tolist()
        if self.gripper is not None:
            self._gripper_otg = ruckig.Ruckig(1, config.control_period)
            self._gripper_input = ruckig.InputParameter(1)
            self._gripper_output = ruckig.OutputParameter(1)
            self._gripper_input.max_velocity = [float(self.gripper.velocity[0])]
            self._gripper_input.max_acceleration = [float(self.gripper.acceleration[0])]
            self._gripper_input.max_jerk = [float(self.gripper.jerk[0])]
        self.monitor = FaultMonitor(world.model)
        self._scratch = mujoco.MjData(world.model)  # for planning checks that must not touch the simulation
        root = world.model.body_rootid[world.model.jnt_bodyid[world.model.joint(self.joints[0]).id]]
        self._robot_bodies = {
            world.model.body(b).name for b in range(world.model.nbody) if world.model.body_rootid[b] == root
        }
        self.log: list[LogEntry] = []
        self.motion: Motion | None = None
        self.sync()

    # -- state ---------------------------------------------------------------------------------------------

    def sync(self) -> None:
        """Takes the robot's current joint positions as the commanded state, at rest (after a reset)."""
        data = self.world.data
        self.position = data.qpos[self.qpos_indices].copy()
        self.velocity = np.zeros(self.dofs)
        self.acceleration = np.zeros(self.dofs)
        data.ctrl[self.actuator_indices] = self.position
        if self.gripper is not None:
            self.gripper_state = [float(data.ctrl[self.gripper.actuator_indices[0]]), 0.0, 0.0]
        self.monitor.reset(data)
        self.motion = None

    @property
    def time(self) -> float:
        return float(self.world.data.time)

    def measured_position(self) -> np.ndarray:
        return self.world.data.qpos[self.qpos_indices].copy()

    def full_qpos(self, joint_positions: np.ndarray) -> np.ndarray:
        """The world's current qpos with the executor's joints set to ``joint_positions``."""
        qpos = self.world.data.qpos.copy()
        qpos[self.qpos_indices] = joint_positions
        return qpos

    # -- motions -------------------------------------------------------------------------------------------

    def start(self, motion: Motion) -> Motion:
        """Makes ``motion`` the current one (the previous one is replaced where it stands)."""
        if isinstance(motion, FollowReference):
            reference = motion.reference
            if reference.positions.shape[1:] != (self.dofs,):
                raise ValueError(
                    f"reference for {self.dofs} joints expected, got {reference.positions.shape}"
                )
            # Commands are clipped to the ranges; a reference that goes clearly beyond them is wrong.
            excess = np.maximum(self.lower - reference.positions, reference.positions - self.upper).max(
                axis=0
            )
            if excess.max() > self.config.range_tolerance:
                joint = self.joints[int(excess.argmax())]
                motion.finish(
                    MotionStatus.FAILED, f"the reference leaves the range of {joint} by {excess.max():.3g}"
                )
            motion.reference = Trajectory(
                reference.times,
                np.clip(reference.positions, self.lower, self.upper),
                reference.velocities,
                reference.accelerations,
            )
        if isinstance(motion, MoveTo):
            motion.target = np.clip(np.asarray(motion.target, dtype=float), self.lower, self.upper)
        self.motion = motion
        return motion

    def stop(self) -> Motion:
        """Pre-empts the current motion with a smooth stop."""
        return self.start(Stop("stop"))

    def run(self, motion: Motion, timeout: float = 30.0, observe: Callable[[], None] | None = None) -> Motion:
        """Runs ``motion`` to its end (or ``timeout`` seconds of simulated time) and returns it; ``observe``
        is called after every control cycle."""
        self.start(motion)
        deadline = self.time + timeout
        while motion.status is MotionStatus.RUNNING:
            if self.time >= deadline:
                motion.finish(MotionStatus.FAILED, f"timed out after {timeout:g} s")
                break
            self.tick()
            if observe is not None:
                observe()
        return motion

    def solve_ik(
        self,
        position,
        orientation,
        *,
        initial: np.ndarray | None = None,
        restarts: int = 0,
        tolerances: tuple[float, float] = (1e-4, 1e-3),
    ) -> robots.IKResult:
        """Inverse kinematics of the executor's site over its joints, started from ``initial`` (default: the
        commanded position), the heavy slow joints taking a small share (weights = acceleration limits)."""
        start = self.position if initial is None else initial
        return robots.solve_ik(
            self.world.robot,
            self.groups,
            position,
            orientation,
            site=self.site,
            initial_qpos=self.full_qpos(start),
            restarts=restarts,
            position_tolerance=tolerances[0],
            orientation_tolerance=tolerances[1],
            joint_weights=self.max_acceleration,
        )

    def tick(self) -> MotionStatus:
        """One control cycle: command, simulate, check; returns the current motion's status."""
        motion = self.motion
        if motion is not None and motion.status is MotionStatus.RUNNING:
            motion.cycles += 1
            self._command(motion)
        self._simulate()
        if motion is None:
            return MotionStatus.SUCCEEDED
        fault = self.monitor.check(self.world.data)
        if fault is not None and motion.status is MotionStatus.RUNNING:
            motion.finish(MotionStatus.FAILED, f"simulation fault: {fault}")
        elif motion.status is MotionStatus.RUNNING:
            self._judge(motion)
        return motion.status

    # -- one cycle -----------------------------------------------------------------------------------------

    def _ruckig_step(
        self,
        position,
        velocity=None,
        acceleration=None,
        synchronize: bool = True,
        minimum_duration: float | None = None,
    ) -> ruckig.Result:
        """Advances the commanded state one cycle towards a target state (clipped to the limits), reached
        no sooner than ``minimum_duration`` from now, all joints together when ``synchronize``."""
        inputs = self._input
        inputs.control_interface = ruckig.ControlInterface.Position
        inputs.synchronization = ruckig.Synchronization.Time if synchronize else ruckig.Synchronization.No
        inputs.minimum_duration = minimum_duration
        inputs.current_position = self.position.tolist()
        inputs.current_velocity = self.velocity.tolist()
        inputs.current_acceleration = self.acceleration.tolist()
        clipped = np.clip(position, self.lower, self.upper)
        inputs.target_position = clipped.tolist()
        zeros = np.zeros(self.dofs)
        velocity, acceleration = self._feasible(
            zeros if velocity is None else velocity, zeros if acceleration is None else acceleration
        )
        at_limit = clipped != position  # a joint held at its limit stops there
        velocity[at_limit] = 0.0
        acceleration[at_limit] = 0.0
        inputs.target_velocity = velocity.tolist()
        inputs.target_acceleration = acceleration.tolist()
        return self._update(inputs)

    def _feasible(self, velocity: np.ndarray, acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clips a target velocity and acceleration to a state Ruckig accepts: within the limits, and with an
        acceleration that can be brought to zero before the velocity passes its limit (v + a^2 / 2j)."""
        velocity = np.clip(velocity, -0.99 * self.max_velocity, 0.99 * self.max_velocity)
        acceleration = np.clip(acceleration, -0.999 * self.max_acceleration, 0.999 * self.max_acceleration)
        headroom = np.sqrt(2.0 * self.max_jerk * np.maximum(0.99 * self.max_velocity - np.abs(velocity), 0.0))
        speeding_up = np.sign(acceleration) == np.sign(velocity)
        acceleration = np.where(speeding_up, np.clip(acceleration, -headroom, headroom), acceleration)
        return velocity, acceleration

    def _update(self, inputs: ruckig.InputParameter) -> ruckig.Result:
        try:
            result = self._otg.update(inputs, self._output)
        except ruckig.RuckigError:  # raised for inputs it rejects: the motion fails, nothing crashes
            return ruckig.Result.ErrorInvalidInput
        return self._apply(result)

    def _brake_step(self) -> ruckig.Result:
        inputs = self._input
        inputs.control_interface = ruckig.ControlInterface.Velocity
        inputs.synchronization = ruckig.Synchronization.No
        inputs.minimum_duration = None
        inputs.current_position = self.position.tolist()
        inputs.current_velocity = self.velocity.tolist()
        inputs.current_acceleration = self.acceleration.tolist()
        inputs.target_velocity = [0.0] * self.dofs
        inputs.target_acceleration = [0.0] * self.dofs
        return self._update(inputs)

    def _apply(self, result: ruckig.Result) -> ruckig.Result:
        if result in (ruckig.Result.Working, ruckig.Result.Finished):
            output = self._output
            self.position = np.array(output.new_position)
            self.velocity = np.array(output.new_velocity)
            self.acceleration = np.array(output.new_acceleration)
        return result

    def _command(self, motion: Motion) -> None:
        if isinstance(motion, FollowReference):
            # Aim at the reference a few cycles ahead, to be reached exactly then: Ruckig plans a smooth
            # approach of that state instead of a bang-bang chase of the next sample.
            reference = motion.reference
            last = len(reference.times) - 1
            k = min(motion.cycles + self.config.lookahead_cycles, last)
            if motion.cycles < last:
                duration = (k - motion.cycles + 1) * self.config.control_period
                result = self._ruckig_step(
                    reference.positions[k],
                    reference.velocities[k],
                    reference.accelerations[k],
                    synchronize=False,
                    minimum_duration=duration,
                )
            else:  # at or past its end, come to rest at the reference's last position
                result = self._ruckig_step(reference.positions[-1], synchronize=True)
        elif isinstance(motion, MoveTo):
            result = self._ruckig_step(motion.target)
        elif isinstance(motion, Stop):
            result = self._brake_step()
        else:  # a gripper motion: the arm holds still (braking first if it was moving)
            result = self._brake_step()
            self._gripper_step(motion.opening)
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            motion.finish(MotionStatus.FAILED, f"Ruckig could not compute a command ({result.name})")

    def _gripper_step(self, opening: float) -> None:
        inputs = self._gripper_input
        inputs.current_position = [self.gripper_state[0]]
        inputs.current_velocity = [self.gripper_state[1]]
        inputs.current_acceleration = [self.gripper_state[2]]
        inputs.target_position = [float(np.clip(opening, self.gripper.lower[0], self.gripper.upper[0]))]
        inputs.target_velocity = [0.0]
        inputs.target_acceleration = [0.0]
        self._gripper_otg.update(inputs, self._gripper_output)
        output = self._gripper_output
        self.gripper_state = [output.new_position[0], output.new_velocity[0], output.new_acceleration[0]]

    def _simulate(self) -> None:
        model, data = self.world.model, self.world.data
        data.ctrl[self.actuator_indices] = self.position
        if self.gripper is not None:
            data.ctrl[self.gripper.actuator_indices[0]] = self.gripper_state[0]
        for _ in range(self.substeps):
            mujoco.mj_step(model, data)
        self.log.append(
            LogEntry(
                float(data.time),
                self.position.copy(),
                self.velocity.copy(),
                self.acceleration.copy(),
                self.gripper_state[0] if self.gripper else 0.0,
            )
        )

    def _judge(self, motion: Motion) -> None:
        """Decides whether a running motion has succeeded or failed after this cycle."""
        config = self.config
        measured = self.measured_position()
        lagging = np.abs(measured - self.position)
        if lagging.max() > config.following_tolerance and not isinstance(motion, Stop):
            joint = self.joints[int(lagging.argmax())]
            motion.finish(
                MotionStatus.FAILED,
                f"joint {joint} cannot follow its command "
                f"({lagging.max():.3g} behind; blocked or in collision)",
            )
            return
        at_rest = np.abs(self.velocity).max() < 1e-6 and np.abs(self.acceleration).max() < 1e-6
        if isinstance(motion, FollowReference):
            reference = motion.reference
            k = min(motion.cycles, len(reference.times) - 1)
            lag = np.abs(self.position - reference.positions[k])
            if k < len(reference.times) - 1 and lag.max() > config.lag_tolerance:
                joint = self.joints[int(lag.argmax())]
                motion.finish(
                    MotionStatus.FAILED,
                    f"the reference is faster than the limits allow ({joint} lags {lag.max():.3g})",
                )
                return
            self._settle(motion, reference.positions[-1], done=motion.cycles >= len(reference.times) - 1)
        elif isinstance(motion, MoveTo):
            self._settle(motion, motion.target, done=at_rest)
        elif isinstance(motion, Stop):
            if at_rest:
                motion.finish(MotionStatus.SUCCEEDED, "stopped")
        elif isinstance(motion, GripperMotion):
            self._judge_gripper(motion)

    def _settle(self, motion: Motion, goal: np.ndarray, done: bool) -> None:
        """Succeeds after the command is at ``goal`` and the robot has stayed there for settle_cycles."""
        tolerance = self.config.arrival_tolerance
        arrived = (
            done
            and np.abs(self.position - goal).max() <= 1e-6
            and np.abs(self.measured_position() - goal).max() <= tolerance
        )
        motion.settled = motion.settled + 1 if arrived else 0
        if motion.settled >= self.config.settle_cycles:
            motion.finish(MotionStatus.SUCCEEDED, "reached")
        elif done and np.abs(self.position - goal).max() <= 1e-6:
            motion.waited += 1
            if motion.waited * self.config.control_period > self.config.arrival_timeout:
                error = np.abs(self.measured_position() - goal)
                joint = self.joints[int(error.argmax())]
                motion.finish(
                    MotionStatus.FAILED,
                    f"joint {joint} stays {error.max():.3g} from its goal (blocked or in contact)",
                )

    def _judge_gripper(self, motion: GripperMotion) -> None:
        data = self.world.data
        fingers = data.qvel[self.gripper_dofs()]
        commanded_done = abs(self.gripper_state[0] - motion.opening) < 1e-9 or (
            motion.opening <= self.gripper.lower[0] + 1e-9 and abs(self.gripper_state[1]) < 1e-9
        )
        if not commanded_done or np.abs(fingers).max() > 1e-3:
            motion.settled = 0
            return
        motion.settled += 1
        if motion.settled < self.config.settle_cycles:
            return
        if motion.expect_grasp and not self.holds(motion.grasp_object):
            motion.finish(MotionStatus.FAILED, "the fingers closed on nothing")
        else:
            motion.finish(MotionStatus.SUCCEEDED, "fingers settled")

    # -- the gripper and grasps ----------------------------------------------------------------------------

    def gripper_dofs(self) -> np.ndarray:
        return self.gripper.dof_indices

    def pad_geoms(self) -> tuple[int, int]:
        """The finger pad geoms of the executor's gripper (the collision geoms of its finger bodies)."""
        model = self.world.model
        bodies = [model.jnt_bodyid[model.joint(name).id] for name in self.gripper.joints]
        return tuple(int(np.flatnonzero(model.geom_bodyid == body)[0]) for body in bodies)

    def touching(self, name: str) -> tuple[bool, bool]:
        """Whether each finger pad touches the object ``name``."""
        model, data = self.world.model, self.world.data
        target = model.body(name).id
        pads = self.pad_geoms()
        touch = [False, False]
        for contact in data.contact[: data.ncon]:
            geoms = (contact.geom1, contact.geom2)
            for i, pad in enumerate(pads):
                if pad in geoms:
                    other = geoms[1] if geoms[0] == pad else geoms[0]
                    touch[i] |= model.geom_bodyid[other] == target
        return touch[0], touch[1]

    def holds(self, name: str | None) -> bool:
        """Both pads touch the object and it moves with the hand (relative speed below 2 cm/s)."""
        if name is None:
            return False
        if not all(self.touching(name)):
            return False
        model, data = self.world.model, self.world.data
        velocity = np.empty(6)
        hand = model.site(self.gripper.site).id
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, model.body(name).id, velocity, 0)
        site_velocity = np.empty(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, hand, site_velocity, 0)
        return bool(np.linalg.norm(velocity[3:] - site_velocity[3:]) < 0.02)

    # -- references from primitives ------------------------------------------------------------------------

    def primitive_reference(
        self, primitive: MovementPrimitive, *, start: np.ndarray | None = None, max_slowdown: float = 4.0
    ) -> Trajectory:
        """The joint reference of a primitive, started in the current commanded state (or at rest in the
        joint configuration ``start``, to plan ahead).

        Joint-space primitives must drive exactly the executor's joints (their DMP has that many
        dimensions). Cartesian primitives start at the pose of the executor's site at rest and are converted
        sample by sample by inverse kinematics started from the previous sample's solution; an unreachable
        sample raises ``ValueError`` with the time and remaining error.

        A reference faster than the joints' velocity, acceleration or jerk limits is slowed down by
        lengthening the DMP's execution time (which keeps the path) by the factor the worst joint needs,
        up to ``max_slowdown`` in all; the primitive's DMP keeps the new execution time.
        """
        dmp = primitive.dmp
        if not isinstance(dmp, CartesianDMP) and dmp.n_dims != self.dofs:
            raise ValueError(
                f"primitive {primitive.name!r} has {dmp.n_dims} dimensions; the executor drives "
                f"{self.dofs} joints ({', '.join(self.joints)})"
            )
        if start is None:
            state = (self.position, self.velocity, self.acceleration)
        else:
            state = (np.asarray(start, dtype=float), np.zeros(self.dofs), np.zeros(self.dofs))
        total = 1.0
        while True:
            reference = self._reference(dmp, *state)
            factor = self.slowdown(reference)
            if factor <= 1.0 or total * factor > max_slowdown:
                return reference
            total *= factor * 1.02
            dmp.execution_time = dmp.execution_time * factor * 1.02

    def _reference(
        self, dmp, position: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray
    ) -> Trajectory:
        if isinstance(dmp, CartesianDMP):
            return self._cartesian_reference(dmp, position)
        dmp.configure(
            start=position,
            start_velocity=velocity,
            start_acceleration=acceleration,
            dt=self.config.control_period,
        )
        return dmp.trajectory()

    def slowdown(self, reference: Trajectory) -> float:
        """How much slower a reference must run to respect every limit (1 if it already does)."""
        jerk = np.abs(np.diff(reference.accelerations, axis=0)).max(axis=0) / self.config.control_period
        return float(
            max(
                1.0,
                (np.abs(reference.velocities).max(axis=0) / self.max_velocity).max(),
                np.sqrt(np.abs(reference.accelerations).max(axis=0) / self.max_acceleration).max(),
                np.cbrt(jerk / self.max_jerk).max(),
            )
        )

    def _cartesian_reference(self, dmp: CartesianDMP, start: np.ndarray) -> Trajectory:
        """Joint reference of a Cartesian DMP: IK at knots every ``ik_knot_period`` (each started from the
        previous knot's solution), joined by a clamped cubic spline (the primitive starts and ends at rest)
        whose derivatives are the reference's velocities and accelerations, free of the noise that
        differencing IK solutions would amplify."""
        period = self.config.control_period
        pose = robots.forward_kinematics(self.world.robot, self.full_qpos(start), self.site)
        dmp.position.configure(start=pose.position, start_velocity=0.0, start_acceleration=0.0, dt=period)
        dmp.start_orientation = pose.quaternion
        dmp.start_angular_velocity = np.zeros(3)
        cartesian = dmp.trajectory()
        stride = max(1, round(self.config.ik_knot_period / period))
        knots = np.unique(np.r_[np.arange(0, len(cartesian.times), stride), len(cartesian.times) - 1])
        joints = np.empty((len(knots), self.dofs))
        accepted_position, accepted_orientation = self.config.ik_acceptance
        tolerances = (self.config.ik_position_tolerance, self.config.ik_orientation_tolerance)
        for row, k in enumerate(knots):
            previous = joints[row - 1] if row else start
            result = self.solve_ik(
                cartesian.positions[k], cartesian.orientations[k], initial=previous, tolerances=tolerances
            )
            if result.position_error > accepted_position or result.orientation_error > accepted_orientation:
                raise ValueError(
                    f"unreachable pose at t={cartesian.times[k]:.3f} s of the primitive: {result.message}"
                )
            joints[row] = result.qpos
        spline = CubicSpline(cartesian.times[knots], joints, axis=0, bc_type="clamped")
        positions = np.clip(spline(cartesian.times), self.lower, self.upper)
        return Trajectory(cartesian.times, positions, spline(cartesian.times, 1), spline(cartesian.times, 2))

    def collisions(self, joint_positions: np.ndarray, allowed: Sequence[str] = ()) -> list[str]:
        """Contacts the robot would have with the executor's joints at ``joint_positions`` and everything else
        as it is now: "body1/body2" for each pair, except pairs with a body named in ``allowed``."""
        model, scratch = self.world.model, self._scratch
        scratch.qpos[:] = self.full_qpos(joint_positions)
        mujoco.mj_kinematics(model, scratch)
        mujoco.mj_collision(model, scratch)
        found = []
        for contact in scratch.contact[: scratch.ncon]:
            bodies = [model.body(model.geom_bodyid[g]).name for g in (contact.geom1, contact.geom2)]
            if contact.dist < 0 and set(bodies) & self._robot_bodies and not set(bodies) & set(allowed):
                found.append("/".join(bodies))
        return found


RANGE_SLACK = 1e-3  # rad or m


def limit_violations(log: Sequence[LogEntry], executor: Executor, tolerance: float = 1e-6) -> list[str]:
    """Checks a command log against the executor's limits; returns one message per violated limit.

    Checked per joint: the commanded velocity and acceleration, the jerk (change of the commanded
    acceleration per cycle), the mean velocity over each cycle (change of the commanded position), and the
    range, up to ``RANGE_SLACK``: Ruckig aims at targets inside the range but may pass a limit by a fraction
    of a milliradian on the way (the position actuators clip their command to the range anyway).
    """
    if len(log) < 2:
        return []
    period = executor.config.control_period
    positions = np.array([entry.position for entry in log])
    velocities = np.array([entry.velocity for entry in log])
    accelerations = np.array([entry.acceleration for entry in log])
    checks = [
        (
            "range",
            np.maximum(executor.lower - positions, positions - executor.upper),
            np.full(executor.dofs, RANGE_SLACK),
        ),
        ("velocity", np.abs(velocities), executor.max_velocity),
        ("mean velocity", np.abs(np.diff(positions, axis=0)) / period, executor.max_velocity),
        ("acceleration", np.abs(accelerations), executor.max_acceleration),
        ("jerk", np.abs(np.diff(accelerations, axis=0)) / period, executor.max_jerk),
    ]
    problems = []
    for name, values, limits in checks:
        excess = values - limits * (1.0 + tolerance) - tolerance
        if excess.max() > 0:
            joint = executor.joints[int(np.unravel_index(excess.argmax(), excess.shape)[1])]
            problems.append(f"{name} limit of {joint} exceeded by {excess.max():.3g}")
    return problems
