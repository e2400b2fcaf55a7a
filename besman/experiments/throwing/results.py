"""The throwing experiment's ``results.json``: every stage's distances summarised over grid targets and seeds
together (mean +- SEM, median, failed throws and the mean of the throws that did not fail), the zero-shot
methods at the validation targets too, what the feasibility guard pulled back, the contextual methods'
settings and how they were chosen, each method's rollouts, the field (every method against its total
rollouts), the training sets' diagnostics, and the paper's claims, the goals and issue 39's acceptance judged
by :mod:`besman.experiments.throwing.claims`."""

from __future__ import annotations

import json
import math
from dataclasses import asdict

import numpy as np

from besman.experiments.throwing.bench import distances_of
from besman.experiments.throwing.claims import acceptance, claims, goals, rollouts_to_reach
from besman.experiments.throwing.config import (
    CONTEXTUAL_METHODS,
    CURVE_METHODS,
    SCHEMA_VERSION,
    VARIANTS,
    ZERO_SHOT_METHODS,
)
from besman.experiments.throwing.contextual import CANDIDATES as CONTEXTUAL_CANDIDATES
from besman.experiments.throwing.stages import Stages
from besman.tasks.throwing.rollouts import FAILURE_REWARD

FAILED_DISTANCE = math.sqrt(-FAILURE_REWARD)  # 31.6 m: a failed throw is at least this far off


def collect_results(stages: Stages) -> dict:
    """Runs (or reads) every stage, in the protocol's order, and gathers them with the claims and goals."""
    config, seeds = stages.config, range(stages.config.seeds)
    spreads = {
        "tabula_rasa": stages.spreads.tabula_rasa(),
        "nearest_start": stages.spreads.nearest_start(stages.training.nearest_thetas),
    }
    evaluation = stages.evaluation
    no_learning = np.tile(evaluation.no_learning(), config.seeds)
    zero, validation, pulled_back = ({m: {} for m in ZERO_SHOT_METHODS} for _ in range(3))
    refined, verdicts, costs = {}, {}, {}
    for k in config.ks:
        runs = [evaluation.per_k(seed, k) for seed in seeds]
        for method in ZERO_SHOT_METHODS:
            zero[method][k] = np.concatenate([s[f"zero_shot_{method}"] for s in runs])
            validation[method][k] = np.concatenate([s[f"validation_{method}"] for s in runs])
            pulled_back[method][k] = int(sum(int(s[f"pulled_back_{method}"]) for s in runs))
        refined[k] = np.concatenate([s["refined"] for s in runs])
        verdicts[k] = {
            "searches": int(sum(len(s["refinement_accepted"]) for s in runs)),
            "kept": int(sum(int(s["refinement_accepted"].sum()) for s in runs)),
            "improvement_mean": float(np.mean([s["refinement_improvement"] for s in runs])),
            "noise_max": float(max(s["refinement_noise"].max() for s in runs)),
        }
        costs[k] = _cost(stages, k, "training")
    curves = {m: np.concatenate([stages.curves.curves(seed, m) for seed in seeds]) for m in CURVE_METHODS}
    outcome_refinement = np.concatenate([stages.curves.outcome_refinement(seed) for seed in seeds])
    contextual, guarded_contextual = {}, {}
    for method in CONTEXTUAL_METHODS:
        runs = [stages.contextual.run(seed, method) for seed in seeds]
        contextual[method] = (
            runs[0]["rollouts"],
            np.concatenate([s["distances"] for s in runs], axis=1),
        )
        guarded_contextual[method] = {
            "proposals": int(sum(int(s["proposals_pulled_back"]) for s in runs)),
            "grid_means_per_checkpoint": np.sum([s["means_pulled_back"] for s in runs], axis=0).tolist(),
        }
    variants_pulled_back = {
        v: {
            str(k): sum(int(evaluation.variant_stage(s, k, v)["pulled_back"]) for s in seeds)
            for k in config.ks
        }
        for v in VARIANTS
    }
    variants = {
        v: {
            k: (
                np.concatenate([evaluation.variant_zero_shot(s, k, v) for s in seeds]),
                _cost(stages, k, v),
            )
            for k in config.ks
        }
        for v in VARIANTS
    }
    results = {
        "schema_version": SCHEMA_VERSION,
        "kind": "besman-throwing-experiment",
        "config": {**json.loads(json.dumps(asdict(config))), "backend": stages.backend},
        "spreads": {
            method: {
                "candidates": stage["spreads"].tolist(),
                "areas_under_curve": stage["scores"].tolist(),
                "chosen": float(stage["chosen"]),
                "rollouts": int(stage["rollouts"]),
            }
            for method, stage in spreads.items()
        },
        "no_learning": summary(no_learning),
        "zero_shot": {m: {str(k): summary(v) for k, v in by_k.items()} for m, by_k in zero.items()},
        "validation": {m: {str(k): summary(v) for k, v in by_k.items()} for m, by_k in validation.items()},
        "pulled_back": {
            "zero_shot": {m: {str(k): n for k, n in by_k.items()} for m, by_k in pulled_back.items()},
            "contextual": guarded_contextual,
            "variants": variants_pulled_back,
        },
        "template_refined": {str(k): summary(v) for k, v in refined.items()},
        # per K: the refinements judged, how many kept their best (improvement > noise), the noise's largest
        "template_refinement_verdicts": {str(k): v for k, v in verdicts.items()},
        "curves": {
            m: [[r, *summary(v[:, r]).values()] for r in range(v.shape[1])] for m, v in curves.items()
        },
        "outcome_refinement": [
            [r, *summary(outcome_refinement[:, r]).values()] for r in range(outcome_refinement.shape[1])
        ],
        "contextual": {
            m: [[int(r), *summary(d[i]).values()] for i, r in enumerate(rollouts)]
            for m, (rollouts, d) in contextual.items()
        },
        "contextual_settings": {
            method: {
                "candidates": [asdict(candidate) for candidate in CONTEXTUAL_CANDIDATES[method]],
                "validation_areas": stage["scores"].tolist(),
                "validation_areas_per_search": stage["areas"].tolist(),
                "chosen": asdict(CONTEXTUAL_CANDIDATES[method][int(stage["chosen"])]),
                "rollouts": int(stage["rollouts"]),
            }
            for method in CONTEXTUAL_METHODS
            for stage in [stages.contextual.settings(method)]
        },
        "variants": {
            v: {str(k): {**summary(d), "rollouts": c} for k, (d, c) in by_k.items()}
            for v, by_k in variants.items()
        },
        "rollouts": {str(k): c for k, c in costs.items()},
    }
    results["field"] = field_series(results)
    results["rollouts_to_half_metre"] = {
        m: rollouts_to_reach(rows, 0.5) for m, rows in results["field"].items()
    }
    results["training"] = [_diagnose_training(stages, seed) for seed in seeds]
    results["claims"] = claims(results)
    results["goals"] = goals(results)
    results["acceptance"] = acceptance(results)
    return results


def _cost(stages: Stages, k: int, source: str) -> dict[str, float]:
    """Mean rollouts over seeds behind the first k tasks of ``source``: their training, the paper's template's
    validation throws for its kernel and (for the paper's training set) the Jacobians of outcome-space
    refinement."""
    seeds = range(stages.config.seeds)
    cost = {
        "training": float(np.mean([stages.training.of(s, source)["rollouts"][:k].sum() for s in seeds])),
        "kernel_choice": float(
            np.mean([int(stages.templates.kernel_choice(s, k, source)["rollouts"]) for s in seeds])
        ),
    }
    if source == "training":
        cost["jacobians"] = float(
            np.mean([stages.training.jacobians(s)["rollouts"][:k].sum() for s in seeds])
        )
    return cost


def _diagnose_training(stages: Stages, seed: int) -> dict:
    """How the training set looks to a template: the training thetas' own distances, how far they drifted
    from theta_0, whether theta distances follow target distances, and the kernels chosen."""
    training = stages.training.paper(seed)
    taus, thetas = training["taus"], training["thetas"]
    pairs = np.triu_indices(len(taus), 1)
    tau_gaps = np.linalg.norm(taus[:, None] - taus[None], axis=2)[pairs]
    theta_gaps = np.linalg.norm(thetas[:, None] - thetas[None], axis=2)[pairs]
    return {
        "seed": seed,
        "trained_distance": float(distances_of(training["rewards"]).mean()),
        "theta_vs_tau_distance_correlation": float(np.corrcoef(tau_gaps, theta_gaps)[0, 1]),
        "theta_drift_from_theta0": float(np.linalg.norm(thetas - stages.bench.theta0, axis=1).mean()),
        "kernels": {
            str(k): {
                "kernel": json.loads(str(choice["kernel"])),
                "validation_distances": choice["losses"].tolist(),
                "pulled_back": int(choice["pulled_back"]),
            }
            for k in stages.config.ks
            for choice in [stages.templates.kernel_choice(seed, k)]
        },
    }


def summary(values: np.ndarray) -> dict:
    """Mean, its standard error, median, the number of failed throws, how many there are, and the mean of
    the throws that did not fail (None if all did)."""
    values = np.asarray(values, dtype=float)
    sem = float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else 0.0
    failed = values >= FAILED_DISTANCE - 1e-9
    return {
        "mean": float(values.mean()),
        "sem": sem,
        "median": float(np.median(values)),
        "failed": int(failed.sum()),
        "count": len(values),
        "non_failed_mean": float(values[~failed].mean()) if (~failed).any() else None,
    }


def field_series(results: dict) -> dict[str, list[list[float]]]:
    """Every method as rows [total rollouts, mean, sem, median, failed] on the grid (module documentation):
    a zero-shot method at K costs K training tasks (and the paper's template its kernel choice), a refinement
    its start's cost plus the rollouts of the new task (outcome-space refinement: the training tasks'
    Jacobians too); the contextual methods' rollouts exclude the choice of their settings, as the spreads'
    are excluded from every method."""
    config, costs = results["config"], {int(k): c for k, c in results["rollouts"].items()}
    training = {k: c["training"] for k, c in costs.items()}
    template = {k: c["training"] + c["kernel_choice"] for k, c in costs.items()}

    def row(x, s):
        return [float(x), s["mean"], s["sem"], s["median"], s["failed"]]

    series = {"no_learning": [row(0, results["no_learning"])]}
    for method, by_k in results["zero_shot"].items():
        cost = template if method == "template" else training
        series[f"zero_shot_{method}"] = [row(cost[int(k)], s) for k, s in by_k.items()]
    curve_k = config["curve_k"]
    outcome_start = training[curve_k] + costs[curve_k].get("jacobians", 0.0)
    series["outcome_refinement"] = [[outcome_start + r[0], *r[1:5]] for r in results["outcome_refinement"]]
    series["template_refined"] = [
        row(template[int(k)] + config["refine_rollouts"], s) for k, s in results["template_refined"].items()
    ]
    for method, rows in results["curves"].items():
        start = {"tabula_rasa": 0, "nearest_start": training[config["curve_k"]]}.get(
            method, template[config["curve_k"]]
        )
        series[f"curve_{method}"] = [[start + r[0], *r[1:5]] for r in rows]
    for method, rows in results["contextual"].items():
        series[method] = [[float(r[0]), *r[1:5]] for r in rows]
    for variant, by_k in results["variants"].items():
        series[f"variant_{variant}"] = [
            row(s["rollouts"]["training"] + s["rollouts"]["kernel_choice"], s) for s in by_k.values()
        ]
    return series
