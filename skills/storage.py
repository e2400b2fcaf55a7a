"""Safe persistence: whole files or nothing, JSON and NPZ only (never pickle), checksummed pairs.

Writers go to a temporary file in the target folder and rename it into place, so a crash leaves either the
old file or the new one, never half of one. Readers load NPZ with ``allow_pickle=False``, and check JSON
documents field by field (:func:`check_schema_version`, :func:`require_field`, :func:`optional_field`) with
messages that name the file and the field; every error is a :class:`~besman.skills.errors.BesmanError`.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from besman.skills.errors import BesmanError, InputError

# The process's umask, read once (reading it means setting it): temporary files are made private (0600),
# and the renamed file gets the permissions an ordinary new file would have.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


def write_atomically(path: str | Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` via a temporary file and a rename (permissions as for a new file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(descriptor, "wb") as file:
            file.write(data)
            file.flush()
            os.fsync(file.fileno())
        os.chmod(temporary, 0o666 & ~_UMASK)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def is_temporary(path: Path) -> bool:
    """Whether ``path`` is a temporary of :func:`write_atomically` (``.NAME.XXXX.tmp``): the only file a
    writer that dies mid-write leaves behind."""
    return path.name.startswith(".") and path.name.endswith(".tmp")


def remove_temporaries(folder: Path) -> None:
    """Removes the temporaries that dead writers left under ``folder``; for the folder's one writer
    (:class:`~besman.skills.writer_lock.WriterLock`), whose own temporaries are not there yet."""
    if folder.is_dir():
        for path in folder.rglob(".*.tmp"):
            path.unlink(missing_ok=True)


def check_output(
    path: str | Path, *, option: str, suffixes: tuple[str, ...] = (), inputs: tuple[str | Path, ...] = ()
) -> Path:
    """``path`` as a Path once it is known to be writable as an output named ``option`` (e.g. "--plot"):
    with one of ``suffixes`` (if given), not a directory, in a writable folder (or one that can be made),
    and none of the command's ``inputs`` (an output never replaces what the command reads). Checked before
    any work, so that a long computation is not lost at the end."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: a directory; give a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{option} {path}: the file must end in {' or '.join(suffixes)}")
    for source in inputs:
        if Path(source).exists() and path.exists() and os.path.samefile(source, path):
            raise InputError(f"{option} {path}: that is an input of this command; it would be overwritten")
    folder = path.absolute().parent  # missing folders are made when the file is written
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: {str(folder)!r} is a file, not a folder")
    if not os.access(folder, os.W_OK):
        raise InputError(f"{option} {path}: the folder {str(folder)!r} is not writable")
    return path


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_json(path: Path, error: type[BesmanError] = InputError, top: type[dict] | type[list] = dict) -> Any:
    """The JSON object (or, with ``top=list``, list) in ``path``; ``error`` names the file if it is missing or
    malformed."""
    try:
        value = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as problem:
        raise error(f"{path}: not valid JSON ({problem})") from None
    if not isinstance(value, top):
        raise error(f"{path}: expected a JSON {'object' if top is dict else 'list'} at the top level")
    return value


def check_schema_version(
    document: dict[str, Any],
    expected: int | tuple[int, ...],
    where: str,
    error: type[BesmanError] = InputError,
) -> None:
    """Refuses a document whose ``schema_version`` is not ``expected`` (or one of them; the message names
    ``where``)."""
    version = document.get("schema_version")
    versions = expected if isinstance(expected, tuple) else (expected,)
    if version not in versions or isinstance(version, bool):
        wanted = versions[0] if len(versions) == 1 else f"one of {versions}"
        raise error(f"{where}: schema_version {version!r} is not supported (expected {wanted})")


def require_field(
    mapping: dict[str, Any],
    key: str,
    kind: type | tuple[type, ...],
    where: str,
    error: type[BesmanError] = InputError,
) -> Any:
    """``mapping[key]`` checked to be a ``kind`` (never a bool for a number); the message names the field."""
    if key not in mapping:
        raise error(f"{where}: missing field {key!r}")
    value = mapping[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        expected = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise error(f"{where}.{key}: expected {expected}, got {value!r}")
    return value


def optional_field(
    mapping: dict[str, Any],
    key: str,
    kind: type | tuple[type, ...],
    where: str,
    error: type[BesmanError] = InputError,
) -> Any:
    """``mapping[key]`` checked as by :func:`require_field`, or None if it is absent or null."""
    if mapping.get(key) is None:
        return None
    return require_field(mapping, key, kind, where, error)


def read_npz(path: Path, expected_sha256: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of an NPZ file (no pickles), checked against a checksum when one is given."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    if expected_sha256 is not None and sha256(data) != expected_sha256:
        raise InputError(f"{path}: the checksum does not match its JSON file (corrupted or modified)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except ValueError as error:
        if "pickle" in str(error):  # numpy would suggest allow_pickle: besman never unpickles
            raise InputError(
                f"{path}: not an NPZ archive of arrays (loading it would unpickle Python objects, which "
                "besman never does)"
            ) from None
        raise InputError(f"{path}: not a readable NPZ archive ({error})") from None
    except Exception as error:  # zipfile, zlib and numpy raise many kinds for damaged archives
        raise InputError(f"{path}: not a readable NPZ archive ({type(error).__name__}: {error})") from None
