"""Online refinement: a skill template's instance tried out in a copy of the world before the real execution.

A template is sure of some tasks (near its training tasks) and unsure of others. :func:`uncertainty` is
the spread of its Gaussian at tau, Omega(tau), over the parameters the training tasks varied (root mean
variance, in theta units: 0.1 rad per unit for the pick-and-place blocks). Where it is high, a few
rollouts of the block in a fork of the world (:meth:`besman.sim.world.World.fork`, the simulation state of
the moment) can find a better theta: CMA-ES started at N(Theta(tau), Omega(tau)) - the exploration the
template itself prescribes (Metzen et al. 2014) - for at most :data:`MAX_ROLLOUTS` rollouts, the mean's
included. The real execution then uses the best theta if it beat the mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.sim.block_simulation import BlockStart, Reward, rollout
from besman.sim.world import World
from besman.skills import MovementPrimitive, SkillTemplate

MAX_ROLLOUTS = 25
DEFAULT_REWARD = Reward()
POPULATION = 8  # the mean and three generations of eight: 25 rollouts


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

    @property
    def improved(self) -> bool:
        return self.best_reward > self.mean_reward


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
    result = policy_search(objective, [search], budget=max(1, budget - 1))[0]
    chosen = result.best_theta if result.best_reward > result.start_reward else mean[mask]
    theta = mean.copy()
    theta[mask] = chosen
    return Refinement(
        template.primitive(theta, tau),
        result.start_reward,
        result.best_reward,
        result.rollouts + 1,
        successes[chosen.tobytes()],
    )
