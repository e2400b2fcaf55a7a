"""The comfort benchmark (``benchmarks/comfort.py``) runs on one held-out task and writes complete, plausible
JSON and its figure."""

import json
import math

from helpers import BENCHMARKS

from besman.tasks import task


def test_comfort_benchmark_reports_jerk_cycle_time_and_the_peoples_durations(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import comfort

    out = tmp_path / "comfort.json"
    assert comfort.main(["--robots", "aila", "--count", "1", "--workers", "1", "--out", str(out)]) == 0
    assert "reach_peak_jerk" in capsys.readouterr().out  # the table
    report = json.loads(out.read_text())
    assert out.with_suffix(".png").stat().st_size > 0
    assert report["count"] == 1 and report["perturb"] is None
    assert set(report["bars"]) == {"reach_peak_jerk", "carry_peak_jerk", "cycle_s"}
    limit = task("pick-place").max_sim_time
    found = report["robots"]["aila"]
    assert set(found["trees"]) == {"learned", "scripted"}
    for tree in found["trees"].values():
        assert tree["runs"] == 1 and tree["success"] == 1, tree["failures"]
        for key in ("reach_peak_jerk", "carry_peak_jerk", "peak_jerk_to_placement"):
            assert 0 < tree[key]["median"] <= tree[key]["p90"] < 1000, key
        assert 0 < tree["reach_joint_jerk_share"]["median"] <= 1.01  # Ruckig keeps the joints' jerk limits
        for key in ("reach_s", "carry_s", "grasp_to_release_s"):
            assert 0 < tree[key]["median"] < tree["cycle_s"]["median"], key
        assert 0 < tree["cycle_s"]["median"] < limit
    for key, ratio in found["ratios"].items():
        assert ratio["pairs"] == 1 and math.isfinite(ratio["ratio"]) and ratio["ratio"] > 0, key
        assert ratio["interval"] == [ratio["ratio"], ratio["ratio"]]
        if key in report["bars"]:
            assert ratio["met"] == (ratio["ratio"] <= 1.0)
    human = report["human"]
    assert human["recordings"] >= 2 and isinstance(human["fallback_to_examples"], bool)
    for key in ("reach_s", "carry_s", "grasp_to_release_s", "pick_to_place_s"):
        assert 0 < human[key]["min"] <= human[key]["median"] <= human[key]["max"] < 30, key
    assert human["pick_to_place_s"]["median"] > human["reach_s"]["median"]
