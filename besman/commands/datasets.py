"""Datasets from the command line: `--dataset` on `besman run` and `besman demo` (a run appended as a
LeRobot v3.0 episode), `besman record` (a task over N seeds) and `besman dataset show`."""

from __future__ import annotations

import argparse
import json
import os
import sys

from besman.commands.options import COUNT, MAX_SEED, SEED
from besman.core.errors import InputError


def require_datasets(option: str = "--dataset") -> None:
    """The ``datasets`` extra's packages, or one line saying how to install them."""
    try:
        import av  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as error:
        raise InputError(f"{option} needs {error.name}: pip install 'besman[datasets]'") from None


def dataset_options(command: argparse.ArgumentParser) -> None:
    """--dataset and --video of a command that runs a tree."""
    command.add_argument(
        "--dataset",
        default=None,
        metavar="DIR",
        help="append the run to this LeRobot v3.0 dataset as an episode (made if missing; docs/datasets.md)",
    )
    command.add_argument(
        "--video", action="store_true", help="with --dataset: record a camera's view too (MP4, 320 x 240)"
    )


def check_dataset(args: argparse.Namespace) -> None:
    """--dataset and its companions checked before any work (a --log inside the dataset's folder stays
    there through the appends)."""
    if args.video and not args.dataset:
        raise InputError("--video records the camera into a dataset: give --dataset DIR")
    if args.dataset:
        require_datasets()
        from besman.datasets.writer import dataset_folder

        folder = dataset_folder(args.dataset)
        if getattr(args, "view", False):
            raise InputError("--dataset records runs without the browser viewer; drop --view")
        log = getattr(args, "log", None)
        if log and os.path.realpath(log) == str(folder):
            raise InputError(f"--log {log}: the same path as --dataset {args.dataset}; give each its own")


def _record(args: argparse.Namespace) -> int:
    require_datasets()
    last = args.seed + args.episodes - 1
    if last > MAX_SEED:
        raise InputError(
            f"--seed {args.seed} --episodes {args.episodes}: the last run's seed would be {last}, seeds go "
            f"up to {MAX_SEED}"
        )
    from besman.datasets.writer import dataset_folder
    from besman.tasks import task
    from besman.tasks.recording import record_run, recorded_seeds

    dataset_folder(args.dataset)
    chosen = task(args.task)
    robot = chosen.check_robot(args.robot)
    from besman.robots import describe

    name = describe(robot).name
    done = recorded_seeds(args.dataset, chosen.name, name)
    wanted = range(args.seed, last + 1)
    recorded = sum(seed in wanted for seed in done)
    if recorded:
        print(f"{args.dataset}: seeds {recorded} of {args.episodes} already recorded", file=sys.stderr)
    seeds = (seed for seed in wanted if seed not in done)  # one at a time: there may be billions
    total = args.episodes - recorded
    successes = 0
    for number, seed in enumerate(seeds, 1):
        summary, index = record_run(
            chosen,
            args.tree,
            dataset=args.dataset,
            video=args.video,
            robot=robot,
            seed=seed,
            perturb=args.perturb,
            demo=None if args.tree else chosen.name,
        )
        successes += summary.success
        print(
            f"[{number}/{total}] seed {seed}: {'success' if summary.success else 'failure'} "
            f"({summary.outcome}) -> episode {index}",
            file=sys.stderr,
            flush=True,
        )
    print(f"{args.dataset}: {successes} of {total} new episodes succeeded")
    return 0


def _dataset_show(args: argparse.Namespace) -> int:
    require_datasets("besman dataset show")
    from besman.datasets.reader import read_dataset

    dataset = read_dataset(args.dataset)
    info = dataset.info
    successes = [dataset.facts(i).get("besman/success") for i in range(len(dataset.episodes))]
    facts = {
        "dataset": str(dataset.root),
        "codebase_version": info["codebase_version"],
        "robot_type": info.get("robot_type"),
        "fps": info["fps"],
        "episodes": info["total_episodes"],
        "frames": info["total_frames"],
        "tasks": list(dataset.tasks),
        "successes": sum(s is True for s in successes) if any(s is not None for s in successes) else None,
        "features": {
            name: {"dtype": f["dtype"], "shape": f["shape"], "names": f.get("names")}
            for name, f in info["features"].items()
        },
    }
    if args.json:
        print(json.dumps(facts, indent=2))
        return 0
    robot = _printable(str(facts["robot_type"]))
    print(f"{facts['dataset']}: LeRobot {facts['codebase_version']}, robot {robot}, {facts['fps']} fps")
    known = "" if facts["successes"] is None else f", {facts['successes']} succeeded"
    print(f"{facts['episodes']} episodes, {facts['frames']} frames{known}")
    for text in facts["tasks"]:
        print(f"task: {_printable(text)}")
    for name, feature in facts["features"].items():
        names = feature["names"]
        shown = (
            ""
            if not isinstance(names, list)
            else ": " + ", ".join(_printable(str(n)) for n in names[:6]) + (" ..." if len(names) > 6 else "")
        )
        print(f"{_printable(name)}\t{feature['dtype']} {feature['shape']}{shown}")
    return 0


def _printable(text: str) -> str:
    """A stranger's text as the terminal may show it: control characters (escape sequences that retitle
    the window or clear the screen) escaped."""
    return text if text.isprintable() else repr(text)[1:-1]


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    record = commands.add_parser(
        "record", help="run a task over N seeds and append every run to a LeRobot v3.0 dataset (resumes)"
    )
    record.add_argument("task", help="the task (besman tasks lists them)")
    record.add_argument("--dataset", required=True, metavar="DIR", help="the dataset (made if missing)")
    record.add_argument(
        "--episodes", type=COUNT, required=True, help="how many runs: seeds SEED to SEED + N - 1"
    )
    record.add_argument("--seed", type=SEED, default=0, help="the first seed (default 0)")
    record.add_argument("--robot", default=None, help="the robot (default: the task's)")
    record.add_argument("--tree", default=None, help="the tree file to run (default: the task's own)")
    record.add_argument(
        "--perturb",
        choices=("perception", "push"),
        default=None,
        help="perturb every run as the task declares (its seed draws it): noisy demonstrations",
    )
    record.add_argument("--video", action="store_true", help="record a camera's view too (MP4, 320 x 240)")
    record.set_defaults(handler=_record)

    dataset = commands.add_parser("dataset", help="LeRobot v3.0 datasets")
    dataset_commands = dataset.add_subparsers(dest="dataset_command", metavar="ACTION", required=True)
    show = dataset_commands.add_parser("show", help="a dataset's robot, fps, episodes, tasks and features")
    show.add_argument("dataset", metavar="DIR")
    show.add_argument("--json", action="store_true", help="everything as JSON")
    show.set_defaults(handler=_dataset_show)
