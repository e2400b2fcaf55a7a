"""Robot descriptions: what a MuJoCo model alone does not say about a robot.

An MJCF file knows joints, ranges and actuators, but not which joints form an arm, how fast they may move, or
which site is the arm's end effector. Each robot folder therefore carries a ``description.json`` beside its
model::

    {
      "schema_version": 1,
      "name": "aila",
      "model": "scene.xml",
      "keyframe": "home",
      "groups": {"right_arm": {"joints": ["J_Shoulder1_r", ...], "site": "right_grasp"}, ...},
      "limits": {"J_Shoulder1_r": {"velocity": 1.5, "acceleration": 4.0, "jerk": 40.0}, ...}
    }

Position limits are not repeated here: they are read from the compiled model (``jnt_range``), so the model
stays the single source of truth for them. Velocity, acceleration and jerk limits are in joint units per
second (rad/s or m/s, and so on); the README of each robot says where every number comes from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from besman.skills.errors import BesmanError
from besman.skills.storage import check_schema_version, optional_field, read_json, require_field

SCHEMA_VERSION = 1


class DescriptionError(BesmanError):
    """A robot description file is malformed; the message names the file and the field."""


@dataclass(frozen=True)
class JointLimitSpec:
    """Velocity, acceleration and jerk limits of one joint (absolute values, joint units per s^k)."""

    velocity: float
    acceleration: float
    jerk: float


@dataclass(frozen=True)
class GroupSpec:
    """A named set of joints (in order), its end-effector site and the equalities that belong to it."""

    name: str
    joints: tuple[str, ...]
    site: str | None
    equalities: tuple[str, ...]


@dataclass(frozen=True)
class RobotDescription:
    """The parsed ``description.json`` of one robot."""

    name: str
    title: str
    model_file: Path
    keyframe: str
    groups: dict[str, GroupSpec]
    limits: dict[str, JointLimitSpec]


def _field(mapping: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    return require_field(mapping, key, kind, where, DescriptionError)


def _string_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise DescriptionError(f"{where}: expected a list of names, got {value!r}")
    if len(set(value)) != len(value):
        raise DescriptionError(f"{where}: names repeat in {value!r}")
    return tuple(value)


def read_description(path: Path) -> RobotDescription:
    """Reads and validates a ``description.json``; errors name the file and the offending field."""
    path = Path(path)
    raw = read_json(path, DescriptionError)
    where = str(path)
    check_schema_version(raw, SCHEMA_VERSION, where, DescriptionError)

    groups: dict[str, GroupSpec] = {}
    for group_name, group in _field(raw, "groups", dict, where).items():
        group_where = f"{where}.groups.{group_name}"
        if not isinstance(group, dict):
            raise DescriptionError(f"{group_where}: expected an object, got {group!r}")
        groups[group_name] = GroupSpec(
            name=group_name,
            joints=_string_list(group.get("joints", []), f"{group_where}.joints"),
            site=optional_field(group, "site", str, group_where, DescriptionError),
            equalities=_string_list(group.get("equalities", []), f"{group_where}.equalities"),
        )

    limits: dict[str, JointLimitSpec] = {}
    for joint, spec in _field(raw, "limits", dict, where).items():
        joint_where = f"{where}.limits.{joint}"
        if not isinstance(spec, dict):
            raise DescriptionError(f"{joint_where}: expected an object, got {spec!r}")
        values = {}
        for key in ("velocity", "acceleration", "jerk"):
            value = _field(spec, key, (int, float), joint_where)
            if not math.isfinite(value) or value <= 0:
                raise DescriptionError(
                    f"{joint_where}.{key}: must be a finite positive number, got {value!r}"
                )
            values[key] = float(value)
        limits[joint] = JointLimitSpec(**values)

    return RobotDescription(
        name=_field(raw, "name", str, where),
        title=optional_field(raw, "title", str, where, DescriptionError) or "",
        model_file=path.parent / _field(raw, "model", str, where),
        keyframe=_field(raw, "keyframe", str, where),
        groups=groups,
        limits=limits,
    )
