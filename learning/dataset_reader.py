"""Reading a LeRobot v3.0 dataset (:mod:`besman.learning.dataset_format`): its metadata whole, an episode's
frames when asked. Everything is checked as it is read; a problem raises :class:`DatasetError` naming the
file and the field."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from besman.learning import dataset_format as fmt
from besman.skills.errors import BesmanError
from besman.skills.storage import read_json

# The episodes table's columns that LeRobot defines; any other (``besman/seed``) is a fact of the episode.
LEROBOT_COLUMNS = ("episode_index", "tasks", "length", "dataset_from_index", "dataset_to_index")
LEROBOT_PREFIXES = ("data/", "videos/", "stats/", "meta/")


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
        (T, n) values of the feature's dtype, in frame order."""
        if not 0 <= episode < len(self.episodes):
            raise DatasetError(f"{self.root}: no episode {episode} (it has {len(self.episodes)})")
        row = self.episodes[episode]
        relative = self.info["data_path"].format(
            chunk_index=row["data/chunk_index"], file_index=row["data/file_index"]
        )
        path = self.root / relative
        try:
            status = path.stat()
        except FileNotFoundError:
            raise DatasetError(f"{path}: missing (episode {episode}'s data file)") from None
        table = _data_table(path, status.st_ino, status.st_mtime_ns)
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
                raise DatasetError(f"{self.root / relative}: no column {name!r}, a feature of info.json")
            columns[name] = fmt.values(rows[name], feature)
        order = np.argsort(columns["frame_index"], kind="stable")
        return {name: values[order] for name, values in columns.items()}


@functools.lru_cache(maxsize=4)
def _data_table(path: Path, inode: int, modified: int) -> pa.Table:
    """A data file, read once while it is the same file (an append puts a new one in its place)."""
    try:
        return pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as error:
        raise DatasetError(f"{path}: cannot read it as parquet ({error})") from None


def read_dataset(root: str | Path) -> LeRobotDataset:
    """The dataset at ``root``, its metadata checked: the format's version, fps, features, the tasks, the
    episodes (numbered 0 to N - 1, as many as ``total_episodes``) and the frames' count."""
    root = Path(root)
    info_path = root / fmt.INFO
    if not info_path.is_file():
        raise DatasetError(f"{root}: not a LeRobot dataset (no {fmt.INFO})")
    info = read_json(info_path, DatasetError)
    version = info.get("codebase_version")
    if version != fmt.CODEBASE_VERSION:
        raise DatasetError(
            f"{info_path}: codebase_version {version!r}; besman reads {fmt.CODEBASE_VERSION} (convert an "
            "older dataset with LeRobot's convert_dataset_v21_to_v30)"
        )
    for key, kind in (
        ("fps", int),
        ("features", dict),
        ("total_episodes", int),
        ("total_frames", int),
        ("data_path", str),
    ):
        if not isinstance(info.get(key), kind) or isinstance(info.get(key), bool):
            raise DatasetError(f"{info_path}: {key} must be {kind.__name__}, got {info.get(key)!r}")
    if info["fps"] < 1:
        raise DatasetError(f"{info_path}: fps must be >= 1, got {info['fps']}")
    for name, feature in info["features"].items():
        if not isinstance(feature, dict) or not isinstance(feature.get("shape"), list):
            raise DatasetError(f"{info_path}: features.{name} needs a dtype and a shape")
        if not fmt.is_video(feature) and feature.get("dtype") not in fmt.SCALAR_TYPES:
            raise DatasetError(
                f"{info_path}: features.{name}: dtype {feature.get('dtype')!r} is not read by besman"
            )
    for name in fmt.DEFAULT_FEATURES:
        if name not in info["features"]:
            raise DatasetError(f"{info_path}: features has no {name!r}, a feature every LeRobot frame has")
    tasks = _tasks(root / fmt.TASKS)
    episodes = _episodes(root, info_path, info["total_episodes"])
    frames = sum(pq.ParquetFile(path).metadata.num_rows for path in sorted(root.glob("data/*/*.parquet")))
    if frames != info["total_frames"]:
        raise DatasetError(
            f"{info_path}: total_frames is {info['total_frames']}, the data files hold {frames} rows"
        )
    return LeRobotDataset(root, info, tasks, episodes)


def _tasks(path: Path) -> tuple[str, ...]:
    if not path.is_file():
        raise DatasetError(f"{path}: missing (every dataset lists its tasks)")
    table = pq.read_table(path)
    names = [n for n in ("task", "__index_level_0__") if n in table.column_names]
    if "task_index" not in table.column_names or not names:
        raise DatasetError(f"{path}: needs the columns task and task_index, has {table.column_names}")
    indices, texts = table["task_index"].to_pylist(), table[names[0]].to_pylist()
    if sorted(indices) != list(range(len(indices))):
        raise DatasetError(f"{path}: task_index must number the tasks 0 to {len(indices) - 1}, got {indices}")
    return tuple(text for _, text in sorted(zip(indices, texts, strict=True)))


def _episodes(root: Path, info_path: Path, total: int) -> tuple[dict, ...]:
    files = sorted(root.glob("meta/episodes/*/*.parquet"))
    rows = [row for path in files for row in pq.read_table(path).to_pylist()]
    numbers = [row.get("episode_index") for row in rows]
    if numbers != list(range(len(rows))) or len(rows) != total:
        raise DatasetError(
            f"{root / 'meta/episodes'}: {len(rows)} episodes numbered {numbers[:5]}...; info.json's "
            f"total_episodes is {total} (episodes 0 to N - 1 in order)"
        )
    for row in rows:
        for key in ("length", "data/chunk_index", "data/file_index"):
            if not isinstance(row.get(key), int):
                raise DatasetError(
                    f"{root / 'meta/episodes'}: episode {row['episode_index']} has no whole {key}"
                )
    return tuple(rows)
