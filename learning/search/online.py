"""Online refinement: a skill template's instance tried out in a copy of the world before the real execution.

A template is sure of some tasks (near its training tasks) and unsure of others. :func:`uncertainty` is
the spread of its Gaussian at tau, Omega(tau), over the parameters the training tasks varied (root mean
variance, in theta units: 0.1 rad per unit for the pick-and-place blocks). Where it is high, a few
rollouts of the block in a fork of the world (:meth:`besman.sim.world.World.fork`, the simulation state of
the moment) can find a better theta: CMA-ES started at N(Theta(tau), Omega(tau)) - the exploration the
template itself prescribes (Metzen et al. 2014) - for at most :data:`MAX_ROLLOUTS` rollouts, the mean's
included. The mean and the best theta are run once more, and the real execution uses the best theta only if
it beat the mean by more than the reward's noise (:mod:`besman.learning.search.acceptance`; the fork's
rollouts reproduce, so the noise is 0). :func:`search_instance` is the same search for a leaf that aims with
a template in its task's own rollouts (a throw, a swing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.learning.search.acceptance import Acceptance, reevaluated
from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.sim.block_simulation import BlockStart, Reward, rollout
from besman.sim.world import World
from besman.skills import MovementPrimitive, SkillTemplate

POPULATION = 8
REPEATS = 1  # the mean and the best theta evaluated again: the reward's noise (0 where rollouts reproduce)
MAX_ROLLOUTS = 1 + 3 * POPULATION + 2 * REPEATS  # the mean, three generations of eight, the two again: 27
DEFAULT_REWARD = Reward()


def varying(template: SkillTemplate) -> np.ndarray:
    """The theta entries the training tasks do not agree on (the others are fixed by the prototype)."""
    return template.thetas.std(axis=0) > 1e-9 * max(1.0, float(np.abs(template.thetas).max()))


def uncertainty(template: SkillTemplate, tau) -> float:
    """The template's spread at tau over the varying entries of theta (root mean variance, theta units)."""
    _, variance = template.predict(tau)
    mask = varying(template)
    return float(np.sqrt(variance[mask].mean())) if mask.any() else 0.0


@dataclass(frozen=True)
class Refinement:
    """The result of refining online: the primitive to execute and what the rollouts found."""

    primitive: MovementPrimitive
    mean_reward: float
    best_reward: float
    rollouts: int
    success: bool  # the chosen theta's rollout succeeded
    acceptance: Acceptance | None = None  # None: nothing was explored

    @property
    def improved(self) -> bool:
        return self.acceptance is not None and self.acceptance.accepted


def refine_online(
    world: World,
    start: BlockStart,
    template: SkillTemplate,
    tau,
    *,
    budget: int = MAX_ROLLOUTS,
    seed: int = 0,
    reward: Reward = DEFAULT_REWARD,
    optimizer: str = "cmaes",
) -> Refinement:
    """At most ``budget`` rollouts of ``start``'s block in a fork of ``world`` (module documentation), the
    search by ``optimizer`` (:func:`~besman.learning.search.policy_search.optimizer_names`)."""
    mask = varying(template)
    if not mask.any():  # nothing to explore: the template is certain
        return Refinement(template.instantiate(tau), np.nan, np.nan, 0, True)
    mean, covariance = template.distribution(np.asarray(tau, dtype=float))
    fork = world.fork()
    primitive = template.primitive(mean, tau)
    successes = {}

    def objective(candidates: np.ndarray, owners: np.ndarray) -> np.ndarray:
        rewards = []
        for candidate in candidates:
            theta = mean.copy()
            theta[mask] = candidate
            primitive.dmp.set_params(theta)
            outcome = rollout(fork, start, primitive)
            successes[candidate.tobytes()] = outcome.success
            rewards.append(reward.score(outcome))
        return np.array(rewards)

    spread = np.sqrt(np.maximum(np.diag(covariance)[mask], 1e-12))
    search = make_optimizer(optimizer, WarmStart(mean[mask], spread), seed=seed, population_size=POPULATION)
    result = policy_search(objective, [search], budget=max(1, budget - 1 - 2 * REPEATS))[0]
    acceptance = reevaluated(
        lambda thetas: objective(thetas, np.zeros(len(thetas))),
        mean[mask],
        result.best_theta,
        REPEATS,
        (result.start_reward, result.best_reward),
    )
    chosen = result.best_theta if acceptance.accepted else mean[mask]
    theta = mean.copy()
    theta[mask] = chosen
    return Refinement(
        template.primitive(theta, tau),
        result.start_reward,
        result.best_reward,
        result.rollouts + 1 + 2 * REPEATS,
        successes[chosen.tobytes()],
        acceptance,
    )


@dataclass(frozen=True)
class InstanceSearch:
    """A template instance searched in simulation before it acts (a leaf's aim): the theta to use, its
    reward, the rollouts the search and the repeated evaluations took, and the verdict."""

    theta: np.ndarray
    reward: float
    rollouts: int
    acceptance: Acceptance


def search_instance(
    evaluate,
    mean: np.ndarray,
    covariance: np.ndarray,
    start_reward: float,
    *,
    budget: int,
    seed: int,
    target_reward: float,
    population_size: int | None = None,
) -> InstanceSearch:
    """CMA-ES from the instance N(``mean``, ``covariance``), whose reward ``start_reward`` the caller has
    measured, on ``evaluate(thetas) -> rewards`` for at most ``budget`` rollouts or until one reaches
    ``target_reward``; the mean and the best are evaluated :data:`REPEATS` times more, and the best is kept
    only where it gained more than the reward's noise (else the mean)."""
    search = make_optimizer("cmaes", WarmStart(mean, covariance), seed=seed, population_size=population_size)
    (result,) = policy_search(
        lambda thetas, _: evaluate(thetas),
        [search],
        budget=budget,
        evaluate_start=False,
        target_reward=target_reward,
    )
    acceptance = reevaluated(evaluate, mean, result.best_theta, REPEATS, (start_reward, result.best_reward))
    kept = acceptance.accepted
    return InstanceSearch(
        result.best_theta if kept else mean,
        result.best_reward if kept else start_reward,
        len(result.rewards) + 2 * REPEATS,
        acceptance,
    )
