"""OpenArm v2: a model from an installed Python package, a home keyframe defined by the description, both
arms' grippers measured (the demos on it: tests/test_acceptance.py)."""

import json
import shutil

import mujoco
import numpy as np
import pytest

import besman.robots as robots
from besman.robots import packages
from besman.robots.catalogue import ROBOTS_DIR
from besman.robots.description import DescriptionError
from besman.robots.gripper import measure_openings


@pytest.fixture(scope="module")
def openarm():
    return robots.load("openarm")


def test_the_model_is_the_file_the_package_installed_found_through_its_record(openarm):
    found = packages.find("openarm-mujoco", "v2/openarm_bimanual.xml", "test.model")
    # Installed as the package's data files, outside site-packages (where its own asset_path looks for them
    # in the running interpreter's prefix only: not in a virtual environment that uses the system's).
    assert found.parts[-4:] == ("share", "openarm_mujoco", "v2", "openarm_bimanual.xml")
    assert '<mujoco model="openarm_v20">' in found.read_text()
    assert openarm.model.njnt == 18 and openarm.model.nu == 16
    assert list(openarm.arms) == ["right", "left"]


@pytest.mark.parametrize(
    ("distribution", "relative", "message"),
    [
        ("no-such-robot-package", "robot.xml", r"test\.package: 'no-such-robot-package' is not installed"),
        (
            "openarm-mujoco",
            "v2/nosuch.xml",
            r"test\.file: openarm-mujoco has no file ending in 'v2/nosuch",
        ),
        ("openarm-mujoco", "../v2/openarm_bimanual.xml", r"test\.file: .* must be a relative path"),
    ],
)
def test_a_package_file_that_is_not_there_is_named_with_the_field(distribution, relative, message):
    with pytest.raises(DescriptionError, match=message):
        packages.find(distribution, relative, "test")


def test_home_is_the_descriptions_keyframe_with_the_actuators_commanded_there(openarm):
    home = openarm.description.home
    model, key = openarm.model, openarm.model.key("home")
    for joint, position in home.items():
        assert key.qpos[model.joint(joint).qposadr[0]] == pytest.approx(position)
    for actuator in range(model.nu):  # every actuator holds its joint where home puts it
        joint = model.actuator_trnid[actuator, 0]
        assert key.ctrl[actuator] == pytest.approx(key.qpos[model.jnt_qposadr[joint]])
    data = openarm.make_data()
    for _ in range(1000):  # 2 s: the robot stays at home
        mujoco.mj_step(model, data)
    assert np.abs(data.qpos - key.qpos).max() < 0.01
    for side in ("right", "left"):  # the hands point down above the table
        site = data.site(f"{side}_tcp")
        assert site.xmat.reshape(3, 3)[:, 2] == pytest.approx([0, 0, -1], abs=0.02)
        assert 0.2 < site.xpos[2] - openarm.description.tabletop.table.height < 0.3


@pytest.mark.parametrize(
    ("home", "message"),
    [
        ({"openarm_left_joint9": 0.0}, r"home\.openarm_left_joint9: the model has no joint"),
        ({"openarm_left_joint4": 3.0}, r"home\.openarm_left_joint4: 3\.0 outside the joint's range"),
        ({"openarm_left_joint4": "up"}, r"home\.openarm_left_joint4: expected a list of finite numbers"),
    ],
)
def test_a_bad_home_is_named_with_the_joint(tmp_path, home, message):
    raw = json.loads((ROBOTS_DIR / "openarm" / "description.json").read_text())
    raw["home"] = home
    (tmp_path / "description.json").write_text(json.dumps(raw))
    with pytest.raises(DescriptionError, match=message):
        robots.load(str(tmp_path))


def test_a_home_for_a_model_with_its_own_keyframe_is_refused(tmp_path):
    shutil.copytree(ROBOTS_DIR / "pa10", tmp_path / "pa10")
    path = tmp_path / "pa10" / "description.json"
    raw = json.loads(path.read_text())
    raw["schema_version"], raw["home"] = 2, {"S1": 0.0}
    path.write_text(json.dumps(raw))
    with pytest.raises(DescriptionError, match=r"home: the model has its own keyframe 'home'; drop home"):
        robots.load(str(tmp_path / "pa10"))


@pytest.mark.parametrize("side", ["right", "left"])
def test_each_grippers_opening_table_is_what_the_model_does(openarm, side):
    """Commands between the table's rows, run in the simulation, open the fingers as far as the table
    interpolates; fully open the tips are 13 cm apart."""
    gripper = openarm.arm(side).gripper
    sign = 1.0 if side == "left" else -1.0
    commands = sign * np.array([0.1, 0.32, 0.55])
    np.testing.assert_allclose(
        gripper.opening_for(commands), measure_openings(openarm, side, commands), atol=5e-4
    )
    assert gripper.upper == pytest.approx(0.0665, abs=5e-4)
