"""A demonstration of an arm's joint motion as a file, and its imitation into an open-loop task's DMP.

The file is JSON (never pickle): ``schema_version`` (:data:`SCHEMA_VERSION`), ``kind`` (what demonstration
it is, e.g. ``"besman ball-in-cup demonstration"``), the robot and its joints, ``synthetic`` with how it was
made (``made_by``), and the samples: ``times`` (s) and ``positions`` (rad, one row of joint values per time),
rounded to 6 decimals.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from besman.core.errors import InputError
from besman.skills import DMP, DMPSettings

SCHEMA_VERSION = 1


def sample_held(
    spline, end: float, sample_rate: float, times=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A joint-space ``spline`` (a scipy piecewise polynomial from t = 0 to ``end`` s) sampled at ``times``
    (default: ``sample_rate`` Hz over it): times (T,), joint positions and velocities (T, joints); after
    its end it holds still."""
    if times is None:
        times = np.arange(round(end * sample_rate) + 1) / sample_rate
    times = np.asarray(times, dtype=float)
    clipped = np.minimum(times, end)
    velocities = spline(clipped, 1)
    velocities[times > end] = 0.0
    return times, spline(clipped), velocities


def write_demonstration(path, *, kind: str, robot: str, joints, made_by: str, times, positions) -> Path:
    """Writes a synthetic demonstration of ``kind`` - times (T,) and joint positions (T, joints) - to
    ``path`` (JSON, see the module documentation)."""
    record = {
        "schema_version": SCHEMA_VERSION,
        "kind": kind,
        "robot": robot,
        "joints": list(joints),
        "synthetic": True,
        "made_by": made_by,
        "times": [round(float(t), 6) for t in times],
        "positions": [[round(float(q), 6) for q in row] for row in positions],
    }
    path = Path(path)
    path.write_text(json.dumps(record, indent=1) + "\n")
    return path


def read_demonstration(path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Times (T,) and joint positions (T, joints) of a demonstration file of ``kind``; a file of another
    kind or schema is refused by name."""
    path = Path(path)
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise InputError(f"{path}: not a readable demonstration file ({error})") from None
    found = record.get("kind") if isinstance(record, dict) else None
    if found != kind:
        raise InputError(f"{path}: not a {kind} (its 'kind' is {found!r})")
    if record.get("schema_version") != SCHEMA_VERSION:
        raise InputError(
            f"{path}: schema_version {record.get('schema_version')!r}, this besman reads {SCHEMA_VERSION}"
        )
    times = np.asarray(record["times"], dtype=float)
    positions = np.asarray(record["positions"], dtype=float)
    if positions.ndim != 2 or positions.shape != (len(times), len(record["joints"])):
        raise InputError(f"{path}: positions must be one row of {len(record['joints'])} per time")
    return times, positions


def imitate(task, times, positions) -> np.ndarray:
    """theta of ``task``'s DMP (an :class:`~besman.sim.open_loop.OpenLoopRollouts`) imitated from one
    demonstration, which must start at the task's start pose and last its execution time."""
    positions = np.asarray(positions, dtype=float)
    if not np.allclose(positions[0], task.start, atol=1e-4):
        raise InputError(f"the demonstration starts at {positions[0]}, not at the task's start {task.start}")
    duration = float(times[-1] - times[0])
    if abs(duration - task.config.execution_time) > 1e-6:
        raise InputError(
            f"the demonstration lasts {duration:g} s; the task's DMP {task.config.execution_time:g} s"
        )
    dmp = DMP(
        task.arm.size,
        settings=DMPSettings(n_weights=task.config.n_weights),
        dt=task.timestep,
    ).imitate(times, positions)
    dmp.start = task.start.copy()  # the demonstration's start, to the last bit
    return dmp.get_params()
