"""Executing motions on a simulated robot: every command passes through Ruckig, every cycle is checked.

An :class:`Executor` drives the arms of a :class:`~besman.sim.world.World`'s robot that its description
defines (e.g. AILA's waist and right arm with the right gripper; a UR5e with its Robotiq), each an
:class:`~besman.sim.arm.Arm` and a gripper with Ruckig streams of their own. Each control cycle (500 Hz by
default) the current :mod:`motion <besman.sim.motions>` advances the commanded joint state through a Ruckig
stream (:mod:`besman.sim.streaming`), the commanded positions go to the position actuators, the physics runs
until the next cycle, and the motion judges the outcome. Faults (MuJoCo warnings, NaN, joints leaving their
ranges; :mod:`besman.sim.faults`) end the motion as FAILED with a reason. Every cycle's commanded state is
logged so that the limits can be checked afterwards (:func:`limit_violations`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from besman.core.errors import InputError, UnknownNameError
from besman.core.validation import (
    CALLABLE,
    checked,
    instance,
    integer,
    items,
    optional,
    positive,
    text,
)
from besman.sim.arm import Arm
from besman.sim.command_log import CommandLog
from besman.sim.executor_config import ExecutorConfig
from besman.sim.faults import FaultMonitor
from besman.sim.hand import Hand
from besman.sim.motions import Chunk, Motion, MotionStatus, Stop
from besman.sim.references import ReferenceSettings
from besman.sim.streaming import WORKING, JerkLimitedStream
from besman.sim.world import World

# The longest chunk :meth:`Executor.run` runs (0.1 s at 500 Hz): what a failure can run on past its cycle.
RUN_CHUNK = 50


class Executor:
    """Streams Ruckig-smoothed commands to a world's robot; see the module documentation."""

    @checked(
        world=instance(World, "a World (sim.tabletop_world)"),
        arms=optional(instance(str | list | tuple, "an arm's name or a list of them")),
        config=instance(ExecutorConfig, "an ExecutorConfig"),
        groups=optional(items(text("a joint group name"))),
    )
    def __init__(
        self,
        world: World,
        arms: str | Sequence[str] | None = None,
        config: ExecutorConfig = ExecutorConfig(),
        *,
        groups: Sequence[str] | None = None,
    ) -> None:
        """Drives ``arms`` of the world's robot (names from its description; default: its first arm, alone).
        The first arm is this executor's; the others run in lockstep with it (:meth:`arm_executor`). With
        several arms, the groups they share (AILA's waist) are held where they are; ``groups`` overrides the
        joint groups this executor's arm moves."""
        names = [arms] if isinstance(arms, str) else list(arms or [world.robot.arm().name])
        if len(set(names)) != len(names):
            raise InputError(f"arms repeat: {', '.join(names)}")
        robot_arms = [world.robot.arm(name) for name in names]
        shared = {
            group
            for arm in robot_arms
            for group in arm.groups
            if sum(group in a.groups for a in robot_arms) > 1
        }
        self.world, self.config, self.name = world, config, names[0]
        steps = config.control_period / world.model.opt.timestep
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise InputError(
                f"control_period {config.control_period} is not a multiple of the timestep "
                f"{world.model.opt.timestep}"
            )
        self.substeps = round(steps)
        own = [group for group in robot_arms[0].groups if group not in shared] if groups is None else groups
        self.arm = Arm(world, names[0], own)
        arm = self.arm
        self.stream = JerkLimitedStream(
            arm.lower, arm.upper, arm.max_velocity, arm.max_acceleration, arm.max_jerk, config.control_period
        )
        # Seconds of commanded velocity added to each position command (see the robot description).
        self._lead = np.zeros(arm.dofs)
        if world.robot.description.velocity_feedforward:
            model, actuators = world.model, arm.actuator_indices
            self._lead = -model.actuator_biasprm[actuators, 2] / model.actuator_gainprm[actuators, 0]
        gripper = arm.gripper
        self.hand = Hand(world, arm.robot_arm) if gripper is not None else None
        # One commanded opening (m per finger) for the gripper, sent as its actuator's command.
        self.gripper_stream = (
            JerkLimitedStream(
                [gripper.lower],
                [gripper.upper],
                [gripper.limits.velocity],
                [gripper.limits.acceleration],
                [gripper.limits.jerk],
                config.control_period,
            )
            if gripper is not None
            else None
        )
        self._finger_joints = self.hand.fingers.qpos_indices if gripper is not None else None
        self.reference_settings = ReferenceSettings(
            period=config.control_period,
            ik_tolerances=(config.ik_position_tolerance, config.ik_orientation_tolerance),
            ik_acceptance=config.ik_acceptance,
            knot_period=config.ik_knot_period,
        )
        self.monitor = FaultMonitor(world.model)
        self.log = CommandLog(self.arm.dofs)
        self.motion: Motion | None = None
        self.companions: dict[str, Executor] = {  # the other arms, run in lockstep
            arm.name: Executor(world, arm.name, config, groups=[g for g in arm.groups if g not in shared])
            for arm in robot_arms[1:]
        }
        self.sync()

    # -- state ---------------------------------------------------------------------------------------------

    def sync(self) -> None:
        """Takes the robot's current joint positions as the commanded state, at rest (after a reset)."""
        data = self.world.data
        self.stream.reset(self.arm.measured())
        data.ctrl[self.arm.actuator_indices] = self.stream.position
        if self.gripper_stream is not None:
            gripper = self.arm.gripper
            self.gripper_stream.reset([gripper.opening_for(data.ctrl[gripper.actuators[0]])])
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
        """The commanded opening (m per finger), None without a gripper."""
        return None if self.gripper_stream is None else float(self.gripper_stream.position[0])

    def measured_position(self) -> np.ndarray:
        return self.arm.measured().copy()

    # -- motions -------------------------------------------------------------------------------------------

    @checked(motion=instance(Motion, "a Motion (sim.motions)"))
    def start(self, motion: Motion) -> Motion:
        """Makes ``motion`` the current one (the previous one is replaced where it stands); a motion that
        cannot start raises (e.g. an :class:`~besman.core.errors.InputError` for an unreachable pose)."""
        motion.begin(self)
        self.motion = motion
        return motion

    def stop(self) -> Motion:
        """Pre-empts the current motion with a smooth stop."""
        return self.start(Stop("stop"))

    @checked(motion=instance(Motion, "a Motion (sim.motions)"), timeout=positive, observe=optional(CALLABLE))
    def run(self, motion: Motion, timeout: float = 30.0, observe: Callable[[], None] | None = None) -> Motion:
        """Runs ``motion`` to its end (or ``timeout`` seconds of simulated time) and returns it; ``observe``
        is called after every control cycle.

        Without ``observe``, the cycles run in chunks (:meth:`advance`) inside which no motion of the arms
        can succeed (``Motion.cycles_before_success``; at most :data:`RUN_CHUNK` cycles): a success ends on
        the same cycle, in the same state, as it does cycle by cycle, at about half the cost. A failure is
        decided on its own cycle (``Motion.ended``), but the physics has run on to the chunk's end, and
        faults are checked at chunk ends."""
        self.start(motion)
        deadline = self.time + timeout
        members = (self, *self.companions.values())
        while motion.status is MotionStatus.RUNNING:
            left = round((deadline - self.time) / self.config.control_period)
            if left <= 0:
                motion.finish(MotionStatus.FAILED, f"timed out after {timeout:g} s")
                break
            if observe is not None:
                self.tick()
                observe()
                continue
            motions = [member.motion for member in members if member.motion is not None]
            needed = [
                m.cycles_before_success(self.config) for m in motions if m.status is MotionStatus.RUNNING
            ]
            self.advance(min(RUN_CHUNK, left, *needed))
        return motion

    @checked(cycles=integer(0))
    def advance(self, cycles: int) -> MotionStatus:
        """Runs ``cycles`` control cycles (e.g. those between two ticks of a behaviour tree) as one chunk
        and returns the motion's status; the other arms (:meth:`arm_executor`) run the same cycles in
        lockstep.

        Each arm's motion computes its commands for the whole chunk first (they never depend on
        measurements), then the physics steps through them back to back (MuJoCo's data stays warm in the
        cache), then each motion judges the chunk's cycles in order. A motion that ends inside a chunk has
        had its commands run to the chunk's end: the same commands for a success (it holds at its goal), at
        most one chunk more of its motion for a failure. Faults are checked at the chunk's end: warnings,
        NaN and runaway speeds persist once they occur, so none is missed, and a motion that ended on a
        faulty state fails with the fault."""
        members = (self, *self.companions.values())
        plans = [member._commands(cycles) for member in members]
        results = _simulate(self.world, self.substeps, members, plans)
        for member, plan, (measured, fingers) in zip(members, plans, results, strict=True):
            member._judge(plan, measured, fingers)
        return self.motion.status if self.motion is not None else MotionStatus.SUCCEEDED

    @property
    def arms(self) -> dict[str, Executor]:
        """This executor and the other arms it runs in lockstep, by name."""
        return {self.name: self, **self.companions}

    def arm_executor(self, name: str | None) -> Executor:
        """The executor of arm ``name`` (None: this one)."""
        if name is None or name == self.name:
            return self
        if name not in self.companions:
            raise UnknownNameError(f"no arm {name!r} in this run; arms: {', '.join(self.arms)}")
        return self.companions[name]

    def tick(self) -> MotionStatus:
        """One control cycle: command, simulate, judge, check for faults; returns the motion's status."""
        return self.advance(1)

    def _commands(self, cycles: int) -> _Commands:
        """This arm's commands for the next ``cycles`` cycles: its motion's, held after a motion that
        failed to command (or with no motion running)."""
        motion = self.motion
        running = motion is not None and motion.status is MotionStatus.RUNNING
        gripper_moves = running and motion.moves_gripper
        commands, grippers = [], []
        if running:
            stream = self.stream
            for _ in range(cycles):
                motion.cycles += 1
                result = motion.command(self)
                if result not in WORKING:
                    motion.finish(
                        MotionStatus.FAILED,
                        f"Ruckig could not compute a command for arm {self.name!r}: "
                        + stream.refusal(self.arm.joints),
                    )
                    break
                commands.append(stream.state_lists())
                if gripper_moves:
                    grippers.append(self.gripper_stream.state_lists())
        judged = running and motion.status is MotionStatus.RUNNING  # every cycle was commanded
        held = cycles - len(commands)  # after a failed command the arm holds its last one
        states = np.array(commands + [self.stream.state_lists()] * held)
        # Arm motions leave the gripper where it is: its command is the same all chunk long.
        gripper = np.array(grippers) if gripper_moves and judged else self._gripper_as_is(cycles)
        return _Commands(
            motion if judged else None,
            motion.cycles - cycles + 1 if judged else 0,
            states,
            gripper,
            gripper_moves and judged,
        )

    def _judge(self, plan: _Commands, measured: np.ndarray, fingers: np.ndarray | None) -> None:
        motion = plan.motion
        if motion is None:
            return
        motion.judge(
            self,
            Chunk(plan.first, plan.states, measured, plan.gripper if plan.gripper_moves else None, fingers),
        )
        fault = self.monitor.check(self.world.data)
        if fault is not None:  # a judgement on a faulty state does not count
            motion.finish(MotionStatus.FAILED, f"simulation fault: {fault}")

    def _gripper_as_is(self, cycles: int) -> np.ndarray | None:
        """The gripper's commanded state repeated for ``cycles`` cycles (None without a gripper)."""
        if self.hand is None:
            return None
        return np.repeat([self.gripper_stream.state_lists()], cycles, axis=0)


@dataclass(frozen=True)
class _Commands:
    """One arm's commands for a chunk: states (n, 3, dofs), gripper states (n, 3, 1; None without a
    gripper), and the motion that judges them (None when nothing is to be judged) from its cycle ``first``."""

    motion: Motion | None
    first: int
    states: np.ndarray
    gripper: np.ndarray | None
    gripper_moves: bool


def _simulate(
    world: World, substeps: int, members: Sequence[Executor], plans: Sequence[_Commands]
) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Steps the physics through the arms' commanded states, cycle by cycle, logging each arm's cycles;
    returns per arm its measured joint positions after each cycle and (for an arm whose gripper moves) the
    fingers' positions."""
    model, data, step = world.model, world.data, mujoco.mj_step
    ctrl, qpos = data.ctrl, data.qpos
    rows = len(plans[0].states)
    # Per arm: its actuators and commanded positions, its gripper's actuators and commands (or None).
    drives = [
        (
            member.arm.actuator_indices,
            plan.states[:, 0] + member._lead * plan.states[:, 1],
            None if plan.gripper is None else member.arm.gripper.actuators,
            None if plan.gripper is None else member.arm.gripper.command_for(plan.gripper[:, 0, 0]),
        )
        for member, plan in zip(members, plans, strict=True)
    ]
    measured = [np.empty((rows, member.arm.dofs)) for member in members]
    fingers = [
        np.empty((rows, len(member._finger_joints))) if plan.gripper_moves else None
        for member, plan in zip(members, plans, strict=True)
    ]
    joints = [member.arm.qpos_indices for member in members]
    times, cycle_steps = np.empty(rows), range(substeps)
    for row in range(rows):
        for actuators, positions, gripper_actuators, commands in drives:
            ctrl[actuators] = positions[row]
            if commands is not None:
                ctrl[gripper_actuators] = commands[row]
        for _ in cycle_steps:
            step(model, data)
        times[row] = data.time
        for index, member_joints in enumerate(joints):
            measured[index][row] = qpos[member_joints]
            if fingers[index] is not None:
                fingers[index][row] = qpos[members[index]._finger_joints]
    for member, plan in zip(members, plans, strict=True):
        openings = np.zeros(rows) if plan.gripper is None else plan.gripper[:, 0, 0]
        member.log.append(times, plan.states, openings)
    return list(zip(measured, fingers, strict=True))


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
