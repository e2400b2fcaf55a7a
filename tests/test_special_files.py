"""Special files and huge files, wherever besman reads: a FIFO (whose open blocks until a writer comes) and
``/dev/zero`` (which never ends) get a clear error naming the file within seconds, a 1 GB recording is
refused with its size and the limit, and a robot description cannot name a model outside its folder.

Each call runs in a forked child, killed after :data:`TIMEOUT` and allowed 1 GB more memory than it starts
with, so that a reader that regresses fails its test instead of hanging the suite or exhausting the machine.
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing
import os
import resource
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from besman import robots
from besman.cli import main
from besman.core.errors import BesmanError
from besman.core.reading import read_bytes
from besman.core.storage import read_npz
from besman.learning import load
from besman.robots.description import DescriptionError
from besman.skills import MovementPrimitive, SkillTemplatePool
from besman.trees import load_tree
from besman.trees.runner import read_log

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TIMEOUT = 30.0  # s after which a call counts as hanging
WITHIN = 5.0  # s in which every refusal comes
GIGABYTE = 2**30


def refusal(call) -> str:
    """The message of the :class:`BesmanError` that ``call()`` raises, run in a forked child; fails if the
    call hangs, takes :data:`WITHIN` s or more, exhausts its memory, or raises anything else."""
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_outcome, args=(call, send))
    start = time.monotonic()
    child.start()
    child.join(TIMEOUT)
    elapsed = time.monotonic() - start
    if child.is_alive():
        child.kill()
        child.join()
        pytest.fail(f"still reading after {TIMEOUT:.0f} s: it hangs")
    assert receive.poll(), f"the child ended without an answer (exit code {child.exitcode})"
    kind, message = receive.recv()
    assert kind == "refused", f"expected a BesmanError, got {kind}: {message}"
    assert elapsed < WITHIN, f"refused after {elapsed:.1f} s: {message}"
    return message


def _outcome(call, send) -> None:
    with open("/proc/self/statm") as statm:
        address_space = int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    resource.setrlimit(resource.RLIMIT_AS, (address_space + GIGABYTE, address_space + GIGABYTE))
    try:
        call()
    except BesmanError as error:
        send.send(("refused", str(error)))
    except BaseException as error:
        send.send((type(error).__name__, str(error)))
    else:
        send.send(("accepted", ""))


def command_line(*argv: str) -> tuple[int, str]:
    """``besman ARGV`` in this process: (exit code, stderr)."""
    errors = io.StringIO()
    with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
        code = main(list(argv))
    return code, errors.getvalue()


def special(path: Path, kind: str) -> Path:
    """``path`` made a FIFO, or a symbolic link to ``/dev/zero``; replaces a file there."""
    path.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    return path


WHAT = {"fifo": "a FIFO, not a", "zero": "a character device, not a"}
KINDS = pytest.mark.parametrize("kind", list(WHAT))


@KINDS
def test_a_special_tree_include_is_refused_by_name(tmp_path, kind):
    special(tmp_path / "sub.yaml", kind)
    tree = tmp_path / "main.yaml"
    tree.write_text("besman_tree: 1\nroot:\n  include: sub.yaml\n")
    message = refusal(lambda: load_tree(tree))
    assert f"main.yaml: {tmp_path / 'sub.yaml'}: {WHAT[kind]} tree file" in message


def test_dev_zero_given_directly_as_a_tree_file_is_refused():
    assert "/dev/zero: a character device, not a tree file" in refusal(lambda: load_tree("/dev/zero"))


@KINDS
@pytest.mark.parametrize("suffix", [".tsv", ".csv", ".npz"])
def test_a_special_recording_is_refused_by_name(tmp_path, kind, suffix):
    path = special(tmp_path / f"recording{suffix}", kind)
    message = refusal(lambda: load(path))
    assert f"{path}: {WHAT[kind]} recording" in message


def test_the_command_line_refuses_a_special_recording_in_one_line(tmp_path):
    path = special(tmp_path / "recording.tsv", "fifo")
    message = refusal(lambda: _fails_in_one_line("segment", str(path)))
    assert f"{path}: a FIFO, not a recording" in message


def _fails_in_one_line(*argv: str) -> None:
    code, errors = command_line(*argv)
    if code == 2 and errors.count("\n") == 1:
        raise BesmanError(errors)  # the one line, passed back to refusal()
    raise AssertionError(f"exit code {code}, stderr: {errors!r}")


def test_a_one_gigabyte_recording_is_refused_with_its_size_and_the_limit(tmp_path):
    huge = tmp_path / "huge.tsv"
    with open(huge, "wb") as file:  # sparse: no disk space
        file.truncate(GIGABYTE)
    message = refusal(lambda: _fails_in_one_line("segment", str(huge)))
    assert f"{huge}: larger than 64000000 bytes (1073741824 bytes), the limit for a recording" in message
    assert "BESMAN_MAX_RECORDING_BYTES" in message


def test_the_recording_limit_is_set_by_the_environment_or_the_caller(monkeypatch):
    recording = EXAMPLES / "data" / "subject1_run1.tsv"
    monkeypatch.setenv("BESMAN_MAX_RECORDING_BYTES", "100000")
    with pytest.raises(BesmanError, match=r"larger than 100000 bytes \(245092 bytes\)"):
        load(recording)
    assert len(load(recording, max_bytes=300_000).times) > 100
    for text in ("lots", "\u00b2", "\u0663"):  # a word; digits that are no ASCII decimal (int() refuses "²")
        monkeypatch.setenv("BESMAN_MAX_RECORDING_BYTES", text)
        code, errors = command_line("segment", str(recording))
        assert code == 2 and f"BESMAN_MAX_RECORDING_BYTES={text!r}: expected a number of bytes" in errors


def test_a_recording_of_more_values_than_its_limit_allows_is_refused(tmp_path):
    recording = tmp_path / "sparse.tsv"
    recording.write_text(
        "Frame\tTime\tHand X\tHand Y\tHand Z\n" + "".join(f"{n}\t{n}\t\t\t1\n" for n in range(200))
    )
    with pytest.raises(
        BesmanError, match=r"sparse\.tsv:\d+: more than 600 values, the most a recording of at most 2400"
    ):
        load(recording, max_bytes=2400)


def _worst_recording(path: Path, size: int) -> None:
    """A recording of ``size`` bytes with the most values reading allows: short rows of one marker."""
    rows = (f"{n}\t{n / 60:.3f}\t\t\t1\n" for n in range(1, size))
    with open(path, "w") as file:
        file.write("Frame\tTime\tHand X\tHand Y\tHand Z\n")
        while file.tell() < size - 100:
            file.write(next(rows))


@pytest.mark.slow
def test_reading_a_recording_at_its_limit_takes_at_most_six_times_the_limit(tmp_path):
    limit = 16_000_000
    recording = tmp_path / "worst.tsv"
    _worst_recording(recording, limit)
    script = (
        "import resource, sys\n"
        "from besman.learning import load\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "demo = load(sys.argv[1])\n"
        "print(len(demo.times), (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script, str(recording)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "BESMAN_MAX_RECORDING_BYTES": str(limit)},
        check=True,
    )
    rows, peak = map(int, result.stdout.split())
    assert rows > 500_000 and peak < 6 * limit, (rows, peak)


def _pool(tmp_path: Path) -> Path:
    pool = tmp_path / "pool"
    pool.mkdir()
    for suffix in (".json", ".npz"):
        shutil.copy(EXAMPLES / "pools" / "pick_place_aila" / f"reach{suffix}", pool)
    return pool


@KINDS
@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_a_special_pool_entry_is_refused_by_name(tmp_path, kind, suffix):
    pool = _pool(tmp_path)
    path = special(pool / f"reach{suffix}", kind)
    message = refusal(lambda: SkillTemplatePool(pool)["reach"])
    assert f"{path}: {WHAT[kind]} pool" in message


@KINDS
@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_a_special_primitive_is_refused_by_name(tmp_path, kind, suffix):
    for part in (".json", ".npz"):
        shutil.copy(EXAMPLES / "pools" / "pick_place_aila" / "work" / "shapes" / f"reach{part}", tmp_path)
    path = special(tmp_path / f"reach{suffix}", kind)
    message = refusal(lambda: MovementPrimitive.load(tmp_path / "reach.json"))
    assert f"{path}: {WHAT[kind]} primitive" in message


def test_arrays_that_unpack_beyond_the_limit_are_refused(tmp_path):
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, zeros=np.zeros(100_000))  # 800 kB of zeros in about 1 kB
    assert path.stat().st_size < 10_000
    message = refusal(lambda: read_npz(path, max_bytes=100_000))
    assert f"{path}: unpacks to 800128 bytes, more than the 100000 of a NPZ archive" in message


def _robot(tmp_path: Path) -> Path:
    folder = tmp_path / "pa10"
    shutil.copytree(ROOT / "robots" / "pa10", folder)
    return folder


@KINDS
@pytest.mark.parametrize("file", ["description.json", "scene.xml", "pa10.xml"])
def test_a_special_robot_description_model_or_include_is_refused_by_name(tmp_path, kind, file):
    folder = _robot(tmp_path)
    path = special(folder / file, kind)
    message = refusal(lambda: robots.load(str(folder)))
    if (file, kind) == ("scene.xml", "zero"):  # the model itself can be /dev/zero only through a link out
        assert "description.json.model: 'scene.xml' lies outside the robot's folder" in message
    else:
        what = "robot description" if file == "description.json" else "robot model"
        assert f"{path}: {WHAT[kind]} {what}" in message


@KINDS
def test_a_special_mesh_of_a_robot_model_is_refused_by_name(tmp_path, kind):
    folder = _robot(tmp_path)
    model = folder / "pa10.xml"
    model.write_text(
        model.read_text().replace("<worldbody>", '<asset><mesh file="m.stl"/></asset><worldbody>', 1)
    )
    path = special(folder / "m.stl", kind)
    message = refusal(lambda: robots.load(str(folder)))
    assert f"{path}: {WHAT[kind]} file of a robot model" in message


@pytest.mark.parametrize("escape", ["../elsewhere/scene.xml", "link/scene.xml"])
def test_a_model_outside_the_description_folder_is_refused(tmp_path, escape):
    folder = _robot(tmp_path)
    shutil.copytree(folder, tmp_path / "elsewhere")
    (folder / "link").symlink_to(tmp_path / "elsewhere")
    description = json.loads((folder / "description.json").read_text())
    description["model"] = escape
    (folder / "description.json").write_text(json.dumps(description))
    with pytest.raises(DescriptionError, match="lies outside the robot's folder") as error:
        robots.load(str(folder))
    assert str(error.value).startswith(f"{folder / 'description.json'}.model: {escape!r}")


@KINDS
def test_a_special_run_log_is_refused_by_name_also_by_view(tmp_path, kind):
    import besman.trees.watching  # noqa: F401 (imported here, so that the time measured is the refusal's)

    path = special(tmp_path / "run.jsonl", kind)
    assert f"{path}: {WHAT[kind]} run log" in refusal(lambda: read_log(path))
    assert f"{path}: {WHAT[kind]} run log" in refusal(
        lambda: _fails_in_one_line("view", "--replay", str(path))
    )


def test_a_run_log_above_its_limit_is_refused_with_the_variable_that_raises_it(tmp_path, monkeypatch):
    log = tmp_path / "run.jsonl"
    log.write_text('{"kind": "besman-run-log"}\n' * 100)
    monkeypatch.setenv("BESMAN_MAX_LOG_BYTES", "1000")
    with pytest.raises(BesmanError, match=r"larger than 1000 bytes \(2700 bytes\).*BESMAN_MAX_LOG_BYTES"):
        read_log(log)


def test_a_socket_and_a_directory_are_refused_by_what_they_are(tmp_path):
    with socket.socket(socket.AF_UNIX) as server:
        server.bind(str(tmp_path / "socket"))
        assert "a socket, not a thing" in refusal(lambda: read_bytes(tmp_path / "socket", 10, what="thing"))
    assert "a directory, not a thing" in refusal(lambda: read_bytes(tmp_path, 10, what="thing"))
