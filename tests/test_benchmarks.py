"""The benchmark scripts run and report ratios as JSON (speed itself is claimed by the scripts, not tests)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.slow
def test_dmp_benchmark_reports_every_case_as_json():
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / "dmp.py"), "--json", "--repeats", "1"],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(result.stdout)
    assert [case["name"][:3] for case in report["cases"]] == ["(a)", "(b)", "(c)", "(d)"]
    for case in report["cases"]:
        assert case["ratio"] == pytest.approx(case["theirs_s"] / case["ours_s"])
        assert case["ours_s"] > 0 and case["theirs_s"] > 0


@pytest.mark.slow
def test_rollouts_benchmark_reports_ratios_as_json():
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / "rollouts.py"), "--json", "--repeats", "1"],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(result.stdout)
    throwing = report["throwing"]
    assert throwing["ours_vs_raw"] == pytest.approx(
        throwing["ours_steps_per_s"] / throwing["raw_rollout_steps_per_s"]
    )
    assert throwing["steps"] == 64 * 1500
    assert report["pick_and_place"]["succeeded"] == report["pick_and_place"]["episodes"]
    assert report["pick_and_place"]["real_time_factor"] > 0


@pytest.mark.slow
def test_trees_benchmark_reports_overhead_and_real_time_factor():
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / "trees.py"), "--json", "--runs", "1"],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(result.stdout)
    assert report["overhead_per_tick_us"] == pytest.approx(report["tick_us"] + report["record_us"])
    assert report["real_time_factor"] > 0


@pytest.mark.slow
def test_segmentation_benchmark_compares_every_method_as_json(shared_recordings):
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / "segmentation.py"), "--json", "--data", str(shared_recordings)],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(result.stdout)
    assert report["recordings"] == 15
    assert set(report["methods"]) == {
        "ours",
        "ours (pruned, 50 particles)",
        "speed minima",
        "ruptures Pelt (linear)",
        "ruptures Dynp (linear)",
    }
    best_other = max(s["f1_0.2"] for name, s in report["methods"].items() if not name.startswith("ours"))
    assert report["ours_vs_best_other_f1_0.2"] == pytest.approx(
        report["methods"]["ours"]["f1_0.2"] / best_other
    )
    assert report["ours_best_f1"] and report["methods"]["ours"]["seconds"] < 1.0
    long = report["long_recording"]
    assert long["duration_s"] > 100 and long["pruned_vs_exact_f1_0.1"] > 0.9
