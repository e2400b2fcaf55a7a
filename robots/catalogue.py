"""Which robots there are and what each is: the shipped ones by name, a folder of one's own by path, those
installed distributions bring by name (a package whose folder holds a ``description.json``, named under the
entry-point group ``besman.robots``: :data:`ENTRY_POINTS`), and their descriptions (read and checked;
:mod:`besman.robots.description`). Light on purpose: listing and showing tasks reads descriptions without
MuJoCo (:mod:`besman.robots.robot` compiles the models)."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import Path

from besman.core.errors import BesmanError, InputError, UnknownNameError
from besman.core.plugins import plugin_modules, warn_plugin
from besman.core.validation import CALLABLE, checked, instance, optional
from besman.robots.description import RobotDescription, read_description

# The check of an argument that names a robot: a shipped robot's name or a robot folder.
ROBOT = instance((str, os.PathLike), "a robot name or folder (str or os.PathLike)")

ROBOTS_DIR = Path(__file__).resolve().parent
DESCRIPTION_FILE = "description.json"


ENTRY_POINTS = "besman.robots"  # the group under which other distributions name their robots' packages


def available() -> list[str]:
    """Names of the robots shipped with besman (folders with a ``description.json``) and of those installed
    packages bring (:data:`ENTRY_POINTS`)."""
    return sorted([*_shipped(), *_installed()])


def _shipped() -> list[str]:
    return [path.parent.name for path in ROBOTS_DIR.glob(f"*/{DESCRIPTION_FILE}")]


@functools.cache
def _installed() -> dict[str, Path]:
    """name -> folder of each robot an installed distribution brings: the folder of the package its entry
    point names, with the description's name. One whose folder has no readable description, or whose name
    is taken, is warned of in one line and left out."""
    found: dict[str, Path] = {}
    for who, module in plugin_modules(ENTRY_POINTS, "robot"):
        folder = Path(module.__file__).parent if getattr(module, "__file__", None) else None
        try:
            if folder is None:
                raise InputError(f"{module.__name__} is no package with a folder")
            name = read_description(folder / DESCRIPTION_FILE).name
        except BesmanError as error:
            warn_plugin(f"{who} is left out: {error}")
            continue
        if name in found or name in _shipped():
            warn_plugin(f"{who} is left out: a robot called {name!r} exists already")
            continue
        found[name] = folder
    return found


@checked(name=ROBOT)
def describe(name: str) -> RobotDescription:
    """The description of a robot by name (shipped or installed) or of a robot folder (a path), read and
    checked."""
    folder = Path(name)
    if not (folder / DESCRIPTION_FILE).exists():  # a special file there is refused by name when read
        if name in _shipped():
            folder = ROBOTS_DIR / name
        elif name in _installed():
            folder = _installed()[name]
        else:
            raise UnknownNameError(f"unknown robot {name!r}; available: {', '.join(available())}")
    return read_description(folder / DESCRIPTION_FILE)


@checked(robot=optional(ROBOT), default=ROBOT, fits=CALLABLE)
def choose(robot: str | None, default: str, fits: Callable[[RobotDescription], bool], what: str) -> str:
    """``robot`` (None: ``default``) if ``fits`` its description; otherwise an error, before any work, saying
    that ``what`` (a task, a demo) does not run on it and naming the robots it runs on (an unknown robot is
    refused with the list of all)."""
    robot = robot or default
    if not fits(describe(robot)):
        fitting = [name for name in available() if fits(describe(name))]
        raise InputError(f"{what} does not run on {robot!r}; it runs on: {', '.join(fitting)}")
    return robot
