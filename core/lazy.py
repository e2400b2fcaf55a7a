"""A package's names imported on first use: ``__getattr__, __dir__ = lazy_names(__name__, homes)`` in its
``__init__``, ``homes`` mapping each name to its module within the package (or, dotted, any module).
Importing one light module of the package (or printing the command line's help) then does not import the
heavy ones (scipy, MuJoCo)."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping

from besman.core.moved import MOVED_NAMES, old_names


def lazy_names(package: str, homes: Mapping[str, str]) -> tuple[Callable, Callable]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` whose names live in ``homes`` (name -> module name
    relative to the package); a name is imported when first used, then kept."""

    def __getattr__(name: str):
        if name not in homes:
            if package in MOVED_NAMES:  # a name that left the package, for one release
                return old_names(package)(name)
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        home = homes[name]
        value = getattr(importlib.import_module(home if "." in home else f"{package}.{home}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return __getattr__, __dir__
