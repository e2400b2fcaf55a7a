"""LeRobot's dataset format v3.0, the parts besman writes and reads (with ``pyarrow``; the ``lerobot`` package
itself needs Python >= 3.12 and is not used).

A dataset is a folder::

    meta/info.json                                 the format's version, fps, totals, paths and features
    meta/stats.json                                per feature: min, max, mean, std, count, q01 ... q99
    meta/tasks.parquet                             the tasks' texts (pandas index "task") and task_index
    meta/episodes/chunk-000/file-000.parquet       one row per episode: its tasks, length, where its rows
                                                   and videos are, its statistics (``stats/<feature>/...``)
    data/chunk-000/file-000.parquet                one row per frame, episodes one after another
    videos/<key>/chunk-000/file-000.mp4            one camera's frames (besman: one file per episode)

Every frame has the five default features (``timestamp`` = frame_index / fps, ``frame_index`` from 0 in
each episode, ``episode_index``, ``index`` over the whole dataset, ``task_index``) after the dataset's own.
A feature of shape ``[1]`` is a scalar column, one of shape ``[n]`` a fixed-size list; a video feature is no
column of the data but an MP4 per camera. The sources: huggingface/lerobot's ``datasets/utils.py``,
``dataset_metadata.py`` and ``compute_stats.py`` (v0.4.x, the releases that write v3.0).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pyarrow as pa

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # files per chunk folder
DATA_FILES_SIZE_IN_MB = 100  # a data file takes episodes until it would pass this
VIDEO_FILES_SIZE_IN_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
INFO, STATS, TASKS = "meta/info.json", "meta/stats.json", "meta/tasks.parquet"
MAX_FPS = 100_000  # frames per second: beyond any recording (and a float, as timestamps are)
MAX_INDEX = 1_000_000  # a chunk's or file's index: a billion files of a kind

DEFAULT_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
SCALAR_TYPES = {
    "float32": pa.float32(),
    "float64": pa.float64(),
    "int64": pa.int64(),
    "int32": pa.int32(),
    "bool": pa.bool_(),
}


def chunk_and_file(position: int) -> tuple[int, int]:
    """The chunk and file index of the ``position``-th file of a kind."""
    return divmod(position, CHUNKS_SIZE)


def is_video(feature: dict) -> bool:
    return feature["dtype"] == "video"


def arrow_type(feature: dict) -> pa.DataType:
    """The column type of a (non-video) feature: a scalar for shape [1], a fixed-size list for [n]."""
    base, shape = SCALAR_TYPES[feature["dtype"]], list(feature["shape"])
    return base if shape == [1] else pa.list_(base, shape[0])


def schema(features: dict[str, dict]) -> pa.Schema:
    """The data files' schema, with the Hugging Face ``datasets`` features that LeRobot's writer puts in the
    metadata (readers that open the files with ``datasets`` take the columns' shapes from them)."""

    def described(feature: dict) -> dict:
        value = {"dtype": feature["dtype"], "_type": "Value"}
        return (
            value
            if list(feature["shape"]) == [1]
            else {"feature": value, "length": feature["shape"][0], "_type": "List"}
        )

    columns = {name: feature for name, feature in features.items() if not is_video(feature)}
    metadata = {"info": {"features": {name: described(feature) for name, feature in columns.items()}}}
    return pa.schema(
        [pa.field(name, arrow_type(feature)) for name, feature in columns.items()],
        metadata={b"huggingface": json.dumps(metadata).encode()},
    )


def column(values: np.ndarray, feature: dict) -> pa.Array:
    """A feature's (T,) or (T, n) values as its column."""
    kind = arrow_type(feature)
    if pa.types.is_fixed_size_list(kind):
        flat = pa.array(np.ascontiguousarray(values).reshape(-1), kind.value_type)
        return pa.FixedSizeListArray.from_arrays(flat, kind.list_size)
    return pa.array(values, kind)


def values(array: pa.ChunkedArray | pa.Array, feature: dict) -> np.ndarray:
    """A column back as (T,) or (T, n) values of the feature's dtype."""
    array = array.combine_chunks() if isinstance(array, pa.ChunkedArray) else array
    dtype = np.dtype(feature["dtype"])
    if pa.types.is_fixed_size_list(array.type):
        return array.flatten().to_numpy(zero_copy_only=False).astype(dtype).reshape(len(array), -1)
    return array.to_numpy(zero_copy_only=False).astype(dtype)


def statistics(frames: np.ndarray) -> dict[str, np.ndarray]:
    """An episode's statistics of one feature, over its frames (each of the feature's shape)."""
    data = np.asarray(frames, dtype=np.float64).reshape(len(frames), -1)
    found = {
        "min": data.min(axis=0),
        "max": data.max(axis=0),
        "mean": data.mean(axis=0),
        "std": data.std(axis=0),
        "count": np.array([len(data)]),
    }
    return found | {name: np.quantile(data, q, axis=0) for name, q in QUANTILES.items()}


def image_statistics(frames: np.ndarray) -> dict[str, np.ndarray]:
    """A camera's statistics per colour channel, scaled to [0, 1], of shape (3, 1, 1) as LeRobot's."""
    found = statistics(np.asarray(frames).reshape(-1, frames.shape[-1]) / 255.0)
    return {
        name: np.array([len(frames)]) if name == "count" else value.reshape(-1, 1, 1)
        for name, value in found.items()
    }


def merged_statistics(episodes: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The dataset's statistics of a feature from its episodes': min, max, mean and std exact (counts as
    weights, the variances pooled), the quantiles their count-weighted means (as LeRobot's aggregation: the
    frames are not read again)."""
    counts = np.array([float(e["count"][0]) for e in episodes])
    weights = (counts / counts.sum()).reshape(-1, *([1] * np.ndim(episodes[0]["mean"])))
    means = np.array([e["mean"] for e in episodes])
    mean = (weights * means).sum(axis=0)
    variance = (weights * (np.array([e["std"] for e in episodes]) ** 2 + (means - mean) ** 2)).sum(axis=0)
    merged = {
        "min": np.min([e["min"] for e in episodes], axis=0),
        "max": np.max([e["max"] for e in episodes], axis=0),
        "mean": mean,
        "std": np.sqrt(variance),
        "count": np.array([int(counts.sum())]),
    }
    return merged | {
        name: (weights * np.array([e[name] for e in episodes])).sum(axis=0) for name in QUANTILES
    }


def tasks_table(tasks: list[str]) -> pa.Table:
    """``meta/tasks.parquet``: what pandas writes for a frame of ``task_index`` indexed by ``task`` (LeRobot
    reads it with pandas and looks tasks up in the index), written without pandas."""
    pandas = {
        "index_columns": ["task"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {
                "name": "task",
                "field_name": "task",
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": None,
            },
        ],
        "creator": {"library": "pyarrow", "version": "14.0.0"},
        "pandas_version": "2.2.3",
    }
    table = pa.table(
        {"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())}
    )
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas).encode()})


def info_document(
    *, robot_type: str | None, fps: int, features: dict[str, dict], episodes: int, frames: int, tasks: int
) -> dict[str, Any]:
    """``meta/info.json``, its keys in LeRobot's order."""
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": tasks,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
        "fps": fps,
        "splits": {"train": f"0:{episodes}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if any(is_video(f) for f in features.values()) else None,
        "features": features,
    }


def as_json(statistics: dict[str, dict[str, np.ndarray]]) -> dict:
    return {
        feature: {name: np.asarray(v).tolist() for name, v in found.items()}
        for feature, found in statistics.items()
    }
