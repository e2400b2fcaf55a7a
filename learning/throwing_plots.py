"""The throwing experiment's figures (Fig. 5 of Metzen et al., KI 2014) from its ``results.json`` data.

- ``fig5_top.png`` - distance to target vs the number of training tasks K: No Learning, the template's
  prediction, and the template refined with uncertainty exploration; mean +- SEM, log scale.
- ``fig5_bottom.png`` - learning curves at one K: distance of the best rollout so far vs rollouts for CMA-ES
  tabula rasa and from the template with each exploration covariance; mean +- SEM bands, log scale.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from besman.learning.figures import plt, save_png

LABELS = {
    "tabula_rasa": "CMA-ES tabula rasa",
    "weight_proportional": "template, weight-proportional exploration",
    "uncertainty": "template, uncertainty exploration",
    "correlated": "template, correlated uncertainty (ours)",
}


def plot_results(results: dict, directory: Path) -> tuple[Path, Path]:
    """Writes both figures into ``directory``; returns their paths."""
    return _top(results, Path(directory) / "fig5_top.png"), _bottom(
        results, Path(directory) / "fig5_bottom.png"
    )


def _top(results: dict, path: Path) -> Path:
    ks = [int(k) for k in results["zero_shot"]]
    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    none = results["no_learning"]
    axes.axhline(none["mean"], color="grey", linestyle="--", label="No Learning")
    axes.axhspan(none["mean"] - none["sem"], none["mean"] + none["sem"], color="grey", alpha=0.15)
    refine = results["config"]["refine_rollouts"]
    for key, label, marker in (
        ("zero_shot", "prediction Theta(tau)", "o"),
        ("st_uncertainty_25", f"template + uncertainty, {refine} rollouts", "s"),
    ):
        means = np.array([results[key][str(k)]["mean"] for k in ks])
        sems = np.array([results[key][str(k)]["sem"] for k in ks])
        axes.errorbar(ks, means, yerr=sems, marker=marker, capsize=3, label=label)
    title = f"PA-10 throwing: {len(ks)} training-set sizes, {results['config']['seeds']} seed(s)"
    return _finish(figure, axes, ("training tasks K", "distance to target (m)", title), path)


def _bottom(results: dict, path: Path) -> Path:
    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    for method, rows in results["curves"].items():
        rows = np.array(rows)
        line = axes.plot(rows[:, 0], rows[:, 1], label=LABELS.get(method, method))[0]
        axes.fill_between(
            rows[:, 0], rows[:, 1] - rows[:, 2], rows[:, 1] + rows[:, 2], color=line.get_color(), alpha=0.15
        )
    k = results["config"]["curve_k"]
    prediction = results["zero_shot"][str(k)]["mean"]
    axes.axhline(prediction, color="black", linestyle=":", label=f"prediction at K={k}")
    labels = ("rollouts", "distance of the best rollout so far (m)", f"Learning curves at K = {k}")
    return _finish(figure, axes, labels, path)


def _finish(figure, axes, labels: tuple[str, str, str], path: Path) -> Path:
    """Log-scale distances, axis labels and title, legend and grid; written to ``path``."""
    axes.set_yscale("log")
    axes.set_xlabel(labels[0])
    axes.set_ylabel(labels[1])
    axes.set_title(labels[2])
    axes.legend(fontsize=8)
    axes.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    return save_png(figure, path, dpi=120)
