"""The documentation site: it builds with MkDocs with every warning an error, and the code of its
getting-started page runs as written."""

from __future__ import annotations

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
