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

Schema version 2 adds what lets any arm run the same skills (version 1 files stay valid):

- ``"model"`` may name a file inside MuJoCo Menagerie, ``{"menagerie": "universal_robots_ur5e/ur5e.xml"}``
  (found on this machine by :mod:`besman.robots.menagerie`, never downloaded), or a file that an installed
  Python package ships, ``{"package": "openarm-mujoco", "file": "v2/openarm_bimanual.xml"}``
  (:mod:`besman.robots.packages`); ``"home"`` (joint -> position) defines the ``keyframe`` for a model that
  has none (the actuators that drive those joints commanded there too); ``"attach"`` lists models
  attached at a site of it (a gripper on a flange: ``{"model": ..., "site": "attachment_site", "prefix":
  "gripper/"}``; names inside get the prefix, the keyframe is extended). ``"floor"`` adds besman's stage
  (floor and lights) to a model that has none, ``"mount"`` (``position``, ``yaw_degrees``) moves the robot's
  root bodies, ``"options"`` sets simulation options (``impratio``, ``cone``, ``timestep``) that an
  attached part or the model needs, and ``"exclude"`` lists body pairs whose contacts
  are ignored. ``"velocity_feedforward": true`` adds the commanded velocity times kv/kp to each position
  actuator's command: such an actuator's damping acts on the joint's velocity, not on its error, so without
  it a joint lags kv/kp x its speed (0.2 s x speed on MuJoCo Menagerie's UR5e); with it the actuator is a PD
  controller on the commanded state.
  ``"gravity_compensation": true`` compensates the weight of the robot's own bodies (MuJoCo's ``gravcomp``),
  as an arm's controller does; what it holds still weighs.
- ``"arms"``: per arm its joint groups, its tool-centre point (a site, or ``{"body", "position"}`` that adds
  one; its z axis points out of the hand, its y axis along the fingers' closing) and its gripper: the joint
  group of the fingers, the actuator, the map between opening (m per finger, half the aperture between the
  pads) and actuator command as matching ``opening`` / ``command`` lists, the opening ``open`` that grasps
  and releases, the pad geoms of each side (``pads``: two lists), the opening's velocity, acceleration and
  jerk limits, and optionally ``still_speed``, the fingers' joint speed (their joint's units per s, default
  1e-3) under which closed fingers count as settled (fingers that squeeze an object may creep). With
  several arms working at once, groups that two arms share (a waist) are held.
- ``"tabletop"``: the robot's work surface: where the tabletop world puts its table and shelf boards, in
  the robot's frame (the world's, with the robot standing at the origin), and ``reach``, the area of the
  table where the first arm reaches top-down grasps (objects start at its middle; tasks draw their objects
  there).
- ``"tasks"``: numbers of tasks that do not know this robot, by task name (``{"pick-place": {"places":
  ...}}``); each task reads and checks its own (:mod:`besman.tasks`). The tasks keep the numbers of the
  shipped robots themselves. An earlier description's ``tabletop.objects`` is read as ``tabletop.reach``,
  its ``tabletop.places`` as ``tasks.pick-place.places`` and its ``tabletop.handover`` as
  ``tasks.handover``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from besman.skills.errors import BesmanError
from besman.skills.storage import check_schema_version, optional_field, read_json, require_field

SCHEMA_VERSION = 2
# Simulation options a description may set (an attached gripper may need them; the parent's are kept).
OPTIONS = ("impratio", "cone", "timestep")


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
class ModelSource:
    """A model file: beside the description, a path inside MuJoCo Menagerie (``menagerie``), or a file that
    the installed Python distribution ``package`` ships (``file`` is the tail of its path)."""

    file: str
    menagerie: bool = False
    package: str | None = None


@dataclass(frozen=True)
class Attachment:
    """A model attached at a site of the robot's model, its names prefixed."""

    model: ModelSource
    site: str
    prefix: str


@dataclass(frozen=True)
class ToolCentrePoint:
    """An arm's tool frame: an existing ``site``, or a new site ``site`` on ``body`` at ``position`` (m)
    turned by ``quaternion`` (w, x, y, z) in the body's frame."""

    site: str
    body: str | None = None
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quaternion: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class GripperSpec:
    """A gripper: its fingers' joint group, its actuators (none named: those that drive the group's joints),
    opening (m per finger) <-> command as matching monotone lists (a list of commands per actuator), the
    opening that grasps and releases, the pads of each side (geoms, or bodies whose geoms they are) and the
    opening's motion limits (m/s, m/s^2, m/s^3 per finger), and the finger joints' speed under which they
    have settled."""

    group: str
    actuators: tuple[str, ...]
    opening: tuple[float, ...]
    command: tuple[tuple[float, ...], ...]
    open: float
    pads: tuple[tuple[str, ...], tuple[str, ...]]
    limits: JointLimitSpec
    still_speed: float = 1e-3


@dataclass(frozen=True)
class ArmSpec:
    """An arm: the joint groups it moves (in order), its tool-centre point and its gripper (if any)."""

    name: str
    groups: tuple[str, ...]
    tcp: ToolCentrePoint
    gripper: GripperSpec | None


@dataclass(frozen=True)
class Board:
    """A horizontal rectangle: top at ``height``, covering [x0, x1] x [y0, y1] (m, robot frame)."""

    height: float
    x: tuple[float, float]
    y: tuple[float, float]


Area = tuple[tuple[float, float], tuple[float, float]]  # (x0, x1), (y0, y1)


@dataclass(frozen=True)
class HandPose:
    """Where a hand goes: ``position`` (m) pointing down, turned by ``yaw`` (rad) about z (None: as it is)."""

    position: tuple[float, float, float]
    yaw: float | None = None


@dataclass(frozen=True)
class TabletopLayout:
    """The robot's work surface: the table, the shelf board on it and the area of the table the first arm
    reaches (top-down grasps)."""

    table: Board
    shelf: Board
    reach: Area


@dataclass(frozen=True)
class Mount:
    """Where the robot's root bodies are moved: ``position`` (m) and a turn ``yaw`` (rad) about z."""

    position: tuple[float, float, float]
    yaw: float


@dataclass(frozen=True)
class RobotDescription:
    """The parsed ``description.json`` of one robot."""

    name: str
    title: str
    folder: Path
    model: ModelSource
    keyframe: str
    groups: dict[str, GroupSpec]
    limits: dict[str, JointLimitSpec]
    attach: tuple[Attachment, ...] = ()
    floor: bool = False
    mount: Mount | None = None
    options: dict[str, Any] = field(default_factory=dict)
    exclude: tuple[tuple[str, str], ...] = ()
    arms: dict[str, ArmSpec] = field(default_factory=dict)
    tabletop: TabletopLayout | None = None
    tasks: dict[str, dict] = field(default_factory=dict)  # task name -> its section (read by the task)
    velocity_feedforward: bool = False
    gravity_compensation: bool = False
    home: dict[str, float] = field(default_factory=dict)

    @property
    def file(self) -> Path:
        """The description file."""
        return self.folder / "description.json"


def _field(mapping: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    return require_field(mapping, key, kind, where, DescriptionError)


def _string_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise DescriptionError(f"{where}: expected a list of names, got {value!r}")
    if len(set(value)) != len(value):
        raise DescriptionError(f"{where}: names repeat in {value!r}")
    return tuple(value)


def _numbers(value: Any, where: str, count: int | None = None) -> tuple[float, ...]:
    if (
        not isinstance(value, list)
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(v) for v in value)
        or (count is not None and len(value) != count)
    ):
        size = f"{count} " if count is not None else ""
        raise DescriptionError(f"{where}: expected a list of {size}finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _range(value: Any, where: str) -> tuple[float, float]:
    low, high = _numbers(value, where, 2)
    if not low < high:
        raise DescriptionError(f"{where}: expected [low, high] with low < high, got {value!r}")
    return low, high


def _object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise DescriptionError(f"{where}: expected an object, got {value!r}")
    return value


def _limits(spec: Any, where: str) -> JointLimitSpec:
    spec = _object(spec, where)
    values = {}
    for key in ("velocity", "acceleration", "jerk"):
        value = _field(spec, key, (int, float), where)
        if not math.isfinite(value) or value <= 0:
            raise DescriptionError(f"{where}.{key}: must be a finite positive number, got {value!r}")
        values[key] = float(value)
    return JointLimitSpec(**values)


def _model_source(value: Any, where: str) -> ModelSource:
    if isinstance(value, str):
        return ModelSource(value)
    if isinstance(value, dict) and set(value) == {"menagerie"} and isinstance(value["menagerie"], str):
        return ModelSource(value["menagerie"], menagerie=True)
    if (
        isinstance(value, dict)
        and set(value) == {"package", "file"}
        and all(isinstance(item, str) for item in value.values())
    ):
        return ModelSource(value["file"], package=value["package"])
    raise DescriptionError(
        f'{where}: expected a file name, {{"menagerie": "folder/file.xml"}} or '
        f'{{"package": "distribution", "file": "folder/file.xml"}}, got {value!r}'
    )


def _tcp(value: Any, where: str) -> ToolCentrePoint:
    value = _object(value, where)
    site = _field(value, "site", str, where)
    body = optional_field(value, "body", str, where, DescriptionError)
    if body is None:
        if set(value) - {"site"}:
            raise DescriptionError(f"{where}: a position or quaternion needs the body the new site is on")
        return ToolCentrePoint(site)
    quaternion = _numbers(value.get("quaternion", [1, 0, 0, 0]), f"{where}.quaternion", 4)
    if not math.isclose(math.hypot(*quaternion), 1.0, abs_tol=1e-6):
        raise DescriptionError(f"{where}.quaternion: must have unit length, got {list(quaternion)}")
    return ToolCentrePoint(
        site, body, _numbers(value.get("position", [0, 0, 0]), f"{where}.position", 3), quaternion
    )


def _gripper(value: Any, where: str) -> GripperSpec:
    value = _object(value, where)
    opening = _numbers(_field(value, "opening", list, where), f"{where}.opening")
    actuators = value.get("actuator", [])
    actuators = _string_list([actuators] if isinstance(actuators, str) else actuators, f"{where}.actuator")
    command = _field(value, "command", list, where)
    # One actuator's commands, or a list per actuator (a gripper with an actuator for each finger).
    tables = command if command and all(isinstance(row, list) for row in command) else [command]
    command = tuple(_numbers(row, f"{where}.command[{i}]") for i, row in enumerate(tables))
    if actuators and len(actuators) != len(command):
        raise DescriptionError(
            f"{where}.command: one list of commands per actuator ({len(actuators)}), got {len(command)}"
        )
    if len(opening) < 2 or any(len(row) != len(opening) for row in command):
        raise DescriptionError(f"{where}: opening and command must be matching lists of 2 or more numbers")
    for name, values in (("opening", opening), *(("command", row) for row in command)):
        steps = [b - a for a, b in itertools.pairwise(values)]
        if not (all(step > 0 for step in steps) or all(step < 0 for step in steps)):
            raise DescriptionError(f"{where}.{name}: must rise or fall strictly, got {list(values)}")
    if min(opening) < 0:
        raise DescriptionError(f"{where}.opening: openings are >= 0 m, got {list(opening)}")
    grasp_open = _field(value, "open", (int, float), where)
    if not min(opening) < grasp_open <= max(opening):
        raise DescriptionError(
            f"{where}.open: must lie in the opening's range "
            f"({min(opening):g}, {max(opening):g}], got {grasp_open!r}"
        )
    pads = value.get("pads")
    if not isinstance(pads, list) or len(pads) != 2:
        raise DescriptionError(
            f"{where}.pads: expected two lists of geom or body names (one per side), got {pads!r}"
        )
    sides = tuple(_string_list(side, f"{where}.pads[{i}]") for i, side in enumerate(pads))
    if not all(sides):
        raise DescriptionError(f"{where}.pads: each side needs at least one geom")
    still_speed = value.get("still_speed", GripperSpec.still_speed)
    if isinstance(still_speed, bool) or not isinstance(still_speed, int | float) or not still_speed > 0:
        raise DescriptionError(f"{where}.still_speed: must be a number above 0, got {still_speed!r}")
    return GripperSpec(
        group=_field(value, "group", str, where),
        actuators=actuators,
        opening=opening,
        command=command,
        open=float(grasp_open),
        pads=(sides[0], sides[1]),
        limits=_limits(_field(value, "limits", dict, where), f"{where}.limits"),
        still_speed=float(still_speed),
    )


def _arm(name: str, value: Any, groups: dict[str, GroupSpec], where: str) -> ArmSpec:
    value = _object(value, where)
    members = _string_list(_field(value, "groups", list, where), f"{where}.groups")
    for group in members:
        if group not in groups:
            raise DescriptionError(f"{where}.groups: no group {group!r}; groups: {', '.join(groups)}")
    gripper = value.get("gripper")
    gripper = None if gripper is None else _gripper(gripper, f"{where}.gripper")
    if gripper is not None and gripper.group not in groups:
        raise DescriptionError(
            f"{where}.gripper.group: no group {gripper.group!r}; groups: {', '.join(groups)}"
        )
    return ArmSpec(name, members, _tcp(_field(value, "tcp", dict, where), f"{where}.tcp"), gripper)


def _board(value: Any, where: str) -> Board:
    value = _object(value, where)
    height = _field(value, "height", (int, float), where)
    return Board(float(height), _range(value.get("x"), f"{where}.x"), _range(value.get("y"), f"{where}.y"))


def read_area(value: Any, where: str, board: Board | None = None) -> Area:
    """An area ``{"x": [x0, x1], "y": [y0, y1]}`` (m); with a ``board``, it must lie on it."""
    value = _object(value, where)
    area = _range(value.get("x"), f"{where}.x"), _range(value.get("y"), f"{where}.y")
    if board is not None and not _inside(area, board):
        raise DescriptionError(
            f"{where}: the area x {list(area[0])}, y {list(area[1])} must lie on the board at "
            f"{board.height} m (x {list(board.x)}, y {list(board.y)})"
        )
    return area


def read_hand_pose(value: Any, where: str) -> HandPose:
    """A hand pose ``{"position": [x, y, z], "yaw": rad}`` (yaw optional)."""
    value = _object(value, where)
    unknown = sorted(set(value) - {"position", "yaw"})
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field of a hand pose (position, yaw)")
    yaw = value.get("yaw")
    return HandPose(
        _numbers(value.get("position"), f"{where}.position", 3),
        None if yaw is None else _numbers([yaw], f"{where}.yaw")[0],
    )


def section(value: Any, where: str, fields: tuple[str, ...]) -> dict:
    """A mapping with exactly the given ``fields`` (a task's section of a description)."""
    value = _object(value, where)
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field here ({', '.join(fields)})")
    for name in fields:
        _field(value, name, dict, where)
    return value


def _inside(area: Area, board: Board) -> bool:
    (x0, x1), (y0, y1) = area
    return board.x[0] <= x0 and x1 <= board.x[1] and board.y[0] <= y0 and y1 <= board.y[1]


# An earlier description's task areas inside "tabletop", and the task section each is read into.
EARLIER_TASK_FIELDS = {"places": "pick-place", "handover": "handover"}


def _tabletop(value: Any, where: str) -> TabletopLayout:
    value = _object(value, where)
    unknown = sorted(set(value) - {"table", "shelf", "reach", "objects", *EARLIER_TASK_FIELDS})
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field of the tabletop (table, shelf, reach)")
    table = _board(_field(value, "table", dict, where), f"{where}.table")
    reach = (
        "reach" if "reach" in value or "objects" not in value else "objects"
    )  # "objects": the earlier name
    return TabletopLayout(
        table=table,
        shelf=_board(_field(value, "shelf", dict, where), f"{where}.shelf"),
        reach=read_area(_field(value, reach, dict, where), f"{where}.{reach}", table),
    )


def _tasks(raw: dict, where: str) -> dict[str, dict]:
    """The description's task sections, the earlier form's areas in ``tabletop`` among them."""
    given = _object(raw.get("tasks", {}), f"{where}.tasks")
    tasks = {name: _object(value, f"{where}.tasks.{name}") for name, value in given.items()}
    earlier = raw.get("tabletop") or {}
    for name, task in EARLIER_TASK_FIELDS.items():
        if name in earlier:
            if task == name:
                tasks.setdefault(task, earlier[name])
            else:
                tasks.setdefault(task, {}).setdefault(name, earlier[name])
    return tasks


# The top-level fields of each schema version (an unknown one is refused, not ignored: a misspelt or
# later field would otherwise be lost without a word).
FIELDS = {
    1: frozenset({"schema_version", "name", "title", "model", "keyframe", "groups", "limits"}),
}
FIELDS[2] = FIELDS[1] | {
    "attach",
    "options",
    "mount",
    "floor",
    "velocity_feedforward",
    "gravity_compensation",
    "home",
    "exclude",
    "arms",
    "tabletop",
    "tasks",
}


def read_description(path: Path) -> RobotDescription:
    """Reads and validates a ``description.json``; errors name the file and the offending field."""
    path = Path(path)
    raw = read_json(path, DescriptionError, what="robot description")
    where = str(path)
    check_schema_version(raw, (1, SCHEMA_VERSION), where, DescriptionError)
    known = FIELDS[raw["schema_version"]]
    unknown = sorted(set(raw) - known)
    if unknown:
        later = " (a field of schema_version 2)" if unknown[0] in FIELDS[2] else ""
        raise DescriptionError(
            f"{where}.{unknown[0]}: not a field of a description{later}; fields: {', '.join(sorted(known))}"
        )

    groups: dict[str, GroupSpec] = {}
    for group_name, group in _field(raw, "groups", dict, where).items():
        group_where = f"{where}.groups.{group_name}"
        group = _object(group, group_where)
        groups[group_name] = GroupSpec(
            name=group_name,
            joints=_string_list(group.get("joints", []), f"{group_where}.joints"),
            site=optional_field(group, "site", str, group_where, DescriptionError),
            equalities=_string_list(group.get("equalities", []), f"{group_where}.equalities"),
        )
    limits = {
        joint: _limits(spec, f"{where}.limits.{joint}")
        for joint, spec in _field(raw, "limits", dict, where).items()
    }
    if raw["schema_version"] == 1:
        return RobotDescription(
            name=_field(raw, "name", str, where),
            title=optional_field(raw, "title", str, where, DescriptionError) or "",
            folder=path.parent,
            model=ModelSource(_field(raw, "model", str, where)),
            keyframe=_field(raw, "keyframe", str, where),
            groups=groups,
            limits=limits,
        )

    attach = []
    for index, item in enumerate(raw.get("attach", [])):
        item_where = f"{where}.attach[{index}]"
        item = _object(item, item_where)
        attach.append(
            Attachment(
                _model_source(item.get("model"), f"{item_where}.model"),
                _field(item, "site", str, item_where),
                _field(item, "prefix", str, item_where),
            )
        )
    mount = raw.get("mount")
    if mount is not None:
        mount = _object(mount, f"{where}.mount")
        mount = Mount(
            _numbers(mount.get("position", [0, 0, 0]), f"{where}.mount.position", 3),
            math.radians(_numbers([mount.get("yaw_degrees", 0)], f"{where}.mount.yaw_degrees")[0]),
        )
    options = _object(raw.get("options", {}), f"{where}.options")
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise DescriptionError(
            f"{where}.options.{unknown[0]}: not a known option; options: {', '.join(OPTIONS)}"
        )
    exclude = raw.get("exclude", [])
    if not isinstance(exclude, list):
        raise DescriptionError(f"{where}.exclude: expected a list of body pairs, got {exclude!r}")
    pairs = []
    for index, pair in enumerate(exclude):
        names = _string_list(pair, f"{where}.exclude[{index}]")
        if len(names) != 2:
            raise DescriptionError(f"{where}.exclude[{index}]: expected two body names, got {pair!r}")
        pairs.append((names[0], names[1]))
    arms = {
        name: _arm(name, value, groups, f"{where}.arms.{name}")
        for name, value in _object(raw.get("arms", {}), f"{where}.arms").items()
    }
    tabletop = raw.get("tabletop")
    switches = {key: raw.get(key, False) for key in ("floor", "velocity_feedforward", "gravity_compensation")}
    for key, value in switches.items():
        if not isinstance(value, bool):
            raise DescriptionError(f"{where}.{key}: expected true or false, got {value!r}")
    home = _object(raw.get("home", {}), f"{where}.home")
    for joint, position in home.items():
        _numbers([position], f"{where}.home.{joint}")
    return RobotDescription(
        name=_field(raw, "name", str, where),
        title=optional_field(raw, "title", str, where, DescriptionError) or "",
        folder=path.parent,
        model=_model_source(raw.get("model"), f"{where}.model"),
        keyframe=_field(raw, "keyframe", str, where),
        groups=groups,
        limits=limits,
        attach=tuple(attach),
        floor=switches["floor"],
        mount=mount,
        options=options,
        exclude=tuple(pairs),
        arms=arms,
        tabletop=None if tabletop is None else _tabletop(tabletop, f"{where}.tabletop"),
        tasks=_tasks(raw, where),
        velocity_feedforward=switches["velocity_feedforward"],
        gravity_compensation=switches["gravity_compensation"],
        home={joint: float(position) for joint, position in home.items()},
    )
