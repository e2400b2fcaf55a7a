"""Policy search: refining a primitive's theta by black-box optimisation of rollout rewards.

An :class:`Optimizer` proposes a population of thetas (:meth:`~Optimizer.ask`) and learns from their rewards
(:meth:`~Optimizer.tell`; rewards are maximised). Two real methods stand behind the interface:

- :class:`CMAES` - CMA-ES (Hansen) through pycma, population size 4 + floor(3 ln n).
- :class:`XNES` - exponential natural evolution strategies (Glasmachers, Schaul, Yi, Wierstra and
  Schmidhuber, GECCO 2010): the search distribution N(m, sigma^2 B B^T) follows the natural gradient of the
  expected rank-based utility; B is updated through a matrix exponential, so it stays invertible.

Both start from a Gaussian N(mean, Sigma) (:class:`WarmStart`): the first population is drawn with that
mean and spread. A diagonal Sigma is given as per-coordinate standard deviations; a full Sigma is handled by
whitening: the optimiser works on z with theta = mean + L z (L the Cholesky factor of Sigma), starting at
z = 0 with unit spread, so its first population has covariance Sigma exactly.

:func:`policy_search` runs optimisers in lockstep: one batch per generation holding every optimiser's
candidates (one task each, or one), so a task that evaluates batches on threads or Ray
(``ThrowingRollouts.evaluate``) sees few large batches. It stops at a rollout budget, a target reward, or when
an optimiser's spread collapses, and records a learning curve per rollout (reward, best so far).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from besman.core.errors import InputError
from besman.core.plugins import plugin_modules, warn_plugin
from besman.core.seeds import cma_seed
from besman.core.validation import (
    CALLABLE,
    COUNT,
    SEED,
    checked,
    finite_array,
    instance,
    integer,
    items,
    number,
    optional,
    shaped,
)


def default_population_size(dimensions: int) -> int:
    """Hansen's default lambda = 4 + floor(3 ln n), shared by both methods."""
    return 4 + int(3 * math.log(dimensions))


@dataclass(frozen=True)
class WarmStart:
    """The Gaussian N(mean, Sigma) a search starts from.

    ``spread`` is either per-coordinate standard deviations (n,) (a diagonal Sigma; a scalar is the same
    for every coordinate) or a full covariance (n, n), symmetric positive definite.
    """

    mean: np.ndarray
    spread: np.ndarray | float

    def __post_init__(self) -> None:
        mean = finite_array("mean", self.mean)
        if mean.ndim != 1 or mean.size == 0:
            raise InputError(f"mean must be a non-empty vector, got shape {mean.shape}")
        spread = finite_array("spread", self.spread)
        n = mean.size
        if spread.ndim == 0:
            spread = np.full(n, float(spread))
        if spread.shape == (n,):
            if np.any(spread <= 0):
                raise InputError("spread: standard deviations must be > 0")
        elif spread.shape == (n, n):
            if not np.allclose(spread, spread.T, rtol=1e-10, atol=1e-12 * np.abs(spread).max()):
                raise InputError("spread: a covariance must be symmetric")
            try:
                np.linalg.cholesky(spread)
            except np.linalg.LinAlgError:
                raise InputError("spread: a covariance must be positive definite") from None
        else:
            raise InputError(
                f"spread must be a scalar, ({n},) standard deviations or ({n}, {n}), got {spread.shape}"
            )
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "spread", spread)

    @property
    def full(self) -> bool:
        return self.spread.ndim == 2

    def factor(self) -> np.ndarray:
        """L with Sigma = L L^T (the diagonal of standard deviations for a diagonal Sigma)."""
        return np.linalg.cholesky(self.spread) if self.full else np.diag(self.spread)

    def covariance(self) -> np.ndarray:
        return self.spread if self.full else np.diag(self.spread**2)


@runtime_checkable  # to check policy_search's optimizers
class Optimizer(Protocol):
    """A population-based optimiser that maximises rewards."""

    population_size: int

    def ask(self) -> np.ndarray:
        """The next population of thetas (population_size, n)."""
        ...

    def tell(self, thetas: np.ndarray, rewards: np.ndarray) -> None:
        """The rewards of the population last asked for (higher is better)."""
        ...

    @property
    def mean(self) -> np.ndarray:
        """The search distribution's mean (in theta)."""
        ...

    def stop(self) -> str | None:
        """Why the search should stop on its own (e.g. its spread collapsed), or None."""
        ...


class _Whitened:
    """theta = mean + L z: the optimisers search z, the caller sees theta."""

    def __init__(self, start: WarmStart) -> None:
        self.start = start
        self._factor = start.factor() if start.full else None

    def to_theta(self, z: np.ndarray) -> np.ndarray:
        return z if self._factor is None else self.start.mean + z @ self._factor.T

    def to_z(self, theta: np.ndarray) -> np.ndarray:
        if self._factor is None:
            return theta
        return np.linalg.solve(self._factor, (theta - self.start.mean).T).T


WARM_START = instance(WarmStart, "a WarmStart")


class CMAES:
    """CMA-ES (pycma) warm-started from ``start``; ``seed`` fixes every sample (same seed, same search)."""

    @checked(start=WARM_START, seed=SEED, population_size=optional(integer(2)))
    def __init__(self, start: WarmStart, *, seed: int, population_size: int | None = None) -> None:
        import cma  # here, not with the module, which tree leaves import: pycma brings matplotlib (0.7 s)

        n = start.mean.size
        self.population_size = population_size or default_population_size(n)
        self._space = _Whitened(start)
        options = {
            "popsize": self.population_size,
            "seed": cma_seed(seed),
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
            "CMA_diagonal": False,
        }
        if start.full:  # z = 0 with unit spread
            self._es = cma.CMAEvolutionStrategy(np.zeros(n), 1.0, options)
        else:  # pycma scales sigma0 by CMA_stds per coordinate
            self._es = cma.CMAEvolutionStrategy(start.mean.copy(), 1.0, {**options, "CMA_stds": start.spread})
        self._asked: list[np.ndarray] | None = None

    def ask(self) -> np.ndarray:
        self._asked = self._es.ask()
        return self._space.to_theta(np.array(self._asked))

    @checked(rewards=shaped(ndim=1))
    def tell(self, thetas: np.ndarray, rewards: np.ndarray) -> None:
        if self._asked is None or len(rewards) != len(self._asked):
            raise InputError("tell() needs the rewards of the population last asked for")
        self._es.tell(self._asked, (-np.asarray(rewards, dtype=float)).tolist())  # pycma minimises
        self._asked = None

    @property
    def mean(self) -> np.ndarray:
        return self._space.to_theta(np.asarray(self._es.mean)[None])[0]

    def stop(self) -> str | None:
        reasons = {key: value for key, value in self._es.stop().items() if key != "maxiter"}
        return ", ".join(f"{key}={value}" for key, value in reasons.items()) or None


class XNES:
    """Exponential NES with rank-based utilities and the default learning rates of Glasmachers et al.:
    eta_mu = 1, eta_sigma = eta_B = 3 (3 + ln n) / (5 n sqrt n)."""

    @checked(start=WARM_START, seed=SEED, population_size=optional(integer(2)))
    def __init__(self, start: WarmStart, *, seed: int, population_size: int | None = None) -> None:
        n = start.mean.size
        self.population_size = population_size or default_population_size(n)
        self._rng = np.random.default_rng(seed)
        self._space = _Whitened(start)
        self._mean = np.zeros(n) if start.full else start.mean.copy()
        # B B^T is the shape of the spread with det B = 1 and sigma its scale (diagonal start: stds).
        stds = np.ones(n) if start.full else start.spread
        self._sigma = float(np.exp(np.mean(np.log(stds))))
        self._shape = np.diag(stds / self._sigma)
        self._eta_sigma = self._eta_shape = 3.0 * (3.0 + math.log(n)) / (5.0 * n * math.sqrt(n))
        ranks = np.arange(1, self.population_size + 1)
        utilities = np.maximum(0.0, math.log(self.population_size / 2 + 1) - np.log(ranks))
        self._utilities = utilities / utilities.sum() - 1.0 / self.population_size
        self._samples: np.ndarray | None = None

    def ask(self) -> np.ndarray:
        self._samples = self._rng.standard_normal((self.population_size, self._mean.size))
        return self._space.to_theta(self._mean + self._sigma * self._samples @ self._shape.T)

    @checked(rewards=shaped(ndim=1))
    def tell(self, thetas: np.ndarray, rewards: np.ndarray) -> None:
        from scipy.linalg import expm  # here, not with the module, which tree leaves import (0.3 s)

        samples = self._samples
        if samples is None or len(rewards) != len(samples):
            raise InputError("tell() needs the rewards of the population last asked for")
        order = np.argsort(-np.asarray(rewards, dtype=float), kind="stable")  # best first
        utilities = np.empty(len(samples))
        utilities[order] = self._utilities
        n = self._mean.size
        gradient_mean = utilities @ samples
        gradient_matrix = (samples * utilities[:, None]).T @ samples - utilities.sum() * np.eye(n)
        gradient_sigma = np.trace(gradient_matrix) / n
        gradient_shape = gradient_matrix - gradient_sigma * np.eye(n)
        self._mean = self._mean + self._sigma * self._shape @ gradient_mean
        self._sigma *= math.exp(0.5 * self._eta_sigma * gradient_sigma)
        self._shape = self._shape @ expm(0.5 * self._eta_shape * gradient_shape)
        self._samples = None

    @property
    def mean(self) -> np.ndarray:
        return self._space.to_theta(self._mean[None])[0]

    def stop(self) -> str | None:
        return "the spread collapsed (sigma < 1e-12)" if self._sigma < 1e-12 else None


# An optimiser by name: a class (or factory) called with a WarmStart, ``seed`` and ``population_size`` (None:
# its own default) that gives an Optimizer. More come from register_optimizer and installed plugins.
OPTIMIZERS: dict[str, Callable[..., Optimizer]] = {"cmaes": CMAES, "xnes": XNES}
ENTRY_POINTS = "besman.optimizers"  # the group under which other distributions name their optimiser modules
_plugins_loaded = False


def register_optimizer(name: str, factory: Callable[..., Optimizer]) -> None:
    """Adds the optimiser ``factory`` under ``name`` (lower case, digits, ``-`` and ``_``): chosen by name
    wherever besman searches (``besman learn --optimizer``,
    :class:`~besman.learning.pipeline.end_to_end.LearnSettings`,
    :func:`make_optimizer`). A name already taken is refused."""
    if not isinstance(name, str) or not re.fullmatch(r"[a-z][a-z0-9_-]*", name):
        raise InputError(f"an optimiser's name is lower case (a-z, 0-9, - and _), got {name!r}")
    if not callable(factory):
        raise InputError(f"optimiser {name!r}: {factory!r} is not a class or function that makes one")
    if name in OPTIMIZERS:
        raise InputError(f"the optimiser {name!r} exists already ({OPTIMIZERS[name]!r})")
    OPTIMIZERS[name] = factory


def optimizer_names() -> list[str]:
    """Every optimiser's name: besman's, those registered, those of installed plugins (a module named under
    :data:`ENTRY_POINTS` whose ``OPTIMIZERS`` maps names to factories; one that cannot be registered is
    named in one warning line and left out)."""
    global _plugins_loaded
    if not _plugins_loaded:
        _plugins_loaded = True
        for who, module in plugin_modules(ENTRY_POINTS, "optimiser"):
            for name, factory in dict(getattr(module, "OPTIMIZERS", {})).items():
                try:
                    register_optimizer(name, factory)
                except InputError as error:
                    warn_plugin(f"{who}: {error} (left out)")
    return list(OPTIMIZERS)


def check_optimizer(method: str, where: str = "optimizer") -> str:
    """``method`` if it names an optimiser, else an error listing them (``where``: the option or field)."""
    names = optimizer_names()
    if method not in names:
        raise InputError(f"{where} must be one of {', '.join(names)}, got {method!r}")
    return method


def make_optimizer(
    method: str, start: WarmStart, *, seed: int, population_size: int | None = None
) -> Optimizer:
    """The optimiser ``method`` (:func:`optimizer_names`) warm-started from ``start``; what it makes is
    checked to be an :class:`Optimizer`."""
    made = OPTIMIZERS[check_optimizer(method, "method")](start, seed=seed, population_size=population_size)
    if not isinstance(made, Optimizer):
        raise InputError(f"optimiser {method!r} made {made!r}, which has no ask, tell, mean and stop")
    return made


@dataclass
class SearchResult:
    """One optimiser's search.

    Attributes:
        best_theta, best_reward: the best rollout's theta and reward.
        rewards, thetas: the reward and theta of every rollout, in order.
        start_theta, start_reward: the start mean and its reward (rollout 0, not counted in the budget), if
            evaluated.
        stopped: why the search ended.
    """

    best_theta: np.ndarray
    best_reward: float
    rewards: list[float] = field(default_factory=list)
    start_reward: float | None = None
    stopped: str = ""
    thetas: list[np.ndarray] = field(default_factory=list)
    start_theta: np.ndarray | None = None

    @property
    def rollouts(self) -> int:
        return len(self.rewards)

    def curve(self) -> np.ndarray:
        """(rollouts + 1, 3) rows [rollout r, reward of rollout r, best reward of rollouts 0..r]; row 0 is the
        start mean (NaN if it was not evaluated), so the best so far starts there."""
        rewards = np.array([np.nan if self.start_reward is None else self.start_reward, *self.rewards])
        best = np.fmax.accumulate(rewards)
        return np.column_stack([np.arange(len(rewards)), rewards, best])

    def best_within(self, budget: int) -> tuple[np.ndarray, float]:
        """The best theta and reward of the start (if evaluated) and the first ``budget`` rollouts: the
        search as its budget counts it (its last generation may pass the budget; :meth:`curve` at row
        ``budget``)."""
        rewards = [-math.inf if self.start_reward is None else self.start_reward, *self.rewards[:budget]]
        best = int(np.argmax(rewards))
        return (self.start_theta if best == 0 else self.thetas[best - 1]), float(rewards[best])


Objective = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""rewards (N,) of thetas (N, n) for the optimisers' indices (N,): one batch for all of them."""


@checked(
    objective=CALLABLE,
    optimizers=items(instance(Optimizer, "an optimizer (learning.make_optimizer)"), "a list of optimizers"),
    budget=COUNT,
    evaluate_start=instance(bool, "True or False"),
    target_reward=optional(number),
    progress=optional(CALLABLE),
)
def policy_search(
    objective: Objective,
    optimizers: Sequence[Optimizer],
    *,
    budget: int,
    evaluate_start: bool = True,
    target_reward: float | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[SearchResult]:
    """Runs ``optimizers`` in lockstep for ``budget`` rollouts each (whole generations: the last may pass the
    budget; the curves say what each rollout did), one objective batch per generation.

    ``objective(thetas, owners)`` returns the rewards of thetas proposed by ``optimizers[owner]``. With
    ``evaluate_start`` the start means are evaluated first (rollout 0 of the curves). An optimiser stops
    early when a rollout reaches ``target_reward`` or its own stopping rule fires; ``progress`` is called with
    the number of rollouts of each batch.
    """
    results = [SearchResult(opt.mean.copy(), -math.inf, start_theta=opt.mean.copy()) for opt in optimizers]
    if evaluate_start:
        means = np.array([opt.mean for opt in optimizers])
        rewards = _checked(objective(means, np.arange(len(optimizers))), len(optimizers))
        for result, mean, reward in zip(results, means, rewards, strict=True):
            result.start_reward, result.best_theta, result.best_reward = float(reward), mean, float(reward)
    active = list(range(len(optimizers)))
    while active:
        populations = [optimizers[i].ask() for i in active]
        owners = np.concatenate([np.full(len(p), i) for i, p in zip(active, populations, strict=True)])
        rewards = _checked(objective(np.concatenate(populations), owners), len(owners))
        if progress is not None:
            progress(len(owners))
        still = []
        for i, population in zip(active, populations, strict=True):
            mine = rewards[owners == i]
            optimizers[i].tell(population, mine)
            result = results[i]
            result.rewards.extend(mine.tolist())
            result.thetas.extend(np.array(population, dtype=float))
            best = int(np.argmax(mine))
            if mine[best] > result.best_reward:
                result.best_reward, result.best_theta = float(mine[best]), population[best].copy()
            reason = optimizers[i].stop()
            if result.rollouts >= budget:
                result.stopped = f"budget of {budget} rollouts"
            elif target_reward is not None and result.best_reward >= target_reward:
                result.stopped = f"reached the target reward {target_reward:g}"
            elif reason is not None:
                result.stopped = reason
            else:
                still.append(i)
        active = still
    return results


def _checked(rewards, n: int) -> np.ndarray:
    rewards = np.asarray(rewards, dtype=float)
    if rewards.shape != (n,):
        raise InputError(f"the objective returned rewards of shape {rewards.shape}, expected ({n},)")
    if not np.all(np.isfinite(rewards)):
        raise InputError("the objective returned a NaN or infinite reward (give failures a finite penalty)")
    return rewards
