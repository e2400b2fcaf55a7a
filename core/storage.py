"""Safe persistence: whole files or nothing, JSON and NPZ only (never pickle), checksummed pairs.

Writers go to a temporary file in the target folder and rename it into place, so a crash leaves either the
old file or the new one, never half of one; a failed write removes its temporary and names the file. A
temporary carries besman's mark (``.NAME.besman-XXXXXXXX.tmp``), and only marked ones are ever cleaned up
(:func:`remove_temporaries`). Readers open only regular files of a bounded size (:data:`JSON_BYTES`,
:data:`NPZ_BYTES`; :mod:`besman.core.reading`), load NPZ with ``allow_pickle=False``, and check JSON
documents field by field (:func:`check_schema_version`, :func:`require_field`, :func:`optional_field`) with
messages that name the file and the field; every error is a :class:`~besman.core.errors.BesmanError`.
"""

from __future__ import annotations

import ctypes
import errno
import hashlib
import io
import json
import os
import re
import stat
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from besman.core.errors import BesmanError, InputError
from besman.core.reading import KINDS, open_file, read_bytes

# Bounds of the files besman writes and reads back (far above what it writes: a pool manifest or primitive
# is about 20 kB, the throwing experiment's results.json 150 kB, an entry's or a stage's arrays 16 kB).
JSON_BYTES = 16_000_000
NPZ_BYTES = 64_000_000  # the file, and its arrays unpacked

# The process's umask, read once (reading it means setting it): temporary files are made private (0600),
# and the renamed file gets the permissions an ordinary new file would have.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


# A temporary's name, ``.NAME.besman-XXXXXXXX.tmp``: the mark that ties it to besman and to the file NAME it
# becomes (mkstemp's random part has no dot).
_MARK = ".besman-"
_TEMPORARY = re.compile(rf"\.(?P<name>.+){re.escape(_MARK)}[^./]+\.tmp")


class WriteError(BesmanError):
    """A file could not be written (a full disk, a file-size limit, a permission); the message names the
    file, and nothing of it is left behind."""


def write_error(path: Path, error: OSError) -> WriteError:
    """The error of a failed write of ``path`` (the final path, not its temporary's)."""
    return WriteError(f"{path}: cannot write it ({error.strerror or error})")


def write_atomically(path: str | Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` via a temporary file and a rename (permissions as for a new file); a
    failed write removes the temporary and raises a :class:`WriteError` naming ``path``."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor, temporary = open_temporary(path)
    except OSError as error:
        raise write_error(path, error) from error
    try:
        with os.fdopen(descriptor, "wb") as file:
            file.write(data)
            file.flush()
            os.fsync(file.fileno())
        put_in_place(temporary, path)
    except BaseException as error:
        temporary.unlink(missing_ok=True)
        if isinstance(error, OSError):
            raise write_error(path, error) from error
        raise
    return path


def open_temporary(path: Path) -> tuple[int, Path]:
    """A new private (0600) temporary file beside ``path``, named with besman's mark for ``path``
    (:func:`is_temporary`): its descriptor and path."""
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}{_MARK}", suffix=".tmp")
    return descriptor, Path(temporary)


def put_in_place(temporary: Path, path: Path) -> None:
    """Renames a finished temporary to ``path``, with the permissions an ordinary new file would have."""
    os.chmod(temporary, 0o666 & ~_UMASK)
    os.replace(temporary, path)


def folder_beside(path: Path) -> Path:
    """A new empty folder beside ``path``, named as besman's temporaries of it, with the permissions an
    ordinary new folder would have: the next state of the folder ``path``, for :func:`exchange_folders`."""
    folder = Path(tempfile.mkdtemp(dir=path.absolute().parent, prefix=f".{path.name}{_MARK}", suffix=".tmp"))
    os.chmod(folder, 0o777 & ~_UMASK)
    return folder


def exchange_folders(new: Path, path: Path) -> None:
    """Puts the folder ``new`` at ``path`` in one step: renamed there if nothing is, else exchanged with the
    folder there (Linux's ``renameat2(RENAME_EXCHANGE)``; ``new`` then holds the old one). A reader, or a
    writer killed at any moment, sees the old folder or the new one, never a mix; ``new``'s files written
    for it (not hard links of older ones) reach the disk first."""
    for folder, _, files in os.walk(new):
        for name in files:
            file = Path(folder, name)
            if file.lstat().st_nlink == 1:
                descriptor = os.open(file, os.O_RDONLY)
                try:
                    os.fsync(descriptor)
                finally:
                    os.close(descriptor)
    if not path.exists():
        os.rename(new, path)
        return
    libc = ctypes.CDLL(None, use_errno=True)
    renameat2 = getattr(libc, "renameat2", None)
    at_cwd, rename_exchange = -100, 2
    if renameat2 is None or renameat2(at_cwd, os.fsencode(new), at_cwd, os.fsencode(path), rename_exchange):
        code = ctypes.get_errno() if renameat2 is not None else errno.ENOSYS
        raise WriteError(
            f"{path}: cannot replace it in one step ({os.strerror(code)}); its file system or system lacks "
            "renameat2's exchange (Linux 3.15 and ext4, XFS, Btrfs or tmpfs have it)"
        )


def is_temporary(path: Path, of: str | None = None) -> bool:
    """Whether ``path`` is named as a temporary of besman's (``.NAME.besman-XXXXXXXX.tmp``; of the file
    named ``of``, if given): the only file a writer that dies mid-write leaves behind."""
    match = _TEMPORARY.fullmatch(path.name)
    return match is not None and of in (None, match["name"])


def holds_files(folder: Path) -> bool:
    """Whether ``folder`` holds a file, at any depth, other than besman's temporaries."""
    return folder.is_dir() and any(p.is_file() and not is_temporary(p) for p in folder.rglob("*"))


def remove_temporaries(folder: Path, parts: tuple[str, ...] = (), of: str | None = None) -> None:
    """Removes the temporaries that dead writers left in ``folder`` and in its subfolders ``parts`` (paths
    relative to it; no deeper, and no symbolic link): regular files of this user, named as besman's
    (of the file named ``of``, if given). For the one writer (:class:`~besman.core.writer_lock.WriterLock`)
    of an output known to be besman's: its own temporaries are not there yet, and nothing else is touched."""
    places = [folder, *(folder / part for part in parts if not (folder / part).is_symlink())]
    for place in places:
        for path in place.iterdir() if place.is_dir() else ():
            if is_temporary(path, of) and _is_own_file(path):
                path.unlink(missing_ok=True)


def _is_own_file(path: Path) -> bool:
    try:
        status = path.lstat()
    except FileNotFoundError:
        return False
    return stat.S_ISREG(status.st_mode) and status.st_uid == os.geteuid()


def check_output(
    path: str | Path,
    *,
    option: str,
    suffixes: tuple[str, ...] = (),
    inputs: tuple[str | Path, ...] = (),
    kind: str | None = None,
) -> Path:
    """``path`` as a Path once it is known to be writable as an output named ``option`` (e.g. "--plot"):
    with one of ``suffixes`` (if given), not a directory, in a writable folder (or one that can be made),
    none of the command's ``inputs`` (an output never replaces what the command reads), and replaceable
    (:func:`check_replaceable`; ``kind``: the header an existing file must have). Checked before any work,
    so that a long computation is not lost at the end."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: a directory; give a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{option} {path}: the file must end in {' or '.join(suffixes)}")
    for source in inputs:
        if Path(source).exists() and path.exists() and os.path.samefile(source, path):
            raise InputError(f"{option} {path}: that is an input of this command; it would be overwritten")
    check_replaceable(path, option, kind)
    folder = path.absolute().parent  # missing folders are made when the file is written
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: {str(folder)!r} is a file, not a folder")
    if not os.access(folder, os.W_OK):
        raise InputError(f"{option} {path}: the folder {str(folder)!r} is not writable")
    return path


def check_replaceable(path: str | Path, option: str, kind: str | None = None) -> None:
    """Refuses to replace what is at ``path`` unless it is nothing or a regular file (a symbolic link, a
    FIFO, a device or a socket is the user's, and the rename of a whole file would destroy it); with
    ``kind``, the regular file too unless its first line is a JSON object of that ``kind`` (e.g.
    "besman-run-log": an earlier output of the same kind, named in messages with spaces for hyphens)."""
    path = Path(path)
    try:
        mode = path.lstat().st_mode
    except (FileNotFoundError, NotADirectoryError):  # nothing there (a folder on the way a file: named later)
        return
    if stat.S_ISDIR(mode):
        return  # check_output names it
    if not stat.S_ISREG(mode):
        what = "a symbolic link" if stat.S_ISLNK(mode) else KINDS.get(stat.S_IFMT(mode), "no regular file")
        raise InputError(f"{option} {path}: {what}, not a regular file; remove it or choose another name")
    if kind is None:
        return
    with open_file(path, 1 << 62, what=kind.replace("-", " ")) as file:  # only the first line is read
        first = file.readline(JSON_BYTES)
    try:
        header = json_value(first, str(path))
    except InputError:
        header = None
    if not isinstance(header, dict) or header.get("kind") != kind:
        raise InputError(
            f"{option} {path}: an existing file that is not a {kind.replace('-', ' ')}; remove it or choose "
            "another name"
        )


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_json(
    path: Path,
    error: type[BesmanError] = InputError,
    top: type[dict] | type[list] = dict,
    *,
    what: str = "JSON document",
    max_bytes: int = JSON_BYTES,
) -> Any:
    """The JSON object (or, with ``top=list``, list) in ``path``, a regular file of at most ``max_bytes``;
    ``error`` names the file if it is missing, special, too large or malformed (``what`` names its kind)."""
    value = json_value(read_bytes(path, max_bytes, what=what, error=error), str(path), error)
    if not isinstance(value, top):
        raise error(f"{path}: expected a JSON {'object' if top is dict else 'list'} at the top level")
    return value


def json_value(data: bytes, where: str, error: type[BesmanError] = InputError) -> Any:
    """The JSON value of ``data``; ``error`` names ``where`` if it is not JSON that Python reads: malformed,
    not UTF-8, an integer longer than Python converts (4300 digits) or nesting deeper than its stack."""
    try:
        return json.loads(data.decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as problem:
        raise error(f"{where}: not valid JSON ({problem})") from None
    except ValueError:  # the only other ValueError of json.loads: int() refusing too many digits
        limit = sys.get_int_max_str_digits()
        raise error(f"{where}: not JSON besman reads (an integer of more than {limit} digits)") from None
    except RecursionError:
        raise error(f"{where}: not JSON besman reads (lists or objects nested too deeply)") from None


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


def optional_field(mapping: dict[str, Any], key: str, *args: Any, **kwargs: Any) -> Any:
    """``mapping[key]`` checked as by :func:`require_field` (which takes the other arguments: ``kind``,
    ``where`` and ``error``), or None if it is absent or null."""
    if mapping.get(key) is None:
        return None
    return require_field(mapping, key, *args, **kwargs)


def read_npz(
    path: Path,
    expected_sha256: str | None = None,
    *,
    what: str = "NPZ archive",
    max_bytes: int = NPZ_BYTES,
    raise_with: str = "",
) -> dict[str, np.ndarray]:
    """The arrays of an NPZ file (no pickles), checked against a checksum when one is given; the file and
    its arrays unpacked are at most ``max_bytes`` each (``what`` names its kind in messages, ``raise_with``
    how to raise the bound)."""
    data = read_bytes(path, max_bytes, what=what, raise_with=raise_with)
    if expected_sha256 is not None and sha256(data) != expected_sha256:
        raise InputError(f"{path}: the checksum does not match its JSON file (corrupted or modified)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            _check_unpacked(archive, path, max_bytes, what)
            return {name: archive[name] for name in archive.files}
    except InputError:
        raise
    except ValueError as error:
        if "pickle" in str(error):  # numpy would suggest allow_pickle: besman never unpickles
            raise InputError(
                f"{path}: not an NPZ archive of arrays (loading it would unpickle Python objects, which "
                "besman never does)"
            ) from None
        raise InputError(f"{path}: not a readable NPZ archive ({error})") from None
    except Exception as error:  # zipfile, zlib and numpy raise many kinds for damaged archives
        raise InputError(f"{path}: not a readable NPZ archive ({type(error).__name__}: {error})") from None


def _check_unpacked(archive: np.lib.npyio.NpzFile, path: Path, max_bytes: int, what: str) -> None:
    """Refuses an archive whose members unpack to more than ``max_bytes`` (a few compressed kilobytes can
    unpack to gigabytes); zipfile stops each member at its stated size, so those sizes bound the memory."""
    unpacked = sum(member.file_size for member in archive.zip.infolist())
    if unpacked > max_bytes:
        raise InputError(f"{path}: unpacks to {unpacked} bytes, more than the {max_bytes} of a {what}")
