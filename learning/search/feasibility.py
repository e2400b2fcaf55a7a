"""The free feasibility guard: a proposed theta whose reference would fail is pulled back toward a feasible
anchor before any rollout.

A throw's reference (its joint positions and speeds, and whether it releases the ball) is known before the
simulation, and 55 of 56 failed zero-shot throws of the first Fig. 5 run broke it
(``../shared/reference/learning.md`` section 3c). Every method that proposes a theta passes it through
:func:`pull_back` with an anchor known to be feasible (the training theta it came from, or theta_0): the
step from the anchor is halved until the reference passes, at most :data:`MAX_HALVINGS` times, after which
the anchor itself is used. The pulled-back proposals are counted, so that a method's reliance on the guard
is reported beside its distances.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

MAX_HALVINGS = 20  # 2^-20 of a step: the anchor for any purpose

Feasible = Callable[[np.ndarray], np.ndarray]
"""Whether each of thetas (N, n) passes the checks made before a rollout: bool (N,)."""


def pull_back(thetas: np.ndarray, anchors: np.ndarray, feasible: Feasible) -> tuple[np.ndarray, np.ndarray]:
    """``thetas`` (N, n) with each infeasible one moved toward its anchor (N, n) by halving its step until
    feasible, and which of them were moved (bool (N,)). The anchors must be feasible."""
    thetas = np.array(thetas, dtype=float, ndmin=2)
    anchors = np.broadcast_to(np.asarray(anchors, dtype=float), thetas.shape)
    moved = ~feasible(thetas)
    pending = np.flatnonzero(moved)
    for _ in range(MAX_HALVINGS):
        if pending.size == 0:
            break
        thetas[pending] = anchors[pending] + 0.5 * (thetas[pending] - anchors[pending])
        pending = pending[~feasible(thetas[pending])]
    thetas[pending] = anchors[pending]
    return thetas, moved
