"""Argument checks, shared by every besman package: errors that name the argument, the value received and
what was expected.

:func:`checked` checks the arguments of a public function, method or class where it is called, before any
work: a keyword it does not take is refused with the nearest one it does, and each argument given is passed
through its check, ``check(name, value) -> value`` (the value the function then gets). Checks:
:func:`shaped` (a finite array of a shape), :func:`numeric` (any numbers), :func:`number`, :func:`positive`,
:func:`non_negative`, :func:`integer` (:data:`SEED`, :data:`COUNT`), :func:`instance`, :func:`text`,
:data:`PATH`, :func:`optional`, :func:`items` (a list of checked items), :func:`mapping` (of known keys)
and :func:`as_given` (checks without converting). A wrong type raises
:class:`~besman.core.errors.ArgumentTypeError` (also a ``TypeError``), a wrong value
:class:`~besman.core.errors.InputError` (also a ``ValueError``), an unknown key
:class:`~besman.core.errors.UnknownNameError` (also a ``KeyError``).
"""

from __future__ import annotations

import functools
import inspect
import os
import sys
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from besman.core.errors import ArgumentTypeError, InputError, UnknownNameError

Check = Callable[[str, Any], Any]


def numeric(name: str, value) -> np.ndarray:
    """``value`` as a float array (of any shape, NaN allowed); a ``TypeError`` if it is not numbers."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{name} must be numeric, got {shown(value)}") from None


def finite_array(name: str, value, *, ndim: int | None = None, shape: tuple | None = None) -> np.ndarray:
    """``value`` as a float array, checked for shape and for NaN or inf (a ``ValueError`` names ``name``)."""
    array = numeric(name, value)
    if ndim is not None and array.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), got shape {array.shape}")
    if shape is not None and (
        len(shape) != array.ndim
        or any(want not in (None, got) for want, got in zip(shape, array.shape, strict=True))
    ):
        expected = "(" + ", ".join("any" if want is None else str(want) for want in shape)
        expected += ",)" if len(shape) == 1 else ")"
        raise InputError(f"{name} must have shape {expected}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        raise InputError(f"{name} contains NaN or inf (first at index {bad}: {array[bad]})")
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


def _real(name: str, value) -> float:
    """``value`` as a float; a ``TypeError`` if it is not a number (a string is not one)."""
    try:
        if isinstance(value, str | bytes):
            raise TypeError
        return float(value)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{name} must be a number, got {shown(value)}") from None


def number(name: str, value) -> float:
    """A finite number."""
    result = _real(name, value)
    if not np.isfinite(result):
        raise InputError(f"{name} must be a finite number, got {value!r}")
    return result


def positive(name: str, value) -> float:
    """A finite number > 0."""
    result = _real(name, value)
    if not (np.isfinite(result) and result > 0):
        raise InputError(f"{name} must be a finite positive number, got {value!r}")
    return result


def non_negative(name: str, value) -> float:
    """A finite number >= 0."""
    result = _real(name, value)
    if not (np.isfinite(result) and result >= 0):
        raise InputError(f"{name} must be a finite number >= 0, got {value!r}")
    return result


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


def shown(value) -> str:
    """``value`` as a message shows it: its repr (cut at 60 characters) and its type, ``123 (int)``."""
    text = repr(value)
    return f"{text if len(text) <= 60 else text[:57] + '...'} ({type(value).__name__})"


def shaped(*, ndim: int | None = None, shape: tuple | None = None) -> Check:
    """A finite float array of ``ndim`` dimensions or of ``shape`` (see :func:`finite_array`)."""
    return lambda name, value: finite_array(name, value, ndim=ndim, shape=shape)


def instance(kind: type | tuple[type, ...], what: str) -> Check:
    """A value of ``kind``; ``what`` says which in words ("a Robot")."""

    def check(name: str, value):
        if not isinstance(value, kind):
            raise ArgumentTypeError(f"{name} must be {what}, got {shown(value)}")
        return value

    return check


def text(what: str) -> Check:
    """A string; ``what`` says what it names ("a robot name")."""
    return instance(str, f"{what} (str)")


PATH = instance((str, os.PathLike), "a path (str or os.PathLike)")
CALLABLE = instance(Callable, "callable")


def integer(low: int | None = None, high: int | None = None) -> Check:
    """An integer (Python's or numpy's; not a bool, not a float) in ``low..high``, returned as an int."""
    expected = "an integer" + (
        f" in {low}..{high}" if high is not None else f" >= {low}" if low is not None else ""
    )

    def check(name: str, value) -> int:
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ArgumentTypeError(f"{name} must be {expected}, got {shown(value)}")
        if (low is not None and value < low) or (high is not None and value > high):
            raise InputError(f"{name} must be {expected}, got {value}")
        return int(value)

    return check


SEED = integer(0, 2**32 - 1)  # what numpy's generators and CMA-ES accept
COUNT = integer(1)


def optional(check: Check) -> Check:
    """None, or a value that ``check`` accepts."""
    return lambda name, value: None if value is None else check(name, value)


def as_given(check: Check) -> Check:
    """``check``, passing the value on as given (a list of numbers stays a list, not an array)."""

    def check_only(name: str, value):
        check(name, value)
        return value

    return check_only


def items(check: Check, what: str = "a list") -> Check:
    """A list or tuple whose every item ``check`` accepts (each named by its index)."""

    def check_all(name: str, value) -> list:
        if not isinstance(value, list | tuple):
            raise ArgumentTypeError(f"{name} must be {what}, got {shown(value)}")
        return type(value)(check(f"{name}[{i}]", item) for i, item in enumerate(value))

    return check_all


def mapping(**checks: Check) -> Check:
    """A mapping with only the keys of ``checks``, each value checked by its own, returned as a new dict
    (None: an empty one). An unknown key is refused with the nearest known one: a typo is never ignored."""

    def check(name: str, value) -> dict:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise ArgumentTypeError(f"{name} must be a mapping of options, got {shown(value)}")
        for key in value:
            if key not in checks:
                raise UnknownNameError(f"{name}: unknown option {key!r}{nearest(key, checks)}")
        return {key: checks[key](f"{name}[{key!r}]", item) for key, item in value.items()}

    return check


def nearest(name, known) -> str:
    """The end of a message about an unknown ``name``: the nearest known name, or all of them."""
    import difflib  # only once a name is wrong

    close = difflib.get_close_matches(str(name), [str(each) for each in known], n=1)
    return f" (did you mean {close[0]!r}?)" if close else f"; known: {', '.join(map(str, known)) or 'none'}"


def checked(**checks: Check):
    """Decorates a public function, method or class (its constructor) so that its arguments are checked
    where it is called, before any work: an unknown keyword or a missing argument raises an
    :class:`~besman.core.errors.ArgumentTypeError`, and each argument given that ``checks`` names goes
    through its check (defaults are trusted). Messages start with the public name (``robots.load: ...``)."""

    def decorate(target):
        function = target.__init__ if isinstance(target, type) else target
        signature = inspect.signature(function)
        parameters = signature.parameters.values()
        keywords = [
            p.name
            for p in parameters
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name not in ("self", "cls")
        ]
        takes_any = any(p.kind is p.VAR_KEYWORD for p in parameters)

        @functools.wraps(function)
        def call(*args, **kwargs):
            if not takes_any:
                for key in kwargs:
                    if key not in keywords:
                        raise ArgumentTypeError(
                            f"{_public_name(target)}: unknown keyword {key!r}{nearest(key, keywords)}"
                        )
            try:
                bound = signature.bind(*args, **kwargs)
            except TypeError as error:  # a missing argument, or too many
                raise ArgumentTypeError(f"{_public_name(target)}: {error}") from None
            try:
                for name, check in checks.items():
                    if name in bound.arguments:
                        bound.arguments[name] = check(name, bound.arguments[name])
            except InputError as error:  # named here, where it costs nothing unless an argument is wrong
                raise type(error)(f"{_public_name(target)}: {error}") from None
            return function(*bound.args, **bound.kwargs)

        if isinstance(target, type):
            target.__init__ = call
            return target
        return call

    return decorate


def _public_name(target) -> str:
    """The name a user calls ``target`` by: ``robots.load`` if its subpackage exports it, else with its
    module (``tasks.running.run_demo``); looked up when called, once the package is imported."""
    package, _, module = target.__module__.removeprefix("besman.").partition(".")
    qualname = target.__qualname__.removesuffix(".__init__")
    exported = qualname.split(".")[0] in getattr(sys.modules.get(f"besman.{package}"), "__all__", ())
    return f"{package}.{qualname}" if exported or not module else f"{package}.{module}.{qualname}"
