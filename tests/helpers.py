"""What several test files share: running the command line and the benchmarks, comparing rotations, killing
long commands and checking what they leave."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import yaml

from besman.cli import main
from besman.core.storage import is_temporary
from besman.sim.reaper import environments

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


def failed_placements(pool: Path, taus, robot: str = "aila", tree: Path = LEARNED_TREE) -> list[tuple]:
    """The learned tree with ``pool``'s templates on ``robot`` at every pick-and-place tau of ``taus`` (each
    checked to be no training task of them), zero shot (the templates' means; online refinement off, as
    ``benchmarks/learned.py``'s zero-shot tree): the runs that did not succeed (the task's rule: the object
    upright on the shelf within 2 cm of its target and 5 deg of its yaw, or the tree failing)."""
    from besman.skills import SkillTemplatePool
    from besman.tasks import task
    from besman.tasks.running import run
    from besman.trees.files import loads_tree

    pick_place = task("pick-place")
    templates = SkillTemplatePool(pool)
    for name in templates:
        trained = np.array([run["task_tau"] for run in templates[name].provenance["training"]])
        for tau in taus:
            distances = np.abs(trained - np.asarray(tau)).max(axis=1)
            assert distances.min() > 1e-3, f"{tau} is a training task of {name!r}"
    text = tree.read_text()
    assert "refine_above: 0.08" in text or tree != LEARNED_TREE
    zero_shot = text.replace("refine_above: 0.08", "refine_above: 1.0e9")
    failed = []
    for tau in taus:
        root = loads_tree(zero_shot, base=tree.parent, source=tree.name, pool=pool)
        summary = run("pick-place", root, values=pick_place.split(tau), robot=robot)
        error = summary.measurements["placement_error_m"]
        if not summary.success:
            failed.append((tuple(tau), summary.status, error, summary.message))
    return failed


def is_whole(path: Path) -> bool:
    """Whether a file that besman writes is complete: JSON that parses, NPZ whose arrays all read (zip
    checksums), PNG that ends with its IEND chunk, YAML (a learned tree) that parses to a mapping."""
    data = path.read_bytes()
    try:
        if path.suffix == ".json":
            json.loads(data)
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as arrays:
                for name in arrays.files:
                    arrays[name]
        elif path.suffix == ".yaml":
            return isinstance(yaml.safe_load(data), dict)
        elif path.suffix == ".png":
            return data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")
        else:
            raise AssertionError(f"{path}: no check for this kind of file")
    except (ValueError, OSError, yaml.YAMLError):
        return False
    return True


def processes_marked(token: str) -> list[int]:
    """The live processes (zombies excluded) whose environment holds ``BESMAN_TEST_TOKEN=token``: a command
    started with it and every process it started, whatever their session or parent now."""
    marker = f"BESMAN_TEST_TOKEN={token}".encode()
    found = []
    for pid, environment in environments().items():
        if marker not in environment:
            continue
        try:
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                found.append(pid)
        except (OSError, IndexError):
            continue  # ended meanwhile
    return found


def process_tree(root: int) -> dict[int, int]:
    """``root`` and its live descendants (zombies excluded), each with its start time (field 22 of
    ``/proc/PID/stat``, which tells it from a later process with its pid): found by parent links, not by
    environment (a process that retitles itself may blank the environment that ``/proc`` shows)."""
    table = {}
    for folder in Path("/proc").glob("[0-9]*"):
        try:
            fields = (folder / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # ended meanwhile
        if fields[0] != "Z":
            table[int(folder.name)] = int(fields[1]), int(fields[19])
    tree, todo = {}, [root]
    while todo:
        pid = todo.pop()
        if pid in table and pid not in tree:
            tree[pid] = table[pid][1]
            todo += [child for child, (parent, _) in table.items() if parent == pid]
    return tree


def command_line(pid: int) -> str:
    """The command line of a process (a retitled one's title), "" once it ended."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        return ""


def alive(processes: dict[int, int]) -> list[int]:
    """Those of ``processes`` (pid: start time, :func:`process_tree`) alive still (zombies excluded)."""
    found = []
    for pid, start in processes.items():
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # ended
        if fields[0] != "Z" and int(fields[19]) == start:
            found.append(pid)
    return found


def start_marked(command: list[str]) -> tuple[subprocess.Popen, str]:
    """``command`` started with a token in its environment (:func:`processes_marked`), output discarded."""
    token = uuid.uuid4().hex
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "BESMAN_TEST_TOKEN": token},
    )
    return process, token


def assert_no_strays(token: str, seconds: float = 5.0, tree: dict[int, int] | None = None) -> None:
    """No process of a killed command is alive ``seconds`` after the kill: none marked with ``token``, nor
    any of ``tree`` (its :func:`process_tree` just before the kill)."""
    deadline = time.monotonic() + seconds
    while (processes_marked(token) or alive(tree or {})) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert processes_marked(token) == [], "processes outlived the command that started them"
    left = {pid: command_line(pid)[:60] for pid in alive(tree or {})}
    assert left == {}, f"processes outlived the command that started them: {left}"


def sigint_by_default() -> None:
    """``preexec_fn`` of a child that a test interrupts with SIGINT: Ctrl-C acts as it does in a terminal
    even when the tests run in a shell's background job, whose commands inherit SIGINT ignored (and a
    Python started with SIGINT ignored keeps ignoring it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def kill_and_resume(
    command: list[str], out: Path, kills: int, seed: int, jitter: float = 1.0, patience: float = 60.0
) -> list[str]:
    """Runs ``command`` (which writes ``out`` and resumes there) and kills it with SIGKILL ``kills`` times,
    starting it again after each kill; then lets it finish. Every other start is killed a seeded random
    time (0 to ``jitter`` s) after it writes its first new file (or after ``patience`` s without one), so
    that the run makes progress and the kills fall all over it; the others within 0.2-3 s of their start
    (while it starts, reads back its finished stages, or writes). After every kill: every file under
    ``out`` (but the temporaries of atomic writes) is whole, and no process the command started outlives
    it by more than 5 s. A run that ends on its own before its kill, once at least half the kills fell, ends
    the kills (what was left of it took less than the wait). Returns what each kill followed (the newest
    file then)."""
    rng = np.random.default_rng(seed)

    def written() -> list[Path]:
        return [p for p in out.rglob("*") if p.is_file() and not is_temporary(p)] if out.exists() else []

    interrupted = []
    for _ in range(kills):
        before = set(written())
        process, token = start_marked(command)
        if len(interrupted) % 2:
            time.sleep(rng.uniform(0.2, 3.0))
        else:
            deadline = time.monotonic() + patience
            while time.monotonic() < deadline and process.poll() is None and set(written()) <= before:
                time.sleep(0.05)
            time.sleep(rng.uniform(0.0, jitter))
        if process.poll() is not None:
            if process.returncode == 0 and len(interrupted) >= kills // 2:
                break  # late in the run what is left can end before the kill falls: nothing left to kill
            raise AssertionError(f"{' '.join(command)} ended (code {process.returncode}) before its kill")
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        assert_no_strays(token)
        files = written()
        torn = [str(p) for p in files if not is_whole(p)]
        assert torn == [], torn
        newest = max(files, key=lambda p: p.stat().st_mtime_ns, default=None)
        interrupted.append("nothing yet" if newest is None else str(newest.relative_to(out)))
    result = subprocess.run(command, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-3000:]
    return interrupted


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative path -> bytes)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def differing_files(folder: Path, other: Path, ignore: tuple[str, ...] = ()) -> list[str]:
    """The files (relative paths, but ``ignore``) in only one of two folders or that differ in a single byte
    (nothing: the same)."""
    first, second = snapshot(folder), snapshot(other)
    names = (first.keys() | second.keys()) - set(ignore)
    return sorted(name for name in names if first.get(name) != second.get(name))


def serve_then_interrupt(
    argv: list, timeout: float = 120.0, signum: int = signal.SIGINT, **popen
) -> tuple[str, str]:
    """Runs a command that ends by serving the browser viewer (``the viewer stays at URL until Ctrl-C``):
    the page at that address answers, then Ctrl-C (or ``signum``: SIGTERM) ends the command as it ends every
    command: exit 130 (143), its last line ``besman: interrupted`` (``terminated``), no traceback and no
    viser "Server stopped". Returns its stdout and stderr."""
    import re
    import subprocess
    import urllib.request

    process = subprocess.Popen(
        [str(a) for a in argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=sigint_by_default,
        **popen,
    )
    try:
        lines = []
        for line in process.stderr:  # the viewer's address, the run, then the line saying it serves
            lines.append(line)
            if "until Ctrl-C" in line:
                break
        else:
            process.wait(timeout=timeout)
            raise AssertionError(f"{argv} ended without serving:\n{''.join(lines)[-3000:]}")
        url = re.search(r"http://127\.0\.0\.1:\d+", line).group(0)  # bound to this machine
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower(), url
        process.send_signal(signum)
        out, err = process.communicate(timeout=timeout)  # a hang guard, generous for a loaded machine
        code, line = (143, "terminated") if signum == signal.SIGTERM else (130, "interrupted")
        assert process.returncode == code and err.splitlines()[-1:] == [f"besman: {line}"], (
            argv,
            err[-3000:],
        )
        assert "Traceback" not in err and "Server stopped" not in err, (argv, err[-3000:])
        return out, "".join(lines) + err
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


PINCER = """
<mujoco model="pincer">
  <compiler angle="radian"/>
  <worldbody>
    <body name="link1" pos="0 0 0.5">
      <joint name="j1" axis="0 0 1" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      <body name="hand" pos="0.3 0 0">
        <site name="tip" pos="0 0 -0.05"/>
        <body name="left_finger" pos="0 0.01 -0.05">
          <joint name="left" type="slide" axis="0 1 0" range="0 0.04" damping="2"/>
          <geom type="box" size="0.005 0.005 0.02" mass="0.05"/>
        </body>
        <body name="right_finger" pos="0 -0.01 -0.05">
          <joint name="right" type="slide" axis="0 -1 0" range="0 0.04" damping="2"/>
          <geom type="box" size="0.005 0.005 0.02" mass="0.05"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="j1" joint="j1" kp="10" ctrlrange="-1 1"/>
    <position joint="left" kp="100" ctrlrange="0 0.04"/>
    <position joint="right" kp="100" ctrlrange="0 0.04"/>
  </actuator>
  <keyframe><key name="home" qpos="0 0 0" ctrl="0 0 0"/></keyframe>
</mujoco>
"""


def pincer(folder, command, **gripper):
    """A one-joint arm with two slide fingers, each driven by an unnamed actuator of its own, and finger
    geoms without names (as gym-aloha's ViperX and Trossen's WidowX have them), standing over a table (0.3 m,
    no place area); ``gripper`` changes its gripper's description."""
    limits = {"velocity": 1.0, "acceleration": 2.0, "jerk": 20.0}
    finger_limits = {"velocity": 0.1, "acceleration": 1.0, "jerk": 10.0}
    desc = {
        "schema_version": 2,
        "name": "pincer",
        "model": "pincer.xml",
        "keyframe": "home",
        "groups": {"arm": {"joints": ["j1"]}, "fingers": {"joints": ["left", "right"]}},
        "limits": {"j1": limits, "left": finger_limits, "right": finger_limits},
        "tabletop": {
            "table": {"height": 0.3, "x": [0.1, 0.6], "y": [-0.4, 0.4]},
            "shelf": {"height": 0.35, "x": [0.1, 0.3], "y": [-0.4, -0.3]},
            "reach": {"x": [0.25, 0.35], "y": [-0.05, 0.05]},
        },
        "arms": {
            "arm": {
                "groups": ["arm"],
                "tcp": {"site": "tip"},
                "gripper": {
                    "group": "fingers",
                    "opening": [0.005, 0.045],  # the pads 1 cm apart at 0, each finger opens 4 cm more
                    "command": command,
                    "open": 0.03,
                    "pads": [["left_finger"], ["right_finger"]],
                    "limits": finger_limits,
                }
                | gripper,
            }
        },
    }
    (folder / "pincer.xml").write_text(PINCER)
    (folder / "description.json").write_text(json.dumps(desc))
    return str(folder)


def run_within_limits(task: str, seed: int, robot: str) -> tuple:
    """The seeded demo of ``task`` (its default tree) on ``robot``: its summary and, for every arm the run
    drives (the executor's first, then those in lockstep with it), the commands it sent beyond that arm's
    limits (:func:`~besman.sim.executor.limit_violations`)."""
    from besman.sim.executor import limit_violations
    from besman.tasks.running import prepare

    prepared = prepare(task, seed=seed, robot=robot, demo=task)
    summary = prepared.judge(prepared.runner.run())
    arms = prepared.runner.executor.arms
    return summary, {name: limit_violations(member.log, member) for name, member in arms.items()}


def follow_page(page: Path, package: Path) -> list[str]:
    """A documentation page that builds a plugin, followed literally: its files (each block marked
    ``<!-- file: PATH -->``) written into the folder ``package``, the package installed as its last bash
    block's first command says (``pip install ./NAME``; here into a folder of its own, beside ``package``),
    then, as its ``cd NAME`` says, that block's other commands run in ``package`` with it installed; their
    outputs, in order."""
    text = page.read_text()
    for path, content in re.findall(r"<!-- file: (\S+) -->\n```\w*\n(.*?)```", text, flags=re.DOTALL):
        (package / path).parent.mkdir(parents=True, exist_ok=True)
        (package / path).write_text(content)
    block = re.findall(r"```bash\n(.*?)```", text, flags=re.DOTALL)[-1]
    commands = [shlex.split(line) for line in block.splitlines() if line.strip()]
    assert commands[:2] == [["pip", "install", f"./{package.name}"], ["cd", package.name]], commands[:2]
    site = package.parent / "site"
    _succeed(sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", site, package)
    environment = {**os.environ, "PYTHONPATH": str(site)}
    outputs = []
    for command in commands[2:]:
        if command[0] == "besman":
            command = [Path(sys.executable).parent / "besman", *command[1:]]
        elif command[:3] == ["python", "-m", "pytest"]:
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *command[3:]]
        outputs.append(_succeed(*command, cwd=package, env=environment).stdout)
    return outputs


def _succeed(*argv, **options) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, **options)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stdout}\n{result.stderr}"
    return result


def install_plugin(site: Path, distribution: str, group: str, module: str, name: str | None = None) -> None:
    """The distribution ``distribution`` 1.0 as importlib.metadata finds it in the folder ``site`` (on the
    path): its dist-info, naming the module ``module`` (written beside it by the caller) under the
    entry-point group ``group`` as ``name`` (default: the module's)."""
    info = site / f"{distribution.replace('-', '_')}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {distribution}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{name or module} = {module}\n")


# -- the open-loop tasks (ball-in-a-cup, the puck strike) ---------------------------------------------------


def mujoco_warnings_said():
    """A fixture's body: the MuJoCo warnings said while the test runs (a list, filled as they come)."""
    import mujoco

    said: list[str] = []
    mujoco.set_mju_user_warning(said.append)
    yield said
    mujoco.set_mju_user_warning(None)


def closing(task):
    """A fixture's body: ``task`` (its rollouts), closed after the tests that use it."""
    yield task
    task.close()


def assert_bit_identical_in_any_order(task, thetas, taus):
    """Five rollouts give the same rewards and details twice, in another order and alone; the first
    evaluation."""
    first = task.evaluate(thetas, taus)
    again = task.evaluate(thetas, taus)
    order = np.array([3, 0, 4, 2, 1])
    shuffled = task.evaluate(thetas[order], taus[order])
    alone = task.evaluate(thetas[2], taus[2])
    np.testing.assert_array_equal(first.rewards, again.rewards)
    np.testing.assert_array_equal(first.rewards[order], shuffled.rewards)
    assert first.rewards[2] == alone.rewards[0]
    assert first.details == again.details
    return first


def assert_no_mujoco_warnings(task, thetas, taus, said) -> None:
    """Rollouts of ``thetas`` in ``taus`` say no MuJoCo warning (``said``: the fixture's list) and none
    diverges."""
    result = task.evaluate(thetas, taus)
    assert said == []
    assert all(d.failure != "the simulation diverged" for d in result.details)
    assert sum(int(d.warning.number.sum()) for d in task._datas) == 0


def assert_too_fast_is_penalised_not_simulated(task, tau, failure_reward: float) -> None:
    """A wrist that would move far beyond its speed limit is refused before simulation, with a penalty."""
    theta = task.still_theta()
    theta[-12:-2] += 30.0  # wrist 3's forcing term: far beyond its speed limit
    result = task.evaluate(theta, tau)
    assert result.rewards[0] < failure_reward
    assert re.match(
        "the reference (exceeds the speed limit|leaves the range) of joint wrist_3", result.details[0].failure
    )
    assert not task.feasible(theta)[0] and task.feasible(task.still_theta())[0]


def assert_demonstration_file_is(demo: Path, synthetic, task, folder: Path, load, save) -> None:
    """The file ``demo`` is the ``synthetic`` motion (a task's, from its start) that ``save`` writes, ``load``
    reads it, and a file of a later schema is refused."""
    import pytest

    from besman.core.errors import InputError

    times, positions = load(demo)
    assert json.loads(demo.read_text())["synthetic"] is True
    _, expected, _ = synthetic(task.start, times)
    np.testing.assert_allclose(positions, expected, atol=1e-6)
    written = save(folder / "demo.json", task.start, task.arm.joints)
    assert written.read_text() == demo.read_text()
    record = json.loads(demo.read_text())
    record["schema_version"] = 99
    (folder / "future.json").write_text(json.dumps(record))
    with pytest.raises(InputError, match="schema_version 99"):
        load(folder / "future.json")


def replayed_everywhere(task, positions, velocities, taus):
    """The evaluation of one joint reference (n_steps + 1, 6), as it is, at every tau (N, d)."""
    n = len(taus)
    return task.evaluate_references(np.repeat(positions[None], n, 0), np.repeat(velocities[None], n, 0), taus)


def registered_leaves(module):
    """A task's leaf module with its node types registered: through the entry point of besman's
    pyproject.toml (an editable install made before that line was added registers them after
    ``pip install -e .``; here, directly)."""
    from besman.trees.nodes import NODE_TYPES, register_node_type

    for node in module.NODE_TYPES:
        if node.__name__ not in NODE_TYPES:
            register_node_type(node)
    return module


def assert_cmaes_succeeds(task, theta, tau, *, sigma: float, budget: int) -> None:
    """CMA-ES from ``theta`` (two seeds) finds a theta that succeeds at ``tau``."""
    from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search

    optimizers = [make_optimizer("cmaes", WarmStart(theta, sigma), seed=seed) for seed in range(2)]
    results = policy_search(
        lambda thetas, owners: task.evaluate(thetas, tau).rewards,
        optimizers,
        budget=budget,
        target_reward=1e-9,
    )
    for result in results:
        assert result.start_reward < 0 < result.best_reward
        assert task.evaluate(result.best_theta, tau).details[0].success


def assert_runs_as_a_gymnasium_environment(name: str) -> None:
    """The task ``name`` passes gymnasium's checks; a reset draws tau in its box and a step holding still
    neither rewards nor ends."""
    import warnings

    from gymnasium.utils.env_checker import check_env

    from besman.tasks import task as registered
    from besman.tasks.environment import TaskEnv

    env = TaskEnv(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its advice (normalised boxes) is not a failure
        check_env(env)
    observation, _ = env.reset(seed=2)
    box = registered(name).bounds("ur5e")
    tau = observation["environment_state"]
    assert np.all((np.asarray(box.low) <= tau) & (tau <= np.asarray(box.high)))
    _, reward, terminated, _, _ = env.step(observation["state"][: env.action_space.shape[0]])
    assert reward == 0.0 and not terminated
    env.close()
