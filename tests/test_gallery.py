"""The demos (a task run with its default tree) and what they needed: loops over blackboard lists, object
names from the blackboard, arms in lockstep, planned moves, the arms' distance guard, throws executed in a
tree, disturbances."""

import argparse
import json
import urllib.request
from dataclasses import replace
from pathlib import Path

import numpy as np
import py_trees
import pytest
from helpers import run_cli
from py_trees.common import Status

from besman.core.errors import InputError
from besman.sim import Executor, tabletop_world
from besman.sim.executor import limit_violations
from besman.sim.world import GraspableObject
from besman.skills.pool import SkillTemplatePool
from besman.tasks import TASKS, task
from besman.tasks.running import run_demo
from besman.tasks.throwing.executor import ThrowingExecutor
from besman.tasks.throwing.rollouts import ThrowingRollouts
from besman.trees.blackboard import set_task_values
from besman.trees.conditions import ArmsApart, ObjectAt
from besman.trees.guards import KeepApart
from besman.trees.leaves import ExecutePrimitive
from besman.trees.loops import ForEach
from besman.trees.manipulation import PerceiveObject, PlanGrasp, PlanMove
from besman.trees.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
THROWING_POOL = ROOT / "examples" / "pools" / "throwing"
DEMOS = [name for name, entry in TASKS.items() if entry.tree is not None]


class _Seen(py_trees.behaviour.Behaviour):
    """Records the blackboard's /loop/object at each run; fails on "bad"."""

    def __init__(self):
        super().__init__("seen")
        self.seen = []
        self.client = self.attach_blackboard_client("seen")
        self.client.register_key("/loop/object", access=py_trees.common.Access.READ)

    def update(self):
        self.seen.append(self.client.get("/loop/object"))
        return Status.FAILURE if self.seen[-1] == "bad" else Status.SUCCESS


def _loop(items):
    py_trees.blackboard.Blackboard.clear()
    set_task_values({"objects": items})
    child = _Seen()
    root = ForEach("each", child, items="/task/objects", namespace="loop")
    for _ in range(10):
        root.tick_once()
        if root.status is not Status.RUNNING:
            break
    return root, child.seen


def test_for_each_runs_its_child_once_per_item_in_order():
    root, seen = _loop([{"object": "a"}, {"object": "b"}, {"object": "c"}])
    assert root.status is Status.SUCCESS and seen == ["a", "b", "c"]
    assert root.feedback_message == "all 3 items done"


def test_for_each_stops_at_the_first_failure_and_refuses_what_is_not_a_list():
    root, seen = _loop([{"object": "a"}, {"object": "bad"}, {"object": "c"}])
    assert root.status is Status.FAILURE and seen == ["a", "bad"]
    assert root.feedback_message.startswith("item 2 of 3 failed")
    root, seen = _loop([])
    assert root.status is Status.SUCCESS and seen == []
    py_trees.blackboard.Blackboard.clear()
    set_task_values({"objects": "red"})
    root = ForEach("each", _Seen(), items="/task/objects", namespace="loop")
    root.tick_once()
    assert root.status is Status.FAILURE and "must hold a list of mappings" in root.feedback_message


def test_a_leaf_reads_its_object_from_the_blackboard():
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world((GraspableObject("red"), GraspableObject("blue")))
    world.place_on("blue", "table", 0.5, -0.1)
    set_task_values({"which": "blue"})
    check = ObjectAt("there?", object="/task/which", position=[0.5, -0.1])
    assert Runner(check, Executor(world)).run().status == "SUCCESS"
    set_task_values({"which": "red"})
    assert Runner(check, Executor(world)).run().status == "FAILURE"


def test_two_arms_move_in_lockstep_and_the_guard_sees_their_distance():
    """The left arm, driven with the right arm by one executor, moves while the right one does: one physics,
    both arms commanded every cycle within their limits, both at their goals; the waist they share is held."""
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    right = Executor(world, ("right", "left"))
    left = right.arm_executor("left")
    assert right.arm.groups == ("right_arm",) and left.arm.groups == ("left_arm",)
    up = np.array([0.05, 0.0, 0.1])  # both hands 10 cm up and 5 cm forward from home, as they are turned
    goal_left = left.arm.site_pose(left.position).position + up
    goal_right = right.arm.site_pose(right.position).position + up
    root = py_trees.composites.Sequence(
        "both",
        memory=True,
        children=[
            PlanMove("plan left", position=goal_left, namespace="left", arm="left"),
            PlanMove("plan right", position=goal_right, namespace="right"),
            py_trees.composites.Parallel(
                "together",
                py_trees.common.ParallelPolicy.SuccessOnAll(),
                children=[
                    ExecutePrimitive(
                        "left moves", namespace="left", remap={"primitive": "/left/motion"}, arm="left"
                    ),
                    ExecutePrimitive("right moves", namespace="right", remap={"primitive": "/right/motion"}),
                ],
            ),
            ArmsApart("apart?", other="left", margin=0.05),
        ],
    )
    result = Runner(root, right).run()
    assert result.status == "SUCCESS", result.message
    assert np.allclose(left.arm.site_pose(left.measured_position()).position, goal_left, atol=0.01)
    assert np.allclose(right.arm.site_pose(right.measured_position()).position, goal_right, atol=0.01)
    assert len(left.log) == len(right.log) and np.array_equal(left.log.times, right.log.times)
    assert limit_violations(left.log, left) == [] and limit_violations(right.log, right) == []
    far = ArmsApart("far?", other="left", margin=2.0)
    assert Runner(far, right).run().status == "FAILURE" and "apart (less than 200 cm)" in far.feedback_message
    with pytest.raises(ValueError, match="no arm 'third'"):
        ExecutePrimitive("x", arm="third").setup(executor=right)


def test_a_throw_in_a_tree_lands_where_the_tasks_rollout_lands():
    task = ThrowingRollouts(variant="paper")
    theta = SkillTemplatePool(THROWING_POOL)["throw"].distribution(np.array([-5.0, -2.0]))[0]
    expected = task.evaluate(theta[None], np.array([[-5.0, -2.0]])).details[0].landing
    executor = ThrowingExecutor(task)
    executor.wind_up()
    flight = executor.start_throw(theta)
    while executor.advance(10).value == "running":
        pass
    np.testing.assert_allclose(flight.landing, expected, atol=1e-9)
    with pytest.raises(ValueError, match="96 parameters"):
        executor.start_throw(theta[:5])


@pytest.mark.parametrize("name", DEMOS)
def test_every_demo_tree_passes_tree_check(capsys, name):
    code, out, _ = run_cli(capsys, "tree", "check", str(task(name).tree_path))
    assert code == 0 and out.strip().endswith(": ok")


def test_demo_list_and_bad_demo_input(capsys):
    code, out, _ = run_cli(capsys, "demo", "--list")
    assert code == 0 and [line.split(":")[0] for line in out.splitlines()] == DEMOS
    code, _, err = run_cli(capsys, "demo", "juggle")
    assert code == 2 and f"unknown task 'juggle'; tasks: {', '.join(TASKS)}" in err
    code, _, err = run_cli(capsys, "demo", "throwing-hardware")
    no_demo = f"task throwing-hardware has no demo (no default tree); demos: {', '.join(DEMOS)}"
    assert code == 2 and no_demo in err
    code, _, err = run_cli(capsys, "demo", "sort", "--set", "target=1,2")
    assert code == 2 and "--set target: not a value of task sort; its values: red, green, blue" in err
    code, _, err = run_cli(capsys, "demo", "throw", "--set", "target=0,0")
    assert code == 2 and "tau target_x = 0 is outside the task's bounds" in err


def test_throw_demo_from_the_command_line(capsys):
    """The demo's earlier name still runs it; a task value set on the command line is its target."""
    code, out, _ = run_cli(capsys, "demo", "throw", "--set=target=-3.2,-3.4", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["success"] and summary["measurements"]["miss_m"] <= 0.5
    assert summary["measurements"]["target"] == [-3.2, -3.4] and summary["robot"] == "pa10"
    assert summary["task"] == summary["demo"] == "throwing"


def test_handover_and_sort_demos_from_the_command_line(capsys):
    code, out, _ = run_cli(capsys, "demo", "handover", "--seed", "3")
    assert code == 0 and "SUCCESS: placement error" in out and "touched at 0 ticks" in out
    code, out, _ = run_cli(capsys, "demo", "sort", "--seed", "3")
    assert code == 0 and "SUCCESS: placement errors red" in out and "slipped and was grasped again" in out


def test_sort_demo_is_the_same_run_for_the_same_seed():
    first, second = run_demo("sort", 5), run_demo("sort", 5)
    assert replace(first, wall_time_s=0) == replace(second, wall_time_s=0)
    assert first.success and first.measurements["slipped"] is not None


@pytest.mark.parametrize("name", ["sort", "handover", "throwing"])  # pick-place: tests/test_viewer.py
def test_a_demo_runs_watched_in_the_browser(name):
    """--view: the run goes at --speed with the viewer serving the page; the run succeeds as without."""
    from besman.commands.viewing import run_task

    args = argparse.Namespace(
        view=True, host="127.0.0.1", port=0, allow_origin=[], speed=1000.0, seed=2, robot=None
    )
    summary, viewers = run_task(args, task=task(name), values={}, log=None, demo=name)
    try:
        assert summary.success and summary.demo == name and summary.seed == 2
        assert set(summary.measurements) == set(task(name).measurements)  # as the docs list them
        with urllib.request.urlopen(viewers[0].url, timeout=10) as page:
            assert page.status == 200
    finally:
        viewers[0].close()


def test_plan_move_goes_to_the_pose_its_goal_role_holds():
    """A pose that depends on the robot comes from the blackboard (remap: {goal: KEY}): the planned move
    ends there; a malformed pose fails the leaf with the key in the message; exactly one target."""
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    executor = Executor(world)
    set_task_values({"ready": {"position": [0.5, -0.25, 0.95], "yaw": -0.8}, "broken": {"where": 1}})
    plan = PlanMove("plan", namespace="m", remap={"goal": "/task/ready"})
    move = ExecutePrimitive("move", namespace="m", remap={"primitive": "/m/motion"})
    root = py_trees.composites.Sequence("go", memory=True, children=[plan, move])
    assert Runner(root, executor).run().status == "SUCCESS"
    tcp = world.data.site(executor.arm.site)
    np.testing.assert_allclose(tcp.xpos, [0.5, -0.25, 0.95], atol=0.01)
    closing = tcp.xmat.reshape(3, 3)[:, 1]  # the hand turned by the yaw (or half a turn: the same grasp)
    assert (np.arctan2(closing[1], closing[0]) + 0.8 + 0.05) % np.pi < 0.1
    broken = PlanMove("broken", namespace="b", remap={"goal": "/task/broken"})
    result = Runner(broken, Executor(tabletop_world())).run()
    assert result.status == "FAILURE" and "/task/broken must hold {'position'" in result.message
    with pytest.raises(InputError, match="give exactly one of position, rise, home"):
        PlanMove("both", position=[0.5, 0, 1], remap={"goal": "/task/ready"})


def test_plan_grasp_takes_its_offset_from_the_key_its_offset_role_names():
    """Where a hand holds an object may be the robot's (the handover's /task/left_grip): the grasp is
    planned that far from the object's centre; a malformed offset fails the leaf naming the key."""

    def planned(key: str):
        py_trees.blackboard.Blackboard.clear()
        set_task_values({"grip": [0.0, 0.02], "broken": [0.02]})
        executor = Executor(tabletop_world())
        see = PerceiveObject("see", object="box", namespace="g")
        plan = PlanGrasp("plan", object="box", namespace="g", remap={"offset": key})
        result = Runner(py_trees.composites.Sequence("g", memory=True, children=[see, plan]), executor).run()
        return result, executor

    result, executor = planned("/task/grip")
    assert result.status == "SUCCESS", result.message
    descend = py_trees.blackboard.Blackboard.get("/g/descend")
    grasp = executor.arm.site_pose(descend.dmp.goal).position
    box = executor.world.object_pose("box").position
    np.testing.assert_allclose(grasp[:2] - box[:2], [0.0, 0.02], atol=1e-3)
    result, _ = planned("/task/broken")
    assert result.status == "FAILURE"
    assert "/task/broken must hold x, y in m (the grasp's offset), got [0.02]" in result.message
    with pytest.raises(InputError, match="give offset or remap it to a key, not both"):
        PlanGrasp("both", object="box", offset=[0.0, 0.02], remap={"offset": "/task/grip"})


def test_keep_apart_stops_its_subtree_when_the_arms_come_closer_than_its_margin():
    """With a margin wider than the arms' distance the guard fails at once and its child never moves; with
    a small one it is what its child is."""
    py_trees.blackboard.Blackboard.clear()
    world = tabletop_world()
    right = Executor(world, ("right", "left"))
    home = right.position.copy()

    def guarded(margin):
        moves = py_trees.composites.Sequence(
            "moves",
            memory=True,
            children=[
                PlanMove("plan", rise=0.05, namespace="m"),
                ExecutePrimitive("rise", namespace="m", remap={"primitive": "/m/motion"}),
            ],
        )
        return KeepApart("apart", moves, other="left", margin=margin)

    wide = guarded(1.5)
    result = Runner(wide, right).run()
    assert result.status == "FAILURE" and "apart (less than 150 cm)" in result.message
    assert np.array_equal(right.position, home)
    narrow = guarded(0.05)
    assert Runner(narrow, right).run().status == "SUCCESS"
    with pytest.raises(ValueError, match="other must name another arm"):
        KeepApart("self", py_trees.behaviours.Success("ok"), other="right").setup(executor=right)


@pytest.mark.parametrize("name", ["sort", "handover", "throwing"])
def test_a_demos_log_replays_its_own_scene(tmp_path, name):
    """The replay rebuilds the demo's world from the log's header and poses every arm, hand and free body
    (the sort's boxes, the handover's left arm, the PA-10's ball) as the run left them."""
    from besman.tasks.running import executor_of
    from besman.trees.watching import Replay

    log = tmp_path / "run.jsonl"
    assert run_demo(name, 4, log=log).success
    replay = Replay(log, executor_of, {"port": 0})
    try:
        last = replay.records[-1]["robot"]
        replay.show(len(replay.records) - 1)
        qpos = replay.world.data.qpos
        np.testing.assert_allclose(qpos[replay._arm], last["joints"], atol=1e-9)
        for body, pose in last["objects"].items():
            address = replay._objects[body]
            np.testing.assert_allclose(qpos[address : address + 7], pose, atol=1e-9)
        assert len(last["objects"]) == {"sort": 3, "handover": 1, "throwing": 1}[name]
        if name == "handover":
            joints, _ = replay._arms["left"]
            np.testing.assert_allclose(qpos[joints], last["arms"]["left"]["joints"], atol=1e-9)
    finally:
        replay.close()
