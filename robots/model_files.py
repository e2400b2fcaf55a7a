"""The files a MuJoCo model reads, checked before MuJoCo reads them.

MuJoCo opens a model's file, the files it includes and its meshes, textures and height fields by path, with
no check of its own: a FIFO among them would block the load forever and ``/dev/zero`` would fill the memory.
:func:`check_model_files` therefore walks the model first - its XML read here within a bound, includes and
nested models followed - and checks every file it names (:mod:`besman.skills.reading`): a regular file of at
most :data:`MAX_XML_BYTES` for XML and :data:`MAX_ASSET_BYTES` for a mesh, texture or height field. MuJoCo
looks for a named file beside the main model or beside the including file, under the compiler's
``meshdir``, ``texturedir`` or ``assetdir``; every such place where a file exists is checked.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

from besman.skills.errors import InputError
from besman.skills.reading import open_file, read_bytes

MAX_XML_BYTES = 16_000_000  # a model's XML (the shipped robots' are at most 40 kB)
MAX_ASSET_BYTES = 256_000_000  # a mesh, texture or height field (the largest shipped mesh is 8 MB)
DIRECTORIES = ("meshdir", "texturedir", "assetdir")  # the compiler's folders for named files


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
