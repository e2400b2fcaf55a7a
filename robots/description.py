"""Robot descriptions: what a MuJoCo model alone does not say about a robot - the field reference.

An MJCF file knows joints, ranges and actuators, but not which joints form an arm, how fast they may move,
where the tool is or how the gripper opens. A robot is a folder with a ``description.json`` that says so
(and a README saying where every number comes from). Position limits are not repeated: they are read from
the compiled model (``jnt_range``). ``besman robots check FOLDER`` (:mod:`besman.tasks.robot_check`) runs
the checks that a description must pass for the tabletop tasks and says what to change.

Top-level fields (schema version 2; a field the version does not have is refused, not ignored):

- ``schema_version`` (required): 2 (1: only the fields marked "in v1", the model a file beside the
  description)
- ``name`` (required; in v1): the robot's name: tasks keep their numbers by it; pools record it
- ``title`` (optional; in v1): one line for listings
- ``model`` (required; in v1): a file beside the description (``"my_arm.xml"``), a Menagerie file
  ``{"menagerie": "universal_robots_ur5e/ur5e.xml"}`` (found in ``$MENAGERIE_ROOT`` or a package that ships
  Menagerie folders, never downloaded: :mod:`besman.robots.menagerie`), or a file an installed package ships
  ``{"package": "trossen-arm-sim", "file": "assets/wxai_follower.xml"}`` (the tail of its path in the
  package's record of installed files: :mod:`besman.robots.packages`)
- ``keyframe`` (required; in v1): the keyframe the robot starts in: the planner solves its first poses from
  there, so the first arm's hand should point down in it, or be turned down from it without restarts
- ``home`` (optional): ``{joint: position}``: the ``keyframe`` for a model that has none (the model's
  reference configuration elsewhere; every actuator that drives one joint commanded to it)
- ``groups`` (required; in v1): ``{name: {"joints": [...], "site": optional, "equalities": optional}}``:
  ordered joint groups
- ``limits`` (required; in v1): ``{joint: {"velocity", "acceleration", "jerk"}}`` per joint of every group, in
  its units per s, s^2, s^3: from the maker's data sheet, and no faster than the model's actuators follow
  (``robots check`` measures it and suggests a value)
- ``attach`` (optional): ``[{"model": ..., "site": ..., "prefix": ...}]``: models attached at a site (a
  gripper on a flange), or at a body's origin (``"body"`` instead of ``"site"``: a model with no site
  there), names prefixed; the keyframe is extended
- ``options`` (optional): simulation options the model or an attached part needs (``impratio``, ``cone``,
  ``timestep``; ``noslip_iterations``: MuJoCo's no-slip solver, for a grip that must not turn an object
  held off its middle, as the handover's bar; ``integrator``: ``Euler``, ``RK4``, ``implicit`` or
  ``implicitfast``, as MJCF spells them; a tabletop world integrates ``implicit`` unless this names one:
  Euler takes actuator damping explicitly, implicitfast leaves out the Coriolis derivatives a grasped object
  spinning between the pads needs); at attach the parent's win
- ``mount`` (optional): ``{"position": [x, y, z], "yaw_degrees": deg}``: where the robot's root bodies stand
  (turned about z, then shifted), however the model orients them
- ``floor`` (optional): true: besman's floor and lights for a model that has none (a raised mount gets a
  pedestal)
- ``velocity_feedforward`` (optional): true: each position command leads by the commanded velocity x kv/kp (an
  actuator whose damping acts on the joint's velocity lags kv/kp x its speed without it)
- ``gravity_compensation`` (optional): true: the robot's bodies weightless to its actuators (MuJoCo
  ``gravcomp``), as an arm's controller does
- ``exclude`` (optional): ``[[body, body], ...]``: pairs whose contacts are ignored
- ``servos`` (optional): ``{joint: {"kp": stiffness, "kv": damping, "force": limit}}``: a position actuator
  on each joint named, in place of whatever drives it in the model (a torque motor: besman commands every
  arm joint's position); ``force`` defaults to the replaced motor's range, ``kv`` to 0
- ``arms`` (for tasks): ``{name: arm}``, the first the one that works alone (below)
- ``tabletop`` (for tasks): ``{"table": board, "shelf": board, "reach": area}``: a board is ``{"height", "x":
  [lo, hi], "y": [lo, hi]}`` in the robot's frame; ``reach`` is the area of the table where the first arm
  reaches top-down grasps (tasks draw their objects there)
- ``tasks`` (for tasks the robot is new to): numbers of tasks by task name, each checked by its task:
  pick-place's ``{"places": area}`` on the shelf; the handover's ``bar``, ``places``, ``ready``, ``present``
  and optionally ``grip`` (:mod:`besman.tasks.handover`)

An arm: ``{"groups": [...], "tcp": ..., "gripper": ...}``.

- ``tcp``, the tool-centre point: ``{"site": name}``, or ``{"site": new name, "body": name, "position": [x,
  y, z], "quaternion": [w, x, y, z]}`` that adds a site there. Its z axis points out of the hand (down at a
  top-down grasp) and its y axis runs from finger to finger; it sits between the pads, where the fingers
  close: the planner grasps 1 cm above an object's centre, so the fingertips may reach at most 4 cm past
  the tool frame (less for a short object: not into the table).
- ``gripper``: ``group`` (the fingers' joints), ``actuator`` (optional: one name or a list; without it, the
  actuators that drive the fingers' joints, named or not, in joint order), ``opening`` and ``command``:
  matching monotone lists, the opening in m per finger (half the aperture between the pads) and the
  actuator's command there, or for several actuators one list of commands per actuator (measure them:
  ``besman robots gripper FOLDER``); ``open``: the opening that grasps and releases; ``pads``: two lists
  (one per side) of geom names, or body names whose colliding geoms are pads (fingers with unnamed
  geoms); ``limits``: the opening's velocity, acceleration and jerk (per finger); ``still_speed``
  (optional, default 1e-3): the fingers' joint speed under which closed fingers count as settled.
- With several arms working at once, groups that two arms share (a waist) are held.

An earlier description's ``tabletop.objects`` is read as ``tabletop.reach``, its ``tabletop.places`` as
``tasks.pick-place.places`` and its ``tabletop.handover`` as ``tasks.handover``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from besman.core.storage import check_schema_version, optional_field, read_json
from besman.robots.fields import (
    DescriptionError,
    finite_number,
    finite_numbers,
    json_object,
    name_list,
    require,
)
from besman.robots.tabletop import TabletopLayout, read_tabletop, task_sections

SCHEMA_VERSION = 2
# Simulation options a description may set (an attached gripper may need them; the parent's are kept).
OPTIONS = ("impratio", "cone", "timestep", "noslip_iterations", "integrator")


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
    """A model attached at a site of the robot's model, or at a body's origin (``site`` None), its names
    prefixed."""

    model: ModelSource
    site: str | None
    prefix: str
    body: str | None = None


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
class Mount:
    """Where the robot's root bodies are moved: ``position`` (m) and a turn ``yaw`` (rad) about z."""

    position: tuple[float, float, float]
    yaw: float


@dataclass(frozen=True)
class Servo:
    """A position actuator the description puts on a joint in place of the model's own (a torque motor):
    stiffness ``kp`` and damping ``kv`` (per rad or m), and its largest force ``force`` (None: the force
    range of the motor it replaces, if that had one)."""

    kp: float
    kv: float = 0.0
    force: float | None = None


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
    servos: dict[str, Servo] = field(default_factory=dict)

    @property
    def file(self) -> Path:
        """The description file."""
        return self.folder / "description.json"


def _limits(spec: Any, where: str) -> JointLimitSpec:
    spec = json_object(spec, where)
    values = {}
    for key in ("velocity", "acceleration", "jerk"):
        value = float(require(spec, key, (int, float), where))  # finite: require refuses others
        if value <= 0:
            raise DescriptionError(f"{where}.{key}: must be a finite positive number, got {value!r}")
        values[key] = value
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
    value = json_object(value, where)
    site = require(value, "site", str, where)
    body = optional_field(value, "body", str, where, DescriptionError)
    if body is None:
        if set(value) - {"site"}:
            raise DescriptionError(f"{where}: a position or quaternion needs the body the new site is on")
        return ToolCentrePoint(site)
    quaternion = finite_numbers(value.get("quaternion", [1, 0, 0, 0]), f"{where}.quaternion", 4)
    if not math.isclose(math.hypot(*quaternion), 1.0, abs_tol=1e-6):
        raise DescriptionError(f"{where}.quaternion: must have unit length, got {list(quaternion)}")
    return ToolCentrePoint(
        site, body, finite_numbers(value.get("position", [0, 0, 0]), f"{where}.position", 3), quaternion
    )


def _gripper(value: Any, where: str) -> GripperSpec:
    value = json_object(value, where)
    opening = finite_numbers(require(value, "opening", list, where), f"{where}.opening")
    actuators = value.get("actuator", [])
    actuators = name_list([actuators] if isinstance(actuators, str) else actuators, f"{where}.actuator")
    command = require(value, "command", list, where)
    # One actuator's commands, or a list per actuator (a gripper with an actuator for each finger).
    tables = command if command and all(isinstance(row, list) for row in command) else [command]
    command = tuple(finite_numbers(row, f"{where}.command[{i}]") for i, row in enumerate(tables))
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
    grasp_open = require(value, "open", (int, float), where)
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
    sides = tuple(name_list(side, f"{where}.pads[{i}]") for i, side in enumerate(pads))
    if not all(sides):
        raise DescriptionError(f"{where}.pads: each side needs at least one geom")
    still_speed = finite_number(value.get("still_speed", GripperSpec.still_speed), f"{where}.still_speed")
    if not still_speed > 0:
        raise DescriptionError(f"{where}.still_speed: must be a number above 0, got {still_speed!r}")
    return GripperSpec(
        group=require(value, "group", str, where),
        actuators=actuators,
        opening=opening,
        command=command,
        open=float(grasp_open),
        pads=(sides[0], sides[1]),
        limits=_limits(require(value, "limits", dict, where), f"{where}.limits"),
        still_speed=still_speed,
    )


def _arm(name: str, value: Any, groups: dict[str, GroupSpec], where: str) -> ArmSpec:
    value = json_object(value, where)
    members = name_list(require(value, "groups", list, where), f"{where}.groups")
    for group in members:
        if group not in groups:
            raise DescriptionError(f"{where}.groups: no group {group!r}; groups: {', '.join(groups)}")
    gripper = value.get("gripper")
    gripper = None if gripper is None else _gripper(gripper, f"{where}.gripper")
    if gripper is not None and gripper.group not in groups:
        raise DescriptionError(
            f"{where}.gripper.group: no group {gripper.group!r}; groups: {', '.join(groups)}"
        )
    return ArmSpec(name, members, _tcp(require(value, "tcp", dict, where), f"{where}.tcp"), gripper)


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
    "servos",
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
    for group_name, group in require(raw, "groups", dict, where).items():
        group_where = f"{where}.groups.{group_name}"
        group = json_object(group, group_where)
        groups[group_name] = GroupSpec(
            name=group_name,
            joints=name_list(group.get("joints", []), f"{group_where}.joints"),
            site=optional_field(group, "site", str, group_where, DescriptionError),
            equalities=name_list(group.get("equalities", []), f"{group_where}.equalities"),
        )
    limits = {
        joint: _limits(spec, f"{where}.limits.{joint}")
        for joint, spec in require(raw, "limits", dict, where).items()
    }
    if raw["schema_version"] == 1:
        return RobotDescription(
            name=require(raw, "name", str, where),
            title=optional_field(raw, "title", str, where, DescriptionError) or "",
            folder=path.parent,
            model=ModelSource(require(raw, "model", str, where)),
            keyframe=require(raw, "keyframe", str, where),
            groups=groups,
            limits=limits,
        )

    attach = []
    for index, item in enumerate(raw.get("attach", [])):
        item_where = f"{where}.attach[{index}]"
        item = json_object(item, item_where)
        if ("site" in item) == ("body" in item):
            raise DescriptionError(f"{item_where}: give where the part goes, a site or a body (its origin)")
        attach.append(
            Attachment(
                _model_source(item.get("model"), f"{item_where}.model"),
                optional_field(item, "site", str, item_where, DescriptionError),
                require(item, "prefix", str, item_where),
                optional_field(item, "body", str, item_where, DescriptionError),
            )
        )
    mount = raw.get("mount")
    if mount is not None:
        mount = json_object(mount, f"{where}.mount")
        mount = Mount(
            finite_numbers(mount.get("position", [0, 0, 0]), f"{where}.mount.position", 3),
            math.radians(finite_numbers([mount.get("yaw_degrees", 0)], f"{where}.mount.yaw_degrees")[0]),
        )
    options = json_object(raw.get("options", {}), f"{where}.options")
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
        names = name_list(pair, f"{where}.exclude[{index}]")
        if len(names) != 2:
            raise DescriptionError(f"{where}.exclude[{index}]: expected two body names, got {pair!r}")
        pairs.append((names[0], names[1]))
    arms = {
        name: _arm(name, value, groups, f"{where}.arms.{name}")
        for name, value in json_object(raw.get("arms", {}), f"{where}.arms").items()
    }
    tabletop = raw.get("tabletop")
    switches = {key: raw.get(key, False) for key in ("floor", "velocity_feedforward", "gravity_compensation")}
    for key, value in switches.items():
        if not isinstance(value, bool):
            raise DescriptionError(f"{where}.{key}: expected true or false, got {value!r}")
    home = json_object(raw.get("home", {}), f"{where}.home")
    for joint, position in home.items():
        finite_numbers([position], f"{where}.home.{joint}")
    return RobotDescription(
        name=require(raw, "name", str, where),
        title=optional_field(raw, "title", str, where, DescriptionError) or "",
        folder=path.parent,
        model=_model_source(raw.get("model"), f"{where}.model"),
        keyframe=require(raw, "keyframe", str, where),
        groups=groups,
        limits=limits,
        attach=tuple(attach),
        floor=switches["floor"],
        mount=mount,
        options=options,
        exclude=tuple(pairs),
        arms=arms,
        tabletop=None if tabletop is None else read_tabletop(tabletop, f"{where}.tabletop"),
        tasks=task_sections(raw, where),
        velocity_feedforward=switches["velocity_feedforward"],
        gravity_compensation=switches["gravity_compensation"],
        home={joint: float(position) for joint, position in home.items()},
        servos={
            joint: _servo(value, f"{where}.servos.{joint}")
            for joint, value in json_object(raw.get("servos", {}), f"{where}.servos").items()
        },
    )


def _servo(value: Any, where: str) -> Servo:
    value = json_object(value, where)
    unknown = sorted(set(value) - {"kp", "kv", "force"})
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field of a servo (kp, kv, force)")
    if "kp" not in value:
        raise DescriptionError(f"{where}: needs kp, the servo's stiffness (force per rad or m)")
    numbers = {key: finite_numbers([given], f"{where}.{key}")[0] for key, given in value.items()}
    for key, number in numbers.items():
        if number < 0 or (number == 0 and key != "kv"):  # no damping is a choice; no stiffness is not
            raise DescriptionError(f"{where}.{key}: must be positive, got {value[key]!r}")
    return Servo(**numbers)
