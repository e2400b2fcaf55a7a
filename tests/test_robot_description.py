"""Robot descriptions: loading a robot folder, and clear errors for bad ones."""

import json
import math
import shutil

import pytest
from helpers import pincer

import besman.robots as robots
from besman.robots.catalogue import ROBOTS_DIR
from besman.robots.description import DescriptionError
from besman.robots.gripper import measure_openings
from besman.sim.objects import GraspableObject
from besman.sim.world import tabletop_world
from besman.tasks import task

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
        # A field the version does not have is refused, not ignored (a mount was lost on version 1).
        (description(mount={"yaw_degrees": 90}), None, r"\.mount: not a field of a description \(a field of"),
        (description(schema_version=2, mout={}), None, r"\.mout: not a field of a description; fields: arms"),
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


# The UR5e's pick-and-place areas as its description held them before the tasks took their own numbers.
UR5E_OBJECTS = {"x": [0.35, 0.52], "y": [-0.1, 0.05]}
UR5E_PLACES = {"x": [0.32, 0.49], "y": [-0.45, -0.31]}


def ur5e_copy(tmp_path, change) -> str:
    """The UR5e's folder copied, its description renamed (so that no task knows it by name: its numbers
    come from the file alone) and changed by ``change(raw)``."""
    folder = tmp_path / "my_ur5e"
    shutil.copytree(ROBOTS_DIR / "ur5e", folder)
    path = folder / "description.json"
    raw = json.loads(path.read_text())
    raw["name"] = "my_ur5e"
    change(raw)
    path.write_text(json.dumps(raw))
    return str(folder)


def test_an_earlier_description_with_objects_and_places_in_the_tabletop_loads_with_its_bounds(tmp_path):
    """``tabletop.objects`` is read as ``tabletop.reach`` and ``tabletop.places`` as
    ``tasks.pick-place.places``: pick and place's bounds on it are the numbers it always had."""

    def earlier(raw):
        tabletop = raw["tabletop"]
        del tabletop["reach"]
        tabletop["objects"], tabletop["places"] = UR5E_OBJECTS, UR5E_PLACES

    folder = ur5e_copy(tmp_path, earlier)
    described = robots.describe(folder)
    assert described.name == "my_ur5e"
    assert described.tabletop.reach == ((0.35, 0.52), (-0.1, 0.05))
    assert described.tasks == {"pick-place": {"places": UR5E_PLACES}}
    bounds = task("pick-place").bounds(folder)
    assert bounds.names == (
        *("object_x", "object_y", "object_yaw", "place_x", "place_y", "place_yaw"),
        *("shape", "object_width", "object_depth", "object_height"),
    )
    # The areas from the file; yaws the whole circle; the family's sizes (the 8 cm gripper holds its widest).
    assert bounds.low == (0.35, -0.10, -180, 0.32, -0.45, -180, 0, 0.04, 0.04, 0.05)
    assert bounds.high == (0.52, 0.05, 180, 0.49, -0.31, 180, 1, 0.07, 0.07, 0.08)
    assert bounds == task("pick-place").bounds("ur5e")  # the shipped UR5e's, now the task's own numbers
    assert robots.load(folder).arm().gripper is not None and task("pick-place").check_robot(folder) == folder


@pytest.mark.parametrize(
    ("places", "message"),
    [
        (
            {"x": [0.32], "y": [-0.45, -0.31]},
            r"tasks\.pick-place\.places\.x: expected a list of 2 finite numbers",
        ),
        ({"x": [0.32, 0.49]}, r"tasks\.pick-place\.places\.y: expected a list of 2 finite numbers"),
        ("here", r"tasks\.pick-place\.places: expected"),
        (None, r"tasks\.pick-place: missing 'places'"),
        pytest.param(
            {"x": [0.9, 1.2], "y": [-0.45, -0.31]},
            r"tasks\.pick-place\.places: the area .* must lie on the board at 0\.9 m",
            id="off the shelf",
        ),
    ],
)
def test_a_bad_pick_place_places_section_is_refused_naming_the_file_and_the_field(tmp_path, places, message):
    def bad(raw):
        raw["tasks"] = {"pick-place": {} if places is None else {"places": places}}

    folder = ur5e_copy(tmp_path, bad)
    with pytest.raises(DescriptionError, match=message) as error:
        task("pick-place").bounds(folder)
    assert f"{folder}/description.json: tasks.pick-place" in str(error.value)


def test_the_mount_turns_a_base_body_that_the_model_turns_with_euler(tmp_path):
    """The mount's yaw is added to the base body's own orientation, however the model writes it (it was
    lost where the model used ``euler``: only ``quat`` was read)."""
    mounted = description(schema_version=2, mount={"position": [0.1, 0.0, 0.5], "yaw_degrees": 90})
    quaternions = []
    for orientation in ('quat="0.9887711 0 0 0.1494381"', 'euler="0 0 0.3"', 'axisangle="0 0 1 0.3"'):
        folder = tmp_path / orientation.split("=")[0]
        folder.mkdir()
        write_robot(folder, mounted)
        model = folder / "tiny.xml"
        model.write_text(
            model.read_text().replace('<body name="link1">', f'<body name="link1" {orientation}>')
        )
        compiled = robots.load(str(folder)).model
        quaternions.append(compiled.body_quat[compiled.body("link1").id])
    half = (0.3 + math.pi / 2) / 2  # the model's 0.3 rad and the mount's 90 deg about z
    for quaternion in quaternions:
        assert quaternion == pytest.approx([math.cos(half), 0, 0, math.sin(half)], abs=1e-6)


def test_a_fragment_given_as_the_model_says_how_to_include_it(tmp_path):
    """Packages often ship ``<mujocoinclude>`` fragments: the error says to include it from a model file of
    the user's own, and that model, beside the description, loads."""
    write_robot(tmp_path, description())
    bodies = TINY_ARM.split("<worldbody>")[1].split("</worldbody>")[0]
    (tmp_path / "arm.xml").write_text(f"<mujocoinclude>{bodies}</mujocoinclude>")
    (tmp_path / "description.json").write_text(json.dumps(description(model="arm.xml")))
    with pytest.raises(ValueError, match="the model does not load") as refused:
        robots.load(str(tmp_path))
    message = str(refused.value)
    assert message.startswith(f"{tmp_path / 'arm.xml'}: the model does not load") and "a fragment" in message
    assert '<mujoco><worldbody><include file="' in message
    model = TINY_ARM.replace(bodies, '<include file="arm.xml"/>')
    (tmp_path / "model.xml").write_text(model)
    (tmp_path / "description.json").write_text(json.dumps(description(model="model.xml")))
    assert robots.load(str(tmp_path)).group("arm").joints == ("j1", "j2")


def test_an_arm_driven_by_torque_motors_is_refused_until_the_description_gives_it_servos(tmp_path):
    """besman commands joint positions: an arm joint driven by a motor (robosuite's arms) is refused with
    the field that fixes it; ``servos`` puts a position actuator on each joint in the motor's place (its
    force range the motor's), the keyframe's controls following, and the joints then hold a command."""
    import mujoco

    motors = TINY_ARM.replace(
        '<position name="j1" joint="j1" kp="10" ctrlrange="-1 1"/>',
        '<motor name="j1" joint="j1" gear="2" ctrlrange="-3 3"/>',
    ).replace('<position name="j2" joint="j2" kp="10" ctrlrange="-2 2"/>', "")
    motors = motors.replace('ctrl="0.1 0.2"', 'ctrl="0.5"')
    arm = {"groups": ["arm"], "tcp": {"site": "tip"}}
    write_robot(tmp_path, None, json.dumps(description(schema_version=2, arms={"arm": arm})))
    (tmp_path / "tiny.xml").write_text(motors)
    with pytest.raises(DescriptionError) as refused:
        robots.load(str(tmp_path))
    assert "arms.arm: joint 'j1' is driven by j1 (not a position servo)" in str(refused.value)
    assert '"servos": {"j1": {"kp": ..., "kv": ...}}' in str(refused.value)
    servos = {"j1": {"kp": 50.0, "kv": 5.0}, "j2": {"kp": 20.0, "force": 4.0}}
    given = description(schema_version=2, arms={"arm": arm}, servos=servos)
    (tmp_path / "description.json").write_text(json.dumps(given))
    robot = robots.load(str(tmp_path))
    model = robot.model
    assert [model.actuator(a).name for a in range(model.nu)] == ["j1_servo", "j2_servo"]
    assert list(model.actuator_forcerange[0]) == [-6.0, 6.0] and list(model.actuator_forcerange[1]) == [-4, 4]
    assert list(model.actuator_ctrlrange[1]) == [-2.0, 2.0] and model.actuator_biasprm[0, 2] == -5.0
    assert list(model.key("home").ctrl) == pytest.approx([0.1, 0.2])  # each servo at its joint's position
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    data.ctrl[:] = [0.4, -0.3]
    for _ in range(3000):
        mujoco.mj_step(model, data)
    assert data.qpos == pytest.approx([0.4, -0.3], abs=0.01)
    for bad, message in (
        ({"kv": 1.0}, "needs kp"),
        ({"kp": -1}, "must be positive"),
        ({"kp": 1, "ki": 2}, "ki"),
    ):
        (tmp_path / "description.json").write_text(json.dumps({**given, "servos": {"j1": bad}}))
        with pytest.raises(DescriptionError, match=f"servos.j1.*{message}|servos.j1: {message}"):
            robots.load(str(tmp_path))


def test_a_part_attaches_at_a_bodys_origin_where_the_model_has_no_site(tmp_path):
    """robosuite's arms carry their gripper on a body with no site: ``attach`` takes the body instead."""
    part = '<mujoco><worldbody><body name="finger"><geom size="0.01" mass="0.1"/></body></worldbody></mujoco>'
    (tmp_path / "part.xml").write_text(part)
    attach = [{"model": "part.xml", "body": "link2", "prefix": "hand/"}]
    write_robot(tmp_path, description(schema_version=2, attach=attach))
    model = robots.load(str(tmp_path)).model
    assert model.body("hand/finger").parentid == model.body("link2").id
    for where, message in (
        ({"site": "tip", "body": "link2"}, "a site or a body"),
        ({"body": "x"}, "no body 'x'"),
    ):
        given = description(schema_version=2, attach=[{"model": "part.xml", "prefix": "p/", **where}])
        (tmp_path / "description.json").write_text(json.dumps(given))
        with pytest.raises(DescriptionError, match=message):
            robots.load(str(tmp_path))


def test_the_world_objects_compile_whatever_the_models_compiler_settings(tmp_path):
    """A model whose compiler infers inertia only from geoms of groups 4-5 (as gym-aloha's do) still gets
    the tabletop world's objects with their mass: the compile error blamed the user's description."""
    model = TINY_ARM.replace(
        '<compiler angle="radian"/>', '<compiler angle="radian" inertiagrouprange="4 5"/>'
    )
    model = model.replace('mass="1"/>', 'group="4" mass="1"/>').replace(
        'mass="0.5"/>', 'group="4" mass="0.5"/>'
    )
    tabletop = {
        "table": {"height": 0.3, "x": [0.1, 0.6], "y": [-0.4, 0.4]},
        "shelf": {"height": 0.35, "x": [0.1, 0.3], "y": [-0.4, -0.3]},
        "reach": {"x": [0.3, 0.4], "y": [0.0, 0.1]},
    }
    write_robot(tmp_path, description(schema_version=2, tabletop=tabletop, floor=True))
    (tmp_path / "tiny.xml").write_text(model)
    cube = GraspableObject("box", size=(0.02, 0.02, 0.02), mass=0.15)
    world = tabletop_world((cube,), robot=str(tmp_path))
    body = world.model.body("box").id
    assert world.model.body_mass[body] == pytest.approx(0.15)
    assert world.model.body_inertia[body] == pytest.approx(cube.inertia)


def test_a_gripper_with_an_unnamed_actuator_per_finger_and_pads_given_as_bodies(tmp_path):
    robot = robots.load(pincer(tmp_path, [[0.0, 0.04], [0.0, 0.04]]))
    gripper = robot.arm().gripper
    fingers = [robot.model.geom_bodyid[side].tolist() for side in gripper.pads]
    assert list(gripper.actuators) == [1, 2] and fingers == [
        [robot.model.body(f"{side}_finger").id] for side in ("left", "right")
    ]
    assert gripper.command_for(0.025) == pytest.approx([0.02, 0.02])
    openings = [0.005, 0.025, 0.045]
    assert measure_openings(robot, None, gripper.command_for(openings)) == pytest.approx(openings, abs=1e-3)


def test_a_gripper_with_an_actuator_per_finger_needs_a_command_list_for_each(tmp_path):
    with pytest.raises(
        DescriptionError, match=r"2 actuators drive the fingers \(#1 \(unnamed\), #2 \(unnamed\)\)"
    ):
        robots.load(pincer(tmp_path, [0.0, 0.04]))
