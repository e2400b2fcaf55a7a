"""Executing motions on a simulated robot: every command passes through Ruckig, every cycle is checked.

An :class:`Executor` drives an :class:`~besman.sim.arm.Arm` (e.g. AILA's waist and right arm) and a gripper
of a :class:`~besman.sim.world.World`. Each control cycle (500 Hz by default) the current
:mod:`motion <besman.sim.motions>` advances the commanded joint state through a Ruckig stream
(:mod:`besman.sim.streaming`), the commanded positions go to the position actuators, the physics runs until
the next cycle, and the motion judges the outcome. Faults (MuJoCo warnings, NaN, joints leaving their
ranges; :mod:`besman.sim.faults`) end the motion as FAILED with a reason. Every cycle's commanded state is
logged so that the limits can be checked afterwards (:func:`limit_violations`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from besman.sim.arm import Arm
from besman.sim.command_log import CommandLog
from besman.sim.faults import FaultMonitor
from besman.sim.hand import Hand
from besman.sim.motions import Chunk, Motion, MotionStatus, Stop
from besman.sim.references import ReferenceSettings
from besman.sim.streaming import WORKING, JerkLimitedStream
from besman.sim.world import World
from besman.skills.errors import InputError


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
        steps = config.control_period / world.model.opt.timestep
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise InputError(
                f"control_period {config.control_period} is not a multiple of the timestep "
                f"{world.model.opt.timestep}"
            )
        self.substeps = round(steps)
        self.arm = Arm(world, groups)
        arm = self.arm
        self.stream = JerkLimitedStream(
            arm.lower, arm.upper, arm.max_velocity, arm.max_acceleration, arm.max_jerk, config.control_period
        )
        group = world.robot.group(gripper) if gripper else None
        self.hand = Hand(world, group) if group is not None else None
        # The fingers are coupled and driven by one actuator: one commanded opening for both.
        self.gripper_stream = (
            JerkLimitedStream(
                group.lower[:1],
                group.upper[:1],
                group.velocity[:1],
                group.acceleration[:1],
                group.jerk[:1],
                config.control_period,
            )
            if group is not None
            else None
        )
        self._gripper_actuator = int(group.actuator_indices[0]) if group is not None else None
        self._finger_dofs = group.dof_indices if group is not None else None
        self.reference_settings = ReferenceSettings(
            period=config.control_period,
            ik_tolerances=(config.ik_position_tolerance, config.ik_orientation_tolerance),
            ik_acceptance=config.ik_acceptance,
            knot_period=config.ik_knot_period,
        )
        self.monitor = FaultMonitor(world.model)
        self.log = CommandLog(self.arm.dofs)
        self.motion: Motion | None = None
        self.sync()

    # -- state ---------------------------------------------------------------------------------------------

    def sync(self) -> None:
        """Takes the robot's current joint positions as the commanded state, at rest (after a reset)."""
        data = self.world.data
        self.stream.reset(self.arm.measured())
        data.ctrl[self.arm.actuator_indices] = self.stream.position
        if self.gripper_stream is not None:
            self.gripper_stream.reset([data.ctrl[self._gripper_actuator]])
        self.monitor.reset(data)
        self.motion = None

    @property
    def time(self) -> float:
        return float(self.world.data.time)

    @property
    def position(self) -> np.ndarray:
        """The commanded joint positions."""
        return self.stream.position

    @property
    def velocity(self) -> np.ndarray:
        return self.stream.velocity

    @property
    def acceleration(self) -> np.ndarray:
        return self.stream.acceleration

    @property
    def gripper_opening(self) -> float | None:
        """The commanded finger opening (m), None without a gripper."""
        return None if self.gripper_stream is None else float(self.gripper_stream.position[0])

    def measured_position(self) -> np.ndarray:
        return self.arm.measured().copy()

    # -- motions -------------------------------------------------------------------------------------------

    def start(self, motion: Motion) -> Motion:
        """Makes ``motion`` the current one (the previous one is replaced where it stands); a motion that
        cannot start raises (e.g. an :class:`~besman.skills.errors.InputError` for an unreachable pose)."""
        motion.begin(self)
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

    def advance(self, cycles: int) -> MotionStatus:
        """Runs ``cycles`` control cycles (e.g. those between two ticks of a behaviour tree) as one chunk
        and returns the motion's status.

        The motion's commands for the whole chunk are computed first (they never depend on measurements),
        then the physics steps through them back to back (MuJoCo's data stays warm in the cache), then the
        motion judges the chunk's cycles in order. A motion that ends inside a chunk has had its commands
        run to the chunk's end: the same commands for a success (it holds at its goal), at most one chunk
        more of its motion for a failure. Faults are checked at the chunk's end: warnings, NaN and runaway
        speeds persist once they occur, so none is missed, and a motion that ended on a faulty state fails
        with the fault."""
        motion = self.motion
        if motion is None or motion.status is not MotionStatus.RUNNING:
            self._hold(cycles)
            return MotionStatus.SUCCEEDED if motion is None else motion.status
        first, commands, stream = motion.cycles + 1, [], self.stream
        # Arm motions leave the gripper where it is: its command is the same all chunk long.
        gripper_moves = motion.moves_gripper
        grippers = []
        for _ in range(cycles):
            motion.cycles += 1
            result = motion.command(self)
            if result not in WORKING:
                motion.finish(MotionStatus.FAILED, f"Ruckig could not compute a command ({result.name})")
                break
            commands.append(stream.state_lists())
            if gripper_moves:
                grippers.append(self.gripper_stream.state_lists())
        if commands:
            states = np.array(commands)
            gripper = np.array(grippers) if gripper_moves else self._gripper_as_is(len(commands))
            measured, fingers = self._simulate(states, gripper, record_fingers=gripper_moves)
        if len(commands) < cycles:
            self._hold(cycles - len(commands))  # after a failed command the arm holds its last one
        if motion.status is MotionStatus.RUNNING:  # every cycle was commanded
            motion.judge(self, Chunk(first, states, measured, gripper if gripper_moves else None, fingers))
            fault = self.monitor.check(self.world.data)
            if fault is not None:  # a judgement on a faulty state does not count
                motion.finish(MotionStatus.FAILED, f"simulation fault: {fault}")
        return motion.status

    def tick(self) -> MotionStatus:
        """One control cycle: command, simulate, judge, check for faults; returns the motion's status."""
        return self.advance(1)

    def _simulate(
        self, states: np.ndarray, gripper: np.ndarray | None, record_fingers: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Steps the physics through commanded arm states (n, 3, dofs) and gripper states (n, 3, 1; None
        without a gripper), logging each cycle; returns the arm's measured joint positions after each cycle
        and (if asked) the fingers' velocities."""
        model, data, arm = self.world.model, self.world.data, self.arm
        ctrl, qpos, qvel, step = data.ctrl, data.qpos, data.qvel, mujoco.mj_step
        actuators, joints, fingers_at = arm.actuator_indices, arm.qpos_indices, self._finger_dofs
        gripper_actuator, substeps, rows = self._gripper_actuator, range(self.substeps), len(states)
        openings = np.zeros(rows) if gripper is None else gripper[:, 0, 0]
        times, measured = np.empty(rows), np.empty((rows, arm.dofs))
        fingers = np.empty((rows, len(fingers_at))) if record_fingers else None
        for row in range(rows):
            ctrl[actuators] = states[row, 0]
            if gripper is not None:
                ctrl[gripper_actuator] = openings[row]
            for _ in substeps:
                step(model, data)
            times[row] = data.time
            measured[row] = qpos[joints]
            if fingers is not None:
                fingers[row] = qvel[fingers_at]
        self.log.append(times, states, openings)
        return measured, fingers

    def _gripper_as_is(self, cycles: int) -> np.ndarray | None:
        """The gripper's commanded state repeated for ``cycles`` cycles (None without a gripper)."""
        if self.hand is None:
            return None
        return np.repeat([self.gripper_stream.state_lists()], cycles, axis=0)

    def _hold(self, cycles: int) -> None:
        """``cycles`` cycles with the commands as they are."""
        states = np.repeat([self.stream.state_lists()], cycles, axis=0)
        self._simulate(states, self._gripper_as_is(cycles))


RANGE_SLACK = 1e-3  # rad or m


def limit_violations(log: CommandLog, executor: Executor, tolerance: float = 1e-6) -> list[str]:
    """Checks a command log against the executor's limits; returns one message per violated limit.

    Checked per joint: the commanded velocity and acceleration, the jerk (change of the commanded
    acceleration per cycle), the mean velocity over each cycle (change of the commanded position), and the
    range, up to ``RANGE_SLACK``: Ruckig aims at targets inside the range but may pass a limit by a fraction
    of a milliradian on the way (the position actuators clip their command to the range anyway).
    """
    if len(log) < 2:
        return []
    arm, period = executor.arm, executor.config.control_period
    positions, velocities, accelerations = log.positions, log.velocities, log.accelerations
    checks = [
        ("range", np.maximum(arm.lower - positions, positions - arm.upper), np.full(arm.dofs, RANGE_SLACK)),
        ("velocity", np.abs(velocities), arm.max_velocity),
        ("mean velocity", np.abs(np.diff(positions, axis=0)) / period, arm.max_velocity),
        ("acceleration", np.abs(accelerations), arm.max_acceleration),
        ("jerk", np.abs(np.diff(accelerations, axis=0)) / period, arm.max_jerk),
    ]
    problems = []
    for name, values, limits in checks:
        excess = values - limits * (1.0 + tolerance) - tolerance
        if excess.max() > 0:
            joint = arm.joints[int(np.unravel_index(excess.argmax(), excess.shape)[1])]
            problems.append(f"{name} limit of {joint} exceeded by {excess.max():.3g}")
    return problems
