"""The executor's command log: every control cycle's commanded state, kept in columns.

One row per control cycle: the simulated time after the cycle, the arm's commanded positions, velocities and
accelerations (the arm's joint order) and the commanded gripper opening (0 without a gripper). Rows arrive a
chunk at a time and are copied into growing numpy arrays (doubling, so appending is amortised O(1)). A
per-cycle list of records would leave four Python containers per cycle, tens of thousands per episode, for
the garbage collector to walk again and again: on a manipulation episode its full collections cost as much
as the control itself.
"""

from __future__ import annotations

import numpy as np


class CommandLog:
    """Commanded states of ``dofs`` joints, one row per control cycle."""

    def __init__(self, dofs: int, capacity: int = 4096) -> None:
        self.dofs = dofs
        self._times = np.empty(capacity)
        self._states = np.empty((capacity, 3, dofs))  # position, velocity, acceleration
        self._gripper = np.empty(capacity)
        self._size = 0

    def __len__(self) -> int:
        return self._size

    def append(self, times: np.ndarray, states: np.ndarray, gripper: np.ndarray | float) -> None:
        """Adds rows: ``times`` (n,), ``states`` (n, 3, dofs) and the gripper commands (n,) or one for all."""
        start, end = self._size, self._size + len(times)
        if end > len(self._times):
            self._grow(end)
        self._times[start:end] = times
        self._states[start:end] = states
        self._gripper[start:end] = gripper
        self._size = end

    def clear(self) -> None:
        self._size = 0

    def _grow(self, needed: int) -> None:
        capacity = max(needed, 2 * len(self._times))
        for name in ("_times", "_states", "_gripper"):
            old = getattr(self, name)
            new = np.empty((capacity, *old.shape[1:]))
            new[: self._size] = old[: self._size]
            setattr(self, name, new)

    # Views of the rows so far (they change when rows are added; copy to keep).

    @property
    def times(self) -> np.ndarray:
        return self._times[: self._size]

    @property
    def positions(self) -> np.ndarray:
        return self._states[: self._size, 0]

    @property
    def velocities(self) -> np.ndarray:
        return self._states[: self._size, 1]

    @property
    def accelerations(self) -> np.ndarray:
        return self._states[: self._size, 2]

    @property
    def gripper(self) -> np.ndarray:
        return self._gripper[: self._size]
