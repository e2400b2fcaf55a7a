"""Two Trossen WidowX AI arms on a stand, a two-arm robot besman does not ship, brought from the PyPI package
``trossen-arm-sim`` with one description file and a stand (``examples/robots/widowx_ai_pair``): every robot
check passes and the learned tree 10/10 on seeds no other test uses (the handover, pick-place and sort 10/10
within the arms' limits, the arms never touching: tests/test_acceptance.py)."""

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from helpers import failed_placements, run_cli

from besman.tasks import task

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT / "examples" / "robots" / "widowx_ai_pair"
POOL = ROOT / "examples" / "pools" / "pick_place_widowx_ai_pair"


def test_closed_fingers_touching_are_no_collision_of_either_arm():
    """The WidowX AI's closed carriages overlap by 0.2 mm: its own hand's parts touching, or another arm's,
    are nothing an arm's motion can change, so no pose collides for it."""
    from besman.sim.arm import Arm
    from besman.sim.world import tabletop_world

    both = tabletop_world(robot=str(PAIR))
    for side in ("right", "left"):
        arm = Arm(both, side)
        assert arm.contacts(arm.home) == [], side  # both grippers closed at home, their carriages touching


@pytest.mark.slow
def test_the_robots_page_two_arm_commands_run_as_written(capsys, monkeypatch):
    """docs/robots.md's "Two arms": its attach field is the folder's, and each command runs from the
    repository's folder: every robot check passes on both arms, the handover succeeds."""
    page = (ROOT / "docs" / "robots.md").read_text()
    section = page[page.index("### Two arms") : page.index("## Shipped robots")]
    attach = re.search(r"```json\n(.*?)```", section, re.S).group(1)
    assert (
        json.loads("{" + attach.rstrip().rstrip(",") + "}")["attach"]
        == json.loads((PAIR / "description.json").read_text())["attach"]
    )
    monkeypatch.chdir(ROOT)
    for line in re.search(r"```bash\n(.*?)```", section, re.S).group(1).splitlines():
        argv = shlex.split(line.split("#")[0])
        code, out, err = run_cli(capsys, *argv[1:])
        assert code == 0, (line, out, err)
        if argv[1:3] == ["robots", "check"]:
            assert out.strip().endswith("all checks passed") and out.count("ok   left:") == 9, out
        else:
            assert out.startswith(("handover", "SUCCESS")) and "SUCCESS" in out, out


@pytest.mark.slow
def test_the_pool_learned_on_the_pair_places_ten_unseen_tasks():
    """``besman learn --robot examples/robots/widowx_ai_pair`` (committed): its learned tree, the templates'
    means alone, at 10 tasks drawn from the right arm's box that no template was trained on."""
    pick_place = task("pick-place")
    rng = np.random.default_rng(3871)
    taus = np.array([pick_place.draw(str(PAIR), rng) for _ in range(10)]).round(4)
    assert json.loads((POOL / "reach.json").read_text())["provenance"]["robot"] == "widowx_ai_pair"
    assert failed_placements(POOL, taus, robot=str(PAIR)) == []
