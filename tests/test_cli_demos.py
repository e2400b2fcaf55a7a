"""The command line for recordings: `besman recordings show` and `besman segment`."""

import json

import numpy as np
import pytest
from helpers import run_cli
from PIL import Image

from besman.skills.transformation import minimum_jerk


def recording(tmp_path, seed=0, rate=60.0, gap=None, name="reach", reach=(0.3, -0.2, 0.1)):
    """A Qualisys-style TSV of one hand marker: hold, minimum-jerk reach, hold; frames start at 500."""
    rng = np.random.default_rng(seed)
    s = np.arange(60) / 60
    path = np.r_[np.zeros(60), minimum_jerk(s), np.ones(60)]
    positions = 1000 * (np.outer(path, reach) + rng.normal(0, 0.001, (len(path), 3)))
    header = [
        "NO_OF_FRAMES\t180",
        f"FREQUENCY\t{rate:g}",
        "MARKER_NAMES\tHand top\t",
        "Frame\tTime\tHand top X\tHand top Y\tHand top Z\t",
    ]
    rows = []
    for i, row in enumerate(positions):
        cells = ["null"] * 3 if gap and gap[0] <= i < gap[1] else [f"{v:.3f}" for v in row]
        rows.append("\t".join([str(500 + i), f"{(500 + i) / rate:.5f}", *cells]) + "\t")
    file = tmp_path / f"{name}.tsv"
    file.write_text("\n".join(header + rows) + "\n")
    return file


def test_demos_show_summarises_a_recording(capsys, tmp_path):
    file = recording(tmp_path, gap=(70, 75))
    code, out, _ = run_cli(capsys, "recordings", "show", str(file), "--json")
    summary = json.loads(out)
    assert code == 0 and summary["samples"] == 180 and summary["rate_hz"] == pytest.approx(60.0, rel=1e-3)
    assert summary["frames"] == [500, 679] and summary["markers"]["Hand top"]["gaps"] == [[570, 574]]
    code, out, _ = run_cli(capsys, "recordings", "show", str(file))
    assert code == 0 and "Hand top: 1 gaps, 5 frames missing (570-574)" in out


def test_segment_prints_json_in_the_files_frames_and_writes_a_plot(capsys, tmp_path):
    file = recording(tmp_path)
    code, out, _ = run_cli(capsys, "segment", str(file), "--json", "--plot", str(tmp_path / "seg.png"))
    result = json.loads(out)
    assert code == 0
    assert result["boundaries_frame"][0] == 500 and result["boundaries_frame"][-1] == 679
    # The reach spans frames 560-620; it reaches 10 % of its peak speed 5 frames after its start.
    np.testing.assert_allclose(result["boundaries_frame"], [500, 565, 615, 679], atol=2)
    first, last = result["segments"][0], result["segments"][-1]
    assert first["start_time"] == 8.33333 and first["label"] is None and last["end_frame"] == 679
    assert [s["end_frame"] for s in result["segments"][:-1]] == [
        s["start_frame"] for s in result["segments"][1:]
    ]
    assert Image.open(tmp_path / "seg.png").size[0] > 500


def test_segment_errors_name_the_file_and_the_problem(capsys, tmp_path):
    file = recording(tmp_path)
    code, _, err = run_cli(capsys, "segment", str(file), "--marker", "Wrist")
    assert code == 2 and str(file) in err and "no marker 'Wrist'" in err
    code, _, err = run_cli(capsys, "segment", str(tmp_path / "missing.tsv"))
    assert code == 2 and "missing.tsv" in err


def test_segment_labels_the_movements_like_the_nearest_annotated_example(capsys, tmp_path):
    example = recording(tmp_path, seed=1, name="example")
    annotation = [{"start index": 560, "end index": 620, "label": "reach"}]
    (tmp_path / "example_manually_segmented.json").write_text(json.dumps(annotation))
    file = recording(tmp_path, seed=2)
    code, out, _ = run_cli(capsys, "segment", str(file), "--json", "--examples", str(example))
    segments = json.loads(out)["segments"]
    assert code == 0 and [s["label"] for s in segments] == [None, "reach", None]
    assert [s["model"] for s in segments][0::2] == ["still", "still"]
    code, out, _ = run_cli(capsys, "segment", str(file), "--examples", str(example))
    lines = out.splitlines()  # a note first: the recording has no finger markers, the hand alone segments it
    assert code == 0 and lines[0].startswith("note: no 'Thumb' marker") and lines[2].endswith("reach")
    code, _, err = run_cli(capsys, "segment", str(file), "--examples", str(file))
    assert code != 0 and f"{file}: no annotated segments" in err
    still = recording(tmp_path, seed=3, name="still", reach=(0.0, 0.0, 0.0))
    code, out, _ = run_cli(capsys, "segment", str(still), "--json", "--examples", str(example))
    assert code == 0 and {s["label"] for s in json.loads(out)["segments"]} == {None}
