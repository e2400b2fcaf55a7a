"""One writer per output: a lock that a second command aimed at the same output cannot take.

A long command (``besman learn --out POOL``, ``besman experiment throwing --out DIR``, a run's ``--log``)
holds an exclusive ``flock`` on ``.NAME.lock`` beside its output for as long as it writes, with its pid and
command line in the file. A second command refuses at once with one line naming that holder instead of
interleaving its writes with the first's. The kernel drops an ``flock`` when its process dies, however it
dies (``kill -9`` included), so a lock left behind by a dead process is simply taken over; the lock file
stays on disk only in that case, and holds nothing that needs cleaning up.

Taking the lock checks that the file locked is still the one at the path: a holder that finishes removes
the file, and a command that opened it just before then would otherwise hold a lock on a file nobody else
can see.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
import sys
from pathlib import Path

from besman.core.errors import BesmanError
from besman.core.storage import write_error


class OutputBusyError(BesmanError):
    """Another live process writes the output; the message names it (pid and command)."""


class WriterLock:
    """The exclusive right to write ``path`` (a file or a folder), named ``option`` in messages."""

    def __init__(self, path: str | Path, option: str) -> None:
        self.path, self.option = Path(path), option
        self.lock_path = self.path.absolute().parent / f".{self.path.name}.lock"
        self._file = None

    def acquire(self) -> WriterLock:
        """Takes the lock or raises :class:`OutputBusyError` naming the holder (or, if the lock file cannot
        be written, a :class:`~besman.core.storage.WriteError` naming the output, with no lock left)."""
        try:
            self.lock_path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self._locked_file()
            # Unbuffered: nothing is left to flush (and fail again on a full disk) when it is released.
            descriptor = self._file.fileno()
            os.ftruncate(descriptor, 0)
            os.write(descriptor, f"pid {os.getpid()} ({' '.join(sys.argv) or sys.executable})\n".encode())
        except OSError as error:
            self.release()
            raise write_error(self.path, error) from error
        return self

    def _locked_file(self):
        """The lock file at the path, opened and locked."""
        while True:
            file = self._open()
            try:
                fcntl.flock(file, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                file.seek(0)
                holder = file.read().strip() or "a process that is starting"
                file.close()
                raise OutputBusyError(f"{self.option} {self.path}: in use by {holder}") from None
            try:
                same = os.fstat(file.fileno()).st_ino == os.stat(self.lock_path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                return file
            file.close()  # the holder finished and removed it meanwhile: lock the file at the path now

    def _open(self):
        """The file at the lock path, made if missing; anything else there than a regular file (a FIFO, a
        link to a device) is refused, never read: it is not besman's and reading it could block for ever."""
        flags = os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
        try:
            descriptor = os.open(self.lock_path, flags, 0o644)
        except OSError as error:
            if error.errno != errno.ELOOP:
                raise
            raise OutputBusyError(
                f"{self.option} {self.path}: {self.lock_path} is a link, not besman's lock file; remove it"
            ) from None
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            os.close(descriptor)
            raise OutputBusyError(
                f"{self.option} {self.path}: {self.lock_path} is not a regular file, not besman's lock file; "
                "remove it"
            )
        os.set_blocking(descriptor, True)
        return os.fdopen(descriptor, "a+")

    def release(self) -> None:
        """Gives the lock up (removing the file first, so that a waiting command finds the path free)."""
        if self._file is None:
            return
        self.lock_path.unlink(missing_ok=True)
        fcntl.flock(self._file, fcntl.LOCK_UN)
        self._file.close()
        self._file = None

    def __enter__(self) -> WriterLock:
        return self.acquire()

    def __exit__(self, *exc_info) -> None:
        self.release()
