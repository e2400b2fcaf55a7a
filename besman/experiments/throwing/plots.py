"""The throwing experiment's figures (Fig. 5 of Metzen et al., KI 2014, and the field) from ``results.json``.

- ``fig5_top.png`` - distance to target vs the number of training tasks K: No Learning, the paper's
  template's prediction, the template refined with uncertainty exploration, besman's outcome template, nearest
  neighbour, the per-dimension template of the first reproduction, and the variants beyond the paper
  (dashed, labelled "variant"); mean +- SEM (filled markers), median (open markers) and the number of failed
  throws where there are any; log scale.
- ``fig5_bottom.png`` - learning curves at K = curve_k: distance of the best rollout so far vs rollouts for
  CMA-ES tabula rasa and from the paper's template with each exploration, from the nearest training theta,
  and besman's outcome-space refinement from its outcome template; mean +- SEM bands and medians (dotted).
- ``fig_field.png`` - every method's distance on the grid against the total rollouts it spent (training
  and kernel choice included), log-log: the paper's methods, zero-shot baselines, refinement baselines,
  contextual policy search and the variants.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.learning.figures import plt, save_png

LABELS = {
    "tabula_rasa": "CMA-ES tabula rasa",
    "weight_proportional": "paper's template, weight-proportional exploration",
    "uncertainty": "paper's template, uncertainty exploration",
    "isotropic": "paper's template mean, isotropic exploration (same trace)",
    "nearest_start": "CMA-ES from the nearest training theta",
    "zero_shot_template": "paper's template prediction Theta(tau)",
    "zero_shot_outcome_template": "besman's outcome template",
    "outcome_refinement": "besman's outcome-space refinement",
    "zero_shot_per_dimension": "per-dimension GPs (first reproduction)",
    "zero_shot_training_mean": "mean of the training thetas",
    "zero_shot_nearest_neighbour": "nearest neighbour",
    "zero_shot_affine": "affine regression",
    "zero_shot_crkr": "CrKR",
    "template_refined": "paper's template + uncertainty, refined",
    "creps": "C-REPS (contextual)",
    "contextual_cmaes": "contextual CMA-ES",
    "variant_bootstrapped": "variant: bootstrapped training",
    "variant_goal_only": "variant: goal-only template",
    "no_learning": "No Learning",
}


def plot_results(results: dict, directory: Path) -> tuple[Path, Path, Path]:
    """Writes the three figures into ``directory``; returns their paths."""
    directory = Path(directory)
    return (
        _top(results, directory / "fig5_top.png"),
        _bottom(results, directory / "fig5_bottom.png"),
        _field(results, directory / "fig_field.png"),
    )


def _errorbar(axes, xs, summaries, **style):
    """Means +- SEM, medians as open markers of the same colour, and failed throws written beside."""
    summaries = list(summaries)
    means = np.array([s["mean"] for s in summaries])
    sems = np.array([s["sem"] for s in summaries])
    line = axes.errorbar(xs, means, yerr=sems, capsize=3, **style).lines[0]
    colour = line.get_color()
    axes.plot(
        xs,
        [s["median"] for s in summaries],
        linestyle="none",
        marker=style.get("marker", "o"),
        markerfacecolor="none",
        color=colour,
    )
    for x, mean, s in zip(xs, means, summaries, strict=True):
        if s["failed"]:
            axes.annotate(
                f"{s['failed']}x",
                (x, mean),
                textcoords="offset points",
                xytext=(4, 4),
                fontsize=6,
                color=colour,
            )


def _top(results: dict, path: Path) -> Path:
    by_k = results["zero_shot"]["template"]
    ks = [int(k) for k in by_k]
    figure, axes = plt.subplots(figsize=(7.2, 4.6))
    none = results["no_learning"]
    axes.axhline(none["mean"], color="grey", linestyle="--", label="No Learning")
    axes.axhspan(none["mean"] - none["sem"], none["mean"] + none["sem"], color="grey", alpha=0.15)
    refine = results["config"]["refine_rollouts"]
    _errorbar(axes, ks, by_k.values(), marker="o", label="paper's template: prediction Theta(tau)")
    _errorbar(
        axes,
        ks,
        results["template_refined"].values(),
        marker="s",
        label=f"paper's template + uncertainty, {refine} rollouts",
    )
    zero_shot_series = (  # method, marker, colour, label
        ("outcome_template", "D", "black", "besman's outcome template (zero shot)"),
        ("nearest_neighbour", "v", "tab:olive", "nearest training theta (zero shot)"),
        ("per_dimension", "^", "tab:grey", "prediction, per-dimension GPs (first reproduction)"),
    )
    for method, marker, colour, label in zero_shot_series:
        _errorbar(axes, ks, results["zero_shot"][method].values(), marker=marker, color=colour, label=label)
    for variant, values in results["variants"].items():
        _errorbar(
            axes,
            [int(k) for k in values],
            values.values(),
            marker="x",
            linestyle="--",
            label=LABELS[f"variant_{variant}"],
        )
    axes.plot([], [], linestyle="none", marker="o", markerfacecolor="none", color="black", label="median")
    axes.plot([], [], linestyle="none", marker="$n$x", color="black", label="failed throws (of grid x seeds)")
    title = f"PA-10 throwing: distance vs training tasks, {results['config']['seeds']} seed(s)"
    return _finish(figure, axes, ("training tasks K", "distance to target (m)", title), path)


def _bottom(results: dict, path: Path) -> Path:
    figure, axes = plt.subplots(figsize=(7.2, 4.6))
    for method, rows in results["curves"].items():
        rows = np.array([row[:5] for row in rows], dtype=float)
        line = axes.plot(rows[:, 0], rows[:, 1], label=LABELS.get(method, method))[0]
        axes.fill_between(
            rows[:, 0], rows[:, 1] - rows[:, 2], rows[:, 1] + rows[:, 2], color=line.get_color(), alpha=0.15
        )
        axes.plot(rows[:, 0], rows[:, 3], color=line.get_color(), linestyle=":", linewidth=1)
    rows = np.array([row[:5] for row in results["outcome_refinement"]], dtype=float)
    line = axes.plot(rows[:, 0], rows[:, 1], marker="D", color="black", label=LABELS["outcome_refinement"])[0]
    axes.fill_between(rows[:, 0], rows[:, 1] - rows[:, 2], rows[:, 1] + rows[:, 2], color="black", alpha=0.15)
    axes.plot(rows[:, 0], rows[:, 3], color=line.get_color(), linestyle=":", linewidth=1)
    axes.plot([], [], color="black", linestyle=":", linewidth=1, label="medians (dotted)")
    k = results["config"]["curve_k"]
    prediction = results["zero_shot"]["template"][str(k)]["mean"]
    axes.axhline(
        prediction, color="black", linestyle="--", linewidth=0.8, label=f"paper's prediction at K={k}"
    )
    labels = ("rollouts", "distance of the best rollout so far (m)", f"Learning curves at K = {k}")
    return _finish(figure, axes, labels, path)


def _field(results: dict, path: Path) -> Path:
    figure, axes = plt.subplots(figsize=(8.4, 5.4))
    axes.set_prop_cycle(color=plt.get_cmap("tab20").colors)  # 19 methods: no colour twice
    for name, rows in results["field"].items():
        rows = np.array(rows, dtype=float)
        xs = np.maximum(rows[:, 0], 1.0)  # No Learning spends nothing: drawn at 1 on the log axis
        style = {"marker": "o", "markersize": 3}
        if name.startswith("curve_"):
            style = {}
        elif name.startswith("variant_"):
            style = {"marker": "x", "linestyle": "--"}
        elif name in ("creps", "contextual_cmaes"):
            style = {"marker": "D", "markersize": 3, "linestyle": "-."}
        elif name in ("zero_shot_outcome_template", "outcome_refinement"):
            style = {"marker": "D", "markersize": 4, "linewidth": 2.2}
        elif name == "no_learning":
            style = {"marker": "*", "markersize": 10, "linestyle": "none", "color": "black"}
        label = LABELS.get(name.removeprefix("curve_"), name)
        axes.plot(xs, rows[:, 1], label=label, **style)
    axes.axhline(0.5, color="black", linewidth=0.8, linestyle=":", label="0.5 m")
    axes.set_xscale("log")
    labels = (
        "total rollouts (training, kernel choice, Jacobians and the new task's)",
        "mean distance on the grid (m)",
        "The field on the paper's protocol",
    )
    _finish(figure, axes, labels, path, legend_outside=True)
    return path


def _finish(figure, axes, labels: tuple[str, str, str], path: Path, legend_outside: bool = False) -> Path:
    """Log-scale distances, axis labels and title, legend and grid; written to ``path``."""
    axes.set_yscale("log")
    axes.set_xlabel(labels[0])
    axes.set_ylabel(labels[1])
    axes.set_title(labels[2])
    if legend_outside:
        axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    else:
        axes.legend(fontsize=7)
    axes.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    return save_png(figure, path, dpi=120)
