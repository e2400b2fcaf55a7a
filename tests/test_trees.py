"""Behaviour trees on the simulated AILA: leaves, failure propagation, slips, pre-emption, sim-time limits."""

import mujoco
import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from besman.core.errors import InputError
from besman.sim.executor import Executor, limit_violations
from besman.sim.motions import MotionStatus, Stop
from besman.sim.world import tabletop_world
from besman.skills import DMP, MovementPrimitive
from besman.trees import (
    ExecutePrimitive,
    Gripper,
    InstantiateSkillTemplate,
    ObjectAt,
    ObjectGrasped,
    PerceiveObject,
    Runner,
    SimTimeout,
    Wait,
    grasp_then_place,
)
from besman.trees.blackboard import set_task_values

HOME_SHIFT = np.array([0.3, -0.3, -0.3, 0.5, -0.5, 0.4, 0.3, 0.4])  # stays in range, clear of the table


@pytest.fixture
def executor():
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    world.place_on("box", "table", 0.55, -0.08)
    return Executor(world)


def move(executor, name, shift=1.0, duration=2.0):
    dmp = DMP(executor.arm.dofs, execution_time=duration, goal=executor.position + shift * HOME_SHIFT)
    return MovementPrimitive(dmp, name)


def test_a_primitive_leaf_runs_until_the_motion_arrives(executor):
    leaf = ExecutePrimitive("move", primitive=move(executor, "move"))
    result = Runner(leaf, executor).run()
    assert result.status == "SUCCESS"
    assert result.sim_time_s == pytest.approx(2.0, abs=0.3)
    np.testing.assert_allclose(executor.measured_position(), executor.position, atol=0.01)


def test_failure_propagates_with_the_failing_leaf_and_its_reason(executor):
    root = py_trees.composites.Sequence(
        "task",
        memory=True,
        children=[
            ExecutePrimitive("move", primitive=move(executor, "move", duration=1.0)),
            Gripper("grab air", action="close", expect_grasp=True, object="box"),
            Wait("never reached", duration=1.0),
        ],
    )
    result = Runner(root, executor).run()
    assert result.status == "FAILURE"
    assert result.failed_node == "task/grab air"
    assert "closed on nothing" in result.message
    assert root.children[2].status is Status.INVALID


def test_the_first_failure_a_retry_absorbed_is_reported_beside_the_last(executor):
    """A step fails once and its retry succeeds; the run then fails elsewhere (the gripper closes on nothing):
    the summary names the last failure and the first, the fault that the retry hid."""
    flaky = py_trees.behaviours.StatusQueue("flaky", queue=[Status.FAILURE], eventually=Status.SUCCESS)
    attempt = py_trees.composites.Sequence("attempt", memory=True, children=[flaky])
    root = py_trees.composites.Sequence(
        "task",
        memory=True,
        children=[
            py_trees.decorators.Retry("retried", attempt, num_failures=2),
            Gripper("grab air", action="close", expect_grasp=True, object="box"),
        ],
    )
    result = Runner(root, executor).run()
    assert result.failed_node == "task/grab air" and "closed on nothing" in result.message
    assert result.first_failure.startswith("task/retried/attempt/flaky: ")
    # A run that fails where it first failed names it once.
    py_trees.blackboard.Blackboard.clear()
    alone = Runner(Gripper("grab air", action="close", expect_grasp=True, object="box"), executor).run()
    assert alone.failed_node == "grab air" and alone.first_failure is None


def test_an_object_is_perceived_once_it_has_come_to_rest(executor):
    """A box dropped from 10 cm above the table (as a failed grasp drops one) is perceived where it lands,
    not in the air; one that never comes to rest fails the look, saying how fast it still moves."""
    world = executor.world
    resting = world.object_pose("box").position
    world.set_object_pose("box", resting + [0.0, 0.0, 0.10])
    executor.advance(10)  # falling
    result = Runner(PerceiveObject("look", object="box"), executor).run()
    seen = py_trees.blackboard.Blackboard.get("/object_position")
    assert result.status == "SUCCESS" and result.sim_time_s > 0.1
    assert seen == pytest.approx(world.object_pose("box").position)
    assert seen[2] == pytest.approx(resting[2], abs=0.005)
    world.model.opt.gravity[:] = [0.0, 0.0, 0.5]  # gravity turned up: the box floats away, never at rest
    executor.advance(10)
    py_trees.blackboard.Blackboard.clear()
    result = Runner(PerceiveObject("look", object="box"), executor).run()
    assert result.status == "FAILURE" and "box moves at" in result.message and "after 2 s" in result.message


def test_preemption_brakes_the_robot_to_rest(executor):
    """A slow motion under a 1 s sim-time timeout: the timeout pre-empts it and the executor brakes."""
    leaf = ExecutePrimitive("slow", primitive=move(executor, "slow", duration=4.0))
    root = SimTimeout("one second", leaf, duration=1.0)
    runner = Runner(root, executor)
    result = runner.run()
    assert result.status == "FAILURE"
    assert "timed out after 1 s of simulated time" in result.message
    assert result.sim_time_s == pytest.approx(1.0, abs=0.05), "simulated time, not wall time"
    assert isinstance(executor.motion, Stop)
    assert np.abs(executor.velocity).max() > 0.05, "it was moving when pre-empted"
    for _ in range(1000):
        executor.tick()
    assert executor.motion.status is MotionStatus.SUCCEEDED
    assert np.abs(executor.velocity).max() < 1e-6
    assert limit_violations(executor.log, executor) == []


def test_wait_counts_simulated_time(executor):
    result = Runner(Wait("pause", duration=0.7), executor).run()
    assert result.status == "SUCCESS"
    assert result.sim_time_s == pytest.approx(0.7, abs=0.03)


def test_a_leaf_without_the_executor_is_a_clear_error():
    with pytest.raises(InputError, match="setup\\(\\) needs executor="):
        ExecutePrimitive("move", primitive=MovementPrimitive(DMP(8), "m")).setup()


class GoalTemplate:
    """A stand-in skill template: tau is a shift of the home pose along HOME_SHIFT."""

    def __init__(self, home):
        self.home = home

    def instantiate(self, tau):
        dmp = DMP(len(self.home), execution_time=1.0, goal=self.home + float(tau[0]) * HOME_SHIFT)
        return MovementPrimitive(dmp, f"shift {float(tau[0]):g}")


def test_a_template_is_instantiated_from_the_blackboard_and_executed(executor):
    set_task_values({"shift": [0.5]})
    pool = {"shift": GoalTemplate(executor.position.copy())}
    root = py_trees.composites.Sequence(
        "templated",
        memory=True,
        children=[
            InstantiateSkillTemplate(
                "instantiate",
                pool=pool,
                template_name="shift",
                namespace="shift",
                remap={"tau": "/task/shift"},
            ),
            ExecutePrimitive("execute", namespace="shift"),
        ],
    )
    result = Runner(root, executor).run()
    assert result.status == "SUCCESS", result.message
    np.testing.assert_allclose(executor.measured_position(), pool["shift"].home + 0.5 * HOME_SHIFT, atol=0.01)
    with pytest.raises(InputError, match="missing: the pool has no template 'wave' \\(has: shift\\)"):
        InstantiateSkillTemplate("missing", pool=pool, template_name="wave", namespace="other")


@pytest.mark.slow
def test_grasp_then_place_recovers_from_a_slip(executor):
    """The box is pulled out of the hand during the carry: the guard fails the placement, the retry
    finds the box not held, grasps it where it now lies and places it."""
    set_task_values({"place": [0.54, -0.41]})
    root = grasp_then_place()
    runner = Runner(root, executor)
    py_trees.trees.setup(root, executor=executor)
    slipped, carry_ticks = False, 0
    status = Status.RUNNING
    while status is Status.RUNNING and executor.time < 60:
        root.tick_once()
        status = root.status
        carry_ticks += any(node.name == "carry" and node.status is Status.RUNNING for node in root.iterate())
        if carry_ticks == 25 and not slipped:  # half a second into the carry, the box in the air
            assert executor.hand.holds("box") and executor.hand.not_held("box") is None
            world = executor.world
            world.data.qvel[world.model.jnt_dofadr[world.model.joint("box").id] + 2] -= 0.1  # sliding down
            mujoco.mj_forward(world.model, world.data)
            assert "pads touch it, but it slips: it moves 0.1" in executor.hand.not_held("box")
            executor.world.place_on("box", "table", 0.50, -0.12)  # out of the hand, back on the table
            slipped = True
        executor.advance(runner.cycles_per_tick)
    assert slipped
    assert status is Status.SUCCESS
    assert root.feedback_message.startswith("succeeded [status: 1 failure")
    box = executor.world.object_pose("box").position
    assert np.linalg.norm(box[:2] - [0.54, -0.41]) < 0.02
    assert limit_violations(executor.log, executor) == []


def test_conditions_report_what_they_see(executor):
    held = Runner(ObjectGrasped("held?", object="box"), executor).run()
    assert held.status == "FAILURE"
    assert held.message == "not holding box: the first and second side's finger pads do not touch it"
    near = ObjectAt("there?", object="box", position=[0.55, -0.08], tolerance=0.01)
    assert Runner(near, executor).run().status == "SUCCESS"
    far = ObjectAt("elsewhere?", object="box", position=[0.45, -0.08])
    result = Runner(far, executor).run()
    assert result.status == "FAILURE"
    assert "box is 10.0 cm from [0.45, -0.08]" in result.message
