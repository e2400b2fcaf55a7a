"""The files a MuJoCo model reads, checked before MuJoCo reads them.

MuJoCo opens a model's file, the files it includes and its meshes, textures and height fields by path, with
no check of its own: a FIFO among them would block the load forever and ``/dev/zero`` would fill the memory.
:func:`check_model_files` therefore walks the model first - its XML read here within a bound, includes and
nested models followed - and checks every file it names (:mod:`besman.core.reading`): a regular file of at
most :data:`MAX_XML_BYTES` for XML and :data:`MAX_ASSET_BYTES` for a mesh, texture or height field. MuJoCo
looks for a named file beside the main model or beside the including file, under the compiler's
``meshdir``, ``texturedir`` or ``assetdir``; every such place where a file exists is checked.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import mujoco

from besman.core.errors import InputError
from besman.core.reading import open_file, read_bytes
from besman.robots.fields import DescriptionError

MAX_XML_BYTES = 16_000_000  # a model's XML (the shipped robots' are at most 40 kB)
MAX_ASSET_BYTES = 256_000_000  # a mesh, texture or height field (the largest shipped mesh is 8 MB)
DIRECTORIES = ("meshdir", "texturedir", "assetdir")  # the compiler's folders for named files
SEARCHED = 20_000  # folders looked through at most for a missing file's name (a package's assets are few)


def check_model_files(path: Path) -> None:
    """Refuses a model whose file, or a file it names, is not a regular file within its bound; the
    :class:`InputError` names that file. A missing model is left to MuJoCo, which says so."""
    path = Path(path)
    if path.exists():
        _walk(path, path.parent, {""}, set())


def _walk(path: Path, main: Path, directories: set[str], seen: set[Path]) -> None:
    """Checks the MJCF file ``path`` of the model in folder ``main`` and the files it names (with the
    compiler ``directories`` in force), once each."""
    if path.resolve() in seen:
        return
    seen.add(path.resolve())
    root = _parse(path)
    directories = directories | {
        element.get(name) for element in root.iter("compiler") for name in DIRECTORIES if element.get(name)
    }
    for element in root.iter():
        for name, value in element.attrib.items():
            if not name.startswith("file"):  # file, and a cube texture's fileright, fileup, ...
                continue
            places = {
                folder / directory / value for folder in (main, path.parent) for directory in directories
            }
            for candidate in filter(Path.exists, places):
                if element.tag == "include":
                    _walk(candidate, main, directories, seen)
                elif element.tag == "model":  # a model of its own: its own folder and compiler
                    _walk(candidate, candidate.parent, {""}, seen)
                else:
                    open_file(candidate, MAX_ASSET_BYTES, what="file of a robot model").close()


def _parse(path: Path) -> ElementTree.Element:
    text = read_bytes(path, MAX_XML_BYTES, what="robot model")
    try:
        return ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise InputError(f"{path}: the model does not load: not valid XML ({error})") from None


def check_assets_found(spec: mujoco.MjSpec, where: str) -> None:
    """Refuses a parsed model whose mesh, height field or texture file is not where MuJoCo will open it when
    it compiles (the model's folder, then the compiler's ``meshdir`` or ``texturedir``; a file named in an
    included file is looked for beside that file, and the including model's relative ``meshdir`` does not
    apply to it). Checked on every load, so that what loads without its meshes (``besman robots show``)
    loads with them; the error names the asset, the path tried, where a file of that name is, and
    ``where``, the description's field that names the model."""
    folder = Path(spec.modelfiledir)
    kinds = (("mesh", spec.meshes, spec.meshdir), ("hfield", spec.hfields, spec.meshdir))
    for kind, assets, directory in (*kinds, ("texture", spec.textures, spec.texturedir)):
        for asset in assets:
            if not asset.file:  # built in, or given by its vertices
                continue
            tried = folder / directory / asset.file
            if tried.is_file():
                continue
            found = _look_for(tried.name, (tried.parent, tried.parent.parent))
            option = "texturedir" if kind == "texture" else "meshdir"
            hint = (
                f"a file of that name is in {found.parent}: give the model (a file of your own that "
                f'includes the package\'s, if it is not yours) <compiler {option}="{found.parent}"/>, an '
                "absolute folder (MuJoCo looks for an included file's assets beside it, and does not apply "
                f"a relative {option} to them)"
                if found is not None
                else f"no file of that name is near it: give the model the {kind}'s file"
            )
            raise DescriptionError(
                f"{where}: {kind} {asset.name!r}: no file {tried} (the model names {asset.file!r}); {hint}"
            )


def _look_for(name: str, folders) -> Path | None:
    """The first file called ``name`` under ``folders`` (at most :data:`SEARCHED` folders looked through)."""
    budget = SEARCHED
    for top in folders:
        for root, directories, files in os.walk(top):
            if name in files:
                return Path(root) / name
            budget -= 1
            if budget <= 0:
                return None
            directories.sort()
    return None
