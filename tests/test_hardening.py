"""Bad input on purpose: every case gets a clear error naming the file, field or value, before any work."""

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import py_trees
import pytest
from helpers import run_cli

from besman.core.errors import InputError
from besman.core.writer_lock import OutputBusyError
from besman.tasks import task
from besman.tasks.running import run
from besman.tasks.throwing.rollouts import BROKEN_REWARD, ThrowingRollouts
from besman.trees import TreeFileError, load_tree
from besman.trees.runner import node_paths

TREES = Path(__file__).resolve().parents[1] / "examples" / "trees"


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_yaml_anchors_and_aliases_are_refused_before_they_expand(tmp_path):
    """A "billion laughs": nine levels of ten aliases each would expand to 10^9 nodes."""
    lines = ["besman_tree: 1", 'a0: &a0 ["x"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    lines.append("root: {Wait: {name: w, duration: 0}}")
    path = tmp_path / "laughs.yaml"
    path.write_text("\n".join(lines))
    start = time.perf_counter()
    with pytest.raises(TreeFileError, match=r"laughs\.yaml:2: anchors and aliases .* are not supported"):
        load_tree(path)
    assert time.perf_counter() - start < 5.0


def test_deep_nesting_binary_and_huge_files_are_refused_by_name(tmp_path):
    deep = tmp_path / "deep.yaml"
    deep.write_text("besman_tree: 1\nroot: " + "{Inverter: {name: i, child: " * 300 + "{}" + "}}" * 300)
    with pytest.raises(TreeFileError, match=r"deep\.yaml:2: nested deeper than 200 levels"):
        load_tree(deep)
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"besman_tree: 1\nroot: \xff\xfe\x00")
    with pytest.raises(TreeFileError, match=r"binary\.yaml: not a text file \(byte 21 is not UTF-8\)"):
        load_tree(binary)
    huge = tmp_path / "huge.yaml"
    huge.write_text("#" * 1_000_001)
    with pytest.raises(TreeFileError, match=r"huge\.yaml: larger than 1000000 bytes"):
        load_tree(huge)
    with pytest.raises(TreeFileError, match="a directory, not a tree file"):
        load_tree(tmp_path)


def test_node_paths_are_linear_in_the_number_of_nodes():
    """10^5 siblings of one name: counting names per child was quadratic (minutes); a Counter is linear."""
    root = py_trees.composites.Sequence("root", memory=True)
    root.children = [py_trees.behaviours.Success("same") for _ in range(100_000)]
    for child in root.children:
        child.parent = root
    start = time.perf_counter()
    paths = node_paths(root)
    assert time.perf_counter() - start < 5.0
    assert len(paths) == 100_001 and paths[root.children[-1].id] == "root/same[99999]"


def test_no_command_writes_over_its_own_input(tmp_path, capsys, shared_recordings):
    recording = tmp_path / "run.tsv"
    recording.write_bytes((shared_recordings / "subject1_run1.tsv").read_bytes())
    before = recording.read_bytes()
    code, _, err = run_cli(capsys, "segment", str(recording), "--plot", str(recording))
    assert code == 2 and "--plot" in err and recording.read_bytes() == before
    assert "must end in .png" in err
    renamed = tmp_path / "run.png"
    renamed.write_bytes(before)  # an input that happens to end in .png
    code, _, err = run_cli(capsys, "segment", str(renamed), "--plot", str(renamed))
    assert code == 2 and "that is an input of this command" in err and renamed.read_bytes() == before
    tree = tmp_path / "tree.jsonl"
    tree.write_text((TREES / "grasp_then_place.yaml").read_text())
    code, _, err = run_cli(capsys, "run", str(tree), "--log", str(tree))
    assert code == 2 and "that is an input of this command" in err
    code, _, err = run_cli(capsys, "tree", "render", str(tree), "--out", str(tmp_path / "x.txt"))
    assert code == 2 and "must end in .svg or .png or .dot" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("demo", "--log", "{tmp}"), "a directory; give a file name"),
        (("demo", "--log", "{tmp}/file.txt/run.jsonl"), "is a file, not a folder"),
        (("demo", "--log", "{tmp}/run.txt"), "must end in .jsonl"),
        (("robots", "render", "aila", "--out", "{tmp}/file.txt/a.png"), "is a file, not a folder"),
    ],
)
def test_outputs_are_checked_before_the_work(tmp_path, capsys, argv, message):
    (tmp_path / "file.txt").write_text("a file where a folder is expected")
    start = time.perf_counter()
    code, out, err = run_cli(capsys, *(arg.format(tmp=tmp_path) for arg in argv))
    assert code == 2 and message in err and out == ""
    assert time.perf_counter() - start < 10.0  # refused up front, not after a run


def test_a_broken_throw_never_scores_better_than_a_failing_one():
    task = ThrowingRollouts()
    theta = task.default_theta()
    failing = [theta + 50.0, theta * 3.0, np.full_like(theta, 1e200)]  # far beyond the ranges and limits
    broken = [theta + np.nan, np.full_like(theta, np.inf), np.full_like(theta, 1e306)]  # the last overflows
    result = task.evaluate(np.array(failing + broken), [-3.5, -3.6], nan="penalize")
    assert all(detail.failure for detail in result.details)
    assert result.rewards[3:].max() <= result.rewards[:3].min()
    assert np.all(np.isfinite(result.rewards)) and result.rewards.min() == BROKEN_REWARD
    assert result.details[5].failure == "the reference overflows (theta too large)"


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (
            ("objet=0.55,-0.1,0",),
            "--set objet: not a value of task pick-place; its values: object, place, shape, size",
        ),
        (("place=0.5,-0.4,0", "place=0.6,-0.4,0"), "--set place: given twice"),
        (("object=nan,0.1,0",), "--set 'object=nan,0.1,0': the values must be finite numbers"),
        (("object=0.5,-0.1,inf",), "--set 'object=0.5,-0.1,inf': the values must be finite numbers"),
        (("shape=sphere",), "--set shape: 'sphere' is not one of box, cylinder"),
        (("object=near",), "--set object: takes numbers (object_x, object_y, object_yaw), got 'near'"),
        (("shap=cylinder",), "--set shap=cylinder: the values must be numbers separated by commas"),
    ],
)
def test_set_typos_repeats_and_non_finite_values_are_refused(capsys, sets, message):
    argv = ["run", str(TREES / "grasp_then_place.yaml")]
    for pair in sets:
        argv += ["--set", pair]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and message in err and out == ""


def _options(parser):
    """(command, option) of every option of every command of ``parser``."""
    from besman.cli import commands

    for path, command in commands(parser):
        for action in command._actions:
            if action.option_strings:
                yield " ".join(path), action


def test_every_numeric_option_has_a_range_that_the_parser_checks():
    from besman.cli import build_parser
    from besman.commands import options

    every = list(_options(build_parser()))
    unchecked = [(command, a.option_strings) for command, a in every if a.type in (int, float)]
    assert unchecked == []  # a bare int or float takes any number
    assert sum(a.type is not None and a.type.__module__ == options.__name__ for _, a in every) >= 13


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ("experiment", "throwing", "--out", "{tmp}/out", "--seeds", "0"),
            "argument --seeds: must be an integer >= 1, got 0",
        ),
        (
            ("view", "--replay", "{tmp}/log", "--port", "70000"),
            "argument --port: must be an integer from 0 to 65535, got 70000",
        ),
        (
            ("learn", "--demos", "{tmp}", "--out", "{tmp}/pool", "--budget", "-3"),
            "argument --budget: must be an integer >= 1, got -3",
        ),
        (
            ("learn", "--demos", "{tmp}", "--out", "{tmp}/pool", "--seed", "-1"),
            "argument --seed: must be an integer from 0 to",
        ),
        (("run", "{tmp}/tree.yaml", "--speed", "nan"), "argument --speed: must be a number above 0, got nan"),
        (("run", "{tmp}/tree.yaml", "--speed", "0"), "argument --speed: must be a number above 0, got 0"),
        (
            ("segment", "{tmp}/a.tsv", "--max-particles", "1"),
            "argument --max-particles: must be an integer >= 2, got 1",
        ),
        (
            ("robots", "render", "aila", "--out", "{tmp}/a.png", "--width", "zero"),
            "argument --width: must be an integer >= 1, got 'zero'",
        ),
    ],
)
def test_numeric_options_out_of_range_are_refused_by_name_before_any_work(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exit:
        run_cli(capsys, *(arg.format(tmp=tmp_path) for arg in argv))
    err = capsys.readouterr().err
    assert exit.value.code == 2 and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_besman_without_a_command_prints_help_and_fails(capsys):
    code, out, err = run_cli(capsys)
    assert code == 2 and out == "" and "usage: besman" in err


def test_demo_json_is_json_alone_and_the_prose_suggests_a_next_step(capsys):
    code, out, _ = run_cli(capsys, "demo", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["success"] and summary["demo"] == summary["task"] == "pick-place"
    measurements = task("pick-place").measurements
    assert summary["kind"] == "besman-run-summary" and set(summary["measurements"]) == set(measurements)
    code, out, _ = run_cli(capsys, "demo", "--seed", "4")
    assert code == 0 and "next: watch it in the browser (besman demo pick-place --view)" in out
    # The run it suggests is on another configuration than the one just run.
    assert "besman run examples/trees/grasp_then_place.yaml --robot aila --seed 5 --log run.jsonl" in out


def test_the_halves_of_pick_and_place_are_judged_by_their_tasks_and_place_alone_fails_clearly(capsys):
    """grasp.yaml is task pick (judged by the lift: the box in the hand, 5 cm up), place.yaml task place
    (the box starts in the hand; judged by the placement); place.yaml on pick-place, where the box stands on
    the table, fails at once and says why."""
    code, out, _ = run_cli(capsys, "run", str(TREES / "grasp.yaml"), "--seed", "1")
    assert code == 0 and out.startswith("SUCCESS: the box is in the hand, ") and "placement error" not in out
    code, out, _ = run_cli(capsys, "run", str(TREES / "grasp.yaml"), "--seed", "1", "--json")
    summary = json.loads(out)
    assert (
        code == 0
        and summary["task"] == "pick"
        and set(summary["measurements"]) == set(task("pick").measurements)
    )
    assert summary["measurements"]["held"] is True and summary["measurements"]["lift_m"] >= 0.045
    code, out, _ = run_cli(capsys, "run", str(TREES / "place.yaml"), "--seed", "1", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["success"] and summary["task"] == "place"
    assert summary["measurements"]["placement_error_m"] <= 0.02
    alone = run("pick-place", load_tree(TREES / "place.yaml"), seed=1)  # the box on the table: not held
    assert not alone.success and alone.failed_node is not None and alone.ticks == 1
    assert alone.message.startswith("not holding box") and alone.measurements["placement_error_m"] > 0.02
    with pytest.raises(InputError, match=r"place\.yaml: the tree is for task place, not pick-place"):
        run("pick-place", TREES / "place.yaml")


def test_written_files_honour_the_umask(tmp_path):
    """In a process of its own: the umask is read when the module loads (reloading it here would give the
    other tests' modules a second set of error classes)."""
    code = (
        "import os, sys; os.umask(0o027); from besman.core.storage import write_atomically; "
        "print(oct(os.stat(write_atomically(sys.argv[1], b'{}')).st_mode & 0o777))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "a.json")], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "0o640"


def test_tree_render_writes_dot_source_without_graphviz(tmp_path, capsys):
    code, _, _ = run_cli(
        capsys, "tree", "render", str(TREES / "grasp.yaml"), "--out", str(tmp_path / "t.dot")
    )
    assert code == 0 and (tmp_path / "t.dot").read_text().startswith("digraph")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"max_iterations": 0}, "max_iterations must be an integer >= 1"),
        ({"restarts": -1}, "restarts must be an integer >= 0"),
        ({"position_tolerance": float("nan")}, "position_tolerance must be a positive number"),
        ({"orientation_tolerance": 0.0}, "orientation_tolerance must be a positive number"),
    ],
)
def test_solve_ik_refuses_meaningless_settings(options, message):
    from besman.robots import load, solve_ik

    with pytest.raises(InputError, match=message):
        solve_ik(load("pa10"), "arm", [0.3, 0.0, 1.0], **options)


def test_example_labels_without_examples_is_an_error(capsys, shared_recordings):
    recording = shared_recordings / "subject1_run1.tsv"
    code, _, err = run_cli(capsys, "segment", str(recording), "--example-labels", "reach")
    assert code == 2 and "give --examples too" in err


def _damaged_recording(shared_recordings, tmp_path, change) -> Path:
    """The first 300 samples of a shared recording with ``change(rows)`` applied to the data rows (cells)."""
    lines = (shared_recordings / "subject1_run1.tsv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("Frame\t"))
    rows = [line.split("\t") for line in lines[header + 1 : header + 301]]
    change(rows)
    path = tmp_path / "damaged.tsv"
    path.write_text("\n".join(lines[: header + 1] + ["\t".join(row) for row in rows]) + "\n")
    return path


def _set(row: int, column: int, text: str):
    def change(rows):
        rows[row][column] = text

    return change


def _shift_times(row: int, seconds: float):
    def change(rows):
        for cells in rows[row:]:
            cells[1] = f"{float(cells[1]) + seconds:.5f}"

    return change


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_set(100, 5, "inf"), r":\d+: column '.*' holds 'inf', not a plausible value"),
        (_set(100, 5, "1e308"), r":\d+: column '.*' holds '1e308', not a plausible value"),
        (_shift_times(150, 100.0), r":\d+: Time jumps by 100\.\d+ s"),
        (_shift_times(150, 10_000.0), r":\d+: Time jumps by 1000\d s"),
        (_set(151, 0, "150"), r":\d+: Frame must increase"),
    ],
)
def test_damaged_recordings_are_refused_naming_file_row_and_column(
    tmp_path, capsys, shared_recordings, change, message
):
    from besman.learning import DemonstrationError, load

    path = _damaged_recording(shared_recordings, tmp_path, change)
    with pytest.raises(DemonstrationError, match=r"damaged\.tsv" + message):
        load(path)
    code, _, err = run_cli(capsys, "segment", str(path))
    assert code == 2 and "damaged.tsv" in err


@pytest.mark.parametrize(
    ("node", "message"),
    [
        (
            "Repeat: {name: r, times: 0, child: {Wait: {name: w, duration: 0}}}",
            "root.Repeat.times: must be at least 1",
        ),
        (
            "Retry: {name: r, attempts: -2, child: {Wait: {name: w, duration: 0}}}",
            "root.Retry.attempts: must be at least 1",
        ),
        (
            "ObjectAt: {name: o, object: box, position: [0.5]}",
            "root.ObjectAt.position: needs 2 or 3 or 4 numbers, got 1",
        ),
        (
            "ObjectAt: {name: o, object: box, tolerance: -0.1}",
            "root.ObjectAt.tolerance: must be greater than 0",
        ),
        (
            "Timeout: {name: t, duration: 0, child: {Wait: {name: w, duration: 0}}}",
            "root.Timeout.duration: must be greater than 0",
        ),
        ("Wait: {name: w, duration: nan}", "root.Wait.duration: expected a finite number"),
        (
            "Parallel: {name: p, policy: sometimes, children: [{Wait: {name: w, duration: 0}}]}",
            "root.Parallel.policy: must be one of all, one, got 'sometimes'",
        ),
        ("Gripper: {name: g, action: open, timeout: -1}", "root.Gripper.timeout: must be greater than 0"),
    ],
)
def test_tree_values_are_checked_at_load_with_file_and_line(tmp_path, node, message):
    path = tmp_path / "values.yaml"
    path.write_text(f"besman_tree: 1\nroot:\n  {node}\n")
    with pytest.raises(
        TreeFileError, match=r"values\.yaml:3: " + message.replace(".", r"\.").replace("[", r"\[")
    ):
        load_tree(path)


@pytest.mark.slow
def test_a_long_recording_is_segmented_by_pruned_inference_automatically(tmp_path, capsys, shared_recordings):
    """Six runs one after the other (about 90 s): past a minute, segment() prunes to 50 candidates (linear
    time and memory) unless asked for exact inference."""
    from besman.learning import load
    from besman.learning.segmentation.segmenter import EXACT_UP_TO, segment

    lines, frame, time_offset = None, 0, 0.0
    for k in range(1, 7):
        source = (shared_recordings / f"subject1_run{k}.tsv").read_text().splitlines()
        header = next(i for i, line in enumerate(source) if line.startswith("Frame\t"))
        lines = lines or source[: header + 1]
        first = source[header + 1].split("\t")
        start_frame, start_time = int(first[0]), float(first[1])
        for line in source[header + 1 :]:
            cells = line.split("\t")
            cells[0] = str(frame + 1 + int(cells[0]) - start_frame)
            cells[1] = f"{time_offset + float(cells[1]) - start_time:.5f}"
            lines.append("\t".join(cells))
        frame, time_offset = int(lines[-1].split("\t")[0]), float(lines[-1].split("\t")[1]) + 0.01
    path = tmp_path / "long.tsv"
    path.write_text("\n".join(lines) + "\n")
    demo = load(path)
    assert demo.duration * 20 > EXACT_UP_TO
    automatic = segment(demo)
    np.testing.assert_array_equal(automatic.boundaries, segment(demo, max_particles=50).boundaries)
    code, out, _ = run_cli(capsys, "segment", str(path), "--json")
    assert code == 0 and json.loads(out)["boundaries_frame"] == [int(f) for f in automatic.frames]


def test_an_interrupted_run_leaves_a_whole_log_and_one_line(tmp_path, capsys, monkeypatch):
    """Ctrl-C in the middle of a run: the log holds the ticks so far and an INTERRUPTED result, and the
    command says so in one line (exit 130)."""
    from besman.sim.executor import Executor
    from besman.trees.runner import read_log

    calls = {"count": 0}
    advance = Executor.advance

    def interrupted_advance(self, cycles):
        calls["count"] += 1
        if calls["count"] == 40:
            raise KeyboardInterrupt
        return advance(self, cycles)

    monkeypatch.setattr(Executor, "advance", interrupted_advance)
    log = tmp_path / "run.jsonl"
    code, _, err = run_cli(
        capsys, "run", str(TREES / "grasp_then_place.yaml"), "--seed", "1", "--log", str(log)
    )
    assert code == 130 and err.strip().splitlines() == [
        f"besman: interrupted ({log} holds the run up to here)"
    ]
    header, records, result = read_log(log)
    assert header["kind"] == "besman-run-log" and len(records) == 40 and result["status"] == "INTERRUPTED"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["run.jsonl"]  # no temporary or lock file


def test_two_runs_cannot_write_the_same_log(tmp_path):
    from besman.trees.runner import LogStream

    first = LogStream(tmp_path / "run.jsonl", {})
    holder = re.escape(f"--log {tmp_path / 'run.jsonl'}: in use by pid {os.getpid()} (")
    with pytest.raises(OutputBusyError, match=holder):
        LogStream(tmp_path / "run.jsonl", {})
    first.abandon()
    LogStream(tmp_path / "run.jsonl", {}).abandon()  # free again


def test_the_readme_recording_examples_run_from_the_shipped_recordings(tmp_path, capsys):
    data = Path(__file__).resolve().parents[1] / "examples" / "data"
    assert (data / "LICENSE").read_text().startswith("Copyright 2018-2022 Lisa Gutzeit")
    assert run_cli(capsys, "recordings", "show", str(data / "subject1_run1.tsv"))[0] == 0
    code, out, _ = run_cli(
        capsys,
        "segment",
        str(data / "subject1_run1.tsv"),
        "--json",
        "--plot",
        str(tmp_path / "segments.png"),
        "--examples",
        str(data / "subject2_run1.tsv"),
    )
    assert code == 0 and (tmp_path / "segments.png").stat().st_size > 1000
    labels = {segment["label"] for segment in json.loads(out)["segments"]}
    assert len(labels - {None}) >= 4  # the movements get the example's building-block labels


def test_unreadable_files_and_impossible_requests_get_one_clear_line(tmp_path, capsys):
    data = Path(__file__).resolve().parents[1] / "examples" / "data"
    noise = np.random.default_rng(0).bytes(3000)
    (tmp_path / "noise.npz").write_bytes(noise)
    (tmp_path / "noise.csv").write_bytes(noise)
    code, _, err = run_cli(capsys, "recordings", "show", str(tmp_path / "noise.npz"))
    assert code == 2 and "never does" in err and "allow_pickle" not in err
    code, _, err = run_cli(capsys, "recordings", "show", str(tmp_path / "noise.csv"))
    assert code == 2 and err.isascii() and "a binary file" in err
    lines = (data / "subject1_run1.tsv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("Frame\t"))
    hand = [i for i, name in enumerate(lines[header].split("\t")) if name.startswith("Hand top ")]
    still = lines[: header + 1]
    for line in lines[header + 1 :]:
        cells = line.split("\t")
        for i in hand:
            cells[i] = "100.0"
        still.append("\t".join(cells))
    (tmp_path / "still.tsv").write_text("\n".join(still) + "\n")
    code, _, err = run_cli(capsys, "segment", str(tmp_path / "still.tsv"))
    assert code == 2 and "marker 'Hand top' does not move" in err
    from besman.skills import DMP

    with pytest.raises(InputError, match=r"run_time 10000 s at dt 0.001 s is 1e\+07 steps; at most 20000"):
        DMP(7, dt=0.001).trajectory(run_time=1e4)


def _wrong_names():
    """Every public lookup by name, with a name that does not exist (evaluated lazily, one world shared)."""
    from besman import robots
    from besman.learning import segment
    from besman.sim.block_simulation import check_block
    from besman.sim.executor import Executor
    from besman.sim.world import tabletop_world
    from besman.skills import SkillTemplatePool
    from besman.tasks.pick_place.blocks import start as block_start
    from besman.tasks.running import run_demo
    from besman.trees.reference import node_reference

    world = tabletop_world()
    robot, executor = world.robot, Executor(world)
    pool = SkillTemplatePool(Path(__file__).resolve().parents[1] / "examples" / "pools" / "pick_place_aila")
    recording = load_recording()
    values = task("pick-place").default_values("aila")
    return {
        "robots.load": lambda: robots.load("nosuch"),
        "robots.describe": lambda: robots.describe("nosuch"),
        "Robot.group": lambda: robot.group("nosuch"),
        "Robot.arm": lambda: robot.arm("nosuch"),
        "Robot.reset keyframe": lambda: robot.reset(world.data, "nosuch"),
        "World.surface": lambda: world.surface("nosuch"),
        "World.object_pose": lambda: world.object_pose("nosuch"),
        "World.place_on object": lambda: world.place_on("nosuch", "table", 0.5, 0.0),
        "World.place_on surface": lambda: world.place_on("box", "nosuch", 0.5, 0.0),
        "Hand.holds": lambda: executor.hand.holds("nosuch"),
        "Executor.arm_executor": lambda: executor.arm_executor("nosuch"),
        "SkillTemplatePool[]": lambda: pool["nosuch"],
        "SkillTemplatePool.remove": lambda: pool.remove("nosuch"),
        "task": lambda: task("nosuch"),
        "pick_place.blocks.start": lambda: block_start(world, "nosuch", task("pick-place").join(values)),
        "check_block": lambda: check_block("nosuch"),
        "run_demo": lambda: run_demo("nosuch"),
        "run task value": lambda: run("pick-place", values={"nosuch": (0.5, 0.0)}),
        "node_reference": lambda: node_reference("nosuch"),
        "Demonstration.channel": lambda: recording.channel("nosuch"),
        "segment marker": lambda: segment(recording, marker="nosuch"),
    }


def load_recording():
    from besman.learning import load

    return load(Path(__file__).resolve().parents[1] / "examples" / "data" / "subject1_run1.tsv")


def test_every_public_lookup_of_a_wrong_name_raises_a_besman_error_naming_it():
    from besman.core.errors import BesmanError

    for what, call in _wrong_names().items():
        with pytest.raises(BesmanError) as raised:
            call()
        assert "nosuch" in str(raised.value), (what, str(raised.value))


def test_a_learned_tree_with_a_damaged_pool_entry_is_refused_before_its_first_tick(tmp_path, capsys):
    import shutil

    pool = tmp_path / "pool"
    shutil.copytree(Path(__file__).resolve().parents[1] / "examples" / "pools" / "pick_place_aila", pool)
    arrays = pool / "carry.npz"
    data = bytearray(arrays.read_bytes())
    data[len(data) // 2] ^= 0xFF
    arrays.write_bytes(bytes(data))
    log = tmp_path / "run.jsonl"
    tree = TREES / "grasp_then_place_learned.yaml"
    start = time.perf_counter()
    code, out, err = run_cli(capsys, "run", str(tree), "--pool", str(pool), "--log", str(log))
    assert code == 2 and out == "", err
    assert "template 'carry'" in err and "carry.npz" in err, err
    assert time.perf_counter() - start < 10.0 and not log.exists()  # no episode ran


def test_a_learned_tree_on_another_robot_than_its_pool_was_learned_on_is_refused_at_setup(capsys):
    """The tree's pool is the robot's own (``pick_place_{robot}``); AILA's pool given for the UR5e is
    refused."""
    aila_pool = TREES.parent / "pools" / "pick_place_aila"
    argv = ["run", str(TREES / "grasp_then_place_learned.yaml"), "--robot", "ur5e", "--pool", str(aila_pool)]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert "was learned on 'aila', this run is on 'ur5e'" in err, err


@pytest.mark.slow
@pytest.mark.parametrize("command", ["run", "learn"])
def test_ctrl_c_at_any_moment_prints_one_line_and_leaves_only_whole_files(
    tmp_path, command, shared_recordings
):
    """Ctrl-C 0.2, 0.5, 1, 2 and 4 s into ``besman run --log`` and ``besman learn``: exit 130, no traceback,
    the last line says what was interrupted, and whatever was written is whole."""
    import subprocess
    import sys

    from helpers import is_whole, sigint_by_default

    from besman.trees.runner import read_log

    demos = tmp_path / "demos"
    demos.mkdir()
    for name in ("subject1_run1.tsv", "subject2_run1.tsv"):
        (demos / name).symlink_to(shared_recordings / name)
    script = Path(sys.executable).parent / "besman"  # the installed command, as a user starts it
    for delay in (0.2, 0.5, 1.0, 2.0, 4.0):
        out = tmp_path / f"{command}-{delay}"
        argv = {
            # The learned tree: long enough (online refinement) that every Ctrl-C lands before its end.
            "run": [
                "run",
                str(TREES / "grasp_then_place_learned.yaml"),
                "--seed",
                "3",
                "--log",
                f"{out}.jsonl",
            ],
            "learn": [
                "learn",
                "--demos",
                str(demos),
                "--out",
                str(out),
                "--training-tasks",
                "2",
                "--budget",
                "4",
            ],
        }[command]
        process = subprocess.Popen(
            [str(script), *argv],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=sigint_by_default,
        )
        time.sleep(delay)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 130, (delay, err)
        assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("besman: interrupted"), err
        written = [p for p in tmp_path.rglob("*") if p.is_file() and p.suffix in (".json", ".npz", ".png")]
        assert all(is_whole(p) for p in written), delay
        log = Path(f"{out}.jsonl")
        if log.exists():
            read_log(log)  # a whole log: header, records, result


@pytest.mark.parametrize("hooked", [True, False])
def test_a_ctrl_c_that_python_would_only_report_is_raised_again(hooked):
    """A Ctrl-C that lands in a callback whose exceptions Python only reports (here a ``__del__``; in the
    suite once an import lock's weakref callback) is raised again where it stops the command; without the
    hook the program runs on (the control case)."""
    import subprocess
    import sys

    from helpers import sigint_by_default

    install = "sys.unraisablehook = besman.stopping.ctrl_c_again(sys.unraisablehook)" if hooked else ""
    code = "\n".join(
        [
            "import sys, time, besman",
            install,
            "class Interrupted:",
            "    def __del__(self):",
            "        raise KeyboardInterrupt",
            "try:",
            "    Interrupted()",
            "    time.sleep(2)",
            "    print('ran on')",
            "except KeyboardInterrupt:",
            "    print('interrupted')",
        ]
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, preexec_fn=sigint_by_default
    )
    assert result.stdout.strip() == ("interrupted" if hooked else "ran on"), result.stderr
    assert ("Exception ignored" in result.stderr) is not hooked


def test_a_ctrl_c_during_a_progress_bar_ends_the_bar_before_its_one_line():
    """A progress bar the Ctrl-C left drawn ends its line first, so that ``besman: interrupted`` is a line of
    its own, the last (without this, the two shared a line: seen in the suite, a learn stopped 0.2 s in)."""
    import subprocess
    import sys

    from helpers import sigint_by_default

    code = "\n".join(
        [
            "import sys, time",
            "from tqdm import tqdm",
            "from besman.stopping import stopped",
            "try:",
            "    for _ in tqdm(range(10), desc='segmenting'):",
            "        print('drawn', flush=True)",
            "        time.sleep(10)",
            "except KeyboardInterrupt:",
            "    sys.exit(stopped())",
        ]
    )
    process = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=sigint_by_default,
    )
    assert process.stdout.readline() == "drawn\n"
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=30)
    lines = err.splitlines()
    assert process.returncode == 130 and lines[-1] == "besman: interrupted", err
    assert lines[-2].startswith("segmenting:")
