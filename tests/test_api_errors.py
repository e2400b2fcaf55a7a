"""The Python API checks its arguments where it is called: a wrong type, a NaN, a count or seed out of
range, an unknown keyword or option key raises besman's own error (a
:class:`~besman.core.errors.BesmanError`) whose message names the function, the parameter and the value
received, before any work."""

import inspect
import math
from pathlib import Path

import numpy as np
import pytest

import besman.learning as learning
import besman.robots as robots
import besman.sim as sim
import besman.skills as skills
import besman.tasks.throwing.rollouts as throwing
import besman.trees as trees
from besman.core.errors import ArgumentTypeError, BesmanError, InputError, UnknownNameError
from besman.tasks.pick_place.episode import PickPlaceRollouts
from besman.tasks.running import prepare, run, run_demo

ROOT = Path(__file__).resolve().parents[1]
RECORDING = ROOT / "examples" / "data" / "subject1_run1.tsv"
TREE = ROOT / "examples" / "trees" / "grasp_then_place.yaml"


@pytest.fixture(scope="module")
def made():
    """What the cases call methods of, made once."""
    template = skills.SkillTemplatePool(ROOT / "examples" / "pools" / "pick_place_aila")["reach"]
    world = sim.tabletop_world()
    return {
        "pa10": robots.load("pa10"),
        "world": world,
        "arm": sim.Arm(world),
        "recording": learning.load(RECORDING),
        "template": template,
        "tau": (np.asarray(template.box.low) + np.asarray(template.box.high)) / 2,
        "warm": learning.WarmStart(np.zeros(3), 1.0),
    }


def _pool():
    return skills.SkillTemplatePool(Path.cwd() / "pool")  # each test runs in its own folder


# (what is called, the call, words the message must hold: the function, the parameter and the value).
CASES = [
    # The four cases.
    ("robots.load(123)", lambda m: robots.load(123), ["robots.load", "name", "123 (int)"]),
    ("run_demo(seed=-1)", lambda m: run_demo("sort", seed=-1), ["run_demo", "seed", "0..4294967295", "-1"]),
    (
        "run_demo with an unknown task value",
        lambda m: run_demo("pick-place", 1, values={"objekt": (0.5, -0.1)}),
        ["--set objekt", "not a value of task pick-place", "its values: object, place"],
    ),
    (
        "run_demo(robt=..)",
        lambda m: run_demo("sort", 1, robt="aila"),
        ["run_demo", "'robt'", "did you mean 'robot'"],
    ),
    ("run_demo('nosuch')", lambda m: run_demo("nosuch"), ["unknown task 'nosuch'", "pick-place"]),
    ("pool.add('x')", lambda m: _pool().add("x"), ["SkillTemplatePool.add", "template", "'x' (str)"]),
    # Unknown keywords.
    ("run_demo(sede=1)", lambda m: run_demo("sort", sede=1), ["run_demo", "'sede'", "did you mean 'seed'"]),
    ("segment(sede=1)", lambda m: learning.segment(m["recording"], sede=1), ["segment", "'sede'", "'seed'"]),
    ("DMPSettings(n_weight=5)", lambda m: skills.DMPSettings(n_weight=5), ["DMPSettings", "'n_weights'"]),
    (
        "ThrowingRollouts(durration=1)",
        lambda m: throwing.ThrowingRollouts(durration=1.0),
        ["'durration'", "'duration'"],
    ),
    (
        "learning.load(unit=..)",
        lambda m: learning.load(RECORDING, unit="mm"),
        ["load_qualisys_tsv", "'unit'"],
    ),
    # robots
    ("robots.describe(1.5)", lambda m: robots.describe(1.5), ["robots.describe", "name", "1.5 (float)"]),
    ("solve_ik('x', ...)", lambda m: robots.solve_ik("x", "arm", [0, 0, 1]), ["solve_ik", "robot", "'x'"]),
    ("solve_ik(seed=-1)", lambda m: robots.solve_ik(m["pa10"], "arm", [0, 0, 1], seed=-1), ["seed", "-1"]),
    ("solve_ik(position='abc')", lambda m: robots.solve_ik(m["pa10"], "arm", "abc"), ["position", "'abc'"]),
    (
        "forward_kinematics(site=5)",
        lambda m: robots.forward_kinematics(m["pa10"], np.zeros(m["pa10"].model.nq), 5),
        ["forward_kinematics", "site", "5 (int)"],
    ),
    ("build_spec('aila')", lambda m: robots.build_spec("aila"), ["build_spec", "description", "'aila'"]),
    ("Robot.make_data(5)", lambda m: m["pa10"].make_data(5), ["keyframe", "5 (int)"]),
    # skills
    ("MovementPrimitive(name=5)", lambda m: skills.MovementPrimitive(skills.DMP(2), 5), ["name", "5 (int)"]),
    ("MovementPrimitive.load(5)", lambda m: skills.MovementPrimitive.load(5), ["load", "path", "5 (int)"]),
    ("SkillTemplatePool(5)", lambda m: skills.SkillTemplatePool(5), ["SkillTemplatePool", "directory", "5"]),
    ("template.sample(count=-1)", lambda m: m["template"].sample(m["tau"], -1, 0), ["count", "-1"]),
    ("template.sample(seed=1.5)", lambda m: m["template"].sample(m["tau"], 2, 1.5), ["seed", "1.5 (float)"]),
    ("template.predict(NaN)", lambda m: m["template"].predict(m["tau"] * np.nan), ["tau", "NaN", "nan"]),
    ("TaskBounds(high=NaN)", lambda m: skills.TaskBounds(("a",), (0.0,), (math.nan,)), ["high", "nan"]),
    ("DMP(2, dt=NaN)", lambda m: skills.DMP(2, dt=math.nan), ["dt", "nan"]),
    # sim
    (
        "tabletop_world(robot=5)",
        lambda m: sim.tabletop_world(robot=5),
        ["tabletop_world", "robot", "5 (int)"],
    ),
    ("Executor('x')", lambda m: sim.Executor("x"), ["Executor", "world", "'x' (str)"]),
    ("ExecutorConfig(NaN)", lambda m: sim.ExecutorConfig(control_period=math.nan), ["control_period", "nan"]),
    ("Executor.advance(-1)", lambda m: sim.Executor(m["world"]).advance(-1), ["advance", "cycles", "-1"]),
    ("World.place_on(x='a')", lambda m: m["world"].place_on("box", "table", "a", 0.0), ["x", "'a' (str)"]),
    ("Arm.site_pose(shape)", lambda m: m["arm"].site_pose(np.zeros(2)), ["joint_positions", "(2,)"]),
    ("ThrowingConfig(n_weights='a')", lambda m: throwing.ThrowingConfig(n_weights="a"), ["n_weights", "'a'"]),
    (
        "PickPlaceRollouts('x')",
        lambda m: PickPlaceRollouts("x"),
        ["PickPlaceRollouts", "config", "'x' (str)"],
    ),
    # learning
    ("learning.load(5)", lambda m: learning.load(5), ["learning.load", "path", "5 (int)"]),
    ("segment('x')", lambda m: learning.segment("x"), ["segment", "demo", "'x' (str)"]),
    ("segment(rate=NaN)", lambda m: learning.segment(m["recording"], rate=math.nan), ["rate", "nan"]),
    ("smooth(config={})", lambda m: learning.smooth(m["recording"], "Hand top", {}), ["config", "{} (dict)"]),
    ("resample('a', 'b', 1)", lambda m: learning.resample("a", "b", 1.0), ["resample", "times", "'a'"]),
    ("cluster(n_blocks=-1)", lambda m: learning.cluster([], -1), ["cluster", "n_blocks", "-1"]),
    ("imitate('x')", lambda m: learning.imitate("x", name="a"), ["imitate", "segments", "'x' (str)"]),
    ("CMAES(seed=-1)", lambda m: learning.CMAES(m["warm"], seed=-1), ["CMAES", "seed", "-1"]),
    ("XNES(population_size=0)", lambda m: learning.XNES(m["warm"], seed=0, population_size=0), ["0"]),
    (
        "policy_search(budget='a')",
        lambda m: learning.policy_search(lambda t, o: -np.sum(t**2, 1), [], budget="a"),
        ["policy_search", "budget", "'a' (str)"],
    ),
    ("SmoothingConfig(max_gap=-1)", lambda m: learning.SmoothingConfig(max_gap=-1), ["max_gap", "-1"]),
    ("grouping_accuracy(5, 6)", lambda m: learning.grouping_accuracy(5, 6), ["true_labels", "5 (int)"]),
    # trees
    ("load_tree(5)", lambda m: trees.load_tree(5), ["load_tree", "path", "5 (int)"]),
    ("loads_tree(5)", lambda m: trees.loads_tree(5), ["loads_tree", "text", "5 (int)"]),
    ("dump_tree(5)", lambda m: trees.dump_tree(5), ["dump_tree", "root", "5 (int)"]),
    # tasks
    ("prepare(seed='a')", lambda m: prepare(tree=TREE, seed="a"), ["prepare", "seed", "'a' (str)"]),
    ("run(values='x')", lambda m: run(tree=TREE, values="x"), ["run", "values", "'x'"]),
    ("run(task=5)", lambda m: run(5), ["run", "task", "5 (int)"]),
    ("Wait(5)", lambda m: trees.Wait(5, duration=1.0), ["Wait", "name", "5 (int)"]),
    ("PlanMove(position NaN)", lambda m: trees.PlanMove("m", position=(math.nan, 0, 0)), ["position", "nan"]),
    ("grasp(attempts=0)", lambda m: trees.grasp(attempts=0), ["grasp", "attempts", "0"]),
    (
        "KeepApart(child='x')",
        lambda m: trees.KeepApart("k", "x", other="left"),
        ["KeepApart", "child", "'x'"],
    ),
    ("Runner(executor='x')", lambda m: trees.Runner(trees.Wait("w", duration=1.0), "x"), ["executor", "'x'"]),
]


@pytest.mark.parametrize(("call", "words"), [case[1:] for case in CASES], ids=[case[0] for case in CASES])
def test_a_bad_argument_raises_a_besman_error_naming_the_parameter_and_the_value(made, call, words):
    with pytest.raises(BesmanError) as raised:
        call(made)
    message = str(raised.value)
    assert all(word in message for word in words), message


def test_the_errors_are_the_builtins_callers_expect():
    """A wrong type is also a TypeError, a wrong value a ValueError, an unknown key a KeyError: code that
    caught Python's own errors keeps working."""
    with pytest.raises(TypeError):
        robots.load(123)
    with pytest.raises(TypeError):
        run_demo("sort", sede=1)
    with pytest.raises(ValueError, match="seed"):
        run_demo("sort", seed=-1)
    with pytest.raises(KeyError):
        run_demo("nosuch")  # an unknown task
    assert issubclass(ArgumentTypeError, InputError) and issubclass(UnknownNameError, InputError)
    assert issubclass(ArgumentTypeError, ValueError)  # every besman error is a ValueError


def test_checked_functions_keep_their_signatures_and_names():
    """The checks are invisible to introspection: documentation and the tree-file table read the same
    signatures as before."""
    parameters = ["name", "seed", "robot", "values", "log", "observe"]
    assert list(inspect.signature(run_demo).parameters) == parameters
    assert run_demo.__name__ == "run_demo" and "Runs the demo of task" in run_demo.__doc__
    assert list(inspect.signature(trees.Wait).parameters) == ["name", "duration"]
    assert "n_weights" in inspect.signature(skills.DMPSettings).parameters
