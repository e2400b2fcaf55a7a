"""Perception and planning leaves for pick and place: where the object is, and the primitives to move it.

- :class:`RiseClear` raises the hand clear of the table if it is down by it (the start of every grasp try).
- :class:`PerceiveObject` writes an object's current position (simulated perception) to ``object_position``.
- :class:`PlanGrasp` reads ``object_position`` and writes the ``reach``, ``descend`` and ``lift``
  primitives planned from the robot's current commanded state (:func:`besman.sim.manipulation.plan_pick`).
- :class:`PlanPlace` reads the ``target`` (:meth:`~besman.sim.plans.Target.read`: x, y, and the yaw
  and the top it is set on if any) and writes ``carry``, ``place`` and ``retreat``.
- :class:`PlanReturn` writes ``return``: a learned return home from where the arm is.
- :class:`PlanMove` writes ``motion``: the hand to a position, straight up, or the arm home (presenting an
  object to the other hand, letting go of it, making room).

The reach, the carry and the return can come from skill templates learned from people
(:mod:`besman.learning.pipeline.end_to_end`), instantiated for the move the leaf plans (the hand's move from
the block's start to its planned end, :func:`~besman.sim.block_simulation.block_input`: the same for any
object, place or task) and refined online where the template is unsure.

The subtrees that use them are in :mod:`besman.trees.idioms`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from py_trees.common import Access, Status

from besman.core.errors import InputError
from besman.sim.misses import PlanningError
from besman.sim.objects import yaw_of
from besman.sim.plans import DEFAULT_PLAN, PickPlacePlan
from besman.trees.base import SimulationBehaviour
from besman.trees.leaves import MotionLeaf
from besman.trees.templates import check_template, check_template_fits

if TYPE_CHECKING:
    from besman.learning.search.online import Refinement
    from besman.sim.motions import Motion

# The planners, the simulation and online refinement (MuJoCo, Ruckig) are imported in the methods that run
# them: building a tree, showing it or listing its node types needs none of them, and answers at once.

# The parameters (kinds: see besman.trees.nodes) of a leaf or subtree whose motion is a skill template's
# instance; LEARNED: of a planning leaf or subtree whose big move may be one, refined online where the
# template is unsure (see _Plan).
TEMPLATE_PARAMETERS = {"pool": "pool", "template": "str"}
LEARNED = {**TEMPLATE_PARAMETERS, "refine_above": "float>=0"}


class TemplateInstance:
    """A skill template's primitive for a block's move from configuration ``start`` to ``end`` (its
    template input, :func:`~besman.sim.block_simulation.block_input`), as the planners take a learned move;
    keeps the input of the last one it gave. A pool entry may instead condition on the move's end
    configurations themselves (a baseline such as ProMP conditioning): it then has
    ``primitive_for_move(start, end)``."""

    def __init__(self, template, arm) -> None:
        self.template, self.arm = template, arm
        self.tau: np.ndarray | None = None

    def __call__(self, start: np.ndarray, end: np.ndarray):
        from besman.sim.block_simulation import block_input

        self.tau = block_input(self.arm, start, end)
        if hasattr(self.template, "primitive_for_move"):
            return self.template.primitive_for_move(start, end)
        return self.template.instantiate(self.tau)


class RiseClear(MotionLeaf):
    """Raises the hand straight up until it is ``height`` (m) above the table, if it is lower (less 5 mm);
    succeeds at once otherwise. Every try of a grasp begins with it: after a try that failed down by the
    object (the fingers closed on nothing: it was pushed, or perceived off), a reach from there to where
    the object now stands would sweep the hand through it, and none is planned."""

    parameters: ClassVar = {"height": "float>0", "object": "str", "arm": "str"}

    def __init__(self, name: str, *, height: float = 0.12, object: str | None = None, arm: str | None = None):
        super().__init__(name, arm=arm)
        self.height = height
        self.use_object(object)
        self.clear = True

    def rise(self) -> float:
        """How far (m) the hand must rise to be ``height`` above the table (0 where there is no table)."""
        table = self.executor.world.surfaces.get("table")
        if table is None:
            return 0.0
        hand = self.executor.arm.site_pose(self.executor.position).position[2]
        return max(0.0, table.height + self.height - hand)

    def initialise(self) -> None:
        self.clear = self.rise() <= 0.005
        if not self.clear:
            super().initialise()

    def update(self) -> Status:
        if self.clear:
            self.feedback_message = "the hand is clear of the table"
            return Status.SUCCESS
        return super().update()

    def make_motion(self) -> Motion:
        from besman.sim.manipulation import plan_move
        from besman.sim.motions import FollowPrimitive

        executor = self.executor
        allowed = () if self.object is None else (self.object,)
        return FollowPrimitive(plan_move(executor.arm, executor.position, rise=self.rise(), allowed=allowed))


# An object moving slower than this (m/s, rad/s) is at rest for perception; one still moving after SETTLE_TIME
# (s) cannot be perceived where it will be.
AT_REST, SETTLE_TIME = (0.01, 0.1), 2.0


class PerceiveObject(SimulationBehaviour):
    """Writes the position of ``object`` as perceived (:meth:`~besman.sim.world.World.perceive`: with the
    run's perception error, if it has one) to the role ``object_position``, once it is at rest: an object
    that a failed grasp dropped or pushed is still falling or sliding, and where it is then is not where it
    will be. Still moving after :data:`SETTLE_TIME`, it fails."""

    roles: ClassVar = {"object_position": Access.WRITE}
    parameters: ClassVar = {"object": "str"}

    def __init__(
        self, name: str, *, object: str, namespace: str = "", remap: Mapping[str, str] | None = None
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        self.use_object(object)
        self.use("object_position")
        self.started = 0.0  # s of simulated time when it began to look

    def initialise(self) -> None:
        self.started = self.time

    def update(self) -> Status:
        item = self.object
        speed, turning = self.executor.world.object_speed(item)
        if speed > AT_REST[0] or turning > AT_REST[1]:
            moving = f"{item} moves at {speed:.3f} m/s, turns at {turning:.2f} rad/s"
            if self.time - self.started < SETTLE_TIME:
                self.feedback_message = f"waiting for it to come to rest: {moving}"
                return Status.RUNNING
            self.feedback_message = (
                f"{moving} after {SETTLE_TIME:g} s (at rest below {AT_REST[0]} m/s, {AT_REST[1]} rad/s): "
                "it cannot be perceived where it will be"
            )
            return Status.FAILURE
        position = self.executor.world.perceive(item).position
        self.blackboard.set("object_position", position, overwrite=True)
        self.feedback_message = f"{item} at {position.round(3).tolist()}"
        return Status.SUCCESS


class _Plan(SimulationBehaviour):
    """A planning leaf: in one tick, plans from the robot's commanded configuration and the place in its
    ``source`` role (its subclass's ``_planned``), and writes the primitives to its other roles.

    With a ``pool`` and a ``template`` name, the big move (reach or carry) is the template's
    instance for the move planned (:class:`TemplateInstance`) - a learned primitive moved to the planned
    end points - instead of a point-to-point move. With ``refine_above`` as well, an instance whose
    template is less sure of its input than that (:func:`besman.learning.search.online.uncertainty`) is first
    refined by at most 25 rollouts in a copy of the world
    (:func:`besman.learning.search.online.refine_online`)."""

    source = ""
    block = ""
    parameters: ClassVar = {"object": "str", **LEARNED, "arm": "str"}

    def __init__(
        self,
        name: str,
        *,
        object: str,
        plan: PickPlacePlan = DEFAULT_PLAN,
        pool: Mapping[str, Any] | None = None,
        template: str | None = None,
        refine_above: float | None = None,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
        arm: str | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap, arm=arm)
        self.plan = plan
        self.use_object(object)
        self.pool, self.template, self.refine_above = pool, template, refine_above
        check_template(name, pool, template)
        if refine_above is not None and pool is None:
            raise InputError(f"{name}: refine_above needs a pool and a template")
        self.refinement: Refinement | None = None  # the last online refinement (for feedback and tests)
        for role in self.roles:
            if self.roles[role] is Access.WRITE or role == self.source or role in self.remap:
                self.use(role)

    def setup(self, **kwargs: Any) -> None:
        from besman.sim.block_simulation import INPUT_NAMES

        super().setup(**kwargs)
        if self.pool is not None:
            robot = self.executor.world.robot.name
            check_template_fits(self.name, self.pool[self.template], robot, INPUT_NAMES)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(role for role, access in self.roles.items() if access is Access.WRITE)

    def goal(self, source: np.ndarray, item: str) -> np.ndarray:
        """Where the hand goes, from the value of the ``source`` role."""
        raise NotImplementedError

    def update(self) -> Status:
        executor = self.executor
        item = executor.world.objects.get(self.object)
        if item is None:
            self.feedback_message = f"no object {self.object!r} in the world"
            return Status.FAILURE
        source = np.asarray(self.blackboard.get(self.source), dtype=float)
        self.refinement, template, learned, note = None, None, None, ""
        try:
            goal = self.goal(source, item.name)
            if self.pool is not None:
                template = self.pool[self.template]
                learned = TemplateInstance(template, executor.arm)
            motions = self._planned(goal, item, learned)
            if template is not None and self.refine_above is not None:
                motions, note = self._refined(motions, template, learned.tau, source, goal, item)
        except (PlanningError, ValueError) as error:
            self.feedback_message = str(error)
            return Status.FAILURE
        for role in self.outputs:
            self.blackboard.set(role, getattr(motions, role), overwrite=True)
        learned = f" ({self.outputs[0]} from template {self.template!r})" if template is not None else ""
        self.feedback_message = "planned " + ", ".join(self.outputs) + learned + note
        return Status.SUCCESS

    def _refined(
        self, motions, template, tau: np.ndarray, source: np.ndarray, goal: np.ndarray, item
    ) -> tuple[Any, str]:
        """The motions planned again with the template's instance refined online, if the template's spread
        at tau is above ``refine_above``; and a note for the feedback."""
        from besman.learning.search.online import refine_online, uncertainty
        from besman.sim.block_simulation import BlockStart, snapshot, steps_after

        spread = uncertainty(template, tau)
        if spread <= self.refine_above:
            return motions, ""
        executor = self.executor
        start = BlockStart(
            self.block,
            snapshot(executor.world),
            executor.position.copy(),
            getattr(motions, self.outputs[0]).dmp.goal.copy(),
            steps_after(self.block, motions),
            source,
        )
        self.refinement = refine_online(executor.world, start, template, tau)
        note = (
            f"; refined online (spread {spread:.2f}): {self.refinement.rollouts} rollouts, "
            f"reward {self.refinement.mean_reward:.3f} -> {self.refinement.best_reward:.3f}, "
            + ("kept" if self.refinement.improved else "not kept: no gain beyond the noise")
        )
        return self._planned(goal, item, self.refinement.primitive), note

    def _planned(self, goal: np.ndarray, item, shape):
        """The leaf's motions to ``goal`` for ``item``, the big move shaped by ``shape`` if given."""
        raise NotImplementedError


def _planning_roles(source: str, *outputs: str) -> dict[str, Access]:
    """A planning leaf's roles: it reads ``source`` and writes the primitives ``outputs``."""
    return {source: Access.READ, **dict.fromkeys(outputs, Access.WRITE)}


class PlanGrasp(_Plan):
    """Plans reach, descend and lift for the object at ``object_position``, grasped ``offset`` (x, y in
    m, default its centre) from its centre: where it stands on the table or, held by another hand, in the
    air; across the faces that fit as the object is turned now (perceived with its position). With the
    role ``offset`` remapped, the offset is the key's when the leaf plans (a robot's own: the handover's
    ``/task/left_grip``). With the role ``target`` remapped (the placement the grasp is for), a grasp from
    which the object can be set down there at the target's yaw."""

    parameters: ClassVar = {**_Plan.parameters, "offset": "floats[2]"}
    source = "object_position"
    roles: ClassVar = {
        **_planning_roles(source, "reach", "descend", "lift"),
        "target": Access.READ,
        "offset": Access.READ,
    }
    block = "reach"

    def __init__(
        self,
        name: str,
        *,
        object: str,
        offset: Sequence[float] | None = None,
        plan: PickPlacePlan = DEFAULT_PLAN,
        pool: Mapping[str, Any] | None = None,
        template: str | None = None,
        refine_above: float | None = None,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
        arm: str | None = None,
    ):
        super().__init__(
            name,
            object=object,
            plan=plan,
            pool=pool,
            template=template,
            refine_above=refine_above,
            namespace=namespace,
            remap=remap,
            arm=arm,
        )
        if offset is not None and "offset" in self.remap:
            raise InputError(f"{name}: give offset or remap it to a key, not both")
        self.offset = np.zeros(2) if offset is None else np.asarray(offset, dtype=float)

    def goal(self, source: np.ndarray, item: str) -> np.ndarray:
        return np.r_[source[:2] + self._offset(), source[2]]

    def _offset(self) -> np.ndarray:
        if "offset" not in self.remap:
            return self.offset
        given = self.blackboard.get("offset")
        try:
            offset = np.asarray(given, dtype=float)
        except (TypeError, ValueError):
            offset = np.empty(0)
        if offset.shape != (2,) or not np.isfinite(offset).all():
            shown = given.tolist() if isinstance(given, np.ndarray) else given
            raise InputError(f"{self.key('offset')} must hold x, y in m (the grasp's offset), got {shown!r}")
        return offset

    def _planned(self, goal: np.ndarray, item, shape):
        from besman.sim.manipulation import plan_pick

        executor = self.executor
        yaw = yaw_of(executor.world.perceived(item.name).rotation)  # as the latest look saw it
        then = self.blackboard.get("target") if "target" in self.remap else None
        settings = executor.reference_settings
        return plan_pick(executor.arm, executor.position, item, goal, self.plan, settings, shape, yaw, then)


class PlanPlace(_Plan):
    """Plans carry, place and retreat to the ``target`` from the current configuration: x, y on the shelf,
    turned to a yaw (deg) if it has one, onto a top at a height if it has one (another object's: a stack;
    :meth:`~besman.sim.plans.Target.read`)."""

    source = "target"
    roles: ClassVar = _planning_roles(source, "carry", "place", "retreat")
    block = "carry"

    def goal(self, source: np.ndarray, item: str) -> np.ndarray:
        return source

    def _planned(self, goal: np.ndarray, item, shape):
        from besman.sim.manipulation import plan_place

        # The object, not the hand, goes to the target: where it is held off its centre (a bar taken over at
        # one end), the planner moves the hand by as much (turned with the hand).
        executor = self.executor
        held = None
        if executor.hand is not None and executor.hand.holds(item.name):  # else the guard fails, says why
            hand = executor.arm.site_pose(executor.arm.measured()).position
            held = executor.world.object_pose(item.name).position[:2] - hand[:2]
        return plan_place(
            executor.arm, executor.position, item, goal, self.plan, executor.reference_settings, shape, held
        )


class PlanReturn(SimulationBehaviour):
    """Writes ``return``: the instance of the ``template`` of ``pool`` (a learned return) for the move from
    where the arm is now to the robot's home configuration, moved to those end points."""

    roles: ClassVar = {"return": Access.WRITE}
    parameters: ClassVar = dict(TEMPLATE_PARAMETERS)

    def __init__(
        self,
        name: str,
        *,
        pool: Mapping[str, Any],
        template: str,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap)
        check_template(name, pool, template)
        self.pool, self.template = pool, template
        self.use("return")

    def setup(self, **kwargs: Any) -> None:
        from besman.sim.block_simulation import INPUT_NAMES

        super().setup(**kwargs)
        check_template_fits(self.name, self.pool[self.template], self.executor.world.robot.name, INPUT_NAMES)

    def update(self) -> Status:
        from besman.sim.primitives import shaped

        executor = self.executor
        arm = executor.arm
        try:
            home = executor.world.home(arm.qpos_indices)
            shape = TemplateInstance(self.pool[self.template], arm)(executor.position, home)
            primitive = shaped(shape, "return", executor.position, home, arm)
        except ValueError as error:
            self.feedback_message = str(error)
            return Status.FAILURE
        self.blackboard.set("return", primitive, overwrite=True)
        self.feedback_message = f"planned the return home (template {self.template!r})"
        return Status.SUCCESS


class PlanMove(SimulationBehaviour):
    """Writes ``motion``: the hand of ``arm`` to ``position`` (x, y, z) as it is turned (or pointing down,
    turned by ``yaw``), to the pose that the role ``goal`` holds (``{"position": [x, y, z], "yaw": rad}``,
    yaw optional: a pose that depends on the robot or the task, given as ``remap: {goal: /task/...}``),
    straight up by ``rise`` m, or the arm to its ``home`` configuration (exactly one), planned from the
    commanded configuration; the end must not collide, except with the held ``object``."""

    roles: ClassVar = {"motion": Access.WRITE, "goal": Access.READ}
    parameters: ClassVar = {
        "position": "floats[3]",
        "rise": "float>0",
        "home": "bool",
        "yaw": "float",
        "object": "str",
        "duration": "float>0",
        "arm": "str",
    }

    def __init__(
        self,
        name: str,
        *,
        position: Sequence[float] | None = None,
        rise: float | None = None,
        home: bool = False,
        yaw: float | None = None,
        object: str | None = None,
        duration: float = 1.0,
        namespace: str = "",
        remap: Mapping[str, str] | None = None,
        arm: str | None = None,
    ):
        super().__init__(name, namespace=namespace, remap=remap, arm=arm)
        self.from_goal = "goal" in self.remap
        if sum((position is not None, rise is not None, bool(home), self.from_goal)) != 1:
            raise InputError(
                f"{name}: give exactly one of position, rise, home: true and remap: {{goal: KEY}}"
            )
        self.position = None if position is None else np.asarray(position, dtype=float)
        if yaw is not None and position is None:
            raise InputError(f"{name}: yaw turns the hand at a position; give the position too")
        self.rise, self.home, self.yaw, self.duration = rise, bool(home), yaw, duration
        self.use_object(object)
        self.use("motion")
        if self.from_goal:
            self.use("goal")

    def _target(self) -> tuple[np.ndarray | None, float | None]:
        """The position and yaw to move to: the parameters, or the pose at ``goal`` now."""
        if not self.from_goal:
            return self.position, self.yaw
        goal = self.blackboard.get("goal")
        try:
            position = np.asarray(goal["position"], dtype=float)
            yaw = goal.get("yaw")
            yaw = None if yaw is None else float(yaw)
        except (TypeError, KeyError, IndexError, ValueError, AttributeError):
            raise InputError(
                f"{self.key('goal')} must hold {{'position': [x, y, z], 'yaw': rad}}, got {goal!r}"
            ) from None
        if position.shape != (3,) or not np.isfinite(position).all():
            raise InputError(f"{self.key('goal')}: position must be three finite numbers, got {goal!r}")
        return position, yaw

    def update(self) -> Status:
        from besman.sim.manipulation import plan_move

        executor = self.executor
        held = self.object
        try:
            position, yaw = self._target()
            motion = plan_move(
                executor.arm,
                executor.position,
                position=position,
                rise=self.rise,
                home=self.home,
                yaw=yaw,
                allowed=() if held is None else (held,),
                duration=self.duration,
            )
        except ValueError as error:
            self.feedback_message = str(error)
            return Status.FAILURE
        self.blackboard.set("motion", motion, overwrite=True)
        self.feedback_message = f"planned {motion.name}"
        return Status.SUCCESS
