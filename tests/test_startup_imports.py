"""The commands that list, show and check import only what they use, so that they answer in well under a
second (``benchmarks/startup.py`` times them): none of scipy, scikit-learn or matplotlib, and MuJoCo only
where the command needs a robot's model. Trees are read, built, checked and shown, and their node types
listed (with the node-type plugins' leaves), without the simulation: the leaves import it when they run."""

import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]
HEAVY = ("scipy", "sklearn", "matplotlib", "mujoco")
# The command's handler run in a new interpreter, its output dropped; then its exit code and the heavy
# packages it imported.
CODE = f"""
import contextlib, io, sys
from besman.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(sys.argv[1:])
print(code, sorted({{name.partition(".")[0] for name in sys.modules}} & set({HEAVY!r})))
"""


@pytest.mark.parametrize(
    ("command", "needs"),
    [
        ("demo --list", []),
        ("tasks show pick-place", []),
        ("robots", []),
        ("robots show ur5e", ["mujoco"]),
        ("pool ls examples/pools/pick_place_aila", []),
        ("pool show examples/pools/pick_place_aila reach", []),
        ("recordings show examples/data/subject1_run1.tsv", []),
        ("tree check examples/trees/grasp_then_place_learned.yaml", []),
        ("tree show examples/trees/grasp_then_place.yaml", []),
        ("tree nodes", []),
        ("tree nodes Throw", []),
        ("tree show examples/trees/ball_in_cup.yaml", []),
        ("tree show examples/trees/stack_learned.yaml", []),
    ],
)
def test_a_listing_command_imports_only_what_it_needs(command, needs):
    result = subprocess.run(
        [sys.executable, "-c", CODE, *command.split()],
        cwd=REPOSITORY,
        capture_output=True,
        text=True,
        check=True,
    )
    assert result.stdout.strip() == f"0 {needs}", result.stderr
