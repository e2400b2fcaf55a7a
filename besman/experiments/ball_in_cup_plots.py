"""The plots of the ball-in-a-cup experiment (:mod:`besman.experiments.ball_in_cup`) from its results."""

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
    """learning_curves.png (one length from the demonstration) and template.png (vs K and vs length)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    single = results["single"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    for entry in single["lengths"]:
        success = np.array([c["success_so_far"] for c in entry["curves"]], dtype=float)
        cost = np.array([c["best_cost_so_far_m"] for c in entry["curves"]])
        x = np.arange(success.shape[1])
        label = f"{entry['string_length_m']:.3f} m"
        left.plot(x, success.mean(axis=0), label=label)
        line = right.plot(x, np.median(cost, axis=0), label=label)[0]
        right.fill_between(x, cost.min(axis=0), cost.max(axis=0), color=line.get_color(), alpha=0.15)
    seeds = len(single["lengths"][0]["curves"])
    scripted = results["summary"]["scripted_baseline_rate"]
    left.axhline(scripted, color="grey", ls="--", label=f"scripted baseline (held out) {scripted:.0%}")
    left.axvline(75, color="k", ls=":", lw=0.8)
    left.set(
        xlabel="rollouts (0: the imitated demonstration)",
        ylabel=f"fraction of {seeds} seeds caught so far",
        title="CMA-ES from the demonstration, one string length",
    )
    right.set(xlabel="rollouts", ylabel="best cost so far (m; median, range over seeds)", yscale="log")
    right.set_title("cost: distance from the cup's axis at the rim")
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
    left.axhline(scripted, color="grey", ls="--", label="scripted baseline")
    imitated = results["summary"]["demonstration_imitated_rate"]
    left.axhline(imitated, color="brown", ls=":", label=f"imitated demonstration {imitated:.0%}")
    left.set(
        xlabel="training tasks K",
        ylabel="success on the held-out lengths",
        ylim=(-0.03, 1.03),
        title=f"skill template, {len(results['templates'])} seeds (mean, range)",
    )
    left.legend(fontsize=8)
    lengths = np.array(results["held_out_m"])
    order = np.argsort(lengths)
    k = results["config"]["k"]
    finals = [next(e for e in s["per_k"] if e["k"] == k) for s in results["templates"]]
    for key, label, marker in (("zero_shot", "zero shot", "o"), ("refined", "after refinement", "x")):
        rate = np.mean([e[key] for e in finals], axis=0)
        right.plot(
            lengths[order], rate[order], marker=marker, ls="-", lw=0.8, label=f"template K = {k}, {label}"
        )
    right.plot(
        lengths[order],
        np.array(results["scripted_baseline"])[order],
        marker="s",
        ls="none",
        color="grey",
        label="scripted baseline",
    )
    for s in results["templates"]:
        right.plot(s["training_lengths_m"], [1.06] * len(s["training_lengths_m"]), "|", color="k")
    right.set(
        xlabel="string length (m); ticks on top: training lengths",
        ylabel="fraction of seeds caught",
        ylim=(-0.05, 1.1),
        title="held-out lengths",
    )
    right.legend(fontsize=8, loc="lower left")
    written.append(_save(plt, fig, directory / "template.png"))
    return written
