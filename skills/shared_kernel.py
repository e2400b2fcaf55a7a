"""The shared model's hyperparameters (:mod:`besman.skills.template_models`): plain data, apart from the
models, so that reading a template (listing a pool) imports neither scipy nor scikit-learn, which the fits
use."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.core.errors import InputError

WEIGHT_FORMS = ("kriging", "convex")
DRIFTS = ("constant", "affine")


@dataclass(frozen=True)
class SharedKernel:
    """The shared model's hyperparameters.

    length_scale: of the squared-exponential correlation, in box widths. noise: the noise-to-signal
    variance ratio r (the training thetas are noisy outcomes of a stochastic search). prior_weight: nu0,
    how many training tasks the prior exploration counts as. weights: ``"kriging"`` (may be negative: the
    prediction extrapolates beyond the training thetas) or ``"convex"`` (negative weights clipped to zero
    and the rest renormalised: a mixture of learned thetas, never beyond them). drift: the mean the
    weights reproduce exactly, ``"constant"`` (ordinary kriging) or ``"affine"`` in tau (universal kriging:
    training thetas that lie on an affine function of tau are predicted on it everywhere, beyond them too;
    it needs training tasks that span tau's box, and m + 2 of them for Omega's leave-one-out residuals). The
    defaults are fixed,
    never tuned on a result: the middle length and the larger noise of
    :data:`besman.learning.template_selection.CANDIDATES`, two tasks, and convex weights (with too few
    tasks to validate a kernel, nothing is extrapolated).
    """

    length_scale: float = 0.6
    noise: float = 0.1
    prior_weight: float = 2.0
    weights: str = "convex"
    drift: str = "constant"

    def __post_init__(self) -> None:
        if self.weights not in WEIGHT_FORMS:
            raise InputError(f"kernel weights must be one of {WEIGHT_FORMS}, got {self.weights!r}")
        if self.drift not in DRIFTS:
            raise InputError(f"kernel drift must be one of {DRIFTS}, got {self.drift!r}")
        if self.drift == "affine" and self.weights == "convex":
            raise InputError(
                "kernel drift 'affine' needs weights 'kriging': clipped weights lose the affine map"
            )
        for field in ("length_scale", "noise", "prior_weight"):
            value = getattr(self, field)
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
                raise InputError(f"kernel {field} must be a positive number, got {value!r}")

    def check_inputs(self, inputs: np.ndarray, *, leave_one_out: bool = True) -> None:
        """Refuses training inputs (K, m) the drift cannot be fitted on: an affine drift needs tasks that
        span tau's space (not all on one line or plane) - with ``leave_one_out``, also without any one of
        them (a template's Omega takes leave-one-out residuals), so K >= m + 2."""
        if self.drift == "affine":
            features = np.hstack([np.ones((len(inputs), 1)), inputs])
            least = features.shape[1] + int(leave_one_out)
            if len(inputs) < least or np.linalg.matrix_rank(features) < features.shape[1]:
                raise InputError(
                    f"an affine drift over {inputs.shape[1]} task parameters needs training tasks that span "
                    f"them (at least {least}, not on one line or plane); got {len(inputs)}"
                )
