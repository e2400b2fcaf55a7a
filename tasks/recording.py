"""Task runs recorded as LeRobot v3.0 episodes (:mod:`besman.datasets.writer`): ``besman run`` and
``besman demo`` with ``--dataset DIR``, and ``besman record`` (a task over N seeds).

One frame per tick of the tree (the runner's rate, 50 Hz: where the tree decides; the executor's 500 Hz
commands between two frames are Ruckig's interpolation toward the next), named as
:mod:`besman.tasks.frames` names them:

- ``observation.state``: the arms' measured joint and finger positions, then their velocities;
- ``observation.environment_state``: tau (constant in an episode);
- ``action``: what the arms were commanded to reach by the next frame (the last frame repeats);
- ``observation.images.<camera>`` with ``--video``: a free camera aimed at the scene's centre, rendered
  offscreen (``MUJOCO_GL=egl``) at 320 x 240.

Each episode's text is the task's title; its row in the episodes table also holds ``besman/task``,
``besman/robot``, ``besman/tree``, ``besman/seed`` (-1: none), ``besman/tau`` and ``besman/success``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.core.errors import InputError
from besman.datasets.writer import DatasetSpec, DatasetWriter, Episode
from besman.tasks import task as find_task
from besman.tasks.frames import RobotFrames, SceneCamera
from besman.tasks.running import observers, prepare
from besman.trees.summary import RunSummary

CAMERA = "observation.images.scene"
CAMERA_SIZE = (240, 320)  # height, width


class RunRecorder:
    """Collects one run's frames (its runner's observer) and makes them an :class:`Episode`."""

    def __init__(self, runner, task, *, video: bool = False) -> None:
        self.runner, self.task = runner, task
        self.frames = frames = RobotFrames(runner.executor)
        if float(runner.rate) != int(runner.rate):
            raise InputError(f"a dataset's fps is whole: the runner's rate {runner.rate} Hz is not")
        features = {
            "observation.state": {
                "dtype": "float32",
                "shape": [len(frames.state_names)],
                "names": frames.state_names,
            },
            "observation.environment_state": {
                "dtype": "float32",
                "shape": [len(task.names)],
                "names": list(task.names),
            },
            "action": {"dtype": "float32", "shape": [len(frames.action_names)], "names": frames.action_names},
        }
        self.camera = None
        if video:
            features[CAMERA] = {
                "dtype": "video",
                "shape": [*CAMERA_SIZE, 3],
                "names": ["height", "width", "channels"],
            }
            self.camera = SceneCamera(runner.executor.world, CAMERA_SIZE)
        robot = runner.run_info.get("robot")
        self.spec = DatasetSpec(fps=int(runner.rate), features=features, robot_type=robot)
        self.states, self.commands, self.images = [], [], []
        runner.observe = observers(runner.observe, self.observe)

    def observe(self, runner, _record: dict) -> None:
        self.states.append(self.frames.state())
        self.commands.append(self.frames.commanded())
        if self.camera is not None:
            self.images.append(self.camera.render())

    def episode(self, summary: RunSummary) -> Episode:
        """The run's episode: its frames, and its facts from the run's ``summary``."""
        run_info, count = self.runner.run_info, len(self.states)
        tau = self.task.join({name: run_info["values"][name] for name in (v.name for v in self.task.values)})
        commands = np.array(self.commands)
        actions = np.concatenate([commands[1:], commands[-1:]])  # what frame t is told to reach by t + 1
        frames = {
            "observation.state": np.array(self.states),
            "observation.environment_state": np.tile(tau, (count, 1)),
            "action": actions,
        }
        tree = run_info["tree"]
        facts = {
            "besman/task": self.task.name,
            "besman/robot": str(run_info["robot"]),
            "besman/tree": tree if isinstance(tree, str) else "built in code",
            "besman/seed": -1 if run_info["seed"] is None else int(run_info["seed"]),
            "besman/tau": tau.tolist(),
            "besman/success": bool(summary.success),
        }
        videos = {CAMERA: np.array(self.images)} if self.camera is not None else {}
        return Episode(self.task.title, frames, videos, facts)

    def close(self) -> None:
        if self.camera is not None:
            self.camera.close()


def record_run(
    task, tree=None, *, dataset: str | Path, video: bool = False, log=None, **options
) -> tuple[RunSummary, int]:
    """Runs ``tree`` on ``task`` (as :func:`~besman.tasks.running.run`, ``options`` alike) and appends it to
    the dataset at ``dataset`` (checked before the run: a dataset recorded with other features is
    refused); the summary and the episode's index."""
    prepared = prepare(task, tree, **options)
    recorder = RunRecorder(prepared.runner, find_task(prepared.runner.run_info["task"]), video=video)
    try:
        with DatasetWriter(dataset, recorder.spec) as writer:
            summary = prepared.judge(prepared.runner.run(log=log))
            return summary, writer.append(recorder.episode(summary))
    finally:
        recorder.close()


def recorded_seeds(dataset: str | Path, task: str, robot: str) -> set[int]:
    """The seeds of the dataset's episodes of ``task`` on ``robot`` (none if there is no dataset yet); a
    dataset of another task or robot is refused."""
    from besman.datasets.reader import read_dataset

    if not (Path(dataset) / "meta" / "info.json").exists():
        return set()
    found = read_dataset(dataset)
    seeds = set()
    for index in range(len(found.episodes)):
        facts = found.facts(index)
        if (facts.get("besman/task"), facts.get("besman/robot")) != (task, robot):
            raise InputError(
                f"--dataset {dataset}: episode {index} is of task {facts.get('besman/task')!r} on "
                f"{facts.get('besman/robot')!r}, not {task} on {robot}; record into another dataset"
            )
        seed = facts.get("besman/seed")
        if type(seed) is not int:
            raise InputError(
                f"--dataset {dataset}: episode {index}'s besman/seed is {seed!r}, not a whole number"
            )
        seeds.add(seed)
    return seeds
