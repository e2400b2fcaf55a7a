"""A command removes only what it can prove it wrote; interrupted and failed writes leave nothing behind.

A user's ``.x.tmp`` files in an ``--out`` folder are never touched (besman's temporaries carry its mark and
are cleaned only in an output known to be besman's); SIGTERM is handled as Ctrl-C (exit 143, one line, no
temporary or lock left); a full disk or a file-size limit during a write names the file and leaves no
temporary and no lock."""

from __future__ import annotations

import contextlib
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import is_whole, run_cli, snapshot

from besman.core.storage import WriteError
from besman.core.writer_lock import OutputBusyError, WriterLock
from besman.trees.runner import read_log

ROOT = Path(__file__).resolve().parents[1]
DEMOS = ROOT / "examples" / "data"
TREES = ROOT / "examples" / "trees"
BESMAN = Path(sys.executable).parent / "besman"  # the installed command, as a user starts it
# The user's files, at two depths, named as temporaries by other programs.
USERS = {".x.tmp": b"mine", "notes/.x.tmp": b"mine too", "work/.y.tmp": b"and mine"}
# Temporaries left by a killed besman writer, in the output's own folders (removed when it resumes); one in a
# folder of the user's (kept: not a folder besman writes).
DEAD_WRITERS = (".results.json.besman-k1ll3d00.tmp", "work/.config.json.besman-k1ll3d00.tmp")
MARKED_IN_USERS = {"notes/.a.json.besman-k1ll3d00.tmp": b"not in besman's folders"}
# An earlier run's log (its header and result): what a new run's --log may replace.
OLDER_LOG = '{"schema_version": 1, "kind": "besman-run-log", "run": {}}\n{"result": {"status": "SUCCESS"}}\n'


def _place(folder: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


def _stop(*args, **kwargs):
    raise KeyboardInterrupt  # where the work would start, once the output is claimed


# -- only marked temporaries, only in besman's own output ---------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "claimed"),
    [
        (
            ("learn", "--demos", str(DEMOS), "--out", "{out}"),
            "besman.learning.pipeline.end_to_end._Run.segmentations",
        ),
        (
            ("experiment", "throwing", "--quick", "--out", "{out}"),
            "besman.experiments.throwing.experiment.Experiment._run",
        ),
    ],
    ids=["learn", "experiment"],
)
def test_out_never_removes_a_users_tmp_files(tmp_path, capsys, monkeypatch, argv, claimed):
    """A folder of the user's holding only ``.x.tmp`` files at two depths is refused and left as it was;
    a besman output resumed keeps the user's files and loses only the temporaries of its dead writers."""
    monkeypatch.setattr(claimed, _stop)
    foreign, own = tmp_path / "foreign", tmp_path / "own"
    _place(foreign, USERS)
    code, _, err = run_cli(capsys, *(arg.format(out=foreign) for arg in argv))
    assert code == 2 and "the folder is not empty and not a" in err, err
    assert snapshot(foreign) == USERS
    assert sorted(p.name for p in tmp_path.iterdir()) == ["foreign"]  # and no lock left beside it
    assert run_cli(capsys, *(arg.format(out=own) for arg in argv))[0] == 130  # claimed, its record written
    record = snapshot(own)
    _place(own, {**USERS, **MARKED_IN_USERS, **dict.fromkeys(DEAD_WRITERS, b"half")})
    code, _, err = run_cli(capsys, *(arg.format(out=own) for arg in argv))
    assert code == 130 and err.strip().splitlines() == ["besman: interrupted (run it again to resume)"]
    assert snapshot(own) == {**record, **USERS, **MARKED_IN_USERS}


def test_a_run_log_removes_only_the_temporaries_of_its_own_file(tmp_path):
    """A run killed while it logged left its temporary: the next run to that log removes it, and nothing
    else beside it."""
    from besman.trees.runner import LogStream

    others = {
        ".run.jsonl.tmp": b"a user's",
        ".other.jsonl.besman-k1ll3d00.tmp": b"another log's",
        "sub/.run.jsonl.besman-k1ll3d00.tmp": b"another folder's",
    }
    _place(tmp_path, {**others, ".run.jsonl.besman-k1ll3d00.tmp": b"half a log"})
    LogStream(tmp_path / "run.jsonl", {}).abandon()
    assert snapshot(tmp_path) == others


# -- an output replaces only what besman wrote --------------------------------------------------------------


def _specials(folder: Path, name: str) -> dict[str, Path]:
    """``name`` in three folders of ``folder``: a user's own file, a FIFO, a link to a user's file."""
    places = {kind: folder / kind / name for kind in ("file", "fifo", "link")}
    for path in places.values():
        path.parent.mkdir()
    places["file"].write_text('{"my": "data"}\n')
    os.mkfifo(places["fifo"])
    (folder / "link" / "target").write_text('{"my": "data"}\n')
    places["link"].symlink_to(folder / "link" / "target")
    return places


LOG_REFUSALS = {
    "file": "an existing file that is not a besman run log; remove it or choose another name",
    "fifo": "a FIFO, not a regular file; remove it or choose another name",
    "link": "a symbolic link, not a regular file; remove it or choose another name",
}


@pytest.mark.parametrize(
    "argv",
    [("run", str(TREES / "grasp_then_place.yaml"), "--log", "{path}"), ("demo", "--log", "{path}")],
    ids=["run", "demo"],
)
def test_a_log_refuses_what_is_not_an_earlier_run_log_and_leaves_it_as_it_was(tmp_path, capsys, argv):
    """A user's own file, a FIFO and a symbolic link at --log: one line naming it, exit 2, before any work,
    and each left as it was (the FIFO still a FIFO, the link still a link to the user's file)."""
    places = _specials(tmp_path, "mine.jsonl")
    before = snapshot(tmp_path)
    for kind, path in places.items():
        code, _, err = run_cli(capsys, *(arg.format(path=path) for arg in argv))
        assert code == 2 and err.splitlines() == [f"besman: error: --log {path}: {LOG_REFUSALS[kind]}"], err
    assert snapshot(tmp_path) == before
    assert places["fifo"].is_fifo() and places["link"].is_symlink()
    assert sorted(p.name for p in places["link"].parent.iterdir()) == ["mine.jsonl", "target"]  # no lock left


def test_a_log_stream_refuses_what_is_not_an_earlier_run_log(tmp_path):
    """The API's log (:class:`LogStream`, what ``Runner.run(log=...)`` writes) refuses them alike."""
    from besman.core.errors import InputError
    from besman.trees.runner import LogStream

    places = _specials(tmp_path, "run.jsonl")
    before = snapshot(tmp_path)
    for kind, path in places.items():
        with pytest.raises(InputError, match=re.escape(f"--log {path}: {LOG_REFUSALS[kind]}")):
            LogStream(path, {})
    assert snapshot(tmp_path) == before and places["fifo"].is_fifo() and places["link"].is_symlink()


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (("segment", str(DEMOS / "subject1_run1.tsv"), "--plot", "{path}"), "--plot"),
        (("tree", "render", str(TREES / "grasp.yaml"), "--out", "{path}"), "--out"),
    ],
    ids=["plot", "out"],
)
def test_every_output_option_refuses_a_fifo_or_a_link(tmp_path, capsys, argv, option):
    """--plot and --out too: a FIFO or a symbolic link is refused by name, before any work, and left as it
    was."""
    suffix = ".png" if option == "--plot" else ".dot"
    places = _specials(tmp_path, f"out{suffix}")
    del places["file"]
    before = snapshot(tmp_path)
    for kind, path in places.items():
        code, _, err = run_cli(capsys, *(arg.format(path=path) for arg in argv))
        assert code == 2 and err.splitlines() == [f"besman: error: {option} {path}: {LOG_REFUSALS[kind]}"], (
            err
        )
    assert snapshot(tmp_path) == before and places["fifo"].is_fifo() and places["link"].is_symlink()


def test_a_log_replaces_an_earlier_run_log(tmp_path, capsys):
    log = tmp_path / "run.jsonl"
    log.write_text(OLDER_LOG)
    code, _, err = run_cli(capsys, "demo", "--log", str(log))
    assert code == 0, err
    header, records, result = read_log(log)
    assert header["run"] and records and result["status"] == "SUCCESS"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.jsonl"]


# -- SIGTERM as Ctrl-C --------------------------------------------------------------------------------------


def _terminate_when(argv: list[str], started: Path, delay: float) -> tuple[int, str]:
    """Runs ``besman ARGV`` and sends it SIGTERM ``delay`` s after ``started`` exists: (exit code, stderr)."""
    process = subprocess.Popen(
        [str(BESMAN), *argv], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 60
    while not started.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(delay)
    assert process.poll() is None, f"{argv} ended before its SIGTERM: {process.stderr.read()[-3000:]}"
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=120)
    return process.returncode, err


def _leftovers(folder: Path) -> list[str]:
    """Temporaries and writer locks under ``folder``."""
    return [str(p) for p in folder.rglob(".*") if p.name.endswith((".tmp", ".lock"))]


@pytest.mark.slow
def test_sigterm_during_a_logged_run_ends_it_as_ctrl_c_does(tmp_path):
    """Exit 143 and one line, the log whole and ending INTERRUPTED, no temporary and no lock beside it. (The
    learned tree: long enough, with online refinement, that the SIGTERM lands in the run.)"""
    out = tmp_path / "out"
    log = out / "run.jsonl"
    argv = ["run", str(TREES / "grasp_then_place_learned.yaml"), "--seed", "3", "--log", str(log)]
    code, err = _terminate_when(argv, out / ".run.jsonl.lock", 0.5)
    assert code == 143 and err.splitlines() == [f"besman: terminated ({log} holds the run up to here)"], err
    assert sorted(p.name for p in out.iterdir()) == ["run.jsonl"]
    assert read_log(log)[2]["status"] == "INTERRUPTED"


@pytest.mark.slow
def test_sigterm_during_learn_ends_it_as_ctrl_c_does(tmp_path):
    """Exit 143, the last line says so, every file whole, no temporary and no lock."""
    out = tmp_path / "pool"
    argv = ["learn", "--demos", str(DEMOS), "--out", str(out), "--training-tasks", "2", "--budget", "4"]
    code, err = _terminate_when(argv, out / "work" / "learn.json", 1.0)
    assert code == 143 and "Traceback" not in err, err
    assert err.count("besman:") == 1, err
    assert err.strip().splitlines()[-1].endswith("besman: terminated (run it again to resume)"), err
    assert _leftovers(tmp_path) == []
    assert all(is_whole(p) for p in out.rglob("*") if p.is_file())


# -- failed writes ----------------------------------------------------------------------------------------


def _fsize_limit() -> None:
    """``preexec_fn``: files up to 64 kB (a bigger write fails with EFBIG: Python ignores SIGXFSZ)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (65536, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


@pytest.fixture
def tmpfs(tmp_path):
    """A 64 kB tmpfs (a full disk within a few writes); skipped where mounting is not allowed."""
    folder = tmp_path / "tmpfs"
    folder.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    result = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], capture_output=True, text=True
    )
    if result.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {result.stderr.strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "--lazy", str(folder)], check=True)  # lazy: even if a file is open


@pytest.fixture(params=["disk full", "file-size limit"])
def small_space(request, tmp_path):
    """A folder where writing more than 64 kB fails, the reason it fails, and the ``preexec_fn`` of the
    child that writes: a full tmpfs (ENOSPC) or a file-size limit (EFBIG)."""
    if request.param == "disk full":
        return request.getfixturevalue("tmpfs"), "No space left on device", None
    folder = tmp_path / "limited"
    folder.mkdir()
    return folder, "File too large", _fsize_limit


@pytest.mark.slow
def test_a_log_that_cannot_be_written_is_named_and_leaves_nothing_behind(small_space):
    """The log outgrows the space: one line naming the log and the reason, exit 2, no temporary, no lock,
    and the older log at that path as it was."""
    folder, reason, limit = small_space
    log = folder / "run.jsonl"
    log.write_text(OLDER_LOG)
    result = subprocess.run(
        [str(BESMAN), "run", str(TREES / "grasp_then_place.yaml"), "--seed", "1", "--log", str(log)],
        capture_output=True,
        text=True,
        preexec_fn=limit,
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == [f"besman: error: {log}: cannot write it ({reason})"]
    assert snapshot(folder) == {"run.jsonl": OLDER_LOG.encode()}


def test_a_file_that_cannot_be_written_is_named_and_leaves_nothing_behind(small_space):
    """What learn and experiment write (whole files via a temporary): the error names the file, and its
    temporary is gone."""
    folder, reason, limit = small_space
    path = folder / "stage.npz"
    code = f"import besman.core.storage as s; s.write_atomically({str(path)!r}, bytes(100_000))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, preexec_fn=limit)
    assert f"besman.core.storage.WriteError: {path}: cannot write it ({reason})" in result.stderr
    assert list(folder.iterdir()) == []


def test_a_writer_lock_on_a_full_disk_names_the_output_and_leaves_no_lock(tmpfs):
    with (tmpfs / "filler").open("wb", buffering=0) as filler, contextlib.suppress(OSError):
        while True:  # until the disk is full
            filler.write(bytes(4096))
    message = re.escape(f"{tmpfs / 'run.jsonl'}: cannot write it (No space left on device)")
    with pytest.raises(WriteError, match=message):
        WriterLock(tmpfs / "run.jsonl", "--log").acquire()
    assert [p.name for p in tmpfs.iterdir()] == ["filler"]


def test_a_lock_path_that_is_no_regular_file_is_refused_and_left_alone(tmp_path):
    """A FIFO (or a link to a device) where the lock file goes is not besman's: refused at once, never read
    (a FIFO would block the read of its holder's line for ever) and never removed."""
    os.mkfifo(tmp_path / ".run.jsonl.lock")
    (tmp_path / ".pool.lock").symlink_to("/dev/zero")
    for output, lock in (("run.jsonl", ".run.jsonl.lock"), ("pool", ".pool.lock")):
        start = time.perf_counter()
        with pytest.raises(OutputBusyError, match=rf"{re.escape(lock)} is (a link|not a regular file)"):
            WriterLock(tmp_path / output, "--out").acquire()
        assert time.perf_counter() - start < 5.0
        assert (tmp_path / lock).is_symlink() or (tmp_path / lock).is_fifo()
