"""Segmentation of the shared human recordings, side by side: ours, ruptures and speed minima, in one run.

    python benchmarks/segmentation.py [--json] [--data DIR] [--cost linear|ar]

Every method segments the Kalman/RTS-smoothed "Hand top" marker, resampled at 20 Hz:
- ours: ``besman.learning.segment`` with its default hyperparameters (no tuning per file), on the hand's
  velocity; also with the candidate change points pruned to 50 (stratified optimal resampling);
- ruptures Pelt and Dynp with a ``linear`` cost (speed regressed on 1, t) or an ``ar`` (order 2) cost,
  ``jump=1``; Pelt's penalty and Dynp's number of change points are chosen for each file by leave-one-out
  (best mean F1 at +-0.2 s on the other files);
- speed minima: local minima of the speed (scipy ``find_peaks`` on -speed, prominence 0.05 m/s, 0.3 s
  apart) plus the recording's first and last sample.
The truth is the start and end frames of the six main segments of each run. Scores: mean boundary F1 at
+-0.1 and +-0.2 s (one-to-one matching of file frames; a hit is strictly closer than the margin: 6 and 12
frames at 60 Hz), mean Hausdorff distance (s), seconds per recording. Then exact and pruned inference on one
long recording (the first eight runs one after the other, about 2 minutes): seconds and their agreement.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import ruptures
from rich.console import Console
from rich.progress import track
from rich.table import Table
from scipy.signal import find_peaks

from besman.learning import Demonstration, load, resample, segment, smooth
from besman.learning.demonstration import PICK_AND_PLACE_MAIN_SEGMENTS
from besman.learning.segmentation import boundary_f1

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "dfki_pick_and_place"
RATE = 20.0
PENALTIES = np.logspace(-3, 0, 13)
CHANGE_POINT_COUNTS = range(6, 17)
PARTICLES = 50
LONG_RUNS = 8


def hausdorff(truth: np.ndarray, predicted: np.ndarray) -> float:
    distances = np.abs(truth[:, None] - predicted[None, :])
    return float(max(distances.min(axis=1).max(), distances.min(axis=0).max()))


def scores(demo: Demonstration, truth: np.ndarray, predicted_times: np.ndarray) -> dict[str, float]:
    """F1 and Hausdorff of predicted times against the true frames, in the file's frames."""
    predicted = demo.frames[demo.nearest_indices(predicted_times)]
    return {
        "f1_0.1": boundary_f1(truth, predicted, 0.1 * demo.rate),
        "f1_0.2": boundary_f1(truth, predicted, 0.2 * demo.rate),
        "hausdorff_s": hausdorff(truth, predicted) / demo.rate,
    }


def one_after_another(demos: list[Demonstration]) -> Demonstration:
    """The recordings' "Hand top" as one long demonstration."""
    times, start = [], 0.0
    for demo in demos:
        times.append(demo.times - demo.times[0] + start)
        start = times[-1][-1] + 1.0 / demo.rate
    joined = np.concatenate(times)
    hand = np.concatenate([demo.channel("Hand top") for demo in demos])
    return Demonstration(times=joined, frames=np.arange(len(joined)), channels={"Hand top": hand})


def long_recording(demos: list[Demonstration]) -> dict[str, float]:
    demo = one_after_another(demos)
    start = time.perf_counter()
    exact = segment(demo)
    exact_seconds = time.perf_counter() - start
    start = time.perf_counter()
    pruned = segment(demo, max_particles=PARTICLES)
    pruned_seconds = time.perf_counter() - start
    return {
        "duration_s": demo.duration,
        "exact_seconds": exact_seconds,
        "pruned_seconds": pruned_seconds,
        "exact_over_pruned_seconds": exact_seconds / pruned_seconds,
        "pruned_vs_exact_f1_0.1": boundary_f1(exact.frames, pruned.frames, 0.1 * demo.rate),
    }


def ruptures_signal(speed: np.ndarray, cost: str) -> np.ndarray:
    if cost == "linear":
        return np.column_stack([speed, np.ones_like(speed), np.arange(len(speed)) / RATE])
    return speed[:, None]


def ruptures_algorithm(kind: str, cost: str, signal: np.ndarray):
    params = {"order": 2} if cost == "ar" else None
    algorithm = ruptures.Pelt if kind == "pelt" else ruptures.Dynp
    return algorithm(model=cost, jump=1, min_size=3, params=params).fit(signal)


def predict(algorithm, kind: str, setting) -> list[int]:
    if kind == "pelt":
        return algorithm.predict(pen=float(setting))
    return algorithm.predict(n_bkps=int(setting))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the shared recordings")
    parser.add_argument("--cost", choices=("linear", "ar"), default="linear", help="ruptures' cost")
    args = parser.parse_args()
    files = sorted(args.data.glob("*.tsv"))
    if len(files) < 2:
        raise SystemExit(f"{args.data}: need at least two recordings (*.tsv) for leave-one-out")

    pruned_name = f"ours (pruned, {PARTICLES} particles)"
    results: dict[str, list[dict[str, float]]] = {"ours": [], pruned_name: [], "speed minima": []}
    # Scores of every ruptures setting on every file, for the leave-one-out choice.
    candidates: dict[str, list[list[dict[str, float]]]] = {"pelt": [], "dynp": []}
    signals, demos = [], []
    for file in track(files, description="segmenting", disable=args.json, console=Console(stderr=True)):
        demo = load(file)
        demos.append(demo)
        truth = np.array(demo.boundary_frames(PICK_AND_PLACE_MAIN_SEGMENTS))
        for name, options in (("ours", {}), (pruned_name, {"max_particles": PARTICLES})):
            start = time.perf_counter()
            ours = segment(demo, **options)
            results[name].append(scores(demo, truth, ours.times) | {"seconds": time.perf_counter() - start})

        start = time.perf_counter()
        times, speed = resample(demo.times, smooth(demo, "Hand top").speed, RATE)
        minima, _ = find_peaks(-speed, prominence=0.05, distance=round(0.3 * RATE))
        predicted = times[np.r_[0, minima, len(times) - 1]]
        results["speed minima"].append(
            scores(demo, truth, predicted) | {"seconds": time.perf_counter() - start}
        )

        signal = ruptures_signal(speed, args.cost)
        edges = np.r_[times, times[-1]]
        signals.append(signal)
        for kind, settings in (("pelt", PENALTIES), ("dynp", CHANGE_POINT_COUNTS)):
            algorithm = ruptures_algorithm(kind, args.cost, signal)
            candidates[kind].append(
                [
                    scores(demo, truth, edges[np.r_[0, predict(algorithm, kind, setting)]])
                    for setting in settings
                ]
            )

    choices = {}
    for kind, per_file in candidates.items():
        name = f"ruptures {kind.capitalize()} ({args.cost})"
        results[name], choices[name] = [], []
        for k in range(len(per_file)):
            others = [per_file[j] for j in range(len(per_file)) if j != k]
            mean_f1 = [np.mean([o[i]["f1_0.2"] for o in others]) for i in range(len(others[0]))]
            best = int(np.argmax(mean_f1))
            setting = (PENALTIES if kind == "pelt" else CHANGE_POINT_COUNTS)[best]
            choices[name].append(float(setting))
            start = time.perf_counter()  # timed afresh: fit and predict with the chosen setting only
            predict(ruptures_algorithm(kind, args.cost, signals[k]), kind, setting)
            results[name].append(per_file[k][best] | {"seconds": time.perf_counter() - start})

    summary = {
        name: {key: float(np.mean([r[key] for r in rows])) for key in rows[0]}
        for name, rows in results.items()
    }
    others = {name: row for name, row in summary.items() if not name.startswith("ours")}
    report = {
        "recordings": len(files),
        "rate_hz": RATE,
        "methods": summary,
        "leave_one_out_settings": choices,
        "ours_best_f1": all(
            summary["ours"][key] >= max(row[key] for row in others.values()) for key in ("f1_0.1", "f1_0.2")
        ),
        "ours_vs_best_other_f1_0.2": summary["ours"]["f1_0.2"]
        / max(row["f1_0.2"] for row in others.values()),
        "long_recording": long_recording(demos[:LONG_RUNS]),
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    table = Table(title=f"Segmentation of {len(files)} recordings (F1: mean over recordings)")
    for column in ("method", "F1 +-0.1 s", "F1 +-0.2 s", "Hausdorff (s)", "s / recording"):
        table.add_column(column, justify="left" if column == "method" else "right")
    for name, row in summary.items():
        table.add_row(
            name,
            f"{row['f1_0.1']:.3f}",
            f"{row['f1_0.2']:.3f}",
            f"{row['hausdorff_s']:.2f}",
            f"{row['seconds']:.3f}",
        )
    console = Console()
    console.print(table)
    long = report["long_recording"]
    console.print(
        f"ours / best other F1 at +-0.2 s: {report['ours_vs_best_other_f1_0.2']:.2f}; "
        f"ours best at both margins: {report['ours_best_f1']}\n"
        f"long recording ({long['duration_s']:.0f} s): exact {long['exact_seconds']:.1f} s, pruned "
        f"{long['pruned_seconds']:.1f} s (exact / pruned = {long['exact_over_pruned_seconds']:.1f}), "
        f"pruned vs exact boundaries F1 at +-0.1 s {long['pruned_vs_exact_f1_0.1']:.2f}"
    )


if __name__ == "__main__":
    main()
