"""The first stages of :func:`~besman.learning.pipeline.end_to_end.learn`: the recordings loaded and checked,
each one segmented (``work/segments/``), and the movements labelled as the task's building blocks
(``work/labels.json``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.core.storage import read_json
from besman.learning.pipeline.imitation import HAND_MARKERS
from besman.learning.pipeline.record import (
    SCHEMA_VERSION,
    LearnError,
    LearnSettings,
    progress_bar,
    write_json,
)
from besman.learning.segmentation.demonstration import Demonstration, DemonstrationError, load
from besman.learning.segmentation.labelling import (
    DemonstrationSegment,
    cluster,
    ground_truth_segments,
    label_few_shot,
)
from besman.learning.segmentation.segmenter import segment

SUFFIXES = (".tsv", ".csv", ".npz")


def recordings(folder: str | Path) -> list[Path]:
    """The recordings in ``folder`` (sorted), or a :class:`LearnError` saying why there are none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise LearnError(f"{folder}: no such demonstration folder")
    try:
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
    except OSError as error:
        raise LearnError(f"{folder}: cannot read the folder ({error.strerror})") from None
    if not files:
        raise LearnError(f"{folder}: no recordings ({', '.join(SUFFIXES)} files) in the folder")
    return files


def load_recording(path: Path) -> Demonstration:
    """A recording with the hand markers imitation follows, or a :class:`LearnError` naming the file."""
    try:
        demo = load(path)
    except DemonstrationError as error:
        raise LearnError(str(error)) from None
    except OSError as error:
        raise LearnError(f"{path}: cannot read the recording ({error.strerror})") from None
    missing = [name for name in HAND_MARKERS if name not in demo.channels]
    if missing:
        raise LearnError(
            f"{path}: no hand markers {', '.join(missing)} (has: {', '.join(sorted(demo.channels))}); "
            "learning follows the hand"
        )
    return demo


def load_examples(paths: tuple[str, ...], role_labels: dict[str, str]) -> list[Demonstration]:
    """The annotated example recordings, each with its annotation, whose labels include every role's."""
    examples = [load_recording(Path(path)) for path in paths]
    for path, demo in zip(paths, examples, strict=True):
        if not demo.segments:
            raise LearnError(f"{path}: an example needs its annotation (<stem>_manually_segmented.json)")
    annotated = {segment.label for demo in examples for segment in demo.segments}
    for block, label in role_labels.items() if examples else ():
        if label not in annotated:
            raise LearnError(
                f"roles: {block}={label!r} is not a label of the examples (they have: "
                f"{', '.join(sorted(annotated))})"
            )
    return examples


def segment_recordings(
    files: list[Path], demos: list[Demonstration], checksums: list[str], folder: Path, shown: bool
) -> list[list[DemonstrationSegment]]:
    """The movement segments of each recording (cached per recording in ``folder``)."""
    folder.mkdir(exist_ok=True)
    found = []
    with progress_bar(len(demos), "segmenting", "recording", shown) as bar:
        for path, demo, digest in zip(files, demos, checksums, strict=True):
            cache = folder / f"{path.stem}.json"
            document = read_json(cache, LearnError) if cache.is_file() else None
            if document is None or document.get("sha256") != digest:
                result = segment(demo)
                document = {
                    "schema_version": SCHEMA_VERSION,
                    "file": path.name,
                    "sha256": digest,
                    "boundaries": result.boundaries.tolist(),
                    "holds": list(result.holds),
                    "models": list(result.models),
                    "signals": list(result.signals),
                    "notes": list(result.notes),
                }
                write_json(cache, document)
            bounds, holds = document["boundaries"], document["holds"]
            movements = [
                DemonstrationSegment(demo, bounds[k], bounds[k + 1])
                for k in range(len(holds))
                if not holds[k]
            ]
            if not movements:
                raise LearnError(f"{path}: the segmentation finds no movement in the recording")
            found.append(movements)
            bar.update()
    return found


def label_blocks(
    movements: list[list[DemonstrationSegment]],
    files: list[Path],
    checksums: list[str],
    examples: list[Demonstration],
    settings: LearnSettings,
    role_labels: dict[str, str],
    cache: Path,
    held: list[np.ndarray] | None = None,
) -> dict[str, list[dict]]:
    """Each block's instances: per recording, the longest run of consecutive segments with the label that
    plays the block (``role_labels``); labelled like the ``examples``, by the gripper's events (``held``,
    per recording and sample: a robot's recordings; :func:`gripper_labels`) or clustered. Cached in
    ``cache``."""
    if cache.is_file():
        return read_json(cache, LearnError)["blocks"]
    flat = [s for per_demo in movements for s in per_demo]
    if held is not None and not examples:
        names = [
            name
            for per_demo, mask in zip(movements, held, strict=True)
            for name in gripper_labels(per_demo, mask)
        ]
        method = "gripper events: the largest movement before the grasp, while holding and after the release"
    elif examples:
        annotated = [s for demo in examples for s in ground_truth_segments(demo)]
        annotated = [s for s in annotated if not s.label.endswith("_part") and s.label != "idle"]
        names = label_few_shot(annotated, flat)
        method = "few-shot (1-NN) from " + ", ".join(Path(p).name for p in settings.examples)
    else:
        if len(flat) < settings.n_blocks:
            raise LearnError(
                f"the recordings hold {len(flat)} movements, fewer than the {settings.n_blocks} "
                "building blocks to cluster them into"
            )
        clusters = cluster(flat, settings.n_blocks)
        phases = {
            c: np.median([_phase(s) for s, k in zip(flat, clusters, strict=True) if k == c])
            for c in set(clusters)
        }
        order = sorted(phases, key=phases.get)
        names = [f"block{order.index(c) + 1}" for c in clusters]
        method = f"clustering (Ward) into {settings.n_blocks}, named in the order of the task"
    labelled, position = [], 0
    for per_demo in movements:
        labelled.append(names[position : position + len(per_demo)])
        position += len(per_demo)
    instances = {}
    for block, label in role_labels.items():
        found = []
        for path, digest, per_demo, per_names in zip(files, checksums, movements, labelled, strict=True):
            run = longest_run(per_demo, per_names, label)
            if run is not None:
                first, last = run
                demo = per_demo[first].demo
                found.append(
                    {
                        "file": path.name,
                        "sha256": digest,
                        "segments": list(range(first, last + 1)),
                        "start": per_demo[first].start,
                        "end": per_demo[last].end,
                        "start_frame": int(demo.frames[per_demo[first].start]),
                        "end_frame": int(demo.frames[per_demo[last].end]),
                    }
                )
        if not found:
            raise LearnError(
                f"no movement was labelled {label!r} (the {block} block); labels found: "
                f"{', '.join(sorted(set(names)))}"
            )
        instances[block] = found
    write_json(cache, {"schema_version": SCHEMA_VERSION, "method": method, "blocks": instances})
    return instances


GRIPPER_LABELS = ("before", "holding", "after")
SHORTEST_HOLD = 0.5  # s: the gripper closed for less is closing or opening, not holding


def gripper_labels(movements: list[DemonstrationSegment], held: np.ndarray) -> list[str]:
    """A robot recording's movements labelled by its gripper's events: of the last hold (the grasp that was
    carried: earlier ones failed and were retried), the free movement before it that moves the hand
    furthest ("before"), the held one ("holding") and the free one after the release ("after"); the others
    "other"."""
    demo = movements[0].demo
    edges = np.flatnonzero(np.diff(np.r_[0, held.astype(int), 0]))
    holds = [
        (int(a), int(b) - 1)
        for a, b in zip(edges[::2], edges[1::2], strict=True)
        if demo.times[b - 1] - demo.times[a] >= SHORTEST_HOLD
    ]
    names = ["other"] * len(movements)
    if not holds:
        return names
    close, release = holds[-1]
    previous = holds[-2][1] if len(holds) > 1 else 0
    hand = demo.channels[HAND_MARKERS[0]]

    def moved(k: int) -> float:
        return float(np.linalg.norm(hand[movements[k].end] - hand[movements[k].start]))

    def holding(segment) -> bool:
        return bool(np.median(held[segment.start : segment.end + 1]))

    slack = round(0.1 * demo.rate)  # a segment may end a few samples past the gripper's event
    phases = {
        "before": [
            k
            for k, s in enumerate(movements)
            if previous <= s.start and s.end <= close + slack and not holding(s)
        ],
        "holding": [
            k for k, s in enumerate(movements) if close <= s.start and s.end <= release + slack and holding(s)
        ],
        "after": [k for k, s in enumerate(movements) if s.start >= release - slack and not holding(s)],
    }
    for label, candidates in phases.items():
        if candidates:
            names[max(candidates, key=moved)] = label
    return names


def longest_run(segments: list[DemonstrationSegment], names: list[str], label: str) -> tuple[int, int] | None:
    """First and last index of the longest (in samples) run of adjacent segments (sharing a boundary, no
    pause between them) named ``label``; None if no segment is."""
    best, first = None, None
    for k, name in enumerate(names):
        if name != label:
            first = None
            continue
        if first is None or segments[k - 1].end != segments[k].start:
            first = k
        if (
            best is None
            or segments[k].end - segments[first].start > segments[best[1]].end - segments[best[0]].start
        ):
            best = (first, k)
    return best


def _phase(segment: DemonstrationSegment) -> float:
    """Where in its recording a segment lies: its middle, as a fraction of the recording's time."""
    times = segment.demo.times
    return float(((times[segment.start] + times[segment.end]) / 2 - times[0]) / (times[-1] - times[0]))
