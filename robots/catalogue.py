"""Which robots there are and what each is: the shipped ones by name, a folder of one's own by path, and
their descriptions (read and checked; :mod:`besman.robots.description`). Light on purpose: listing and
showing tasks reads descriptions without MuJoCo (:mod:`besman.robots.robot` compiles the models)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from besman.robots.description import RobotDescription, read_description
from besman.skills.errors import InputError, UnknownNameError
from besman.skills.validation import CALLABLE, checked, instance, optional

# The check of an argument that names a robot: a shipped robot's name or a robot folder.
ROBOT = instance((str, os.PathLike), "a robot name or folder (str or os.PathLike)")

ROBOTS_DIR = Path(__file__).resolve().parent
DESCRIPTION_FILE = "description.json"


def available() -> list[str]:
    """Names of the robots shipped with besman (folders with a ``description.json``)."""
    return sorted(path.parent.name for path in ROBOTS_DIR.glob(f"*/{DESCRIPTION_FILE}"))


@checked(name=ROBOT)
def describe(name: str) -> RobotDescription:
    """The description of a shipped robot (by name) or of a robot folder (a path), read and checked."""
    folder = Path(name)
    if not (folder / DESCRIPTION_FILE).exists():  # a special file there is refused by name when read
        if name not in available():
            raise UnknownNameError(f"unknown robot {name!r}; available: {', '.join(available())}")
        folder = ROBOTS_DIR / name
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
