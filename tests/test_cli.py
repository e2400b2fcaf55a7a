"""The `besman` command line."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import run_cli
from PIL import Image

from besman import __version__
from besman.cli import main

TREES = Path(__file__).resolve().parents[1] / "examples" / "trees"


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"besman {__version__}"
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "robots" in capsys.readouterr().out


def test_robots_lists_the_models(capsys):
    code, out, _ = run_cli(capsys, "robots")
    assert code == 0
    assert [line.split("\t")[0] for line in out.splitlines()] == ["aila", "openarm", "pa10", "ur5e"]


def test_robots_show_json_is_the_joint_table(capsys):
    code, out, _ = run_cli(capsys, "robots", "show", "aila", "--json")
    assert code == 0
    table = json.loads(out)
    joints = {joint["name"]: joint for joint in table["joints"]}
    assert joints["J_Elbow_r"] == {
        "group": "right_arm",
        "name": "J_Elbow_r",
        "lower": -0.0873,
        "upper": 1.8326,
        "velocity": 1.5,
        "acceleration": 4.0,
        "jerk": 40.0,
    }
    assert table["groups"]["right_gripper"]["actuators"] == ["right_gripper"]
    assert len(table["joints"]) == 3 + 4 + 1 + 2 + 2 * 7 + 2 * 2  # J_Waist twice: torso and waist
    assert len(joints) == 3 + 4 + 2 + 2 * 7 + 2 * 2


def test_robots_show_prints_a_table(capsys):
    code, out, _ = run_cli(capsys, "robots", "show", "pa10")
    assert code == 0
    assert "S1" in out and "W2" in out and "velocity" in out and "6.283" in out


def test_unknown_robot_is_a_clear_error(capsys):
    code, _, err = run_cli(capsys, "robots", "show", "r2d2")
    assert code == 2
    assert "unknown robot 'r2d2'; available: aila, openarm, pa10, ur5e" in err
    assert "Traceback" not in err


def test_render_writes_a_png(capsys, tmp_path):
    out_file = tmp_path / "pictures" / "pa10.png"
    code, _, _ = run_cli(
        capsys, "robots", "render", "pa10", "--out", str(out_file), "--width", "320", "--height", "240"
    )
    assert code == 0
    image = np.asarray(Image.open(out_file))
    assert image.shape == (240, 320, 3)
    assert image.std() > 10, "a real picture, not a blank frame"
    assert list(tmp_path.joinpath("pictures").iterdir()) == [out_file], "no temporary files left behind"


def test_render_rejects_a_non_png_name(capsys, tmp_path):
    code, _, err = run_cli(
        capsys,
        "robots",
        "render",
        "pa10",
        "--out",
        str(tmp_path / "x.jpg"),
        "--width",
        "64",
        "--height",
        "48",
    )
    assert code == 2 and "must end in .png" in err


@pytest.mark.slow
def test_python_dash_m_besman(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "besman", "robots"], capture_output=True, text=True, cwd=tmp_path, check=True
    )
    assert result.stdout.startswith("aila")


def test_a_command_ends_the_process_before_the_native_teardown(tmp_path):
    """``besman.main`` ends the process itself once the command has ended (pyarrow's thread pools abort the
    native teardown now and then, apache/arrow#34314; after a Ctrl-C nanobind reports ruckig's objects):
    first what Python's teardown does first (a running thread joined, the atexit handlers), with the
    command's exit code; the teardown itself never runs (an object it would finalise says nothing)."""
    code = (
        "import atexit, sys, threading, time, pyarrow, besman\n"
        "class Finalised:\n"
        "    def __del__(self):\n"
        "        print('torn down', flush=True)\n"
        "kept = Finalised()\n"
        "threading.Thread(target=lambda: (time.sleep(0.2), print('thread joined', flush=True))).start()\n"
        "atexit.register(lambda: print('atexit ran', flush=True))\n"
        "sys.argv = ['besman', 'dataset', 'show', sys.argv[1]]\n"
        "sys.exit(besman.main())\n"
    )
    ended = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
    assert ended.returncode == 2 and "not a LeRobot dataset" in ended.stderr, ended.stderr
    assert ended.stdout.splitlines() == ["thread joined", "atexit ran"]


def test_a_run_in_a_terminal_shows_its_progress_and_wipes_it_and_a_pipe_gets_none(tmp_path):
    """On a terminal the run redraws one status line (the leaf at work, the tick, the simulated time) and
    wipes it before the summary; piped, stderr holds nothing of it."""
    import os
    import pty

    from besman.commands.progress import CLEAR_LINE

    argv = [sys.executable, "-m", "besman", "run", str(TREES / "grasp_then_place.yaml"), "--seed", "1"]
    terminal, other_end = pty.openpty()
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=other_end, cwd=tmp_path)
    os.close(other_end)
    shown = b""
    while True:
        try:
            chunk = os.read(terminal, 4096)
        except OSError:  # the run ended: the terminal's other end closed
            break
        if not chunk:
            break
        shown += chunk
    out, _ = process.communicate(timeout=120)
    os.close(terminal)
    lines = [line for line in shown.decode().split(CLEAR_LINE) if line]
    assert process.returncode == 0 and out.decode().startswith("SUCCESS")
    status = re.compile(r"\d+ s: .*tick \d+.* \(?\d+\.\d s simulated\)")
    assert lines and all(status.fullmatch(line) for line in lines), lines
    assert shown.endswith(CLEAR_LINE.encode()), shown[-200:]
    piped = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path)
    assert piped.returncode == 0 and piped.stderr == "", piped.stderr


@pytest.mark.parametrize("unbuffered", ["1", ""])
def test_output_piped_to_a_reader_that_stops_early_ends_quietly(unbuffered):
    """``besman tree nodes | head -1``: the reader closes the pipe; the command ends as a closed pipe ends
    any command (exit 141, 128 + SIGPIPE) and says nothing (no "Broken pipe" error, no traceback), whether
    its output is written as it goes (PYTHONUNBUFFERED) or at its end."""
    script = Path(sys.executable).parent / "besman"
    environment = {**os.environ, "PYTHONUNBUFFERED": unbuffered}
    process = subprocess.Popen(
        [str(script), "tree", "nodes"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=environment
    )
    process.stdout.close()  # before the command writes: every write finds the pipe closed
    assert process.wait(timeout=60) == 141
    assert process.stderr.read() == b""
