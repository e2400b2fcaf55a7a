"""Ball-in-a-cup on the UR5e, batched for policy search (after Kober & Peters 2009, NIPS).

theta drives the arm's 6 joints through a joint-space DMP (10 weights, goal and goal velocity per joint:
6 x 12 = 72-D) that starts at rest in :data:`START` (the cup upright in front of the robot, the ball hanging
still under it). The joints follow the reference with the robot's velocity feedforward (each position
command leads by the commanded velocity x kv/kp, ``robots/ur5e/README.md``); the gripper stays as it is.

tau is the string's length (m, from the knot under the cup to the ball's centre), in :data:`BOUNDS`.

Success (:func:`judge`): the ball's centre is inside the cup - below the rim (0 <= z < :data:`CUP_DEPTH` in
the cup's frame, z from the inner bottom along the cup's axis) and within the cup's inner radius
(sqrt(x^2 + y^2) < :data:`CUP_RADIUS`) - at every step of the rollout's last :data:`SETTLE_TIME` s, i.e. it
went in at some time after the swing and is still inside at the end (the rollout lasts ``duration``, 1 s
longer than the motion).

Reward (Kober & Peters' shaping): where the ball's centre first passes down through the rim's plane (the
cup's frame, interpolated between steps), its distance from the cup's axis is the cost ``c`` (m); a ball
that never comes down through that plane costs ``MISS_COST`` plus how far its highest point stayed below
the rim. The reward is ``-c``, plus ``SUCCESS_REWARD`` for a success. A reference that leaves the joint
ranges or the joints' speed limits is not simulated: it gets ``FAILURE_REWARD * (1 + violation)`` (rad and
relative overspeed, capped), a diverged simulation ``FAILURE_REWARD``.

Rollouts are open loop and run in MuJoCo's C rollout (:class:`~besman.sim.open_loop.OpenLoopRollouts`), on a
few copies of the model whose string lengths are set before each batch of rollouts that share them (a copy is
~50 MB of meshes: never one per length); the same theta and tau give the same reward bit for bit, whatever
else is in the batch and in whatever order.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import ClassVar

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, instance, integer, optional, positive
from besman.sim.open_loop import FAILURE_REWARD as FAILURE_REWARD  # the task's, too
from besman.sim.open_loop import OpenLoopRollouts
from besman.skills.task_bounds import TaskBounds
from besman.tasks.ball_in_cup.world import (
    CUP_DEPTH,
    CUP_RADIUS,
    ROBOT,
    ball_in_cup_world,
    set_string_length,
)

# tau's box per robot: the string's length (m, knot to ball centre).
BOUNDS = {"ur5e": TaskBounds(("string_length",), (0.30,), (0.45,))}
# The start pose: the cup upright at (0.62, 0.13, 1.04) m, the arm in the vertical plane y = 0.13 m whose
# pitch joints (shoulder lift, elbow, wrist 1) swing it.
START = (-1.5708, -1.8, 2.4, -0.6, 1.5708, 0.0)
EXECUTION_TIME = 1.2  # s, the demonstration's duration and the DMP's
SETTLE_TIME = 0.25  # s at the end of a rollout during which the ball must stay inside
SUCCESS_REWARD = 1.0
MISS_COST = 1.0  # m, the cost of a ball that never comes down through the rim's plane (plus its shortfall)
SETTLE_STEPS = 150  # steps the ball hangs still under the held cup before a rollout's initial state is taken


@dataclass(frozen=True)
class CatchDetail:
    """One rollout: success, the first time the ball was inside the cup (s, None if never), the distance
    from the cup's axis where it first came down through the rim's plane (m, None if it never did), its
    highest point relative to the rim (m, in the cup's frame) and why it failed before or during simulation
    (None if it ran)."""

    success: bool
    caught_time: float | None
    crossing_distance: float | None
    peak_above_rim: float | None
    failure: str | None


def inside_cup(ball_in_cup: np.ndarray) -> np.ndarray:
    """Whether the ball's centre (..., 3), in the cup's frame, is inside the cup: below the rim, above the
    inner bottom and within the inner radius (the success rule's test at one step)."""
    p = np.asarray(ball_in_cup, dtype=float)
    radial = np.hypot(p[..., 0], p[..., 1])
    return (p[..., 2] >= 0.0) & (p[..., 2] < CUP_DEPTH) & (radial < CUP_RADIUS)


def judge(ball_in_cup: np.ndarray, timestep: float) -> tuple[bool, float | None, float | None, float]:
    """The success rule and the shaping on one rollout's ball positions (T, 3) in the cup's frame: success,
    the first time inside, the distance from the axis at the first downward pass through the rim's plane
    (None if none) and the peak height relative to the rim."""
    p = np.asarray(ball_in_cup, dtype=float)
    inside = inside_cup(p)
    last = max(1, round(SETTLE_TIME / timestep))
    success = bool(inside[-last:].all())
    caught = float((inside.argmax() + 1) * timestep) if inside.any() else None
    z = p[:, 2]
    down = np.flatnonzero((z[:-1] > CUP_DEPTH) & (z[1:] <= CUP_DEPTH))
    crossing = None
    if down.size:
        k = down[0]
        fraction = (z[k] - CUP_DEPTH) / (z[k] - z[k + 1])
        point = p[k] + fraction * (p[k + 1] - p[k])
        crossing = float(np.hypot(point[0], point[1]))
    return success, caught, crossing, float(z.max() - CUP_DEPTH)


def reward_of(success: bool, crossing: float | None, peak_above_rim: float) -> float:
    """The reward of a simulated rollout (see the module documentation)."""
    cost = crossing if crossing is not None else MISS_COST + max(0.0, -peak_above_rim)
    return -cost + (SUCCESS_REWARD if success else 0.0)


@checked(
    execution_time=positive,
    duration=positive,
    n_weights=integer(2),
)
@dataclass(frozen=True)
class BallInCupConfig:
    """Everything that defines the task; ``build()`` makes it (also on Ray workers)."""

    execution_time: float = EXECUTION_TIME  # s, the DMP's
    duration: float = 2.2  # s simulated per rollout (the motion, then the ball's flight and settling)
    n_weights: int = 10
    robot: str = ROBOT

    def build(self) -> BallInCupRollouts:
        return BallInCupRollouts(self)


class BallInCupRollouts(OpenLoopRollouts):
    """The UR5e swings a ball on a string into the cup it holds; see the module documentation."""

    boxes: ClassVar[dict[str, TaskBounds]] = BOUNDS
    start_steps: ClassVar[int] = SETTLE_STEPS

    @checked(config=optional(instance(BallInCupConfig, "a BallInCupConfig")))
    def __init__(self, config: BallInCupConfig | None = None, **overrides) -> None:
        config = replace(config or BallInCupConfig(), **overrides)
        if config.robot not in BOUNDS:
            raise InputError(f"ball-in-cup runs on {', '.join(BOUNDS)}, not {config.robot!r}")
        if config.duration < config.execution_time + 2 * SETTLE_TIME:
            raise InputError(
                f"duration ({config.duration} s) must exceed the execution time ({config.execution_time} s) "
                f"by at least {2 * SETTLE_TIME} s"
            )
        self._set_up(config, BOUNDS[config.robot], ball_in_cup_world(), START)

    def start_state(self, length: float) -> np.ndarray:
        """The full physics state (``mjSTATE_FULLPHYSICS``) a rollout with a string of ``length`` m starts
        from: the arm at rest in the start pose, the ball hanging still under the cup, time 0."""
        return self._start_for(float(self.bounds.check([length])[0, 0]))

    def model_with(self, length: float) -> mujoco.MjModel:
        """A copy of the model with a string of ``length`` m, for one's own use."""
        model = copy.copy(self.model)
        self._configure(model, float(length))
        return model

    # -- what is the ball-in-a-cup's -----------------------------------------------------------------------

    def _physics_key(self, tau: np.ndarray) -> float:
        return float(tau[0])  # the string's length

    def _configure(self, model: mujoco.MjModel, length: float) -> None:
        set_string_length(model, length)

    def _place(self, model: mujoco.MjModel, data: mujoco.MjData, length: float) -> None:
        """The ball hanging still under the cup's knot (it settles before the rollout starts)."""
        mujoco.mj_kinematics(model, data)
        address = model.jnt_qposadr[model.joint("ball").id]
        data.qpos[address : address + 3] = data.site("knot").xpos - [0.0, 0.0, length]
        data.qpos[address + 3 : address + 7] = [1.0, 0.0, 0.0, 0.0]

    def failed(self, reason: str) -> CatchDetail:
        return CatchDetail(False, None, None, None, reason)

    def _score(self, states: np.ndarray, sensors: np.ndarray, tau: np.ndarray) -> tuple[float, CatchDetail]:
        # The first sensor is the ball's position in the cup's frame.
        success, caught, crossing, peak = judge(sensors[:, :3], self.timestep)
        return reward_of(success, crossing, peak), CatchDetail(success, caught, crossing, peak, None)
