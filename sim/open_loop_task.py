"""What a task whose policy search runs open loop (:mod:`besman.sim.open_loop`) says once for all of them.

:class:`OpenLoopTask` is mixed into such a task (before :class:`~besman.tasks.base.Task`): its robots, its
tau box per robot and its batched rollouts come from its rollouts class, named by :attr:`rollouts` and
imported on first use, so that the task registry does not bring MuJoCo with it.
"""

from __future__ import annotations

import importlib
from typing import ClassVar

import numpy as np

from besman.skills.task_bounds import TaskBounds


class OpenLoopTask:
    """The parts of a task that its open-loop rollouts class (``rollouts``: ``"package.module.Class"``, with
    ``boxes``, tau's box per robot name) decides."""

    rollouts: ClassVar[str]

    def _rollouts_class(self) -> type:
        module, _, name = self.rollouts.rpartition(".")
        return getattr(importlib.import_module(module), name)

    def fits(self, robot) -> bool:
        return robot.name in self._rollouts_class().boxes

    def bounds(self, robot: str) -> TaskBounds:
        import besman.robots as robots

        box = self._rollouts_class().boxes[robots.describe(robot).name]
        return TaskBounds(self.names, box.low, box.high)

    def draw(self, robot: str, rng: np.random.Generator) -> np.ndarray:
        """As :meth:`Task.draw`, to the millimetre."""
        return super().draw(robot, rng).round(3)

    def batched(self, robot: str):
        return self._rollouts_class()(robot=self.check_robot(robot))
