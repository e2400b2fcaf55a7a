"""A package's names imported on first use: ``__getattr__, __dir__, __all__ = lazy_names(__name__, modules)``
in its ``__init__``, ``modules`` mapping each module within the package (or, dotted, any module) to the
names it gives the package.
Importing one light module of the package (or printing the command line's help) then does not import the
heavy ones (scipy, MuJoCo)."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping

from besman.core.moved import MOVED_NAMES, old_names


def lazy_names(package: str, modules: Mapping[str, tuple[str, ...]]) -> tuple[Callable, Callable, list[str]]:
    """The ``__getattr__``, ``__dir__`` and ``__all__`` of ``package`` whose names live in ``modules``
    (module name, relative to the package unless dotted -> its names); a name is imported when first used,
    then kept."""
    homes = {name: module for module, names in modules.items() for name in names}
    moved = old_names(package) if package in MOVED_NAMES else None  # names that left it, for one release

    def __getattr__(name: str):
        if name not in homes:
            if moved is not None:
                return moved(name)
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        home = homes[name]
        value = getattr(importlib.import_module(home if "." in home else f"{package}.{home}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return __getattr__, __dir__, sorted(homes)
