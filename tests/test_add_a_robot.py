"""The documentation's "Add a robot" page (docs/add-a-robot.md), followed literally; and robots that
installed packages bring, broken ones left out in one warning line."""

import subprocess
import sys
from pathlib import Path

import pytest
from helpers import follow_page, install_plugin

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "add-a-robot.md"


@pytest.mark.slow
def test_the_add_a_robot_page_works_as_written(tmp_path):
    listed, checked, demo, tested = follow_page(PAGE, tmp_path / "besman-widowx")
    assert "widowx_ai\tTrossen WidowX AI" in listed and "aila\t" in listed
    assert checked.strip().endswith("all checks passed")
    assert demo.splitlines()[1].startswith("SUCCESS: placement error")
    assert "1 passed" in tested


def test_a_robot_package_without_a_description_or_with_a_taken_name_is_one_warning_line(tmp_path):
    site = tmp_path / "site"
    for dist, module, description in [
        ("besman-empty", "empty_robot", None),
        ("besman-copy", "copied_robot", (ROOT / "robots" / "ur5e" / "description.json").read_text()),
    ]:
        install_plugin(site, dist, "besman.robots", module)
        (site / module).mkdir()
        (site / module / "__init__.py").write_text("")
        if description is not None:
            (site / module / "description.json").write_text(description)
    result = subprocess.run(
        [Path(sys.executable).parent / "besman", "robots"],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
    )
    assert result.returncode == 0 and [line.split("\t")[0] for line in result.stdout.splitlines()] == [
        "aila",
        "openarm",
        "pa10",
        "ur5e",
    ]
    warnings = sorted(result.stderr.splitlines())
    assert len(warnings) == 2, result.stderr
    assert warnings[0] == (
        "besman: warning: the robot plugin 'copied_robot' of the distribution besman-copy 1.0 is left out: a "
        "robot called 'ur5e' exists already"
    )
    assert warnings[1].startswith(
        "besman: warning: the robot plugin 'empty_robot' of the distribution besman-empty 1.0 is left out: "
    )
    assert "description.json" in warnings[1]
