"""The ProMP baseline beside the skill templates: conditioning on a move's ends, the leave-one-out choice of
its weights and determinism on a synthetic family of joint trajectories (no simulation); and, slow, the
learned tree with the baselines of the committed AILA pool in place of its templates."""

import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("movement_primitives.promp", reason="dev dependency movement-primitives")

from besman.core.errors import InputError
from besman.sim.block_simulation import INPUT_NAMES
from besman.skills import DMP, DMPSettings, MovementPrimitive, SkillTemplate, TaskBounds
from besman.tasks.pick_place.promp_baseline import (
    ProMPBaseline,
    TrainingMoves,
    conditioned_mean,
    fit,
    normalised,
    select_weights,
)
from besman.trees.templates import check_template_fits

JOINTS, DURATION, DT = 3, 1.0, 0.01
ROOT = Path(__file__).resolve().parents[1]


def family(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Joint trajectories (K, T, D) of a known family: the minimum-jerk path between the ends plus a bump
    of half the move, as the prototype samples them."""
    s = np.linspace(0.0, 1.0, round(DURATION / DT) + 1)[None, :, None]
    move = (ends - starts)[:, None, :]
    return (
        starts[:, None, :] + move * (10 * s**3 - 15 * s**4 + 6 * s**5) + 0.5 * move * np.sin(np.pi * s) ** 2
    )


def moves_of(seed: int, count: int = 8) -> TrainingMoves:
    rng = np.random.default_rng(seed)
    starts, ends = rng.uniform(-1.0, 1.0, (2, count, JOINTS))
    return TrainingMoves(starts, ends, family(starts, ends), template(count).taus)


def template(count: int = 8) -> SkillTemplate:
    prototype = MovementPrimitive(
        DMP(JOINTS, settings=DMPSettings(n_weights=6), execution_time=DURATION, dt=DT),
        "reach",
        robot="aila",
        group="arm",
    )
    taus = np.random.default_rng(0).uniform(-0.5, 0.5, (count, len(INPUT_NAMES)))
    thetas = np.zeros((count, prototype.theta.size))
    box = TaskBounds(INPUT_NAMES, [-1.0] * len(INPUT_NAMES), [1.0] * len(INPUT_NAMES))
    return SkillTemplate(
        "reach", prototype, taus, thetas, box, prior_spread=0.1, provenance={"robot": "aila"}
    )


def test_the_conditioned_mean_and_the_primitive_pass_through_the_given_ends():
    moves = moves_of(seed=1)
    start, end = np.array([0.3, -0.2, 0.5]), np.array([-0.4, 0.6, 0.1])
    mean = conditioned_mean(fit(normalised(moves.trajectories), 8), start, end)
    np.testing.assert_allclose(mean[0], start, atol=1e-3)
    np.testing.assert_allclose(mean[-1], end, atol=1e-3)
    baseline = ProMPBaseline(template(), moves, weights=8)
    dmp = baseline.primitive_for_move(start, end).dmp
    np.testing.assert_array_equal(dmp.start, start)
    np.testing.assert_array_equal(dmp.goal, end)
    executed = dmp.trajectory().positions
    np.testing.assert_allclose(executed[0], start, atol=1e-12)
    # The forcing term's last bit leaves a DMP near, not at, its goal at its execution time.
    np.testing.assert_allclose(executed[-1], end, atol=5e-3)


def test_conditioning_on_the_ends_recovers_a_held_out_member_of_the_family():
    baseline = ProMPBaseline(template(), moves_of(seed=2), weights=8)
    start, end = np.random.default_rng(3).uniform(-1.0, 1.0, (2, JOINTS))
    held = family(start[None], end[None])[0]
    executed = baseline.primitive_for_move(start, end).dmp.trajectory().positions
    direct = DMP(JOINTS, execution_time=DURATION, dt=DT, start=start, goal=end).trajectory().positions
    error = np.sqrt(np.mean((executed - held) ** 2))
    without_bump = np.sqrt(np.mean((direct - held) ** 2))
    assert error < 0.1 * without_bump


def test_leave_one_out_chooses_the_setting_of_smallest_error_among_the_candidates():
    moves = moves_of(seed=4, count=5)
    selection = select_weights(moves, template().prototype, candidates=(4, 8))
    assert set(selection["rmse_rad"]) == {4, 8}
    assert selection["weights_per_joint"] == min(selection["rmse_rad"], key=selection["rmse_rad"].get)
    assert all(rmse > 0 for rmse in selection["rmse_rad"].values())
    assert set(selection["peak_acceleration_share_of_limit"]) == {4, 8}
    # Chosen without a setting given, and recorded.
    baseline = ProMPBaseline(template(count=5), moves, candidates=(4, 8))
    assert baseline.provenance["selection"] == selection
    assert baseline.weights == selection["weights_per_joint"]


def test_the_same_training_moves_give_the_same_baseline():
    first, second = (
        ProMPBaseline(template(count=5), moves_of(seed=5, count=5), candidates=(4, 6)) for _ in range(2)
    )
    assert first.provenance["selection"] == second.provenance["selection"]
    start, end = np.array([0.1, 0.2, 0.3]), np.array([0.5, -0.5, 0.0])
    np.testing.assert_array_equal(
        first.primitive_for_move(start, end).theta, second.primitive_for_move(start, end).theta
    )


def test_the_baseline_passes_a_learned_leafs_checks_counts_changed_moves_and_refuses_another_count():
    baseline = ProMPBaseline(template(), moves_of(seed=6), weights=4)
    check_template_fits("grasp", baseline, "aila", INPUT_NAMES)
    assert baseline.provenance["changed_training_moves"] == []
    moves = moves_of(seed=6)
    turned = moves.inputs.copy()
    turned[2, -1] += 90.0  # the planner now turns the hand otherwise in task 2
    turned[3, -1] += 360.0  # the same turn
    changed = TrainingMoves(moves.starts, moves.ends, moves.trajectories, turned)
    assert ProMPBaseline(template(), changed, weights=4).provenance["changed_training_moves"] == [2]
    with pytest.raises(InputError, match="training tasks"):
        ProMPBaseline(template(count=8), moves_of(seed=6, count=5), weights=4)


@pytest.mark.slow
def test_the_learned_tree_with_the_aila_pools_promp_baselines_places_the_box():
    from besman.skills import SkillTemplatePool
    from besman.tasks.pick_place.promp_baseline import baseline_pool
    from besman.tasks.running import prepare
    from besman.trees.files import loads_tree
    from besman.trees.registry import register_pool

    folder = ROOT / "examples" / "pools" / "pick_place_aila"
    if not (folder / "reach.json").is_file():
        pytest.skip(f"no AILA pool at {folder}")
    pool = SkillTemplatePool(folder)
    if tuple(pool["reach"].box.names) != INPUT_NAMES:
        pytest.skip(f"{folder} is not a pool over the hand's move ({', '.join(INPUT_NAMES)}): learn it again")
    # A fixed setting, the smoothest candidate: the leave-one-out choice is tested above and made by
    # benchmarks/learned.py.
    register_pool("test_promp_baseline:POOL", baseline_pool(pool, weights=dict.fromkeys(pool, 4)))
    text = (ROOT / "examples" / "trees" / "grasp_then_place_learned.yaml").read_text()
    text = re.sub(r"^\s*refine_above: .*\n", "", text, flags=re.MULTILINE)
    text, named = re.subn(r"pool: \S+", "pool: test_promp_baseline:POOL", text)
    assert named == 3
    values = {
        "object": (0.52, -0.05, 30.0),
        "place": (0.5, -0.42, -60.0),
        "shape": (0,),
        "size": (0.05, 0.06, 0.07),
    }
    trained = [entry["task_tau"] for name in pool for entry in pool[name].provenance["training"]]
    tau = np.concatenate([np.ravel(v) for v in values.values()])
    assert not any(np.allclose(tau, t) for t in trained)
    tree = loads_tree(text, base=ROOT / "examples" / "trees", source="grasp_then_place_learned.yaml")
    prepared = prepare("pick-place", tree, values=values, robot="aila")
    summary = prepared.judge(prepared.runner.run())
    assert summary.success, f"{summary.message}; {summary.outcome}"
