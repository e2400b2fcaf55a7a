"""Ball-in-a-cup leaves for the UR5e: choose the swing with a skill template over the string's length, then
swing.

- :class:`AimSwing` reads the string's length (``string``, m) and instantiates the ball-in-a-cup skill
  template there: Theta(tau) is the swing, Omega(tau) the template's uncertainty (Metzen et al. 2014). Where
  the template's own swing would not catch the ball in simulation (the task's rollouts, apart from the
  running simulation), the leaf refines it by CMA-ES started from N(Theta(tau), Omega(tau)) (population
  ``population``) until a simulated swing catches or ``budget`` swings are spent; the template's swing and
  the best are swung once more, and the best is kept only where it gained more than the reward's noise
  (:mod:`~besman.learning.search.acceptance`). It writes the swing's parameters (role ``swing``).
- :class:`Swing` executes the swing in the running simulation
  (:class:`~besman.tasks.ball_in_cup.executor.CatchExecutor`), RUNNING while the arm swings and the ball flies
  and settles, and writes where the ball ended in the cup's frame (role ``ball``); it succeeds if the ball is
  inside the cup for the swing's last 0.25 s (the task's rule).

Blackboard keys: ``/<ns>/swing``, the swing for ``/<ns>/string`` (the instantiated, possibly refined,
template), ``AimSwing`` writes and ``Swing`` reads; ``/<ns>/ball``, the ball's centre at the end (x, y, z in
the cup's frame), ``Swing`` writes. Both are node types as any distribution's are (:data:`NODE_TYPES`, named
under the entry-point group ``besman.node_types`` in besman's own ``pyproject.toml``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from py_trees.common import Access, Status

from besman.core.errors import InputError
from besman.core.validation import SEED
from besman.learning.search.acceptance import Acceptance
from besman.learning.search.online import search_instance
from besman.sim.motions import MotionStatus
from besman.tasks.ball_in_cup.executor import CatchExecutor
from besman.trees.base import SimulationBehaviour
from besman.trees.manipulation import TEMPLATE_PARAMETERS


def _catching(name: str, executor) -> CatchExecutor:
    if not isinstance(executor, CatchExecutor):
        raise InputError(
            f"{name}: ball-in-a-cup needs the UR5e's catching executor (besman demo ball-in-cup)"
        )
    return executor


class AimSwing(SimulationBehaviour):
    """Instantiates the template ``template`` of ``pool`` for the ``string`` length and refines it in
    simulation where it would not catch, with at most ``budget`` more simulated swings; writes ``swing``."""

    roles: ClassVar = {"string": Access.READ, "swing": Access.WRITE}
    parameters: ClassVar = {
        **TEMPLATE_PARAMETERS,
        "budget": "int>=0",
        "population": "int>0",
        "seed": "int",
    }

    def __init__(
        self,
        name: str,
        *,
        pool: Mapping[str, Any],
        template: str = "ball_in_cup",
        budget: int = 10,
        population: int = 5,
        seed: int = 0,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        if template not in pool:
            raise InputError(f"{name}: the pool has no template {template!r} (has: {', '.join(pool)})")
        self.template = pool[template]
        self.budget, self.population = budget, population
        self.seed = SEED(f"{name}: seed", seed)  # out of range: refused with the file, not mid-run
        self.instantiated: tuple | None = None  # (template, tau) of the last aim, for viewers
        self.rollouts = 0  # simulated swings of the last aim
        self.expected: bool | None = None  # whether the chosen swing catches in simulation
        self.acceptance: Acceptance | None = None  # the last aim's refinement's verdict (None: none ran)
        self.use("string")
        self.use("swing")

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        _catching(self.name, self.executor)

    def update(self) -> Status:
        task = self.executor.task
        tau = np.asarray(self.blackboard.get("string"), dtype=float).reshape(-1)
        try:
            self.template.box.check(tau)
            mean, covariance = self.template.distribution(tau)
        except ValueError as error:
            self.feedback_message = f"string {tau.tolist()}: {error}"
            return Status.FAILURE

        def swings(thetas: np.ndarray) -> np.ndarray:
            return task.evaluate(thetas, tau).rewards

        evaluation = task.evaluate(mean[None], tau)
        (predicted,), (predicted_reward,) = evaluation.details, evaluation.rewards
        best, caught, self.rollouts, self.acceptance = mean, predicted.success, 1, None
        if not caught and self.budget > 0:
            found = search_instance(
                swings,
                mean,
                covariance,
                predicted_reward,
                budget=self.budget,
                seed=self.seed,
                target_reward=1e-9,  # every catch scores > 0, every miss <= 0
                population_size=min(self.population, self.budget),
            )
            self.acceptance, self.rollouts = found.acceptance, self.rollouts + found.rollouts
            if found.acceptance.accepted:
                best, caught = found.theta, found.reward > 0
        self.expected = caught
        self.instantiated = (self.template, tau)
        self.blackboard.set("swing", best, overwrite=True)
        refined = "" if self.acceptance is None else f" (the refinement's {self.acceptance.text()})"
        self.feedback_message = (
            f"template at {tau[0]:.3f} m: {'catches' if predicted.success else 'misses'} in simulation; "
            f"after {self.rollouts} simulated swings: {'catches' if caught else 'still misses'}{refined}"
        )
        return Status.SUCCESS


class Swing(SimulationBehaviour):
    """Swings ``swing`` and writes where the ``ball`` ended (cup frame); succeeds if it was caught."""

    roles: ClassVar = {"swing": Access.READ, "ball": Access.WRITE}
    parameters: ClassVar = {}

    def __init__(self, name: str, *, namespace: str = "", remap: Mapping[str, str] | None = None) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        self.swing = None
        self.problem = ""
        for role in self.roles:
            self.use(role)

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        _catching(self.name, self.executor)

    def initialise(self) -> None:
        self.problem, self.swing = "", None
        try:
            self.swing = self.executor.start_swing(self.blackboard.get("swing"))
        except (ValueError, KeyError) as error:
            self.problem = str(error)

    def update(self) -> Status:
        if self.problem:
            self.feedback_message = self.problem
            return Status.FAILURE
        swing = self.swing
        if swing.status is MotionStatus.RUNNING:
            seconds = swing.step * self.executor.world.model.opt.timestep
            self.feedback_message = f"swinging, {seconds:.2f} s"
            return Status.RUNNING
        detail = swing.detail
        if detail.failure is not None:
            self.feedback_message = detail.failure
            return Status.FAILURE
        ball = np.round(swing.ball[-1], 3)
        self.blackboard.set("ball", ball, overwrite=True)
        self.feedback_message = (
            f"the ball is {'in' if detail.success else 'not in'} the cup, at {ball.tolist()} (cup frame)"
        )
        return Status.SUCCESS if detail.success else Status.FAILURE


NODE_TYPES = (AimSwing, Swing)  # registered by besman.trees.nodes (its entry points)
