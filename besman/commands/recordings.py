"""`besman segment` and `besman recordings`: human recordings inspected and cut into labelled segments."""

from __future__ import annotations

import argparse
import json

from besman.commands.options import integer
from besman.core.errors import InputError


def _segment(args: argparse.Namespace) -> int:
    from besman.core.storage import check_output
    from besman.learning import load
    from besman.learning.segmentation.contact import ContactMarkers
    from besman.learning.segmentation.segmenter import segment

    if args.example_labels and not args.examples:
        raise InputError("--example-labels chooses among the segments of --examples; give --examples too")
    if args.plot:
        check_output(
            args.plot, option="--plot", suffixes=(".png",), inputs=(args.file, *(args.examples or ()))
        )
    demo = load(args.file)
    from tqdm import tqdm

    from besman.learning.segmentation.segmenter import EXACT_UP_TO

    samples = int(demo.duration * 20.0)  # at segment()'s signal rate; pruned inference reports progress
    with tqdm(
        total=samples, desc="segmenting", unit="sample", leave=False, disable=samples <= EXACT_UP_TO
    ) as bar:
        segmentation = segment(
            demo,
            marker=args.marker,
            contact=None if args.hand_only else ContactMarkers(object=args.object),
            max_particles=None if args.exact else (args.max_particles or "auto"),
            progress=bar.update,
        )
    labels = _few_shot_labels(args, demo, segmentation) if args.examples else [None] * len(segmentation)
    frames = [int(frame) for frame in segmentation.frames]
    times = [float(time) for time in segmentation.times]
    result = {
        "segments": [
            {
                "start_frame": frames[k],
                "end_frame": frames[k + 1],
                "start_time": times[k],
                "end_time": times[k + 1],
                "label": labels[k],
                "model": segmentation.models[k],
            }
            for k in range(len(segmentation))
        ],
        "boundaries_frame": frames,
        "signals": list(segmentation.signals),
        "notes": list(segmentation.notes),
        "prior": {
            "expected_length_s": segmentation.prior.expected_length,
            "hold_weight": segmentation.prior.hold_weight,
            "chosen_by": "marginal likelihood",
        },
        "log_evidence": segmentation.log_evidence,
    }
    if args.plot:
        from besman.learning.segmentation.plot import plot_segmentation

        plot_segmentation(demo, segmentation, args.plot)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for note in segmentation.notes:
            print(f"note: {note}")
        for k, entry in enumerate(result["segments"]):
            print(
                f"{k:2d}  frames {entry['start_frame']}-{entry['end_frame']}  "
                f"{entry['start_time']:.2f}-{entry['end_time']:.2f} s  {entry['model']}"
                + (f"  {entry['label']}" if entry["label"] else "")
            )
    return 0


def _few_shot_labels(args: argparse.Namespace, demo, segmentation) -> list[str | None]:
    """Labels of the movements found: those of the nearest annotated segments of the example recordings
    (holds stay unlabelled)."""
    from besman.learning import DemonstrationError, load
    from besman.learning.segmentation.labelling import ground_truth_segments, label_few_shot, segments_of

    wanted = args.example_labels.split(",") if args.example_labels else None
    examples = []
    for path in args.examples:
        annotated = ground_truth_segments(load(path), wanted)
        if not annotated:
            raise DemonstrationError(
                f"{path}: no annotated segments{' with labels ' + args.example_labels if wanted else ''} "
                "(expected a *_manually_segmented.json beside it)"
            )
        examples += annotated
    found = segments_of(demo, segmentation)
    moving = [k for k, hold in enumerate(segmentation.holds) if not hold]
    labels: list[str | None] = [None] * len(found)
    if not moving:
        return labels
    for k, label in zip(
        moving, label_few_shot(examples, [found[k] for k in moving], marker=args.marker), strict=True
    ):
        labels[k] = label
    return labels


def _recordings_show(args: argparse.Namespace) -> int:
    from besman.learning import load

    demo = load(args.file)
    summary = {
        "file": str(args.file),
        "duration_s": demo.duration,
        "rate_hz": demo.rate,
        "samples": len(demo.times),
        "frames": [int(demo.frames[0]), int(demo.frames[-1])],
        "units": demo.units,
        "markers": {name: {"gaps": demo.gaps(name)} for name in demo.channels},
        "ground_truth_segments": len(demo.segments),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"{summary['file']}: {demo.duration:.2f} s at {demo.rate:.1f} Hz, {len(demo.times)} samples "
        f"(frames {demo.frames[0]}-{demo.frames[-1]}), {len(demo.segments)} ground-truth segments"
    )
    for name in demo.channels:
        gaps = demo.gaps(name)
        missing = sum(last - first + 1 for first, last in gaps)
        detail = ", ".join(f"{first}-{last}" for first, last in gaps[:5]) + (" ..." if len(gaps) > 5 else "")
        print(f"  {name}: {len(gaps)} gaps, {missing} frames missing" + (f" ({detail})" if gaps else ""))
    return 0


def register(commands) -> None:
    """Adds this module's commands to the parser's subcommands."""
    segment = commands.add_parser(
        "segment", help="cut a recording into segments (hand velocity and grip, Bayesian)"
    )
    segment.add_argument("file", help="a recording (.tsv Qualisys export, .csv, .npz)")
    segment.add_argument("--marker", default="Hand top", help="the marker to segment (default: Hand top)")
    segment.add_argument("--json", action="store_true", help="print the segments as JSON")
    contact = segment.add_mutually_exclusive_group()
    contact.add_argument(
        "--object", metavar="MARKER", help="observe this marker on the object too (e.g. 'Box back')"
    )
    contact.add_argument(
        "--hand-only", action="store_true", help="observe the hand alone (not the grip aperture)"
    )
    inference = segment.add_mutually_exclusive_group()
    inference.add_argument(
        "--exact",
        action="store_true",
        help="exact inference at any length (O(T^2) memory; default up to 60 s)",
    )
    inference.add_argument(
        "--max-particles",
        type=integer(2),
        metavar="N",
        help="pruned inference with N candidate change points (default beyond 60 s: 50)",
    )
    segment.add_argument("--plot", metavar="PNG", help="write the speed with the boundaries to this file")
    segment.add_argument(
        "--examples",
        nargs="+",
        metavar="FILE",
        help="annotated recordings whose segments label the movements found (few-shot, nearest neighbour)",
    )
    segment.add_argument(
        "--example-labels", metavar="L1,L2", help="use only the examples' segments with these labels"
    )
    segment.set_defaults(handler=_segment)

    recordings = commands.add_parser(
        "recordings", help="inspect recordings of people (formerly besman demos)"
    )
    actions = recordings.add_subparsers(dest="recordings_command", metavar="ACTION", required=True)
    show = actions.add_parser("show", help="duration, rate, markers and gaps of a recording")
    show.add_argument("file")
    show.add_argument("--json", action="store_true")
    show.set_defaults(handler=_recordings_show)
