"""``besman learn --refinement sequence``: the blocks and their subgoals refined together on whole-task
rollouts, and the learned tree that carries the subgoals. Its own file, so that the suite's workers run it
beside the other learns."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml
from test_learning_pipeline import _learn

from besman.learning.pipeline.sequence_refinement import EVALUATION_ROLLOUTS
from besman.skills import SkillTemplatePool


@pytest.mark.slow
def test_a_learn_that_refines_the_sequence_writes_its_subgoals_into_the_tree(shared_recordings, tmp_path):
    """``--refinement sequence``: every training task refined on whole-task rollouts (cached per task, the
    budget counted in them), the templates from the refined thetas, and the tree beside the pool with the
    refined subgoals of the grasp and the place; it passes the check."""
    demos = tmp_path / "demos"
    demos.mkdir()
    for name in ("subject1_run1.tsv", "subject2_run1.tsv"):
        shutil.copy(shared_recordings / name, demos / name)
    out = _learn(
        demos, tmp_path / "pool", "--training-tasks", "2", "--budget", "8", "--refinement", "sequence"
    )
    record = json.loads((out / "work" / "learn.json").read_text())
    assert record["settings"]["refinement"] == "sequence"
    documents = [json.loads((out / "work" / "refined" / f"sequence-{k}.json").read_text()) for k in (0, 1)]
    assert all(d["rollouts"] == 8 and d["refinement"] == "sequence" for d in documents)
    for document in documents:  # judged on the paired evaluation rollouts: kept only beyond the noise
        verdict = document["acceptance"]
        assert verdict["evaluations"] == EVALUATION_ROLLOUTS and verdict["noise"] >= 0.0
        assert verdict["accepted"] == (verdict["improvement"] > verdict["noise"])
        assert (
            (document["after"] == document["refined"])
            if verdict["accepted"]
            else (document["after"] == document["before"])
        )
    pool = SkillTemplatePool(out)
    assert sorted(pool) == ["carry", "reach", "return"] and len(pool["reach"].taus) == 2
    tree = yaml.safe_load((out / "tree.yaml").read_text())
    steps = tree["root"]["Sequence"]["children"][0]["Retry"]["child"]["Selector"]["children"][1]
    steps = steps["Sequence"]["children"]
    grasp, place = steps[0]["Selector"]["children"][1]["Grasp"], steps[1]["Place"]
    refined = [d["subgoals"]["reach"]["approach_height"] for d in documents]
    assert grasp["approach_height"] == pytest.approx(float(np.median(refined)))
    assert {"approach_height", "grasp_height", "descend_time"} <= set(grasp)
    assert {"clearance", "release_height", "descend_time"} <= set(place)
    assert (
        subprocess.run([sys.executable, "-m", "besman", "tree", "check", str(out / "tree.yaml")]).returncode
        == 0
    )
