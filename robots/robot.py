"""A robot: a compiled MuJoCo model together with its description (joint groups and limits).

``load(name)`` finds the robot's folder (Menagerie layout, shipped as package data), compiles its scene and
checks the description against the model: every joint, site and equality it names must exist, every actuated
joint must have velocity, acceleration and jerk limits. The result is a :class:`Robot` whose
:class:`JointGroup` objects carry the index arrays and limit vectors that controllers and learners need.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import mujoco
import numpy as np

from besman.robots.description import DescriptionError, RobotDescription, read_description
from besman.skills.errors import InputError

ROBOTS_DIR = Path(__file__).resolve().parent
DESCRIPTION_FILE = "description.json"


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


class Robot:
    """A compiled robot model plus its description.

    Attributes:
        name: the robot's name (``besman.robots.available()`` lists them).
        model: the compiled ``mujoco.MjModel`` of the robot's scene.
        groups: joint groups by name, e.g. ``robot.groups["right_arm"]``.
        folder: the robot's model folder (``<robot>.xml``, ``scene.xml``, ``README.md``, ...).
    """

    def __init__(self, description: RobotDescription, model: mujoco.MjModel) -> None:
        self.description = description
        self.model = model
        self.name = description.name
        self.folder = description.model_file.parent
        self.keyframe = description.keyframe
        self.groups: Mapping[str, JointGroup] = MappingProxyType(
            {name: self._compile_group(name) for name in description.groups}
        )

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.model.nq}, nu={self.model.nu}, groups={list(self.groups)})"

    def group(self, name: str) -> JointGroup:
        """The joint group ``name``; an unknown name raises a ``KeyError`` that lists the groups."""
        try:
            return self.groups[name]
        except KeyError:
            raise KeyError(
                f"robot {self.name!r} has no joint group {name!r}; groups: {', '.join(self.groups)}"
            ) from None

    def make_data(self, keyframe: str | None = None) -> mujoco.MjData:
        """A new ``MjData`` reset to ``keyframe`` (default: the description's) and forwarded."""
        data = mujoco.MjData(self.model)
        self.reset(data, keyframe)
        return data

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
        where = f"{self.description.model_file.parent / DESCRIPTION_FILE}: group {name!r}"

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


def available() -> list[str]:
    """Names of the robots shipped with besman (folders with a ``description.json``)."""
    return sorted(path.parent.name for path in ROBOTS_DIR.glob(f"*/{DESCRIPTION_FILE}"))


def load(name: str) -> Robot:
    """Loads a shipped robot by name (see :func:`available`), or a robot folder given as a path.

    Raises:
        ValueError: unknown name (the message lists the available robots), or a malformed description or
            model (the message names the file).
    """
    folder = Path(name)
    if not (folder / DESCRIPTION_FILE).is_file():
        if name not in available():
            raise InputError(f"unknown robot {name!r}; available: {', '.join(available())}")
        folder = ROBOTS_DIR / name
    description = read_description(folder / DESCRIPTION_FILE)
    try:
        model = mujoco.MjModel.from_xml_path(str(description.model_file))
    except ValueError as error:
        raise InputError(f"{description.model_file}: the model does not compile: {error}") from None
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, description.keyframe) < 0:
        raise DescriptionError(f"{description.model_file}: no keyframe {description.keyframe!r}")
    return Robot(description, model)
