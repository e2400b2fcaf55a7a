"""Ctrl-C at any moment of a ``--view`` run: while the command loads, the viewer starts, the run runs and the
viewer serves it, the command ends as every command does: one line, exit 130 (docs/viewer.md). Before
``besman.main`` ended the process itself, a Ctrl-C during the run printed nanobind's 30-line report of the
ruckig objects the interrupted frames held, and now and then crashed in the teardown (exit 139)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import sigint_by_default

# Seconds after the start: from the handlers' first moment (Python's own start-up, before any of besman runs,
# is not ours) through the imports, the viewer's start (about 0.9 s), the run (about 1.5 s at --speed 8) and
# the serving after it; on a loaded machine the same moments land earlier in the command's life.
MOMENTS = [0.1 + 0.14 * i for i in range(20)]


@pytest.mark.slow
def test_ctrl_c_at_any_moment_of_a_view_run_ends_in_one_line_with_exit_130():
    script = Path(sys.executable).parent / "besman"  # the installed command, as a user starts it
    ended = []
    for moment in MOMENTS:
        process = subprocess.Popen(
            [str(script), "demo", "--view", "--speed", "8"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=sigint_by_default,
            env={**os.environ, "PYTHONFAULTHANDLER": "1"},  # where it hangs, if it does: every thread's stack
        )
        time.sleep(moment)
        process.send_signal(signal.SIGINT)
        try:
            _, err = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # a lost Ctrl-C (seen once in about 100): the stacks say where
            process.send_signal(signal.SIGABRT)
            _, err = process.communicate()
        said = [
            line for line in err.splitlines() if not line.startswith(("viewer: http", "the viewer stays at"))
        ]
        ended.append((round(moment, 2), process.returncode, said))
    assert all(code == 130 and said == ["besman: interrupted"] for _, code, said in ended), [
        case for case in ended if case[1:] != (130, ["besman: interrupted"])
    ]
