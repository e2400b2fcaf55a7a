"""Demonstrations: loading Qualisys TSV, CSV and NPZ recordings, smoothing and gaps."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from besman.learning.segmentation.demonstration import Demonstration, DemonstrationError, load
from besman.learning.segmentation.preprocessing import SmoothingConfig, hand_pose, resample, smooth
from besman.skills.transformation import minimum_jerk

HEADER = "NO_OF_FRAMES\t4\nFREQUENCY\t60\nMARKER_NAMES\tHand\nFrame\tTime\tHand X\tHand Y\tHand Z\t\n"


def test_a_qualisys_recording_loads_without_a_list_of_columns(shared_recordings):
    demo = load(shared_recordings / "subject1_run1.tsv")
    assert len(demo.channels) == 13 and "Hand top" in demo.channels
    assert demo.frames[0] == 690 and demo.times[0] == pytest.approx(11.48333)
    assert demo.rate == pytest.approx(60.0, rel=1e-3)
    np.testing.assert_allclose(demo.channel("Hand top")[0], [0.373477, 0.249861, -0.421439])  # mm -> m
    assert {s.label for s in demo.segments} >= {"approach_forward", "move_to_rest_down"}


def write(tmp_path, text, name="rec.tsv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_null_cells_are_gaps(tmp_path):
    rows = "".join(
        f"{10 + i}\t{0.1 * i:.1f}\t" + ("null\tnull\tnull" if i == 2 else f"{i}\t0\t0") + "\n"
        for i in range(5)
    )
    demo = load(write(tmp_path, HEADER + rows))
    assert np.isnan(demo.channel("Hand")[2]).all()
    assert demo.gaps("Hand") == [(12, 12)]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (HEADER + "1\t0.0\t1\t2\t3\n2\t0.1\t1\t2\n", r"rec.tsv:6: 4 values for 5 columns \(truncated"),
        ("NO_OF_FRAMES\t2\nHand X\tHand Y\tHand Z\n1\t2\t3\n", "no column header line starting with 'Frame'"),
        (
            HEADER + "1\t0.0\t1\t2\t3\n2\t0.1\tabc\t2\t3\n",
            r"rec.tsv:6: column 'Hand X' holds 'abc', not a number",
        ),
        (
            HEADER + "1\t0.0\tnull\tnull\tnull\n2\t0.1\tnull\tnull\tnull\n",
            "marker 'Hand' has no valid sample",
        ),
        (HEADER, "fewer than 2 rows"),
    ],
)
def test_bad_recordings_name_the_file_and_the_problem(tmp_path, text, message):
    with pytest.raises(DemonstrationError, match=message):
        load(write(tmp_path, text))


def test_unknown_marker_lists_the_markers(tmp_path):
    demo = load(write(tmp_path, HEADER + "1\t0.0\t1\t2\t3\n2\t0.1\t1\t2\t3\n"))
    with pytest.raises(DemonstrationError, match="no marker 'Wrist'; markers: Hand"):
        demo.channel("Wrist")


def test_csv_and_npz_round_trip(tmp_path):
    path = write(tmp_path, "time,hand_x,hand_y,hand_z\n0,1,2,3\n0.5,4,5,6\n1.0,7,8,9\n", "rec.csv")
    demo = load(path, units="mm")
    np.testing.assert_allclose(demo.channel("hand")[1], [0.004, 0.005, 0.006])
    again = load(demo.save(tmp_path / "rec.npz"))
    np.testing.assert_array_equal(again.channel("hand"), demo.channel("hand"))
    np.testing.assert_array_equal(again.times, demo.times)
    with pytest.raises(DemonstrationError, match="no time column 'time'"):
        load(write(tmp_path, "t,hand_x\n0,1\n1,2\n", "bad.csv"))
    with pytest.raises(DemonstrationError, match=r"unknown format '\.bvh'"):
        load(tmp_path / "x.bvh")


def test_smoothing_reduces_noise_and_estimates_velocity():
    rng = np.random.default_rng(0)
    times = np.arange(0, 3, 0.01)
    s = np.clip(times / 2, 0, 1)
    truth = np.column_stack([0.5 * minimum_jerk(s), 0.2 * np.sin(np.pi * s), 0 * s])
    noisy = truth + rng.normal(0, 0.05, truth.shape)
    demo = Demonstration(times, np.arange(len(times)), {"m": noisy})
    smoothed = smooth(demo, "m", SmoothingConfig(measurement_noise=0.05))
    raw_error = np.sqrt(np.mean((noisy - truth) ** 2))
    assert np.sqrt(np.mean((smoothed.positions - truth) ** 2)) < 0.35 * raw_error
    velocity = np.gradient(truth, times, axis=0)
    naive = np.sqrt(np.mean((np.gradient(noisy, times, axis=0) - velocity) ** 2))
    assert np.sqrt(np.mean((smoothed.velocities - velocity) ** 2)) < 0.05 * naive


def test_short_gaps_are_bridged_and_long_gaps_are_refused():
    times = np.arange(0, 2, 0.01)
    positions = np.column_stack([times, 0 * times, 0 * times])
    short = positions.copy()
    short[50:60] = np.nan  # 0.1 s
    demo = Demonstration(times, np.arange(100, 300), {"m": short})
    bridged = smooth(demo, "m").positions
    np.testing.assert_allclose(bridged[50:60, 0], times[50:60], atol=2e-3)
    long = positions.copy()
    long[50:100] = np.nan  # 0.5 s
    with pytest.raises(DemonstrationError, match=r"marker 'm' is missing for 0\.50 s \(frames 150-199\)"):
        smooth(Demonstration(times, np.arange(100, 300), {"m": long}), "m")


def test_resampling():
    times = np.linspace(0, 1, 61)
    new_times, values = resample(times, np.column_stack([times, 2 * times]), 20.0)
    assert len(new_times) == 21
    np.testing.assert_allclose(values[:, 1], 2 * new_times)


def _hand(rotation: np.ndarray, offset: np.ndarray) -> tuple[Demonstration, dict[str, np.ndarray]]:
    """Three still hand markers, rotated and shifted as a rigid body."""
    markers = {
        "Hand top": np.array([0.0, 0.0, 0.05]),
        "Hand left": np.array([0.0, 0.04, 0.0]),
        "Hand right": np.array([0.0, -0.04, 0.0]),
    }
    placed = {name: rotation @ point + offset for name, point in markers.items()}
    times = np.linspace(0, 1, 61)
    return Demonstration(times, np.arange(61), {n: np.tile(p, (61, 1)) for n, p in placed.items()}), placed


def test_hand_pose_is_the_markers_frame():
    """y from the right marker to the left, z the plane's normal (top - right) x y, x = y x z: for the
    markers as given that frame is a -90 deg turn about y; turning the markers by any R turns it by R."""
    demo, placed = _hand(np.eye(3), np.zeros(3))
    position, quaternion = hand_pose(demo)
    np.testing.assert_allclose(position[0], sum(placed.values()) / 3, atol=1e-6)
    base = Rotation.from_rotvec([0.0, -np.pi / 2, 0.0])
    np.testing.assert_allclose(_matrices(quaternion), np.tile(base.as_matrix(), (61, 1, 1)), atol=1e-6)
    turn = Rotation.from_rotvec([0.3, -1.1, 0.7])
    demo, placed = _hand(turn.as_matrix(), np.array([0.4, -0.2, 1.0]))
    position, quaternion = hand_pose(demo)
    np.testing.assert_allclose(position[0], sum(placed.values()) / 3, atol=1e-6)
    np.testing.assert_allclose(_matrices(quaternion)[0], (turn * base).as_matrix(), atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(quaternion, axis=1), 1.0)


def _matrices(quaternions: np.ndarray) -> np.ndarray:
    return Rotation.from_quat(quaternions[:, [1, 2, 3, 0]]).as_matrix()  # scipy's order is (x, y, z, w)
