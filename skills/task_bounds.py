"""What every task shares: a box of task parameters tau and its validation.

A task parameter vector tau places things (a landing target, an object and a place position). Each task
exposes its :class:`TaskBounds`; values outside them are rejected with a message that names the value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array, items, text


@dataclass(frozen=True)
class TaskBounds:
    """An axis-aligned box of task parameters: ``low`` and ``high`` (inclusive), one name per entry."""

    names: tuple[str, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]

    def __post_init__(self) -> None:
        items(text("a task parameter's name"), "a tuple of names")("skills.TaskBounds: names", self.names)
        for bound in ("low", "high"):
            finite_array(f"skills.TaskBounds: {bound}", getattr(self, bound), ndim=1)
        if not len(self.names) == len(self.low) == len(self.high):
            raise InputError("bounds need as many names as low and high values")
        if any(lo > hi for lo, hi in zip(self.low, self.high, strict=True)):
            raise InputError(f"bounds have low > high: {self.low} vs {self.high}")

    @property
    def size(self) -> int:
        return len(self.names)

    def check(self, taus, *, n: int | None = None) -> np.ndarray:
        """``taus`` as an (N, size) array, broadcast from one tau if ``n`` is given; a ``ValueError`` names
        any value outside the box."""
        taus = finite_array("tau", taus)
        if taus.ndim == 1:
            taus = taus[None]
        if taus.ndim != 2 or taus.shape[1] != self.size:
            raise InputError(
                f"tau must have {self.size} entries ({', '.join(self.names)}), got shape {taus.shape}"
            )
        if n is not None and len(taus) == 1:
            taus = np.repeat(taus, n, axis=0)
        elif n is not None and len(taus) != n:
            raise InputError(f"got {len(taus)} taus for {n} candidates")
        low, high = np.asarray(self.low), np.asarray(self.high)
        outside = (taus < low - 1e-12) | (taus > high + 1e-12)
        if outside.any():
            row, column = (int(i) for i in np.argwhere(outside)[0])
            raise InputError(
                f"tau {self.names[column]} = {taus[row, column]:.4g} is outside the task's bounds "
                f"[{self.low[column]:.4g}, {self.high[column]:.4g}]"
            )
        return taus

    def normalise(self, taus: np.ndarray) -> np.ndarray:
        """taus mapped to the unit box ([0, 1] per parameter; beyond it outside the box)."""
        low = np.asarray(self.low, dtype=float)
        return (finite_array("taus", taus) - low) / np.maximum(np.asarray(self.high) - low, 1e-300)

    def columns(self, names) -> TaskBounds:
        """The box of the parameters ``names`` alone (a part of tau, in that order)."""
        missing = [name for name in names if name not in self.names]
        if missing:
            raise InputError(f"no task parameter {missing[0]!r}; parameters: {', '.join(self.names)}")
        index = [self.names.index(name) for name in names]
        return TaskBounds(tuple(names), tuple(self.low[i] for i in index), tuple(self.high[i] for i in index))

    def as_dict(self) -> dict:
        return {name: [lo, hi] for name, lo, hi in zip(self.names, self.low, self.high, strict=True)}
