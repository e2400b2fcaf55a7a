"""Reading a description's JSON fields, one at a time: each reader checks a field's type and values and
raises :class:`DescriptionError` naming the file and the field (``where``)."""

from __future__ import annotations

import math
from typing import Any

from besman.core.errors import BesmanError
from besman.core.storage import require_field


class DescriptionError(BesmanError):
    """A robot description file is malformed; the message names the file and the field."""


def require(mapping: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    """``mapping[key]`` of type ``kind``; a number must be finite (:func:`finite_number`)."""
    value = require_field(mapping, key, kind, where, DescriptionError)
    if isinstance(value, int | float) and not isinstance(value, bool):
        finite_number(value, f"{where}.{key}")
    return value


def finite_number(value: Any, where: str) -> float:
    """``value`` as a float: a number (not a bool) that is finite and that a float holds (JSON reads
    ``1e400`` as infinity, and ``1`` followed by 400 zeros as an int no float holds)."""
    number = _float(value)
    if number is None or not math.isfinite(number):
        raise DescriptionError(f"{where}: expected a finite number, got {_shown(value)}")
    return number


def _float(value: Any) -> float | None:
    """A number as a float (infinite where it overflows one), anything else None."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return None
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _shown(value: Any) -> str:
    """``value`` for a message: a number too long to read, by its digits."""
    if isinstance(value, int) and abs(value) >= 10**20:
        return f"a {len(str(abs(value)))}-digit number"
    return repr(value)


def name_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise DescriptionError(f"{where}: expected a list of names, got {value!r}")
    if len(set(value)) != len(value):
        raise DescriptionError(f"{where}: names repeat in {value!r}")
    return tuple(value)


def finite_numbers(value: Any, where: str, count: int | None = None) -> tuple[float, ...]:
    numbers = [_float(v) for v in value] if isinstance(value, list) else [None]
    if not all(n is not None and math.isfinite(n) for n in numbers) or (
        count is not None and len(numbers) != count
    ):
        size = f"{count} " if count is not None else ""
        shown = f"[{', '.join(map(_shown, value))}]" if isinstance(value, list) else repr(value)
        raise DescriptionError(f"{where}: expected a list of {size}finite numbers, got {shown}")
    return tuple(numbers)


def number_range(value: Any, where: str) -> tuple[float, float]:
    low, high = finite_numbers(value, where, 2)
    if not low < high:
        raise DescriptionError(f"{where}: expected [low, high] with low < high, got {value!r}")
    return low, high


def json_object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise DescriptionError(f"{where}: expected an object, got {value!r}")
    return value
