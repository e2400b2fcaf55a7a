"""Plugins: modules that other installed distributions name under one of besman's entry-point groups
(``besman.tasks``, ``besman.node_types``). Each is loaded on its own: one that does not import, or that
declares what besman cannot take, is named in one :class:`~besman.core.errors.PluginWarning` line (its
entry point, its distribution and why) and left out, so that one broken installed package never takes a
command down with it.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from importlib.metadata import EntryPoint, entry_points
from types import ModuleType

from besman.core.errors import PluginWarning


def plugin_modules(group: str, kind: str) -> Iterator[tuple[str, ModuleType]]:
    """(who, module) of each module named under the entry-point ``group``; ``who`` names it in messages
    ("the ``kind`` plugin 'tidy' of the distribution besman-tidy 0.1.0"). One that does not import is
    warned of and left out."""
    for point in entry_points(group=group):
        who = f"the {kind} plugin {point.name!r} of {_distribution(point)}"
        try:
            module = point.load()
        except Exception as error:  # whatever its import raises (a missing dependency, a syntax error...)
            warn_plugin(f"{who} is left out: loading {point.value} raised {type(error).__name__}: {error}")
            continue
        yield who, module


def _distribution(point: EntryPoint) -> str:
    dist = point.dist
    return "an unknown distribution" if dist is None else f"the distribution {dist.name} {dist.version}"


def warn_plugin(message: str) -> None:
    """Warns of a plugin left out, in one line (the first of a multi-line exception message says what
    went wrong)."""
    warnings.warn(message.splitlines()[0], PluginWarning, stacklevel=2)
