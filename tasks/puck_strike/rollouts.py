"""The puck strike on the UR5e, batched for policy search.

theta drives the arm's 6 joints through a joint-space DMP (10 weights, goal and goal velocity per joint:
6 x 12 = 72-D) that starts at rest in :data:`START` (the bat drawn back, its blade 29 cm behind the
contact point at the puck's mid-height: the demonstration's backswing). The joints follow the reference
with the robot's velocity feedforward (each position command leads by the commanded velocity x kv/kp,
``robots/ur5e/README.md``); the gripper stays as it is.

tau is the target: x, y (m) on the table where the puck should come to rest, in :data:`BOUNDS` - beyond
where the bat's blade reaches on the table (x <= 1.26 m along the puck's line, with the arm stretched and
the bat tilted; measured by inverse kinematics).

Success (:func:`judge`): at the rollout's end the puck is at rest - its speed below :data:`REST_SPEED` - on
the table, and its centre is within :data:`SUCCESS_RADIUS` of the target in the table's plane. The rollout
lasts ``duration`` (4 s: the 1 s strike, then the slide).

Reward: ``-d``, where ``d`` (m) is the distance in the table's plane between the target and where the puck
comes to rest - at the rollout's end its position, plus, if it still slides, the distance friction lets it
slide on, v^2 / (2 mu g) along its velocity (exact for a puck sliding flat on the table without spin) - plus
:data:`SUCCESS_REWARD` for a success. A reference that leaves the joint ranges or the joints' speed limits
is not simulated: it gets ``FAILURE_REWARD * (1 + violation)`` (rad and relative overspeed, capped), a
diverged simulation ``FAILURE_REWARD``.

Rollouts are open loop and run in MuJoCo's C rollout (:class:`~besman.sim.open_loop.OpenLoopRollouts`). tau
changes nothing in the physics (only the reward), so every rollout starts from the same state on a copy of the
model; each rollout is independent of the others (its own state, zero warm start), and the same theta and tau
give the same reward bit for bit, whatever else is in the batch and in whatever order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, instance, integer, optional, positive
from besman.sim.open_loop import FAILURE_REWARD as FAILURE_REWARD  # the task's, too
from besman.sim.open_loop import OpenLoopRollouts
from besman.skills.task_bounds import TaskBounds
from besman.tasks.puck_strike.world import (
    PUCK_FRICTION,
    PUCK_HEIGHT,
    PUCK_START,
    ROBOT,
    TABLE,
    puck_strike_world,
)

# tau's box per robot: the target (m) on the table, beyond the bat's reach.
BOUNDS = {"ur5e": TaskBounds(("target_x", "target_y"), (1.4, -0.05), (1.7, 0.32))}
# The start pose, the demonstration's backswing: the bat drawn back and tilted, the blade's centre at
# (0.21, 0.134, 0.796) m, in the arm's vertical plane (pan -90 deg) through the puck.
START = (-1.5708, -1.9378, 2.1635, -1.5258, -1.5708, -1.5708)
EXECUTION_TIME = 1.0  # s, the demonstration's duration and the DMP's
DURATION = 4.0  # s simulated per rollout
SUCCESS_RADIUS = 0.05  # m between the puck's centre at rest and the target
REST_SPEED = 0.01  # m/s: below it the puck is at rest
ON_TABLE = 0.005  # m: the puck's centre within this of its resting height counts as on the table
SUCCESS_REWARD = 1.0
SETTLE_STEPS = 100  # steps the puck rests on the table before a rollout's initial state is taken
GRAVITY = 9.81


@dataclass(frozen=True)
class StrikeDetail:
    """One rollout: success, where the puck came to rest (x, y in m; None if it did not run), its distance
    from the target (m), whether the puck was still sliding at the end, whether the bat moved it at all, and
    why the rollout failed before or during simulation (None if it ran)."""

    success: bool
    rest: tuple[float, float] | None
    distance: float | None
    sliding: bool
    moved: bool
    failure: str | None


def rest_point(position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Where a puck at ``position`` (x, y, ...) sliding at ``velocity`` (vx, vy, ...) comes to rest on the
    table: v^2 / (2 mu g) further along its velocity (mu: the puck's sliding friction)."""
    p = np.asarray(position, dtype=float)[..., :2]
    v = np.asarray(velocity, dtype=float)[..., :2]
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    return p + v * speed / (2 * PUCK_FRICTION[0] * GRAVITY)


def judge(position, velocity, target) -> tuple[bool, np.ndarray, float, bool]:
    """The success rule on the puck's final state: its position (3,) and linear velocity (3,) in the world
    and the target (x, y). Success, the rest point (x, y), its distance from the target, whether the puck
    still slides."""
    position = np.asarray(position, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    sliding = bool(np.linalg.norm(velocity) >= REST_SPEED)
    on_table = bool(
        abs(position[2] - (TABLE.height + PUCK_HEIGHT / 2)) <= ON_TABLE and TABLE.contains(*position[:2])
    )
    rest = rest_point(position, velocity) if on_table else position[:2].copy()
    distance = float(np.linalg.norm(rest - np.asarray(target, dtype=float)))
    at_target = float(np.linalg.norm(position[:2] - np.asarray(target, dtype=float))) < SUCCESS_RADIUS
    return (not sliding) and on_table and at_target, rest, distance, sliding


def reward_of(success: bool, distance: float) -> float:
    """The reward of a simulated rollout (see the module documentation)."""
    return -distance + (SUCCESS_REWARD if success else 0.0)


@checked(execution_time=positive, duration=positive, n_weights=integer(2))
@dataclass(frozen=True)
class PuckStrikeConfig:
    """Everything that defines the task; ``build()`` makes it (also on Ray workers)."""

    execution_time: float = EXECUTION_TIME  # s, the DMP's
    duration: float = DURATION  # s simulated per rollout (the strike, then the slide)
    n_weights: int = 10
    robot: str = ROBOT

    def build(self) -> PuckStrikeRollouts:
        return PuckStrikeRollouts(self)


class PuckStrikeRollouts(OpenLoopRollouts):
    """The UR5e strikes the puck with its bat so that it slides to a target; see the module documentation."""

    boxes: ClassVar[dict[str, TaskBounds]] = BOUNDS
    start_steps: ClassVar[int] = SETTLE_STEPS

    @checked(config=optional(instance(PuckStrikeConfig, "a PuckStrikeConfig")))
    def __init__(self, config: PuckStrikeConfig | None = None, **overrides) -> None:
        config = replace(config or PuckStrikeConfig(), **overrides)
        if config.robot not in BOUNDS:
            raise InputError(f"puck-strike runs on {', '.join(BOUNDS)}, not {config.robot!r}")
        if config.duration < config.execution_time + 1.0:
            raise InputError(
                f"duration ({config.duration} s) must exceed the execution time ({config.execution_time} s) "
                "by at least 1 s (the puck's slide)"
            )
        self._set_up(config, BOUNDS[config.robot], puck_strike_world(), START)
        self._position = self.model.sensor("puck_position").adr[0]
        self._velocity = self.model.sensor("puck_velocity").adr[0]

    def start_state(self) -> np.ndarray:
        """The full physics state (``mjSTATE_FULLPHYSICS``) every rollout starts from: the arm at rest in the
        start pose, the puck at rest on the table at its start, time 0."""
        return self._start_for(None)  # tau (the target) changes nothing in the physics

    # -- what is the puck strike's -------------------------------------------------------------------------

    def failed(self, reason: str) -> StrikeDetail:
        return StrikeDetail(False, None, None, False, False, reason)

    def _sound(self, states: np.ndarray, sensors: np.ndarray) -> np.ndarray:
        return super()._sound(states, sensors) & np.isfinite(sensors).all(axis=(1, 2))

    def _score(self, states: np.ndarray, sensors: np.ndarray, tau: np.ndarray) -> tuple[float, StrikeDetail]:
        p, v = self._position, self._velocity
        success, rest, distance, sliding = judge(sensors[-1, p : p + 3], sensors[-1, v : v + 3], tau)
        # Whether the bat moved the puck at all: more than 1 cm from its start at some step.
        moved = bool(np.linalg.norm(sensors[:, p : p + 2] - np.asarray(PUCK_START), axis=1).max() > 0.01)
        rest_xy = (round(float(rest[0]), 6), round(float(rest[1]), 6))
        return reward_of(success, distance), StrikeDetail(success, rest_xy, distance, sliding, moved, None)
