"""LeRobot v3.0 datasets: runs recorded as episodes, read back exactly, checked by lerobot-doctor, safe
against kill -9, and bad input refused with the file and the field."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from helpers import run_cli

from besman.core.errors import InputError
from besman.core.writer_lock import OutputBusyError
from besman.datasets import format as fmt
from besman.datasets.reader import DatasetError, read_dataset
from besman.datasets.writer import DatasetSpec, DatasetWriter, Episode
from besman.tasks.recording import CAMERA, record_run

FEATURES = {
    "observation.state": {"dtype": "float32", "shape": [3], "names": ["a", "b", "c"]},
    "action": {"dtype": "float32", "shape": [2], "names": ["a", "b"]},
}
SPEC = DatasetSpec(fps=50, features=FEATURES, robot_type="arm")


def episode(length: int, offset: float = 0.0, **changes) -> Episode:
    t = np.linspace(0, 1, length)[:, None]
    frames = {
        "observation.state": np.sin(t * [1, 2, 3] + offset),
        "action": np.cos(t * [1, 2] + offset),
    }
    fields = {"task": "move", "frames": frames, "facts": {"besman/seed": 0}} | changes
    return Episode(**fields)


def record_command(root: Path, episodes: int, *more: str) -> list[str]:
    """``besman record pick-place`` into ``root``, in a process of its own."""
    return [
        sys.executable,
        "-m",
        "besman",
        "record",
        "pick-place",
        "--dataset",
        str(root),
        "--episodes",
        str(episodes),
        *more,
    ]


def doctor(dataset: Path) -> dict:
    """lerobot-doctor's verdict on the dataset (offline: an absolute path), as its JSON report."""
    result = subprocess.run(
        [shutil.which("lerobot-doctor") or "lerobot-doctor", str(dataset.absolute()), "--json"],
        capture_output=True,
        text=True,
        env={**os.environ, "HF_HUB_OFFLINE": "1"},  # it never asks the hub about a local folder
    )
    return json.loads(result.stdout)


def failures(report: dict) -> list[str]:
    return [
        f"{check['name']}: {message['message']}"
        for check in report["checks"]
        for message in check["messages"]
        if message["severity"] == "FAIL"
    ]


def test_episodes_append_with_their_default_columns_and_read_back(tmp_path):
    with DatasetWriter(tmp_path / "d", SPEC) as writer:
        assert writer.append(episode(30)) == 0
        assert writer.append(episode(20, 1.0, task="move back", facts={"besman/seed": 5})) == 1
    dataset = read_dataset(tmp_path / "d")
    assert dataset.info["total_episodes"] == 2 and dataset.info["total_frames"] == 50
    (tmp_path / "plain").mkdir()  # the dataset's folder has an ordinary folder's permissions
    assert (tmp_path / "d").stat().st_mode == (tmp_path / "plain").stat().st_mode
    assert dataset.tasks == ("move", "move back") and dataset.facts(1) == {"besman/seed": 5}
    frames = dataset.frames(1)
    np.testing.assert_array_equal(
        frames["observation.state"], episode(20, 1.0).frames["observation.state"].astype(np.float32)
    )
    np.testing.assert_array_equal(frames["index"], np.arange(30, 50))
    np.testing.assert_array_equal(frames["frame_index"], np.arange(20))
    np.testing.assert_allclose(frames["timestamp"], np.arange(20) / 50)
    assert set(frames["task_index"]) == {1} and set(frames["episode_index"]) == {1}
    stats = json.loads((tmp_path / "d" / fmt.STATS).read_text())
    both = np.concatenate([dataset.frames(0)["action"], frames["action"]]).astype(np.float64)
    np.testing.assert_allclose(stats["action"]["mean"], both.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats["action"]["std"], both.std(axis=0), rtol=1e-9)
    assert stats["action"]["count"] == [50] and stats["action"]["min"] == both.min(axis=0).tolist()


def test_bad_episodes_and_datasets_are_refused_naming_the_field(tmp_path):
    root = tmp_path / "d"
    with DatasetWriter(root, SPEC) as writer:
        writer.append(episode(10))
        nan = episode(10)
        nan.frames["action"][3, 1] = np.nan
        with pytest.raises(InputError, match="action has values that are not finite"):
            writer.append(nan)
        with pytest.raises(
            InputError, match=r"observation.state has shape \(10, 2\), the dataset's \[10, 3\]"
        ):
            writer.append(
                episode(10, frames={"observation.state": np.zeros((10, 2)), "action": np.zeros((10, 2))})
            )
        with pytest.raises(InputError, match="features missing: \\['action'\\]"):
            writer.append(episode(10, frames={"observation.state": np.zeros((10, 3))}))
        with pytest.raises(InputError, match="facts"):
            writer.append(episode(10, facts={}))
        with pytest.raises(OutputBusyError, match="--dataset"):
            DatasetWriter(root, SPEC)  # one writer at a time
    assert read_dataset(root).info["total_episodes"] == 1  # nothing of the refused episodes
    other = DatasetSpec(fps=30, features=FEATURES, robot_type="arm")
    with pytest.raises(InputError, match="its fps is 50, these episodes' 30"):
        DatasetWriter(root, other)
    wider = DatasetSpec(
        fps=50,
        features={**FEATURES, "extra": {"dtype": "float32", "shape": [1], "names": None}},
        robot_type="arm",
    )
    with pytest.raises(InputError, match="extra differ"):
        DatasetWriter(root, wider)
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "a.txt").write_text("mine")
    with pytest.raises(InputError, match="not a LeRobot dataset"):
        DatasetWriter(tmp_path / "notes", SPEC)
    info = json.loads((root / fmt.INFO).read_text())
    (root / fmt.INFO).write_text(json.dumps(info | {"codebase_version": "v2.1"}))
    with pytest.raises(DatasetError, match=r"codebase_version 'v2\.1'.*convert_dataset_v21_to_v30"):
        read_dataset(root)
    (root / fmt.INFO).write_text(json.dumps(info | {"total_frames": 11}))
    with pytest.raises(DatasetError, match="total_frames is 11, the data files hold 10 rows"):
        read_dataset(root)
    with pytest.raises(InputError, match="a video's shape"):
        DatasetSpec(fps=50, features={"cam": {"dtype": "video", "shape": [11, 10, 3]}})


@pytest.fixture(scope="module")
def aila_dataset(tmp_path_factory) -> Path:
    """Twenty pick-and-place demos on AILA, perception-perturbed, recorded by ``besman record``."""
    root = tmp_path_factory.mktemp("aila") / "dataset"
    result = subprocess.run(
        record_command(root, 20, "--perturb", "perception"),
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    return root


@pytest.mark.slow
def test_twenty_aila_episodes_pass_lerobot_doctor_and_round_trip_exactly(aila_dataset, tmp_path):
    dataset = read_dataset(aila_dataset)
    assert dataset.info["total_episodes"] == 20 and dataset.info["robot_type"] == "aila"
    assert [dataset.facts(i)["besman/seed"] for i in range(20)] == list(range(20))
    assert failures(doctor(aila_dataset)) == []
    # Read back and written again, every episode gives the same files, byte for byte.
    features = {k: v for k, v in dataset.features.items() if k not in fmt.DEFAULT_FEATURES}
    spec = DatasetSpec(fps=dataset.fps, features=features, robot_type=dataset.info["robot_type"])
    copy = tmp_path / "copy"
    with DatasetWriter(copy, spec) as writer:
        for index in range(20):
            frames = {k: v for k, v in dataset.frames(index).items() if k in features}
            writer.append(Episode(dataset.episodes[index]["tasks"][0], frames, facts=dataset.facts(index)))
    for path in sorted(aila_dataset.rglob("*")):
        if path.is_file():
            assert path.read_bytes() == (copy / path.relative_to(aila_dataset)).read_bytes(), path


@pytest.mark.slow
def test_a_ur5e_dataset_passes_lerobot_doctor(tmp_path):
    for seed in (1, 2):
        summary, index = record_run("pick-place", robot="ur5e", seed=seed, dataset=tmp_path / "ur5e")
        assert summary.success and index == seed - 1
    dataset = read_dataset(tmp_path / "ur5e")
    assert dataset.info["robot_type"] == "ur5e" and dataset.features["action"]["shape"] == [7]  # 6 + gripper
    assert failures(doctor(tmp_path / "ur5e")) == []


@pytest.mark.slow
def test_a_throw_with_its_camera_and_no_gripper_passes_lerobot_doctor(tmp_path):
    summary, _ = record_run("throwing", seed=0, dataset=tmp_path / "throw", video=True)
    dataset = read_dataset(tmp_path / "throw")
    assert all(name.endswith(".pos") for name in dataset.features["action"]["names"])  # no gripper
    assert dataset.facts(0)["besman/success"] == summary.success
    report = doctor(tmp_path / "throw")
    assert failures(report) == []
    video = next(c for c in report["checks"] if c["name"].startswith("Video"))
    assert video["severity"] == "PASS"  # decoded: its frames and fps as the metadata says
    import av

    path = tmp_path / "throw" / fmt.VIDEO_PATH.format(video_key=CAMERA, chunk_index=0, file_index=0)
    with av.open(str(path)) as container:
        images = [frame.to_ndarray(format="rgb24") for frame in container.decode(video=0)]
    assert len(images) == dataset.episodes[0]["length"] and images[0].shape == (240, 320, 3)
    assert np.ptp(np.array(images[-1], dtype=float)) > 50  # a picture, not a blank frame


def test_both_arms_of_a_handover_are_recorded(tmp_path):
    summary, _ = record_run("handover", seed=0, dataset=tmp_path / "d")
    names = read_dataset(tmp_path / "d").features["action"]["names"]
    assert summary.success and "left.gripper" in names and "right.gripper" in names


@pytest.mark.slow
def recorded(root: Path) -> int:
    """The episodes the dataset at ``root`` holds (0 before its first)."""
    try:
        return json.loads((root / fmt.INFO).read_text())["total_episodes"]
    except FileNotFoundError:
        return 0


def test_kill_9_while_recording_leaves_a_valid_dataset_that_a_rerun_completes(tmp_path):
    root = tmp_path / "dataset"
    command = record_command(root, 6)
    rng = np.random.default_rng(3)
    kills = 0
    while kills < 4:
        before = recorded(root)
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 120
        while process.poll() is None and recorded(root) == before and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 0.9))  # past an episode (about 1 s each), into the next run or its append
        if process.poll() is not None:
            break
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        kills += 1
        if (root / fmt.INFO).exists():
            read_dataset(root)  # valid: every episode whole, the totals right
            assert failures(doctor(root)) == []
    assert kills >= 2
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    dataset = read_dataset(root)
    assert [dataset.facts(i)["besman/seed"] for i in range(6)] == list(range(6))
    assert not list(tmp_path.glob(".dataset.besman-*"))  # the killed appends' folders removed
    # The same as a recording never killed.
    clean = tmp_path / "clean"
    subprocess.run(record_command(clean, 6), check=True, capture_output=True)
    assert pq.read_table(root / "data/chunk-000/file-000.parquet").equals(
        pq.read_table(clean / "data/chunk-000/file-000.parquet")
    )


def test_the_command_line_records_shows_and_refuses(tmp_path, capsys):
    root = tmp_path / "d"
    code, out, err = run_cli(capsys, "demo", "pick-place", "--seed", "2", "--dataset", str(root))
    assert code == 0 and "the run is episode 0" in err
    code, out, _ = run_cli(capsys, "dataset", "show", str(root), "--json")
    shown = json.loads(out)
    assert shown["episodes"] == 1 and shown["successes"] == 1 and shown["robot_type"] == "aila"
    assert shown["features"]["action"]["names"][-1] == "right.gripper"
    assert shown["features"]["observation.environment_state"]["names"][:2] == ["object_x", "object_y"]
    code, _, err = run_cli(capsys, "record", "stack", "--dataset", str(root), "--episodes", "1")
    assert code == 2 and "episode 0 is of task 'pick-place' on 'aila', not stack on" in err
    code, _, err = run_cli(capsys, "demo", "--video")
    assert code == 2 and "--video records the camera into a dataset" in err
    code, _, err = run_cli(capsys, "demo", "--dataset", str(root), "--view")
    assert code == 2 and "drop --view" in err


def test_an_append_stopped_before_its_exchange_leaves_the_dataset_as_it_was(tmp_path, monkeypatch):
    import besman.datasets.writer as writer_module

    root = tmp_path / "d"
    with DatasetWriter(root, SPEC) as writer:
        writer.append(episode(10))
    before = {p.relative_to(root): p.read_bytes() for p in root.rglob("*") if p.is_file()}

    def stopped(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(writer_module, "exchange_folders", stopped)
    with DatasetWriter(root, SPEC) as writer, pytest.raises(KeyboardInterrupt):
        writer.append(episode(12))
    assert {p.relative_to(root): p.read_bytes() for p in root.rglob("*") if p.is_file()} == before
    assert not list(tmp_path.glob(".d.besman-*"))
    # What a kill -9 leaves (the next state half built beside the dataset) the next writer removes.
    (tmp_path / ".d.besman-killed.tmp" / "data").mkdir(parents=True)
    monkeypatch.undo()
    with DatasetWriter(root, SPEC) as writer:
        assert writer.append(episode(12)) == 1
    assert not list(tmp_path.glob(".d.besman-*")) and read_dataset(root).info["total_frames"] == 22
