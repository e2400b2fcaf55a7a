"""Aiming with a skill template: a leaf instantiates a template of a pool at the run's tau and, where the
instance would not do in simulation, refines it there before the real motion (Metzen et al. 2014: Theta(tau)
is the motion, Omega(tau) the template's uncertainty, which sets the search's exploration).

:class:`TemplateAim` holds what such leaves share - the template named in the tree file (checked when the
tree is built), the refinement's budget and seed, and :meth:`TemplateAim.aim`: the instance simulated once
and, where its reward falls short of a target, CMA-ES from N(Theta(tau), Omega(tau)) on simulated rollouts
(the task's, apart from the running simulation) until one reaches it or the budget is spent, the best kept
only where it gained more than the reward's noise (:func:`~besman.learning.search.online.search_instance`).
The throwing aim (:class:`~besman.tasks.throwing.leaves.AimThrow`) and the open-loop tasks' aims
(:class:`~besman.trees.open_loop.OpenLoopAim`) are such leaves.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from besman.core.validation import SEED
from besman.trees.base import SimulationBehaviour
from besman.trees.templates import check_template

if TYPE_CHECKING:
    from besman.learning.search.acceptance import Acceptance


@dataclass(frozen=True)
class Aimed:
    """An aim's outcome: the theta chosen, its simulated reward and the instance's own (before any search)."""

    theta: np.ndarray
    reward: float
    instance_reward: float


class TemplateAim(SimulationBehaviour):
    """A leaf that instantiates the template ``template`` of ``pool`` at tau and refines it in simulation
    with at most ``budget`` more rollouts (seeded by ``seed``); see the module documentation."""

    def __init__(
        self,
        name: str,
        *,
        pool: Mapping[str, Any],
        template: str,
        budget: int,
        seed: int,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        check_template(name, pool, template)
        self.template = pool[template]
        self.budget = budget
        self.seed = SEED(f"{name}: seed", seed)  # out of range: refused with the file, not mid-run
        self.instantiated: tuple | None = None  # (template, tau) of the last aim, for viewers
        self.rollouts = 0  # simulated rollouts of the last aim
        self.acceptance: Acceptance | None = None  # the last aim's refinement's verdict (None: none ran)

    def aim(
        self,
        what: str,
        tau: np.ndarray,
        simulated: Callable[[np.ndarray], np.ndarray],
        target_reward: float,
        population: int | None = None,
    ) -> Aimed | None:
        """The template's instance at ``tau`` (named ``what`` in messages), refined where its reward from
        ``simulated(thetas) -> rewards`` is below ``target_reward``; None, with the reason as the leaf's
        feedback, for a tau the template does not take."""
        try:
            self.template.box.check(tau)
            mean, covariance = self.template.distribution(tau)
        except ValueError as error:
            self.feedback_message = f"{what} {tau.tolist()}: {error}"
            return None
        (instance_reward,) = simulated(mean[None])
        theta, reward, self.rollouts, self.acceptance = mean, float(instance_reward), 1, None
        if reward < target_reward and self.budget > 0:
            from besman.learning.search.online import search_instance  # MuJoCo: only where it refines

            found = search_instance(
                simulated,
                mean,
                covariance,
                reward,
                budget=self.budget,
                seed=self.seed,
                target_reward=target_reward,
                population_size=population,
            )
            theta, reward, self.acceptance = found.theta, float(found.reward), found.acceptance
            self.rollouts += found.rollouts
        self.instantiated = (self.template, tau)
        return Aimed(theta, reward, float(instance_reward))

    def refinement_text(self) -> str:
        """The last aim's refinement's verdict for the feedback ("" where none ran)."""
        return "" if self.acceptance is None else f" (the refinement's {self.acceptance.text()})"
