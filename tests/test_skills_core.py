"""What the DMP kinds share: one settings object, one ridge fit, one protocol; quaternions from matrices;
the project's error base class."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from besman.core.storage import optional_field, read_json, require_field
from besman.learning.segmentation.demonstration import DemonstrationError, Segment, load
from besman.robots import DescriptionError
from besman.sim.manipulation import PlanningError
from besman.skills import DMP, BesmanError, CartesianDMP, DMPSettings, InputError, Primitive
from besman.skills.dmp_core import fit_weights
from besman.skills.quaternion import from_matrix
from besman.skills.transformation import minimum_jerk
from besman.trees import TreeFileError


@pytest.mark.parametrize("make", [lambda s: DMP(4, settings=s), lambda s: CartesianDMP(settings=s)])
def test_every_primitive_kind_satisfies_the_protocol(make):
    settings = DMPSettings(n_weights=6)
    dmp = make(settings)
    assert isinstance(dmp, Primitive)
    assert dmp.settings is settings and dmp.n_weights == 6
    theta = dmp.get_params() + 0.1
    assert dmp.set_params(theta) is dmp
    np.testing.assert_allclose(dmp.get_params(), theta)
    single = dmp.trajectory(run_time=0.5)
    np.testing.assert_array_equal(dmp.trajectory(theta).positions, dmp.trajectory().positions)
    batch = dmp.trajectories(np.stack([theta, theta]))
    assert len(single.times) == round(0.5 / dmp.dt) + 1
    np.testing.assert_array_equal(batch.positions[0], batch.positions[1])
    assert dmp.n_params == len(theta)
    dmp.execution_time = 2.0
    assert dmp.execution_time == 2.0 and dmp.trajectory().times[-1] == pytest.approx(2.0)


def test_the_ridge_fit_solves_the_regularised_normal_equations():
    rng = np.random.default_rng(0)
    features = [rng.normal(size=(40, 5)), rng.normal(size=(25, 5))]
    weights = rng.normal(size=(3, 5))
    targets = [x @ weights.T for x in features]
    np.testing.assert_allclose(fit_weights(features, targets, 0.0), weights, atol=1e-10)
    x, y = np.concatenate(features), np.concatenate(targets)
    lam = 0.5 * np.trace(x.T @ x) / 5  # regularization 0.5, scaled by the mean feature energy
    brute = np.linalg.lstsq(np.vstack([x, np.sqrt(lam) * np.eye(5)]), np.vstack([y, np.zeros((5, 3))]))[0]
    np.testing.assert_allclose(fit_weights(features, targets, 0.5), brute.T, atol=1e-10)


def test_both_kinds_fit_their_forcing_weights_the_same_way():
    """A Cartesian DMP's position part is a 3-D DMP: imitating the same demonstration gives the same theta."""
    times = np.linspace(0.0, 1.0, 201)
    positions = np.column_stack([minimum_jerk(times), np.sin(np.pi * times) * 0.2, 0.1 * times])
    orientations = np.tile([1.0, 0.0, 0.0, 0.0], (len(times), 1))
    joint = DMP(3).imitate(times, positions)
    cartesian = CartesianDMP().imitate(times, positions, orientations)
    np.testing.assert_allclose(cartesian.position.get_params(), joint.get_params(), rtol=1e-12)


def test_settings_are_checked_with_their_names():
    with pytest.raises(BesmanError, match="n_weights must be an integer >= 2"):
        DMPSettings(n_weights=1)
    with pytest.raises(BesmanError, match="alpha_y must be a finite positive number"):
        DMPSettings(alpha_y=-1.0)
    with pytest.raises(InputError, match="settings must be a DMPSettings"):
        DMP(2, settings={"n_weights": 3})


def test_matrices_become_the_quaternions_scipy_finds():
    rotations = Rotation.random(500, random_state=3)
    expected = rotations.as_quat()[:, [3, 0, 1, 2]]  # scipy's order is (x, y, z, w)
    expected *= np.where(expected[:, :1] < 0, -1.0, 1.0)
    np.testing.assert_allclose(from_matrix(rotations.as_matrix()), expected, atol=1e-12)
    for angle in (np.pi, np.pi - 1e-9):  # half turns: w ~ 0, the largest component is x, y or z
        half_turn = Rotation.from_rotvec([0.0, angle, 0.0]).as_matrix()
        q = from_matrix(half_turn)
        np.testing.assert_allclose(Rotation.from_quat(q[[1, 2, 3, 0]]).as_matrix(), half_turn, atol=1e-12)


def test_minimum_jerk_starts_and_ends_at_rest():
    s = np.linspace(0.0, 1.0, 1001)
    profile = minimum_jerk(s)
    assert profile[0] == 0.0 and profile[-1] == 1.0 and profile[500] == pytest.approx(0.5)
    velocity = np.gradient(profile, s)
    assert abs(velocity[0]) < 1e-5 and abs(velocity[-1]) < 1e-5
    assert velocity.max() == pytest.approx(1.875, rel=1e-4)  # the textbook peak speed


def test_every_project_error_is_a_besman_error_and_a_value_error():
    for error in (
        BesmanError,
        InputError,
        DescriptionError,
        DemonstrationError,
        PlanningError,
        TreeFileError,
    ):
        assert issubclass(error, BesmanError) and issubclass(error, ValueError)
    with pytest.raises(BesmanError, match="theta contains NaN"):
        DMP(2).trajectory(np.full(24, np.nan))


def test_json_fields_are_checked_with_the_file_and_the_field_named(tmp_path):
    listing = tmp_path / "listing.json"
    listing.write_text('[{"robot": 5}]')
    [entry] = read_json(listing, top=list)
    with pytest.raises(InputError, match="expected a JSON object"):
        read_json(listing)
    with pytest.raises(InputError, match=r"listing.json\[0\].robot: expected str, got 5"):
        optional_field(entry, "robot", str, f"{listing}[0]")
    assert (
        optional_field({"robot": None}, "robot", str, "x") is None
        and optional_field({}, "robot", str, "x") is None
    )
    with pytest.raises(InputError, match="x: missing field 'name'"):
        require_field(entry, "name", str, "x")


def test_a_damaged_ground_truth_names_the_file_and_the_field(tmp_path):
    recording = tmp_path / "run.tsv"
    rows = "".join(f"{frame}\t{0.01 * frame:.2f}\t{frame}\t0\t0\n" for frame in range(10))
    recording.write_text("NO_OF_FRAMES\t10\nFrame\tTime\thand X\thand Y\thand Z\n" + rows)
    sidecar = tmp_path / "run_manually_segmented.json"
    sidecar.write_text('[{"start index": 2, "end index": 5, "label": "reach"}]')
    assert load(recording).segments == (Segment(2, 5, "reach"),)
    sidecar.write_text('[{"start index": 2, "end index": "5", "label": "reach"}]')
    with pytest.raises(DemonstrationError, match=r"run_manually_segmented.json\[0\].end index: expected int"):
        load(recording)
