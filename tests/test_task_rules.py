"""One success rule per task: pick and place's demo summary, the reward of its learned carry, its scripted
episode and the learned benchmark judge the same final states alike (placed; a little off; too far off;
tilted, and falling flat as it settles; on its side; in the air above the target; left on the table)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from besman.sim.blocks import judge_block, restore, snapshot
from besman.sim.outcomes import placement
from besman.tasks.running import prepare

ROOT = Path(__file__).resolve().parents[1]
# Where the box is put once the demo has placed it (x, y, z offsets from where it stands; a tilt in deg),
# and whether the task then counts as done.
FINAL_STATES = {
    "as placed": ((0.0, 0.0, 0.0), 0.0, True),
    "1.5 cm off": ((0.015, 0.0, 0.0), 0.0, True),
    "2.5 cm off": ((0.0, 0.025, 0.0), 0.0, False),
    "tilted 20 deg, falls flat": ((0.0, 0.0, 0.012), 20.0, True),
    "on its side": ((0.0, 0.0, 0.001), 90.0, False),
    "1 cm above": ((0.0, 0.0, 0.01), 0.0, True),
    "on the table": ((0.0, 0.45, -0.12), 0.0, False),
}


@pytest.fixture(scope="module")
def placed():
    """A pick-and-place demo's run on AILA (its default configuration), ended, and its final state."""
    prepared = prepare("pick-place")
    result = prepared.runner.run()
    return prepared, result, snapshot(prepared.runner.executor.world)


def put_box(world, state, offset, tilt_degrees) -> None:
    """Restores ``state`` and moves the box by ``offset``, tilted about x, at rest."""
    restore(world, state)
    joint = world.model.joint("box")
    address, velocity = joint.qposadr[0], joint.dofadr[0]
    world.data.qpos[address : address + 3] += offset
    w, x, y, z = world.data.qpos[address + 3 : address + 7]
    turned = Rotation.from_quat([x, y, z, w]) * Rotation.from_euler("x", tilt_degrees, degrees=True)
    x, y, z, w = turned.as_quat()
    world.data.qpos[address + 3 : address + 7] = (w, x, y, z)
    world.data.qvel[velocity : velocity + 6] = 0.0


@pytest.mark.parametrize("name", list(FINAL_STATES))
def test_the_demo_the_learning_reward_and_the_episode_judge_a_final_state_alike(placed, name):
    prepared, result, state = placed
    executor = prepared.runner.executor
    world, place = executor.world, np.asarray(prepared.runner.run_info["settings"]["place"])
    offset, tilt, done = FINAL_STATES[name]
    verdicts = {}
    put_box(world, state, offset, tilt)
    verdicts["demo summary"] = prepared.judge(result).success
    put_box(world, state, offset, tilt)
    verdicts["learned carry's reward"] = judge_block(world, executor.hand, "carry", place)[0]
    put_box(world, state, offset, tilt)
    verdicts["scripted episode"] = placement(world, "box", place).success
    assert verdicts == dict.fromkeys(verdicts, done), verdicts


@pytest.mark.slow
def test_the_learned_benchmark_reports_the_tasks_judgement(monkeypatch):
    """benchmarks/learned.py's success of an episode is the task's rule on the run's final state."""
    spec = importlib.util.spec_from_file_location("learned_benchmark", ROOT / "benchmarks" / "learned.py")
    benchmark = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(benchmark)
    runs = []

    def recorded(*args, **kwargs):
        runs.append(prepare(*args, **kwargs))
        return runs[-1]

    monkeypatch.setattr(benchmark, "prepare", recorded)
    build = benchmark.trees(ROOT / "examples" / "pools" / "pick_place_aila")["ik"]
    tau = np.array([0.5, -0.05, 0.58, -0.44])
    reported = benchmark.episode(build, tau, "aila")
    (run,) = runs
    world = run.runner.executor.world
    again = placement(world, "box", tau[2:])
    assert reported["success"] == again.success is True
    assert reported["placement_error_m"] == pytest.approx(again.error, abs=2e-4)
