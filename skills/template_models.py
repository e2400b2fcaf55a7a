"""The two models of a skill template's Theta(tau) and per-coordinate uncertainty, on normalised tau.

Both take the training tasks' inputs X (K, m) (tau normalised to the task box, [0, 1] per coordinate) and
thetas (K, n), and predict for new inputs the mean theta and a variance per theta coordinate.

Shared weights (:class:`SharedKernelModel`, the default)
-------------------------------------------------------
A primitive's theta is mostly null space: in the throwing task the landing depends on 2 of the 96
directions of theta, and policy search random-walks in the other 94 (``../shared/reference/learning.md``
section 3b). A GP per coordinate then sees 96 noisy series, fits each its own length scale and noise by
marginal likelihood, and shrinks every coordinate towards the training mean on its own: the predicted theta
mixes coordinates of different training thetas and throws about as badly as the mean of the training
thetas. The shared model instead combines *whole* training thetas with one set of weights per query,
w(x) (K,), the same for every coordinate:

    Theta(x) = Theta^T w(x),   sum_i w_i(x) = 1.

The weights are those of GP regression with a constant mean estimated by generalised least squares
("ordinary kriging", Rasmussen and Williams 2006, section 2.7): with the correlation
c(x, x') = exp(-|x - x'|^2 / (2 l^2)) and A = C(X, X) + r I (r: the noise-to-signal variance ratio),

    w(x) = A^-1 c(x) + A^-1 1 (1 - 1^T A^-1 c(x)) / (1^T A^-1 1).

The weights sum to one, so a coordinate that every training theta agrees on is predicted exactly, and at
K = 1 the prediction is the one training theta. With an affine drift (``drift="affine"``, "universal
kriging", ibid.) the constant 1 becomes the features f(x) = [1, x] and F = f(X):

    w(x) = A^-1 c(x) + A^-1 F (F^T A^-1 F)^-1 (f(x) - F^T A^-1 c(x)),

so F^T w(x) = f(x): training thetas on an affine function of tau are predicted on it, also beyond them
(a contextual search's linear policy, :mod:`besman.learning.search.contextual`, kept as its values at the
training tasks, is the template it was). A variant clips negative weights (``weights="convex"``):
the prediction is then a mixture of learned thetas and never extrapolates beyond them (kriging's negative
weights can combine feasible throws into an infeasible one). The hyperparameters (l, r, the weights'
form) are shared by all outputs; they are not fitted by marginal likelihood in theta space, which the
harmless null-space noise dominates (it picks heavy shrinkage), but given
(:class:`~besman.skills.shared_kernel.SharedKernel`) or chosen by the outcome of predictions at held-out
targets (:mod:`besman.learning.template_selection` tries them out).

Omega: per-coordinate spread between a prior and the data
----------------------------------------------------------
How far x is from the data is the GP's normalised posterior variance lambda(x) = 1 - c(x)^T A^-1 c(x), in
[0, 1] (1 far from every training task). Near the data a coordinate is as uncertain as the training
thetas disagree with what the other tasks predict for them: its mean squared leave-one-out residual
mse_j. The prior is the exploration a search without a template would use (tabula rasa), sigma0_j^2,
which counts as nu0 training tasks:

    rho_j^2 = (nu0 sigma0_j^2 + (K - 1) mse_j) / (nu0 + K - 1)      (a conjugate, inverse-gamma-like update)
    Omega_jj(x) = lambda(x) sigma0_j^2 + (1 - lambda(x)) rho_j^2.

Far from the data, and at K = 1 (no residual to learn from: rho_j = sigma0_j), Omega is the prior
exploration instead of collapsing; near many tasks it is what they disagree about, per coordinate.

One GP per coordinate (:class:`PerDimensionModel`)
--------------------------------------------------
The model of the first reproduction, kept as a named option for comparisons: coordinate j has its own GP,
C * RBF(anisotropic) + White with amplitude, length scales (1/20 to 20 box widths) and noise fitted by
maximum marginal likelihood on standardised outputs (scikit-learn), so var_j(x) has its own shape.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Kernel, WhiteKernel

from besman.core.errors import InputError
from besman.core.seeds import SEEDS
from besman.core.validation import finite_array
from besman.skills.shared_kernel import SharedKernel

LENGTH_SCALE_BOUNDS = (0.05, 20.0)  # in box widths
AMPLITUDE_BOUNDS = (1e-4, 1e2)  # of the standardised outputs
NOISE_BOUNDS = (1e-8, 1.0)
VARIANCE_FLOOR = 1e-300  # a covariance must stay positive definite


def drift_features(inputs: np.ndarray, drift: str) -> np.ndarray:
    """(N, p) the drift's features of inputs (N, m): [1] (constant) or [1, x] (affine)."""
    ones = np.ones((len(inputs), 1))
    return ones if drift == "constant" else np.hstack([ones, inputs])


class KrigingWeights:
    """The shared model's weights w(x) of the training thetas and lambda(x), for one training set."""

    def __init__(self, inputs: np.ndarray, kernel: SharedKernel) -> None:
        self.inputs, self.kernel = inputs, kernel
        self._factor = cho_factor(self._correlation(inputs, inputs) + kernel.noise * np.eye(len(inputs)))
        features = drift_features(inputs, kernel.drift)  # F (K, p)
        self._solved_features = cho_solve(self._factor, features)  # A^-1 F
        kernel.check_inputs(inputs, leave_one_out=False)
        self._gram = features.T @ self._solved_features  # F^T A^-1 F

    def _correlation(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        squared = ((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2)
        return np.exp(-0.5 * squared / self.kernel.length_scale**2)

    def __call__(self, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, K) weights of the training thetas (rows sum to one) and (N,) lambda, the normalised posterior
        variance (0 at noise-free data, 1 far from it)."""
        cross = self._correlation(self.inputs, inputs)  # (K, N)
        solved = cho_solve(self._factor, cross)  # A^-1 c
        # The drift's deficit f(x) - F^T A^-1 c(x), made up by the drift's generalised least squares; the
        # constant drift in its closed form, the arithmetic of the templates learned before the affine one.
        if self.kernel.drift == "constant":
            ones = self._solved_features[:, 0]  # A^-1 1
            weights = (solved + np.outer(ones, 1.0 - ones @ cross) / ones.sum()).T
        else:
            deficit = drift_features(inputs, self.kernel.drift).T - self._solved_features.T @ cross  # (p, N)
            weights = (solved + self._solved_features @ np.linalg.solve(self._gram, deficit)).T
        if self.kernel.weights == "convex":
            weights = np.clip(weights, 0.0, None)
            weights /= weights.sum(axis=1, keepdims=True)  # the largest kriging weight is always positive
        remote = np.clip(1.0 - np.einsum("kn,kn->n", cross, solved), 0.0, 1.0)
        return weights, remote


class SharedKernelModel:
    """Theta as one combination of whole training thetas per query; Omega between prior and data."""

    name = "shared"

    def __init__(self, inputs: np.ndarray, thetas: np.ndarray, kernel: SharedKernel, prior_variance) -> None:
        self.thetas, self.kernel, self.prior_variance = thetas, kernel, prior_variance
        self.weights = KrigingWeights(inputs, kernel)
        count, prior = len(inputs), kernel.prior_weight
        if count == 1:  # no residual to learn from
            self.residual_variance = prior_variance.copy()
        else:  # rho_j^2: the prior updated with the mean squared leave-one-out residuals
            mse = ((thetas - leave_one_out_means(inputs, thetas, kernel)) ** 2).mean(axis=0)
            self.residual_variance = (prior * prior_variance + (count - 1) * mse) / (prior + count - 1)

    def predict(self, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        weights, remote = self.weights(inputs)
        variances = remote[:, None] * self.prior_variance + (1.0 - remote[:, None]) * self.residual_variance
        return weights @ self.thetas, np.maximum(variances, VARIANCE_FLOOR)


def leave_one_out_means(inputs: np.ndarray, thetas: np.ndarray, kernel: SharedKernel) -> np.ndarray:
    """(K, n): each training theta as the shared model of the other K - 1 tasks predicts it (K >= 2)."""
    count = len(inputs)
    if count < 2:
        raise InputError("leave-one-out predictions need at least two training tasks")
    means = np.empty_like(thetas)
    for i in range(count):
        others = np.arange(count) != i
        means[i] = KrigingWeights(inputs[others], kernel)(inputs[i : i + 1])[0][0] @ thetas[others]
    return means


def per_dimension_kernel(tau_dims: int) -> Kernel:
    """C * RBF (one length scale per tau coordinate) + White, on normalised tau and standardised theta."""
    return ConstantKernel(1.0, AMPLITUDE_BOUNDS) * RBF(
        np.full(tau_dims, 0.5), LENGTH_SCALE_BOUNDS
    ) + WhiteKernel(1e-2, NOISE_BOUNDS)


class PerDimensionModel:
    """One GP per theta coordinate, hyperparameters by maximum marginal likelihood (or given, (n, p))."""

    name = "per_dimension"

    def __init__(self, inputs: np.ndarray, thetas: np.ndarray, hyperparameters=None, seed: int = 0) -> None:
        if hyperparameters is None:
            # seed + j as the committed experiment's fits had it, wrapped into scikit-learn's range at the top
            self._gps = [_fit(inputs, thetas[:, j], (seed + j) % SEEDS) for j in range(thetas.shape[1])]
            return
        hyperparameters = finite_array("hyperparameters", hyperparameters, ndim=2)
        kernel = per_dimension_kernel(inputs.shape[1])
        if hyperparameters.shape != (thetas.shape[1], kernel.theta.size):
            raise InputError(
                f"hyperparameters must have shape {(thetas.shape[1], kernel.theta.size)}, "
                f"got {hyperparameters.shape}"
            )
        self._gps = [
            GaussianProcessRegressor(kernel.clone_with_theta(row), optimizer=None, normalize_y=True).fit(
                inputs, thetas[:, j]
            )
            for j, row in enumerate(hyperparameters)
        ]

    @property
    def hyperparameters(self) -> np.ndarray:
        """(n, p): each coordinate's fitted kernel parameters (log scale, scikit-learn's ``kernel.theta``)."""
        return np.array([gp.kernel_.theta for gp in self._gps])

    def predict(self, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        means, variances = np.empty((len(inputs), len(self._gps))), np.empty((len(inputs), len(self._gps)))
        for j, gp in enumerate(self._gps):
            means[:, j], std = gp.predict(inputs, return_std=True)
            variances[:, j] = std**2
        return means, np.maximum(variances, VARIANCE_FLOOR)


def _fit(inputs: np.ndarray, values: np.ndarray, seed: int) -> GaussianProcessRegressor:
    gp = GaussianProcessRegressor(
        per_dimension_kernel(inputs.shape[1]), normalize_y=True, n_restarts_optimizer=2, random_state=seed
    )
    with warnings.catch_warnings():  # hyperparameters at a bound are expected (e.g. a constant theta_j)
        warnings.simplefilter("ignore", ConvergenceWarning)
        return gp.fit(inputs, values)
