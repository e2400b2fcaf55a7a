"""Outcome-space refinement: a few trials at a new task, each a Gauss-Newton step toward the target in the
coordinates of theta that move the outcome, the Jacobian corrected by what each trial reports (Broyden).

Where a trial reports its outcome in the task's own space (where the ball landed, for a target), the
outcome's error is a vector, not just a reward: y(theta) - tau. From a start theta with a known outcome and
an estimate J (m x c) of the outcome's Jacobian in c chosen coordinates of theta (for the throw: the DMP's
goals and goal velocities, 16 of 96; the Jacobian of the training task the start came from), each trial
steps from the best theta so far by the minimum-norm solution of J d = tau - y, scaled down if the predicted
move |J d| exceeds ``step_cap`` (outcome units: a linear model is trusted that far) and guarded (pulled back
until its reference is feasible, :mod:`besman.learning.search.feasibility`). The trial's outcome corrects J by
Broyden's rank-one update, J += (dy - J d) d^T / d^T d, so that the next step uses what this one saw. The
best outcome so far is kept: a failed trial costs its rollout and nothing else.

CMA-ES, the paper's refinement, sees only -|y - tau|^2 and needs tens of rollouts in 96-D; this needs the
outcome and a few.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from besman.core.errors import InputError

RIDGE = 1e-9  # keeps J J^T invertible where a Jacobian is (nearly) zero; in squared outcome units

Trial = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""outcomes (N, m) of thetas (N, n) tried at targets (N, m); NaN rows for failed trials."""

Guard = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""thetas (N, n) made feasible by pulling each back toward its anchor (N, n)."""


def refine_in_outcome_space(
    trial: Trial,
    guard: Guard,
    starts: np.ndarray,
    start_outcomes: np.ndarray,
    jacobians: np.ndarray,
    targets: np.ndarray,
    coordinates: np.ndarray,
    trials: int,
    step_cap: float = 1.0,
) -> np.ndarray:
    """(N, trials + 1) distances to target of the best outcome so far (column 0: the starts'), for starts
    (N, n) with their outcomes (N, m) and Jacobians (N, m, c) in theta's ``coordinates`` (c,)."""
    # Fresh C-ordered copies: numpy's sums follow the memory layout, and a strided Jacobian (as computed) and
    # a contiguous one (as read back by a resumed run) would differ in the last bits.
    best = np.array(starts, dtype=float, order="C")
    outcomes = np.array(start_outcomes, dtype=float, order="C")
    jacobians = np.array(jacobians, dtype=float, order="C")
    targets = np.array(targets, dtype=float, order="C")
    if not (len(best) == len(outcomes) == len(jacobians) == len(targets)):
        raise InputError("starts, their outcomes, Jacobians and targets must have one row per target")
    if jacobians.shape[1:] != (targets.shape[1], len(coordinates)):
        raise InputError(
            f"Jacobians must be (N, {targets.shape[1]}, {len(coordinates)}), got {jacobians.shape}"
        )
    if trials < 1 or not step_cap > 0:
        raise InputError(f"need at least one trial and a positive step cap, got {trials}, {step_cap}")
    distances = np.empty((len(best), trials + 1))
    distances[:, 0] = np.linalg.norm(targets - outcomes, axis=1)
    identity = np.eye(targets.shape[1])
    for t in range(1, trials + 1):
        gram = jacobians @ jacobians.transpose(0, 2, 1) + RIDGE * identity
        steps = np.einsum(
            "nmc,nm->nc", jacobians, np.linalg.solve(gram, (targets - outcomes)[..., None])[..., 0]
        )
        moves = np.linalg.norm(np.einsum("nmc,nc->nm", jacobians, steps), axis=1)
        steps *= np.minimum(1.0, step_cap / np.maximum(moves, 1e-300))[:, None]
        proposals = best.copy()
        proposals[:, coordinates] += steps
        proposals = guard(proposals, best)
        steps = (proposals - best)[:, coordinates]
        tried = trial(proposals, targets)
        seen = np.isfinite(tried).all(axis=1) & ((steps**2).sum(axis=1) > 0)
        change = np.where(seen[:, None], tried - outcomes, 0.0)
        surprise = change - np.einsum("nmc,nc->nm", jacobians, steps)
        norms = np.where(seen, (steps**2).sum(axis=1), 1.0)
        jacobians += np.where(
            seen[:, None, None], surprise[:, :, None] * steps[:, None, :] / norms[:, None, None], 0.0
        )
        better = seen & (np.linalg.norm(targets - tried, axis=1) < distances[:, t - 1])
        best[better], outcomes[better] = proposals[better], tried[better]
        distances[:, t] = np.linalg.norm(targets - outcomes, axis=1)
    return distances
