"""Every task as a Gymnasium environment: Gymnasium's own checker, determinism by seed, a recorded
demonstration replayed to success, the throw's landing as the task's rollouts find it."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from besman.core.errors import InputError
from besman.tasks import TASKS
from besman.tasks.environment import TaskEnv, register_environments
from besman.tasks.throwing.rollouts import ThrowingRollouts

REPO = Path(__file__).resolve().parents[1]
CASES = [(name, None) for name in TASKS] + [("pick-place", "ee"), ("handover", "ee")]


@pytest.mark.slow
@pytest.mark.parametrize(("task", "control"), CASES)
def test_every_task_passes_gymnasiums_checker(task, control):
    env = TaskEnv(task, control=control, render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its advice (normalised boxes) is not a failure
        check_env(env)
    image = env.render()
    assert image.shape == (240, 320, 3) and np.ptp(image) > 50
    env.close()


def _episode(env: TaskEnv, seed: int, steps: int) -> list:
    observation, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    trace = [np.r_[observation["state"], observation["environment_state"]]]
    for _ in range(steps):
        observation, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        trace.append(np.r_[observation["state"], reward, terminated, truncated])
        if terminated or truncated:
            break
    return trace


def test_the_same_seed_gives_the_same_episode_and_another_seed_another():
    env, other = TaskEnv("pick-place"), TaskEnv("pick-place")
    first = _episode(env, 7, 40)
    np.testing.assert_array_equal(np.concatenate(first), np.concatenate(_episode(other, 7, 40)))
    assert not np.array_equal(first[0], _episode(other, 8, 1)[0])
    # The seed is the task's: the scene of besman run --seed 7.
    from besman.tasks.running import prepare

    values = prepare("pick-place", seed=7).runner.run_info["values"]
    observation, _ = env.reset(seed=7)
    np.testing.assert_allclose(observation["environment_state"], env.task.join(values))


@pytest.mark.slow
def test_the_scripted_and_random_policies_of_the_example():
    result = subprocess.run(
        [sys.executable, str(REPO / "examples" / "gym_policies.py"), "--seeds", "0-2", "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    import json

    results = json.loads(result.stdout)
    assert [r["done"] for r in results["scripted"]] == [True, True, True]  # the tree's commands, replayed
    assert not any(r["done"] for r in results["random"])


def test_a_throw_lands_where_the_tasks_rollouts_land_it():
    env = TaskEnv("throwing")
    observation, _ = env.reset(seed=3)
    task = ThrowingRollouts()
    theta = task.default_theta()
    _, reward, terminated, truncated, info = env.step(theta)
    assert terminated and not truncated and reward in (0.0, 1.0)
    evaluated = task.evaluate(theta[None], observation["environment_state"][None])
    landing = np.asarray(evaluated.details[0].landing)
    np.testing.assert_allclose(info["measurements"]["landing"], landing, atol=1e-3)
    _, reward, terminated, _, info = env.step(np.full_like(theta, 50.0))
    assert terminated and reward == 0.0 and info["failure"] == "infeasible throw"


def test_gymnasium_makes_them_by_name_and_bad_settings_are_refused():
    ids = register_environments()
    assert "besman/pick-place" in ids and len(ids) == len(TASKS)
    env = gymnasium.make("besman/stack")
    assert env.unwrapped.task.name == "stack"
    env.close()
    with pytest.raises(InputError, match="control 'joint': task throwing takes throw"):
        TaskEnv("throwing", control="joint")
    with pytest.raises(InputError, match="control 'throw': task pick-place takes joint or ee"):
        TaskEnv("pick-place", control="throw")
    env = TaskEnv("pick")
    env.reset(seed=0)
    with pytest.raises(InputError, match="an action is 9 finite numbers"):
        env.step(np.full(9, np.nan))
