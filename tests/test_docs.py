"""The documentation site: it builds with MkDocs with every warning an error, the code of its getting-started
page runs as written and prints what its comments say, and the times the README and the docs state are the
measured ones."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_documentation_builds_with_warnings_as_errors(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    site = tmp_path / "site"
    assert (site / "index.html").is_file() and (site / "api" / "skills" / "index.html").is_file()
    command_line = (site / "cli" / "index.html").read_text()
    assert "besman learn" in command_line and "--budget" in command_line  # generated from the parser


@pytest.mark.slow
def test_every_python_block_of_the_getting_started_page_runs(tmp_path):
    page = (ROOT / "docs" / "getting-started.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.DOTALL)
    assert len(blocks) >= 2
    for block in blocks:
        result = subprocess.run(
            [sys.executable, "-c", block], cwd=tmp_path, capture_output=True, text=True, timeout=300
        )
        assert result.returncode == 0, (block, result.stderr[-3000:])
        assert "SUCCESS" in result.stdout, (block, result.stdout)
        # A comment that shows a print's output, up to its "...", is what it prints.
        for shown in re.findall(r"^print\(.*\)  # (.+) \.\.\.$", block, flags=re.MULTILINE):
            assert shown in result.stdout, (shown, result.stdout)


def _normalised(page: str) -> str:
    return re.sub(r"\s+", " ", (ROOT / page).read_text())


def test_the_times_the_docs_state_for_commands_are_the_measured_ones():
    """``benchmarks/command_times.py`` measured each command whose time the README and the docs state; they
    state it in the words it gives, from its record."""
    spec = importlib.util.spec_from_file_location("command_times", ROOT / "benchmarks" / "command_times.py")
    command_times = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(command_times)
    record = json.loads(command_times.RECORD.read_text())
    assert record["schema_version"] == command_times.SCHEMA_VERSION
    assert set(record["seconds"]) == set(command_times.COMMANDS) == set(command_times.STATED)
    for name, places in command_times.STATED.items():
        said = record["stated"][name]
        assert said == command_times.stated(record["seconds"][name]), name
        for page, words in places:
            assert words.format(said) in _normalised(page), (page, words.format(said))
        row = f"| {name} | {record['seconds'][name]:.1f} s |"  # the table of every measured command
        assert row in (ROOT / "docs" / "benchmarks.md").read_text(), row


def test_the_readme_states_the_suites_time_and_memory_as_tests_suite_measured_them():
    """``tests/suite.py`` (the README's test command) keeps the whole suite's time and peak memory in
    ``tests/suite.json``; the README says them."""
    record = json.loads((ROOT / "tests" / "suite.json").read_text())
    # A run of the whole suite (its figures say what the suite costs, whatever one test gave in it).
    passed = sum(phase["counts"].get("passed", 0) for phase in record["phases"])
    assert record["schema_version"] == 1 and passed > 1000
    minutes, memory, cores = record["minutes"], record["peak_memory_gb"], record["cores"]
    said = (
        f"the whole suite takes {minutes:.0f} minutes and at most {memory:.1f} GB of memory on {cores} cores"
    )
    assert said in _normalised("README.md"), said
