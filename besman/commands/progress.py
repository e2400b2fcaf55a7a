"""A run's progress on the terminal: one status line on stderr, redrawn twice a second while the tree runs
(the wall time, the leaf running, the tick and the simulated time), wiped when the run ends. Only where stderr
is a terminal: a log or a pipe gets the run's summary alone. The line is drawn by a thread of its own, so it
keeps counting through a tick that takes long (a learned tree's online refinement runs inside one)."""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

CLEAR_LINE = "\r\033[K"  # back to the line's start and erase it


class RunProgress:
    """Use as a context around a run, its :meth:`observe` the runner's observer (every tick)."""

    def __init__(self, stream: TextIO | None = None, interval: float = 0.5) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.interval = interval
        self.leaf = "starting"
        self.tick = 0
        self.simulated = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = self._ticked = time.monotonic()

    def observe(self, _runner, record: dict) -> None:
        running = [path for path, status in record["statuses"].items() if status == "RUNNING"]
        if running:  # the deepest running node: the leaf at work
            self.leaf = max(running, key=lambda path: path.count("/")).rpartition("/")[2]
        self.tick, self.simulated = record["tick"], record["time"]
        self._ticked = time.monotonic()

    def line(self) -> str:
        now = time.monotonic()
        at = f"{now - self._started:.0f} s: "
        simulated = f"{self.simulated:.1f} s simulated"
        if now - self._ticked < 1.0:
            return at + f"{self.leaf} (tick {self.tick}, {simulated})"
        # A long tick: a leaf starting (planning, a learned primitive refined online), not yet seen running.
        working = f"tick {self.tick + 1} at work for {now - self._ticked:.0f} s"
        return at + f"{working}, after {self.leaf} ({simulated})"

    def _draw(self) -> None:
        while not self._stop.wait(self.interval):
            self.stream.write(CLEAR_LINE + self.line())
            self.stream.flush()

    def __enter__(self) -> RunProgress:
        if self.stream.isatty():
            self._thread = threading.Thread(target=self._draw, name="besman-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *_exception) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self.stream.write(CLEAR_LINE)
            self.stream.flush()
