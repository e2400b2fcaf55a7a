"""Robot descriptions: loading a robot folder, and clear errors for bad ones."""

import json

import pytest

import besman.robots as robots

TINY_ARM = """
<mujoco model="tiny">
  <compiler angle="radian"/>
  <worldbody>
    <body name="link1">
      <joint name="j1" axis="0 0 1" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      <body name="link2" pos="0.3 0 0">
        <joint name="j2" axis="0 0 1" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.5"/>
        <site name="tip" pos="0.2 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="j1" joint="j1" kp="10" ctrlrange="-1 1"/>
    <position name="j2" joint="j2" kp="10" ctrlrange="-2 2"/>
  </actuator>
  <keyframe><key name="home" qpos="0.1 0.2" ctrl="0.1 0.2"/></keyframe>
</mujoco>
"""


def description(**overrides):
    value = {
        "schema_version": 1,
        "name": "tiny",
        "model": "tiny.xml",
        "keyframe": "home",
        "groups": {"arm": {"joints": ["j1", "j2"], "site": "tip"}},
        "limits": {
            "j1": {"velocity": 1.0, "acceleration": 2.0, "jerk": 20.0},
            "j2": {"velocity": 1.5, "acceleration": 3.0, "jerk": 30.0},
        },
    }
    value.update(overrides)
    return value


def write_robot(folder, desc, text=None):
    (folder / "tiny.xml").write_text(TINY_ARM)
    (folder / "description.json").write_text(text if text is not None else json.dumps(desc))
    return folder


def test_a_robot_folder_loads_by_path(tmp_path):
    robot = robots.load(str(write_robot(tmp_path, description())))
    arm = robot.group("arm")
    assert arm.joints == ("j1", "j2") and arm.actuators == ("j1", "j2")
    assert list(arm.lower) == [-1, -2] and list(arm.upper) == [1, 2]
    assert list(arm.velocity) == [1.0, 1.5] and list(arm.jerk) == [20.0, 30.0]
    with pytest.raises(ValueError, match="read-only"):
        arm.lower[0] = 5
    result = robots.solve_ik(robot, "arm", [0.35, 0.25, 0.0])
    assert result.success


def test_unknown_robot_lists_the_available_ones():
    with pytest.raises(ValueError, match=r"unknown robot 'r2d2'; available: aila, openarm, pa10, ur5e"):
        robots.load("r2d2")


@pytest.mark.parametrize(
    ("desc", "text", "message"),
    [
        (None, "{not json", "not valid JSON"),
        (None, "[]", "expected a JSON object"),
        (description(schema_version=9), None, "schema_version 9 is not supported"),
        ({k: v for k, v in description().items() if k != "groups"}, None, "missing field 'groups'"),
        (description(groups={"arm": {"joints": ["j1", "elbow"]}}), None, "no joint 'elbow'"),
        (description(groups={"arm": {"joints": ["j1", "j1"]}}), None, "names repeat"),
        (description(groups={"arm": {"joints": ["j1"], "site": "nose"}}), None, "no site 'nose'"),
        (
            description(limits={"j1": {"velocity": 1.0, "acceleration": 2.0, "jerk": 20.0}}),
            None,
            "joint 'j2' has no velocity",
        ),
        (
            description(limits={"j1": {"velocity": -1, "acceleration": 2, "jerk": 2}}),
            None,
            r"limits.j1.velocity: must be a finite positive number",
        ),
        (
            description(limits={"j1": {"velocity": "fast", "acceleration": 2, "jerk": 2}}),
            None,
            r"limits.j1.velocity: expected int or float",
        ),
        (description(keyframe="ready"), None, "no keyframe 'ready'"),
        (description(model="missing.xml"), None, "missing.xml: the model does not load"),
    ],
)
def test_bad_descriptions_name_the_file_and_the_problem(tmp_path, desc, text, message):
    folder = write_robot(tmp_path, desc, text)
    with pytest.raises(ValueError, match=message) as error:
        robots.load(str(folder))
    assert str(tmp_path) in str(error.value)


def test_unknown_keyframe_lists_the_keyframes():
    with pytest.raises(ValueError, match="no keyframe 'ready'; keyframes: home"):
        robots.load("pa10").make_data("ready")
