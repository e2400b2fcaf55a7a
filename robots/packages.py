"""Model files that installed Python distributions ship: found through the distribution's own record of its
files (``importlib.metadata``), never downloaded.

A description names such a file by the distribution and the file's path's tail, ``{"package":
"openarm-mujoco", "file": "v2/openarm_bimanual.xml"}``. The record lists every installed file, including data
files that an installer puts outside ``site-packages`` (``openarm-mujoco`` installs its models under
``<prefix>/share/openarm_mujoco/v2``), so one rule finds a model wherever the package keeps it; the tail must
name exactly one file.
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path, PurePosixPath

from besman.robots.description import DescriptionError


def find(distribution: str, relative: str, where: str) -> Path:
    """The installed file of ``distribution`` whose path ends with ``relative``; errors name ``where`` (the
    field that asked for it) and say how to install the package or which models it has."""
    tail = PurePosixPath(relative).parts
    if not tail or PurePosixPath(relative).is_absolute() or ".." in tail:
        raise DescriptionError(f"{where}.file: {relative!r} must be a relative path (folder/file.xml)")
    try:
        installed = importlib.metadata.distribution(distribution)
    except importlib.metadata.PackageNotFoundError:
        raise DescriptionError(
            f"{where}.package: {distribution!r} is not installed (pip install {distribution})"
        ) from None
    files = installed.files or []
    matches = [file for file in files if PurePosixPath(file).parts[-len(tail) :] == tail]
    if len(matches) != 1:
        models = sorted(str(PurePosixPath(*PurePosixPath(f).parts[-2:])) for f in files if f.suffix == ".xml")
        problem = "has no file" if not matches else f"has {len(matches)} files"
        raise DescriptionError(
            f"{where}.file: {distribution} {problem} ending in {relative!r}; its models: "
            f"{', '.join(models[:12]) or 'none'}{' ...' if len(models) > 12 else ''}"
        )
    return Path(installed.locate_file(matches[0])).resolve()
