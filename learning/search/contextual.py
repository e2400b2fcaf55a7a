"""Contextual policy search: one upper-level policy pi(theta | s) for every context s at once.

Task-at-a-time policy search (:mod:`besman.learning.search.policy_search`) refines one theta per task. A
contextual optimiser instead learns a Gaussian upper-level policy whose mean is linear in context features,

    pi(theta | s) = N(W phi(s), Sigma),   phi(s) = [1, s]  (affine)  or  [1, s, s_i s_j]  (quadratic),

from rollouts in contexts drawn from the task distribution; its mean ``W phi(s)`` is the parameterised skill
(:meth:`ContextualOptimizer.policy_mean`, evaluated zero-shot on a grid of contexts). Contexts are normalised
to [0, 1] per coordinate when a :class:`ContextBox` is given, so the features are well scaled.

Two methods stand behind the :class:`ContextualOptimizer` interface, both re-implemented here:

- :class:`CREPS` - contextual relative entropy policy search (Kupcsik, Deisenroth, Peters, Neumann, AAAI 2013;
  Kupcsik, Deisenroth, Peters, Loh, Vadakkepat, Neumann, Artificial Intelligence 247, 2017). Rollouts are
  weighted by d_i = exp((R_i - V(s_i)) / eta), with the context baseline V(s) = v^T psi(s) and the temperature
  eta from the dual

      g(eta, v) = eta epsilon + v^T mean(psi) + eta log mean(exp((R - v^T psi) / eta)),

  which bounds the KL divergence between the reweighted and the old rollout distribution by epsilon while
  keeping the context distribution (its feature means). The policy is then the weighted maximum-likelihood
  fit: W by weighted ridge regression, Sigma the weighted covariance of the rollouts' steps from the mean.
- :class:`ContextualCMAES` - contextual CMA-ES (Abdolmaleki, Price, Lau, Reis, Neumann, IJCAI 2017): rewards
  minus a quadratic context baseline are ranked, CMA-ES's log-rank weights fit W by weighted regression, and
  step size and covariance follow CMA-ES's evolution paths, taken at the mean context features.

Defaults follow BOLeRo (rock-learning/bolero, commit 0eb963d, ``bolero/optimizer/creps.py`` and
``bolero/optimizer/ccmaes.py``), where they are:

- C-REPS (``CREPSOptimizer``): epsilon = 2.0, an update every ``train_freq`` = 25 rollouts over the last
  ``n_samples_per_update`` = 100 (the first update uses the first 25), ``context_features`` None meaning
  affine for the policy and the baseline, ridge ``gamma`` = 1e-4 on the policy's regression, ``min_eta`` =
  1e-8; Sigma is the weighted covariance of the steps from the mean that sampled them (``LinearGaussianPolicy
  .fit`` computes it before refitting W), normalised by 1 - sum(d^2) for weights d summing to one.
- C-CMA-ES (``CCMAESOptimizer``): population lambda = 4 + floor(3 ln(n + m)) (1 + 2 m) for n parameters and
  an m-D context (69 for n = 96, m = 2), an update per population; mu = floor(lambda / 2) log-rank weights;
  a degree-2 polynomial baseline fitted by ridge regression (``baseline_degree`` 2, ``gamma`` 1e-4);
  CMA-ES's learning rates with the dimension N = n + m: c_1 = 2 / ((N + 1.3)^2 + mu_eff),
  c_mu = min(1 - c_1, 2 (mu_eff - 2 + 1 / mu_eff) / ((N + 2)^2 + mu_eff)),
  c_c = (4 + mu_eff / N) / (N + 4 + 2 mu_eff / N), c_sigma = (mu_eff + 2) / (N + mu_eff + 5),
  d_sigma = 1 + 2 max(0, sqrt((mu_eff - 1) / (N + 1)) - 1) + c_sigma + ln(m + 1); the step size changes by
  at most a factor exp(0.6) per update.

Where this module departs from BOLeRo, each for a reason:

- Ridge regression pulls the coefficients toward the current policy, not toward zero: BOLeRo's pull toward
  W = 0 (offset included) moves a converged policy by about 1e-3 of |W| per update, more than its exploration
  once that is small, and the error grows again.
- C-REPS's dual is minimised by BFGS over log(eta - min_eta) and v, for rewards normalised per window: the
  minimiser is equivariant under positive affine reward transforms and under adding v_0^T psi(s), so a
  least-squares baseline of the better half of the rewards is subtracted and the residuals are divided by
  their spread (:func:`solve_creps_dual`). Failed throws (-1e3 .. -1e9) then get zero weight without setting
  the scale, and eta stays near 1 when the rewards mostly vary with the context.
- C-CMA-ES by default fits its baseline to the rewards' ranks (``baseline_target="ranks"``), so the search
  is invariant to strictly increasing reward transforms as CMA-ES is, and a -1e9 penalty cannot swamp the
  baseline; ``"rewards"`` is BOLeRo's (and the paper's) choice.

Measured (tests/test_contextual_search.py's problem: theta in R^5, theta*(s) affine in s in [0, 1]^2,
reward -||theta - theta*(s)||^2, start theta = 0 with spread 1, 2000 rollouts): C-CMA-ES reaches ~0.1 % of
the start's error. C-REPS with BOLeRo's update every 25 rollouts shrinks Sigma by ~20 % per update, faster
than its mean moves, and stalls at 15-60 % of the start's error; with an update every 100 fresh rollouts
(``CREPSConfig(update_every=100)``) it reaches 0.01-0.3 %. Centring Sigma on the new mean instead (the
weighted ML of Kupcsik et al.) stalled at 50-70 % (every 25) and at 0-8 % (every 100, epsilon 1; old mean:
~0 %).

:func:`contextual_search` drives one optimiser: it draws contexts from a seeded generator, asks for thetas,
evaluates each batch in one objective call, tells the rewards, and calls back at checkpoints so the caller
can evaluate the mean policy on a grid.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Literal, Protocol

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import SEED, checked, finite_array
from besman.learning.search.linear_gaussian import (
    FEATURE_KINDS,
    DualSolution,
    FeatureKind,
    context_features,
    solve_creps_dual,
    weighted_ridge,
)
from besman.learning.search.policy_search import WarmStart


class ContextualOptimizer(Protocol):
    """Learns an upper-level policy pi(theta | s) that maximises rewards over contexts s."""

    batch_size: int
    """How many contexts it wants per :meth:`ask` (its update period)."""

    def ask(self, contexts: np.ndarray) -> np.ndarray:
        """Thetas (N, n) sampled from the current policy for ``contexts`` (N, m)."""
        ...

    def tell(self, contexts: np.ndarray, thetas: np.ndarray, rewards: np.ndarray) -> None:
        """The rewards (N,) of ``thetas`` in ``contexts`` (higher is better); updates when it is due."""
        ...

    def policy_mean(self, contexts: np.ndarray) -> np.ndarray:
        """The policy's mean thetas (N, n) for ``contexts`` (N, m): the deterministic skill."""
        ...


@dataclass(frozen=True)
class ContextBox:
    """The task's context box low <= s <= high; contexts are normalised to [0, 1] per coordinate."""

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        low = finite_array("context_box.low", self.low, ndim=1)
        high = finite_array("context_box.high", self.high, shape=low.shape)
        if low.size == 0:
            raise InputError("context_box.low must not be empty")
        if np.any(high <= low):
            raise InputError("context_box.high must exceed context_box.low in every coordinate")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    def normalise(self, contexts: np.ndarray) -> np.ndarray:
        return (contexts - self.low) / (self.high - self.low)


def _check_features(name: str, kind: str) -> None:
    if kind not in FEATURE_KINDS:
        raise InputError(f"{name} must be one of {FEATURE_KINDS}, got {kind!r}")


@dataclass(frozen=True)
class CREPSConfig:
    """C-REPS settings (defaults: BOLeRo's ``CREPSOptimizer``, see the module docstring).

    Attributes:
        epsilon: the KL bound between successive rollout distributions.
        update_every: rollouts between updates (also the batch size asked for).
        window: the last rollouts each update uses.
        policy_features, baseline_features: phi(s) of the policy mean and psi(s) of the baseline V(s).
        ridge: the penalty pulling the policy's coefficients toward the current ones in the weighted
            regression (weights summing to one).
        min_eta: the dual's lower bound on the temperature, in normalised reward units.
        covariance_floor: added to Sigma's diagonal after each update, relative to the initial mean variance.
    """

    epsilon: float = 2.0
    update_every: int = 25
    window: int = 100
    policy_features: FeatureKind = "affine"
    baseline_features: FeatureKind = "affine"
    ridge: float = 1e-4
    min_eta: float = 1e-8
    covariance_floor: float = 1e-10

    def __post_init__(self) -> None:
        for name in ("epsilon", "min_eta", "covariance_floor"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if not self.ridge >= 0:
            raise InputError(f"ridge must be >= 0, got {self.ridge!r}")
        for name in ("update_every", "window"):
            if not isinstance(getattr(self, name), int) or getattr(self, name) < 1:
                raise InputError(f"{name} must be a positive integer, got {getattr(self, name)!r}")
        if self.window < self.update_every:
            raise InputError(f"window ({self.window}) must be at least update_every ({self.update_every})")
        _check_features("policy_features", self.policy_features)
        _check_features("baseline_features", self.baseline_features)


@dataclass(frozen=True)
class ContextualCMAESConfig:
    """Contextual CMA-ES settings (defaults: BOLeRo's ``CCMAESOptimizer``, see the module docstring).

    Attributes:
        population_size: rollouts per update (also the batch size asked for); None for
            4 + floor(3 ln(n + m)) (1 + 2 m).
        policy_features: phi(s) of the policy mean.
        baseline_features: the features of the reward baseline fitted before ranking.
        baseline_target: fit the baseline to the rewards' ranks (robust to huge penalties) or to the
            rewards themselves (as BOLeRo does).
        ridge: the penalty of the baseline's regression (toward zero, for centred targets) and of the
            policy's (toward the current coefficients); weights sum to one.
    """

    population_size: int | None = None
    policy_features: FeatureKind = "affine"
    baseline_features: FeatureKind = "quadratic"
    baseline_target: Literal["ranks", "rewards"] = "ranks"
    ridge: float = 1e-4

    def __post_init__(self) -> None:
        size = self.population_size
        if size is not None and (not isinstance(size, int) or size < 4):
            raise InputError(f"population_size must be an integer >= 4 (or None), got {size!r}")
        if not self.ridge >= 0:
            raise InputError(f"ridge must be >= 0, got {self.ridge!r}")
        _check_features("policy_features", self.policy_features)
        _check_features("baseline_features", self.baseline_features)
        if self.baseline_target not in ("ranks", "rewards"):
            raise InputError(f"baseline_target must be 'ranks' or 'rewards', got {self.baseline_target!r}")


def contextual_population_size(parameters: int, context_dimensions: int) -> int:
    """BOLeRo's C-CMA-ES default lambda = 4 + floor(3 ln(n + m)) (1 + 2 m)."""
    return 4 + int(3 * math.log(parameters + context_dimensions)) * (1 + 2 * context_dimensions)


def _context_dimensions(context_box: ContextBox | None, context_dimensions: int | None) -> int:
    """m, from the box if there is one (``context_dimensions`` must then agree or be None)."""
    if context_box is not None:
        if context_dimensions not in (None, context_box.low.size):
            raise InputError(
                f"context_dimensions ({context_dimensions}) disagrees with context_box "
                f"({context_box.low.size} coordinates)"
            )
        return context_box.low.size
    if not isinstance(context_dimensions, int | np.integer) or context_dimensions < 1:
        raise InputError(
            f"context_dimensions must be a positive integer (or give context_box), got {context_dimensions!r}"
        )
    return int(context_dimensions)


class _LinearGaussianPolicySearch:
    """The upper-level policy N(W phi(s), Sigma) with its sampling, its rollout window and update schedule;
    ``config`` holds the method's settings (default: its ``config_type``'s defaults).

    ``coefficients`` (k, n), W^T on the policy's features of normalised contexts, start the policy's mean
    somewhere other than the constant policy at ``mean`` (e.g. a fit of thetas already learned per context).

    Subclasses name their settings' class (``config_type``), say how many rollouts are between updates and
    how many each update uses (``_schedule``), set up their own state in ``_begin`` (``_factor``, L with
    Sigma = L L^T, starts as the start's) and implement ``_update`` on the window's normalised contexts,
    thetas and rewards.
    """

    config_type: ClassVar[type[CREPSConfig | ContextualCMAESConfig]]

    def __init__(
        self,
        mean,
        spread,
        *,
        seed: int,
        context_box: ContextBox | None = None,
        context_dimensions: int | None = None,
        config: CREPSConfig | ContextualCMAESConfig | None = None,
        coefficients=None,
    ) -> None:
        self.config = self.config_type() if config is None else config
        self._start = WarmStart(mean, spread)
        seed = SEED(f"learning.{type(self).__name__}: seed", seed)
        self.context_dimensions = _context_dimensions(context_box, context_dimensions)
        self.parameters = self._start.mean.size
        self._box = context_box
        self._policy_features = self.config.policy_features
        self._rng = np.random.default_rng(seed)
        self._update_every, window = self._schedule()
        shape = (self._features(np.zeros((1, self.context_dimensions))).shape[1], self.parameters)
        if coefficients is None:  # the constant policy at the start's mean
            coefficients = np.zeros(shape)
            coefficients[0] = self._start.mean
        self._coefficients = finite_array("coefficients", coefficients, shape=shape).copy()  # W^T: (k, n)
        self._factor = self._start.factor()
        self._window_contexts: deque[np.ndarray] = deque(maxlen=window)  # normalised
        self._window_thetas: deque[np.ndarray] = deque(maxlen=window)
        self._window_rewards: deque[float] = deque(maxlen=window)
        self.rollouts_told = 0
        self.updates = 0
        self._begin()

    @property
    def batch_size(self) -> int:
        return self._update_every

    @property
    def covariance(self) -> np.ndarray:
        """The current exploration covariance Sigma (n, n)."""
        return self._factor @ self._factor.T

    def _normalised(self, name: str, contexts) -> np.ndarray:
        contexts = finite_array(name, contexts, shape=(None, self.context_dimensions))
        return contexts if self._box is None else self._box.normalise(contexts)

    def _features(self, normalised_contexts: np.ndarray) -> np.ndarray:
        return context_features(normalised_contexts, self._policy_features)

    def policy_mean(self, contexts) -> np.ndarray:
        return self._features(self._normalised("contexts", contexts)) @ self._coefficients

    def ask(self, contexts) -> np.ndarray:
        means = self.policy_mean(contexts)
        return means + self._rng.standard_normal(means.shape) @ self._factor.T

    def tell(self, contexts, thetas, rewards) -> None:
        normalised = self._normalised("contexts", contexts)
        count = len(normalised)
        thetas = finite_array("thetas", thetas, shape=(count, self.parameters))
        rewards = finite_array("rewards", rewards, shape=(count,))
        for context, theta, reward in zip(normalised, thetas, rewards, strict=True):
            self._window_contexts.append(context)
            self._window_thetas.append(theta)
            self._window_rewards.append(float(reward))
            self.rollouts_told += 1
            if self.rollouts_told % self._update_every == 0:
                self._update(
                    np.array(self._window_contexts),
                    np.array(self._window_thetas),
                    np.array(self._window_rewards),
                )
                self.updates += 1

    def _schedule(self) -> tuple[int, int]:
        """The rollouts between updates (the batch size) and the last rollouts each update uses."""
        raise NotImplementedError

    def _begin(self) -> None:
        """Sets up the method's own state, once the policy and its window are."""
        raise NotImplementedError

    def _update(self, normalised_contexts: np.ndarray, thetas: np.ndarray, rewards: np.ndarray) -> None:
        raise NotImplementedError


class CREPS(_LinearGaussianPolicySearch):
    """C-REPS with the upper-level policy N(a + A phi(s), Sigma), starting at N(mean, spread) everywhere.

    ``spread`` is a scalar or (n,) standard deviations or an (n, n) covariance; ``context_box`` (or else
    ``context_dimensions``) gives the contexts' size; ``seed`` fixes every sample.
    """

    config_type = CREPSConfig

    def _schedule(self) -> tuple[int, int]:
        return self.config.update_every, self.config.window

    def _begin(self) -> None:
        mean_variance = float(np.mean(np.diag(self._start.covariance())))
        self._variance_floor = self.config.covariance_floor * mean_variance
        self.last_dual: DualSolution | None = None

    def _update(self, normalised_contexts: np.ndarray, thetas: np.ndarray, rewards: np.ndarray) -> None:
        config = self.config
        baseline_features = context_features(normalised_contexts, config.baseline_features)
        dual = solve_creps_dual(baseline_features, rewards, config.epsilon, config.min_eta)
        weights = dual.weights
        features = self._features(normalised_contexts)
        # Steps from the current mean, which sampled the newest rollouts (as BOLeRo; see the module docs).
        steps = thetas - features @ self._coefficients
        self._coefficients = weighted_ridge(features, thetas, weights, config.ridge, prior=self._coefficients)
        normaliser = max(1.0 - float(weights @ weights), np.finfo(float).eps)  # unbiased, as weights sum to 1
        covariance = (steps * weights[:, None]).T @ steps / normaliser
        covariance = 0.5 * (covariance + covariance.T) + self._variance_floor * np.eye(self.parameters)
        self._factor = np.linalg.cholesky(covariance)
        self.last_dual = dual


class ContextualCMAES(_LinearGaussianPolicySearch):
    """Contextual CMA-ES with the search distribution N(W phi(s), sigma^2 C), starting at N(mean, spread).

    ``spread`` is a scalar or (n,) standard deviations or an (n, n) covariance Sigma_0, split into the step
    size sigma_0 = det(Sigma_0)^(1 / 2n) and the shape C_0 = Sigma_0 / sigma_0^2; ``context_box`` (or else
    ``context_dimensions``) gives the contexts' size; ``seed`` fixes every sample.
    """

    config_type = ContextualCMAESConfig

    def _schedule(self) -> tuple[int, int]:
        default = contextual_population_size(self.parameters, self.context_dimensions)
        population = self.config.population_size or default
        return population, population  # an update per population, on that population

    def _begin(self) -> None:
        self.population_size = self._update_every
        n, total = self.parameters, self.parameters + self.context_dimensions
        mu = self.population_size // 2
        ranked = math.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
        self._ranked_weights = np.concatenate([ranked / ranked.sum(), np.zeros(self.population_size - mu)])
        self.mu_eff = 1.0 / float(np.sum(self._ranked_weights**2))
        mu_eff = self.mu_eff
        self.c_1 = 2.0 / ((total + 1.3) ** 2 + mu_eff)
        self.c_mu = min(1.0 - self.c_1, 2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((total + 2.0) ** 2 + mu_eff))
        self.c_c = (4.0 + mu_eff / total) / (total + 4.0 + 2.0 * mu_eff / total)
        self.c_sigma = (mu_eff + 2.0) / (total + mu_eff + 5.0)
        self.d_sigma = (
            1.0
            + 2.0 * max(0.0, math.sqrt((mu_eff - 1.0) / (total + 1.0)) - 1.0)
            + self.c_sigma
            + math.log(self.context_dimensions + 1.0)
        )
        self._expected_norm = math.sqrt(n) * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n**2))
        covariance = self._start.covariance()
        self.sigma = float(np.exp(np.linalg.slogdet(covariance)[1] / (2 * n)))
        self.shape = covariance / self.sigma**2  # C
        self._path_sigma = np.zeros(n)
        self._path_c = np.zeros(n)
        self._set_shape(self.shape)

    def _set_shape(self, shape: np.ndarray) -> None:
        """C, its inverse square root for the step-size path, and the sampling factor sigma B D."""
        self.shape = 0.5 * (shape + shape.T)
        eigenvalues, eigenvectors = np.linalg.eigh(self.shape)
        eigenvalues = np.maximum(eigenvalues, 1e-14 * eigenvalues.max())
        self._inverse_sqrt_shape = (eigenvectors / np.sqrt(eigenvalues)) @ eigenvectors.T
        self._factor = self.sigma * eigenvectors * np.sqrt(eigenvalues)

    def _advantages(self, normalised_contexts: np.ndarray, rewards: np.ndarray) -> np.ndarray:
        config = self.config
        target = rewards
        if config.baseline_target == "ranks":
            target = np.argsort(np.argsort(rewards, kind="stable"), kind="stable") / (len(rewards) - 1.0)
        features = context_features(normalised_contexts, config.baseline_features)
        target = target - target.mean()
        uniform = np.full(len(rewards), 1.0 / len(rewards))
        return target - features @ weighted_ridge(features, target, uniform, config.ridge)

    def _update(self, normalised_contexts: np.ndarray, thetas: np.ndarray, rewards: np.ndarray) -> None:
        advantages = self._advantages(normalised_contexts, rewards)
        weights = np.empty(len(rewards))
        weights[np.argsort(-advantages, kind="stable")] = self._ranked_weights
        features = self._features(normalised_contexts)
        mean_features = features.mean(axis=0)
        old_coefficients = self._coefficients
        self._coefficients = weighted_ridge(
            features, thetas, weights, self.config.ridge, prior=old_coefficients
        )
        mean_step = mean_features @ (self._coefficients - old_coefficients) / self.sigma

        generation = self.updates + 1
        decay = (1.0 - self.c_sigma) ** (2 * generation)
        self._path_sigma = (1.0 - self.c_sigma) * self._path_sigma + math.sqrt(
            self.c_sigma * (2.0 - self.c_sigma) * self.mu_eff
        ) * (self._inverse_sqrt_shape @ mean_step)
        path_sigma_norm = float(np.linalg.norm(self._path_sigma))
        n = self.parameters
        path_too_long = path_sigma_norm**2 / (1.0 - decay) / n >= 2.0 + 4.0 / (n + 1)
        self._path_c = (1.0 - self.c_c) * self._path_c
        if not path_too_long:
            self._path_c += math.sqrt(self.c_c * (2.0 - self.c_c) * self.mu_eff) * mean_step
        steps = (thetas - features @ old_coefficients) / self.sigma
        rank_mu = (steps * weights[:, None]).T @ steps
        c_1_lost = self.c_1 * self.c_c * (2.0 - self.c_c) if path_too_long else 0.0
        shape = (
            (1.0 - self.c_1 - self.c_mu + c_1_lost) * self.shape
            + self.c_1 * np.outer(self._path_c, self._path_c)
            + self.c_mu * rank_mu
        )
        self.sigma *= math.exp(
            min(0.6, self.c_sigma / self.d_sigma * (path_sigma_norm / self._expected_norm - 1))
        )
        self._set_shape(shape)


Objective = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""rewards (N,) of thetas (N, n) in contexts (N, m): one batch per ask."""

ContextSampler = Callable[[np.random.Generator, int], np.ndarray]
"""contexts (count, m) drawn with the given generator."""


@dataclass(frozen=True)
class ContextualSearchResult:
    """One contextual search.

    Attributes:
        contexts: the context of every rollout (rollouts, m), in order.
        rewards: the reward of every rollout, in order.
        checkpoints: the rollout counts at which ``on_checkpoint`` was called.
    """

    contexts: np.ndarray
    rewards: np.ndarray
    checkpoints: list[int]

    @property
    def rollouts(self) -> int:
        return len(self.rewards)


@checked(seed=SEED)
def contextual_search(
    objective: Objective,
    optimizer: ContextualOptimizer,
    *,
    budget: int,
    sample_contexts: ContextSampler,
    seed: int,
    checkpoint_every: int | None = None,
    on_checkpoint: Callable[[int, ContextualOptimizer], None] | None = None,
    progress: Callable[[int], None] | None = None,
) -> ContextualSearchResult:
    """Runs ``optimizer`` for exactly ``budget`` rollouts.

    Each batch draws ``optimizer.batch_size`` contexts (fewer at the budget or a checkpoint) with
    ``sample_contexts`` and a generator seeded by ``seed``, asks for thetas, evaluates them in one
    ``objective(thetas, contexts)`` call and tells the rewards. ``on_checkpoint(rollouts, optimizer)`` is
    called before the first rollout, after every ``checkpoint_every`` rollouts and at the end (batches are
    cut at checkpoints, which the optimisers' rollout-counted updates do not notice); ``progress`` is called
    with the number of rollouts of each batch.
    """
    if not isinstance(budget, int | np.integer) or budget < 1:
        raise InputError(f"budget must be a positive number of rollouts, got {budget!r}")
    if checkpoint_every is not None and (
        not isinstance(checkpoint_every, int | np.integer) or checkpoint_every < 1
    ):
        raise InputError(f"checkpoint_every must be a positive number of rollouts, got {checkpoint_every!r}")
    rng = np.random.default_rng(seed)
    period = checkpoint_every or budget
    contexts_seen: list[np.ndarray] = []
    rewards_seen: list[np.ndarray] = []
    checkpoints: list[int] = []

    def checkpoint(rollouts: int) -> None:
        if on_checkpoint is not None:
            on_checkpoint(rollouts, optimizer)
        checkpoints.append(rollouts)

    checkpoint(0)
    rollouts = 0
    while rollouts < budget:
        count = min(optimizer.batch_size, budget - rollouts, period - rollouts % period)
        contexts = finite_array("sample_contexts' contexts", sample_contexts(rng, count))
        if contexts.ndim != 2 or len(contexts) != count:
            raise InputError(f"sample_contexts returned shape {contexts.shape}, expected ({count}, m)")
        thetas = optimizer.ask(contexts)
        rewards = np.asarray(objective(thetas, contexts), dtype=float)
        if rewards.shape != (count,):
            raise InputError(f"the objective returned rewards of shape {rewards.shape}, expected ({count},)")
        if not np.all(np.isfinite(rewards)):
            raise InputError(
                "the objective returned a NaN or infinite reward (give failures a finite penalty)"
            )
        optimizer.tell(contexts, thetas, rewards)
        contexts_seen.append(contexts)
        rewards_seen.append(rewards)
        rollouts += count
        if progress is not None:
            progress(count)
        if rollouts % period == 0 or rollouts == budget:
            checkpoint(rollouts)
    return ContextualSearchResult(np.concatenate(contexts_seen), np.concatenate(rewards_seen), checkpoints)
