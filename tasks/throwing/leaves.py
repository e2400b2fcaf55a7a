"""Throwing leaves for the PA-10: aim with a skill template, then throw.

- :class:`AimThrow` reads the ``target`` (x, y on the floor) and instantiates the throwing skill template
  there: Theta(tau) is the throw, Omega(tau) the template's uncertainty (Metzen et al. 2014). Where the
  template's own throw would miss by more than ``accept`` m in simulation, the leaf refines it as the paper
  does, by CMA-ES started from N(Theta(tau), Omega(tau)) on simulated throws (the task's rollouts, apart
  from the running simulation) until one lands within ``accept`` or ``budget`` throws are spent; the
  template's throw and the best are thrown once more, and the best is kept only where it gained more than
  the reward's noise (:mod:`~besman.learning.search.acceptance`). It writes the throw's parameters (role
  ``throw``).
- :class:`Throw` executes the throw in the running simulation
  (:class:`~besman.tasks.throwing.executor.ThrowingExecutor`), RUNNING while the ball flies, and writes where
  it landed (role ``landing``); it succeeds if the ball lands within ``tolerance`` m of the ``target``.

Blackboard keys: ``/<ns>/throw``, the throw aimed at ``/<ns>/target`` (the instantiated, possibly refined,
template), ``AimThrow`` writes and ``Throw`` reads; ``/<ns>/landing``, where the ball first touched the floor
(x, y), ``Throw`` writes. Both are node types as any distribution's are (:data:`NODE_TYPES`, named under
the entry-point group ``besman.node_types`` in besman's own ``pyproject.toml``).
"""

from __future__ import annotations

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
    from besman.tasks.throwing.executor import ThrowingExecutor


def _throwing(name: str, executor) -> ThrowingExecutor:
    from besman.tasks.throwing.executor import ThrowingExecutor  # to run: listing the leaves needs no MuJoCo

    if not isinstance(executor, ThrowingExecutor):
        raise InputError(f"{name}: throwing needs the PA-10's throwing executor (besman demo throwing)")
    return executor


class AimThrow(TemplateAim):
    """Instantiates the throwing template ``template`` of ``pool`` for the ``target`` and refines it in
    simulation where it would miss by more than ``accept`` m; writes ``throw``."""

    roles: ClassVar = {"target": Access.READ, "throw": Access.WRITE}
    parameters: ClassVar = {**TEMPLATE_PARAMETERS, "accept": "float>0", "budget": "int>=0", "seed": "int"}

    def __init__(
        self,
        name: str,
        *,
        pool: Mapping[str, Any],
        template: str = "throw",
        accept: float = 0.25,
        budget: int = 400,
        seed: int = 0,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(
            name, pool=pool, template=template, budget=budget, seed=seed, namespace=namespace, remap=remap
        )
        self.accept = accept
        self.expected_miss: float | None = None  # m, of the chosen throw in simulation
        self.use("target")
        self.use("throw")

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        _throwing(self.name, self.executor)

    def update(self) -> Status:
        task = self.executor.task
        tau = np.asarray(self.blackboard.get("target"), dtype=float)
        # The reward is minus the squared miss (m^2); a throw that lands nowhere scores <= -1000.
        aimed = self.aim("target", tau, lambda thetas: task.evaluate(thetas, tau).rewards, -(self.accept**2))
        if aimed is None:
            return Status.FAILURE
        self.expected_miss = float(np.sqrt(-aimed.reward)) if aimed.reward > -1000 else None
        self.blackboard.set("throw", aimed.theta, overwrite=True)
        predicted = aimed.instance_reward
        predicted_miss = "no landing" if predicted <= -1000 else f"{np.sqrt(-predicted):.2f} m"
        expected = "no landing" if self.expected_miss is None else f"{self.expected_miss:.2f} m"
        self.feedback_message = (
            f"template at {np.round(tau, 2).tolist()}: misses by {predicted_miss}; "
            f"after {self.rollouts} simulated throws: {expected}{self.refinement_text()}"
        )
        return Status.SUCCESS


class Throw(SimulationBehaviour):
    """Throws ``throw`` and writes the ``landing``; succeeds if it is within ``tolerance`` m of ``target``."""

    roles: ClassVar = {"throw": Access.READ, "target": Access.READ, "landing": Access.WRITE}
    parameters: ClassVar = {"tolerance": "float>0"}

    def __init__(
        self,
        name: str,
        *,
        tolerance: float = 0.5,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        self.tolerance = tolerance
        self.flight = None
        self.problem = ""
        for role in self.roles:
            self.use(role)

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        _throwing(self.name, self.executor)

    def initialise(self) -> None:
        self.problem, self.flight = "", None
        try:
            self.flight = self.executor.start_throw(self.blackboard.get("throw"))
        except (ValueError, KeyError) as error:
            self.problem = str(error)

    def update(self) -> Status:
        if self.problem:
            self.feedback_message = self.problem
            return Status.FAILURE
        flight = self.flight
        if flight.status is MotionStatus.RUNNING:
            self.feedback_message = "released, in flight" if flight.step > flight.release_step else "swinging"
            return Status.RUNNING
        if flight.status is MotionStatus.FAILED:
            self.feedback_message = flight.failure
            return Status.FAILURE
        self.blackboard.set("landing", flight.landing, overwrite=True)
        target = np.asarray(self.blackboard.get("target"), dtype=float)
        miss = float(np.linalg.norm(flight.landing - target))
        self.feedback_message = (
            f"landed at {np.round(flight.landing, 2).tolist()}, {miss:.2f} m from the target"
        )
        return Status.SUCCESS if miss <= self.tolerance else Status.FAILURE


NODE_TYPES = (AimThrow, Throw)  # registered by besman.trees.nodes (its entry points)
