"""How long the commands take whose times the README and the docs state, measured here as a user runs them:
each command once, one after the other, from an empty folder with the examples copied (``besman examples
--copy``), its wall time from start to exit (the human recordings read from ``../shared`` beside the
checkout).

    python benchmarks/command_times.py [--json] [--only NAME ...] [--out docs/results/command_times.json]

Every time the docs state for these commands is written from the record this keeps
(``docs/results/command_times.json``, with the machine's processor and cores and the date), in the words of
:data:`STATED`; ``tests/test_docs.py`` checks that the docs say what the record holds. The times of the long
runs (the experiments' full runs, the benchmarks of many minutes) are measured by the runs themselves and
kept in their own results (``minutes`` in their JSON), not here. A command that fails stops the script and
nothing is written.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
RECORD = REPOSITORY / "docs" / "results" / "command_times.json"
SCHEMA_VERSION = 1
SHARED = REPOSITORY.parent / "shared" / "data" / "dfki_pick_and_place"  # the human recordings
# name -> the command, run from the empty folder ("{repo}" the checkout, "{shared}" the recordings); a
# command that needs another's output first gives both, the last one timed.
COMMANDS = {
    "demo": ["besman demo"],
    "robots check": ["besman robots check examples/robots/widowx_ai"],
    "throwing --quick": ["besman experiment throwing --quick --out throwing"],
    "ball-in-cup --quick": ["besman experiment ball-in-cup --quick --out ball_in_cup"],
    "puck-strike --quick": ["besman experiment puck-strike --quick --out puck_strike"],
    "benchmarks/ball_in_cup.py": ["{python} {repo}/benchmarks/ball_in_cup.py"],
    "benchmarks/puck_strike.py": ["{python} {repo}/benchmarks/puck_strike.py"],
    "learn from a dataset": [
        "besman record pick-place --dataset demos --episodes 15 --perturb perception",
        "besman learn --demos demos --out dataset_pool --training-tasks 2 --budget 8",
    ],
    "learn on AILA": ["besman learn --demos {shared} --out mypool"],
    "learn on the UR5e": ["besman learn --robot ur5e --demos {shared} --out ur5e_pool"],
}
# name -> where the docs state its time and in which words ({} the time as :func:`stated` writes it); the
# test reads the pages with their line breaks made spaces.
STATED = {
    "demo": [("docs/getting-started.md", "besman demo # pick-place on AILA, {} on two cores")],
    "robots check": [("docs/robots.md", "one failed demo at a time, in {} on two cores")],
    "throwing --quick": [
        ("README.md", "`--quick` runs a small version in {} on two cores"),
        ("docs/throwing.md", "`--quick` takes {} on two cores"),
        ("docs/throwing.md", "`--quick` {} on two cores (limit 3 minutes)"),
    ],
    "ball-in-cup --quick": [("docs/ball_in_cup.md", "`--quick` is a {} version for tests")],
    "puck-strike --quick": [("docs/puck_strike.md", "`--quick` is a {} version for tests")],
    "benchmarks/ball_in_cup.py": [("docs/ball_in_cup.md", "for the report as JSON; {} on two cores")],
    "benchmarks/puck_strike.py": [("docs/puck_strike.md", "for the report as JSON; {} on two cores")],
    "learn from a dataset": [("docs/datasets.md", "--budget 8` learns in {} on two cores")],
    "learn on AILA": [("docs/learning.md", "--out mypool # {} on two cores")],
    "learn on the UR5e": [("docs/robots.md", "all 24 training tasks succeed; {} on two cores")],
}


def stated(seconds: float) -> str:
    """A time as the docs write it: seconds to a tenth under ten, whole seconds under two minutes, else
    minutes to a tenth."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} minutes"


def processor() -> str:
    """The processor's model name (Linux's /proc/cpuinfo), or "unknown"."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return "unknown"
    return next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "unknown")


def measure(names: list[str]) -> dict[str, float]:
    """Each command's wall time (s), run once from an empty folder holding a copy of the examples."""
    seconds = {}
    with tempfile.TemporaryDirectory(prefix="besman-times-") as folder:
        subprocess.run(["besman", "examples", "--copy", folder], check=True, capture_output=True)
        for name in names:
            for command in COMMANDS[name]:
                argv = shlex.split(command.format(python=sys.executable, repo=REPOSITORY, shared=SHARED))
                print(f"{name}: {' '.join(argv)}", file=sys.stderr, flush=True)
                started = time.perf_counter()
                result = subprocess.run(argv, cwd=folder, capture_output=True, text=True)
                seconds[name] = round(time.perf_counter() - started, 1)
                if result.returncode != 0:
                    raise SystemExit(f"{name} failed (exit {result.returncode}):\n{result.stderr[-2000:]}")
            print(f"  {seconds[name]:.1f} s", file=sys.stderr, flush=True)
    return seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the record as JSON")
    parser.add_argument("--only", nargs="+", choices=list(COMMANDS), help="measure these (others kept)")
    parser.add_argument("--out", type=Path, default=RECORD, help=f"the record (default {RECORD.name})")
    args = parser.parse_args()
    kept = json.loads(args.out.read_text())["seconds"] if args.only and args.out.is_file() else {}
    seconds = {**kept, **measure(args.only or list(COMMANDS))}
    record = {
        "schema_version": SCHEMA_VERSION,
        "date": datetime.date.today().isoformat(),
        "cores": os.cpu_count(),
        "processor": processor(),
        "seconds": seconds,
        "stated": {name: stated(value) for name, value in seconds.items()},
    }
    text = json.dumps(record, indent=1) + "\n"
    temporary = args.out.with_name(f".{args.out.name}.tmp")
    temporary.write_text(text)
    temporary.replace(args.out)
    if args.json:
        print(text, end="")
    else:
        for name, value in seconds.items():
            print(f"{name:28s} {value:7.1f} s   the docs say: {stated(value)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
