"""Appending episodes to a LeRobot v3.0 dataset (:mod:`besman.datasets.format`), each append atomic.

:class:`DatasetWriter` is a dataset's one writer (:class:`~besman.core.writer_lock.WriterLock`) for as
long as it is open. An append builds the dataset's next state in a temporary folder beside it - every file
the episode does not change hard-linked, the changed ones (the current data file, the episodes table, the
tasks, the statistics, ``info.json``) and the episode's videos written anew - and exchanges that folder with
the dataset in one step (:func:`~besman.core.storage.exchange_folders`). So the dataset is always whole,
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
import stat
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from besman.core.errors import InputError
from besman.core.storage import (
    WriteError,
    exchange_folders,
    folder_beside,
    is_temporary,
    open_temporary,
    put_in_place,
    write_error,
)
from besman.core.validation import shown
from besman.core.writer_lock import WriterLock
from besman.datasets import format as fmt
from besman.datasets.reader import DatasetError, LeRobotDataset, read_dataset, read_parquet

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
        if type(self.fps) is not int or not 1 <= self.fps <= fmt.MAX_FPS:
            raise InputError(f"fps must be a whole number from 1 to {fmt.MAX_FPS}, got {shown(self.fps)}")
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


def dataset_folder(root: str | Path) -> Path:
    """The folder that the dataset ``--dataset root`` is written in: a link's target (the link stays a
    link), checked to be no file, and neither the working directory nor a folder holding it (an append
    puts a new folder in its place and removes the old one, the process's working directory with it)."""
    folder = Path(os.path.realpath(root))
    if folder.exists() and not folder.is_dir():
        raise InputError(f"--dataset {root}: a file, not a dataset folder")
    working = Path(os.path.realpath(Path.cwd()))
    if folder in (working, *working.parents):
        raise InputError(
            f"--dataset {root}: the working directory or a folder holding it; an append replaces the "
            "dataset's folder, so give it a folder of its own (e.g. ./dataset)"
        )
    return folder


class DatasetWriter:
    """The one writer of the dataset at ``root`` (made by the first append), for episodes of ``spec``; an
    existing dataset must have been made for the same spec (its fps, features and robot type). Every file,
    folder and link in the dataset's folder that is not the dataset's own stays there through the appends.
    """

    def __init__(self, root: str | Path, spec: DatasetSpec) -> None:
        self.root, self.spec = Path(root), spec
        self.folder = dataset_folder(root)  # the files are written there; messages name root
        self._lock = WriterLock(self.folder, "--dataset").acquire()
        try:
            for stale in self.folder.parent.iterdir() if self.folder.parent.is_dir() else ():
                if is_temporary(stale, of=self.folder.name) and stale.is_dir() and not stale.is_symlink():
                    shutil.rmtree(stale)  # a killed append's next state, or the old one
            _refuse_links(self.folder, self.root)
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
            if self.folder.exists() and any(self.folder.iterdir()):
                raise InputError(
                    f"--dataset {self.root}: a folder that is not a LeRobot dataset; give another"
                )
            return
        info, expected = self.dataset.info, self.spec.all_features
        for name, want in (("fps", self.spec.fps), ("robot_type", self.spec.robot_type)):
            if info.get(name) != want:
                raise InputError(
                    f"--dataset {self.root}: its {name} is {info.get(name)!r}, these episodes' {want!r}"
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
        statistics = [f"stats/{f}/{n}" for f in expected for n in ("min", "max", "mean", "std", "count")]
        for row in self.dataset.episodes:  # the dataset's statistics are merged from its episodes'
            missing = next((column for column in statistics if column not in row), None)
            if missing is not None:
                raise InputError(
                    f"--dataset {self.root}: episode {row['episode_index']} has no {missing} in "
                    "meta/episodes; an append merges every episode's statistics"
                )

    # -- appending ---------------------------------------------------------------------------------------

    def append(self, episode: Episode) -> int:
        """Appends ``episode`` (checked first: every feature, its shape, finite values, at least two
        frames, the facts of the dataset's other episodes) in one step; returns its index."""
        length = self._check(episode)
        index = self.episodes
        stage = folder_beside(self.folder)
        videos = []  # the episode's video files (through a linked folder: outside the stage)
        exchanged = False
        try:
            rows = list(self.dataset.episodes) if self.dataset is not None else []
            tasks = list(self.dataset.tasks) if self.dataset is not None else []
            if episode.task not in tasks:
                tasks.append(episode.task)
            frames = 0 if self.dataset is None else self.dataset.info["total_frames"]
            data_at = self._data_file(rows, length)
            changed = {fmt.INFO, fmt.STATS, fmt.TASKS, fmt.EPISODES_PATH.format(chunk_index=0, file_index=0)}
            changed.add(fmt.DATA_PATH.format(chunk_index=data_at[0], file_index=data_at[1]))
            video_at = {key: self._video_file(rows, key) for key in episode.videos}
            changed |= {
                fmt.VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file)
                for key, (chunk, file) in video_at.items()
            }
            if self.folder.exists():  # the first append too: files may have been put there since
                os.chmod(stage, stat.S_IMODE(self.folder.stat().st_mode))
                _link_into(self.folder, stage, changed, self.folder.stat().st_dev)
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
                chunk, file = video_at[key]
                videos.append(
                    stage / fmt.VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file)
                )
                encode_video(videos[-1], video, self.spec.fps)
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
            exchange_folders(stage, self.folder)
            exchanged = True
        except OSError as error:
            raise write_error(self.root, error) from error
        finally:
            if not exchanged:
                for path in videos:
                    path.unlink(missing_ok=True)
                shutil.rmtree(stage, ignore_errors=True)  # an unfinished next state
        self.dataset = LeRobotDataset(self.root, info, tuple(tasks), tuple(rows))  # as just written
        # The old state: what was put in the folder or taken out of it meanwhile (a run's log) follows.
        folders = {parent.as_posix() for path in changed for parent in Path(path).parents[:-1]}
        left = _move_back(stage, self.folder, changed, changed | folders) if stage.exists() else []
        if left:
            kept = self.folder.parent / f"{self.folder.name}.besman-kept-{time.strftime('%Y%m%d-%H%M%S')}"
            os.rename(stage, kept)
            raise WriteError(
                f"{self.root}: episode {index} was recorded, but {left[0]}"
                + (f" and {len(left) - 1} more" if len(left) > 1 else "")
                + f" changed in the folder meanwhile and could not be put back: they are in {kept}"
            )
        shutil.rmtree(stage, ignore_errors=True)
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
        current = self.folder / fmt.DATA_PATH.format(chunk_index=chunk, file_index=file)
        size = current.stat().st_size
        held = sum(
            r["length"] for r in rows if (r["data/chunk_index"], r["data/file_index"]) == (chunk, file)
        )
        if size + size / max(1, held) * length <= fmt.DATA_FILES_SIZE_IN_MB * 1e6:
            return chunk, file
        return fmt.chunk_and_file(chunk * fmt.CHUNKS_SIZE + file + 1)

    @staticmethod
    def _video_file(rows: list[dict], key: str) -> tuple[int, int]:
        """Where the episode's video of camera ``key`` goes: the file after the last one an episode has
        (besman's own datasets: file i for episode i; LeRobot's writer puts several episodes in a file)."""
        files = [
            r[f"videos/{key}/chunk_index"] * fmt.CHUNKS_SIZE + r[f"videos/{key}/file_index"] for r in rows
        ]
        return fmt.chunk_and_file(max(files, default=-1) + 1)

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
        earlier = []
        if (self.folder / relative).exists():
            earlier = read_parquet(self.folder / relative, "data file", _row_groups)
        with pq.ParquetWriter(stage / relative, schema) as writer:
            for group in earlier:
                writer.write_table(group.cast(schema))
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


def _row_groups(parquet: pq.ParquetFile) -> list[pa.Table]:
    return [parquet.read_row_group(group) for group in range(parquet.num_row_groups)]


def _refuse_links(folder: Path, root: Path) -> None:
    """Refuses a dataset whose ``meta/`` or ``data/`` holds a symbolic link: an append rewrites those in the
    dataset's next state, and writing through a link would change the live files (or another folder)
    before the exchange. Only ``videos/`` may live elsewhere: an append only adds files there."""
    for part in ("meta", "data"):
        inside = (
            Path(top, name) for top, folders, files in os.walk(folder / part) for name in (*folders, *files)
        )
        link = next((path for path in (folder / part, *inside) if path.is_symlink()), None)
        if link is not None:
            raise InputError(
                f"--dataset {root}: {link.relative_to(folder)} is a symbolic link; besman writes meta/ and "
                "data/ in the dataset's own folder (only videos/ may be linked): put the files back there"
            )


def _link_into(source: Path, target: Path, skip: set[str], device: int, relative: str = "") -> None:
    """Hard-links what is in the folder ``source`` into the new folder ``target`` (a symbolic link as
    itself, never followed; a folder made anew with the same permissions), but for the paths ``skip``
    (relative to the dataset). A mounted file system inside it is refused: no link crosses one."""
    for entry in os.scandir(source):
        there, name = target / entry.name, relative + entry.name
        if name in skip:
            continue
        status = entry.stat(follow_symlinks=False)
        if stat.S_ISDIR(status.st_mode):
            if status.st_dev != device:
                raise InputError(
                    f"{entry.path}: another file system mounted in the dataset; an append links every file "
                    "into the dataset's next state, and no link crosses file systems: mount it elsewhere "
                    "and put a symbolic link here"
                )
            there.mkdir()
            os.chmod(there, stat.S_IMODE(status.st_mode))
            _link_into(Path(entry.path), there, skip, device, f"{name}/")
        else:
            try:
                os.link(entry.path, there, follow_symlinks=False)
            except OSError as error:
                raise WriteError(
                    f"{entry.path}: cannot link it into the dataset's next state ({error})"
                ) from None


def _move_back(old: Path, folder: Path, skip: set[str], written: set[str], relative: str = "") -> list[str]:
    """After the exchange: what was put into the dataset's folder (``old`` now) while the append ran moves
    into its new state ``folder`` (a file replaced meanwhile replaces the linked one), and what was taken
    out of it is taken out of the new state; but for the paths ``skip`` (relative to the dataset), which
    the append wrote (``written``: those and the folders they are in). The paths that could not be put
    back (a file that became a folder or the other way round), relative to the dataset."""
    left = []
    for entry in os.scandir(folder):
        name = relative + entry.name
        if name not in written and not os.path.lexists(old / entry.name):  # removed meanwhile
            try:
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path)
                else:
                    os.unlink(entry.path)
            except OSError:
                left.append(name)
    for entry in os.scandir(old):
        there, name = folder / entry.name, relative + entry.name
        if name in skip or _same(entry, there):
            continue
        now_folder = entry.is_dir(follow_symlinks=False)
        if now_folder and there.is_dir() and not there.is_symlink():
            left += _move_back(Path(entry.path), there, skip, written, f"{name}/")
        elif not os.path.lexists(there) or now_folder == (there.is_dir() and not there.is_symlink()):
            try:
                os.replace(entry.path, there)
            except OSError:
                left.append(name)
        else:
            left.append(name)
    return left


def _same(entry: os.DirEntry, path: Path) -> bool:
    try:
        return entry.inode() == path.lstat().st_ino
    except FileNotFoundError:
        return False


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
    second frame, as LeRobot's encoder: frames are read at random); written whole or not at all (a
    dataset's linked videos folder is written in place)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = open_temporary(path)
    os.close(descriptor)
    try:
        _encode(temporary, frames, fps)
        put_in_place(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _encode(path: Path, frames: np.ndarray, fps: int) -> None:
    import av

    with av.open(str(path), "w", format="mp4") as container:
        stream = container.add_stream(VIDEO_CODEC, rate=fps, options={"g": "2", "crf": "23"})
        stream.width, stream.height, stream.pix_fmt = frames.shape[2], frames.shape[1], "yuv420p"
        stream.time_base = Fraction(1, fps)
        for i, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts, frame.time_base = i, Fraction(1, fps)
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


__all__ = ["DatasetError", "DatasetSpec", "DatasetWriter", "Episode", "dataset_folder", "encode_video"]
