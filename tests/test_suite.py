"""tests/suite.py, the README's test command's runner: both phases run whatever the first gives, the exit code
says whether either failed, and the memory it reports counts the processes below it."""

import json
import os
import subprocess
import sys
import time

import suite


def test_the_second_phase_runs_after_a_failed_first_and_the_suite_fails(tmp_path, monkeypatch, capsys):
    (tmp_path / "conftest.py").write_text(  # the option the suite's own conftest adds
        "def pytest_addoption(parser):\n    parser.addoption('--record-durations', action='store_true')\n"
    )
    (tmp_path / "test_fails.py").write_text("def test_fails():\n    assert False\n")
    (tmp_path / "test_passes.py").write_text("def test_passes():\n    pass\n")
    monkeypatch.setattr(suite, "TESTS", tmp_path)
    monkeypatch.setattr(suite, "RECORD", tmp_path / "suite.json")
    monkeypatch.setattr(
        suite,
        "PHASES",
        {
            "first": [str(tmp_path / "test_fails.py"), "-p", "no:cacheprovider"],
            "second": [str(tmp_path / "test_passes.py"), "-p", "no:cacheprovider"],
        },
    )
    assert suite.main() == 1
    record = json.loads((tmp_path / "suite.json").read_text())
    assert [(phase["name"], phase["exit_code"], phase["counts"]) for phase in record["phases"]] == [
        ("first", 1, {"failed": 1}),
        ("second", 0, {"passed": 1}),
    ]
    assert capsys.readouterr().out.splitlines()[-1].endswith("FAILED: first")


def test_the_memory_of_a_process_tree_counts_its_children():
    """A child holding 300 MB of its own pages raises the tree's proportional set size by about that much."""
    before = suite.tree_memory(os.getpid())
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; b = bytearray(300_000_000); print(1, flush=True); time.sleep(30)",
        ],
        stdout=subprocess.PIPE,
    )
    try:
        child.stdout.readline()  # it holds the pages now
        time.sleep(0.1)
        grown = suite.tree_memory(os.getpid()) - before
    finally:
        child.kill()
        child.wait()
    assert 0.3e9 <= grown <= 0.4e9, grown
