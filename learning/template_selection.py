"""The shared-kernel template's hyperparameters chosen by the outcome of leave-one-out predictions.

A template's hyperparameters must not be chosen on the tasks it is evaluated on, and marginal likelihood in
theta space is no help when most of theta is null space (it rewards explaining the harmless noise;
:mod:`besman.skills.template_models`). What matters is the outcome: for each candidate kernel, each
training task's theta is predicted from the other K - 1 tasks and tried at its own tau (one rollout per
task and candidate, counted by the caller); the candidate whose predictions land closest on average wins
(ties: the first; the candidates are ordered from cautious to bold). Below :data:`MINIMUM_TASKS` training
tasks there is nothing to compare (with two tasks each prediction is simply the other task's theta), so the
default kernel is used without a rollout.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.skills.shared_kernel import SharedKernel
from besman.skills.tasks import TaskBounds
from besman.skills.template_models import leave_one_out_means

# Convex mixtures before extrapolating kriging, long length scales before short, smoothing before
# interpolating; fixed before any run. Length scales from beyond the box to a third of it (twenty tasks in
# a 2-D box lie about a fifth of it apart: shorter scales only copy the nearest task), noise ratios of a
# tenth and a hundredth of the signal. SharedKernel() is the convex half's middle length, larger noise.
CANDIDATES = tuple(
    SharedKernel(length_scale, noise, weights=weights)
    for weights in ("convex", "kriging")
    for length_scale in (1.2, 0.6, 0.3)
    for noise in (0.1, 0.01)
)
MINIMUM_TASKS = 3

Loss = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""losses (N,) of thetas (N, n) tried at taus (N, m); lower is better (e.g. the distance to the target)."""


@dataclass(frozen=True)
class KernelChoice:
    """The chosen kernel, every candidate's mean leave-one-out loss and the rollouts spent."""

    kernel: SharedKernel
    losses: tuple[float, ...]
    rollouts: int


def choose_kernel(
    taus: np.ndarray,
    thetas: np.ndarray,
    box: TaskBounds,
    loss: Loss,
    candidates: tuple[SharedKernel, ...] = CANDIDATES,
) -> KernelChoice:
    """The candidate whose leave-one-out predictions have the lowest mean ``loss`` (module documentation)."""
    if len(taus) < MINIMUM_TASKS:
        return KernelChoice(SharedKernel(), (), 0)
    inputs = box.normalise(taus)
    predicted = np.concatenate([leave_one_out_means(inputs, thetas, kernel) for kernel in candidates])
    losses = np.asarray(loss(predicted, np.tile(taus, (len(candidates), 1))), dtype=float)
    means = losses.reshape(len(candidates), len(taus)).mean(axis=1)
    best = int(np.argmin(means))
    return KernelChoice(candidates[best], tuple(float(m) for m in means), len(losses))
