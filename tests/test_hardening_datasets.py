"""Issue 52, datasets: a stranger's dataset is safe to read (LeRobot's own paths only, every file a regular
file, every field bounded and checked against the data) and an append never loses what the user keeps in
the dataset's folder (files put there, links, a link to the dataset itself)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import run_cli

from besman.core.errors import InputError
from besman.core.storage import WriteError
from besman.datasets import format as fmt
from besman.datasets.reader import DatasetError, read_dataset
from besman.datasets.writer import DatasetSpec, DatasetWriter, Episode

CAMERA = "observation.images.cam"
FEATURES = {
    "observation.state": {"dtype": "float32", "shape": [3], "names": ["a", "b", "c"]},
    CAMERA: {"dtype": "video", "shape": [16, 16, 3], "names": ["height", "width", "channels"]},
}
SPEC = DatasetSpec(fps=10, features=FEATURES, robot_type="arm")
DATA = fmt.DATA_PATH.format(chunk_index=0, file_index=0)
EPISODES = fmt.EPISODES_PATH.format(chunk_index=0, file_index=0)


def video(index: int, file: int | None = None) -> str:
    return fmt.VIDEO_PATH.format(video_key=CAMERA, chunk_index=0, file_index=index if file is None else file)


def episode(seed: int) -> Episode:
    rng = np.random.default_rng(seed)
    frames = {"observation.state": rng.normal(size=(4, 3))}
    images = {CAMERA: rng.integers(0, 255, size=(4, 16, 16, 3), dtype=np.uint8)}
    return Episode("move", frames, images, {"besman/seed": seed})


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("made") / "d"
    with DatasetWriter(root, SPEC) as writer:
        writer.append(episode(0))
        writer.append(episode(1))
    return root


@pytest.fixture
def dataset(made, tmp_path) -> Path:
    """Two episodes of four frames with a 16 x 16 camera, a copy of its own."""
    return Path(shutil.copytree(made, tmp_path / "d", symlinks=True))


def contents(folder: Path) -> dict:
    """Every file's bytes and every link's target below ``folder`` (links not followed)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        key = str(path.relative_to(folder))
        if path.is_symlink():
            found[key] = os.readlink(path)
        elif path.is_file():
            found[key] = path.read_bytes()
    return found


def edit_info(root: Path, **changes) -> None:
    info = json.loads((root / fmt.INFO).read_text())
    (root / fmt.INFO).write_text(json.dumps(info | changes))


def edit_table(path: Path, **columns) -> None:
    table = pq.read_table(path)
    for name, values in columns.items():
        position = table.column_names.index(name)
        table = table.set_column(position, name, pa.array(values, table.schema.field(name).type))
    pq.write_table(table, path)


def one_line_error(capsys, *argv: str) -> str:
    code, _, err = run_cli(capsys, *argv)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, (code, err)
    return err


# -- finding 1: LeRobot's two paths, never a stranger's ----------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("data_path", "/etc/hostname"),
        ("data_path", "{chunk_index.__class__.__init__.__globals__}"),
        ("data_path", "data/{chunk_index:0100000000d}.parquet"),
        ("data_path", "../elsewhere/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"),
        ("video_path", "/tmp/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"),
        ("video_path", None),
    ],
)
def test_only_lerobots_paths_are_read(dataset, capsys, key, value):
    edit_info(dataset, **{key: value})
    with pytest.raises(DatasetError, match=f"{fmt.INFO}: {key} .* is not LeRobot's"):
        read_dataset(dataset)
    assert len(one_line_error(capsys, "dataset", "show", str(dataset)).replace(str(dataset), "")) < 300


@pytest.mark.parametrize(
    ("column", "value"),
    [("data/chunk_index", -1), ("data/file_index", 10**12), (f"videos/{CAMERA}/file_index", -5)],
)
def test_file_indices_of_the_episodes_table_are_bounded(dataset, column, value):
    edit_table(dataset / EPISODES, **{column: [0, value]})
    with pytest.raises(DatasetError, match=f"episode 1: {column} {value} .*no whole number from 0"):
        read_dataset(dataset)


def test_a_video_name_that_leaves_the_videos_folder_is_refused(dataset):
    info = json.loads((dataset / fmt.INFO).read_text())
    info["features"]["../../outside"] = info["features"].pop(CAMERA)
    (dataset / fmt.INFO).write_text(json.dumps(info))
    with pytest.raises(DatasetError, match=r"features\.\.\./\.\./outside: a video needs .* a folder's"):
        read_dataset(dataset)


# -- findings 3, 4 and 5: an append keeps what is in the folder, links as links ----------------------------


def test_files_put_in_the_folder_before_and_during_an_append_stay(tmp_path, monkeypatch):
    import besman.datasets.writer as writer_module

    root = tmp_path / "new"
    exchange = writer_module.exchange_folders

    def meanwhile(stage, folder):
        (folder / "late.txt").write_text("written while the append ran")
        (folder / "notes").mkdir()
        (folder / "run.jsonl").write_text("the log, replaced")  # a new file in its place
        exchange(stage, folder)

    with DatasetWriter(root, SPEC) as writer:
        root.mkdir()  # what `besman run --dataset NEW --log NEW/run.jsonl` does during the run
        (root / "run.jsonl").write_text("the log")
        writer.append(episode(0))
        monkeypatch.setattr(writer_module, "exchange_folders", meanwhile)
        writer.append(episode(1))
    assert (root / "run.jsonl").read_text() == "the log, replaced"
    assert (root / "late.txt").exists() and (root / "notes").is_dir()
    assert read_dataset(root).info["total_episodes"] == 2 and not list(tmp_path.glob(".new.besman-*"))


def test_a_runs_log_inside_the_new_dataset_survives(tmp_path, capsys):
    root = tmp_path / "new"
    code, _, err = run_cli(
        capsys, "demo", "pick-place", "--seed", "2", "--dataset", str(root), "--log", str(root / "run.jsonl")
    )
    assert code == 0, err
    assert (root / "run.jsonl").stat().st_size > 0 and read_dataset(root).info["total_episodes"] == 1
    err = one_line_error(capsys, "demo", "pick-place", "--dataset", str(root), "--log", str(root))
    assert f"--log {root}: the same path as --dataset" in err


def test_a_linked_videos_folder_and_linked_files_stay_links(dataset, tmp_path, monkeypatch):
    import besman.datasets.writer as writer_module

    big = tmp_path / "big-disk" / "videos"
    big.parent.mkdir()
    shutil.move(dataset / "videos", big)
    (dataset / "videos").symlink_to(big)
    (tmp_path / "README").write_text("mine")
    (dataset / "README").symlink_to(tmp_path / "README")
    before = contents(big)
    with DatasetWriter(dataset, SPEC) as writer:
        assert writer.append(episode(2)) == 2
    assert os.readlink(dataset / "videos") == str(big) and os.readlink(dataset / "README") == str(
        tmp_path / "README"
    )
    assert contents(big).items() >= before.items() and (big / video(2).removeprefix("videos/")).is_file()
    read_dataset(dataset)  # every episode's video is there
    # A failed append leaves everything as it was, the linked folder too (its new video removed).
    before, before_big = contents(dataset), contents(big)

    def failing(*_):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(writer_module, "exchange_folders", failing)
    with DatasetWriter(dataset, SPEC) as writer, pytest.raises(WriteError, match="No space left"):
        writer.append(episode(3))
    assert contents(dataset) == before and contents(big) == before_big


def test_an_append_never_replaces_another_episodes_video(dataset):
    # LeRobot's writer numbers video files by its own rule: episode 1's may be any file.
    os.rename(dataset / video(1), dataset / video(2))
    edit_table(dataset / EPISODES, **{f"videos/{CAMERA}/file_index": [0, 2]})
    kept = (dataset / video(2)).read_bytes()
    with DatasetWriter(dataset, SPEC) as writer:
        writer.append(episode(2))
    assert (dataset / video(2)).read_bytes() == kept and (dataset / video(3)).is_file()
    assert read_dataset(dataset).episodes[2][f"videos/{CAMERA}/file_index"] == 3


def test_a_missing_or_special_video_file_is_refused(dataset, capsys):
    (dataset / video(0)).unlink()
    with pytest.raises(DatasetError, match=f"{dataset / video(0)}: no such file"):
        read_dataset(dataset)
    one_line_error(capsys, "dataset", "show", str(dataset))
    os.mkfifo(dataset / video(0))
    with pytest.raises(DatasetError, match=f"{dataset / video(0)}: a FIFO, not a video file"):
        read_dataset(dataset)


def test_a_link_to_the_dataset_stays_a_link(dataset, tmp_path):
    link = tmp_path / "link"
    link.symlink_to(dataset)
    with DatasetWriter(link, SPEC) as writer:
        assert writer.append(episode(2)) == 2
    assert link.is_symlink() and read_dataset(dataset).info["total_episodes"] == 3
    assert not [p for p in tmp_path.iterdir() if ".besman-" in p.name]


# -- findings 7 and 11: special and damaged files, one line naming the file --------------------------------


@pytest.mark.parametrize("name", [DATA, EPISODES, fmt.TASKS])
def test_a_table_linked_to_dev_zero_is_refused(dataset, name):
    (dataset / name).unlink()
    (dataset / name).symlink_to("/dev/zero")
    with pytest.raises(DatasetError, match=f"{dataset / name}: a character device"):
        read_dataset(dataset)


def test_a_fifo_as_a_data_file_is_refused_at_once(dataset):
    (dataset / DATA).unlink()
    os.mkfifo(dataset / DATA)
    result = subprocess.run(  # in a process of its own: the reader once blocked in pyarrow for ever
        [sys.executable, "-m", "besman", "dataset", "show", str(dataset)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2 and result.stderr == (
        f"besman: error: {dataset / DATA}: a FIFO, not a data file; besman reads only regular files\n"
    )


def test_a_truncated_data_file_is_named(dataset):
    data = (dataset / DATA).read_bytes()
    (dataset / DATA).write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match=f"{dataset / DATA}: cannot read it as parquet"):
        read_dataset(dataset)


def test_values_that_are_not_finite_name_the_dataset_episode_and_feature(dataset):
    table = pq.read_table(dataset / DATA)
    state = table["observation.state"].combine_chunks()
    flat = state.flatten().to_numpy().copy()
    flat[len(flat) - 2] = np.nan  # in the last frame, of episode 1
    nan = pa.FixedSizeListArray.from_arrays(pa.array(flat, pa.float32()), 3)
    table = table.set_column(table.column_names.index("observation.state"), "observation.state", nan)
    pq.write_table(table, dataset / DATA)
    found = read_dataset(dataset)
    found.frames(0)
    with pytest.raises(
        DatasetError, match=f"{dataset / DATA}: episode 1's observation.state has values that"
    ):
        found.frames(1)


# -- finding 9: bounds, and the columns' widths as declared ------------------------------------------------


def test_an_fps_of_400_digits_is_refused(dataset, capsys):
    edit_info(dataset, fps=10**400)
    with pytest.raises(DatasetError, match="fps must be from 1 to 100000, got 1000000000"):
        read_dataset(dataset)
    assert len(one_line_error(capsys, "dataset", "show", str(dataset)).replace(str(dataset), "")) < 150
    with pytest.raises(InputError, match="fps must be a whole number from 1 to 100000"):
        DatasetSpec(fps=10**400, features=FEATURES)


def test_a_column_narrower_than_declared_is_refused(dataset):
    info = json.loads((dataset / fmt.INFO).read_text())
    info["features"]["observation.state"] |= {"shape": [4], "names": ["a", "b", "c", "d"]}
    (dataset / fmt.INFO).write_text(json.dumps(info))
    with pytest.raises(
        DatasetError,
        match=r"'observation.state' holds fixed_size_list.*\[3\], info.json declares float32 of shape \[4\]",
    ):
        read_dataset(dataset).frames(0)
    info["features"]["observation.state"]["shape"] = [3]  # four names for three columns
    (dataset / fmt.INFO).write_text(json.dumps(info))
    with pytest.raises(
        DatasetError, match=r"features.observation.state: shape \[3\] with \['a', 'b', 'c', 'd'\]"
    ):
        read_dataset(dataset)


# -- finding 10: what record can know before its first run -------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("--seed", "4294967295", "--episodes", "2"), "the last run's seed would be 4294967296"),
        (("--episodes", "100000000000"), "the last run's seed would be 99999999999"),
    ],
)
def test_record_refuses_seeds_past_the_last_before_any_run(tmp_path, capsys, argv, message):
    err = one_line_error(capsys, "record", "pick-place", "--dataset", str(tmp_path / "d"), *argv)
    assert message in err and not (tmp_path / "d").exists()


def test_the_working_directory_is_no_dataset_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for given in (".", str(tmp_path.parent)):
        err = one_line_error(capsys, "record", "pick-place", "--dataset", given, "--episodes", "1")
        assert f"--dataset {given}: the working directory or a folder holding it" in err
    assert list(tmp_path.iterdir()) == []


# -- the review of this round: links, bombs, permissions, races ------------------------------------------


@pytest.mark.parametrize(
    "part", ["data", "meta", "data/chunk-000", "meta/episodes/chunk-000/file-000.parquet"]
)
def test_a_linked_data_or_meta_is_refused_before_anything_is_written(dataset, tmp_path, part):
    elsewhere = tmp_path / "elsewhere"
    shutil.move(dataset / part, elsewhere)
    (dataset / part).symlink_to(elsewhere)
    before, outside = contents(dataset), contents(elsewhere) if elsewhere.is_dir() else elsewhere.read_bytes()
    with pytest.raises(InputError, match=f"{part} is a symbolic link; besman writes meta/ and data/"):
        DatasetWriter(dataset, SPEC)
    assert contents(dataset) == before
    assert (contents(elsewhere) if elsewhere.is_dir() else elsewhere.read_bytes()) == outside


def test_a_table_that_would_unpack_to_millions_of_rows_is_refused_unread(dataset):
    # 2 x 10^7 zeros compress to a few hundred kilobytes; read whole they took 5 GB.
    bomb = dataset / fmt.EPISODES_PATH.format(chunk_index=0, file_index=1)
    pq.write_table(pa.table({"episode_index": pa.array(np.zeros(20_000_000, dtype=np.int64))}), bomb)
    assert bomb.stat().st_size < 2_000_000
    with pytest.raises(
        DatasetError, match=r"meta/episodes: 20000002 episodes; info.json's total_episodes is 2"
    ):
        read_dataset(dataset)


def test_a_parquet_file_that_unpacks_past_the_bound_is_refused_unread(dataset, monkeypatch):
    import besman.datasets.reader as reader

    monkeypatch.setattr(reader, "MAX_UNPACKED", 1000)  # the episodes table unpacks to a few kilobytes
    with pytest.raises(
        DatasetError, match=rf"{EPISODES}: unpacks to \d+ bytes, more than the 1000 besman reads"
    ):
        read_dataset(dataset)


def test_an_append_keeps_the_folders_permissions(dataset):
    os.chmod(dataset, 0o2770)
    (dataset / "private").mkdir(mode=0o700)
    os.chmod(dataset / "private", 0o700)
    with DatasetWriter(dataset, SPEC) as writer:
        writer.append(episode(2))
    assert oct(dataset.stat().st_mode & 0o7777) == oct(0o2770)
    assert oct((dataset / "private").stat().st_mode & 0o777) == oct(0o700)


def test_a_dataset_whose_name_has_glob_characters_leaves_other_appends_alone(tmp_path):
    other = tmp_path / ".d1.besman-abcd1234.tmp"  # d1's append in progress
    other.mkdir()
    with DatasetWriter(tmp_path / "d[1]", SPEC) as writer:
        writer.append(episode(0))
    assert other.is_dir()


def test_a_file_system_mounted_in_the_dataset_is_named(dataset):
    mounted = dataset / "videos" / "more"
    mounted.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mounted)]).returncode:
        pytest.skip("mounting needs root and a system that allows it")
    try:
        before = contents(dataset)
        with (
            DatasetWriter(dataset, SPEC) as writer,
            pytest.raises(InputError, match="videos/more: another file"),
        ):
            writer.append(episode(2))
        assert contents(dataset) == before
    finally:
        subprocess.run(["umount", str(mounted)], check=True)


def test_what_changed_kind_meanwhile_is_kept_beside_and_the_episode_recorded(dataset, monkeypatch):
    import besman.datasets.writer as writer_module

    (dataset / "notes").write_text("a file")
    exchange = writer_module.exchange_folders

    def meanwhile(stage, folder):
        (folder / "notes").unlink()
        (folder / "notes").mkdir()  # now a folder, with the user's file in it
        (folder / "notes" / "today.txt").write_text("mine")
        (folder / "gone.txt").unlink()  # taken out meanwhile: stays out
        exchange(stage, folder)

    (dataset / "gone.txt").write_text("about to go")
    monkeypatch.setattr(writer_module, "exchange_folders", meanwhile)
    with DatasetWriter(dataset, SPEC) as writer:
        with pytest.raises(
            WriteError, match="episode 2 was recorded, but notes changed in the folder meanwhile"
        ):
            writer.append(episode(2))
        assert writer.episodes == 3
    (kept,) = dataset.parent.glob("d.besman-kept-*")
    assert (kept / "notes" / "today.txt").read_text() == "mine"
    assert not (dataset / "gone.txt").exists() and read_dataset(dataset).info["total_episodes"] == 3
    DatasetWriter(dataset, SPEC).close()  # the next writer leaves what was kept alone
    assert (kept / "notes" / "today.txt").is_file()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("no episode_index", r"needs an integer column episode_index"),
        ("text episode_index", r"needs an integer column episode_index"),
        ("no robot_type", r"its robot_type is None, these episodes' 'arm'"),
        ("no statistics", r"episode 0 has no stats/observation.state/min in meta/episodes"),
    ],
)
def test_tables_without_what_every_lerobot_dataset_has_are_named(dataset, change, message):
    if change.endswith("episode_index"):
        table = pq.read_table(dataset / DATA)
        position = table.column_names.index("episode_index")
        table = table.remove_column(position)
        if change.startswith("text"):
            table = table.append_column("episode_index", pa.array([str(i) for i in range(table.num_rows)]))
        pq.write_table(table, dataset / DATA)
        with pytest.raises(DatasetError, match=message):
            read_dataset(dataset).frames(0)
        return
    if change == "no robot_type":
        info = json.loads((dataset / fmt.INFO).read_text())
        del info["robot_type"]
        (dataset / fmt.INFO).write_text(json.dumps(info))
    else:
        table = pq.read_table(dataset / EPISODES)
        pq.write_table(table.drop_columns(["stats/observation.state/min"]), dataset / EPISODES)
    with pytest.raises(InputError, match=message):
        DatasetWriter(dataset, SPEC)


def test_a_strangers_text_reaches_the_terminal_escaped(dataset, capsys):
    table = pq.read_table(dataset / fmt.TASKS)
    texts = ["move\x1b]0;pwned\x07\x1b[2J"]
    pq.write_table(
        table.set_column(table.column_names.index("task"), "task", pa.array(texts)), dataset / fmt.TASKS
    )
    code, out, _ = run_cli(capsys, "dataset", "show", str(dataset))
    assert code == 0 and "\x1b" not in out and "task: move\\x1b]0;pwned\\x07\\x1b[2J" in out
