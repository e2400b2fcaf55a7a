"""A robot: a compiled MuJoCo model together with its description (joint groups, limits and arms).

``load(name)`` finds the robot's folder (Menagerie layout, shipped as package data), assembles its model
(:mod:`besman.robots.assembly`), compiles it and checks the description against the model: every joint,
site, equality, actuator and geom it names must exist, every actuated joint must have velocity, acceleration
and jerk limits. The result is a :class:`Robot` whose :class:`JointGroup` objects carry the index arrays and
limit vectors that controllers and learners need, and whose :class:`RobotArm` objects say what each arm
moves, where its tool is and how its gripper works.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import mujoco
import numpy as np

from besman.core.errors import InputError, UnknownNameError
from besman.core.validation import checked, instance, optional, text
from besman.robots.assembly import build_spec
from besman.robots.catalogue import ROBOT, describe
from besman.robots.description import DescriptionError, GripperSpec, RobotDescription
from besman.robots.gripper import Gripper


def _frozen(values, dtype=float) -> np.ndarray:
    array = np.array(values, dtype=dtype)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class JointGroup:
    """A named, ordered set of joints with their limits and the actuators that drive them.

    All arrays follow the order of ``joints``. ``qpos_indices`` and ``dof_indices`` index ``MjData.qpos`` and
    ``MjData.qvel``; ``actuators`` are the actuators whose transmission acts on these joints (directly or
    through a tendon), and ``actuator_indices`` index ``MjData.ctrl``.
    """

    name: str
    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    site: str | None
    equalities: tuple[str, ...]
    qpos_indices: np.ndarray
    dof_indices: np.ndarray
    actuator_indices: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @property
    def size(self) -> int:
        """Number of joints in the group."""
        return len(self.joints)


@dataclass(frozen=True, eq=False)
class RobotArm:
    """An arm of a compiled robot: the joint groups it moves (in order), its tool-centre point site and its
    gripper (None without one)."""

    name: str
    groups: tuple[str, ...]
    tcp: str
    gripper: Gripper | None


class Robot:
    """A compiled robot model plus its description.

    Attributes:
        name: the robot's name (``besman.robots.available()`` lists them).
        model: the compiled ``mujoco.MjModel`` of the robot's scene.
        groups: joint groups by name, e.g. ``robot.groups["right_arm"]``.
        arms: arms by name, in the description's order (the first is the one that works alone).
        folder: the robot's folder (``description.json``, ``README.md``, ...).
    """

    def __init__(self, description: RobotDescription, model: mujoco.MjModel) -> None:
        self.description = description
        self.model = model
        self.name = description.name
        self.folder = description.folder
        self.keyframe = description.keyframe
        self.groups: Mapping[str, JointGroup] = MappingProxyType(
            {name: self._compile_group(name) for name in description.groups}
        )
        self.arms: Mapping[str, RobotArm] = MappingProxyType(
            {name: self._compile_arm(name) for name in description.arms}
        )

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.model.nq}, nu={self.model.nu}, groups={list(self.groups)})"

    def group(self, name: str) -> JointGroup:
        """The joint group ``name``; an unknown name raises :class:`UnknownNameError` listing the groups."""
        if name not in self.groups:
            raise UnknownNameError(
                f"robot {self.name!r} has no joint group {name!r}; groups: {', '.join(self.groups)}"
            )
        return self.groups[name]

    def arm(self, name: str | None = None) -> RobotArm:
        """The arm ``name`` (None: the first, the one that works alone); an unknown name raises an
        :class:`UnknownNameError` listing the arms."""
        if not self.arms:
            raise InputError(f"robot {self.name!r}: its description has no arms ({self.description.file})")
        if name is None:
            return next(iter(self.arms.values()))
        if name not in self.arms:
            raise UnknownNameError(f"robot {self.name!r} has no arm {name!r}; arms: {', '.join(self.arms)}")
        return self.arms[name]

    def make_data(self, keyframe: str | None = None) -> mujoco.MjData:
        """A new ``MjData`` reset to ``keyframe`` (default: the description's) and forwarded."""
        data = mujoco.MjData(self.model)
        self.reset(data, keyframe)
        return data

    @checked(data=instance(mujoco.MjData, "an MjData"), keyframe=optional(text("a keyframe name")))
    def reset(self, data: mujoco.MjData, keyframe: str | None = None) -> None:
        """Resets ``data`` to a keyframe (state and ctrl) and runs ``mj_forward``."""
        name = keyframe or self.keyframe
        key = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, name)
        if key < 0:
            names = [self.model.key(k).name for k in range(self.model.nkey)]
            raise InputError(f"robot {self.name!r} has no keyframe {name!r}; keyframes: {', '.join(names)}")
        mujoco.mj_resetDataKeyframe(self.model, data, key)
        mujoco.mj_forward(self.model, data)

    def _compile_group(self, name: str) -> JointGroup:
        spec = self.description.groups[name]
        model = self.model
        where = f"{self.description.file}: group {name!r}"

        joint_ids = []
        for joint in spec.joints:
            joint_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
            if joint_id < 0:
                raise DescriptionError(f"{where}: the model has no joint {joint!r}")
            if int(model.jnt_type[joint_id]) not in (
                mujoco.mjtJoint.mjJNT_HINGE.value,
                mujoco.mjtJoint.mjJNT_SLIDE.value,
            ):
                raise DescriptionError(f"{where}: joint {joint!r} is not a hinge or slide joint")
            if not model.jnt_limited[joint_id]:
                raise DescriptionError(f"{where}: joint {joint!r} has no range in the model")
            if joint not in self.description.limits:
                raise DescriptionError(f"{where}: joint {joint!r} has no velocity/acceleration/jerk limits")
            joint_ids.append(joint_id)
        if spec.site is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, spec.site) < 0:
            raise DescriptionError(f"{where}: the model has no site {spec.site!r}")
        for equality in spec.equalities:
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, equality) < 0:
                raise DescriptionError(f"{where}: the model has no equality {equality!r}")

        dofs = {int(model.jnt_dofadr[j]) for j in joint_ids}
        actuator_ids = [a for a in range(model.nu) if dofs & self._actuated_dofs(a)]
        limits = [self.description.limits[joint] for joint in spec.joints]
        return JointGroup(
            name=name,
            joints=spec.joints,
            actuators=tuple(model.actuator(a).name for a in actuator_ids),
            site=spec.site,
            equalities=spec.equalities,
            qpos_indices=_frozen([model.jnt_qposadr[j] for j in joint_ids], int),
            dof_indices=_frozen([model.jnt_dofadr[j] for j in joint_ids], int),
            actuator_indices=_frozen(actuator_ids, int),
            lower=_frozen([model.jnt_range[j, 0] for j in joint_ids]),
            upper=_frozen([model.jnt_range[j, 1] for j in joint_ids]),
            velocity=_frozen([limit.velocity for limit in limits]),
            acceleration=_frozen([limit.acceleration for limit in limits]),
            jerk=_frozen([limit.jerk for limit in limits]),
        )

    def _compile_arm(self, name: str) -> RobotArm:
        spec, model = self.description.arms[name], self.model
        where = f"{self.description.file}.arms.{name}"
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, spec.tcp.site) < 0:
            raise DescriptionError(f"{where}.tcp: the model has no site {spec.tcp.site!r}")
        for group in spec.groups:
            self._check_servos(self.group(group), where)
        gripper = None
        if spec.gripper is not None:
            gripper = self._compile_gripper(spec.gripper, f"{where}.gripper")
        return RobotArm(name, spec.groups, spec.tcp.site, gripper)

    def _check_servos(self, group: JointGroup, where: str) -> None:
        """Every joint of an arm's group driven by a position actuator: besman commands joint positions."""
        model = self.model
        for joint, dof in zip(group.joints, group.dof_indices, strict=True):
            drivers = [a for a in group.actuator_indices if dof in self._actuated_dofs(a)]
            if any(_is_servo(model, a) for a in drivers):
                continue
            driven = (
                "no actuator"
                if not drivers
                else ", ".join(f"{model.actuator(a).name or f'#{a}'} (not a position servo)" for a in drivers)
            )
            raise DescriptionError(
                f"{where}: joint {joint!r} is driven by {driven}: besman commands each arm joint's position; "
                f'give it a position actuator in the description: "servos": {{"{joint}": {{"kp": ..., "kv": '
                "...}} (stiffness and damping: the maker's gains, or what robots check then shows it follows)"
            )

    def _compile_gripper(self, description: GripperSpec, where: str) -> Gripper:
        model = self.model
        if description.actuators:
            named = description.actuators
            actuators = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in named]
            if min(actuators) < 0:
                missing = named[actuators.index(min(actuators))]
                raise DescriptionError(f"{where}.actuator: the model has no actuator {missing!r}")
        else:  # those that drive the fingers' joints (named or not)
            actuators = list(self.group(description.group).actuator_indices)
        if len(actuators) != len(description.command):
            names = ", ".join(model.actuator(a).name or f"#{a} (unnamed)" for a in actuators)
            raise DescriptionError(
                f"{where}: {len(actuators)} actuators drive the fingers ({names}): command needs a list of "
                f"commands for each, in that order (it has {len(description.command)})"
            )
        pads = tuple(_frozen(self._pad_geoms(side, f"{where}.pads"), int) for side in description.pads)
        order = np.argsort(description.opening)
        return Gripper(
            group=description.group,
            actuators=_frozen(actuators, int),
            opening=_frozen(np.asarray(description.opening)[order]),
            command=_frozen(np.asarray(description.command).T[order]),
            open=description.open,
            pads=(pads[0], pads[1]),
            limits=description.limits,
            still_speed=description.still_speed,
        )

    def _pad_geoms(self, names: tuple[str, ...], where: str) -> list[int]:
        """The geoms of one side's pads: each name a geom, or a body whose colliding geoms are pads (finger
        geoms a model leaves unnamed)."""
        model, geoms = self.model, []
        for name in names:
            geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if geom >= 0:
                geoms.append(geom)
                continue
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if body < 0:
                raise DescriptionError(f"{where}: the model has no geom or body {name!r}")
            colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
            found = np.flatnonzero((model.geom_bodyid == body) & colliding)
            if len(found) == 0:
                raise DescriptionError(f"{where}: body {name!r} has no geom that collides")
            geoms.extend(int(geom) for geom in found)
        return geoms

    def _actuated_dofs(self, actuator: int) -> set[int]:
        """The DOFs an actuator's transmission acts on (joint or fixed tendon)."""
        model = self.model
        kind, target = int(model.actuator_trntype[actuator]), model.actuator_trnid[actuator, 0]
        if kind == mujoco.mjtTrn.mjTRN_JOINT.value:
            return {int(model.jnt_dofadr[target])}
        if kind == mujoco.mjtTrn.mjTRN_TENDON.value:
            first, count = model.tendon_adr[target], model.tendon_num[target]
            return {
                int(model.jnt_dofadr[model.wrap_objid[w]])
                for w in range(first, first + count)
                if model.wrap_type[w] == mujoco.mjtWrap.mjWRAP_JOINT.value
            }
        return set()


def _is_servo(model: mujoco.MjModel, actuator: int) -> bool:
    """Whether the actuator is a position servo: force kp * (command - position) - kv * velocity."""
    kp = model.actuator_gainprm[actuator, 0]
    return (
        model.actuator_gaintype[actuator] == mujoco.mjtGain.mjGAIN_FIXED
        and model.actuator_biastype[actuator] == mujoco.mjtBias.mjBIAS_AFFINE
        and kp > 0
        and np.isclose(model.actuator_biasprm[actuator, 1], -kp)
    )


@checked(name=ROBOT, meshes=instance(bool, "True or False"))
def load(name: str, *, meshes: bool = True) -> Robot:
    """Loads a shipped robot by name (see :func:`available`), or a robot folder given as a path. With
    ``meshes=False`` no mesh file is read (:func:`~besman.robots.assembly.without_meshes`), for what needs
    only its joints, actuators and description (``besman robots show``).

    Raises:
        InputError: unknown name (the message lists the available robots), or a model that does not load.
        DescriptionError: a malformed description, or one that does not fit the model (the message names the
            file and field).
    """
    description = describe(name)
    return Robot(description, compile_spec(build_spec(description, meshes=meshes), description))


@checked(
    spec=instance(mujoco.MjSpec, "an MjSpec (robots.build_spec)"),
    description=instance(RobotDescription, "a RobotDescription (robots.describe)"),
)
def compile_spec(spec: mujoco.MjSpec, description: RobotDescription) -> mujoco.MjModel:
    """Compiles an assembled model (with whatever a world added); errors name the description, or where the
    robot's model compiles alone, what was added to it (the model's compiler settings apply to all of it)."""
    try:
        model = spec.compile()
    except ValueError as error:
        reason = " ".join(str(error).split())
        try:
            build_spec(description).compile()
        except ValueError:
            raise InputError(f"{description.file}: the robot's model does not compile: {reason}") from None
        compiler = spec.compiler
        settings = (
            f"inertiafromgeom {compiler.inertiafromgeom.name[18:].lower()}, inertiagrouprange "
            f"{[int(group) for group in compiler.inertiagrouprange]}, angles in "
            f"{'degrees' if compiler.degree else 'radians'}"
        )
        raise InputError(
            f"besman's additions to the robot's model (its world's objects and furniture) do not compile: "
            f"{reason}; the robot's model {description.file} compiles alone, and its compiler settings "
            f"apply to them too ({settings}): a fault of besman's, please report it"
        ) from None
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, description.keyframe) < 0:
        raise DescriptionError(f"{description.file}: the model has no keyframe {description.keyframe!r}")
    return model
