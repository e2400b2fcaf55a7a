"""Trossen's WidowX AI, an arm besman does not ship, brought from the PyPI package ``trossen-arm-sim`` with
one description file (``examples/robots/widowx_ai``): docs/robots.md done as written and the learned tree
10/10 on seeds no other test uses (pick-place and sort 10/10 within the arm's limits:
tests/test_acceptance.py)."""

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from helpers import failed_placements, run_cli

from besman.tasks import task

ROOT = Path(__file__).resolve().parents[1]
WIDOWX = ROOT / "examples" / "robots" / "widowx_ai"
POOL = ROOT / "examples" / "pools" / "pick_place_widowx_ai"


@pytest.mark.slow
def test_the_robots_page_brings_the_widowx_as_it_says(capsys, tmp_path, monkeypatch):
    """docs/robots.md's description (the folder's file, word for word) into ./my_arm, then every command of
    its steps from a folder of its own (the first copies the examples in), the gripper table pasted in."""
    page = (ROOT / "docs" / "robots.md").read_text()
    description = re.search(r"<!-- description -->\n```json\n(.*?)```", page, re.S).group(1)
    assert description == (WIDOWX / "description.json").read_text()
    steps = re.search(r"<!-- steps -->\n```bash\n(.*?)```", page, re.S).group(1)
    folder = tmp_path / "my_arm"
    folder.mkdir()
    (folder / "description.json").write_text(description)
    monkeypatch.chdir(tmp_path)
    for line in steps.splitlines():
        argv = shlex.split(line.split("#")[0])
        assert argv[0] == "besman"
        code, out, err = run_cli(capsys, *argv[1:])
        assert code == 0, (line, out, err)
        if argv[1:3] == ["robots", "check"]:
            assert out.strip().endswith("all checks passed"), out
        if argv[1:3] == ["robots", "gripper"]:
            table = json.loads(out)
            written = json.loads((folder / "description.json").read_text())
            given = written["arms"]["arm"]["gripper"]
            # The two points the description gives are the measured table's line.
            expected = np.interp(table["command"], given["command"], given["opening"])
            np.testing.assert_allclose(table["opening"][1:], expected[1:], atol=2e-4)
            given.update(table)
            (folder / "description.json").write_text(json.dumps(written))
        if "--json" in argv:
            summary = json.loads(out)
            assert summary["success"] and summary["robot"] == "./my_arm", summary
        if argv[1] == "run":
            assert out.startswith("SUCCESS"), out
    assert (tmp_path / "my_arm.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_the_pool_learned_on_the_widowx_folder_places_ten_unseen_tasks():
    """``besman learn --robot examples/robots/widowx_ai`` from the 15 shared recordings (committed): the
    learned tree with the templates' means alone at 10 tasks drawn from the arm's box that no template was
    trained on, every one placed by the task's rule; the pool names the robot, not the folder."""
    pick_place = task("pick-place")
    rng = np.random.default_rng(3831)
    taus = np.array([pick_place.draw(str(WIDOWX), rng) for _ in range(10)]).round(4)
    assert json.loads((POOL / "reach.json").read_text())["provenance"]["robot"] == "widowx_ai"
    assert failed_placements(POOL, taus, robot=str(WIDOWX)) == []
