"""The whole suite as CI runs it (the README's test command ends with ``python tests/suite.py``): every test,
slow ones included, in two pytest runs at once. The browser viewer's tests run in one of their own beside the
rest: they mostly wait on real time and on the headless browser (about 40 s of processor time in 90 s), but
software WebGL next to a busy worker is too slow for their real-time checks, so the rest run at a lower
priority (nice 10) and leave them the processor whenever they want it. Each run goes on whatever the other
gives; the exit code is non-zero where either failed. It measures what the README states of the suite: the
wall time and the peak memory of the whole process tree (pytest, its workers and every command, Ray worker
and browser they start: the sum of their proportional set sizes, /proc's PSS, sampled every half second),
printed at the end and kept in ``tests/suite.json`` beside the test files' own times
(``tests/durations.json``). The rest's output comes as it runs, the viewer's after it."""

import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
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


def start(name: str, arguments: list[str], output, nice: int) -> subprocess.Popen:
    """One pytest run, started with its output to ``output``, at the priority ``nice``."""
    argv = [sys.executable, "-m", "pytest", "-m", "", "--record-durations", *arguments]
    print(f"+ python {shlex.join(argv[1:])}  ({name}, nice {nice})", flush=True)
    return subprocess.Popen(
        argv,
        stdout=output,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=TESTS.parent,
        preexec_fn=(lambda: os.nice(nice)) if nice else None,
    )


def outcome(name: str, code: int, last_line: str, seconds: float, peak: int) -> dict:
    counted = re.findall(r"(\d+) (passed|failed|errors?|skipped)", last_line)  # pytest's last line
    return {
        "name": name,
        "exit_code": code,
        "counts": {word: int(number) for number, word in counted},
        "minutes": round(seconds / 60, 2),
        "peak_memory_gb": round(peak / 1e9, 2),
    }


def main() -> int:
    started = time.monotonic()
    (rest_name, rest), (viewer_name, viewer) = PHASES.items()
    with tempfile.TemporaryFile("w+") as viewer_output:
        processes = {
            viewer_name: start(viewer_name, viewer, viewer_output, nice=0),
            rest_name: start(rest_name, rest, subprocess.PIPE, nice=10),
        }
        ended: dict[str, float] = {}
        peaks = dict.fromkeys(processes, 0)
        peak = [0]  # of both at once

        def sample() -> None:
            while len(ended) < len(processes):
                both = 0
                for name, process in processes.items():
                    if name in ended:
                        continue
                    if process.poll() is not None:
                        ended[name] = time.monotonic() - started
                        continue
                    used = tree_memory(process.pid)
                    peaks[name], both = max(peaks[name], used), both + used
                peak[0] = max(peak[0], both)
                time.sleep(SAMPLE_SECONDS)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        last = ""
        for line in processes[rest_name].stdout:
            sys.stdout.write(line)
            sys.stdout.flush()
            last = line if line.strip() else last
        codes = {name: process.wait() for name, process in processes.items()}
        sampler.join()  # it notes when each ended
        viewer_output.seek(0)
        viewer_lines = viewer_output.read()
    sys.stdout.write(viewer_lines)
    viewer_last = next((line for line in reversed(viewer_lines.splitlines()) if line.strip()), "")
    phases = [
        outcome(rest_name, codes[rest_name], last, ended[rest_name], peaks[rest_name]),
        outcome(viewer_name, codes[viewer_name], viewer_last, ended[viewer_name], peaks[viewer_name]),
    ]
    record = {
        "schema_version": 1,
        "cores": os.cpu_count(),
        "minutes": round((time.monotonic() - started) / 60, 2),
        "peak_memory_gb": round(peak[0] / 1e9, 2),
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
