"""The throwing experiment's output folder: claimed for one writer, refused unless it is new, empty or a run
of the same configuration, and the cache of finished stages in ``DIR/work`` that lets a run resume."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from besman.core.errors import InputError
from besman.core.storage import (
    holds_files,
    npz_bytes,
    read_json,
    read_npz,
    remove_temporaries,
    write_atomically,
)
from besman.core.writer_lock import WriterLock
from besman.experiments.throwing.config import SCHEMA_VERSION, ExperimentConfig

# The folders in DIR that a run writes (besides DIR itself), where a killed run leaves temporaries.
OUTPUT_FOLDERS = ("work", "pool")


@dataclass
class RunFolder:
    """``directory``, claimed for a run of ``config`` when made; :meth:`release` gives it up."""

    directory: Path
    config: ExperimentConfig
    _stages: dict[str, dict[str, np.ndarray]] = field(init=False, default_factory=dict)  # read once

    def __post_init__(self) -> None:
        # The directory's one writer from here to release() (or the end of this process).
        self._lock = WriterLock(self.directory, "--out").acquire()
        try:
            self._check()
        except BaseException:
            self._lock.release()  # refused: no lock file stays beside it
            raise

    def release(self) -> None:
        self._lock.release()

    def _check(self) -> None:
        """Refuses a file, a run of another configuration and a folder of someone else's; in a run's folder
        (its configuration the same, or nothing in it but besman's temporaries), removes the temporaries
        that a killed run left."""
        stored = self.directory / "work" / "config.json"
        config = json.loads(json.dumps({"schema_version": SCHEMA_VERSION, **asdict(self.config)}))
        if self.directory.exists() and not self.directory.is_dir():
            raise InputError(f"{self.directory}: the output is a file, not a folder")
        if stored.exists():
            if read_json(stored) != config:
                raise InputError(
                    f"{self.directory} holds a run with another configuration ({stored}); use another --out"
                )
        elif holds_files(self.directory):
            raise InputError(
                f"{self.directory}: the folder is not empty and not a run of this experiment; "
                "use another --out"
            )
        else:
            write_atomically(stored, (json.dumps(config, indent=2) + "\n").encode())
        remove_temporaries(self.directory, OUTPUT_FOLDERS)

    def stage(self, name: str, compute: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        """A stage's arrays: read from DIR/work if a previous run finished it, else computed and written;
        kept in memory, since templates, costs and diagnostics ask for the same training stages again."""
        if name not in self._stages:
            path = self.directory / "work" / f"{name}.npz"
            if path.exists():
                self._stages[name] = read_npz(path)
            else:
                self._stages[name] = compute()
                write_atomically(path, npz_bytes(self._stages[name]))
        return self._stages[name]
