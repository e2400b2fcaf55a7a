"""Puck strike on the UR5e: the success rule, deterministic rollouts without MuJoCo warnings, the
demonstration that misses, the scripted baseline and CMA-ES from the demonstration."""

import mujoco
import numpy as np
import pytest
from helpers import (
    assert_bit_identical_in_any_order,
    assert_cmaes_succeeds,
    assert_demonstration_file_is,
    assert_no_mujoco_warnings,
    assert_runs_as_a_gymnasium_environment,
    assert_too_fast_is_penalised_not_simulated,
    closing,
    mujoco_warnings_said,
    registered_leaves,
    replayed_everywhere,
)

from besman import examples
from besman.core.errors import InputError
from besman.tasks import task as registered
from besman.tasks.puck_strike.baseline import (
    calibrated_baseline,
    calibrated_exit_ratio,
    scripted_baseline,
    scripted_strike,
    strike_plan,
)
from besman.tasks.puck_strike.demonstration import (
    FILE,
    imitate,
    load_demonstration,
    save_demonstration,
    synthetic_strike,
)
from besman.tasks.puck_strike.rollouts import (
    BOUNDS,
    FAILURE_REWARD,
    REST_SPEED,
    SUCCESS_RADIUS,
    SUCCESS_REWARD,
    PuckStrikeRollouts,
    judge,
    rest_point,
    reward_of,
)
from besman.tasks.puck_strike.world import (
    PUCK_FRICTION,
    PUCK_HEIGHT,
    PUCK_START,
    TABLE,
    puck_strike_world,
)

DEMO = examples.path("data") / FILE
MIDDLE = np.array([1.55, 0.135])
ON_TABLE = TABLE.height + PUCK_HEIGHT / 2  # the puck's centre's height at rest on the table
TARGETS = np.array([[1.4, -0.05], [1.7, -0.05], [1.55, 0.135], [1.4, 0.32], [1.7, 0.32], [1.62, 0.2]])


@pytest.fixture(scope="module")
def task():
    yield from closing(PuckStrikeRollouts())


@pytest.fixture(scope="module")
def demo_theta(task):
    return imitate(task, *load_demonstration(DEMO))


@pytest.fixture
def warnings_said():
    yield from mujoco_warnings_said()


# -- the success rule ---------------------------------------------------------------------------------------


def test_success_is_the_puck_at_rest_on_the_table_within_the_radius_of_the_target():
    target = np.array([1.5, 0.1])
    still = np.zeros(3)
    cases = [
        ([1.5, 0.1, ON_TABLE], still, True),  # on the target
        ([1.5 + 0.035, 0.1 + 0.035, ON_TABLE], still, True),  # 4.9 cm off
        ([1.5 + SUCCESS_RADIUS + 0.001, 0.1, ON_TABLE], still, False),  # just outside the radius
        ([1.5, 0.1, ON_TABLE], [0.02, 0.0, 0.0], False),  # on the target but still sliding
        ([1.5, 0.1, ON_TABLE], [0.5 * REST_SPEED, 0.0, 0.0], True),  # slower than the rest speed: at rest
        ([1.5, 0.1, 0.02], still, False),  # on the floor under the target (fell off the table)
        ([1.5, 0.1, ON_TABLE + 0.02], still, False),  # in the air
    ]
    for position, velocity, expected in cases:
        success, rest, distance, sliding = judge(position, velocity, target)
        assert success is expected, (position, velocity)
        assert sliding == bool(np.linalg.norm(velocity) >= REST_SPEED)
    # A sliding puck is scored where friction stops it: v^2 / (2 mu g) further along its velocity.
    success, rest, distance, sliding = judge([1.3, 0.1, ON_TABLE], [1.0, 0.0, 0.0], target)
    slide = 1.0 / (2 * PUCK_FRICTION[0] * 9.81)
    assert not success and sliding
    np.testing.assert_allclose(rest, [1.3 + slide, 0.1])
    assert distance == pytest.approx(abs(1.3 + slide - 1.5))
    np.testing.assert_allclose(
        rest_point([0.0, 0.0], [0.0, -2.0]), [0.0, -4.0 / (2 * PUCK_FRICTION[0] * 9.81)]
    )
    assert reward_of(True, 0.01) == pytest.approx(SUCCESS_REWARD - 0.01)
    assert reward_of(False, 0.3) == pytest.approx(-0.3)


def test_the_tasks_judge_reads_the_puck_in_the_world():
    entry = registered("puck-strike")
    values = entry.resolve("ur5e", {"target": [1.6, 0.2]}, None)
    scene = entry.scene("ur5e", values, None)
    world = scene.executor.world
    measured = scene.judge()
    assert not measured.done and measured.measurements["puck"] == list(PUCK_START)
    address = world.model.jnt_qposadr[world.model.joint("puck").id]
    for offset, expected in [((0.0, 0.0), True), ((0.03, -0.03), True), ((0.06, 0.0), False)]:
        world.data.qpos[address : address + 3] = [1.6 + offset[0], 0.2 + offset[1], ON_TABLE]
        mujoco.mj_forward(world.model, world.data)
        measured = scene.judge()
        assert measured.done is expected
        assert measured.measurements["miss_m"] == pytest.approx(np.hypot(*offset), abs=1e-4)


def test_the_world_uses_the_implicit_integrator_and_the_puck_rests_on_the_table(task, warnings_said):
    world = puck_strike_world()
    assert world.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICIT
    assert 0.1 <= world.model.body("puck").mass[0] <= 0.2
    model = task.model
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, task.start_state(), mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.body("puck").xpos, [*PUCK_START, ON_TABLE], atol=5e-4)
    np.testing.assert_allclose(data.qpos[task.arm.qpos_indices], task.start, atol=2e-3)
    touching = {
        frozenset((model.geom(c.geom1).name, model.geom(c.geom2).name)) for c in data.contact[: data.ncon]
    }
    assert touching == {frozenset(("puck", "table"))}  # the bat touches nothing at the start
    assert warnings_said == []


# -- rollouts -----------------------------------------------------------------------------------------------


def test_theta_is_72_dimensional_and_tau_is_a_target_beyond_reach(task):
    assert task.n_params == 72
    assert task.bounds == BOUNDS["ur5e"]
    assert registered("puck-strike").bounds("ur5e").as_dict() == {
        "target_x": [1.4, 1.7],
        "target_y": [-0.05, 0.32],
    }


def test_rewards_are_bit_identical_twice_and_in_another_order(task, demo_theta, warnings_said):
    rng = np.random.default_rng(5)
    thetas = demo_theta + 0.1 * rng.normal(size=(5, task.n_params))
    taus = TARGETS[:5]
    first = assert_bit_identical_in_any_order(task, thetas, taus)
    assert any(d.moved for d in first.details)
    assert warnings_said == []


def test_no_mujoco_warnings_in_vigorous_rollouts(task, demo_theta, warnings_said):
    rng = np.random.default_rng(11)
    thetas = demo_theta + 0.5 * rng.normal(size=(8, task.n_params))
    assert_no_mujoco_warnings(task, thetas, np.resize(TARGETS, (8, 2)), warnings_said)


def test_infeasible_references_are_penalised_not_simulated(task):
    assert_too_fast_is_penalised_not_simulated(task, MIDDLE, FAILURE_REWARD)


def test_holding_still_leaves_the_puck_where_it_is(task):
    result = task.evaluate(np.repeat(task.still_theta()[None], 2, 0), TARGETS[:2])
    assert [d.success or d.moved for d in result.details] == [False, False]
    expected = [-np.linalg.norm(target - PUCK_START) for target in TARGETS[:2]]
    assert result.rewards.tolist() == pytest.approx(expected, abs=1e-3)


@pytest.mark.parametrize(
    ("tau", "message"),
    [
        ([1.0, 0.1], r"tau target_x = 1 is outside the task's bounds \[1\.4, 1\.7\]"),
        ([1.5, 0.9], r"tau target_y = 0\.9 is outside the task's bounds \[-0\.05, 0\.32\]"),
        ([1.5], r"tau must have 2 entries \(target_x, target_y\)"),
        ([np.nan, 0.1], r"tau contains NaN"),
    ],
)
def test_a_bad_tau_is_refused_with_a_clear_error(task, tau, message):
    with pytest.raises(InputError, match=message):
        task.evaluate(task.still_theta(), tau)


def test_a_bad_theta_or_task_value_is_refused(task):
    with pytest.raises(InputError, match="theta must have 72 entries"):
        task.evaluate(np.zeros(5), MIDDLE)
    with pytest.raises(InputError, match="target_x"):
        registered("puck-strike").resolve("ur5e", {"target": [0.6, 0.1]}, None)
    with pytest.raises(InputError, match="puck-strike runs on ur5e"):
        PuckStrikeRollouts(robot="pa10")


# -- the demonstration and the baseline ---------------------------------------------------------------------


def test_the_demonstration_file_is_the_scripts_synthetic_strike(task, tmp_path):
    assert_demonstration_file_is(
        DEMO, synthetic_strike, task, tmp_path, load_demonstration, save_demonstration
    )


def test_the_demonstration_alone_misses_but_comes_close(task, demo_theta):
    n = len(TARGETS)
    imitated = task.evaluate(np.repeat(demo_theta[None], n, 0), TARGETS)
    steps = np.arange(task.n_steps + 1) * task.timestep
    replayed = replayed_everywhere(task, *synthetic_strike(task.start, steps)[1:], TARGETS)
    for result in (imitated, replayed):
        assert not any(d.success for d in result.details)
        assert all(d.moved and d.failure is None for d in result.details)
        middle = result.details[2]  # the target the demonstration aimed at: missed by about 21 cm
        assert 0.15 < middle.distance < 0.3
        assert middle.rest[0] > 1.26  # beyond the bat's reach
        # It stops short of the whole box, by more than the success radius: it succeeds for no target.
        low, high = np.asarray(BOUNDS["ur5e"].low), np.asarray(BOUNDS["ur5e"].high)
        nearest = np.clip(middle.rest, low, high)
        assert np.linalg.norm(np.asarray(middle.rest) - nearest) > SUCCESS_RADIUS


def test_the_scripted_strike_keeps_the_limits_and_aims_along_the_line(task):
    target = np.array([1.6, 0.3])
    poses, velocity = strike_plan(task, target)
    q, _ = scripted_strike(task, target)
    assert task.check_references(q[None])[0] == [None]
    model, data = task.model, mujoco.MjData(task.model)
    data.qpos[task.arm.qpos_indices] = poses[1]
    mujoco.mj_kinematics(model, data)
    head = data.site("head").xpos
    line = (target - PUCK_START) / np.linalg.norm(target - PUCK_START)
    behind = np.asarray(PUCK_START) - head[:2]
    assert line[0] * behind[1] - line[1] * behind[0] == pytest.approx(0.0, abs=1e-4)  # on the line
    assert behind @ line > 0  # behind the puck
    assert head[2] == pytest.approx(ON_TABLE, abs=1e-3)
    assert np.abs(velocity).max() <= task.speed_limits.max()


@pytest.mark.slow
def test_the_scripted_baseline_succeeds_rarely_and_a_calibrated_one_often(task):
    taus = registered("puck-strike").spread("ur5e", 50, 1)
    result = scripted_baseline(task, taus)
    assert np.mean([d.success for d in result.details]) <= 0.2  # measured: 0 of 50, all overshoot
    ratio = calibrated_exit_ratio(task, MIDDLE)
    assert ratio > 1.05  # the puck leaves faster than the blade: what the textbook plan leaves out
    calibrated = calibrated_baseline(task, taus[:5])
    assert np.mean([d.success for d in calibrated.details]) >= 0.8  # measured: 50 of 50


@pytest.mark.slow
def test_cmaes_from_the_demonstration_hits_the_target(task, demo_theta):
    assert_cmaes_succeeds(task, demo_theta, MIDDLE, sigma=0.1, budget=100)


@pytest.mark.slow
def test_the_task_runs_as_a_gymnasium_environment():
    assert_runs_as_a_gymnasium_environment("puck-strike")


# -- the tree and the demo ----------------------------------------------------------------------------------

POOL = examples.path("pools") / "puck_strike"
TREE = examples.path("trees") / "puck_strike.yaml"


@pytest.fixture(scope="module")
def leaves():
    from besman.tasks.puck_strike import leaves as module

    return registered_leaves(module)


@pytest.fixture(scope="module")
def demo_pool(task, demo_theta, tmp_path_factory):
    """A pool with a plumbing template: the imitated demonstration's strike at four targets, varied a
    little (it misses everywhere)."""
    from besman.skills import MovementPrimitive, SkillTemplate
    from besman.skills.pool import SkillTemplatePool

    taus = TARGETS[[0, 1, 3, 4]]
    thetas = demo_theta + 0.01 * np.random.default_rng(0).normal(size=(len(taus), task.n_params))
    prototype = MovementPrimitive(task.dmp, "puck_strike", robot="ur5e", group="arm")
    template = SkillTemplate(
        "puck_strike",
        prototype,
        taus,
        thetas,
        task.bounds,
        prior_spread=0.1,
        task="puck-strike",
        provenance={"made by": "tests/test_puck_strike.py (plumbing: the demonstration's strike)"},
    )
    pool = SkillTemplatePool(tmp_path_factory.mktemp("pool") / "puck_strike")
    pool.add(template)
    return pool


def test_the_leaves_are_named_under_the_node_type_entry_point_and_the_task_has_a_demo(capsys):
    import tomllib

    from besman.cli import main

    pyproject = tomllib.loads((examples.path("pools").parents[1] / "pyproject.toml").read_text())
    points = pyproject["project"]["entry-points"]["besman.node_types"]
    assert points["puck_strike"] == "besman.tasks.puck_strike.leaves"
    assert (
        registered("puck-strike").tree == "puck_strike.yaml" and registered("puck-strike").tree_path == TREE
    )
    assert main(["demo", "--list"]) == 0
    assert "puck-strike: the UR5e strikes a puck" in capsys.readouterr().out


def test_the_run_with_the_tree_is_the_rollouts_outcome(leaves, demo_pool, task):
    """The tree aims (the template, refined in simulation) and strikes in the run's world: the run's outcome
    is the rollouts' for the strike it chose, by the task's rule, to the bit."""
    import py_trees

    from besman.tasks.running import prepare

    prepared = prepare("puck-strike", TREE, pool=demo_pool.directory, values={"target": MIDDLE})
    summary = prepared.judge(prepared.runner.run())
    strike = py_trees.blackboard.Blackboard.get("/strike/strike")
    expected = task.evaluate(strike, MIDDLE).details[0]
    assert summary.success is expected.success
    assert summary.status == ("SUCCESS" if expected.success else "FAILURE")
    rest = np.round(expected.rest, 3).tolist()
    strike = prepared.runner.root.children[1]
    assert (
        strike.feedback_message
        == f"the puck came to rest at {rest}, {expected.distance:.3f} m from the target"
    )
    np.testing.assert_array_equal(
        py_trees.blackboard.Blackboard.get("/strike/puck"), np.round(expected.rest, 3)
    )
    # The task's rule on the world as the run left it is the rollouts' rule on their last step.
    assert summary.measurements["miss_m"] == pytest.approx(
        np.linalg.norm(np.asarray(expected.rest) - MIDDLE), abs=1e-4
    )
    aim = prepared.runner.root.children[0]
    # The demonstration's strike misses; the refinement (the tree's budget) finds a hit or says it did not.
    assert aim.feedback_message.startswith("template at (1.550, 0.135) m: misses in simulation; after ")
    outcome = "hits" if expected.success else "still misses"
    assert f"simulated strikes: {outcome} (the refinement's" in aim.feedback_message


def test_a_target_outside_the_templates_box_fails_the_aim_by_name(leaves, demo_pool):
    import py_trees
    from py_trees.common import Status

    from besman.trees.blackboard import set_task_values

    scene = registered("puck-strike").scene("ur5e", {"target": MIDDLE}, None)
    py_trees.blackboard.Blackboard.clear()
    set_task_values({"target": [1.0, 0.1]})
    aim = leaves.AimStrike("aim", pool=demo_pool, remap={"target": "/task/target"})
    aim.setup(executor=scene.executor)
    aim.tick_once()
    assert aim.status is Status.FAILURE
    assert aim.feedback_message == (
        "target [1.0, 0.1]: tau target_x = 1 is outside the task's bounds [1.4, 1.7]"
    )
    with pytest.raises(InputError, match="no template 'other'"):
        leaves.AimStrike("aim", pool=demo_pool, template="other")


def test_the_leaves_need_the_open_loop_executor(leaves):
    from besman.sim import Executor

    scene = registered("ball-in-cup").scene("ur5e", {"string": [0.4]}, None)
    strike = leaves.Strike("strike")
    with pytest.raises(InputError, match="strike: Strike needs the open-loop executor"):
        strike.setup(executor=Executor(scene.executor.world))


def test_the_pool_holds_the_template_over_the_target():
    from besman.skills.pool import SkillTemplatePool

    pool = SkillTemplatePool(POOL)
    assert list(pool) == ["puck_strike"] and pool.problems() == {}
    template = pool["puck_strike"]
    assert template.task == "puck-strike" and template.box == BOUNDS["ur5e"]
    assert template.thetas.shape[1] == 72 and template.prototype.robot == "ur5e"


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0])
def test_the_demo_strikes_the_puck_to_the_target_by_the_tasks_rule(leaves, task, seed, capsys):
    import py_trees

    from besman.cli import main
    from besman.tasks.running import run_demo

    summary = run_demo("puck-strike", seed=seed)
    assert summary.success and summary.status == "SUCCESS"
    measured = summary.measurements
    assert measured["miss_m"] < SUCCESS_RADIUS and measured["puck_speed_m_s"] < REST_SPEED
    target = np.array(measured["target"])
    BOUNDS["ur5e"].check(target)  # inside the box
    # The rollouts say the same of the strike the tree chose.
    expected = task.evaluate(py_trees.blackboard.Blackboard.get("/strike/strike"), target).details[0]
    assert expected.success and list(measured["puck"]) == np.round(expected.rest, 3).tolist()
    assert main(["demo", "puck-strike", "--seed", str(seed)]) == 0
    assert "SUCCESS: the puck is at rest at" in capsys.readouterr().out


@pytest.mark.slow
def test_the_demo_runs_watched_in_the_browser(leaves):
    """--view: the run goes with the viewer serving the page and succeeds as without."""
    import argparse
    import urllib.request

    from besman.commands.viewing import run_task

    args = argparse.Namespace(
        view=True, host="127.0.0.1", port=0, allow_origin=[], speed=1000.0, seed=1, robot=None
    )
    entry = registered("puck-strike")
    summary, viewers = run_task(args, task=entry, values={}, log=None, demo="puck-strike")
    try:
        assert summary.success and summary.demo == "puck-strike" and summary.seed == 1
        assert set(summary.measurements) == set(entry.measurements)
        with urllib.request.urlopen(viewers[0].url, timeout=10) as page:
            assert page.status == 200
    finally:
        viewers[0].close()
