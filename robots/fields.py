"""Reading a description's JSON fields, one at a time: each reader checks a field's type and values and
raises :class:`DescriptionError` naming the file and the field (``where``)."""

from __future__ import annotations

import math
from typing import Any

from besman.skills.errors import BesmanError
from besman.skills.storage import require_field


class DescriptionError(BesmanError):
    """A robot description file is malformed; the message names the file and the field."""


def require(mapping: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    return require_field(mapping, key, kind, where, DescriptionError)


def name_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise DescriptionError(f"{where}: expected a list of names, got {value!r}")
    if len(set(value)) != len(value):
        raise DescriptionError(f"{where}: names repeat in {value!r}")
    return tuple(value)


def finite_numbers(value: Any, where: str, count: int | None = None) -> tuple[float, ...]:
    if (
        not isinstance(value, list)
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(v) for v in value)
        or (count is not None and len(value) != count)
    ):
        size = f"{count} " if count is not None else ""
        raise DescriptionError(f"{where}: expected a list of {size}finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def number_range(value: Any, where: str) -> tuple[float, float]:
    low, high = finite_numbers(value, where, 2)
    if not low < high:
        raise DescriptionError(f"{where}: expected [low, high] with low < high, got {value!r}")
    return low, high


def json_object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise DescriptionError(f"{where}: expected an object, got {value!r}")
    return value
