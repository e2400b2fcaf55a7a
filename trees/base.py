"""What besman's leaves share: the executor they drive and their blackboard clients.

Every besman behaviour is a real ``py_trees.behaviour.Behaviour``. Those that touch the simulation get the
:class:`~besman.sim.executor.Executor` in ``setup(executor=...)`` (``BehaviourTree.setup(executor=...)``
passes it to every behaviour), and read the simulated clock from it, so timers run in simulated time.

Blackboard access goes through py_trees' access-controlled clients. A leaf declares the keys it reads and
writes by *role* ("object_position", "primitive", ...) with defaults in its skill instance's namespace
(``/<namespace>/<role>``); ``remap`` points a role at any other key, which is how tree files wire subtrees
together (see :mod:`besman.trees.blackboard` for the layout).
"""

from __future__ import annotations

from collections.abc import Mapping

import py_trees

from besman.sim.executor import Executor


class SimulationBehaviour(py_trees.behaviour.Behaviour):
    """A behaviour that needs the executor (given to ``setup``) and may use the blackboard by role."""

    def __init__(self, name: str, *, namespace: str = "", remap: Mapping[str, str] | None = None) -> None:
        super().__init__(name=name)
        self.namespace = namespace.strip("/")
        self.remap = dict(remap or {})
        self.executor: Executor | None = None
        self.blackboard = self.attach_blackboard_client(name=name)

    def key(self, role: str) -> str:
        """The blackboard key of a role: remapped, or ``/<namespace>/<role>``."""
        if role in self.remap:
            return self.remap[role]
        return f"/{self.namespace}/{role}" if self.namespace else f"/{role}"

    def use(self, role: str, access: py_trees.common.Access) -> None:
        """Registers the key of ``role`` with this behaviour's client."""
        self.blackboard.register_key(key=self.key(role), access=access)

    def read(self, role: str):
        return self.blackboard.get(self.key(role))

    def write(self, role: str, value) -> None:
        self.blackboard.set(self.key(role), value, overwrite=True)

    def has(self, role: str) -> bool:
        return self.blackboard.exists(self.key(role))

    def setup(self, **kwargs) -> None:
        executor = kwargs.get("executor")
        if not isinstance(executor, Executor):
            raise KeyError(
                f"{self.name}: setup() needs executor=<besman.sim.executor.Executor> "
                "(BehaviourTree.setup(executor=...))"
            )
        self.executor = executor

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self.executor.time
