"""The reaper of a local Ray instance: its processes end with the process that started it.

Ray's workers, raylet and GCS share the fate of the driver that started them, but its dashboard and
runtime-env agents outlive a ``kill -9`` of the driver by a minute or more (they try to report the raylet's
death to the dead GCS first). So when :func:`besman.sim.evaluation.evaluate_on_ray` starts Ray itself, it
first starts this reaper with a pipe to it and marks its own environment (``BESMAN_RAY_OWNER``), which Ray's
raylet, GCS and workers inherit; workers also name their raylet (``RAY_RAYLET_PID``). The agents cannot be
found that way: the raylet starts them, and the process title they take (``ray::DashboardAgent``) can blank
the environment that ``/proc`` shows (it often does with Ray 2.60). So while the pipe is open, the reaper
notes the marked processes and every descendant of them (the agents are the raylet's children), each with its
start time (after 1, 3, 7... s, then every 30 s); when it closes - the driver ended, however it ended - it
kills every noted process still alive with the same start time (a pid used again by another process is
spared), and every process that carries the mark, names one of the marked as its raylet or descends from them
then (found through ``/proc``: Linux).
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

OWNER = "BESMAN_RAY_OWNER"


def start(mark: str) -> subprocess.Popen:
    """Starts the reaper of processes marked ``mark`` (its own environment unmarked); it acts when the
    returned process's stdin closes: keep the object as long as Ray runs."""
    environment = {name: value for name, value in os.environ.items() if name != OWNER}
    return subprocess.Popen(
        [sys.executable, "-m", "besman.sim.reaper", mark],
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=environment,
        start_new_session=True,  # a Ctrl-C in the terminal reaches the driver, not the reaper
    )


def environments() -> dict[int, list[bytes]]:
    """Every readable process's environment entries, by pid."""
    found = {}
    for folder in Path("/proc").glob("[0-9]*"):
        try:
            found[int(folder.name)] = (folder / "environ").read_bytes().split(b"\0")
        except OSError:
            continue  # ended meanwhile, or not ours to read
    return found


def marked(mark: str, raylets: set[int] = frozenset()) -> set[int]:
    """The processes whose environment holds ``BESMAN_RAY_OWNER=mark``, or names one of ``raylets`` as
    their raylet."""
    entries = {f"{OWNER}={mark}".encode(), *(f"RAY_RAYLET_PID={pid}".encode() for pid in raylets)}
    return {pid for pid, environment in environments().items() if entries.intersection(environment)}


def processes() -> dict[int, tuple[int, int]]:
    """Every process's parent pid and start time (clock ticks after boot: with the pid, one process), by
    pid."""
    found = {}
    for folder in Path("/proc").glob("[0-9]*"):
        try:
            fields = (folder / "stat").read_text().rsplit(")", 1)[1].split()  # the name may hold ")"
            found[int(folder.name)] = int(fields[1]), int(fields[19])  # fields 4 and 22 of stat
        except (OSError, IndexError, ValueError):
            continue  # ended meanwhile
    return found


def family(pids: set[int], noted: dict[int, int]) -> dict[int, int]:
    """The live processes among ``pids``, those of ``noted`` (pid: start time) that started when noted (not
    another process with the pid), and every descendant of them, with their start times."""
    table = processes()
    children: dict[int, list[int]] = {}
    for pid, (parent, _) in table.items():
        children.setdefault(parent, []).append(pid)
    todo = [pid for pid in pids if pid in table]
    todo += [pid for pid, start in noted.items() if pid in table and table[pid][1] == start]
    found = {}
    while todo:
        pid = todo.pop()
        if pid not in found:
            found[pid] = table[pid][1]
            todo += children.get(pid, [])  # the raylet's agents, whose environment /proc no longer shows
    return found


def main() -> None:
    mark, seen, noted, wait = sys.argv[1], set(), {}, 1.0
    while not select.select([sys.stdin], [], [], wait)[0] or sys.stdin.buffer.read1(1):
        now = marked(mark)  # the pipe is open: the driver lives
        seen, noted = seen | now, noted | family(now, noted)
        wait = min(2 * wait, 30.0)  # Ray starts its raylet at once: look often at first, then seldom
    for _ in range(3):  # Ray may still be starting a process as the driver dies
        for pid in family(marked(mark, seen), noted).keys() - {os.getpid()}:
            with contextlib.suppress(ProcessLookupError):  # ended meanwhile
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.5)


if __name__ == "__main__":
    main()
