"""Leaves that aim and run a task's open-loop motion (:mod:`besman.sim.open_loop_executor`) with a skill
template over the task's parameters tau; a task's own leaves are thin subclasses that name their roles and
words (ball-in-a-cup's :mod:`~besman.tasks.ball_in_cup.leaves`, the puck strike's
:mod:`~besman.tasks.puck_strike.leaves`).

- :class:`OpenLoopAim` reads tau (its one read role) and instantiates the template ``template`` of ``pool``
  there: Theta(tau) is the motion, Omega(tau) the template's uncertainty (Metzen et al. 2014). Where the
  template's own motion would not succeed in simulation (the task's rollouts, apart from the running
  simulation), it refines it by CMA-ES started from N(Theta(tau), Omega(tau)) (population ``population``)
  until a simulated motion succeeds or ``budget`` motions are spent; the template's motion and the best are
  simulated once more, and the best is kept only where it gained more than the reward's noise
  (:mod:`~besman.learning.search.acceptance`). It writes theta (its one write role); a tau outside the
  template's box fails it, with a message that names the value.
- :class:`OpenLoopRun` executes theta (its one read role) in the running simulation
  (:class:`~besman.sim.open_loop_executor.OpenLoopExecutor`), RUNNING while the motion and what it set going
  run, and writes the task's outcome (its one write role); it succeeds if the rollouts' detail says the run
  succeeded (the task's rule).
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from py_trees.common import Access, Status

from besman.core.errors import InputError
from besman.sim.motion_status import MotionStatus
from besman.trees.aim import TemplateAim
from besman.trees.base import SimulationBehaviour
from besman.trees.manipulation import TEMPLATE_PARAMETERS

if TYPE_CHECKING:
    from besman.sim.open_loop_executor import OpenLoopMotion

# The open-loop executor and the tasks' rewards (MuJoCo) are imported where a leaf runs: building a tree or
# listing its node types needs no MuJoCo.


def _role(cls: type, access: Access) -> str:
    """The one role of ``cls`` with ``access``."""
    (role,) = (role for role, given in cls.roles.items() if given is access)
    return role


class OpenLoopBehaviour(SimulationBehaviour):
    """A leaf that needs the open-loop executor; ``demo`` names the demo that has one, for the message."""

    demo: ClassVar[str] = ""

    def setup(self, **kwargs) -> None:
        from besman.sim.open_loop_executor import OpenLoopExecutor

        super().setup(**kwargs)
        if not isinstance(self.executor, OpenLoopExecutor):
            raise InputError(
                f"{self.name}: {type(self).__name__} needs the open-loop executor "
                f"(besman.sim.open_loop_executor.OpenLoopExecutor: besman demo {self.demo})"
            )


class OpenLoopAim(TemplateAim, OpenLoopBehaviour):
    """Instantiates the template ``template`` of ``pool`` at tau and refines it in simulation where it would
    not succeed, with at most ``budget`` more simulated motions; writes theta.

    A subclass declares ``roles`` (tau read, theta written), ``default_template`` (the default of
    ``template``) and the words of its feedback: ``unit`` (tau's), ``motions`` (what a simulated motion is
    called, plural), ``succeeds`` and ``fails`` (what a motion does)."""

    parameters: ClassVar = {
        **TEMPLATE_PARAMETERS,
        "budget": "int>=0",
        "population": "int>0",
        "seed": "int",
    }
    default_template: ClassVar[str] = ""
    unit: ClassVar[str] = "m"
    motions: ClassVar[str] = "motions"
    succeeds: ClassVar[str] = "succeeds"
    fails: ClassVar[str] = "fails"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """The constructor's signature, as the node reference reads it: ``template`` defaults to the class's
        ``default_template`` (None, the constructor's default, stands for it)."""
        super().__init_subclass__(**kwargs)
        signature = inspect.signature(cls.__init__)
        parameters = list(signature.parameters.values())[1:]  # without self
        cls.__signature__ = signature.replace(
            parameters=[
                p.replace(default=cls.default_template) if p.name == "template" and p.default is None else p
                for p in parameters
            ],
            return_annotation=inspect.Signature.empty,
        )

    def __init__(
        self,
        name: str,
        *,
        pool: Mapping[str, Any],
        template: str | None = None,
        budget: int = 10,
        population: int = 5,
        seed: int = 0,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        template = self.default_template if template is None else template
        super().__init__(
            name, pool=pool, template=template, budget=budget, seed=seed, namespace=namespace, remap=remap
        )
        self.population = population
        self.tau_role, self.theta_role = _role(type(self), Access.READ), _role(type(self), Access.WRITE)
        self.expected: bool | None = None  # whether the chosen motion succeeds in simulation
        for role in self.roles:
            self.use(role)

    def where(self, tau: np.ndarray) -> str:
        """tau for the feedback: "0.375 m", "(1.550, 0.135) m"."""
        values = ", ".join(f"{value:.3f}" for value in tau)
        return f"{values if tau.size == 1 else f'({values})'} {self.unit}"

    def update(self) -> Status:
        from besman.sim.open_loop import SUCCESS

        rollouts = self.executor.rollouts
        tau = np.asarray(self.blackboard.get(self.tau_role), dtype=float).reshape(-1)
        aimed = self.aim(
            self.tau_role,
            tau,
            lambda thetas: rollouts.evaluate(thetas, tau).rewards,
            SUCCESS,
            min(self.population, self.budget) if self.budget > 0 else None,
        )
        if aimed is None:
            return Status.FAILURE
        predicted, self.expected = (
            aimed.instance_reward >= SUCCESS,
            aimed.reward >= SUCCESS,
        )
        self.blackboard.set(self.theta_role, aimed.theta, overwrite=True)
        self.feedback_message = (
            f"template at {self.where(tau)}: {self.succeeds if predicted else self.fails} in "
            f"simulation; after {self.rollouts} simulated {self.motions}: "
            f"{self.succeeds if self.expected else 'still ' + self.fails}{self.refinement_text()}"
        )
        return Status.SUCCESS


class OpenLoopRun(OpenLoopBehaviour):
    """Executes theta and writes the task's outcome; succeeds if the rollouts' detail says it succeeded.

    A subclass declares ``roles`` (theta read, the outcome written), ``doing`` (the feedback while it runs)
    and :meth:`outcome`."""

    parameters: ClassVar = {}
    doing: ClassVar[str] = "running"

    def __init__(self, name: str, *, namespace: str = "", remap: Mapping[str, str] | None = None) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        self.theta_role, self.outcome_role = _role(type(self), Access.READ), _role(type(self), Access.WRITE)
        self.motion: OpenLoopMotion | None = None
        self.problem = ""
        for role in self.roles:
            self.use(role)

    def outcome(self, motion: OpenLoopMotion) -> tuple[Any, str]:
        """What the motion, run to its end, wrote (the outcome role's value) and says (the feedback)."""
        raise NotImplementedError

    def initialise(self) -> None:
        self.problem, self.motion = "", None
        try:
            self.motion = self.executor.start_motion(self.blackboard.get(self.theta_role))
        except (ValueError, KeyError) as error:
            self.problem = str(error)

    def update(self) -> Status:
        if self.problem:
            self.feedback_message = self.problem
            return Status.FAILURE
        motion = self.motion
        if motion.status is MotionStatus.RUNNING:
            self.feedback_message = f"{self.doing}, {motion.elapsed:.2f} s"
            return Status.RUNNING
        detail = motion.detail
        if detail.failure is not None:
            self.feedback_message = detail.failure
            return Status.FAILURE
        value, self.feedback_message = self.outcome(motion)
        self.blackboard.set(self.outcome_role, value, overwrite=True)
        return Status.SUCCESS if detail.success else Status.FAILURE
