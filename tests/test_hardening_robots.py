"""Issue 52, arms users bring (from gymnasium-robotics, gym-aloha, robosuite): ``besman robots check`` and the
description name the real cause - mesh paths, a joint's damping and friction against the velocity asked, the
integrator, a tool frame on a leaf body, absurd numbers - and say what to change. Each on the inline pincer
arm of the other robot tests, with real MuJoCo physics."""

import json
import re

import mujoco
import pytest
from helpers import PINCER, pincer, run_cli

import besman.robots as robots
from besman.robots.description import DescriptionError
from besman.sim.world import tabletop_world
from besman.tasks.robot_check import _fingertips, _integrator, _limits

COMMANDS = [[0.0, 0.04], [0.0, 0.04]]  # the pincer's two finger actuators
MESH = "v 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 0 0 0.02\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def brought(tmp_path, model=PINCER, **changes) -> str:
    """The pincer robot with its model text ``model`` and its description's top-level fields ``changes``."""
    folder = pincer(tmp_path, COMMANDS)
    (tmp_path / "pincer.xml").write_text(model)
    path = tmp_path / "description.json"
    path.write_text(json.dumps(json.loads(path.read_text()) | changes))
    return folder


def test_a_fragments_mesh_that_show_skipped_is_named_with_the_path_tried_by_show_and_check_alike(tmp_path):
    """A model of the user's including a package's fragment whose meshes sit in the package's ``meshdir``:
    ``robots show`` (no meshes) loaded it and the check's compile did not; both now refuse it alike, naming
    the mesh, the path MuJoCo tries and the folder that has it, and load it once the model says so."""
    package = tmp_path / "package" / "assets"
    (package / "meshes").mkdir(parents=True)
    (package / "meshes" / "finger.obj").write_text(MESH)
    (package / "finger_assets.xml").write_text(
        '<mujocoinclude><mesh name="finger" file="finger.obj"/></mujocoinclude>'
    )
    asset = f'<asset><include file="{package / "finger_assets.xml"}"/></asset>'
    mesh_finger = PINCER.replace("<worldbody>", asset + "<worldbody>", 1).replace(
        '<geom type="box" size="0.005 0.005 0.02" mass="0.05"/>\n        </body>\n        <body name="right',
        '<geom type="box" size="0.005 0.005 0.02" mass="0.05"/><geom type="mesh" mesh="finger" contype="0" '
        'conaffinity="0"/>\n        </body>\n        <body name="right',
    )
    robot = brought(tmp_path, mesh_finger)
    messages = set()
    for meshes in (False, True):
        with pytest.raises(DescriptionError) as refused:
            robots.load(robot, meshes=meshes)
        messages.add(str(refused.value))
    (message,) = messages
    assert message.startswith(f"{tmp_path / 'description.json'}.model: mesh 'finger': no file ")
    assert str(package / "finger.obj") in message and f'<compiler meshdir="{package / "meshes"}"/>' in message
    fixed = mesh_finger.replace("<asset>", f'<compiler meshdir="{package / "meshes"}"/><asset>')
    (tmp_path / "pincer.xml").write_text(fixed)
    assert robots.load(robot).model.nmesh == 1


def test_a_joint_slowed_by_its_damping_is_told_by_its_cause_and_the_velocity_suggested_passes(tmp_path):
    """j1 with damping 3 under a kp-10 servo at 1 rad/s (the demo: "blocked or in collision"): the check
    names the damping, the force it needs and the lag, and the velocity it suggests then passes (the
    proportional estimate of the lag cut short by the failed move, 0.72, lags 0.2 again). A friction loss
    whose lag alone exceeds the share of the tolerance: no velocity limit does, and the check says so."""
    damped = PINCER.replace('range="-1 1"/>', 'range="-1 1" damping="3"/>', 1)
    robot = brought(tmp_path, damped)
    found = _limits(tabletop_world((), robot=robot), "arm", "FILE")
    assert not found.passed
    assert re.search(
        r"j1's damping 3 and friction loss 0 need 3 at 1\.00/s; its actuator has no force limit and lags "
        r"0\.300",
        found.measured,
    )
    assert "lower j1's damping or frictionloss in the model, or raise its actuator's kp" in found.fix
    suggested = float(
        re.search(r"a velocity limit of at most ([0-9.]+) \(FILE: limits\.j1\.velocity\)", found.fix)[1]
    )
    assert suggested == 0.39  # below (0.12 x kp 10) / damping 3 = 0.4, where the lag is at the allowance
    raw = json.loads((tmp_path / "description.json").read_text())
    raw["limits"]["j1"]["velocity"] = suggested
    (tmp_path / "description.json").write_text(json.dumps(raw))
    assert _limits(tabletop_world((), robot=robot), "arm", "FILE").passed
    stuck = PINCER.replace('range="-1 1"/>', 'range="-1 1" damping="3" frictionloss="1.2"/>', 1)
    (tmp_path / "pincer.xml").write_text(stuck)
    found = _limits(tabletop_world((), robot=robot), "arm", "FILE")
    assert not found.passed and "friction loss 1.2" in found.measured and "0.120 at rest" in found.measured
    assert found.fix.endswith("kp or forcerange: no velocity limit is slow enough")


def test_the_integrator_is_an_option_and_euler_with_a_stiff_light_finger_is_named(tmp_path):
    """A finger servo with kv 60 on 50 g: MuJoCo's Euler (the fragments' default, named here: a tabletop world
    otherwise integrates implicitly) takes kv explicitly and the finger runs off (real physics); the check
    names the joint and says to set options.integrator, spelt as MuJoCo spells it."""
    stiff = PINCER.replace('<position joint="left" kp="100"', '<position joint="left" kp="100" kv="60"')
    results = {}
    for options in ({"integrator": "Euler"}, {}):
        world = tabletop_world((), robot=brought(tmp_path, stiff, options=options))
        found = _integrator(world, "arm", "FILE")
        world.data.ctrl[1] = 0.03
        for _ in range(1500):  # 3 s: the implicit finger settles (kv / kp 0.6 s)
            mujoco.mj_step(world.model, world.data)
        results[found.passed] = found, world.data.qpos[world.model.joint("left").qposadr[0]]
    euler, ran_off = results[False]
    assert euler.measured.startswith("Euler at timestep 0.002 s: the least stable joint, left")
    assert (
        "grows 1.30 times a step" in euler.measured and 'options.integrator "implicit" in FILE' in euler.fix
    )
    assert abs(ran_off - 0.03) > 0.01 and results[True][1] == pytest.approx(0.03, abs=1e-3)
    for bad in ("euler", 3):
        brought(tmp_path, stiff, options={"integrator": bad})
        with pytest.raises(
            DescriptionError, match=r"options\.integrator: one of Euler, RK4, implicit, implicitfast"
        ):
            robots.load(str(tmp_path), meshes=False)


def test_a_tool_frame_on_a_leaf_body_beside_the_fingers_measures_the_fingers(tmp_path):
    """robosuite's and gym-aloha's hands carry the tool frame on a body of its own beside the fingers: no
    geom below it crashed the check ("need at least one array to concatenate")."""
    leaf = PINCER.replace(
        '<site name="tip" pos="0 0 -0.05"/>', '<body name="eef" pos="0 0 -0.05"><site name="tip"/></body>'
    )
    found = _fingertips(tabletop_world((), robot=brought(tmp_path, leaf)), "arm", "FILE", _the_box())
    assert "the fingertips reach 20 mm past the tool frame" in found.measured


def _the_box():
    from besman.sim.objects import GraspableObject

    return GraspableObject("box", size=(0.02, 0.02, 0.03), mass=0.1)


@pytest.mark.parametrize(
    ("where", "value", "message"),
    [
        (
            "velocity",
            "1" + "0" * 400,
            r"limits\.j1\.velocity: expected a finite number, got a 401-digit number",
        ),
        ("velocity", "1e400", r"limits\.j1\.velocity: expected a finite number, got inf"),
        ("still_speed", "1" + "0" * 400, r"gripper\.still_speed: expected a finite number, got a 401-digit"),
        ("timestep", "1" + "0" * 400, r"options\.timestep: expected a finite number, got a 401-digit"),
        ("noslip", "1" + "0" * 400, r"options\.noslip_iterations: expected a whole number from 0 to 1000"),
        (
            "home",
            "-1" + "0" * 400,
            r"home\.j1: expected a list of finite numbers, got \[a 401-digit number\]",
        ),
    ],
)
def test_absurd_numbers_are_one_line_naming_the_file_and_field_exit_2(
    tmp_path, capsys, where, value, message
):
    robot = brought(tmp_path, options={"timestep": 0.002})
    text = (tmp_path / "description.json").read_text()
    places = {
        "velocity": ('"j1": {"velocity": 1.0', f'"j1": {{"velocity": {value}'),
        "still_speed": ('"open": 0.03', f'"open": 0.03, "still_speed": {value}'),
        "timestep": ('"timestep": 0.002', f'"timestep": {value}'),
        "noslip": ('"timestep": 0.002', f'"noslip_iterations": {value}'),
        "home": ('"schema_version": 2', f'"schema_version": 2, "home": {{"j1": {value}}}'),
    }
    old, new = places[where]
    assert old in text
    (tmp_path / "description.json").write_text(text.replace(old, new))
    code, out, err = run_cli(capsys, "robots", "show", robot)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert re.search(message, err) and f"{tmp_path / 'description.json'}" in err
