"""How fast the command line answers: ``besman --help`` and every command's ``--help`` beside a bare Python.

    python benchmarks/startup.py [--json] [--runs 7]

Each is started ``runs`` times as a new process (the installed ``besman`` script beside this interpreter;
the median wall time), in alternation with ``python -c pass`` on the same interpreter, whose time is the
floor no command line can go below. Target: every ``--help`` under 0.3 s.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

TARGET_S = 0.3


def commands() -> list[list[str]]:
    """``--help`` of the command line and of every command and subcommand."""
    from besman.cli import build_parser, commands

    return [[*path, "--help"] for path, _ in commands(build_parser())]


def wall_time(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--runs", type=int, default=7, help="starts of each (the median is reported)")
    args = parser.parse_args()
    if args.runs < 1:
        raise SystemExit(f"--runs must be at least 1, got {args.runs}")
    script = Path(sys.executable).parent / "besman"
    if not script.exists():
        raise SystemExit(f"{script}: no besman script beside this Python (pip install the package)")
    bare = [sys.executable, "-c", "pass"]
    helps = commands()
    samples: dict[str, list[float]] = {"python -c pass": []} | {" ".join(["besman", *h]): [] for h in helps}
    for _ in range(args.runs):
        samples["python -c pass"].append(wall_time(bare))
        for argv in helps:
            samples[" ".join(["besman", *argv])].append(wall_time([str(script), *argv]))
    medians = {name: statistics.median(times) for name, times in samples.items()}
    floor = medians.pop("python -c pass")
    report = {
        "benchmark": "startup",
        "runs": args.runs,
        "python_s": floor,
        "commands": {name: {"s": s, "over_python_s": s - floor} for name, s in medians.items()},
        "slowest_s": max(medians.values()),
        "target_s": TARGET_S,
        "met": max(medians.values()) < TARGET_S,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    table = Table(title=f"Start-up, median of {args.runs} (python -c pass: {floor:.3f} s)")
    for column in ("command", "s", "over python"):
        table.add_column(column, justify="right" if column != "command" else "left")
    for name, s in medians.items():
        table.add_row(name, f"{s:.3f}", f"{s - floor:+.3f}")
    console = Console(width=120)
    console.print(table)
    verdict = "met" if report["met"] else "NOT met"
    console.print(f"slowest {report['slowest_s']:.3f} s (target < {TARGET_S} s): {verdict}")


if __name__ == "__main__":
    main()
