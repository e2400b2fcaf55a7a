"""The shared-kernel template's hyperparameters chosen by the outcome of predictions at held-out targets.

A template's hyperparameters must not be chosen on the tasks it is evaluated on, and marginal likelihood in
theta space is no help when most of theta is null space (it rewards explaining the harmless noise;
:mod:`besman.skills.template_models`). What matters is the outcome: for each candidate kernel, the template
of all K training tasks predicts a theta for each held-out validation target, which is tried there (one
rollout per target and candidate, counted by the caller); the candidate whose predictions land closest on
average wins (ties: the first; the candidates are ordered from cautious to bold).

The targets are held out from training and evaluation alike, and half of them lie on the box's edges
(:func:`besman.experiments.throwing.bench.validation_targets`): leave-one-out, the first choice, tested
interpolation inside the training tasks' hull only and so rewarded kernels whose negative weights extrapolate
the training thetas' null-space drift at the box's edges (``../shared/reference/learning.md`` section 3c).
With a single training task every candidate predicts its theta, so the default kernel is used without a
rollout.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from besman.skills.shared_kernel import SharedKernel
from besman.skills.task_bounds import TaskBounds
from besman.skills.template_models import KrigingWeights

# Convex mixtures before extrapolating kriging, long length scales before short, smoothing before
# interpolating; fixed before any run. Length scales from beyond the box to a third of it (twenty tasks in
# a 2-D box lie about a fifth of it apart: shorter scales only copy the nearest task), noise ratios of a
# tenth and a hundredth of the signal. Kriging only with the larger noise: interpolating kriging (a
# hundredth) puts weights of several times the data on the training thetas near the box's edges and, on
# the throwing grid, caused 22-69 failed throws per K where every other candidate caused 0-2 (section 3c).
# SharedKernel() is the convex half's middle length, larger noise.
CANDIDATES = (
    *(
        SharedKernel(length_scale, noise, weights="convex")
        for length_scale in (1.2, 0.6, 0.3)
        for noise in (0.1, 0.01)
    ),
    *(SharedKernel(length_scale, 0.1, weights="kriging") for length_scale in (1.2, 0.6, 0.3)),
)
MINIMUM_TASKS = 2

Loss = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""losses (N,) of thetas (N, n) tried at taus (N, m); lower is better (e.g. the distance to the target)."""


@dataclass(frozen=True)
class KernelChoice:
    """The chosen kernel, every candidate's mean loss at the held-out targets and the rollouts spent."""

    kernel: SharedKernel
    losses: tuple[float, ...]
    rollouts: int


def predictions(
    taus: np.ndarray, thetas: np.ndarray, box: TaskBounds, kernel: SharedKernel, targets
) -> np.ndarray:
    """(N, n): the shared model's mean theta at ``targets`` (N, m) from the training tasks (K, m), (K, n)."""
    return KrigingWeights(box.normalise(taus), kernel)(box.normalise(targets))[0] @ thetas


def choose_kernel(
    taus: np.ndarray,
    thetas: np.ndarray,
    box: TaskBounds,
    targets: np.ndarray,
    loss: Loss,
    candidates: tuple[SharedKernel, ...] = CANDIDATES,
) -> KernelChoice:
    """The candidate whose predictions at the held-out ``targets`` have the lowest mean ``loss`` (module
    documentation)."""
    if len(taus) < MINIMUM_TASKS:
        return KernelChoice(SharedKernel(), (), 0)
    predicted = np.concatenate([predictions(taus, thetas, box, kernel, targets) for kernel in candidates])
    losses = np.asarray(loss(predicted, np.tile(targets, (len(candidates), 1))), dtype=float)
    means = losses.reshape(len(candidates), len(targets)).mean(axis=1)
    best = int(np.argmin(means))
    return KernelChoice(candidates[best], tuple(float(m) for m in means), len(losses))
