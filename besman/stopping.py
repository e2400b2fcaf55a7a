"""How a command stops on Ctrl-C or SIGTERM: in one line, with the exit code a shell expects
(:func:`stopped`), and never inside an import or a callback whose exceptions Python only reports."""

import os
import signal
import sys
import threading

# The signals that stopped the command, in order. SIGTERM (``kill``, a supervisor) raises KeyboardInterrupt as
# Ctrl-C does, so that every clean-up of Ctrl-C runs for it too; which signal it was is kept here, not in the
# exception (Ray's ray.get replaces any KeyboardInterrupt with a new one).
_received: list[int] = []
# The exit code of a command whose output's reader stopped reading (| head): 128 + SIGPIPE, what a shell
# reports of a command a closed pipe ended.
PIPE_CLOSED = 141


def stopped(kept: str = "") -> int:
    """Says in one line that Ctrl-C or SIGTERM stopped the command (``kept``: what it leaves that is of use)
    and returns the exit code: 130 for Ctrl-C, 143 for SIGTERM. Both are 128 + the signal's number, what a
    shell reports for a process the signal ended, so a supervisor that sent SIGTERM sees the stop it asked
    for, and not a user's Ctrl-C."""
    terminated = _received[-1:] == [signal.SIGTERM]
    bars = sys.modules.get("tqdm")
    for bar in list(getattr(getattr(bars, "tqdm", None), "_instances", ())):
        bar.close()  # a progress bar the stop left drawn ends its line first: ours is the last line
    print(f"besman: {'terminated' if terminated else 'interrupted'}{kept}", file=sys.stderr)
    return 143 if terminated else 130


def stop_after_imports(signum, frame) -> None:
    """Python's Ctrl-C, for SIGTERM too, but not inside an import: a KeyboardInterrupt raised while an
    extension module initialises (mujoco's, numpy's) can leave it half made and crash the process later (a
    segmentation fault, seen once in the suite). Inside an import the signal is sent again 50 ms later, until
    it lands after."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            threading.Timer(0.05, os.kill, (os.getpid(), signum)).start()
            return
        frame = frame.f_back
    _received.append(signum)
    raise KeyboardInterrupt


def ctrl_c_again(report):
    """An unraisable-exception hook that does not lose a Ctrl-C (or a SIGTERM): one that arrives while Python
    runs a callback whose exceptions it only reports (an import lock's weakref callback, a ``__del__``) would
    be printed as "Exception ignored" and the command would run on; it is raised again, where it counts, by
    the signal sent once more from a thread when the callback is over (sent at once, it would land in this
    hook, where exceptions are only reported too)."""

    def hook(unraisable) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            again = _received[-1] if _received else signal.SIGINT
            threading.Timer(0.05, os.kill, (os.getpid(), again)).start()
            return
        report(unraisable)

    return hook
