"""The plots of a template study (:mod:`besman.experiments.template_study`) from its results."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _save(plt, fig, path: Path) -> Path:
    """Writes the figure to ``path`` and closes it."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot(results: dict, directory: Path) -> list[Path]:
    """learning_curves.png (one tau from the demonstration) and template.png (vs K, and over tau)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    single, summary = results["single"], results["summary"]
    scripted = summary["scripted_baseline_rate"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    for entry in single["taus"]:
        success = np.array([c["success_so_far"] for c in entry["curves"]], dtype=float)
        cost = np.array([c["best_cost_so_far"] for c in entry["curves"]])
        x = np.arange(success.shape[1])
        label = ", ".join(f"{value:.3f}" for value in entry["tau"])
        left.plot(x, success.mean(axis=0), label=label)
        line = right.plot(x, np.median(cost, axis=0), label=label)[0]
        right.fill_between(x, cost.min(axis=0), cost.max(axis=0), color=line.get_color(), alpha=0.15)
    seeds = len(single["taus"][0]["curves"])
    left.axhline(scripted, color="grey", ls="--", label=f"scripted baseline (held out) {scripted:.0%}")
    left.axvline(75, color="k", ls=":", lw=0.8, label="75 rollouts (Kober & Peters' ball in a cup)")
    left.set(
        xlabel="rollouts (0: the imitated demonstration)",
        ylabel=f"fraction of {seeds} seeds succeeded so far",
        title=f"CMA-ES from the demonstration, one {results['tau_label']}",
    )
    right.set(xlabel="rollouts", ylabel="best cost so far (median, range over seeds)", yscale="log")
    right.set_title(f"cost: {results['cost_label']}", fontsize=9)
    left.legend(fontsize=8)
    right.legend(fontsize=8)
    written.append(_save(plt, fig, directory / "learning_curves.png"))

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    ks = results["config"]["ks"]
    zero = np.array([[e["zero_shot_rate"] for e in s["per_k"]] for s in results["templates"]])
    refined = np.array([[e["refined_rate"] for e in s["per_k"]] for s in results["templates"]])
    budget = results["config"]["refine_budget"]
    for values, label in ((zero, "zero shot"), (refined, f"after <= {budget} more rollouts")):
        line = left.plot(ks, values.mean(axis=0), marker="o", label=label)[0]
        left.fill_between(ks, values.min(axis=0), values.max(axis=0), color=line.get_color(), alpha=0.15)
    for name, style in zip(results["baselines"], ("--", "-.", ":"), strict=False):
        rate = summary[f"{name}_rate"]
        left.axhline(rate, color="grey", ls=style, label=f"{name.replace('_', ' ')} {rate:.0%}")
    left.set(
        xlabel="training tasks K",
        ylabel=f"success on the held-out {results['tau_label']}s",
        ylim=(-0.03, 1.03),
        title=f"skill template, {len(results['templates'])} seeds (mean, range)",
    )
    left.legend(fontsize=8)
    k = results["config"]["k"]
    finals = [next(e for e in s["per_k"] if e["k"] == k) for s in results["templates"]]
    held_out = np.array(results["held_out"])
    if held_out.shape[1] == 1:
        _over_length(right, results, held_out[:, 0], finals, k)
    else:
        _over_plane(right, results, held_out, finals, k)
    written.append(_save(plt, fig, directory / "template.png"))
    return written


def _over_length(axes, results: dict, taus: np.ndarray, finals: list, k: int) -> None:
    """Success over a 1-D tau: per held-out tau, the fraction of seeds; ticks on top: training taus."""
    order = np.argsort(taus)
    for key, label, marker in (("zero_shot", "zero shot", "o"), ("refined", "after refinement", "x")):
        rate = np.mean([e[key] for e in finals], axis=0)
        axes.plot(taus[order], rate[order], marker=marker, ls="-", lw=0.8, label=f"template K = {k}, {label}")
    axes.plot(
        taus[order],
        np.array(results["scripted_baseline"])[order],
        marker="s",
        ls="none",
        color="grey",
        label="scripted baseline",
    )
    for s in results["templates"]:
        training = [tau[0] for tau in s["training_taus"]]
        axes.plot(training, [1.06] * len(training), "|", color="k")
    axes.set(
        xlabel=f"{results['tau'][0]}; ticks on top: training {results['tau_label']}s",
        ylabel="fraction of seeds succeeded",
        ylim=(-0.05, 1.1),
        title=f"held-out {results['tau_label']}s",
    )
    axes.legend(fontsize=8, loc="lower left")


def _over_plane(axes, results: dict, taus: np.ndarray, finals: list, k: int) -> None:
    """Success over a 2-D tau: each held-out tau coloured by the fraction of seeds succeeding zero shot,
    ringed where refinement still missed on some seed; seed 0's training taus as crosses."""
    zero = np.mean([e["zero_shot"] for e in finals], axis=0)
    refined = np.mean([e["refined"] for e in finals], axis=0)
    points = axes.scatter(taus[:, 0], taus[:, 1], c=zero, cmap="RdYlGn", vmin=0, vmax=1, s=40)
    missed = refined < 1
    axes.scatter(
        taus[missed, 0],
        taus[missed, 1],
        s=120,
        facecolors="none",
        edgecolors="k",
        lw=0.8,
        label="missed after refinement (some seed)",
    )
    training = np.array(results["templates"][0]["training_taus"])
    axes.plot(training[:, 0], training[:, 1], "k+", ms=9, label="training (seed 0)")
    axes.figure.colorbar(points, ax=axes, label=f"fraction of seeds succeeding zero shot, K = {k}")
    axes.set(xlabel=results["tau"][0], ylabel=results["tau"][1], title=f"held-out {results['tau_label']}s")
    axes.set_aspect("equal", adjustable="datalim")
    axes.legend(fontsize=8, loc="lower left")
