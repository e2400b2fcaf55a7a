"""How fast the command line answers: every ``--help``, every command that lists, shows or checks, the first
tick of a run and the first answer of a check that simulates, each beside a bare Python.

    python benchmarks/startup.py [--json] [--runs 5]

Each is started ``runs`` times as a new process (the median wall time), in alternation with ``python -c pass``
on the same interpreter, whose time is the floor no command line can go below (the table gives each as a
ratio to it). Targets: every ``--help`` under 0.3 s; every listing, showing and checking command, with real
arguments (a shipped tree, pool, robot, task and recording), under 1 s; a run's first tick, and the first
line of ``besman robots check`` (which simulates the robot, check after check, a line each), under 2 s. The
first tick is seen in the run's own process: it starts the command line with py_trees' ``tick_once`` (what
the runner calls on the root every tick) wrapped to end the process as soon as the root has ticked once, so
the time runs from the start of the process to the end of the first tick, the run after it not awaited; the
check is stopped once its first line is read.
"""

from __future__ import annotations

import argparse
import atexit
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

REPOSITORY = Path(__file__).resolve().parents[1]  # the commands' folder: their arguments are relative to it
TARGETS_S = {"help": 0.3, "listing": 1.0, "first tick": 2.0, "first line": 2.0}
TICKED = "besman-benchmark: ticked once"
# The command line (the arguments after -c's code) until the runner has ticked the tree once.
FIRST_TICK = f"""
import os, sys
import py_trees
tick_once = py_trees.behaviour.Behaviour.tick_once
def first_tick(self):
    tick_once(self)
    print({TICKED!r}, flush=True)
    os._exit(0)
py_trees.behaviour.Behaviour.tick_once = first_tick
import besman
sys.argv[0] = "besman"
sys.exit(besman.main())
"""


def helps() -> list[list[str]]:
    """``--help`` of the command line and of every command and subcommand."""
    from besman.cli import build_parser, commands

    return [[*path, "--help"] for path, _ in commands(build_parser())]


def listings(dataset: str) -> list[list[str]]:
    """Every command that lists, shows or checks, with the arguments of the README's tour (``dataset``: one
    episode recorded before the timing)."""
    pool = "examples/pools/pick_place_aila"
    return [
        ["demo", "--list"],
        ["tasks"],
        ["tasks", "show", "pick-place"],
        ["robots"],
        ["robots", "show", "ur5e"],
        ["robots", "show", "openarm"],  # the robot with the most meshes (94)
        ["tree", "check", "examples/trees/grasp_then_place_learned.yaml"],
        ["tree", "show", "examples/trees/grasp_then_place.yaml"],
        ["tree", "nodes"],
        ["tree", "schema"],
        ["pool", "ls", pool],
        ["pool", "show", pool, "reach"],
        ["recordings", "show", "examples/data/subject1_run1.tsv"],
        ["examples"],
        ["dataset", "show", dataset],
    ]


def runs() -> list[list[str]]:
    """The README's runs: the default demo, a tree file, and a learned tree with its pool."""
    values = ["--set", "object=0.5,-0.05,30", "--set", "place=0.58,-0.44,0"]
    return [
        ["demo"],
        ["run", "examples/trees/grasp_then_place.yaml", *values],
        [
            "run",
            "examples/trees/grasp_then_place_learned.yaml",
            "--pool",
            "examples/pools/pick_place_aila",
            *values,
        ],
    ]


def checks() -> list[list[str]]:
    """The checks that simulate: timed to their first line."""
    return [["robots", "check", "ur5e"]]


def wall_time(name: str, argv: list[str], kind: str) -> float:
    """Seconds from starting ``argv`` until what its ``kind`` waits for: its first tick (where the probe ends
    it), its first line (then it is stopped), else its end; a command that fails first, or ends without a
    tick or a line, stops the benchmark with its error."""
    start = time.perf_counter()
    process = subprocess.Popen(
        argv, cwd=REPOSITORY, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    if kind == "first line":
        answered = process.stdout.readline() != ""
        elapsed = time.perf_counter() - start
        if answered:
            process.kill()
        _, errors = process.communicate()
    else:
        output, errors = process.communicate()
        elapsed = time.perf_counter() - start
        answered = process.returncode == 0 and (kind != "first tick" or output.endswith(TICKED + "\n"))
    if not answered:
        raise SystemExit(f"{name} ended (exit {process.returncode}) without answering\n{errors}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--runs", type=int, default=5, help="starts of each (the median is reported)")
    args = parser.parse_args()
    if args.runs < 1:
        raise SystemExit(f"--runs must be at least 1, got {args.runs}")
    script = Path(sys.executable).parent / "besman"
    if not script.exists():
        raise SystemExit(f"{script}: no besman script beside this Python (pip install the package)")
    bare = [sys.executable, "-c", "pass"]
    # name -> (kind, the process to start)
    started = {" ".join(["besman", *argv]): ("help", [str(script), *argv]) for argv in helps()}
    folder = tempfile.mkdtemp(prefix="besman-startup-")
    atexit.register(shutil.rmtree, folder, True)
    dataset = Path(folder) / "dataset"
    record = [str(script), "record", "pick-place", "--dataset", str(dataset), "--episodes", "1"]
    subprocess.run(record, check=True, capture_output=True)
    started |= {
        " ".join(["besman", *argv]): ("listing", [str(script), *argv]) for argv in listings(str(dataset))
    }
    started |= {
        " ".join(["besman", *argv]): ("first tick", [sys.executable, "-c", FIRST_TICK, *argv])
        for argv in runs()
    }
    started |= {" ".join(["besman", *argv]): ("first line", [str(script), *argv]) for argv in checks()}
    floor_samples: list[float] = []
    samples: dict[str, list[float]] = {name: [] for name in started}
    for _ in range(args.runs):
        floor_samples.append(wall_time("python -c pass", bare, "end"))
        for name, (kind, argv) in started.items():
            samples[name].append(wall_time(name, argv, kind))
    floor = statistics.median(floor_samples)
    rows = {}
    for name, (kind, _) in started.items():
        s = statistics.median(samples[name])
        target = TARGETS_S[kind]
        rows[name] = {
            "kind": kind,
            "s": s,
            "over_python_s": s - floor,
            "ratio": s / floor,
            "target_s": target,
            "met": s < target,
        }
    missed = [name for name, row in rows.items() if not row["met"]]
    report = {
        "benchmark": "startup",
        "runs": args.runs,
        "python_s": floor,
        "targets_s": TARGETS_S,
        "commands": rows,
        "missed": missed,
        "met": not missed,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    table = Table(title=f"Start-up, median of {args.runs} (python -c pass: {floor:.3f} s)")
    for column in ("command", "s", "x python", "target", ""):
        table.add_column(column, justify="left" if column in ("command", "") else "right")
    for kind in TARGETS_S:
        table.add_section()
        for name, row in rows.items():
            if row["kind"] == kind:
                verdict = "[green]met" if row["met"] else "[red]MISSED"
                label = f"{name} ({kind})" if kind.startswith("first") else name
                table.add_row(
                    label, f"{row['s']:.3f}", f"{row['ratio']:.1f}", f"< {row['target_s']:g} s", verdict
                )
    console = Console(width=140)
    console.print(table)
    if missed:
        console.print(f"[red]{len(missed)} of {len(rows)} missed their target: {', '.join(missed)}")
    else:
        console.print(f"every target met ({len(rows)} commands)")


if __name__ == "__main__":
    main()
