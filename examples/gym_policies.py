"""Two policies on a task's Gymnasium environment (:mod:`besman.tasks.environment`), nothing trained: a random
one, and a scripted one that replays what the task's own IK-planned tree commands at every tick of a run
with the same seed (its ``action``s, as ``besman record`` stores them). One line per episode and the
success rate of each; ``--json`` for a JSON document.

    python examples/gym_policies.py [--task pick-place] [--robot ur5e] [--seeds 0-4] [--json]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from besman.tasks.environment import TICK_RATE, TaskEnv
from besman.tasks.frames import RobotFrames
from besman.tasks.running import prepare

RANDOM_STEPS = 250  # 5 s of random targets: enough to see that nothing is done by chance


def scripted_actions(task: str, robot: str | None, seed: int) -> np.ndarray:
    """The commands of the task's tree at every tick of its run with ``seed``, each the next tick's."""
    prepared = prepare(task, robot=robot, seed=seed)
    frames, commanded = RobotFrames(prepared.runner.executor), []
    prepared.runner.observe = lambda runner, record: commanded.append(frames.commanded())
    prepared.runner.run()
    return np.array(commanded[1:] + commanded[-1:])


def episode(env: TaskEnv, seed: int, actions) -> dict:
    """Runs ``actions`` (then holds the last) until the episode ends, or the random policy's steps."""
    env.reset(seed=seed)
    reward, steps, info = 0.0, 0, {}
    for action in actions:
        _, reward, terminated, truncated, info = env.step(action)
        steps += 1
        if terminated or truncated:
            break
    return {"seed": seed, "done": reward == 1.0, "seconds": steps / TICK_RATE, **info}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="pick-place")
    parser.add_argument("--robot", default=None)
    parser.add_argument("--seeds", default="0-4", help="FIRST-LAST")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    first, _, last = args.seeds.partition("-")
    seeds = range(int(first), int(last or first) + 1)
    env = TaskEnv(args.task, args.robot)
    results = {"random": [], "scripted": []}
    for seed in seeds:
        env.action_space.seed(seed)
        results["random"].append(episode(env, seed, (env.action_space.sample() for _ in range(RANDOM_STEPS))))
        actions = scripted_actions(args.task, args.robot, seed)
        held = (actions[min(i, len(actions) - 1)] for i in range(10**6))  # the last held until judged
        results["scripted"].append(episode(env, seed, held))
    env.close()
    if args.json:
        print(json.dumps(results, indent=2))
        return
    for policy, rows in results.items():
        for row in rows:
            verdict = "done" if row["done"] else "not done"
            said = row.get("outcome") or row.get("failure") or ""
            print(f"{policy}\tseed {row['seed']}: {verdict} after {row['seconds']:.1f} s {said}")
        print(f"{policy}: {sum(r['done'] for r in rows)} of {len(rows)} done")


if __name__ == "__main__":
    main()
