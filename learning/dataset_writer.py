"""Appending episodes to a LeRobot v3.0 dataset (:mod:`besman.learning.dataset_format`), each append atomic.

:class:`DatasetWriter` is a dataset's one writer (:class:`~besman.skills.writer_lock.WriterLock`) for as
long as it is open. An append builds the dataset's next state in a temporary folder beside it - every file
the episode does not change hard-linked, the changed ones (the current data file, the episodes table, the
tasks, the statistics, ``info.json``) and the episode's videos written anew - and exchanges that folder with
the dataset in one step (:func:`~besman.skills.storage.exchange_folders`). So the dataset is always whole,
with or without the episode: a writer killed at any moment (``kill -9`` included) leaves it valid, and the
temporary folder it leaves is removed by the next writer.

Episodes accumulate in a data file until it would pass ``data_files_size_in_mb``, as LeRobot's writer
does; each camera's frames of an episode are one MP4 (H.264 through PyAV, ``yuv420p``; the episode's
``videos/<key>/from_timestamp`` is 0).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from besman.learning import dataset_format as fmt
from besman.learning.dataset_reader import DatasetError, LeRobotDataset, read_dataset
from besman.skills.errors import InputError
from besman.skills.storage import exchange_folders, folder_beside, write_error
from besman.skills.writer_lock import WriterLock

VIDEO_CODEC = "h264"  # LeRobot reads h264, hevc and AV1; H.264 encodes fastest on a CPU


@dataclass(frozen=True)
class DatasetSpec:
    """What every episode of a dataset has: ``fps``, its own ``features`` (LeRobot's ``{"dtype", "shape",
    "names"}``; a camera's dtype is ``video``, shape [height, width, 3]; the five default features are added)
    and ``robot_type``."""

    fps: int
    features: Mapping[str, dict]
    robot_type: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.fps, int) or self.fps < 1:
            raise InputError(f"fps must be a whole number >= 1, got {self.fps!r}")
        for name, feature in self.features.items():
            if name in fmt.DEFAULT_FEATURES:
                raise InputError(f"feature {name!r} is one of LeRobot's defaults; name it otherwise")
            shape = list(feature.get("shape", ()))
            if fmt.is_video(feature):
                if len(shape) != 3 or shape[2] != 3 or shape[0] % 2 or shape[1] % 2:
                    raise InputError(f"feature {name!r}: a video's shape is [height, width, 3], both even")
            elif feature.get("dtype") not in fmt.SCALAR_TYPES or len(shape) != 1 or shape[0] < 1:
                raise InputError(
                    f"feature {name!r}: dtype one of {', '.join(fmt.SCALAR_TYPES)} and shape [n], got "
                    f"{feature.get('dtype')!r} and {shape}"
                )

    @property
    def all_features(self) -> dict[str, dict]:
        """The features as ``info.json`` lists them: the dataset's own, then LeRobot's defaults."""
        return {**{name: dict(feature) for name, feature in self.features.items()}, **fmt.DEFAULT_FEATURES}


@dataclass(frozen=True)
class Episode:
    """One episode to append: the text of its ``task``, its ``frames`` (feature -> (T, n) values, or (T,)
    for shape [1]), its ``videos`` (camera -> (T, height, width, 3) uint8) and ``facts``: more columns of
    its row in the episodes table (the same names in every episode of a dataset, e.g. ``besman/seed``)."""

    task: str
    frames: Mapping[str, np.ndarray]
    videos: Mapping[str, np.ndarray] = field(default_factory=dict)
    facts: Mapping[str, Any] = field(default_factory=dict)


class DatasetWriter:
    """The one writer of the dataset at ``root`` (made by the first append), for episodes of ``spec``; an
    existing dataset must have been made for the same spec (its fps, features and robot type)."""

    def __init__(self, root: str | Path, spec: DatasetSpec) -> None:
        self.root, self.spec = Path(root), spec
        if self.root.exists() and not self.root.is_dir():
            raise InputError(f"--dataset {self.root}: a file, not a dataset folder")
        self._lock = WriterLock(self.root, "--dataset").acquire()
        try:
            for stale in self.root.absolute().parent.glob(f".{self.root.name}.besman-*.tmp"):
                if stale.is_dir() and not stale.is_symlink():  # a killed append's next state, or old one
                    shutil.rmtree(stale)
            self.dataset = read_dataset(self.root) if (self.root / fmt.INFO).exists() else None
            self._check_matches()
        except BaseException:
            self._lock.release()
            raise

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, *_) -> None:
        self.close()

    def close(self) -> None:
        self._lock.release()

    @property
    def episodes(self) -> int:
        return 0 if self.dataset is None else self.dataset.info["total_episodes"]

    def _check_matches(self) -> None:
        if self.dataset is None:
            if self.root.exists() and any(self.root.iterdir()):
                raise InputError(
                    f"--dataset {self.root}: a folder that is not a LeRobot dataset; give another"
                )
            return
        info, expected = self.dataset.info, self.spec.all_features
        for name, want in (("fps", self.spec.fps), ("robot_type", self.spec.robot_type)):
            if info[name] != want:
                raise InputError(
                    f"--dataset {self.root}: its {name} is {info[name]!r}, these episodes' {want!r}"
                )
        have = {
            name: {k: f.get(k) for k in ("dtype", "shape", "names")} for name, f in info["features"].items()
        }
        want = {name: {k: f.get(k) for k in ("dtype", "shape", "names")} for name, f in expected.items()}
        if have != want:
            differing = sorted(set(have) ^ set(want)) or [n for n in want if have[n] != want[n]]
            raise InputError(
                f"--dataset {self.root}: recorded with other features ({', '.join(differing)} differ); "
                "record these episodes into another dataset"
            )

    # -- appending ---------------------------------------------------------------------------------------

    def append(self, episode: Episode) -> int:
        """Appends ``episode`` (checked first: every feature, its shape, finite values, at least two
        frames, the facts of the dataset's other episodes) in one step; returns its index."""
        length = self._check(episode)
        index = self.episodes
        stage = folder_beside(self.root)
        try:
            rows = list(self.dataset.episodes) if self.dataset is not None else []
            tasks = list(self.dataset.tasks) if self.dataset is not None else []
            if episode.task not in tasks:
                tasks.append(episode.task)
            frames = 0 if self.dataset is None else self.dataset.info["total_frames"]
            data_at = self._data_file(rows, length)
            changed = {fmt.INFO, fmt.STATS, fmt.TASKS, fmt.EPISODES_PATH.format(chunk_index=0, file_index=0)}
            changed.add(fmt.DATA_PATH.format(chunk_index=data_at[0], file_index=data_at[1]))
            self._link_unchanged(stage, changed)
            columns = self._columns(episode, index, frames, tasks.index(episode.task), length)
            self._write_data(stage, data_at, columns)
            row = {
                "episode_index": index,
                "tasks": [episode.task],
                "length": length,
                "data/chunk_index": data_at[0],
                "data/file_index": data_at[1],
                "dataset_from_index": frames,
                "dataset_to_index": frames + length,
            }
            statistics = {name: fmt.statistics(values) for name, values in columns.items()}
            for key, video in episode.videos.items():
                chunk, file = fmt.chunk_and_file(index)
                path = stage / fmt.VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file)
                encode_video(path, video, self.spec.fps)
                row |= {
                    f"videos/{key}/chunk_index": chunk,
                    f"videos/{key}/file_index": file,
                    f"videos/{key}/from_timestamp": 0.0,
                    f"videos/{key}/to_timestamp": length / self.spec.fps,
                }
                statistics[key] = fmt.image_statistics(video)
            for feature in self.spec.all_features:
                for name, value in statistics[feature].items():
                    row[f"stats/{feature}/{name}"] = np.asarray(value).tolist()
            row |= {"meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0, **dict(episode.facts)}
            rows.append(row)
            info = self._write_meta(stage, rows, tasks, frames + length)
            exchange_folders(stage, self.root)
        except OSError as error:
            raise write_error(self.root, error) from error
        finally:
            # The old state (after the exchange) or an unfinished one.
            shutil.rmtree(stage, ignore_errors=True)
        self.dataset = LeRobotDataset(self.root, info, tuple(tasks), tuple(rows))  # as just written
        return index

    def _check(self, episode: Episode) -> int:
        where = f"episode {self.episodes} of {self.root}"
        features = self.spec.features
        missing = sorted(set(features) - set(episode.frames) - set(episode.videos))
        unknown = sorted((set(episode.frames) | set(episode.videos)) - set(features))
        if missing or unknown:
            raise InputError(
                f"{where}: features missing: {missing or 'none'}; not of the dataset: {unknown or 'none'}"
            )
        lengths = {len(np.asarray(v)) for v in (*episode.frames.values(), *episode.videos.values())}
        if len(lengths) != 1 or min(lengths) < 2:
            raise InputError(
                f"{where}: every feature needs the same number (>= 2) of frames, got {sorted(lengths)}"
            )
        (length,) = lengths
        for name, values in episode.frames.items():
            shape = (length, *features[name]["shape"])
            if np.shape(values) not in (shape, shape[:1] if shape[1:] == (1,) else shape):
                raise InputError(f"{where}: {name} has shape {np.shape(values)}, the dataset's {list(shape)}")
            if not np.isfinite(np.asarray(values, dtype=float)).all():
                raise InputError(f"{where}: {name} has values that are not finite (NaN or infinite)")
        for name, video in episode.videos.items():
            if np.shape(video) != (length, *features[name]["shape"]) or np.asarray(video).dtype != np.uint8:
                raise InputError(
                    f"{where}: {name} must be uint8 of shape {[length, *features[name]['shape']]}"
                )
        if self.dataset is not None and self.dataset.episodes:
            facts = set(self.dataset.facts(0))
            if facts != set(episode.facts):
                raise InputError(f"{where}: facts {sorted(episode.facts)}, the dataset's {sorted(facts)}")
        return length

    def _data_file(self, rows: list[dict], length: int) -> tuple[int, int]:
        """Where the episode's rows go: the last data file, unless it would pass the size limit."""
        if not rows:
            return 0, 0
        chunk, file = rows[-1]["data/chunk_index"], rows[-1]["data/file_index"]
        current = self.root / fmt.DATA_PATH.format(chunk_index=chunk, file_index=file)
        size = current.stat().st_size
        held = sum(
            r["length"] for r in rows if (r["data/chunk_index"], r["data/file_index"]) == (chunk, file)
        )
        if size + size / max(1, held) * length <= fmt.DATA_FILES_SIZE_IN_MB * 1e6:
            return chunk, file
        return fmt.chunk_and_file(chunk * fmt.CHUNKS_SIZE + file + 1)

    def _link_unchanged(self, stage: Path, changed: set[str]) -> None:
        if self.dataset is None:
            return
        for folder, _, files in os.walk(self.root):
            for name in files:
                source = Path(folder, name)
                relative = source.relative_to(self.root).as_posix()
                if relative not in changed:
                    (stage / relative).parent.mkdir(parents=True, exist_ok=True)
                    os.link(source, stage / relative)

    def _columns(self, episode: Episode, index: int, first: int, task_index: int, length: int) -> dict:
        frames = np.arange(length)
        defaults = {
            "timestamp": (frames / self.spec.fps).astype(np.float32),
            "frame_index": frames.astype(np.int64),
            "episode_index": np.full(length, index, dtype=np.int64),
            "index": (first + frames).astype(np.int64),
            "task_index": np.full(length, task_index, dtype=np.int64),
        }
        features = self.spec.all_features
        own = {
            name: np.asarray(values, dtype=features[name]["dtype"]).reshape(length, -1).squeeze(-1)
            if features[name]["shape"] == [1]
            else np.asarray(values, dtype=features[name]["dtype"])
            for name, values in episode.frames.items()
        }
        return {name: (own | defaults)[name] for name in features if not fmt.is_video(features[name])}

    def _write_data(self, stage: Path, at: tuple[int, int], columns: dict) -> None:
        """The data file ``at``: its episodes so far (one row group each), then this one's."""
        relative = fmt.DATA_PATH.format(chunk_index=at[0], file_index=at[1])
        features, schema = self.spec.all_features, fmt.schema(self.spec.all_features)
        table = pa.Table.from_arrays(
            [fmt.column(columns[n], features[n]) for n in schema.names], schema=schema
        )
        (stage / relative).parent.mkdir(parents=True, exist_ok=True)
        with pq.ParquetWriter(stage / relative, schema) as writer:
            if (self.root / relative).exists():
                earlier = pq.ParquetFile(self.root / relative)
                for group in range(earlier.num_row_groups):
                    writer.write_table(earlier.read_row_group(group).cast(schema))
            writer.write_table(table)

    def _write_meta(self, stage: Path, rows: list[dict], tasks: list[str], frames: int) -> dict:
        episodes = stage / fmt.EPISODES_PATH.format(chunk_index=0, file_index=0)
        episodes.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.Table.from_pylist(rows), episodes)
        pq.write_table(fmt.tasks_table(tasks), stage / fmt.TASKS)
        features = self.spec.all_features
        for key in (name for name, feature in features.items() if fmt.is_video(feature)):
            features[key]["info"] = video_info(self.spec.features[key], self.spec.fps)
        statistics = {
            feature: fmt.merged_statistics(
                [
                    {
                        name: np.asarray(row[f"stats/{feature}/{name}"])
                        for name in (*fmt.QUANTILES, "min", "max", "mean", "std", "count")
                    }
                    for row in rows
                ]
            )
            for feature in features
        }
        (stage / fmt.STATS).write_text(json.dumps(fmt.as_json(statistics), indent=4) + "\n")
        info = fmt.info_document(
            robot_type=self.spec.robot_type,
            fps=self.spec.fps,
            features=features,
            episodes=len(rows),
            frames=frames,
            tasks=len(tasks),
        )
        (stage / fmt.INFO).write_text(json.dumps(info, indent=4) + "\n")
        return info


def video_info(feature: dict, fps: int) -> dict:
    """A camera feature's ``info`` in ``info.json``, as LeRobot's writer probes it from the MP4."""
    height, width, _ = feature["shape"]
    return {
        "video.height": height,
        "video.width": width,
        "video.codec": VIDEO_CODEC,
        "video.pix_fmt": "yuv420p",
        "video.is_depth_map": False,
        "video.fps": fps,
        "video.channels": 3,
        "has_audio": False,
    }


def encode_video(path: Path, frames: np.ndarray, fps: int) -> None:
    """``frames`` (T, height, width, 3 uint8) as an H.264 MP4, frame i at i / fps s (a keyframe every
    second frame, as LeRobot's encoder: frames are read at random)."""
    import av

    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as container:
        stream = container.add_stream(VIDEO_CODEC, rate=fps, options={"g": "2", "crf": "23"})
        stream.width, stream.height, stream.pix_fmt = frames.shape[2], frames.shape[1], "yuv420p"
        stream.time_base = Fraction(1, fps)
        for i, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts, frame.time_base = i, Fraction(1, fps)
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


__all__ = ["DatasetError", "DatasetSpec", "DatasetWriter", "Episode", "encode_video"]
