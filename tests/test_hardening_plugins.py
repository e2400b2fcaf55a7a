"""Hardening, fourth round (issue 52): one broken plugin breaks nothing, reads write nothing, and untrusted
JSON, tree includes, environment inputs and recordings get one-line errors naming the file and field."""

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import install_plugin, run_cli, snapshot

from besman import examples
from besman.core.errors import InputError
from besman.core.storage import check_output
from besman.learning.segmentation.demonstration import load
from besman.learning.segmentation.preprocessing import smooth
from besman.learning.segmentation.segmenter import MIN_PEAK_SPEED, NEAR_ORIGIN
from besman.skills.pool import PoolError, SkillTemplatePool
from besman.tasks import TASKS
from besman.tasks.environment import TaskEnv
from besman.trees import TreeFileError, load_tree
from besman.trees.files import MAX_INCLUDES
from besman.trees.runner import LOG_KIND
from tests.test_hardening_writes import small_space, tmpfs  # noqa: F401 (fixtures: a full disk, a size limit)

EXAMPLES = examples.path()

# Installed task plugins, as importlib.metadata finds them: a distribution's dist-info (its name, version and
# entry points) beside its module, in a folder on the path.
PLUGINS = {
    "besman-tidy": ("tidy", "import besman_tidy", "TASKS = (Tidy(),)"),
    "besman-broken": ("broken", "import a_dependency_not_installed", "TASKS = ()"),
    "besman-wrong": ("wrong", "", "TASKS = ('pick-place',)"),
    "besman-clash": ("clash", "", "TASKS = (Clash(),)"),
}
TASK_CLASSES = """
from besman.tasks.base import Task


class Tidy(Task):
    name, title, randomised, success, robot = "tidy", "put it away", "nothing", "always", "aila"


class Clash(Tidy):
    name, title = "pick-place", "a plugin's pick-place"
"""


@pytest.fixture(scope="module")
def plugins(tmp_path_factory) -> Path:
    site = tmp_path_factory.mktemp("site")
    (site / "besman_tidy.py").write_text(TASK_CLASSES)
    for dist, (name, imports, tasks) in PLUGINS.items():
        module = f"{name}_tasks"
        (site / f"{module}.py").write_text(f"{imports}\nfrom besman_tidy import *  # noqa\n{tasks}\n")
        install_plugin(site, dist, "besman.tasks", module, name)
    return site


def besman(*argv: str, plugins: Path) -> subprocess.CompletedProcess:
    """``besman ARGV`` with the plugins of the folder ``plugins`` installed."""
    path = os.pathsep.join(filter(None, [str(plugins), os.environ.get("PYTHONPATH")]))
    return subprocess.run(
        [sys.executable, "-m", "besman", *argv],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": path},
    )


@pytest.mark.parametrize("command", [["tasks"], ["demo", "--list"]])
def test_a_broken_plugin_is_named_in_one_warning_line_and_the_tasks_work(plugins, command):
    result = besman(*command, plugins=plugins)
    assert result.returncode == 0, result.stderr
    warnings = result.stderr.splitlines()
    assert len(warnings) == 3, result.stderr  # one line per broken plugin, no traceback
    broken, clash, wrong = sorted(warnings)  # by the plugins' names
    assert broken.startswith(
        "besman: warning: the task plugin 'broken' of the distribution besman-broken 1.0 "
    )
    assert "ModuleNotFoundError: No module named 'a_dependency_not_installed'" in broken
    assert "'wrong' of the distribution besman-wrong 1.0 is left out" in wrong and "'pick-place'" in wrong
    assert "'clash' of the distribution besman-clash 1.0: its task 'pick-place' is left out" in clash
    listed = [line.split(":" if command[0] == "demo" else "\t")[0] for line in result.stdout.splitlines()]
    demos = [name for name, entry in TASKS.items() if entry.tree is not None]
    assert listed == (demos if command[0] == "demo" else [*TASKS, "tidy"])  # the working plugin's too


def test_a_plugin_cannot_replace_a_builtin_task(plugins):
    result = besman("tasks", "show", "pick-place", plugins=plugins)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"pick-place on aila: {TASKS['pick-place'].title}\n")


# -- reads write nothing -----------------------------------------------------------------------------------


@pytest.fixture
def read_only_pool(tmp_path):
    """The throwing example pool, copied and mounted read-only (a read-only file system refuses root's
    writes too); skipped where mounting is not allowed."""
    source, mounted = tmp_path / "source", tmp_path / "pool"
    shutil.copytree(EXAMPLES / "pools" / "throwing", source)
    mounted.mkdir()
    result = subprocess.run(["mount", "--bind", "-o", "ro", source, mounted], capture_output=True, text=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount read-only here: {result.stderr.strip()}")
    try:
        yield mounted
    finally:
        subprocess.run(["umount", "--lazy", mounted], check=True)


def test_reading_a_pool_writes_nothing_into_it(tmp_path, capsys):
    pool = tmp_path / "pool"
    shutil.copytree(EXAMPLES / "pools" / "throwing", pool)
    before = snapshot(pool)
    assert run_cli(capsys, "pool", "show", str(pool), "throw")[0] == 0
    assert SkillTemplatePool(pool)["throw"].name == "throw"
    assert snapshot(pool) == before  # no lock file beside the templates


def test_a_read_only_pool_reads_and_refuses_writes_in_one_line(read_only_pool, capsys):
    code, out, err = run_cli(capsys, "pool", "show", str(read_only_pool), "throw")
    assert code == 0 and out.startswith("name\tthrow\n"), err
    pool = SkillTemplatePool(read_only_pool)
    with pytest.raises(PoolError, match=f"^{re.escape(str(read_only_pool))}: the pool is read-only here$"):
        pool.remove("throw")
    assert list(pool) == ["throw"]


# -- untrusted JSON ----------------------------------------------------------------------------------------

HUGE_NUMBER = '{"schema_version": ' + "7" * 5001 + "}"
DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        (HUGE_NUMBER, "an integer of more than 4300 digits"),
        (DEEP, "lists or objects nested too deeply"),
    ],
    ids=["5001 digits", "100000 deep"],
)
@pytest.mark.parametrize(
    ("command", "file"),
    [(("robots", "show"), "description.json"), (("dataset", "show"), "meta/info.json")],
    ids=["description.json", "info.json"],
)
def test_json_that_python_cannot_hold_is_named_in_one_line(tmp_path, capsys, text, problem, command, file):
    path = tmp_path / "folder" / file
    path.parent.mkdir(parents=True)
    path.write_text(text)
    code, out, err = run_cli(capsys, *command, str(tmp_path / "folder"))
    assert (code, out) == (2, "")
    assert err == f"besman: error: {path}: not JSON besman reads ({problem})\n"


def test_an_output_whose_first_line_python_cannot_hold_is_not_replaced(tmp_path):
    log = tmp_path / "run.jsonl"
    for text in (HUGE_NUMBER, DEEP):
        log.write_text(text + "\n")
        with pytest.raises(InputError, match="an existing file that is not a besman run log"):
            check_output(log, option="--log", kind=LOG_KIND)


def test_a_run_log_line_python_cannot_hold_is_named_by_file_and_line(tmp_path, capsys):
    log = tmp_path / "run.jsonl"
    for text, problem in ((HUGE_NUMBER, "more than 4300 digits"), (DEEP, "nested too deeply")):
        log.write_text('{"kind": "besman-run-log", "schema_version": 1}\n' + text + "\n")
        code, out, err = run_cli(capsys, "view", "--replay", str(log))
        assert (code, out) == (2, "") and err.startswith(f"besman: error: {log}:2: not JSON besman reads")
        assert problem in err and err.count("\n") == 1


def test_examples_copied_onto_too_small_a_space_name_the_file_in_one_line(small_space):  # noqa: F811
    folder, reason, limit = small_space
    result = subprocess.run(
        [sys.executable, "-m", "besman", "examples", "--copy", str(folder)],
        capture_output=True,
        text=True,
        preexec_fn=limit,
    )
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.splitlines()
    assert re.fullmatch(
        rf"besman: error: {re.escape(str(folder))}/examples/\S+: cannot write it \({reason}\)", line
    )
    assert snapshot(folder) == {}  # no half copy, no temporary folder


# -- tree includes -----------------------------------------------------------------------------------------


def test_a_chain_of_400_includes_is_refused_at_the_bound_naming_the_file_and_line(tmp_path, capsys):
    for k in range(400):
        (tmp_path / f"{k}.yaml").write_text(f"besman_tree: 1\nroot:\n  include: {k + 1}.yaml\n")
    (tmp_path / "400.yaml").write_text("besman_tree: 1\nroot: {Wait: {name: w, duration: 0.1}}\n")
    message = f"{tmp_path / f'{MAX_INCLUDES - 1}.yaml'}:3: root.include: files included deeper than 32 levels"
    with pytest.raises(TreeFileError) as refused:
        load_tree(tmp_path / "0.yaml")
    assert str(refused.value) == message
    code, out, _ = run_cli(capsys, "tree", "check", str(tmp_path / "0.yaml"))
    assert code == 1 and out == f"{message}\n"


def test_includes_that_fan_out_are_refused_at_the_node_bound_at_once(tmp_path):
    """Each file a Sequence of two includes of the next, 30 deep: 2^30 nodes, were they built."""
    for k in range(30):
        twice = f"[{{include: {k + 1}.yaml}}, {{include: {k + 1}.yaml}}]"
        (tmp_path / f"{k}.yaml").write_text(
            f"besman_tree: 1\nroot: {{Sequence: {{name: s, children: {twice}}}}}\n"
        )
    (tmp_path / "30.yaml").write_text("besman_tree: 1\nroot: {Wait: {name: w, duration: 0.1}}\n")
    start = time.perf_counter()
    with pytest.raises(TreeFileError, match=r"\.yaml:2: root.*: the tree has more than 10000 nodes"):
        load_tree(tmp_path / "0.yaml")
    assert time.perf_counter() - start < 5.0  # each file parsed once


def test_a_tree_deeper_than_the_bound_through_includes_is_refused_naming_the_file(tmp_path):
    """Each file within the bound of its own nesting, together beyond the tree's."""
    levels = 40  # a Sequence a level: three YAML levels each, within one file's bound
    for k in range(3):
        child = f"{{include: {k + 1}.yaml}}" if k < 2 else "{Wait: {name: w, duration: 0.1}}"
        for level in range(levels):
            child = f"{{Sequence: {{name: s{level}, children: [{child}]}}}}"
        (tmp_path / f"{k}.yaml").write_text(f"besman_tree: 1\nroot: {child}\n")
    with pytest.raises(
        TreeFileError, match=rf"^{re.escape(str(tmp_path / '2.yaml'))}:2: root(\.\S+)?: the tree is"
    ):
        load_tree(tmp_path / "0.yaml")


# -- environments ------------------------------------------------------------------------------------------


def test_an_environments_inputs_are_named_before_any_work():
    env = TaskEnv("pick")
    env.reset(seed=0)
    action = np.zeros(9)
    action[[2, 7]] = np.nan, np.inf
    with pytest.raises(
        InputError, match=r"^an action is 9 finite numbers; not finite: \[2\] = nan, \[7\] = inf$"
    ):
        env.step(action)
    with pytest.raises(InputError, match=r"^an action is 9 finite numbers, got 'open'$"):
        env.step("open")
    values = env.values
    for options, message in [
        (
            {"values": "object"},
            r"""reset options\["values"\]: expected a dict of task values, .* got 'object'""",
        ),
        ("values", r"reset options: expected a dict"),
        (
            {"value": {"object": [0.5, 0.0]}},
            r"reset options: unknown option 'value'; the one option is 'values'",
        ),
        (
            {"values": {"object": {"a": 1}}},
            r"--set object: takes numbers \(object_x, object_y, object_yaw\), got \{'a': 1\} \(dict\)",
        ),
    ]:
        with pytest.raises(InputError, match=f"^{message}"):
            env.reset(seed=1, options=options)
    assert env.values is values  # nothing was set up
    env.close()


# -- recordings in the wrong unit --------------------------------------------------------------------------


def test_a_recording_in_metres_is_refused_naming_the_likely_unit(tmp_path, capsys):
    lines = (EXAMPLES / "data" / "subject1_run1.tsv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("Frame\t"))
    metres = lines[: header + 1]
    for line in lines[header + 1 :]:
        frame, time, *cells = line.split("\t")
        metres.append(
            "\t".join(
                [
                    frame,
                    time,
                    *(f"{float(c) / 1000:.6f}" if c[:1].isdigit() or c[:1] == "-" else c for c in cells),
                ]
            )
        )
    path = tmp_path / "metres.tsv"
    path.write_text("\n".join(metres) + "\n")
    code, out, err = run_cli(capsys, "segment", str(path))
    assert (code, out) == (2, "")
    assert re.fullmatch(
        rf"besman: error: {re.escape(str(path))}: marker 'Hand top' stays within 0\.\d mm of the origin "
        r"and moves at most 1\.\d mm/s over 12 s: is the recording in metres\? besman reads a \.tsv in "
        r"millimetres\n",
        err,
    )


def test_the_shared_recordings_are_far_beyond_the_bounds(shared_recordings):
    for path in sorted(shared_recordings.glob("*.tsv")):
        smoothed = smooth(load(path), "Hand top")
        assert np.max(np.linalg.norm(smoothed.positions, axis=1)) > 20 * NEAR_ORIGIN, path
        assert np.max(smoothed.speed) > 20 * MIN_PEAK_SPEED, path
