"""Reading a LeRobot v3.0 dataset (:mod:`besman.datasets.format`): its metadata whole, an episode's
frames when asked. Everything is checked as it is read; a problem raises :class:`DatasetError` naming the
file and the field."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from besman.core.errors import BesmanError
from besman.core.reading import open_file
from besman.core.storage import read_json
from besman.core.validation import shown
from besman.datasets import format as fmt

# The episodes table's columns that LeRobot defines; any other (``besman/seed``) is a fact of the episode.
LEROBOT_COLUMNS = ("episode_index", "tasks", "length", "dataset_from_index", "dataset_to_index")
LEROBOT_PREFIXES = ("data/", "videos/", "stats/", "meta/")
ANY_SIZE = 1 << 62  # a dataset's files are as large as their author made them: their tables are bounded
# What a parquet file of a dataset may unpack to: LeRobot's data files hold 100 MB of compressed frames
# (data_files_size_in_mb) and its metadata tables far less; a few kilobytes of zeros can unpack to gigabytes.
MAX_UNPACKED = 2_000_000_000  # bytes


class DatasetError(BesmanError):
    """A dataset cannot be read; the message names the file and what is wrong."""


@dataclass(frozen=True, eq=False)
class LeRobotDataset:
    """A dataset's ``info.json``, its tasks (by task_index) and its episodes' rows (by episode_index)."""

    root: Path
    info: dict
    tasks: tuple[str, ...]
    episodes: tuple[dict, ...]

    @property
    def fps(self) -> int:
        return self.info["fps"]

    @property
    def features(self) -> dict[str, dict]:
        return self.info["features"]

    def facts(self, episode: int) -> dict:
        """The episode's columns that are not LeRobot's (besman's ``besman/seed``, ``besman/tau`` ...)."""
        row = self.episodes[episode]
        return {
            k: v for k, v in row.items() if k not in LEROBOT_COLUMNS and not k.startswith(LEROBOT_PREFIXES)
        }

    def frames(self, episode: int) -> dict[str, np.ndarray]:
        """The episode's frames: every column of the data (its own features and the defaults) as (T,) or
        (T, n) values of the feature's dtype, in frame order; each column of the type and width that its
        feature declares, and finite."""
        if not 0 <= episode < len(self.episodes):
            raise DatasetError(f"{self.root}: no episode {episode} (it has {len(self.episodes)})")
        row = self.episodes[episode]
        path = _data_file(self.root, row)
        try:
            status = path.stat()
        except FileNotFoundError:
            raise DatasetError(f"{path}: missing (episode {episode}'s data file)") from None
        table = _data_table(path, status.st_ino, status.st_mtime_ns)
        if "episode_index" not in table.column_names or not pa.types.is_integer(table["episode_index"].type):
            raise DatasetError(f"{path}: needs an integer column episode_index, as every LeRobot data file")
        rows = table.filter(pc.equal(table["episode_index"], episode))
        if rows.num_rows != row["length"]:
            raise DatasetError(
                f"{path}: episode {episode} has {rows.num_rows} rows, its length is {row['length']}"
            )
        columns = {}
        for name, feature in self.features.items():
            if fmt.is_video(feature):
                continue
            if name not in rows.column_names:
                raise DatasetError(f"{path}: no column {name!r}, a feature of info.json")
            kind, wanted = rows.schema.field(name).type, fmt.arrow_type(feature)
            if _base_and_width(kind) != _base_and_width(wanted):
                raise DatasetError(
                    f"{path}: column {name!r} holds {kind}, info.json declares {feature['dtype']} of shape "
                    f"{feature['shape']}"
                )
            columns[name] = found = fmt.values(rows[name], feature)
            if found.dtype.kind == "f" and not np.isfinite(found).all():
                raise DatasetError(
                    f"{path}: episode {episode}'s {name} has values that are not finite (NaN or infinite)"
                )
        order = np.argsort(columns["frame_index"], kind="stable")
        return {name: values[order] for name, values in columns.items()}


def _data_file(root: Path, row: dict) -> Path:
    """The data file of the episode of ``row`` (whose indices :func:`read_dataset` checked)."""
    return root / fmt.DATA_PATH.format(chunk_index=row["data/chunk_index"], file_index=row["data/file_index"])


def _base_and_width(kind: pa.DataType) -> tuple[pa.DataType, int]:
    """A column type's scalar type and its width (1 for a scalar; a list's item name does not matter)."""
    if pa.types.is_fixed_size_list(kind):
        return kind.value_type, kind.list_size
    return kind, 1


def read_parquet(path: Path, what: str, read=pq.ParquetFile.read, max_rows: int | None = None):
    """``read`` (a function of a ``pyarrow.parquet.ParquetFile``; default: the whole table) applied to the
    parquet file at ``path``, opened only once it is known to be a regular file (pyarrow would block on a
    FIFO for ever and read ``/dev/zero`` without end), and read only if its metadata promise at most
    ``max_rows`` rows and :data:`MAX_UNPACKED` bytes; any problem is a :class:`DatasetError` naming the file
    (``what`` names its kind)."""
    with open_file(path, ANY_SIZE, what=what, error=DatasetError) as file:
        try:
            parquet = pq.ParquetFile(file)
            meta = parquet.metadata
            unpacked = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
            if max_rows is not None and meta.num_rows > max_rows:
                raise DatasetError(
                    f"{path}: {meta.num_rows} rows, more than the {max_rows} a {what} has here"
                )
            if unpacked > MAX_UNPACKED:
                raise DatasetError(
                    f"{path}: unpacks to {unpacked} bytes, more than the {MAX_UNPACKED} besman reads of a "
                    "parquet file"
                )
            return read(parquet)
        except (OSError, pa.ArrowException) as error:
            raise DatasetError(f"{path}: cannot read it as parquet ({error})") from None


@functools.lru_cache(maxsize=4)
def _data_table(path: Path, inode: int, modified: int) -> pa.Table:
    """A data file, read once while it is the same file (an append puts a new one in its place)."""
    return read_parquet(path, "data file")


def read_dataset(root: str | Path) -> LeRobotDataset:
    """The dataset at ``root``, its metadata checked: the format's version, fps, features, LeRobot's own
    paths, the tasks, the episodes (numbered 0 to N - 1, as many as ``total_episodes``; their files' indices
    and video files), and the frames' count."""
    root = Path(root)
    info_path = root / fmt.INFO
    if not info_path.exists():  # anything else there than a regular file is named by read_json
        raise DatasetError(f"{root}: not a LeRobot dataset (no {fmt.INFO})")
    info = read_json(info_path, DatasetError)
    version = info.get("codebase_version")
    if version != fmt.CODEBASE_VERSION:
        raise DatasetError(
            f"{info_path}: codebase_version {shown(version)}; besman reads {fmt.CODEBASE_VERSION} (convert "
            "an older dataset with LeRobot's convert_dataset_v21_to_v30)"
        )
    for key, kind in (("fps", int), ("features", dict), ("total_episodes", int), ("total_frames", int)):
        if not isinstance(info.get(key), kind) or isinstance(info.get(key), bool):
            raise DatasetError(f"{info_path}: {key} must be {kind.__name__}, got {shown(info.get(key))}")
    if not 0 <= info["total_episodes"] <= fmt.MAX_INDEX:
        raise DatasetError(
            f"{info_path}: total_episodes must be from 0 to {fmt.MAX_INDEX}, got "
            f"{shown(info['total_episodes'])}"
        )
    if not 1 <= info["fps"] <= fmt.MAX_FPS:
        raise DatasetError(f"{info_path}: fps must be from 1 to {fmt.MAX_FPS}, got {shown(info['fps'])}")
    if not isinstance(info.get("robot_type"), str | None):
        raise DatasetError(
            f"{info_path}: robot_type must be a text or null, got {shown(info.get('robot_type'))}"
        )
    _check_features(info_path, info["features"])
    # The paths are LeRobot's templates, never a stranger's: formatting one would walk attributes or
    # allocate without bound, and it could name any file on the machine.
    videos = [name for name, feature in info["features"].items() if fmt.is_video(feature)]
    for key, template, absent in (
        ("data_path", fmt.DATA_PATH, False),
        ("video_path", fmt.VIDEO_PATH, not videos),
    ):
        if info.get(key) != template and not (absent and info.get(key) is None):
            raise DatasetError(
                f"{info_path}: {key} {shown(info.get(key))} is not LeRobot's {template!r}, the only one "
                "besman reads"
            )
    tasks = _tasks(root / fmt.TASKS)
    episodes = _episodes(root, info["total_episodes"], videos)
    files = sorted(root.glob("data/*/*.parquet"))
    for row in episodes:
        path = _data_file(root, row)
        if path not in files:
            raise DatasetError(f"{path}: missing (episode {row['episode_index']}'s data file)")
    frames = sum(read_parquet(path, "data file", lambda parquet: parquet.metadata.num_rows) for path in files)
    if frames != info["total_frames"]:
        raise DatasetError(
            f"{info_path}: total_frames is {info['total_frames']}, the data files hold {frames} rows"
        )
    return LeRobotDataset(root, info, tasks, episodes)


def _check_features(info_path: Path, features: dict) -> None:
    """Every feature a dtype besman reads and a shape of whole numbers >= 1 (a column's: [n], its names
    as many if listed; a camera's: [height, width, channels], its name a folder's)."""
    for name, feature in features.items():
        shape = feature.get("shape") if isinstance(feature, dict) else None
        if (
            not isinstance(shape, list)
            or not all(type(n) is int and n >= 1 for n in shape)
            or not isinstance(feature.get("dtype"), str)
        ):
            raise DatasetError(
                f"{info_path}: features.{name} needs a dtype and a shape of whole numbers >= 1"
            )
        if fmt.is_video(feature):
            if len(shape) != 3 or name in ("", ".", "..") or "/" in name or "\0" in name:
                raise DatasetError(
                    f"{info_path}: features.{name}: a video needs a shape [height, width, channels] and a "
                    "name that can be a folder's"
                )
            continue
        if feature.get("dtype") not in fmt.SCALAR_TYPES:
            raise DatasetError(
                f"{info_path}: features.{name}: dtype {shown(feature.get('dtype'))} is not read by besman"
            )
        names = feature.get("names")
        if len(shape) != 1 or (isinstance(names, list) and len(names) != shape[0]):
            raise DatasetError(
                f"{info_path}: features.{name}: shape {shape} with {shown(names)} as names; besman reads a "
                "shape [n] with n names (or none)"
            )
    for name in fmt.DEFAULT_FEATURES:
        if name not in features:
            raise DatasetError(f"{info_path}: features has no {name!r}, a feature every LeRobot frame has")


def _tasks(path: Path) -> tuple[str, ...]:
    if not path.exists():
        raise DatasetError(f"{path}: missing (every dataset lists its tasks)")
    table = read_parquet(path, "tasks table", max_rows=fmt.MAX_INDEX)
    names = [n for n in ("task", "__index_level_0__") if n in table.column_names]
    if "task_index" not in table.column_names or not names:
        raise DatasetError(f"{path}: needs the columns task and task_index, has {table.column_names}")
    indices, texts = table["task_index"].to_pylist(), table[names[0]].to_pylist()
    numbered = all(type(i) is int for i in indices) and sorted(indices) == list(range(len(indices)))
    if not numbered or not all(isinstance(t, str) for t in texts):
        raise DatasetError(
            f"{path}: task_index must number the tasks 0 to {len(indices) - 1} and each task be a text, got "
            f"{shown(indices)}"
        )
    return tuple(text for _, text in sorted(zip(indices, texts, strict=True)))


def _episodes(root: Path, total: int, videos: list[str]) -> tuple[dict, ...]:
    """The episodes' rows, each with its data file's and its videos' indices (whole numbers from 0 to
    :data:`~besman.datasets.format.MAX_INDEX`) and its video files there, regular files."""
    files = sorted(root.glob("meta/episodes/*/*.parquet"))
    counted = sum(
        read_parquet(path, "episodes table", lambda parquet: parquet.metadata.num_rows) for path in files
    )
    if counted != total:  # before any is read: a stranger's table may hold millions of rows
        raise DatasetError(
            f"{root / 'meta/episodes'}: {counted} episodes; info.json's total_episodes is {total}"
        )
    rows = [row for path in files for row in read_parquet(path, "episodes table").to_pylist()]
    numbers = [row.get("episode_index") for row in rows]
    if numbers != list(range(total)):
        raise DatasetError(
            f"{root / 'meta/episodes'}: {len(rows)} episodes numbered {shown(numbers[:5])}...; info.json's "
            f"total_episodes is {total} (episodes 0 to N - 1 in order)"
        )
    for row in rows:
        where = f"{root / 'meta/episodes'}: episode {row['episode_index']}"
        if not _whole(row.get("length")):
            raise DatasetError(f"{where}: length {shown(row.get('length'))} is no whole number >= 0")
        for prefix in ("data", *(f"videos/{key}" for key in videos)):
            for key in (f"{prefix}/chunk_index", f"{prefix}/file_index"):
                if not _whole(row.get(key), fmt.MAX_INDEX):
                    raise DatasetError(
                        f"{where}: {key} {shown(row.get(key))} is no whole number from 0 to {fmt.MAX_INDEX}"
                    )
        for key in videos:
            path = root / fmt.VIDEO_PATH.format(
                video_key=key,
                chunk_index=row[f"videos/{key}/chunk_index"],
                file_index=row[f"videos/{key}/file_index"],
            )
            open_file(path, ANY_SIZE, what="video file", error=DatasetError).close()
    return tuple(rows)


def _whole(value, high: float = math.inf) -> bool:
    """Whether ``value`` is an int (no bool) from 0 to ``high``."""
    return type(value) is int and 0 <= value <= high
