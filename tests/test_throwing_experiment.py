"""The paper's throwing experiment (Fig. 5): the quick run end to end, resuming, and its claims."""

import itertools
import json

import pytest
from PIL import Image

from besman.learning.throwing_experiment import CURVE_METHODS, claims
from tests.helpers import run_cli


@pytest.mark.slow
def test_the_quick_experiment_writes_results_and_both_figures_and_resumes(tmp_path, capsys):
    out = tmp_path / "throwing"
    code, stdout, _ = run_cli(capsys, "experiment", "throwing", "--quick", "--out", str(out))
    assert code == 0, stdout
    results = json.loads((out / "results.json").read_text())
    assert results["schema_version"] == 1 and results["config"]["grid"] == 3
    ks = results["config"]["ks"]
    for key in ("zero_shot", "st_uncertainty_25"):
        assert list(results[key]) == [str(k) for k in ks]
        assert all(v["mean"] > 0 and v["sem"] >= 0 for v in results[key].values())
    assert set(results["curves"]) == set(CURVE_METHODS)
    for rows in results["curves"].values():
        assert [row[0] for row in rows] == list(range(results["config"]["curve_rollouts"] + 1))
        means = [row[1] for row in rows]
        assert all(b <= a + 1e-12 for a, b in itertools.pairwise(means))  # the best so far never worsens
    # Every curve that starts from the template starts at its prediction (the same mean).
    prediction = results["zero_shot"][str(results["config"]["curve_k"])]["mean"]
    assert results["curves"]["uncertainty"][0][1] == pytest.approx(prediction)
    assert results["curves"]["tabula_rasa"][0][1] == pytest.approx(results["no_learning"]["mean"])
    assert set(results["claims"]) == set(claims(results)) and len(results["claims"]) == 5
    assert all(isinstance(claim["holds"], bool) for claim in results["claims"].values())
    assert stdout.count("\t") >= 5
    (training,) = results["training"]  # one seed
    assert training["seed"] == 0 and training["trained_distance"] > 0
    assert (
        -1 <= training["theta_vs_tau_distance_correlation"] <= 1 and training["median_noise_to_amplitude"] > 0
    )
    for name in ("fig5_top.png", "fig5_bottom.png"):
        with Image.open(out / name) as image:
            assert image.format == "PNG" and image.size[0] > 500
    # Run again: every stage is read back, and the results are the same.
    stages = sorted(path.name for path in (out / "work").iterdir())
    assert run_cli(capsys, "experiment", "throwing", "--quick", "--out", str(out))[0] == 0
    assert json.loads((out / "results.json").read_text()) == results
    assert sorted(path.name for path in (out / "work").iterdir()) == stages
    # Another configuration in the same directory is refused before any work.
    code, _, err = run_cli(capsys, "experiment", "throwing", "--quick", "--seeds", "2", "--out", str(out))
    assert code == 2 and "holds a run with another configuration" in err


def test_the_claims_follow_the_numbers():
    def summary(mean):
        return {"mean": mean, "sem": 0.1}

    results = {
        "config": {"curve_k": 4},
        "no_learning": summary(4.0),
        "zero_shot": {"1": summary(3.0), "2": summary(2.0), "4": summary(1.0)},
        "st_uncertainty_25": {"1": summary(1.5), "2": summary(0.9), "4": summary(0.5)},
        "curves": {
            "tabula_rasa": [[r, 4.0 - 0.1 * r, 0.1] for r in range(31)],
            "weight_proportional": [[r, 1.0 - 0.001 * r, 0.1] for r in range(31)],
            "uncertainty": [[r, 1.0 - 0.03 * r, 0.1] for r in range(31)],
            "correlated": [[r, 1.0 - 0.03 * r, 0.1] for r in range(31)],
        },
    }
    found = claims(results)
    assert found["a_prediction_improves_with_k"]["holds"]
    assert found["b_refined_template_beats_prediction_for_small_k"]["extra_training_tasks_to_match"] == 3
    assert found["b_refined_template_beats_prediction_for_small_k"]["holds"]
    assert found["c_uncertainty_beats_tabula_rasa_everywhere"]["holds"]
    assert found["d_weight_proportional_loses_its_advantage"]["holds"]
    assert found["e_tabula_rasa_needs_about_20_rollouts"]["rollouts_to_reach_prediction"] == 30
    results["curves"]["uncertainty"][5][1] = 10.0
    assert claims(results)["c_uncertainty_beats_tabula_rasa_everywhere"]["rollouts_where_not"] == [5]
