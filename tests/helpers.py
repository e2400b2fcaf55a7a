"""What several test files share: running the command line and the benchmarks, comparing rotations."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from besman.cli import main

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
LEARNED_TREE = Path(__file__).resolve().parents[1] / "examples" / "trees" / "grasp_then_place_learned.yaml"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``besman ARGV`` in this process: (exit code, stdout, stderr)."""
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def run_benchmark(script: str, *argv: str) -> dict:
    """The JSON report of ``benchmarks/SCRIPT --json ARGV`` (a failing script fails the test)."""
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--json", *argv],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(result.stdout)


def rotation_angle(q1, q2) -> np.ndarray:
    """The angle (rad) between rotations given as (w, x, y, z) quaternions (q and -q are the same)."""
    dot = np.abs(np.sum(np.asarray(q1) * np.asarray(q2), axis=-1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def failed_placements(pool: Path, taus, robot: str = "aila") -> list[tuple]:
    """The learned tree with ``pool``'s templates on ``robot`` at every tau of ``taus`` (each checked to be
    no training task of them), zero shot (the templates' means; online refinement off, as
    ``benchmarks/learned.py``'s zero-shot tree): the runs that did not succeed (the box farther than the
    placement tolerance from its target, or the tree failing)."""
    from besman.sim.pick_place import pick_place_bounds
    from besman.skills import SkillTemplatePool
    from besman.trees.files import loads_tree
    from besman.trees.tabletop import run_on_tabletop

    names = pick_place_bounds(robot).names
    templates = SkillTemplatePool(pool)
    for name in templates:
        columns = [names.index(n) for n in templates[name].box.names]
        for tau in taus:
            distances = np.abs(templates[name].taus - np.asarray(tau)[columns]).max(axis=1)
            assert distances.min() > 1e-3, f"{tau} is a training task of {name!r}"
    text = LEARNED_TREE.read_text()
    assert "refine_above: 0.08" in text
    zero_shot = text.replace("refine_above: 0.08", "refine_above: 1.0e9")
    failed = []
    for tau in taus:
        tree = loads_tree(zero_shot, base=LEARNED_TREE.parent, source=LEARNED_TREE.name, pool=pool)
        summary = run_on_tabletop(tree, {"object": tuple(tau[:2]), "place": tuple(tau[2:])}, robot=robot)
        if not summary["success"] or summary["placement_error_m"] is None:
            failed.append((tuple(tau), summary["status"], summary["placement_error_m"], summary["message"]))
    return failed
