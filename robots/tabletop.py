"""A robot's tabletop: its table and shelf boards and the area its first arm reaches, and the readers of
the areas and hand poses that tasks keep per robot (a description's ``tabletop`` and ``tasks`` sections)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from besman.robots.fields import DescriptionError, finite_numbers, json_object, number_range, require


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


def read_board(value: Any, where: str) -> Board:
    value = json_object(value, where)
    height = require(value, "height", (int, float), where)
    return Board(
        float(height), number_range(value.get("x"), f"{where}.x"), number_range(value.get("y"), f"{where}.y")
    )


def read_area(value: Any, where: str, board: Board | None = None) -> Area:
    """An area ``{"x": [x0, x1], "y": [y0, y1]}`` (m); with a ``board``, it must lie on it."""
    value = json_object(value, where)
    area = number_range(value.get("x"), f"{where}.x"), number_range(value.get("y"), f"{where}.y")
    if board is not None and not _inside(area, board):
        raise DescriptionError(
            f"{where}: the area x {list(area[0])}, y {list(area[1])} must lie on the board at "
            f"{board.height} m (x {list(board.x)}, y {list(board.y)})"
        )
    return area


def read_hand_pose(value: Any, where: str) -> HandPose:
    """A hand pose ``{"position": [x, y, z], "yaw": rad}`` (yaw optional)."""
    value = json_object(value, where)
    unknown = sorted(set(value) - {"position", "yaw"})
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field of a hand pose (position, yaw)")
    yaw = value.get("yaw")
    return HandPose(
        finite_numbers(value.get("position"), f"{where}.position", 3),
        None if yaw is None else finite_numbers([yaw], f"{where}.yaw")[0],
    )


def section(value: Any, where: str, fields: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    """A mapping with exactly the given ``fields``, each a mapping, and maybe ``optional`` ones (a task's
    section of a description; the task reads those)."""
    value = json_object(value, where)
    unknown = sorted(set(value) - set(fields) - set(optional))
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field here ({', '.join(fields + optional)})")
    for name in fields:
        require(value, name, dict, where)
    return value


def _inside(area: Area, board: Board) -> bool:
    (x0, x1), (y0, y1) = area
    return board.x[0] <= x0 and x1 <= board.x[1] and board.y[0] <= y0 and y1 <= board.y[1]


# An earlier description's task areas inside "tabletop", and the task section each is read into.
EARLIER_TASK_FIELDS = {"places": "pick-place", "handover": "handover"}


def read_tabletop(value: Any, where: str) -> TabletopLayout:
    value = json_object(value, where)
    unknown = sorted(set(value) - {"table", "shelf", "reach", "objects", *EARLIER_TASK_FIELDS})
    if unknown:
        raise DescriptionError(f"{where}.{unknown[0]}: not a field of the tabletop (table, shelf, reach)")
    table = read_board(require(value, "table", dict, where), f"{where}.table")
    reach = (
        "reach" if "reach" in value or "objects" not in value else "objects"
    )  # "objects": the earlier name
    return TabletopLayout(
        table=table,
        shelf=read_board(require(value, "shelf", dict, where), f"{where}.shelf"),
        reach=read_area(require(value, reach, dict, where), f"{where}.{reach}", table),
    )


def task_sections(raw: dict, where: str) -> dict[str, dict]:
    """The description's task sections, the earlier form's areas in ``tabletop`` among them."""
    given = json_object(raw.get("tasks", {}), f"{where}.tasks")
    tasks = {name: json_object(value, f"{where}.tasks.{name}") for name, value in given.items()}
    earlier = raw.get("tabletop") or {}
    for name, task in EARLIER_TASK_FIELDS.items():
        if name in earlier:
            if task == name:
                tasks.setdefault(task, earlier[name])
            else:
                tasks.setdefault(task, {}).setdefault(name, earlier[name])
    return tasks
