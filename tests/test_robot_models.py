"""The shipped MJCF models: they compile, hold their home pose, and match the published numbers."""

import math

import mujoco
import numpy as np
import pytest

import besman.robots as robots
from besman.core.errors import UnknownNameError
from besman.skills import quaternion
from besman.skills.transformation import minimum_jerk

# DFKI's joint-limit configuration (rad, rad/s), as in shared/reference/robots.md.
AILA_LIMITS = {
    "J_Foot": (-1.9199, 1.9199, 0.5),
    "J_Knees": (2.1817, 2.7053, 0.5),
    "J_Hip": (1.9199, 2.7053, 0.5),
    "J_Waist": (-1.0472, 1.0472, 0.5),
    "J_Shoulder1_r": (-1.7453, 0.8727, 1.5),
    "J_Shoulder1_l": (-0.8727, 1.7453, 1.5),
    "J_Shoulder2_r": (-0.0873, 1.4835, 1.5),
    "J_Shoulder2_l": (-1.4835, 0.0873, 1.5),
    "J_UpperArm_r": (-1.9199, 1.9199, 1.5),
    "J_UpperArm_l": (-1.9199, 1.9199, 1.5),
    "J_Elbow_r": (-0.0873, 1.8326, 1.5),
    "J_Elbow_l": (-1.8326, 0.0873, 1.5),
    "J_Forearm_r": (-1.9199, 1.5708, 1.5),
    "J_Forearm_l": (-1.9199, 1.5708, 1.5),
    "J_Wrist1_r": (-1.5708, 0.0, 1.5),
    "J_Wrist1_l": (-1.5708, 0.0, 1.5),
    "J_Wrist2_r": (-0.2618, 0.6109, 1.5),
    "J_Wrist2_l": (-0.6109, 0.2618, 1.5),
    "J_Pan": (-0.6981, 0.7854, 1.0),
    "J_Tilt": (-1.0472, 0.5236, 1.0),
}
# PA10-7C limits (deg) and the recalled speed limits (rad/s).
PA10_LIMITS_DEG = {"S1": 177, "S2": 91, "S3": 174, "E1": 137, "E2": 255, "W1": 165, "W2": 255}
PA10_SPEED = {
    "S1": 1.0,
    "S2": 1.0,
    "S3": 2.0,
    "E1": 2.0,
    "E2": 2 * math.pi,
    "W1": 2 * math.pi,
    "W2": 2 * math.pi,
}
PA10_MASSES = {
    "S1_link": 9.78,
    "S2_link": 8.41,
    "S3_link": 3.52,
    "E1_link": 4.31,
    "E2_link": 3.45,
    "W1_link": 1.46,
    "W2_link": 0.24,
}
AILA_DH_D = (0.214, 0.0, 0.285, 0.0, 0.2886, 0.0, 0.0)


def joint_range(model, name):
    return model.jnt_range[model.joint(name).id]


@pytest.fixture(scope="module", params=["aila", "openarm", "pa10", "ur5e"])
def robot(request):
    return robots.load(request.param)


def test_available_lists_the_shipped_robots():
    assert robots.available() == ["aila", "openarm", "pa10", "ur5e"]


def test_home_keyframe_is_held_without_drift(robot):
    model = robot.model
    data = robot.make_data()
    assert data.ncon == 0, "nothing touches anything in the home pose"
    start = data.site_xpos.copy()
    limited = model.jnt_limited.astype(bool)
    addresses = model.jnt_qposadr[limited]
    # Soft joint limits give a little: the Robotiq 2F-85's linkage rests 0.1 mrad past its coupler's limit.
    for _ in range(round(2.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
        qpos = data.qpos[addresses]
        assert np.all(qpos >= model.jnt_range[limited, 0] - 1e-3)
        assert np.all(qpos <= model.jnt_range[limited, 1] + 1e-3)
    drift = np.linalg.norm(data.site_xpos - start, axis=1)
    assert drift.max() < 1e-3, f"site {model.site(int(drift.argmax())).name} drifted {drift.max():.2e} m"
    assert not any(warning.number for warning in data.warning)


def test_home_keyframe_is_within_the_joint_ranges(robot):
    model = robot.model
    qpos = model.key(robot.keyframe).qpos
    for j in np.flatnonzero(model.jnt_limited):
        low, high = model.jnt_range[j]
        assert low <= qpos[model.jnt_qposadr[j]] <= high, model.joint(j).name


def test_position_actuators_cover_exactly_the_joint_ranges(robot):
    model = robot.model
    for group in robot.groups.values():
        for actuator in group.actuators:
            a = model.actuator(actuator)
            assert model.actuator_gaintype[a.id] == mujoco.mjtGain.mjGAIN_FIXED
            if model.actuator_trntype[a.id] == mujoco.mjtTrn.mjTRN_JOINT:
                # Menagerie's UR5e rounds +-2 pi to 6.2831 for the commands and 6.28319 for the joints.
                np.testing.assert_allclose(a.ctrlrange, model.jnt_range[a.trnid[0]], atol=1e-4)
    # The OpenArm's model integrates as its maker ships it (Euler; its actuators' damping is small).
    if robot.name != "openarm":
        assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_aila_limits_equal_dfki_tables():
    aila = robots.load("aila")
    for joint, (low, high, speed) in AILA_LIMITS.items():
        np.testing.assert_allclose(joint_range(aila.model, joint), (low, high), atol=1e-12, err_msg=joint)
        group = next(g for g in aila.groups.values() if joint in g.joints)
        i = group.joints.index(joint)
        assert group.velocity[i] == speed, joint
        assert group.lower[i] == low and group.upper[i] == high
    arm = aila.group("right_arm")
    assert np.all(arm.acceleration > 0) and np.all(arm.jerk > arm.acceleration)


def test_pa10_limits_equal_reference_tables():
    pa10 = robots.load("pa10")
    arm = pa10.group("arm")
    assert arm.joints == tuple(PA10_LIMITS_DEG)
    for i, (joint, degrees) in enumerate(PA10_LIMITS_DEG.items()):
        np.testing.assert_allclose(joint_range(pa10.model, joint), np.radians([-degrees, degrees]), atol=1e-5)
        assert arm.velocity[i] == pytest.approx(PA10_SPEED[joint], abs=1e-4)
    for body, mass in PA10_MASSES.items():
        assert pa10.model.body(body).mass[0] == pytest.approx(mass)


def test_aila_groups_and_actuators():
    aila = robots.load("aila")
    assert set(aila.groups) == {
        "base",
        "torso",
        "waist",
        "head",
        "right_arm",
        "left_arm",
        "right_gripper",
        "left_gripper",
    }
    assert aila.group("waist").joints == ("J_Waist",), "the torso's last joint, for reaching across"
    assert aila.group("torso").joints == ("J_Foot", "J_Knees", "J_Hip", "J_Waist")
    assert aila.group("right_arm").actuators == aila.group("right_arm").joints
    assert aila.group("right_gripper").actuators == ("right_gripper",)
    assert aila.group("right_gripper").equalities == ("right_finger_coupling",)
    assert aila.model.nu == 3 + 4 + 2 + 2 * 7 + 2
    for name in ("right_wrist_force", "right_wrist_torque", "left_wrist_force", "left_wrist_torque"):
        assert mujoco.mj_name2id(aila.model, mujoco.mjtObj.mjOBJ_SENSOR, name) >= 0
    assert mujoco.mj_name2id(aila.model, mujoco.mjtObj.mjOBJ_CAMERA, "head_camera") >= 0
    with pytest.raises(UnknownNameError, match="groups: base, torso"):
        aila.group("tail")
    with pytest.raises(UnknownNameError, match="no arm 'middle'; arms: right, left"):
        aila.arm("middle")


def _line_distance(p1, d1, p2, d2):
    normal = np.cross(d1, d2)
    return abs((p2 - p1) @ normal) / np.linalg.norm(normal)


@pytest.mark.parametrize("side", ["r", "l"])
def test_aila_arm_follows_the_dh_parameters(side):
    """Standard DH with a = 0 and alpha = +-90 deg: consecutive joint axes intersect at right angles, joints
    1-3 meet at the shoulder centre, 3-4 at the elbow, 5-7 at the wrist, and the distances between those
    points are d3 and d5, over random configurations."""
    aila = robots.load("aila")
    model, data = aila.model, aila.make_data()
    arm = aila.group("right_arm" if side == "r" else "left_arm")
    prefix = "right" if side == "r" else "left"
    rng = np.random.default_rng(7)
    d1, _, d3, _, d5, _, _ = AILA_DH_D
    for _ in range(50):
        data.qpos[arm.qpos_indices] = rng.uniform(arm.lower, arm.upper)
        mujoco.mj_kinematics(model, data)
        anchors = [data.xanchor[model.joint(j).id].copy() for j in arm.joints]
        axes = [data.xaxis[model.joint(j).id].copy() for j in arm.joints]
        for i in range(6):
            assert abs(axes[i] @ axes[i + 1]) < 1e-9, "alpha = +-90 deg"
            assert _line_distance(anchors[i], axes[i], anchors[i + 1], axes[i + 1]) < 1e-9, "a = 0"
        shoulder = data.site(f"{prefix}_shoulder").xpos
        elbow = data.site(f"{prefix}_elbow").xpos
        wrist = data.site(f"{prefix}_wrist").xpos
        for i, centre in [
            (0, shoulder),
            (1, shoulder),
            (2, shoulder),
            (3, elbow),
            (4, wrist),
            (5, wrist),
            (6, wrist),
        ]:
            offset = centre - anchors[i]
            assert np.linalg.norm(offset - (offset @ axes[i]) * axes[i]) < 1e-9, (
                f"joint {i + 1} misses its centre"
            )
        elbow_angle = data.qpos[arm.qpos_indices[3]]
        expected = math.sqrt(d3**2 + d5**2 + 2 * d3 * d5 * math.cos(elbow_angle))
        assert np.linalg.norm(wrist - shoulder) == pytest.approx(expected, abs=1e-6)
        assert np.linalg.norm(elbow - shoulder) == pytest.approx(d3, abs=1e-6)
        assert np.linalg.norm(wrist - elbow) == pytest.approx(d5, abs=1e-6)
        chest = data.site("chest").xpos
        assert np.linalg.norm(shoulder - chest) == pytest.approx(d1, abs=1e-6)


def test_aila_arms_are_mirror_images():
    """Equal-and-opposite values of mirrored joints (same values for Forearm and Wrist1) mirror the pose."""
    aila = robots.load("aila")
    model, data = aila.model, aila.make_data()
    right, left = aila.group("right_arm"), aila.group("left_arm")
    sign = np.array([-1, -1, -1, -1, 1, 1, -1])
    rng = np.random.default_rng(3)
    mirror = np.diag([1.0, -1.0, 1.0])
    tested = 0
    while tested < 20:
        q = rng.uniform(right.lower, right.upper)
        if np.any(sign * q < left.lower) or np.any(sign * q > left.upper):
            continue
        data.qpos[right.qpos_indices] = q
        data.qpos[left.qpos_indices] = sign * q
        mujoco.mj_kinematics(model, data)
        for part in ("elbow", "wrist", "grasp"):
            np.testing.assert_allclose(
                mirror @ data.site(f"right_{part}").xpos, data.site(f"left_{part}").xpos, atol=1e-12
            )
        tested += 1


def test_pa10_flange_height_in_the_zero_pose():
    pa10 = robots.load("pa10")
    data = mujoco.MjData(pa10.model)
    mujoco.mj_kinematics(pa10.model, data)
    np.testing.assert_allclose(data.site("flange").xpos, [0, 0, 1.345], atol=1e-12)


def _pa10_holding_the_ball_in(pose):
    """The PA-10 at rest in ``pose`` (7 joint values) with the ball welded in its hand."""
    pa10 = robots.load("pa10")
    model, data = pa10.model, pa10.make_data()
    data.qpos[:7] = data.ctrl[:7] = pose
    mujoco.mj_kinematics(model, data)
    holder = data.site("ball_holder")
    ball = model.jnt_qposadr[model.joint("ball").id]
    data.qpos[ball : ball + 3] = holder.xpos
    data.qpos[ball + 3 : ball + 7] = quaternion.from_matrix(holder.xmat.reshape(3, 3))
    mujoco.mj_forward(model, data)
    return pa10, model, data


def test_pa10_releases_the_ball_when_the_weld_switches_off():
    """Hand pointing down: held while the weld is on, free fall once it is off."""
    pa10, model, data = _pa10_holding_the_ball_in([0, 0.8, 0, 1.2, 0, np.pi - 2.0, 0])
    weld = model.equality("ball_weld").id
    assert pa10.group("release").equalities == ("ball_weld",)
    holder = data.site("ball_holder").xpos.copy()
    for _ in range(200):
        mujoco.mj_step(model, data)
    assert np.linalg.norm(data.body("ball").xpos - holder) < 1e-3, "held while the weld is on"
    data.eq_active[weld] = 0
    for _ in range(200):
        mujoco.mj_step(model, data)
    fallen = holder[2] - data.body("ball").xpos[2]
    assert fallen == pytest.approx(0.5 * 9.81 * 0.2**2, rel=0.05), "free fall once released, hand untouched"
    np.testing.assert_allclose(data.site("ball_holder").xpos, holder, atol=1e-3)


def test_pa10_held_ball_clears_the_palm_and_a_released_one_lands_on_it():
    """Palm up (the zero pose): the held ball floats 2 mm above the palm, touching nothing; released, it
    drops onto the palm and stays there (contact is real once it has left the hand)."""
    _, model, data = _pa10_holding_the_ball_in(np.zeros(7))
    ball = model.body("ball").id
    for _ in range(200):
        mujoco.mj_step(model, data)
    assert not any(ball in model.geom_bodyid[pair] for pair in data.contact.geom[: data.ncon])
    data.eq_active[model.equality("ball_weld").id] = 0
    for _ in range(500):
        mujoco.mj_step(model, data)
    palm_top = data.body("hand").xpos[2] + 0.02
    assert data.body("ball").xpos[2] == pytest.approx(palm_top + 0.035, abs=1e-3)  # resting on the palm
    assert any(ball in model.geom_bodyid[pair] for pair in data.contact.geom[: data.ncon])


def test_aila_gripper_holds_a_box_lifted_and_moved():
    """A 0.2 kg box pinched by real contacts: lifted 20 cm and moved for 2 s, it slips < 5 mm in the hand."""
    aila = robots.load("aila")
    spec = mujoco.MjSpec.from_file(str(aila.folder / "scene.xml"))
    grasp_point = np.array([0.47, -0.2, 0.78])
    table = spec.worldbody.add_body(name="table", pos=[0.6, -0.2, 0.375])
    table.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.25, 0.375])
    box = spec.worldbody.add_body(name="box", pos=grasp_point)
    box.add_freejoint()
    box.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.03, 0.03, 0.03], mass=0.2, friction=[0.8, 0.02, 0.0001]
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)

    down = [0.0, 0.70710678, 0.70710678, 0.0]  # approach axis -z, fingers closing along world x
    arm, gripper = aila.group("right_arm"), aila.group("right_gripper")
    poses = [
        grasp_point,
        grasp_point + [0, 0, 0.2],
        grasp_point + [-0.05, 0.12, 0.2],
        grasp_point + [0, 0, 0.2],
    ]
    solutions = [robots.solve_ik(aila, "right_arm", p, down) for p in poses]
    assert all(s.success for s in solutions)
    data.qpos[arm.qpos_indices] = data.ctrl[arm.actuator_indices] = solutions[0].qpos
    data.qpos[gripper.qpos_indices] = data.ctrl[gripper.actuator_indices] = 0.05
    mujoco.mj_forward(model, data)
    site, body = model.site("right_grasp").id, model.body("box").id

    def box_in_hand():
        return data.site_xmat[site].reshape(3, 3).T @ (data.xpos[body] - data.site_xpos[site])

    def move(seconds, start=None, end=None):
        steps = round(seconds / model.opt.timestep)
        for i in range(1, steps + 1):
            if start is not None:
                s = i / steps
                data.ctrl[arm.actuator_indices] = start + minimum_jerk(s) * (end - start)
            mujoco.mj_step(model, data)

    def wrist_force():
        return data.sensor("right_wrist_force").data

    move(0.2)
    empty_hand = np.linalg.norm(wrist_force())
    assert empty_hand == pytest.approx(0.76 * 9.81, rel=0.05), "palm and fingers hang on the sensor"
    data.ctrl[gripper.actuator_indices] = 0.0  # close
    move(0.8)
    held = box_in_hand()
    assert data.qpos[gripper.qpos_indices[0]] == pytest.approx(0.03, abs=2e-3), "fingers stopped by the box"
    start_height = data.xpos[body][2]
    move(1.0, solutions[0].qpos, solutions[1].qpos)
    assert data.xpos[body][2] - start_height == pytest.approx(0.2, abs=0.01), "lifted 20 cm"
    move(0.3)
    # The wrist sensor now feels the box's weight on top of the hand's own.
    assert np.linalg.norm(wrist_force()) - empty_hand == pytest.approx(0.2 * 9.81, rel=0.05)
    slip = 0.0
    for a, b in [(1, 2), (2, 3)]:  # 2 s of carrying: out and back
        move(1.0, solutions[a].qpos, solutions[b].qpos)
        slip = max(slip, np.linalg.norm(box_in_hand() - held))
    assert slip < 5e-3
    assert not any(warning.number for warning in data.warning)
