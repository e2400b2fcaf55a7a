"""Waiting and time limits in simulated time (py_trees' own Timer and Timeout use the wall clock).

- :class:`Wait` - RUNNING for ``duration`` simulated seconds, then SUCCESS.
- :class:`SimTimeout` - a decorator that fails its child (stopping it) when it runs longer than
  ``duration`` simulated seconds.
"""

from __future__ import annotations

import py_trees
from py_trees.common import Status

from besman.sim.executor import Executor
from besman.trees.base import SimulationBehaviour


class Wait(SimulationBehaviour):
    """Succeeds ``duration`` simulated seconds after it starts."""

    def __init__(self, name: str, *, duration: float) -> None:
        super().__init__(name)
        if not duration >= 0:
            raise ValueError(f"{name}: duration must be >= 0, got {duration!r}")
        self.duration = float(duration)
        self.finish = 0.0

    def initialise(self) -> None:
        self.finish = self.time + self.duration

    def update(self) -> Status:
        remaining = self.finish - self.time
        self.feedback_message = f"{max(remaining, 0.0):.2f} s left"
        return Status.SUCCESS if remaining <= 1e-9 else Status.RUNNING


class SimTimeout(py_trees.decorators.Decorator):
    """Fails (and stops) its child once it has run for ``duration`` simulated seconds."""

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, *, duration: float) -> None:
        super().__init__(name=name, child=child)
        if not duration > 0:
            raise ValueError(f"{name}: duration must be > 0, got {duration!r}")
        self.duration = float(duration)
        self.executor: Executor | None = None
        self.finish = 0.0

    def setup(self, **kwargs) -> None:
        SimulationBehaviour.setup(self, **kwargs)

    def initialise(self) -> None:
        self.finish = self.executor.time + self.duration

    def update(self) -> Status:
        if self.executor.time > self.finish and self.decorated.status is Status.RUNNING:
            self.feedback_message = f"timed out after {self.duration:g} s of simulated time"
            self.decorated.stop(Status.INVALID)
            return Status.FAILURE
        self.feedback_message = self.decorated.feedback_message
        return self.decorated.status
