"""Throwing: the PA-10 throws a ball at a target on the floor (the paper's experiment, Metzen et al., KI
2014; :mod:`besman.tasks.throwing.rollouts`). The run starts with the arm at rest in its wind-up pose, the
ball in the hand.

- **throwing** (aliases ``throw``, the demo's earlier name; default tree ``throw.yaml``: the throwing skill
  template of the paper's experiment aims the throw, refined in simulation where it would miss). The paper's
  variant: joint speeds relaxed to 6 rad/s.
- **throwing-hardware** (no default tree): the PA-10 within its own speed limits, nearer targets.

Randomised: tau = ``target`` (x, y on the floor, m), drawn uniformly from the variant's box
(:data:`~besman.tasks.throwing.rollouts.PAPER_BOUNDS`,
:data:`~besman.tasks.throwing.rollouts.HARDWARE_BOUNDS`); without a seed the middle of the box. Success: the
ball's first touch of the floor is within :data:`THROW_TOLERANCE` of the target. Policy search (``batched``)
evaluates theta, the throw's 96 DMP parameters, for many targets at once on
:class:`~besman.tasks.throwing.rollouts.ThrowingRollouts`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from besman.skills.task_bounds import TaskBounds
from besman.tasks.base import Scene, Task, TaskValue

THROW_TOLERANCE = 0.5  # m between the landing and the target


class Throwing(Task):
    name = "throwing"
    controls = ("throw",)  # one step: the throw itself (the release is no joint target)
    aliases = ("throw",)
    title = "the PA-10 throws the ball at a target on the floor (the paper's variant)"
    randomised = "the target on the floor (tau)"
    success = f"the ball lands within {THROW_TOLERANCE} m of the target"
    robot = "pa10"
    tree = "throw.yaml"
    values = (TaskValue("target", ("target_x", "target_y"), "m", "where the ball should land on the floor"),)
    measurements: ClassVar[Mapping[str, str]] = {
        "target": "where the ball should land, x, y on the floor",
        "landing": "where it first touched the floor (None if it never did)",
        "miss_m": f"the distance between the two (success: within {THROW_TOLERANCE} m)",
    }
    max_sim_time = 10.0
    variant = "paper"  # of besman.tasks.throwing.rollouts's ThrowingRollouts

    def fits(self, robot) -> bool:
        return robot.name == "pa10"

    def bounds(self, robot: str) -> TaskBounds:
        from besman.tasks.throwing.rollouts import VARIANTS

        box = VARIANTS[self.variant].bounds
        return TaskBounds(self.names, box.low, box.high)

    def draw(self, robot: str, rng: np.random.Generator) -> np.ndarray:
        """As :meth:`Task.draw`, to the millimetre: a seed gives the target it gave the throw demo."""
        return super().draw(robot, rng).round(3)

    def scene(self, robot: str, values, seed: int | None) -> Scene:
        from besman.tasks.throwing.executor import ThrowingExecutor

        executor = ThrowingExecutor(self.batched(robot))  # in the world of the rollouts policy search runs
        executor.wind_up()
        target = values["target"]
        return Scene(
            executor, dict(values), {"target": target.tolist()}, lambda: self.judge(executor, target)
        )

    def judge(self, executor, target):
        """The success rule on the run's throw (see the module documentation)."""
        from besman.trees.summary import Measured

        flight = executor.throw
        landing = None if flight is None or flight.landing is None else np.round(flight.landing, 3)
        miss = None if landing is None else float(np.linalg.norm(flight.landing - target))
        return Measured(
            miss is not None and miss <= THROW_TOLERANCE,
            "no landing"
            if landing is None
            else f"landed at {landing.tolist()}, {miss:.3f} m from {target.tolist()}",
            {
                "target": target.tolist(),
                "landing": None if landing is None else landing.tolist(),
                "miss_m": None if miss is None else round(miss, 3),
            },
        )

    def batched(self, robot: str):
        from besman.tasks.throwing.rollouts import ThrowingRollouts

        return ThrowingRollouts(variant=self.variant)


class ThrowingHardware(Throwing):
    name = "throwing-hardware"
    aliases = ()
    title = "the PA-10 throws the ball at a near target within its hardware speed limits"
    tree = None
    variant = "hardware"


TASKS = (Throwing(), ThrowingHardware())
