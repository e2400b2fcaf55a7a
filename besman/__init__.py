"""besman: robots learn reusable manipulation skills and run them as behaviour trees.

The subpackages follow the BESMAN learning platform (Metzen et al., "Towards Learning of Generic Skills for
Robotic Manipulation", KI 2014): ``besman.skills`` (DMPs and movement primitives), ``besman.learning``
(from demonstrations to primitives), ``besman.robots`` (models and kinematics), ``besman.sim`` (worlds,
rollouts, execution) and ``besman.trees`` (behaviour trees); ``besman.cli`` is the command line on top (its
commands in ``besman.commands``, a module per family).
"""

import os
import signal
import sys

from besman._version import __version__
from besman.core import moved
from besman.stopping import PIPE_CLOSED, ctrl_c_again, stop_after_imports, stopped

moved.install()  # the old names of modules that moved keep importing (besman.core.moved)

__all__ = ["__version__", "main", "stopped"]


def main() -> int:
    """The ``besman`` command: the command line (:mod:`besman.cli`), imported here so that a Ctrl-C or a
    SIGTERM while it loads ends with one line too; once the command has ended, so does the process
    (:func:`_end_before_teardown`)."""
    sys.unraisablehook = ctrl_c_again(sys.unraisablehook)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where Ctrl-C is ignored
        signal.signal(signal.SIGINT, stop_after_imports)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:  # not where SIGTERM is ignored
        signal.signal(signal.SIGTERM, stop_after_imports)
    try:
        from besman.cli import main as command_line
    except KeyboardInterrupt:  # its modules are pure Python: no extension's ImportError to unwrap
        return stopped()
    code = command_line()
    # The command has ended and said so: a Ctrl-C while the interpreter tears down changes nothing, and a
    # SIGTERM ends it at once (nothing is left to clean up).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if signal.getsignal(signal.SIGTERM) is stop_after_imports:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _end_before_teardown(code)


def _end_before_teardown(code: int) -> None:
    """Ends the process once the command has ended, after what Python's teardown runs first (non-daemon
    threads joined, atexit handlers, the streams flushed) but before the native libraries' teardown, which
    adds nothing to a command that has said all and has broken its last line: pyarrow's thread pools abort
    the process now and then ("terminate called without an active exception", exit -6; apache/arrow#34314,
    open); after a Ctrl-C mid-run, nanobind prints a 30-line report of the ruckig objects the interrupted
    frames still hold, and the viewer's threads met the freed MuJoCo data (exit 139)."""
    import atexit
    import threading

    threading._shutdown()  # what the interpreter's finalisation does first: join the non-daemon threads
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
    except BrokenPipeError:  # the reader stopped before the output's last block (besman tree nodes | head)
        code = code or PIPE_CLOSED
    sys.stderr.flush()
    os._exit(code)
