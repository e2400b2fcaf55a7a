"""The kinematic model of the joints an executor drives: what planning and execution both ask about.

An :class:`Arm` is an arm of a :class:`~besman.sim.world.World`'s robot as its description defines it (AILA's
waist and right arm with the right hand's tool frame and gripper, say; or only some of its joint groups):
their joints, ranges and motion limits, the tool-centre point site, the gripper, and the queries on
configurations of those joints with everything else as it stands in the world - forward kinematics,
inverse kinematics and collisions. Queries run in a scratch ``MjData`` of their own, so planning never
touches the simulation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

import besman.robots as robots
from besman.core.validation import checked, finite_array, instance, items, optional, text
from besman.sim.streaming import ACCELERATION_SHARE, VELOCITY_SHARE
from besman.sim.world import World

# Planning asks inverse kinematics the same question again and again (a pick's candidate legs share their
# poses; a placement is planned to check a grasp, then to run it): half the solves of a stack episode. The
# solver is deterministic (its restarts seeded), so an arm keeps its last answers, this many
# (benchmarks/ik_answers.py: with none kept, the same outcomes and more processor time).
IK_ANSWERS_KEPT = 4096


@dataclass(frozen=True)
class Contact:
    """A contact of the robot at a configuration: "body1/body2", "geom1/geom2", how deep they overlap (m),
    whether one is furniture (the world's fixed geoms: table, shelf) and whether one is of the hand (the
    tool frame's body or below it: the fingers)."""

    bodies: str
    geoms: str
    depth: float
    furniture: bool
    hand: bool


class Arm:
    """Joints, limits and kinematic queries of an arm of a world's robot; see the module documentation.

    Attributes:
        robot_arm: the description's arm (its name, groups, tool-centre point and gripper).
        groups: the joint groups moved (the arm's, unless given).
        joints: joint names, in the groups' order (every array below follows it).
        qpos_indices, dof_indices, actuator_indices: where the joints sit in qpos, qvel and ctrl.
        lower, upper: joint ranges (rad or m).
        max_velocity, max_acceleration, max_jerk: motion limits from the robot description.
        site: the tool-centre point site.
        gripper: the arm's gripper (:class:`~besman.robots.Gripper`), None without one.
    """

    @checked(
        world=instance(World, "a World (sim.tabletop_world)"),
        arm=optional(text("an arm name")),
        groups=optional(items(text("a joint group name"))),
    )
    def __init__(self, world: World, arm: str | None = None, groups: Sequence[str] | None = None) -> None:
        self.world = world
        robot = world.robot
        self.robot_arm = robot.arm(arm)
        self.groups = tuple(self.robot_arm.groups if groups is None else groups)
        self.gripper = self.robot_arm.gripper
        members = [robot.group(name) for name in self.groups]
        self.joints = tuple(j for g in members for j in g.joints)
        self.qpos_indices = np.concatenate([g.qpos_indices for g in members])
        self.dof_indices = np.concatenate([g.dof_indices for g in members])
        self.actuator_indices = np.concatenate([g.actuator_indices for g in members])
        self.lower = np.concatenate([g.lower for g in members])
        self.upper = np.concatenate([g.upper for g in members])
        self.max_velocity = np.concatenate([g.velocity for g in members])
        self.max_acceleration = np.concatenate([g.acceleration for g in members])
        self.max_jerk = np.concatenate([g.jerk for g in members])
        self.site = self.robot_arm.tcp
        model = world.model
        self._site_id = robots.kinematics.site_id(model, self.site)
        self._scratch = mujoco.MjData(model)
        self._solved: dict[tuple, robots.IKResult] = {}  # solve_ik's answers, by question
        root = model.body_rootid[model.jnt_bodyid[model.joint(self.joints[0]).id]]
        self._robot_body = model.body_rootid == root  # per body: part of the robot
        # The geoms the arm's joints move, and the furniture (the world body's own geoms), that collide.
        moved = self._moved_body = robots.kinematics.bodies_below(
            model, [model.jnt_bodyid[model.joint(name).id] for name in self.joints]
        )
        colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        self._moved_geoms = np.flatnonzero(moved[model.geom_bodyid] & colliding)
        self._furniture = np.flatnonzero((model.geom_bodyid == 0) & colliding)
        # The hand: the tool frame's body and what hangs from it (the fingers).
        self._hand_body = robots.kinematics.bodies_below(model, [model.site_bodyid[self._site_id]])
        self._fromto = np.empty(6)

    @property
    def dofs(self) -> int:
        return len(self.joints)

    @property
    def name(self) -> str:
        """The robot and groups, as primitives record them ("aila", "waist+right_arm")."""
        return "+".join(self.groups)

    def full_qpos(self, joint_positions: np.ndarray) -> np.ndarray:
        """The world's current qpos with the arm's joints set to ``joint_positions``."""
        qpos = self.world.data.qpos.copy()
        qpos[self.qpos_indices] = self._configuration(joint_positions)
        return qpos

    def measured(self) -> np.ndarray:
        """The arm's joint positions in the simulation now."""
        return self.world.data.qpos[self.qpos_indices]

    @property
    def home(self) -> np.ndarray:
        """The arm's joint positions in the robot's home keyframe."""
        key = self.world.model.key(self.world.robot.description.keyframe)
        return key.qpos[self.qpos_indices].copy()

    # -- forward kinematics --------------------------------------------------------------------------------

    def _configuration(self, joint_positions) -> np.ndarray:
        """One configuration of the arm's joints, refused by name (wrong shape, NaN) before any work."""
        return finite_array("joint_positions", joint_positions, shape=(self.dofs,))

    def _pose_scratch(self, joint_positions: np.ndarray) -> mujoco.MjData:
        scratch = self._scratch
        scratch.qpos[:] = self.world.data.qpos
        scratch.qpos[self.qpos_indices] = joint_positions
        mujoco.mj_kinematics(self.world.model, scratch)
        return scratch

    def site_pose(self, joint_positions: np.ndarray) -> robots.Pose:
        """The world pose of the site at ``joint_positions``."""
        scratch = self._pose_scratch(self._configuration(joint_positions))
        return robots.site_pose(self.world.model, scratch, self._site_id)

    def site_path(self, joint_positions: np.ndarray) -> np.ndarray:
        """Site positions (K, 3) along configurations (K, dofs)."""
        # Copies: the scratch data's rows are overwritten by the next configuration.
        return np.array([self._pose_scratch(q).site_xpos[self._site_id].copy() for q in joint_positions])

    # -- inverse kinematics --------------------------------------------------------------------------------

    def solve_ik(
        self,
        position,
        orientation,
        *,
        initial: np.ndarray,
        restarts: int = 0,
        tolerances: tuple[float, float] = (1e-4, 1e-3),
    ) -> robots.IKResult:
        """Inverse kinematics of the site over the arm's joints started from ``initial``, the heavy slow
        joints taking a small share (weights = acceleration limits). The solver's answer is kept: the same
        question asked again (the same target, from the same configuration of the whole world) gets it
        again, with its own copy of ``qpos``."""
        initial_qpos = self.full_qpos(initial)
        try:
            question = (
                np.asarray(position, dtype=float).tobytes(),
                None if orientation is None else np.asarray(orientation, dtype=float).tobytes(),
                initial_qpos.tobytes(),
                restarts,
                tuple(tolerances),
            )
        except (TypeError, ValueError):  # not numbers: the solver's own check says which (it raises)
            question = None
        answer = None if question is None else self._solved.get(question)
        if answer is None:
            answer = robots.solve_ik(
                self.world.robot,
                self.groups,
                position,
                orientation,
                site=self.site,
                initial_qpos=initial_qpos,
                restarts=restarts,
                position_tolerance=tolerances[0],
                orientation_tolerance=tolerances[1],
                joint_weights=self.max_acceleration,
                data=self._scratch,
            )
            if question is not None and IK_ANSWERS_KEPT > 0:
                if len(self._solved) >= IK_ANSWERS_KEPT:
                    del self._solved[next(iter(self._solved))]  # the oldest
                self._solved[question] = answer
        return replace(answer, qpos=answer.qpos.copy())  # a caller may change its configuration in place

    # -- collisions ----------------------------------------------------------------------------------------

    def collisions(
        self, joint_positions: np.ndarray, allowed: Sequence[str] = (), margin: float = 0.0
    ) -> list[str]:
        """Contacts the robot would have with the arm at ``joint_positions`` and everything else as it is
        now: "body1/body2" for each pair, except pairs with a body named in ``allowed``. With a ``margin``
        (m), the parts the arm moves also collide with the furniture (the world's fixed geoms: table, shelf)
        closer than that: room for how far a fast move's tracking strays from its commanded path."""
        hits = [contact.bodies for contact in self.contacts(joint_positions, allowed)]
        if margin > 0 and not hits:
            model, scratch = self.world.model, self._scratch  # posed by contacts()
            hits = [
                f"{model.body(model.geom_bodyid[part]).name}/{model.geom(furniture).name or 'world'}"
                for part in self._moved_geoms
                for furniture in self._furniture
                if mujoco.mj_geomDistance(model, scratch, part, furniture, margin, self._fromto) < margin
            ]
        return hits

    def contacts(self, joint_positions: np.ndarray, allowed: Sequence[str] = ()) -> list[Contact]:
        """The contacts :meth:`collisions` names, deepest first, with their geoms and depths."""
        model, scratch = self.world.model, self._pose_scratch(self._configuration(joint_positions))
        mujoco.mj_collision(model, scratch)
        contacts = scratch.contact
        bodies = model.geom_bodyid[contacts.geom]  # (ncon, 2)
        excused = np.isin(bodies, [model.body(name).id for name in allowed]).any(axis=1)
        hand = self._hand_body
        # Contacts the arm cannot change are not its collisions: the hand's own parts touching (closed
        # fingers), or two bodies it does not move (another arm's closed fingers).
        excused |= hand[bodies].all(axis=1) | ~self._moved_body[bodies].any(axis=1)
        found = np.flatnonzero((contacts.dist < 0) & self._robot_body[bodies].any(axis=1) & ~excused)
        return [
            Contact(
                "/".join(model.body(b).name for b in bodies[i]),
                "/".join(model.geom(g).name or f"geom {g}" for g in contacts.geom[i]),
                float(-contacts.dist[i]),
                furniture=bool(np.isin(contacts.geom[i], self._furniture).any()),
                hand=bool(hand[bodies[i]].any()),
            )
            for i in found[np.argsort(contacts.dist[found])]
        ]

    # -- limits --------------------------------------------------------------------------------------------

    def limit_margin(self, joint_positions: np.ndarray) -> float:
        """The smallest distance of any joint from a limit, as a fraction of its range (over all rows)."""
        q = np.asarray(joint_positions)
        return float((np.minimum(q - self.lower, self.upper - q) / (self.upper - self.lower)).min())

    def slowdown(
        self, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray, period: float
    ):
        """How much slower a joint trajectory sampled every ``period`` must run to respect every limit (1 if
        it already does): velocity scales with 1/f, acceleration 1/f^2, jerk 1/f^3. The velocity and
        acceleration limits are the shares a tracked target may have (``streaming.VELOCITY_SHARE``): a
        reference at 99.7 % of a speed limit is one the executor falls behind on."""
        jerk = np.abs(np.diff(accelerations, axis=0)).max(axis=0) / period
        velocity, acceleration = (
            VELOCITY_SHARE * self.max_velocity,
            ACCELERATION_SHARE * self.max_acceleration,
        )
        return float(
            max(
                1.0,
                (np.abs(velocities).max(axis=0) / velocity).max(),
                np.sqrt(np.abs(accelerations).max(axis=0) / acceleration).max(),
                np.cbrt(jerk / self.max_jerk).max(),
            )
        )
