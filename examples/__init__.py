"""The examples that ship with besman (``besman.examples``): tree files, skill template pools, two human
recordings and robots brought from a package's files, installed with the package and found through
:mod:`importlib.resources`.

``besman examples --copy DIR`` puts a copy in ``DIR/examples`` (trees, pools, data, robots), where the
README's commands find them; the scripts beside them (``robot_tour.py``...) run from a checkout.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

CONTENTS = ("trees", "pools", "data", "robots")  # what a copy holds


def path(*parts: str) -> Path:
    """The installed examples folder, or a file in it (``path("trees", "sort.yaml")``)."""
    return Path(str(files(__name__))).joinpath(*parts)
