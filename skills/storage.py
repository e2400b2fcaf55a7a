"""Safe persistence: whole files or nothing, JSON and NPZ only (never pickle), checksummed pairs.

Writers go to a temporary file in the target folder and rename it into place, so a crash leaves either the
old file or the new one, never half of one. Readers load NPZ with ``allow_pickle=False``.
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


def write_atomically(path: str | Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` via a temporary file and a rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(descriptor, "wb") as file:
            file.write(data)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; a ``ValueError`` naming the file if it is missing or malformed."""
    try:
        value = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: not valid JSON ({error})") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path}: expected a JSON object at the top level")
    return value


def read_npz(path: Path, expected_sha256: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of an NPZ file (no pickles), checked against a checksum when one is given."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    if expected_sha256 is not None and sha256(data) != expected_sha256:
        raise ValueError(f"{path}: the checksum does not match its JSON file (corrupted or modified)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except Exception as error:  # zipfile, zlib and numpy raise many kinds for damaged archives
        raise ValueError(f"{path}: not a readable NPZ archive ({type(error).__name__}: {error})") from None
