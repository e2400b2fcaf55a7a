"""What besman's behaviours share: blackboard roles declared once per class, and the executor they drive.

Every besman behaviour is a real ``py_trees.behaviour.Behaviour``. Blackboard access goes through py_trees'
own access-controlled clients, namespaces and remapping: a behaviour class declares the *roles* it reads
and writes once, in :attr:`RoleBehaviour.roles` (``{"primitive": Access.READ}``); an instance's client lives
in the instance's ``namespace`` (so a role's key is ``/<namespace>/<role>``, py_trees'
``Blackboard.absolute_name``), and ``remap`` (role -> key) is py_trees' ``remap_to`` for that role. Code reads
and writes by role (``self.blackboard.get("primitive")``) and never spells a key; :meth:`RoleBehaviour.key`
and :meth:`RoleBehaviour.role_keys` say where a role lives, for messages and for tree files that rename keys
(see :mod:`besman.trees.blackboard` for the layout).

Behaviours that touch the simulation (:class:`SimulationBehaviour`) get the
:class:`~besman.sim.executor.Executor` in ``setup(executor=...)`` (``BehaviourTree.setup(executor=...)``
passes it to every behaviour) and read the simulated clock from it, so timers run in simulated time. On a
robot with several arms driven in lockstep (``Executor(world, ("right", "left"))``), ``arm`` names the
one a behaviour drives or looks at (default: the executor's own). A behaviour about an object takes its
name, or a blackboard key (starting with ``/``) that holds the name when the behaviour runs, so one subtree
can work through several objects (:class:`~besman.trees.loops.ForEach`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import py_trees
from py_trees.blackboard import Blackboard
from py_trees.common import Access

from besman.core.errors import InputError, UnknownNameError
from besman.core.validation import as_given, checked, instance, integer, number, optional, shaped, text
from besman.skills import MovementPrimitive

if TYPE_CHECKING:
    from besman.sim.executor import Executor

BEHAVIOUR = instance(py_trees.behaviour.Behaviour, "a py_trees behaviour")
NAMES = instance(Mapping, "a mapping of names")
# The Python type of each parameter kind a class declares (its rule, ">0" and the like, stays with the tree
# file's loader and the class): a behaviour built in code is refused by the parameter's name, as in a file.
KIND_CHECKS = {
    "str": text("a string"),
    "float": number,
    "int": integer(),
    "bool": instance(bool, "True or False"),
    "floats": shaped(ndim=1),
    "keys": NAMES,
    "primitive": instance(MovementPrimitive, "a MovementPrimitive"),
}


class RoleBehaviour(py_trees.behaviour.Behaviour):
    """A behaviour that uses the blackboard by role (declared in :attr:`roles`), in a namespace.

    Attributes:
        roles: role -> access, declared once per class.
        parameters: the tree-file parameters of the class beyond ``name``, ``namespace`` and ``remap``:
            parameter -> kind (see :mod:`besman.trees.nodes`); defaults come from ``__init__``.
    """

    roles: ClassVar[Mapping[str, Access]] = {}
    parameters: ClassVar[Mapping[str, str]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Checks the arguments of each subclass's constructor by the kinds it declares (and ``name``,
        ``namespace``, ``remap``), leaving their values as given."""
        super().__init_subclass__(**kwargs)
        if "__init__" in vars(cls):
            kinds = {param: re.match(r"[a-z]+", kind)[0] for param, kind in cls.parameters.items()}
            checks = {
                param: optional(KIND_CHECKS[kind]) for param, kind in kinds.items() if kind in KIND_CHECKS
            }
            checks |= {
                "name": text("a behaviour name"),
                "namespace": text("a namespace"),
                "remap": optional(NAMES),
            }
            cls.__init__ = checked(**{param: as_given(check) for param, check in checks.items()})(
                cls.__init__
            )

    def __init__(self, name: str, *, namespace: str = "", remap: Mapping[str, str] | None = None) -> None:
        super().__init__(name=name)
        self.namespace = namespace.strip("/")
        self.remap = dict(remap or {})
        unknown = sorted(set(self.remap) - set(self.roles))
        if unknown:
            known = ", ".join(self.roles) or "none"
            raise InputError(f"{name}: remap names unknown role {unknown[0]!r}; roles: {known}")
        self.blackboard = self.attach_blackboard_client(name=name, namespace=f"/{self.namespace}")

    def use(self, role: str) -> None:
        """Registers ``role`` (with its declared access) with this behaviour's client."""
        self.blackboard.register_key(key=role, access=self.roles[role], remap_to=self.remap.get(role))

    def key(self, role: str) -> str:
        """Where ``role`` lives on the blackboard."""
        return self.role_keys(self.namespace, self.remap, (role,))[role]

    @classmethod
    def role_keys(
        cls, namespace: str, remap: Mapping[str, str], roles: tuple[str, ...] | None = None
    ) -> dict[str, str]:
        """The key of each role (default: all declared) for an instance in ``namespace`` with ``remap``."""
        namespace = "/" + namespace.strip("/")
        return {
            role: remap.get(role) or Blackboard.absolute_name(namespace, role)
            for role in (cls.roles if roles is None else roles)
        }


class SimulationBehaviour(RoleBehaviour):
    """A behaviour that needs the executor (given to ``setup``) of its ``arm`` (None: the executor's own)."""

    def __init__(
        self,
        name: str,
        *,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
        arm: str | None = None,
    ) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        self.arm = arm
        self.executor: Executor | None = None
        self._object: str | None = None

    def setup(self, **kwargs: Any) -> None:
        executor = executor_of(self.name, kwargs)
        try:
            self.executor = executor.arm_executor(self.arm)
        except KeyError as error:
            raise InputError(f"{self.name}: {error.args[0]}") from None

    def use_object(self, object: str | None) -> None:
        """Sets the object the behaviour is about: a name, or a blackboard key (``/...``) holding one."""
        self._object = object
        if object is not None and object.startswith("/"):
            self.blackboard.register_key(key=object, access=Access.READ)

    @property
    def object(self) -> str | None:
        """The object's name now (read from the blackboard if :meth:`use_object` was given a key)."""
        reference = self._object
        if reference is None or not reference.startswith("/"):
            return reference
        if not self.blackboard.exists(reference):
            raise UnknownNameError(f"{self.name}: no object name at {reference} on the blackboard")
        return str(self.blackboard.get(reference))

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self.executor.time


def executor_of(name: str, setup_arguments: Mapping[str, Any]) -> Executor:
    """The executor given to ``setup``; a clear error names the behaviour if there is none."""
    from besman.sim.executor import Executor  # when a tree is set up to run: building one needs no MuJoCo

    executor = setup_arguments.get("executor")
    if not isinstance(executor, Executor):
        raise InputError(
            f"{name}: setup() needs executor=<besman.sim.executor.Executor> "
            "(BehaviourTree.setup(executor=...))"
        )
    return executor
