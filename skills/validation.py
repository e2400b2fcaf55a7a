"""Input checks shared by the skills package: errors that name the argument and the problem."""

from __future__ import annotations

import numpy as np

from besman.skills.errors import InputError


def finite_array(name: str, value, *, ndim: int | None = None, shape: tuple | None = None) -> np.ndarray:
    """``value`` as a float array, checked for shape and for NaN or inf (a ``ValueError`` names ``name``)."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numeric, got {type(value).__name__}") from None
    if ndim is not None and array.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), got shape {array.shape}")
    if shape is not None and (
        len(shape) != array.ndim
        or any(want not in (None, got) for want, got in zip(shape, array.shape, strict=True))
    ):
        expected = "(" + ", ".join("any" if want is None else str(want) for want in shape) + ")"
        raise InputError(f"{name} must have shape {expected}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        bad = np.argwhere(~np.isfinite(array))[0]
        raise InputError(f"{name} contains NaN or inf (first at index {tuple(int(i) for i in bad)})")
    return array


def increasing_times(name: str, value, *, minimum_length: int = 2) -> np.ndarray:
    """A 1-D array of strictly increasing, finite times."""
    times = finite_array(name, value, ndim=1)
    if len(times) < minimum_length:
        raise InputError(f"{name} needs at least {minimum_length} samples, got {len(times)}")
    steps = np.diff(times)
    if np.any(steps <= 0):
        first = int(np.argmax(steps <= 0))
        raise InputError(
            f"{name} must be strictly increasing: {name}[{first + 1}] = {times[first + 1]!r} "
            f"follows {name}[{first}] = {times[first]!r}"
        )
    return times


def positive(name: str, value) -> float:
    """A finite number > 0."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"{name} must be a finite positive number, got {value!r}")
    return number


def broadcast_vector(name: str, value, size: int, default: float = 0.0) -> np.ndarray:
    """A finite vector of length ``size`` from None (``default``), a number, or ``size`` numbers."""
    if value is None:
        return np.full(size, float(default))
    array = finite_array(name, value)
    if array.ndim == 0:
        return np.full(size, float(array))
    if array.shape != (size,):
        raise InputError(f"{name} must have shape ({size},), got {array.shape}")
    return array.copy()
