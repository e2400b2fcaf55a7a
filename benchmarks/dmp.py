"""DMP speed, side by side with movement-primitives (its compiled Cython steps) in one run.

    python benchmarks/dmp.py [--json] [--repeats 7]

Cases: (a) 64 candidate 7-DOF trajectories of 500 steps (ours: one batched call; theirs: one open_loop
per candidate), (b) one 7-DOF trajectory of 1000 steps, (c) imitating one 7-DOF demonstration of 1000
steps, (d) one Cartesian DMP trajectory of 1000 steps. Each time is the median of ``--repeats`` runs after
a warm-up run (ours keeps its precomputed responses between calls, as it does in policy search; the cold
first call is reported too). Ratios are theirs / ours.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
from movement_primitives import dmp as peer
from movement_primitives import dmp_fast  # noqa: F401  (fails loudly if the compiled steps are missing)
from rich.console import Console
from rich.table import Table

from besman.skills import DMP, CartesianDMP
from besman.skills import quaternion as quat
from besman.skills.transformation import minimum_jerk

TARGETS = {"a": 50.0, "b": 5.0, "c": 1.0, "d": 5.0}


def median_seconds(function, repeats: int) -> tuple[float, float]:
    """(cold, median warm) wall time of ``function()``."""
    start = time.perf_counter()
    function()
    cold = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return cold, statistics.median(times)


def demonstration(steps: int, dims: int = 7) -> tuple[np.ndarray, np.ndarray]:
    times = np.linspace(0.0, (steps - 1) * 0.001, steps)
    s = times / times[-1]
    profile = minimum_jerk(s)
    positions = np.column_stack(
        [0.3 * (d + 1) * profile + 0.1 * np.sin(np.pi * s * (d % 3 + 1)) ** 2 for d in range(dims)]
    )
    return times, positions


def case_population(repeats: int, rng: np.random.Generator) -> dict:
    times, positions = demonstration(500)
    ours = DMP(7, dt=0.001).imitate(times, positions)
    theirs = peer.DMPWithFinalVelocity(7, execution_time=times[-1], dt=0.001, n_weights_per_dim=10)
    theirs.imitate(times, positions)
    thetas = ours.get_params() + rng.normal(size=(64, ours.n_params))
    raw = [DMP(7, dt=0.001).configure(start=ours.start).set_params(theta) for theta in thetas]

    def run_theirs():
        for candidate in raw:
            theirs.forcing_term.weights_[:] = candidate.weights
            theirs.configure(goal_y=candidate.goal, goal_yd=candidate.goal_velocity)
            theirs.open_loop()

    _, their_time = median_seconds(run_theirs, max(1, repeats // 3))
    cold, our_time = median_seconds(lambda: ours.trajectories(thetas), repeats)
    return {
        "name": "(a) 64 candidates x 7 DOF x 500 steps",
        "ours_s": our_time,
        "ours_cold_s": cold,
        "theirs_s": their_time,
    }


def case_single(repeats: int) -> dict:
    times, positions = demonstration(1000)
    ours = DMP(7, dt=0.001).imitate(times, positions)
    theirs = peer.DMPWithFinalVelocity(7, execution_time=times[-1], dt=0.001, n_weights_per_dim=10)
    theirs.imitate(times, positions)
    _, their_time = median_seconds(theirs.open_loop, repeats)
    cold, our_time = median_seconds(ours.trajectory, repeats)
    return {
        "name": "(b) one 7-DOF trajectory, 1000 steps",
        "ours_s": our_time,
        "ours_cold_s": cold,
        "theirs_s": their_time,
    }


def case_imitation(repeats: int) -> dict:
    times, positions = demonstration(1000)
    ours = DMP(7, dt=0.001)
    theirs = peer.DMPWithFinalVelocity(7, execution_time=times[-1], dt=0.001, n_weights_per_dim=10)
    _, their_time = median_seconds(lambda: theirs.imitate(times, positions), repeats)
    cold, our_time = median_seconds(lambda: ours.imitate(times, positions), repeats)
    return {
        "name": "(c) imitate one 7-DOF demonstration, 1000 steps",
        "ours_s": our_time,
        "ours_cold_s": cold,
        "theirs_s": their_time,
    }


def case_cartesian(repeats: int) -> dict:
    times, positions = demonstration(1000, dims=6)
    orientations = quat.from_rotation_vector(positions[:, 3:])
    ours = CartesianDMP(dt=0.001).imitate(times, positions[:, :3], orientations)
    theirs = peer.CartesianDMP(execution_time=times[-1], dt=0.001, n_weights_per_dim=10)
    theirs.imitate(times, np.hstack([positions[:, :3], orientations]))
    _, their_time = median_seconds(theirs.open_loop, max(1, repeats // 2))
    cold, our_time = median_seconds(ours.trajectory, repeats)
    return {
        "name": "(d) one Cartesian trajectory, 1000 steps",
        "ours_s": our_time,
        "ours_cold_s": cold,
        "theirs_s": their_time,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    results = [
        case_population(args.repeats, rng),
        case_single(args.repeats),
        case_imitation(args.repeats),
        case_cartesian(args.repeats),
    ]
    for key, result in zip(TARGETS, results, strict=True):
        result["ratio"] = result["theirs_s"] / result["ours_s"]
        result["target"] = TARGETS[key]
        result["met"] = result["ratio"] >= TARGETS[key]
    if args.json:
        print(
            json.dumps(
                {"benchmark": "dmp", "peer": "movement-primitives (compiled)", "cases": results}, indent=2
            )
        )
        return
    table = Table(title="DMPs: besman vs movement-primitives (theirs / ours)")
    for column in ("case", "ours", "ours, cold", "theirs", "ratio", "target"):
        table.add_column(column, justify="left" if column == "case" else "right")
    for result in results:
        table.add_row(
            result["name"],
            f"{1e3 * result['ours_s']:.3f} ms",
            f"{1e3 * result['ours_cold_s']:.3f} ms",
            f"{1e3 * result['theirs_s']:.2f} ms",
            f"[{'green' if result['met'] else 'red'}]{result['ratio']:.1f}x",
            f">= {result['target']:g}x",
        )
    Console().print(table)


if __name__ == "__main__":
    main()
