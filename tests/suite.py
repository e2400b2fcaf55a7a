"""The whole suite as CI runs it (the README's test command ends with ``python tests/suite.py``): every test,
slow ones included, in two phases, the browser viewer's tests alone after the rest (software WebGL beside a
busy worker is too slow for their real-time checks; run beside the rest at a lower priority, the suite took
longer, not less), and the second whatever the first gave; the exit code is
non-zero where either phase failed. It measures what the README states of the suite: the wall time and the
peak memory of the whole process tree (pytest, its workers and every command, Ray worker and browser they
start: the sum of their proportional set sizes, /proc's PSS, sampled every half second), printed at the end
and kept in ``tests/suite.json`` beside the test files' own times (``tests/durations.json``)."""

import json
import os
import re
import shlex
import subprocess
import sys
import threading
import time
from pathlib import Path

TESTS = Path(__file__).resolve().parent
RECORD = TESTS / "suite.json"
PHASES = {
    "all but the viewer": ["-n", "auto", "--dist", "loadfile", "--ignore", str(TESTS / "test_viewer.py")],
    "the viewer": [str(TESTS / "test_viewer.py")],
}
SAMPLE_SECONDS = 0.5


def tree_memory(root: int) -> int:
    """The proportional set size (bytes) of ``root`` and every process below it: a shared page counts once
    in all, split among the processes that map it. Linux only (/proc)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:  # ended meanwhile
                continue
            parent = int(stat.rpartition(")")[2].split()[1])  # the name in parentheses may hold spaces
            children.setdefault(parent, []).append(int(entry))
    below, frontier = [root], [root]
    while frontier:
        found = children.get(frontier.pop(), [])
        below.extend(found)
        frontier.extend(found)
    total = 0
    for pid in below:
        try:
            rollup = Path(f"/proc/{pid}/smaps_rollup").read_text()
        except OSError:
            continue
        match = re.search(r"^Pss:\s+(\d+) kB", rollup, flags=re.MULTILINE)
        total += int(match.group(1)) * 1024 if match else 0
    return total


def run_phase(name: str, arguments: list[str]) -> dict:
    """One pytest run, its output passed on as it comes; its exit code, counts, minutes and peak memory."""
    argv = [sys.executable, "-m", "pytest", "-m", "", "--record-durations", *arguments]
    print(f"+ python {shlex.join(argv[1:])}  ({name})", flush=True)
    started = time.monotonic()
    process = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=TESTS.parent
    )
    peak = [0]

    def sample() -> None:
        while process.poll() is None:
            peak[0] = max(peak[0], tree_memory(process.pid))
            time.sleep(SAMPLE_SECONDS)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    last = ""
    for line in process.stdout:
        sys.stdout.write(line)
        sys.stdout.flush()
        if line.strip():
            last = line
    code = process.wait()
    sampler.join()
    counted = re.findall(r"(\d+) (passed|failed|errors?|skipped)", last)  # pytest's last line
    counts = {word: int(number) for number, word in counted}
    return {
        "name": name,
        "exit_code": code,
        "counts": counts,
        "minutes": round((time.monotonic() - started) / 60, 2),
        "peak_memory_gb": round(peak[0] / 1e9, 2),
    }


def main() -> int:
    started = time.monotonic()
    phases = [run_phase(name, arguments) for name, arguments in PHASES.items()]
    record = {
        "schema_version": 1,
        "cores": os.cpu_count(),
        "minutes": round((time.monotonic() - started) / 60, 2),
        "peak_memory_gb": max(phase["peak_memory_gb"] for phase in phases),
        "phases": phases,
    }
    RECORD.write_text(json.dumps(record, indent=1) + "\n")
    failed = [phase["name"] for phase in phases if phase["exit_code"] != 0]
    verdict = f"FAILED: {', '.join(failed)}" if failed else "passed"
    print(
        f"suite: {record['minutes']:.1f} min on {record['cores']} cores, peak memory "
        f"{record['peak_memory_gb']:.1f} GB ({RECORD.name}); {verdict}",
        flush=True,
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
