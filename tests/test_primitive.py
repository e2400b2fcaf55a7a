"""Movement primitives: metadata, and JSON + NPZ persistence that refuses anything damaged."""

import json

import numpy as np
import pytest

from besman.skills import DMP, CartesianDMP, MovementPrimitive
from besman.skills import quaternion as quat


@pytest.fixture
def joint_primitive():
    times = np.linspace(0, 1.5, 151)
    positions = np.column_stack([np.sin(times + k) for k in range(7)])
    dmp = DMP(7, dt=0.01, scale=[0.1] * 6 + [0.2]).imitate(times, positions)
    return MovementPrimitive(
        dmp,
        "reach",
        robot="aila",
        group="right_arm",
        provenance={"demonstration": "subject1_run1.tsv", "segment": 2},
    )


def test_joint_primitive_round_trips(tmp_path, joint_primitive):
    path = joint_primitive.save(tmp_path / "reach")
    assert path.name == "reach.json"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reach.json", "reach.npz"]
    loaded = MovementPrimitive.load(path)
    assert (loaded.name, loaded.space, loaded.robot, loaded.group) == ("reach", "joint", "aila", "right_arm")
    assert loaded.provenance == joint_primitive.provenance
    np.testing.assert_array_equal(loaded.theta, joint_primitive.theta)
    np.testing.assert_array_equal(
        loaded.dmp.trajectory().positions, joint_primitive.dmp.trajectory().positions
    )
    document = json.loads(path.read_text())
    assert document["schema_version"] == 1
    assert document["dmp"]["execution_time"] == 1.5


def test_cartesian_primitive_round_trips(tmp_path):
    dmp = CartesianDMP(dt=0.02, goal_position=[0.5, 0.1, 0.9], goal_orientation=[0, 1, 0, 0])
    dmp.rotation_weights[:] = np.arange(30).reshape(3, 10)
    dmp.position.start_acceleration[:] = [0.1, 0.2, 0.3]
    primitive = MovementPrimitive(dmp, "grasp", space="cartesian", robot="aila", frame="right_grasp")
    loaded = MovementPrimitive.load(primitive.save(tmp_path / "grasp.json"))
    assert isinstance(loaded.dmp, CartesianDMP)
    np.testing.assert_array_equal(loaded.theta, primitive.theta)
    np.testing.assert_array_equal(loaded.dmp.trajectory().orientations, dmp.trajectory().orientations)
    np.testing.assert_array_equal(loaded.dmp.position.start_acceleration, [0.1, 0.2, 0.3])


def test_metadata_is_validated():
    with pytest.raises(ValueError, match="space must be one of"):
        MovementPrimitive(DMP(2), "x", space="task")
    with pytest.raises(ValueError, match="cartesian-space primitive needs a CartesianDMP"):
        MovementPrimitive(DMP(2), "x", space="cartesian")
    with pytest.raises(ValueError, match="provenance must be JSON-compatible"):
        MovementPrimitive(DMP(2), "x", provenance={"when": object()})


def edit_json(path, change):
    document = json.loads(path.read_text())
    change(document)
    path.write_text(json.dumps(document))


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda j, n: j.write_text("{broken"), "reach.json: not valid JSON"),
        (lambda j, n: n.unlink(), "reach.npz: no such file"),
        (lambda j, n: n.write_bytes(n.read_bytes()[:-20]), "checksum does not match"),
        (
            lambda j, n: edit_json(j, lambda d: d.update(schema_version=7)),
            "schema_version 7 is not supported",
        ),
        (
            lambda j, n: edit_json(j, lambda d: d["dmp"].update(execution_time=-1)),
            "execution_time must be a finite",
        ),
        (
            lambda j, n: edit_json(j, lambda d: d["dmp"].update(n_dims=3)),
            r"scale must have shape \(3,\), got \(7,\)",
        ),
        (lambda j, n: edit_json(j, lambda d: d["dmp"].update(type="GMM")), "dmp.type must be"),
        (lambda j, n: edit_json(j, lambda d: d.pop("name")), "missing field 'name'"),
        (
            lambda j, n: edit_json(j, lambda d: d["arrays"].update(file="../../etc/passwd")),
            "a file name beside",
        ),
    ],
)
def test_damaged_files_give_clear_errors(tmp_path, joint_primitive, damage, message):
    path = joint_primitive.save(tmp_path / "reach")
    damage(path, path.with_suffix(".npz"))
    with pytest.raises(ValueError, match=message) as error:
        MovementPrimitive.load(path)
    assert "reach" in str(error.value)


def test_tampered_arrays_with_a_matching_checksum_are_still_validated(tmp_path, joint_primitive):
    """Someone rewrites the NPZ with NaN weights and fixes the checksum: values are still checked."""
    from besman.core.storage import npz_bytes, sha256

    path = joint_primitive.save(tmp_path / "reach")
    with np.load(path.with_suffix(".npz")) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays["weights"][0, 0] = np.nan
    data = npz_bytes(arrays)
    path.with_suffix(".npz").write_bytes(data)
    edit_json(path, lambda d: d["arrays"].update(sha256=sha256(data)))
    with pytest.raises(ValueError, match="'weights' must hold finite floats"):
        MovementPrimitive.load(path)


def test_saving_over_an_existing_primitive_is_atomic(tmp_path, joint_primitive, monkeypatch):
    path = joint_primitive.save(tmp_path / "reach")
    before = path.read_bytes()
    import besman.core.storage as storage

    def failing_replace(source, target):
        raise OSError("disk full")

    monkeypatch.setattr(storage.os, "replace", failing_replace)
    with pytest.raises(storage.WriteError, match=r"reach\.npz: cannot write it \(disk full\)"):
        joint_primitive.save(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reach.json", "reach.npz"], (
        "no temporary files left"
    )


def test_quaternion_helpers_round_trip():
    rng = np.random.default_rng(2)
    vectors = rng.normal(size=(50, 3))
    vectors *= (np.pi * 0.99 / np.linalg.norm(vectors, axis=1))[:, None] * rng.uniform(0, 1, size=(50, 1))
    np.testing.assert_allclose(quat.rotation_vector(quat.from_rotation_vector(vectors)), vectors, atol=1e-12)
    np.testing.assert_allclose(quat.rotation_vector(np.array([1.0, 0, 0, 0])), 0.0)
