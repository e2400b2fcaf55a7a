"""The benchmark scripts run and report complete, sane JSON; their speed targets are claimed by the scripts
themselves (side by side in one run), not asserted here."""

import math
import shutil
import subprocess
import sys

import pytest
from helpers import run_benchmark

from besman.cli import build_parser, commands


def _ratio_of(entry: dict, ours: str, theirs: str) -> float:
    return entry[theirs] / entry[ours]


@pytest.mark.slow
def test_dmp_benchmark_reports_every_case_as_json():
    report = run_benchmark("dmp.py", "--repeats", "1")
    assert report["benchmark"] == "dmp"
    assert [case["name"][:3] for case in report["cases"]] == ["(a)", "(b)", "(c)", "(d)"]
    for case in report["cases"]:
        assert case["ours_s"] > 0 and case["ours_cold_s"] > 0 and case["theirs_s"] > 0
        assert case["ratio"] == pytest.approx(_ratio_of(case, "ours_s", "theirs_s"))
        assert case["target"] >= 1.0 and case["met"] == (case["ratio"] >= case["target"])


@pytest.mark.slow
def test_rollouts_benchmark_reports_ratios_as_json():
    report = run_benchmark("rollouts.py", "--repeats", "1")
    throwing = report["throwing"]
    assert throwing["steps"] == 64 * 1500
    assert throwing["ours_vs_raw"] == pytest.approx(
        throwing["ours_steps_per_s"] / throwing["raw_rollout_steps_per_s"]
    )
    assert throwing["ours_vs_naive"] == pytest.approx(
        throwing["ours_steps_per_s"] / throwing["naive_loop_steps_per_s"]
    )
    assert set(throwing["targets"]) == {"ours_vs_raw", "ours_vs_naive"}
    place = report["pick_and_place"]
    assert place["succeeded"] == place["episodes"] == 3
    assert place["real_time_factor"] == pytest.approx(place["simulated_s"] / place["wall_s"])
    blocks = report["block_rollouts"]
    assert blocks["same_rewards"] is True and blocks["rollouts"] == 4
    assert blocks["speedup"] == pytest.approx(blocks["cycle_by_cycle_s"] / blocks["chunked_s"])
    assert place["simulated_s"] > 3 * 5.0, "three whole episodes of several seconds each were simulated"


@pytest.mark.slow
def test_trees_benchmark_compares_the_tree_with_raw_physics():
    report = run_benchmark("trees.py", "--runs", "1")
    assert report["overhead_per_tick_us"] == pytest.approx(report["tick_us"] + report["record_us"])
    assert 0 < report["tick_us"] < report["longest_tick_ms"] * 1000
    assert report["ratios_to_raw"] == [pytest.approx(report["ratio_to_raw"])]  # one run: its own ratio
    assert 0 < report["ratio_to_raw"] < 1, "the tree runs the same physics and more"
    assert report["target_ratio_to_raw"] == 0.3


@pytest.mark.slow
def test_policy_search_benchmark_sets_the_optimisers_beside_their_rollouts():
    report = run_benchmark("policy_search.py", "--generations", "2")
    assert report["benchmark"] == "policy_search" and report["dimensions"] == 96
    for method in ("cmaes", "xnes"):
        numbers = report[method]
        assert numbers["population"] == 17
        assert 0 < numbers["optimizer_ms_per_generation"] < numbers["rollouts_ms_per_generation"]
        assert numbers["overhead"] == pytest.approx(
            numbers["optimizer_ms_per_generation"] / numbers["rollouts_ms_per_generation"]
        )
        assert numbers["target_overhead"] == 0.1


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("chromium") is None, reason="needs Debian's chromium (apt-get install chromium)"
)
def test_viewer_benchmark_reports_its_cost_beside_the_run():
    report = run_benchmark("viewer.py", "--runs", "1")
    assert report["benchmark"] == "viewer" and 0 < report["update_ms"] < 1000
    assert report["real_time_factor_without_viewer"] > 0 and report["real_time_factor_with_viewer"] > 0
    assert report["viewer_share_of_wall_time"] == pytest.approx(
        1 - report["real_time_factor_with_viewer"] / report["real_time_factor_without_viewer"]
    )
    assert 0 < report["server_side_share_of_wall_time"] < 1 and report["target_share"] == 0.2
    assert report["frames_per_second"] > 0


@pytest.mark.slow
def test_segmentation_benchmark_compares_every_method_as_json(shared_recordings, tmp_path):
    # Five of the fifteen recordings, both subjects (the whole set takes ten minutes; its figures are in
    # docs/learning.md): every method, fold and score is computed the same way.
    data = tmp_path / "recordings"
    data.mkdir()
    for name in ("subject1_run1", "subject1_run2", "subject1_run3", "subject2_run1", "subject2_run2"):
        for suffix in (".tsv", "_manually_segmented.json"):
            (data / f"{name}{suffix}").symlink_to(shared_recordings / f"{name}{suffix}")
    plot = tmp_path / "segmentation.png"
    report = run_benchmark("segmentation.py", "--data", str(data), "--plot", str(plot))
    assert plot.read_bytes().startswith(b"\x89PNG")
    assert report["recordings"] == 5
    methods = report["methods"]
    assert set(methods) == {
        "ours, nothing tuned",
        "ours, tuned on labels",
        "ours, tuned on labels (pruned, 50 particles)",
        "speed minima",
        "ruptures Pelt (linear)",
        "ruptures Dynp (linear)",
    }
    folds = [
        "subject 1 (settings from subject 2)",
        "subject 2 (settings from subject 1)",
        "all (leave one recording out)",
    ]
    assert report["subjects"] == {"1": 3, "2": 2}
    for rows in methods.values():
        assert list(rows) == folds
        for scores in rows.values():
            assert 0 <= scores["f1_0.1"] <= scores["f1_0.2"] <= 1
            assert scores["hausdorff_s"] > 0 and scores["seconds"] > 0
        # One setting chosen on the other subject; one per held-out recording at most.
        assert len(rows[folds[0]]["settings"]) == len(rows[folds[1]]["settings"]) == 1
        assert 1 <= len(rows[folds[2]]["settings"]) <= 5
    for fold in folds:
        for key in ("f1_0.1", "f1_0.2"):
            assert report["ours_minus_speed_minima"][fold][key] == pytest.approx(
                methods["ours, nothing tuned"][fold][key] - methods["speed minima"][fold][key]
            )
    assert methods["ours, nothing tuned"][folds[2]]["settings"] == ["null"]  # the defaults: nothing chosen
    long = report["long_recording"]
    assert long["duration_s"] > 50 and math.isfinite(long["exact_seconds"])
    assert 0.9 < long["pruned_vs_exact_f1_0.1"] <= 1


@pytest.mark.slow
def test_learned_benchmark_compares_the_three_trees_as_json():
    # One task (docs/learning.md's 100: the full run): every tree, measure and target is computed as there.
    report = run_benchmark("learned.py", "--count", "1")
    assert report["benchmark"] == "learned" and report["count"] == 1 and report["robot"] == "aila"
    assert set(report["trees"]) == {"ik", "zero-shot", "promp"}
    for name, row in report["trees"].items():
        assert 0.0 <= row["success_rate"] <= 1.0
        assert row["mean_episode_s"] > 0 and row["mean_path_length_m"] > 0
        placed = row["mean_path_length_to_placement_m"]
        assert 0 < placed <= row["mean_path_length_m"]  # the learned tree's return home comes after
        assert (placed == row["mean_path_length_m"]) == (name == "ik")
        assert row["met"] is None if name == "promp" else row["met"] in (True, False)


@pytest.mark.slow
def test_ik_answers_benchmark_compares_kept_answers_with_none_and_finds_the_same_outcomes():
    report = run_benchmark("ik_answers.py", "--task", "stack", "--episodes", "1")
    assert report["benchmark"] == "ik_answers" and report["answers_kept"] > 0
    assert report["same_outcomes"] is True
    assert 0 < report["solves"]["kept"] < report["solves"]["none kept"]  # a stack asks again (a sort may not)
    assert all(len(seconds) == 1 and seconds[0] > 0 for seconds in report["process_s"].values())


def test_startup_benchmark_times_every_help_listing_and_first_tick_beside_a_bare_python():
    report = run_benchmark("startup.py", "--runs", "1")
    rows = report["commands"]
    timed = {
        kind: [name.split()[1:] for name, row in rows.items() if row["kind"] == kind]
        for kind in report["targets_s"]
    }
    assert ["--help"] in timed["help"] and ["learn", "--help"] in timed["help"] and len(timed["help"]) >= 20
    # Every subcommand that lists, shows or checks is timed with real arguments (one that simulates to its
    # first line), and so are the commands that list without a subcommand of their own.
    answering = timed["listing"] + timed["first line"]
    for path, _ in commands(build_parser()):
        if path and path[-1] in ("ls", "show", "check", "nodes", "schema"):
            assert any(argv[: len(path)] == list(path) for argv in answering), path
    for argv in (["demo", "--list"], ["tasks"], ["robots"], ["examples"]):
        assert argv in timed["listing"]
    assert ["demo"] in timed["first tick"] and any(argv[0] == "run" for argv in timed["first tick"])
    for row in rows.values():
        target = report["targets_s"][row["kind"]]
        assert row["s"] > 0 and row["over_python_s"] == pytest.approx(row["s"] - report["python_s"])
        assert row["ratio"] == pytest.approx(row["s"] / report["python_s"])
        assert row["target_s"] == target and row["met"] == (row["s"] < target)
    assert report["missed"] == [name for name, row in rows.items() if not row["met"]]
    assert report["met"] == (not report["missed"])


def test_the_command_line_loads_without_the_heavy_libraries():
    """What ``besman --help`` imports: none of scipy, scikit-learn, mujoco, ray or numpy (each command
    imports what it uses when it runs)."""
    heavy = ("scipy", "sklearn", "mujoco", "ray", "numpy")
    code = f"import sys, besman.cli; print([m for m in {heavy!r} if m in sys.modules])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
