"""besman's action leaves: execute primitives, instantiate skill templates, drive the gripper.

- :class:`ExecutePrimitive` executes a :class:`~besman.skills.MovementPrimitive` (given, or read from the
  blackboard role ``primitive``) through the Ruckig executor: RUNNING while it moves, SUCCESS when the end
  state is reached, FAILURE with a feedback message on an unreachable pose, a tracking error, a simulation
  fault or its sim-time ``timeout``. Pre-empted (terminated with INVALID), it brakes the robot to rest
  within the limits.
- :class:`InstantiateSkillTemplate` reads tau (role ``tau``), asks a skill template (any object with
  ``instantiate(tau) -> MovementPrimitive``, given directly or by name from a pool, i.e. any mapping of
  names to templates) for a primitive and writes it (role ``primitive``).
- :class:`Gripper` opens or closes the hand; closing with ``expect_grasp`` fails if nothing is held.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
from py_trees.common import Access, Status

from besman.core.errors import InputError
from besman.sim.motion_status import MotionStatus
from besman.skills import MovementPrimitive
from besman.trees.base import RoleBehaviour, SimulationBehaviour
from besman.trees.templates import check_template
from besman.trees.timing import Deadline

if TYPE_CHECKING:
    from besman.sim.motions import Motion

_STATUS = {
    MotionStatus.RUNNING: Status.RUNNING,
    MotionStatus.SUCCEEDED: Status.SUCCESS,
    MotionStatus.FAILED: Status.FAILURE,
}


class MotionLeaf(SimulationBehaviour):
    """A leaf that runs one executor motion: starts it in ``initialise``, mirrors its status in ``update``
    and brakes the robot if it is pre-empted or its sim-time ``timeout`` (a :class:`Deadline`) passes."""

    def __init__(self, name: str, *, timeout: float | None = None, **wiring) -> None:
        super().__init__(name, **wiring)
        self.deadline = Deadline(name, timeout)
        self.motion: Motion | None = None
        self.problem = ""

    @property
    def timeout(self) -> float | None:
        return self.deadline.duration

    def make_motion(self) -> Motion:
        raise NotImplementedError

    def initialise(self) -> None:
        self.problem, self.motion = "", None
        try:
            self.motion = self.executor.start(self.make_motion())
        except (ValueError, KeyError) as error:
            self.problem = str(error)
        self.deadline.start(self.time)

    def update(self) -> Status:
        if self.problem:
            self.feedback_message = self.problem
            return Status.FAILURE
        if self.deadline.expired(self.time) and self.motion.status is MotionStatus.RUNNING:
            self.feedback_message = self.deadline.message
            return Status.FAILURE
        self.feedback_message = self.motion.message or self.motion.status.value
        return _STATUS[self.motion.status]

    def terminate(self, new_status: Status) -> None:
        running = self.motion is not None and self.motion.status is MotionStatus.RUNNING
        if running and self.executor.motion is self.motion:
            self.executor.stop()  # pre-empted or timed out: brake within the limits


class ExecutePrimitive(MotionLeaf):
    """Executes a movement primitive, started in the robot's current commanded state.

    Args:
        name: the leaf's name.
        primitive: the primitive; if None it is read from the blackboard role ``primitive``.
        timeout: simulated seconds after which a still-running motion fails (default: none).
        namespace: the blackboard namespace of its roles (see :mod:`besman.trees.base`).
        remap: roles read from or written to other keys (see :mod:`besman.trees.base`).
        arm: the arm that executes it, on a robot driven with several (default: the executor's own).
        untouched: an object (a name, or a key holding one) that the robot must not touch on the way: a
            touch fails it (:class:`~besman.sim.motions.FollowPrimitive`).
    """

    roles: ClassVar = {"primitive": Access.READ}
    parameters: ClassVar = {"primitive": "primitive", "timeout": "float>0", "arm": "str", "untouched": "str"}

    def __init__(
        self,
        name: str,
        *,
        primitive: MovementPrimitive | None = None,
        timeout: float | None = None,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
        arm: str | None = None,
        untouched: str | None = None,
    ) -> None:
        super().__init__(name, timeout=timeout, namespace=namespace, remap=remap, arm=arm)
        self.primitive = primitive
        self.use_object(untouched)
        if primitive is None:
            self.use("primitive")

    def make_motion(self) -> Motion:
        primitive = self.primitive if self.primitive is not None else self.blackboard.get("primitive")
        if not isinstance(primitive, MovementPrimitive):
            raise InputError(
                f"{self.key('primitive')} holds {type(primitive).__name__}, not a MovementPrimitive"
            )
        from besman.sim.motions import FollowPrimitive  # as a motion starts: building a tree needs no MuJoCo

        return FollowPrimitive(primitive, untouched=self.object)


class Gripper(MotionLeaf):
    """Opens (``action="open"``) or closes (``"close"``) the gripper; SUCCESS when the fingers settle.

    With ``expect_grasp`` (closing only) it fails unless both fingers touch ``object`` (a name, or a key
    holding one) and it moves with the hand; ``arm`` chooses the hand on a robot driven with several arms.
    """

    parameters: ClassVar = {
        "action": "str{open|close}",
        "opening": "float>=0",
        "expect_grasp": "bool",
        "object": "str",
        "timeout": "float>0",
        "arm": "str",
    }

    def __init__(
        self,
        name: str,
        *,
        action: str,
        opening: float | None = None,
        expect_grasp: bool = False,
        object: str | None = None,
        timeout: float | None = 5.0,
        arm: str | None = None,
    ) -> None:
        if action not in ("open", "close"):
            raise InputError(f"{name}: action must be 'open' or 'close', got {action!r}")
        if expect_grasp and (action != "close" or object is None):
            raise InputError(f"{name}: expect_grasp needs action='close' and an object")
        super().__init__(name, timeout=timeout, arm=arm)
        self.action, self.expect_grasp = action, expect_grasp
        self.use_object(object)
        # Opening: the gripper's own for "open" (None), closed for "close", unless given.
        self.opening = (None if action == "open" else 0.0) if opening is None else float(opening)

    def make_motion(self) -> Motion:
        from besman.sim.motions import GripperMotion  # as the motion starts (see ExecutePrimitive)

        return GripperMotion(
            self.name, opening=self.opening, expect_grasp=self.expect_grasp, grasp_object=self.object
        )


class SkillTemplate(Protocol):
    """Anything that turns task parameters into a movement primitive."""

    def instantiate(self, tau: np.ndarray) -> MovementPrimitive: ...


class InstantiateSkillTemplate(RoleBehaviour):
    """Reads tau (role ``tau``), instantiates a skill template and writes the primitive (role ``primitive``).

    Args:
        name: the leaf's name.
        template: the template object, or
        pool: a mapping of names to templates (a pool), with
        template_name: the name to take from it.
        namespace: the blackboard namespace: by default it reads ``/<namespace>/tau`` and writes
            ``/<namespace>/primitive``.
        remap: roles read from or written to other keys.
    """

    roles: ClassVar = {"tau": Access.READ, "primitive": Access.WRITE}
    parameters: ClassVar = {"template": "template", "pool": "pool", "template_name": "str"}

    def __init__(
        self,
        name: str,
        *,
        template: SkillTemplate | None = None,
        pool: Mapping[str, Any] | None = None,
        template_name: str | None = None,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(name, namespace=namespace, remap=remap)
        if (template is None) == (pool is None):
            raise InputError(f"{name}: give either a template or a pool and a template_name")
        if pool is not None and template_name is None:
            raise InputError(f"{name}: a pool needs a template_name")
        if pool is not None:
            check_template(name, pool, template_name)
        self.template, self.pool, self.template_name = template, pool, template_name
        self.instantiated: tuple | None = None  # (template, tau) of the last instance (for viewers)
        self.use("tau")
        self.use("primitive")

    def update(self) -> Status:
        if self.pool is not None:
            if self.template_name not in self.pool:
                self.feedback_message = f"the pool has no template {self.template_name!r}"
                return Status.FAILURE
            template = self.pool[self.template_name]
        else:
            template = self.template
        if not self.blackboard.exists("tau"):
            self.feedback_message = f"no tau at {self.key('tau')}"
            return Status.FAILURE
        tau = np.asarray(self.blackboard.get("tau"), dtype=float)
        try:
            primitive = template.instantiate(tau)
        except ValueError as error:
            self.feedback_message = f"the template rejected tau {tau.tolist()}: {error}"
            return Status.FAILURE
        self.blackboard.set("primitive", primitive, overwrite=True)
        self.instantiated = (template, tau)
        self.feedback_message = f"instantiated {getattr(primitive, 'name', 'a primitive')}"
        return Status.SUCCESS
