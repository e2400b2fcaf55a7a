"""Demonstrations: recorded human motion as named 3-D channels over time, and the loaders that read them.

A :class:`Demonstration` holds sample times (s), the recording's own frame numbers, named channels of 3-D
positions in metres (missing samples are NaN until preprocessing bridges them), the source file and,
when known, ground-truth segments (start and end frame, label).

Loaders, chosen by :func:`load` from the file's suffix:

- Qualisys Track Manager TSV exports (``.tsv``): a header block of ``KEY<TAB>values`` lines, a column line
  ``Frame  Time  <marker> X  <marker> Y  <marker> Z ...`` (any marker order), one row per frame, ``null``
  for missing values, millimetres; frames and times are the file's own (cropped recordings start anywhere).
  A ``<stem>_manually_segmented.json`` beside the file (a list of ``{"start index", "end index", "label"}``
  with frame numbers) becomes the ground truth.
- CSV (``.csv``): a header with a time column and columns ``<channel>_x``, ``<channel>_y``, ``<channel>_z``
  (metres unless ``units="mm"``).
- NPZ (``.npz``): ``times`` and one (T, 3) array per channel, with ``schema_version`` 1 (no pickles).

Every problem - a truncated file, no ``Frame``/``Time`` columns, a non-numeric cell, an unknown or all-missing
marker - raises :class:`DemonstrationError` naming the file, line or marker.
"""

from __future__ import annotations

import io
from array import array
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from besman.core.errors import BesmanError
from besman.core.reading import Limit, read_bytes
from besman.core.storage import npz_bytes, read_json, read_npz, require_field, write_atomically
from besman.core.validation import COUNT, PATH, checked, instance, items, optional, shaped, text

SCHEMA_VERSION = 1
AXES = ("X", "Y", "Z")
# The fields of each entry of a ``<stem>_manually_segmented.json``, in the order of Segment's.
SEGMENT_FIELDS = (("start index", int), ("end index", int), ("label", str))


# The six main segments of each run of the DFKI pick-and-place recordings (their ``_part`` sub-segments
# overlap these); the ground truth of segmentation and labelling on that data.
PICK_AND_PLACE_MAIN_SEGMENTS = (
    "approach_forward",
    "move_obj_table",
    "move_to_rest_right",
    "approach_right",
    "move_obj_shelf",
    "move_to_rest_down",
)


class DemonstrationError(BesmanError):
    """A demonstration file cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Segment:
    """A ground-truth segment: frames ``start_frame`` to ``end_frame`` (the file's numbering) and a label."""

    start_frame: int
    end_frame: int
    label: str


@dataclass(frozen=True, eq=False)
class Demonstration:
    """A recording: ``times`` (T,) in s, ``frames`` (T,), ``channels`` name -> (T, 3) positions in m."""

    times: np.ndarray
    frames: np.ndarray
    channels: dict[str, np.ndarray]
    source: str | None = None
    units: str = "m"
    segments: tuple[Segment, ...] = field(default=())

    @property
    def rate(self) -> float:
        """Samples per second (from the median time step)."""
        return float(1.0 / np.median(np.diff(self.times)))

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    def channel(self, name: str) -> np.ndarray:
        """The (T, 3) positions of a channel; a ``DemonstrationError`` lists the channels if it is unknown."""
        if name not in self.channels:
            raise DemonstrationError(
                f"{self.source or 'demonstration'}: no marker {name!r}; markers: {', '.join(self.channels)}"
            )
        return self.channels[name]

    def gaps(self, name: str) -> list[tuple[int, int]]:
        """Runs of missing samples of a channel as (first frame, last frame)."""
        missing = np.isnan(self.channel(name)).any(axis=1)
        edges = np.flatnonzero(np.diff(np.r_[0, missing.astype(int), 0]))
        return [
            (int(self.frames[a]), int(self.frames[b - 1]))
            for a, b in zip(edges[::2], edges[1::2], strict=True)
        ]

    @checked(labels=optional(items(text("a label"), "a list of labels")))
    def boundary_frames(self, labels: Sequence[str] | None = None) -> list[int]:
        """Sorted start and end frames of the annotated segments (only those with one of ``labels``)."""
        return sorted(
            {
                frame
                for s in self.segments
                if labels is None or s.label in labels
                for frame in (s.start_frame, s.end_frame)
            }
        )

    @checked(times=shaped())
    def nearest_indices(self, times: np.ndarray) -> np.ndarray:
        """The sample index nearest to each time (s)."""
        return np.clip(np.searchsorted(self.times, times - 0.5 / self.rate), 0, len(self.times) - 1)

    def frame_index(self, frame: int) -> int:
        """The sample index of a frame number."""
        index = int(np.searchsorted(self.frames, frame))
        if index >= len(self.frames) or self.frames[index] != frame:
            raise DemonstrationError(
                f"{self.source}: frame {frame} is not in the recording ({self.frames[0]}..{self.frames[-1]})"
            )
        return index

    @checked(path=PATH)
    def save(self, path: str | Path) -> Path:
        """Writes the demonstration as NPZ (atomically)."""
        arrays = {"schema_version": np.array(SCHEMA_VERSION), "times": self.times, "frames": self.frames}
        arrays |= {f"channel/{name}": values for name, values in self.channels.items()}
        return write_atomically(path, npz_bytes(arrays))


DEMONSTRATION = instance(Demonstration, "a Demonstration (learning.load)")


@checked(path=PATH)
def load(path: str | Path, **options) -> Demonstration:
    """Loads a demonstration, choosing the reader by suffix (``.tsv``, ``.csv``, ``.npz``); ``options`` are
    the reader's (an option it does not take is refused by name)."""
    path = Path(path)
    readers = {".tsv": load_qualisys_tsv, ".csv": load_csv, ".npz": load_npz}
    if path.suffix.lower() not in readers:
        raise DemonstrationError(f"{path}: unknown format {path.suffix!r}; known: {', '.join(readers)}")
    return readers[path.suffix.lower()](path, **options)


# Recordings are refused above this size (the DFKI recordings are 0.15-0.35 MB: about 1000 rows of 41
# columns at 60 Hz; this holds some 190,000 such rows, 50 minutes), unless the variable or a caller's
# max_bytes raises it.
RECORDING_LIMIT = Limit(64_000_000, "BESMAN_MAX_RECORDING_BYTES")
# Values a text recording may hold: one per 4 bytes of its limit (the DFKI recordings have one per 8 bytes),
# so that reading one takes at most about 6 times the limit in memory, whatever its shape (docs/learning.md).
BYTES_PER_VALUE = 4


def read_recording(path: Path, max_bytes: int | None = None) -> bytes:
    """The bytes of a recording file: a regular file within :data:`RECORDING_LIMIT` (or ``max_bytes``)."""
    limit, advice = RECORDING_LIMIT.bytes(max_bytes), RECORDING_LIMIT.advice
    return read_bytes(path, limit, what="recording", error=DemonstrationError, raise_with=advice)


def _lines(path: Path, limit: int) -> Iterator[tuple[int, str]]:
    """The numbered lines of a text recording, one at a time (no list of them all: a file of millions of
    short rows would need gigabytes for it)."""
    data = read_recording(path, limit)
    if b"\x00" in data[:4096]:
        raise DemonstrationError(f"{path}: a binary file, not a text recording")
    number = 0
    for raw in io.BytesIO(data):
        # Exports may carry a stray non-UTF-8 byte in a description; the numbers are ASCII either way.
        for line in raw.decode("utf-8", errors="replace").splitlines():
            number += 1
            yield number, line


MAX_MAGNITUDE = 1e9  # no time (s), frame number or coordinate (mm) of a recording is this large
MAX_TIME_STEP = 1.0  # s between samples: a longer pause is a broken or concatenated recording


def _numbers(cells: list[str], path: Path, line: int, names: list[str]) -> np.ndarray:
    values = np.empty(len(cells))
    for i, cell in enumerate(cells):
        text = cell.strip()
        if text in ("null", "", "NaN", "nan"):
            values[i] = np.nan
            continue
        try:
            values[i] = float(text)
        except ValueError:
            raise DemonstrationError(
                f"{path}:{line}: column {names[i]!r} holds {text!r}, not a number"
            ) from None
        if not abs(values[i]) <= MAX_MAGNITUDE:  # inf, or a value no recording holds
            raise DemonstrationError(
                f"{path}:{line}: column {names[i]!r} holds {text!r}, not a plausible value"
            )
    return values


def _check_clock(path: Path, times: np.ndarray, frames: np.ndarray, lines: np.ndarray | None = None) -> None:
    """Times and frame numbers increase, by steps of at most :data:`MAX_TIME_STEP`; ``lines`` gives each
    row's line in the file (for the message)."""

    def where(row: int) -> str:
        return f"{path}:{lines[row]}" if lines is not None else f"{path}: sample {row}"

    steps = np.diff(times)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 1
        raise DemonstrationError(f"{where(row)}: Time must increase ({times[row - 1]:g} then {times[row]:g})")
    if np.any(steps > MAX_TIME_STEP):
        row = int(np.argmax(steps > MAX_TIME_STEP)) + 1
        raise DemonstrationError(
            f"{where(row)}: Time jumps by {steps[row - 1]:g} s (more than {MAX_TIME_STEP:g} s between "
            "samples: a gap in the recording; split it there)"
        )
    if np.any(np.diff(frames) <= 0):
        row = int(np.argmax(np.diff(frames) <= 0)) + 1
        raise DemonstrationError(f"{where(row)}: Frame must increase ({frames[row - 1]} then {frames[row]})")


def _table(
    lines: Iterator[tuple[int, str]], path: Path, names: list[str], separator: str, limit: int
) -> tuple[np.ndarray, np.ndarray]:
    """The rows of numbers under a header of ``names`` as a (rows, columns) array, and each row's line
    number. The values are stored flat as they are parsed: 8 bytes each, at most one per
    :data:`BYTES_PER_VALUE` bytes of the recording's size ``limit``."""
    values, numbers = array("d"), array("q")
    for number, line in lines:
        if not line.strip():
            continue
        cells = line.split(separator)
        while len(cells) > len(names) and not cells[-1].strip():
            cells.pop()  # exports end each line with a separator
        if len(cells) != len(names):
            raise DemonstrationError(
                f"{path}:{number}: {len(cells)} values for {len(names)} columns (truncated or damaged file)"
            )
        values.extend(_numbers(cells, path, number, names))
        numbers.append(number)
        if len(values) > limit // BYTES_PER_VALUE:
            raise DemonstrationError(
                f"{path}:{number}: more than {limit // BYTES_PER_VALUE} values, the most a recording of at "
                f"most {limit} bytes may hold (one per {BYTES_PER_VALUE} bytes); {RECORDING_LIMIT.advice}"
            )
    if len(numbers) < 2:
        raise DemonstrationError(f"{path}: fewer than 2 rows of data")
    return np.frombuffer(values).reshape(len(numbers), len(names)), np.frombuffer(numbers, dtype=np.int64)


@checked(path=PATH, max_bytes=optional(COUNT))
def load_qualisys_tsv(path: str | Path, *, max_bytes: int | None = None) -> Demonstration:
    """Reads a Qualisys TSV export (see the module documentation); ``max_bytes`` replaces the size limit
    (:data:`RECORDING_LIMIT`)."""
    path, limit = Path(path), RECORDING_LIMIT.bytes(max_bytes)
    lines = _lines(path, limit)
    header_line, header = next(
        ((n, line) for n, line in lines if line.split("\t")[:1] == ["Frame"]), (0, None)
    )
    if header is None:
        raise DemonstrationError(f"{path}: no column header line starting with 'Frame' and 'Time'")
    names = header.split("\t")
    while names and not names[-1].strip():
        names.pop()  # exports end the header line with a tab
    if names[:2] != ["Frame", "Time"]:
        raise DemonstrationError(
            f"{path}:{header_line}: the columns must start with Frame and Time, got {names[:2]}"
        )
    data, numbers = _table(lines, path, names, "\t", limit)
    if np.isnan(data[:, :2]).any():
        row = int(np.argwhere(np.isnan(data[:, :2]))[0, 0])
        raise DemonstrationError(f"{path}:{numbers[row]}: Frame and Time must be numbers")
    channels: dict[str, np.ndarray] = {}
    for column, name in enumerate(names[2:], 2):
        marker, _, axis = name.rpartition(" ")
        if axis not in AXES or not marker:
            raise DemonstrationError(f"{path}:{header_line}: column {name!r} is not '<marker> X|Y|Z'")
        channels.setdefault(marker, np.full((len(data), 3), np.nan))[:, AXES.index(axis)] = (
            data[:, column] / 1000.0
        )
    for marker, values in channels.items():
        if np.isnan(values).all():
            raise DemonstrationError(f"{path}: marker {marker!r} has no valid sample (all null)")
    times, frames = data[:, 1], data[:, 0].astype(int)
    _check_clock(path, times, frames, numbers)
    return Demonstration(times, frames, channels, str(path), "m", _ground_truth(path, frames))


def _ground_truth(path: Path, frames: np.ndarray) -> tuple[Segment, ...]:
    sidecar = path.with_name(f"{path.stem}_manually_segmented.json")
    if not sidecar.exists():
        return ()
    segments = []
    for number, entry in enumerate(read_json(sidecar, DemonstrationError, top=list, what="segmentation")):
        where = f"{sidecar}[{number}]"
        if not isinstance(entry, dict):
            raise DemonstrationError(f"{where}: expected a segment object, got {entry!r}")
        segments.append(
            Segment(
                *(require_field(entry, key, kind, where, DemonstrationError) for key, kind in SEGMENT_FIELDS)
            )
        )
    for segment in segments:
        if not frames[0] <= segment.start_frame <= segment.end_frame <= frames[-1]:
            raise DemonstrationError(
                f"{sidecar}: segment {segment} lies outside the recording's frames {frames[0]}..{frames[-1]}"
            )
    return tuple(segments)


@checked(path=PATH, time_column=text("a column name"), units=text("a unit"), max_bytes=optional(COUNT))
def load_csv(
    path: str | Path, *, time_column: str = "time", units: str = "m", max_bytes: int | None = None
) -> Demonstration:
    """Reads a CSV with a time column and ``<channel>_x/_y/_z`` columns (``units`` "m" or "mm");
    ``max_bytes`` replaces the size limit (:data:`RECORDING_LIMIT`)."""
    path = Path(path)
    if units not in ("m", "mm"):
        raise DemonstrationError(f"{path}: units must be 'm' or 'mm', got {units!r}")
    limit = RECORDING_LIMIT.bytes(max_bytes)
    lines = _lines(path, limit)
    _, header = next(lines, (0, None))
    if header is None:
        raise DemonstrationError(f"{path}: empty file")
    names = [name.strip() for name in header.split(",")]
    if not all(name.isprintable() for name in names):
        raise DemonstrationError(f"{path}:1: not a CSV header line (unprintable characters)")
    if time_column not in names:
        shown = ", ".join(names[:20]) + (", ..." if len(names) > 20 else "")
        raise DemonstrationError(f"{path}:1: no time column {time_column!r}; columns: {shown}")
    data, numbers = _table(lines, path, names, ",", limit)
    times = data[:, names.index(time_column)]
    if np.isnan(times).any():
        raise DemonstrationError(
            f"{path}:{numbers[int(np.argmax(np.isnan(times)))]}: {time_column!r} is empty"
        )
    _check_clock(path, times, np.arange(len(times)), numbers)
    channels: dict[str, np.ndarray] = {}
    scale = 0.001 if units == "mm" else 1.0
    for column, name in enumerate(names):
        channel, _, axis = name.rpartition("_")
        if name == time_column:
            continue
        if axis.upper() not in AXES or not channel:
            raise DemonstrationError(f"{path}:1: column {name!r} is not '<channel>_x|y|z'")
        channels.setdefault(channel, np.full((len(data), 3), np.nan))[:, AXES.index(axis.upper())] = (
            data[:, column] * scale
        )
    return Demonstration(times, np.arange(len(times)), channels, str(path), "m")


@checked(path=PATH, max_bytes=optional(COUNT))
def load_npz(path: str | Path, *, max_bytes: int | None = None) -> Demonstration:
    """Reads a demonstration saved with :meth:`Demonstration.save` (``max_bytes`` as for TSV)."""
    path = Path(path)
    limit, advice = RECORDING_LIMIT.bytes(max_bytes), RECORDING_LIMIT.advice
    arrays = read_npz(path, what="recording", max_bytes=limit, raise_with=advice)
    if "schema_version" not in arrays or int(arrays["schema_version"]) != SCHEMA_VERSION:
        raise DemonstrationError(f"{path}: not a besman demonstration (schema_version {SCHEMA_VERSION})")
    for key in ("times", "frames"):
        if key not in arrays:
            raise DemonstrationError(f"{path}: missing array {key!r}")
    times, frames = arrays["times"].astype(float), arrays["frames"].astype(int)
    channels = {
        key.removeprefix("channel/"): arrays[key].astype(float)
        for key in arrays
        if key.startswith("channel/")
    }
    for name, values in channels.items():
        if values.shape != (len(times), 3):
            raise DemonstrationError(
                f"{path}: channel {name!r} has shape {values.shape}, expected ({len(times)}, 3)"
            )
    if len(times) < 2 or len(frames) != len(times) or not np.isfinite(times).all():
        raise DemonstrationError(f"{path}: times must be at least 2 finite numbers, one per frame")
    for name, values in channels.items():
        if np.any(np.abs(values[np.isfinite(values)]) > MAX_MAGNITUDE / 1000) or np.isinf(values).any():
            raise DemonstrationError(f"{path}: channel {name!r} holds an infinite or implausible value")
    _check_clock(path, times, frames)
    return Demonstration(times, frames, channels, str(path), "m")
