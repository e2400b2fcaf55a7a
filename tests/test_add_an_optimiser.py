"""The documentation's "Add an optimiser" page (docs/optimizers.md), followed literally; and the rules of
choosing and registering optimisers by name."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import follow_page, install_plugin, run_cli

from besman.core.errors import InputError
from besman.learning.search.policy_search import (
    CMAES,
    OPTIMIZERS,
    WarmStart,
    make_optimizer,
    optimizer_names,
    register_optimizer,
)

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "optimizers.md"


@pytest.mark.slow
def test_the_add_an_optimiser_page_works_as_written(tmp_path):
    package = tmp_path / "besman-cem"
    _, learned, listed, tested = follow_page(PAGE, package)
    assert "reach: 2 training tasks" in learned and listed.count("pick-place/aila\tK=2") == 3
    record = json.loads((package / "cem_pool" / "work" / "learn.json").read_text())
    assert record["settings"]["optimizer"] == "cem"
    assert "2 passed" in tested


def test_a_registered_optimiser_is_made_by_name_and_names_are_not_taken_over():
    register_optimizer("cmaes-copy", CMAES)
    try:
        assert "cmaes-copy" in optimizer_names()
        asked = [
            make_optimizer(name, WarmStart(np.zeros(2), 0.1), seed=3).ask()
            for name in ("cmaes-copy", "cmaes")
        ]
        np.testing.assert_array_equal(*asked)
        with pytest.raises(InputError, match="the optimiser 'cmaes' exists already"):
            register_optimizer("cmaes", CMAES)
    finally:
        del OPTIMIZERS["cmaes-copy"]
    for name, factory, message in [
        ("CMA", CMAES, "an optimiser's name is lower case"),
        ("spare", 3, "3 is not a class or function that makes one"),
    ]:
        with pytest.raises(InputError, match=message):
            register_optimizer(name, factory)
    register_optimizer("nothing", lambda start, seed, population_size: None)
    try:
        with pytest.raises(InputError, match="optimiser 'nothing' made None, which has no ask, tell"):
            make_optimizer("nothing", WarmStart(np.zeros(2), 0.1), seed=0)
    finally:
        del OPTIMIZERS["nothing"]


def test_an_unknown_optimiser_is_refused_before_any_work(tmp_path, capsys):
    code, out, err = run_cli(
        capsys, "learn", "--demos", str(ROOT / "examples" / "data"), "--out", str(tmp_path / "pool"),
        "--optimizer", "annealing",
    )  # fmt: skip
    assert (code, out) == (2, "")
    assert err == "besman: error: optimizer must be one of cmaes, xnes, got 'annealing'\n"
    assert not (tmp_path / "pool").exists()


def test_a_broken_optimiser_plugin_is_one_warning_line(tmp_path):
    site = tmp_path / "site"
    taken = "from besman.learning.search.policy_search import XNES\nOPTIMIZERS = {'xnes': XNES}\n"
    plugins = {
        "besman-broken": ("broken_search", "import not_installed_anywhere\n"),
        "besman-taken": ("taken_search", taken),
    }
    for dist, (module, source) in plugins.items():
        install_plugin(site, dist, "besman.optimizers", module)
        (site / f"{module}.py").write_text(source)
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            "from besman.learning.search.policy_search import optimizer_names as n; print(n())",
        ],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
    )
    assert result.returncode == 0 and result.stdout == "['cmaes', 'xnes']\n"
    warnings = [
        line.split("PluginWarning: ")[1] for line in result.stderr.splitlines() if "PluginWarning" in line
    ]
    assert len(warnings) == 2, result.stderr
    assert any(
        w.startswith("the optimiser plugin 'broken_search' of the distribution besman-broken 1.0 is left out")
        for w in warnings
    )
    assert any("besman-taken 1.0: the optimiser 'xnes' exists already" in w for w in warnings)
