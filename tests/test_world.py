"""Worlds: robots composed with furniture and objects through MjSpec."""

import mujoco
import numpy as np
import pytest

from besman.core.errors import UnknownNameError
from besman.sim.faults import FaultMonitor, counted_warnings
from besman.sim.world import GraspableObject, tabletop_world
from besman.tasks.throwing.world import throwing_world


@pytest.fixture(scope="module")
def world():
    return tabletop_world()


def test_tabletop_world_composes_robot_table_shelf_and_box(world):
    model = world.model
    for name in ("table", "shelf", "box"):
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) >= 0
    arm = world.robot.group("right_arm")
    np.testing.assert_array_equal(world.data.qpos[arm.qpos_indices], model.key("home").qpos[arm.qpos_indices])
    assert world.data.ncon == 0 or all(
        model.geom_bodyid[c.geom1] == model.body("box").id
        or model.geom_bodyid[c.geom2] == model.body("box").id
        for c in world.data.contact[: world.data.ncon]
    ), "only the box rests on the table"
    assert model.body("box").mass[0] == pytest.approx(0.2)


def test_objects_rest_where_they_are_placed(world):
    world.reset()
    world.place_on("box", "shelf", 0.5, -0.4, yaw=0.3)
    for _ in range(250):
        mujoco.mj_step(world.model, world.data)
    pose = world.object_pose("box")
    table, shelf = world.surface("table"), world.surface("shelf")
    np.testing.assert_allclose(pose.position, [0.5, -0.4, shelf.height + 0.03], atol=2e-3)
    assert shelf.contains(0.5, -0.4) and not shelf.contains(0.5, 0.0)
    assert (table.height, shelf.height) == (0.78, 0.90)  # AILA's layout
    world.reset()  # the box at the middle of the layout's object area
    np.testing.assert_allclose(world.object_pose("box").position, [0.535, -0.075, table.height + 0.03])


def test_object_errors_name_the_problem(world):
    with pytest.raises(UnknownNameError, match="no object 'cup' in the world; objects: box"):
        world.object_pose("cup")
    with pytest.raises(UnknownNameError, match="no surface 'floor' in the world; surfaces: table, shelf"):
        world.place_on("box", "floor", 0.5, 0.0)
    with pytest.raises(ValueError, match="3 \\+ 4 finite numbers"):
        world.set_object_pose("box", [0.5, np.nan, 1.0])
    with pytest.raises(ValueError, match="shape must be one of"):
        tabletop_world((GraspableObject("ball", shape="sphere"),))


def test_several_objects(world):
    cylinder = GraspableObject("can", shape="cylinder", size=(0.033, 0.06), mass=0.35)
    two = tabletop_world((GraspableObject("box"), cylinder))
    assert two.object_pose("can").position[2] == pytest.approx(two.surface("table").height + 0.06)
    assert (
        two.robot.group("right_arm").qpos_indices.tolist()
        == world.robot.group("right_arm").qpos_indices.tolist()
    )


def test_throwing_world_senses_the_ball():
    world = throwing_world()
    mujoco.mj_forward(world.model, world.data)
    np.testing.assert_allclose(world.data.sensordata[:3], world.data.body("ball").xpos)


TINY = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link">
      <joint name="hinge" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.mujoco_warnings  # provokes the fault it detects
def test_fault_monitor_reports_nan_divergence_warnings_and_ranges():
    model = mujoco.MjModel.from_xml_string(TINY)
    data = mujoco.MjData(model)
    monitor = FaultMonitor(model)
    monitor.reset(data)
    assert monitor.check(data) is None
    data.qpos[0] = 1.5
    assert "joint hinge left its range by 0.5" in monitor.check(data)
    data.qpos[0] = 0.0
    data.qvel[0] = 1e4
    assert "diverged: joint hinge moves at" in monitor.check(data)
    data.qvel[0] = np.nan
    assert "NaN" in monitor.check(data)
    mujoco.mj_resetData(model, data)
    data.qfrc_applied[0] = 1e30  # an impossible force: MuJoCo warns of a bad acceleration and resets
    mujoco.mj_step(model, data)
    assert monitor.check(data).startswith("mujoco warning BADQACC")
    assert counted_warnings(data) == ("BADQACC: 1",)
    monitor.reset(data)
    assert monitor.check(data) is None, "old warnings are forgotten after reset()"
