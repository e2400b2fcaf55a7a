"""What every DMP kind shares: shape settings, the scaling of forcing weights in theta, and the ridge fit.

A joint :class:`~besman.skills.dmp.DMP` and the orientation part of a
:class:`~besman.skills.cartesian_dmp.CartesianDMP` have the same forcing term and gains, so they take one
:class:`DMPSettings` (N basis functions, their phase and overlap, the gains alpha_y and beta_y) and share:

- :meth:`DMPSettings.weight_units` - a weight's unit in theta: 1 / the largest displacement (in normalised
  time) a unit weight causes, so that a step of 1 in any weight moves the movement by at most 1 (times the
  DMP's ``scale``); computed once per settings (it simulates the transformation system on a fine grid).
- :func:`fit_weights` - forcing weights from stacked demonstrations by ridge regression (Muelling et al.,
  IJRR 2013): w = (X^T X + lambda I)^-1 X^T F with lambda = regularization * trace(X^T X) / N, so that the
  regularisation does not depend on how many samples there are or how the features are scaled.

:class:`Primitive` is the protocol every primitive kind satisfies (what movement primitives, optimisers and
the executor ask of a DMP).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Protocol, runtime_checkable

import numpy as np

from besman.core.validation import checked
from besman.skills.forcing import ForcingBasis
from besman.skills.transformation import TransformationSystem


@checked()  # an unknown keyword is named, with the nearest known one
@dataclass(frozen=True)
class DMPSettings:
    """The shape of a DMP's forcing term and transformation system.

    Attributes:
        n_weights: basis functions (weights) per dimension.
        alpha_y, beta_y: gains of the transformation system (critically damped for beta = alpha / 4).
        final_phase, overlap: phase at tau and overlap of neighbouring basis functions.
    """

    n_weights: int = 10
    alpha_y: float = 25.0
    beta_y: float = 6.25
    final_phase: float = 0.01
    overlap: float = 0.8

    @cached_property
    def basis(self) -> ForcingBasis:
        return ForcingBasis(self.n_weights, self.final_phase, self.overlap)

    @cached_property
    def system(self) -> TransformationSystem:
        return TransformationSystem.shared(float(self.alpha_y), float(self.beta_y))

    def __post_init__(self) -> None:
        self.basis  # noqa: B018  (checks n_weights, final_phase and overlap now, with their names)
        self.system  # noqa: B018

    @cached_property
    def weight_units(self) -> np.ndarray:
        """(N,): raw weight = theta entry * unit (* the DMP's scale); see the module documentation."""
        return 1.0 / self.system.peak_displacements(self.basis)


def fit_weights(features: list[np.ndarray], targets: list[np.ndarray], regularization: float) -> np.ndarray:
    """Ridge regression of forcing weights (D, N) on stacked demonstrations: ``features`` (T_k, N) and
    ``targets`` (T_k, D) per demonstration, each already weighted; see the module documentation."""
    design, target = np.concatenate(features), np.concatenate(targets)
    gram = design.T @ design
    ridge = max(regularization, 0.0) * np.trace(gram) / gram.shape[0]
    return np.linalg.solve(gram + ridge * np.eye(gram.shape[0]), design.T @ target).T


@runtime_checkable
class Primitive(Protocol):
    """What every primitive kind (:class:`~besman.skills.dmp.DMP`,
    :class:`~besman.skills.cartesian_dmp.CartesianDMP`) provides."""

    @property
    def settings(self) -> DMPSettings: ...

    @property
    def n_params(self) -> int: ...

    @property
    def execution_time(self) -> float: ...

    @execution_time.setter
    def execution_time(self, value: float) -> None: ...

    @property
    def dt(self) -> float: ...

    def get_params(self) -> np.ndarray: ...

    def set_params(self, theta) -> Primitive: ...

    def trajectory(self, theta=None, *, run_time: float | None = None): ...

    def trajectories(self, thetas, *, run_time: float | None = None): ...
