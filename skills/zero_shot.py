"""Zero-shot predictors of theta for a new task from the training pairs (tau_i, theta_i): the field a skill
template's prediction Theta(tau) is compared with.

Each takes the training inputs X (K, m) (tau normalised to the task box), thetas (K, n) and the query
inputs (N, m) and returns (N, n) predicted thetas. None has a setting chosen on evaluation results; the
fixed ones are stated with their reasons.

- :func:`training_mean` - the mean of the training thetas, whatever the task.
- :func:`nearest_neighbour` - the training theta of the nearest training task.
- :func:`affine_regression` - theta = a + B x by least squares (minimum norm while K <= m: fewer tasks
  than an affine map has unknowns).
- :func:`crkr` - cost-regularised kernel regression (Kober, Wilhelm, Oztop and Peters, "Reinforcement
  learning to adjust parametrized motor primitives to new situations", Autonomous Robots 2012):
  mean k(x)^T (K + lambda C)^-1 Gamma with C = diag(1 / r_i), so that training tasks learned badly (low
  reward r_i > 0) count less. Here r_i = exp(-d_i / 1 m) of the training theta's own distance d_i, the
  kernel is the shared template's default (squared exponential, 0.6 box widths), lambda = 0.5, and Gamma
  is centred on the training mean (the uncentred form shrinks every prediction towards theta = 0, no
  throw at all); fixed before any run.
- :func:`nearest_outcome` - besman's outcome template: every rollout of the training searches relabelled
  with the task it did solve (where its throw landed, hindsight relabelling), and the theta whose outcome is
  nearest the query. It needs a task whose outcome lives in the task space (a landing for a target) and the
  rollouts' outcomes, which the paper's template throws away.
"""

from __future__ import annotations

import numpy as np

from besman.skills.shared_kernel import SharedKernel

CRKR_REGULARISATION = 0.5


def training_mean(inputs: np.ndarray, thetas: np.ndarray, queries: np.ndarray) -> np.ndarray:
    return np.tile(thetas.mean(axis=0), (len(queries), 1))


def nearest_neighbour(inputs: np.ndarray, thetas: np.ndarray, queries: np.ndarray) -> np.ndarray:
    distances = ((queries[:, None, :] - inputs[None, :, :]) ** 2).sum(axis=2)
    return thetas[np.argmin(distances, axis=1)]


def nearest_outcome(outcomes: np.ndarray, thetas: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """For each query (N, m), the theta (of ``thetas`` (M, n)) whose outcome (of ``outcomes`` (M, m), in the
    queries' units) is nearest: the relabelled rollout that did what the query asks, or came closest."""
    return nearest_neighbour(outcomes, thetas, queries)


def affine_regression(inputs: np.ndarray, thetas: np.ndarray, queries: np.ndarray) -> np.ndarray:
    design = np.column_stack([np.ones(len(inputs)), inputs])
    coefficients = np.linalg.lstsq(design, thetas, rcond=None)[0]
    return np.column_stack([np.ones(len(queries)), queries]) @ coefficients


def crkr(
    inputs: np.ndarray,
    thetas: np.ndarray,
    queries: np.ndarray,
    rewards: np.ndarray,
    *,
    length_scale: float = SharedKernel().length_scale,
    regularisation: float = CRKR_REGULARISATION,
) -> np.ndarray:
    """``rewards`` (K,) > 0: how well each training theta solved its task (module documentation)."""

    def kernel(a, b):
        return np.exp(-0.5 * ((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2) / length_scale**2)

    centre = thetas.mean(axis=0)
    system = kernel(inputs, inputs) + regularisation * np.diag(1.0 / np.asarray(rewards, dtype=float))
    return centre + kernel(queries, inputs) @ np.linalg.solve(system, thetas - centre)
