"""The canonical system and the forcing term's basis functions, shared by every DMP here.

A DMP runs on a phase z that decays from 1 to ``final_phase`` over the execution time tau
(Ijspeert et al., "Dynamical Movement Primitives", Neural Computation 2013)::

    z(t) = exp(-alpha_z t / tau),   alpha_z = -ln(final_phase)  (0.01 -> alpha_z ~ 4.605)

The forcing term is a normalised radial-basis-function network gated by the phase::

    f(z) = z * sum_i w_i psi_i(z) / sum_i psi_i(z),   psi_i(z) = exp(-h_i (z - c_i)^2)

with N centres at the phases of N equally spaced times, c_i = z(i tau / (N - 1)), and widths chosen so that
neighbouring functions overlap at ``overlap``: h_i = -ln(overlap) / (c_{i+1} - c_i)^2 (the last copies the
previous one). Everything is expressed in normalised time s = t / tau, so it does not depend on tau.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked


@checked()  # an unknown keyword is named, with the nearest known one
@dataclass(frozen=True)
class ForcingBasis:
    """The phase and the N normalised basis functions of a forcing term, in normalised time s = t / tau."""

    n_weights: int = 10
    final_phase: float = 0.01
    overlap: float = 0.8

    def __post_init__(self) -> None:
        if not isinstance(self.n_weights, int) or self.n_weights < 2:
            raise InputError(f"n_weights must be an integer >= 2, got {self.n_weights!r}")
        if not 0.0 < self.final_phase < 1.0:
            raise InputError(f"final_phase must be in (0, 1), got {self.final_phase!r}")
        if not 0.0 < self.overlap < 1.0:
            raise InputError(f"overlap must be in (0, 1), got {self.overlap!r}")

    @property
    def alpha_z(self) -> float:
        """Decay rate of the canonical system: z(tau) = final_phase."""
        return -math.log(self.final_phase)

    @cached_property
    def centres(self) -> np.ndarray:
        return np.exp(-self.alpha_z * np.linspace(0.0, 1.0, self.n_weights))

    @cached_property
    def widths(self) -> np.ndarray:
        widths = -math.log(self.overlap) / np.diff(self.centres) ** 2
        return np.append(widths, widths[-1])

    def phase(self, s: np.ndarray) -> np.ndarray:
        """z at normalised times s."""
        return np.exp(-self.alpha_z * np.asarray(s, dtype=float))

    def features(self, s: np.ndarray) -> np.ndarray:
        """The design matrix (len(s), N): z * psi_i(z) / sum_j psi_j(z), so that f(s) = features(s) @ w."""
        z = self.phase(s)[..., None]
        # Shifting by the largest exponent keeps the normalisation exact where every psi would underflow.
        exponents = -self.widths * (z - self.centres) ** 2
        activations = np.exp(exponents - exponents.max(axis=-1, keepdims=True))
        return z * activations / activations.sum(axis=-1, keepdims=True)
