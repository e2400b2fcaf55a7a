"""Simulated time in trees: one deadline mechanism for time limits, and waiting (py_trees' own Timer and
Timeout use the wall clock, which means nothing to a simulation that runs faster than real time).

- :class:`Deadline` - a time limit restarted whenever its behaviour starts; the leaves' ``timeout``
  parameter and the :class:`SimTimeout` decorator both use it.
- :class:`Wait` - RUNNING for ``duration`` simulated seconds, then SUCCESS.
- :class:`SimTimeout` - a decorator that fails its child (stopping it) when it runs longer than
  ``duration`` simulated seconds.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import py_trees
from py_trees.common import Status

from besman.core.errors import InputError
from besman.core.validation import checked, text
from besman.trees.base import BEHAVIOUR, SimulationBehaviour, executor_of

if TYPE_CHECKING:
    from besman.sim.executor import Executor


class Deadline:
    """``duration`` simulated seconds from each :meth:`start` (None: no limit)."""

    def __init__(self, owner: str, duration: float | None) -> None:
        if duration is not None and not (isinstance(duration, int | float) and 0 < duration < math.inf):
            raise InputError(f"{owner}: a time limit must be a positive number of seconds, got {duration!r}")
        self.duration = None if duration is None else float(duration)
        self.finish = math.inf

    def start(self, now: float) -> None:
        self.finish = math.inf if self.duration is None else now + self.duration

    def expired(self, now: float) -> bool:
        return now > self.finish

    @property
    def message(self) -> str:
        return f"timed out after {self.duration:g} s of simulated time"


class Wait(SimulationBehaviour):
    """Succeeds ``duration`` simulated seconds after it starts."""

    parameters: ClassVar = {"duration": "float>=0"}

    def __init__(self, name: str, *, duration: float) -> None:
        super().__init__(name)
        if not (isinstance(duration, int | float) and 0 <= duration < math.inf):
            raise InputError(f"{name}: duration must be a number >= 0, got {duration!r}")
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

    @checked(name=text("a behaviour name"), child=BEHAVIOUR)  # the duration: the Deadline's own check
    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, *, duration: float) -> None:
        super().__init__(name=name, child=child)
        self.deadline = Deadline(name, duration)
        self.executor: Executor | None = None

    @property
    def duration(self) -> float:
        return self.deadline.duration

    def setup(self, **kwargs: Any) -> None:
        self.executor = executor_of(self.name, kwargs)

    def initialise(self) -> None:
        self.deadline.start(self.executor.time)

    def update(self) -> Status:
        if self.deadline.expired(self.executor.time) and self.decorated.status is Status.RUNNING:
            self.feedback_message = self.deadline.message
            self.decorated.stop(Status.INVALID)
            return Status.FAILURE
        self.feedback_message = self.decorated.feedback_message
        return self.decorated.status
