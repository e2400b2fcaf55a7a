"""Opening files for reading: only regular files, and only up to a size stated for their kind.

A FIFO blocks whoever opens it until some writer comes, ``/dev/zero`` never ends, and a directory, device or
socket is no file besman can use; a regular file may still be far larger than anything of its kind. Every
reader therefore opens its files here, with the bound of its kind (the bounds live beside their readers
and are listed in ``docs/reproducibility.md``): the path is checked with ``stat`` before it is opened (a
device is never opened), opened with ``O_NONBLOCK`` (a FIFO swapped in meanwhile cannot block the open),
checked again on the open descriptor (what is read is what was checked), and read no further than the bound
(a file that grows while it is read is refused too). Every refusal is the reader's
:class:`~besman.core.errors.BesmanError`, naming the file, what it is and what may be changed.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from besman.core.errors import BesmanError, InputError

KINDS = {
    stat.S_IFIFO: "a FIFO",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
    stat.S_IFDIR: "a directory",
}


def open_file(
    path: str | Path, limit: int, *, what: str, error: type[BesmanError] = InputError, raise_with: str = ""
) -> BinaryIO:
    """``path`` opened for reading in binary, once it is known to be a regular file of at most ``limit``
    bytes; otherwise ``error`` names the file and says why (``what`` names the kind of file, ``raise_with``
    how to raise the bound, if it can be)."""
    _check(path, os.stat, limit, what, error, raise_with)
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except OSError as problem:
        raise _unreadable(path, problem, error) from None
    try:
        _check(descriptor, os.fstat, limit, what, error, raise_with, path)
        os.set_blocking(descriptor, True)
    except BaseException:
        os.close(descriptor)
        raise
    # Outside the try: once the file object owns the descriptor, closing it is the object's (a Ctrl-C landing
    # in fdopen would otherwise close it twice, maybe another thread's new file).
    return os.fdopen(descriptor, "rb")


def read_bytes(
    path: str | Path, limit: int, *, what: str, error: type[BesmanError] = InputError, raise_with: str = ""
) -> bytes:
    """The contents of ``path``, checked and bounded as by :func:`open_file`."""
    with open_file(path, limit, what=what, error=error, raise_with=raise_with) as file:
        data = file.read(limit + 1)
    if len(data) > limit:  # it grew since the check, or it is a kernel file that reports no size
        raise error(_too_large(path, limit, "it grew as it was read", what, raise_with))
    return data


@dataclass(frozen=True)
class Limit:
    """The size limit of a kind of file that a user may need larger: ``default`` bytes, unless the
    environment variable ``variable`` (for every command) or a caller's ``max_bytes`` says otherwise."""

    default: int
    variable: str

    def bytes(self, max_bytes: int | None = None) -> int:
        """``max_bytes`` if given, else ``$variable`` if set, else ``default``."""
        if max_bytes is not None:
            return max_bytes
        text = os.environ.get(self.variable, "").strip()
        if not text:
            return self.default
        if not (text.isascii() and text.isdecimal()) or int(text) < 1:
            raise InputError(f"{self.variable}={text!r}: expected a number of bytes (a whole number above 0)")
        return int(text)

    @property
    def advice(self) -> str:
        """How to raise it, for the message that refuses a file."""
        return f"set {self.variable} to a larger number of bytes to read it"


def _check(target, status, limit, what, error, raise_with, path=None) -> None:
    """Refuses what ``status(target)`` (``os.stat`` of a path, ``os.fstat`` of a descriptor) shows is no
    regular file or is larger than ``limit``."""
    path = target if path is None else path
    try:
        found = status(target)
    except OSError as problem:
        raise _unreadable(path, problem, error) from None
    if not stat.S_ISREG(found.st_mode):
        kind = KINDS.get(stat.S_IFMT(found.st_mode), "a special file")
        raise error(f"{path}: {kind}, not a {what}; besman reads only regular files")
    if found.st_size > limit:
        raise error(_too_large(path, limit, f"{found.st_size} bytes", what, raise_with))


def _too_large(path, limit: int, size: str, what: str, raise_with: str) -> str:
    advice = f"; {raise_with}" if raise_with else ""
    return f"{path}: larger than {limit} bytes ({size}), the limit for a {what}{advice}"


def _unreadable(path, problem: OSError, error: type[BesmanError]) -> BesmanError:
    if isinstance(problem, FileNotFoundError):
        return error(f"{path}: no such file")
    return error(f"{path}: cannot be read ({problem.strerror or problem})")
