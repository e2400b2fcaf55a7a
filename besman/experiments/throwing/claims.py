"""The paper's Fig. 5 claims and our goals, judged on a throwing experiment's ``results.json`` data.

Each threshold is written here before the run and derived from the paper's words (Metzen et al., KI 2014,
section on the throwing experiment; ``../shared/reference/learning.md`` section 3). Two rules turn words
into numbers: "about N" means within a factor of two of N, and "well below No Learning" is read through
claim (e), so that the two cannot contradict each other: if tabula rasa needs about 20 (at least 10)
rollouts to reach the prediction, the prediction is better than anything tabula rasa has after 9.

- (a) The prediction improves with the number of training tasks K (the largest K beats the smallest) to
  well below No Learning: at K = curve_k it is better than tabula rasa after :data:`A_ROLLOUTS` rollouts.
- (b) For small K the refined template is much better than the prediction; the prediction needs about 6
  more training tasks to match it: at the smallest K the refined template beats the prediction, and the
  first K whose prediction matches it is 3 to 12 tasks later.
- (c) Uncertainty exploration is consistently better than tabula rasa: below it at every rollout.
- (d) Weight-proportional exploration quickly loses its advantage: its advantage over tabula rasa (ratio
  of distances) at the end of the curves is less than half of that at the start, and it ends behind
  uncertainty exploration.
- (e) Tabula rasa needs about 20 rollouts to reach the prediction's quality at K = curve_k: 10 to 40.

Goals (issue 25, not the paper's): the prediction at K = curve_k is at least twice as close as No
Learning; the template's prediction beats every zero-shot baseline from K = 4 on; it beats C-REPS and
contextual CMA-ES at equal total rollouts (each contextual method's latest checkpoint at or below the
template's cost).

Acceptance (issue 39, written before its run): besman's outcome template never fails a throw, its mean
never rises from K = 2 on (by more than :data:`NOT_RISING`), it is at most :data:`VERSUS_NEAREST` of nearest
neighbour's mean from K = 4 and below :data:`OUTCOME_TEMPLATE_MEANS` at their K, its median at K = 10 at
most 0.4 m; the paper's template fails at most one throw per K and its mean does not rise from K = 4;
C-REPS is within 1.2 m with at most 2 failed throws at 1,200 rollouts and its median within 0.5 m at 3,600;
outcome-space refinement at K = curve_k has a median within 0.10 m and a mean within 0.40 m after 3 throws.
An item whose K or checkpoint the run does not have fails, saying so.
"""

from __future__ import annotations

import numpy as np

ABOUT = 2.0  # "about N": within a factor of two
E_ROLLOUTS = (20 / ABOUT, 20 * ABOUT)  # (e): about 20 rollouts
B_EXTRA_TASKS = (6 / ABOUT, 6 * ABOUT)  # (b): about 6 more training tasks
A_ROLLOUTS = int(E_ROLLOUTS[0]) - 1  # (a): better than tabula rasa after 9 rollouts, implied by (e)
BASELINES_FROM_K = 4
ZERO_SHOT_BASELINES = ("per_dimension", "training_mean", "nearest_neighbour", "affine", "crkr")


def rollouts_to_reach(rows: list[list[float]], level: float) -> float | None:
    """The first total-rollout count of a field series (rows [rollouts, mean, ...]) whose mean is at most
    ``level``, or None."""
    for row in rows:
        if row[1] <= level:
            return row[0]
    return None


def _means(by_k: dict) -> tuple[list[int], np.ndarray]:
    ks = [int(k) for k in by_k]
    return ks, np.array([by_k[str(k)]["mean"] for k in ks])


def claims(results: dict) -> dict:
    """Each of the paper's claims as true/false with the numbers behind it (module documentation)."""
    ks, zero = _means(results["zero_shot"]["template"])
    _, refined = _means(results["template_refined"])
    no_learning = results["no_learning"]["mean"]
    curve_k = results["config"]["curve_k"]
    curves = {method: np.array([row[1] for row in rows]) for method, rows in results["curves"].items()}
    tabula_rasa = curves["tabula_rasa"]
    prediction = results["zero_shot"]["template"][str(curve_k)]["mean"]

    a_level = tabula_rasa[min(A_ROLLOUTS, len(tabula_rasa) - 1)]
    matched = [k for k, z in zip(ks, zero, strict=True) if z <= refined[0]]
    extra = (matched[0] - ks[0]) if matched else None
    start_gain = tabula_rasa[0] / curves["weight_proportional"][0]
    end_gain = tabula_rasa[-1] / curves["weight_proportional"][-1]
    reached = np.flatnonzero(tabula_rasa <= prediction)
    needed = int(reached[0]) if reached.size else None
    return {
        "a_prediction_improves_with_k": {
            "holds": bool(zero[-1] < zero[0] and prediction < a_level),
            "zero_shot_first_k": float(zero[0]),
            "zero_shot_last_k": float(zero[-1]),
            f"zero_shot_k{curve_k}": prediction,
            f"tabula_rasa_after_{A_ROLLOUTS}": float(a_level),
            "no_learning": no_learning,
        },
        "b_refined_template_beats_prediction_for_small_k": {
            "holds": bool(
                refined[0] < zero[0] and extra is not None and B_EXTRA_TASKS[0] <= extra <= B_EXTRA_TASKS[1]
            ),
            "k": ks[0],
            "refined": float(refined[0]),
            "zero_shot": float(zero[0]),
            "extra_training_tasks_to_match": extra,
        },
        "c_uncertainty_beats_tabula_rasa_everywhere": {
            "holds": bool(np.all(curves["uncertainty"] < tabula_rasa)),
            "rollouts_where_not": np.flatnonzero(curves["uncertainty"] >= tabula_rasa).tolist(),
        },
        "d_weight_proportional_loses_its_advantage": {
            "holds": bool(
                end_gain < 0.5 * start_gain and curves["weight_proportional"][-1] > curves["uncertainty"][-1]
            ),
            "advantage_over_tabula_rasa_at_start": float(start_gain),
            "advantage_over_tabula_rasa_at_end": float(end_gain),
        },
        "e_tabula_rasa_needs_about_20_rollouts": {
            "holds": bool(needed is not None and E_ROLLOUTS[0] <= needed <= E_ROLLOUTS[1]),
            "rollouts_to_reach_prediction": needed,
            "prediction": prediction,
        },
    }


def goals(results: dict) -> dict:
    """Issue 25's goals as true/false with the numbers behind them (module documentation)."""
    curve_k = results["config"]["curve_k"]
    ks, template = _means(results["zero_shot"]["template"])
    prediction = results["zero_shot"]["template"][str(curve_k)]["mean"]
    no_learning = results["no_learning"]["mean"]
    late = [i for i, k in enumerate(ks) if k >= BASELINES_FROM_K]
    losses = {
        method: [ks[i] for i in late if results["zero_shot"][method][str(ks[i])]["mean"] <= template[i]]
        for method in ZERO_SHOT_BASELINES
    }
    costs = [
        results["rollouts"][str(k)]["training"] + results["rollouts"][str(k)]["kernel_choice"] for k in ks
    ]
    contextual = {}
    for method, rows in results["contextual"].items():
        compared = []
        for k, cost, mean in zip(ks, costs, template, strict=True):
            earlier = [row for row in rows if 0 < row[0] <= cost]
            if earlier:
                compared.append({"k": k, "rollouts": cost, "template": float(mean), method: earlier[-1][1]})
        contextual[method] = compared
    return {
        "prediction_twice_as_close_as_no_learning": {
            "holds": bool(prediction <= 0.5 * no_learning),
            f"zero_shot_k{curve_k}": prediction,
            "no_learning": no_learning,
        },
        "template_beats_every_zero_shot_baseline_from_k4": {
            "holds": bool(late) and not any(losses.values()),
            "ks_where_a_baseline_is_as_good": {m: ks_lost for m, ks_lost in losses.items() if ks_lost},
        },
        "template_beats_contextual_policy_search_at_equal_rollouts": {
            "holds": all(rows for rows in contextual.values())
            and all(row["template"] < row[m] for m, rows in contextual.items() for row in rows),
            "comparisons": contextual,
        },
    }


NOT_RISING = 0.03  # m: "never rises", for besman's template
VERSUS_NEAREST = 0.7
OUTCOME_TEMPLATE_MEANS = {4: 1.0, 6: 0.9, 10: 0.75, 14: 0.6, 20: 0.45}
OUTCOME_TEMPLATE_MEDIAN = (10, 0.4)
CREPS_AT = ((1200, 1.2, 2), (3600, 0.5))  # (rollouts, mean, failed), (rollouts, median)
REFINEMENT = (3, 0.10, 0.40)  # throws, median, mean


def _rises(means: np.ndarray, tolerance: float) -> bool:
    return bool(np.any(np.diff(means) > tolerance))


def acceptance(results: dict) -> dict:
    """Issue 39's acceptance as true/false with the numbers behind it (module documentation)."""
    ours, paper = results["zero_shot"]["outcome_template"], results["zero_shot"]["template"]
    nearest = results["zero_shot"]["nearest_neighbour"]
    ks = [int(k) for k in ours]
    from_2 = [str(k) for k in ks if k >= 2]
    from_4 = [str(k) for k in ks if k >= BASELINES_FROM_K]
    limits = {k: v for k, v in OUTCOME_TEMPLATE_MEANS.items() if str(k) in ours}
    median_k, median_limit = OUTCOME_TEMPLATE_MEDIAN
    ours_ok = (
        all(s["failed"] == 0 for s in ours.values())
        and not _rises(np.array([ours[k]["mean"] for k in from_2]), NOT_RISING)
        and all(ours[k]["mean"] <= VERSUS_NEAREST * nearest[k]["mean"] for k in from_4)
        and len(limits) == len(OUTCOME_TEMPLATE_MEANS)
        and all(ours[str(k)]["mean"] <= v for k, v in limits.items())
        and str(median_k) in ours
        and ours[str(median_k)]["median"] <= median_limit
    )
    creps = {int(row[0]): row for row in results["contextual"]["creps"]}
    (at, mean_limit, failed_limit), (late, median_limit_creps) = CREPS_AT
    creps_ok = (
        at in creps
        and late in creps
        and creps[at][1] <= mean_limit
        and creps[at][4] <= failed_limit
        and creps[late][3] <= median_limit_creps
    )
    throws, refine_median, refine_mean = REFINEMENT
    refinement = results["outcome_refinement"]
    refinement_ok = (
        len(refinement) > throws
        and refinement[throws][3] <= refine_median
        and refinement[throws][1] <= refine_mean
    )
    return {
        "outcome_template": {
            "holds": bool(ours_ok),
            "means": {k: s["mean"] for k, s in ours.items()},
            "failed": {k: s["failed"] for k, s in ours.items()},
            "versus_nearest_neighbour": {k: ours[k]["mean"] / nearest[k]["mean"] for k in from_4},
            f"median_k{median_k}": ours[str(median_k)]["median"] if str(median_k) in ours else None,
        },
        "paper_template": {
            "holds": bool(
                all(s["failed"] <= 1 for s in paper.values())
                and not _rises(np.array([paper[k]["mean"] for k in from_4]), 0.0)
            ),
            "means": {k: s["mean"] for k, s in paper.items()},
            "failed": {k: s["failed"] for k, s in paper.items()},
        },
        "creps": {
            "holds": bool(creps_ok),
            f"mean_at_{at}": creps[at][1] if at in creps else None,
            f"failed_at_{at}": creps[at][4] if at in creps else None,
            f"median_at_{late}": creps[late][3] if late in creps else None,
        },
        "outcome_refinement": {
            "holds": bool(refinement_ok),
            f"median_after_{throws}": refinement[throws][3] if len(refinement) > throws else None,
            f"mean_after_{throws}": refinement[throws][1] if len(refinement) > throws else None,
        },
    }
