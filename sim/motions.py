"""Motions: what an executor does, cycle by cycle, and how each decides it is done.

A motion is started by :meth:`Executor.start <besman.sim.executor.Executor.start>` (which calls its
:meth:`~Motion.begin`). The executor then runs control cycles in chunks (:class:`Chunk`): the motion
commands the executor's Ruckig streams one cycle at a time (:meth:`~Motion.command`; commands never depend
on measurements, so a whole chunk is known ahead), the physics runs the chunk, and the motion judges the
chunk's cycles in order (:meth:`~Motion.judge`), ending at the first cycle that decides it. Each kind
carries its own logic:

- :class:`FollowReference` - track a joint reference (positions, velocities, accelerations at the control
  rate), aiming a few cycles ahead, then hold its last state until the robot arrives;
  :class:`FollowPrimitive` makes that reference from a movement primitive when it starts, in the current
  commanded state (:mod:`besman.sim.references`).
- :class:`MoveTo` - a time-optimal jerk-limited move to a joint configuration (Ruckig's own trajectory).
- :class:`TrackTarget` - track a joint configuration and a gripper opening that change from outside (a
  Gymnasium environment's actions), never ending by itself.
- :class:`GripperMotion` - open or close the gripper while the arm holds still; closing can require a grasp.
- :class:`Stop` - brake to rest within the limits (what pre-emption does).

An arm motion fails when the robot cannot follow its command (blocked or in collision), when the command
cannot keep up with a reference (too fast for the limits), or when the robot does not arrive in time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Protocol

import numpy as np
import ruckig

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.sim.executor_config import ExecutorConfig
from besman.sim.hand import Hand
from besman.sim.motion_status import MotionStatus
from besman.sim.references import ReferenceSettings, joint_reference
from besman.sim.streaming import JerkLimitedStream
from besman.skills import MovementPrimitive, Trajectory

AT_REST = 1e-6  # commanded speed and acceleration below which a command is at rest
AT_GOAL = 1e-6  # commanded distance (rad or m) at which a command is at its goal


class Driver(Protocol):
    """What a motion uses of the executor that runs it (:class:`~besman.sim.executor.Executor`): the arm, the
    settings, the hand and the two command streams."""

    arm: Arm
    config: ExecutorConfig
    hand: Hand | None
    stream: JerkLimitedStream
    gripper_stream: JerkLimitedStream | None
    reference_settings: ReferenceSettings


class Chunk:
    """What happened in consecutive control cycles of one motion, one row per cycle.

    Attributes:
        first: the motion's cycle number of the first row (1 for the motion's first cycle).
        commanded, commanded_velocity, commanded_acceleration: the arm's commanded state after each cycle.
        measured: the arm's joint positions after each cycle's physics.
        gripper: the commanded gripper opening and its velocity after each cycle (columns), if recorded.
        fingers: the fingers' measured joint positions after each cycle (columns), if recorded.
    """

    def __init__(
        self,
        first: int,
        states: np.ndarray,
        measured: np.ndarray,
        gripper: np.ndarray | None = None,
        fingers: np.ndarray | None = None,
    ) -> None:
        """``states`` (n, 3, dofs): commanded positions, velocities, accelerations; ``gripper`` (n, 3, 1) the
        same for the gripper; ``fingers`` (n, fingers) the fingers' measured positions."""
        self.first, self.measured = first, measured
        self.commanded, self.commanded_velocity, self.commanded_acceleration = (
            states[:, 0],
            states[:, 1],
            states[:, 2],
        )
        self.gripper = None if gripper is None else gripper[:, :2, 0]
        self.fingers = fingers

    def __len__(self) -> int:
        return len(self.measured)

    @property
    def at_rest(self) -> np.ndarray:
        return (np.abs(self.commanded_velocity).max(axis=1) < AT_REST) & (
            np.abs(self.commanded_acceleration).max(axis=1) < AT_REST
        )


@dataclass
class Motion:
    """Base of motions: a name for logs and messages, a status, and a message when it ends."""

    name: str
    status: MotionStatus = field(default=MotionStatus.RUNNING, init=False)
    message: str = field(default="", init=False)
    cycles: int = field(default=0, init=False)  # cycles commanded so far
    ended: int = field(default=0, init=False)  # the cycle that decided the motion, once it has ended
    settled: int = field(default=0, init=False)  # consecutive cycles at the goal
    waited: int = field(default=0, init=False)  # cycles the command has been at the goal
    moves_gripper: ClassVar[bool] = False  # whether the chunk must record the gripper and the fingers

    def finish(self, status: MotionStatus, message: str = "", cycle: int | None = None) -> MotionStatus:
        """Ends the motion, decided by its cycle ``cycle`` (None: the last one commanded)."""
        self.status, self.message = status, message
        self.ended = self.cycles if cycle is None else cycle
        return status

    def begin(self, executor: Driver) -> None:
        """Prepares the motion when it starts (checks, conversions); may finish it as FAILED."""

    def command(self, executor: Driver) -> ruckig.Result:
        """Advances the commanded state by cycle ``self.cycles`` (already counted)."""
        raise NotImplementedError

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        """Goes through the chunk's cycles in order and ends the motion at the first that decides it."""
        raise NotImplementedError

    def cycles_before_success(self, config: ExecutorConfig) -> int:
        """The fewest cycles from now after which the motion could succeed (at least 1): a chunk that long
        cannot pass a success (:meth:`Executor.run <besman.sim.executor.Executor.run>` runs such chunks).
        1 unless the motion knows more."""
        return 1

    def _cycles_to_settle(self, config: ExecutorConfig) -> int:
        """What :meth:`settle` needs at least: ``settle_cycles`` consecutive cycles at the goal."""
        return max(1, config.settle_cycles - self.settled)

    # -- shared judgements, vectorised over a chunk --------------------------------------------------------

    def blocked_at(self, executor: Driver, chunk: Chunk) -> int | None:
        """The first row where a joint is further behind its command than ``following_tolerance``."""
        behind = np.abs(chunk.measured - chunk.commanded)
        rows = np.flatnonzero(behind.max(axis=1) > executor.config.following_tolerance)
        return int(rows[0]) if rows.size else None

    def fail_blocked(self, executor: Driver, chunk: Chunk, row: int) -> None:
        behind = np.abs(chunk.measured[row] - chunk.commanded[row])
        joint = executor.arm.joints[int(behind.argmax())]
        self.finish(
            MotionStatus.FAILED,
            f"joint {joint} cannot follow its command ({behind.max():.3g} behind; blocked or in collision)",
            chunk.first + row,
        )

    def settle(
        self, executor: Driver, chunk: Chunk, goal: np.ndarray, done: np.ndarray, until: int | None
    ) -> None:
        """Cycle by cycle up to row ``until`` (None: all), where a cycle before ``until`` is fine otherwise:
        succeeds once the command is at ``goal`` (and ``done``) and the robot has stayed within
        ``arrival_tolerance`` of it for ``settle_cycles``; fails if it does not arrive in time."""
        config = executor.config
        if not done[:until].any():  # still on the way (most chunks): nothing is at the goal yet
            self.settled = 0
            return
        commanded_there = done & (np.abs(chunk.commanded - goal).max(axis=1) <= AT_GOAL)
        error = np.abs(chunk.measured - goal)
        arrived = commanded_there & (error.max(axis=1) <= config.arrival_tolerance)
        rows = len(chunk) if until is None else until
        for row in range(rows):
            self.settled = self.settled + 1 if arrived[row] else 0
            if self.settled >= config.settle_cycles:
                self.finish(MotionStatus.SUCCEEDED, "reached", chunk.first + row)
                return
            if commanded_there[row]:
                self.waited += 1
                if self.waited * config.control_period > config.arrival_timeout:
                    joint = executor.arm.joints[int(error[row].argmax())]
                    self.finish(
                        MotionStatus.FAILED,
                        f"joint {joint} stays {error[row].max():.3g} from its goal (blocked or in contact)",
                        chunk.first + row,
                    )
                    return


def _first(*rows: int | None) -> int | None:
    """The earliest of some rows (None where nothing happened)."""
    found = [row for row in rows if row is not None]
    return min(found) if found else None


@dataclass
class FollowReference(Motion):
    """Track ``reference`` (positions/velocities/accelerations of the executor's joints, sampled at the
    control period), then hold its last state until the robot arrives."""

    reference: Trajectory = None  # type: ignore[assignment]
    _targets: list = field(default_factory=list, init=False, repr=False)
    _rest: tuple = field(default=(), init=False, repr=False)  # at rest at the last position

    def begin(self, executor: Driver) -> None:
        arm, reference = executor.arm, self.reference
        if reference.positions.shape[1:] != (arm.dofs,):
            raise InputError(f"reference for {arm.dofs} joints expected, got {reference.positions.shape}")
        # Commands are clipped to the ranges; a reference that goes clearly beyond them is wrong.
        excess = np.maximum(arm.lower - reference.positions, reference.positions - arm.upper).max(axis=0)
        if excess.max() > executor.config.range_tolerance:
            joint = arm.joints[int(excess.argmax())]
            self.finish(
                MotionStatus.FAILED, f"the reference leaves the range of {joint} by {excess.max():.3g}"
            )
        positions = np.clip(reference.positions, arm.lower, arm.upper)
        self.reference = Trajectory(reference.times, positions, reference.velocities, reference.accelerations)
        # Every sample made a feasible Ruckig target once, as plain lists: the per-cycle work is a lookup.
        feasible = executor.stream.feasible(positions, reference.velocities, reference.accelerations)
        self._targets = list(zip(*(array.tolist() for array in feasible), strict=True))
        zeros = np.zeros(arm.dofs)
        self._rest = tuple(a.tolist() for a in executor.stream.feasible(positions[-1], zeros, zeros))

    def command(self, executor: Driver) -> ruckig.Result:
        # Aim at the reference a few cycles ahead, to be reached exactly then: Ruckig plans a smooth
        # approach of that state instead of a bang-bang chase of the next sample.
        last = len(self._targets) - 1
        if self.cycles < last:
            k = min(self.cycles + executor.config.lookahead_cycles, last)
            duration = (k - self.cycles + 1) * executor.config.control_period
            return executor.stream.track_feasible(
                *self._targets[k], synchronize=False, minimum_duration=duration
            )
        # At or past its end, come to rest at the reference's last position.
        return executor.stream.track_feasible(*self._rest)

    def cycles_before_success(self, config: ExecutorConfig) -> int:
        # The command reaches the reference's end at its last cycle; then the robot must settle there.
        to_end = max(0, len(self._targets) - 1 - self.cycles - 1)
        return to_end + self._cycles_to_settle(config)

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        positions = self.reference.positions
        last = len(positions) - 1
        cycles = np.arange(chunk.first, chunk.first + len(chunk))
        lag = np.abs(chunk.commanded - positions[np.minimum(cycles, last)])
        lagging = np.flatnonzero((cycles < last) & (lag.max(axis=1) > executor.config.lag_tolerance))
        blocked = self.blocked_at(executor, chunk)
        lag_row = int(lagging[0]) if lagging.size else None
        failure = _first(blocked, lag_row)
        self.settle(executor, chunk, positions[last], cycles >= last, until=failure)
        if self.status is not MotionStatus.RUNNING or failure is None:
            return
        if failure == blocked:
            self.fail_blocked(executor, chunk, failure)
        else:
            joint = executor.arm.joints[int(lag[failure].argmax())]
            self.finish(
                MotionStatus.FAILED,
                f"the reference is faster than the limits allow ({joint} lags {lag[failure].max():.3g})",
                chunk.first + failure,
            )


GUARD_CYCLES = 5  # control cycles between the checks of a guarded motion's contacts (10 ms at 500 Hz)


class FollowPrimitive(FollowReference):
    """Execute ``primitive``: its joint reference, made when the motion starts in the commanded state.

    Starting raises an :class:`~besman.core.errors.InputError` for a primitive the arm cannot execute (an
    unreachable Cartesian pose, a joint primitive of the wrong size). With ``untouched`` (an object's name)
    it is guarded: as soon as the robot touches that object (checked every :data:`GUARD_CYCLES`) it brakes
    within the limits and fails once at rest, as a hand coming down around an object that is not where it
    was perceived would push it over if it went on."""

    def __init__(self, primitive: MovementPrimitive, name: str | None = None, untouched: str | None = None):
        super().__init__(name or primitive.name)
        self.primitive = primitive
        self.untouched = untouched
        self.touched = False

    def begin(self, executor: Driver) -> None:
        self.reference = joint_reference(
            executor.arm, self.primitive, executor.stream.state(), executor.reference_settings
        )
        super().begin(executor)

    def command(self, executor: Driver) -> ruckig.Result:
        return executor.stream.brake() if self.touched else super().command(executor)

    def cycles_before_success(self, config: ExecutorConfig) -> int:
        cycles = super().cycles_before_success(config)
        return cycles if self.untouched is None else min(cycles, GUARD_CYCLES)

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        if self.touched:
            rest = np.flatnonzero(chunk.at_rest)
            if rest.size:
                self.finish(
                    MotionStatus.FAILED,
                    f"the robot touched {self.untouched} on the way: it is not where it was perceived",
                    chunk.first + int(rest[0]),
                )
            return
        super().judge(executor, chunk)
        if self.status is MotionStatus.RUNNING and self.untouched and executor.hand.bumps(self.untouched):
            self.touched = True


@dataclass
class MoveTo(Motion):
    """Go to ``target`` (joint positions of the executor's joints) and stop there."""

    target: np.ndarray = None  # type: ignore[assignment]

    def begin(self, executor: Driver) -> None:
        self.target = np.clip(np.asarray(self.target, dtype=float), executor.arm.lower, executor.arm.upper)

    def command(self, executor: Driver) -> ruckig.Result:
        return executor.stream.track(self.target)

    def cycles_before_success(self, config: ExecutorConfig) -> int:
        return self._cycles_to_settle(config)

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        blocked = self.blocked_at(executor, chunk)
        self.settle(executor, chunk, self.target, chunk.at_rest, until=blocked)
        if self.status is MotionStatus.RUNNING and blocked is not None:
            self.fail_blocked(executor, chunk, blocked)


@dataclass
class TrackTarget(Motion):
    """Track ``target`` (joint positions) and the gripper's ``opening`` (m per finger; None: leave it) with
    the Ruckig streams, jerk-limited, for as long as it runs: it never ends by itself (a Gymnasium step
    starts the next one over it), and fails when the robot cannot follow (blocked)."""

    target: np.ndarray = None  # type: ignore[assignment]
    opening: float | None = None
    _gripper: tuple | None = field(default=None, init=False, repr=False)  # its feasible Ruckig target
    moves_gripper: ClassVar[bool] = True

    def begin(self, executor: Driver) -> None:
        self.target = np.clip(np.asarray(self.target, dtype=float), executor.arm.lower, executor.arm.upper)
        self.moves_gripper = executor.hand is not None  # an arm without a gripper records none
        if self.opening is not None and executor.hand is not None:
            gripper = executor.arm.gripper
            goal = float(np.clip(self.opening, gripper.lower, gripper.upper))
            self._gripper = executor.gripper_stream.feasible([goal], [0.0], [0.0])

    def command(self, executor: Driver) -> ruckig.Result:
        if self._gripper is not None:
            executor.gripper_stream.track_feasible(*self._gripper)
        return executor.stream.track(self.target)

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        blocked = self.blocked_at(executor, chunk)
        if blocked is not None:
            self.fail_blocked(executor, chunk, blocked)


@dataclass
class GripperMotion(Motion):
    """Drive the gripper to ``opening`` (m per finger; None: the gripper's own opening for grasping and
    releasing; 0 closes it) while the arm holds still; with ``expect_grasp`` it fails unless it ends up
    holding ``grasp_object``."""

    opening: float | None = 0.0
    expect_grasp: bool = False
    grasp_object: str | None = None
    _target: tuple = field(default=(), init=False, repr=False)
    _goal: float = field(default=0.0, init=False, repr=False)
    _fingers: np.ndarray | None = field(default=None, init=False, repr=False)  # positions of recent cycles
    moves_gripper: ClassVar[bool] = True

    def begin(self, executor: Driver) -> None:
        if executor.hand is None:
            raise InputError("the executor has no gripper")
        gripper = executor.arm.gripper
        wanted = gripper.open if self.opening is None else self.opening
        self._goal = float(np.clip(wanted, gripper.lower, gripper.upper))
        self._target = tuple(a.tolist() for a in executor.gripper_stream.feasible([self._goal], [0.0], [0.0]))

    def command(self, executor: Driver) -> ruckig.Result:
        result = executor.stream.brake()  # the arm holds still (braking first if it was moving)
        executor.gripper_stream.track_feasible(*self._target)
        return result

    def cycles_before_success(self, config: ExecutorConfig) -> int:
        return self._cycles_to_settle(config)  # the fingers settle over a window of settle_cycles

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        blocked = self.blocked_at(executor, chunk)
        opening, speed = chunk.gripper[:, 0], chunk.gripper[:, 1]
        closed_on_limit = self._goal <= executor.gripper_stream.lower[0] + 1e-9
        commanded_done = (np.abs(opening - self._goal) < 1e-9) | (closed_on_limit & (np.abs(speed) < 1e-9))
        window = executor.config.settle_cycles
        # The fingers have settled when, over the settle window, they moved less than the gripper's still
        # speed would take them: a net motion, not the instantaneous speed, because fingers that squeeze an
        # object another hand also holds chatter in place (+-1.5e-3 rad/s on OpenArm, 1e-6 rad net).
        allowed = executor.arm.gripper.still_speed * window * executor.config.control_period
        fingers = chunk.fingers if self._fingers is None else np.concatenate([self._fingers, chunk.fingers])
        before = len(fingers) - len(chunk)  # rows of earlier chunks at the front
        self._fingers = fingers[-window:]
        for row in range(len(chunk) if blocked is None else blocked):
            self.settled = self.settled + 1 if commanded_done[row] else 0
            at = before + row
            if self.settled >= window and np.abs(fingers[at] - fingers[at - window]).max() <= allowed:
                # Judged on the simulation as it is now (at most a chunk later): the fingers have settled.
                if self.expect_grasp and not executor.hand.holds(self.grasp_object):
                    self.finish(MotionStatus.FAILED, "the fingers closed on nothing", chunk.first + row)
                else:
                    self.finish(MotionStatus.SUCCEEDED, "fingers settled", chunk.first + row)
                return
        if blocked is not None:
            self.fail_blocked(executor, chunk, blocked)


@dataclass
class Stop(Motion):
    """Brake to rest within the limits."""

    def command(self, executor: Driver) -> ruckig.Result:
        return executor.stream.brake()

    def judge(self, executor: Driver, chunk: Chunk) -> None:
        rest = np.flatnonzero(chunk.at_rest)
        if rest.size:
            self.finish(MotionStatus.SUCCEEDED, "stopped", chunk.first + int(rest[0]))
