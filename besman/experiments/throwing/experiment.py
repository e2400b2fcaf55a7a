"""The paper's skill-template experiment on the simulated PA-10 throwing task (Metzen et al. 2014, Fig. 5),
besman's own outcome template, and the field they are compared with on the same protocol.

Protocol (``../shared/reference/learning.md`` sections 3, 3b and 3c), every setting fixed before the run and
none chosen on the evaluation grid:

0. **Validation targets and spreads** (:func:`besman.experiments.throwing.bench.validation_targets`,
   :mod:`besman.experiments.throwing.spreads`): ``validation_targets`` targets drawn from the box and as many
   on its edges, with their own seed; every setting below is chosen on them. Every method that starts a search
   with a spread of its own chooses it by one procedure: for each of ``spreads``, CMA-ES from the method's
   start for ``curve_rollouts`` rollouts per target; the spread with the lowest mean distance of the best
   rollout so far, averaged over rollouts 1..curve_rollouts (the area under the learning curve) wins. Two
   methods have one: tabula rasa (from theta_0, the shipped throw towards (-3.5, -3.6); the training
   searches, the template's prior exploration and the contextual methods' start use it too) and CMA-ES from
   the nearest training theta (seed 0's first ``curve_k`` training tasks). These rollouts are reported apart.
1. **Training** (per seed, :mod:`besman.experiments.throwing.training`): ``max(ks)`` targets drawn uniformly
   from the box, each learned by CMA-ES for ``training_rollouts`` rollouts from theta_0 with the tabula-rasa
   spread; theta_i is the best rollout's theta, and every rollout that landed is kept with its landing. The
   landing's Jacobian in the 16 goal coordinates at each theta_i, by central differences of
   ``jacobian_step`` (33 rollouts per task, counted). The first K tasks train everything "at K".
2. **Templates at K** (:mod:`besman.experiments.throwing.templates`): the paper's shared-kernel template
   (:mod:`besman.skills.template_models`), its kernel chosen by throws at the validation targets
   (:mod:`besman.learning.template_selection`, rollouts counted), prior exploration the tabula-rasa spread;
   besman's outcome template (:func:`besman.skills.zero_shot.nearest_outcome`: the training rollout whose
   landing is nearest the target); the per-dimension template of the first reproduction for comparison.
3. **The guard** (:mod:`besman.learning.search.feasibility`): every theta any method proposes (a zero-shot
   prediction, a search's start mean, a contextual method's proposal and mean) whose reference would fail
   is pulled back toward a feasible anchor before it is thrown, and counted.
4. **Evaluation** on the ``grid`` x ``grid`` targets covering the box
   (:mod:`besman.experiments.throwing.evaluation`, the searches in :mod:`besman.experiments.throwing.curves`
   and
   :mod:`besman.experiments.throwing.contextual`):
   - "No Learning": theta_0 everywhere;
   - zero shot at each K, on the grid and at the validation targets: the paper's template, besman's outcome
     template, the per-dimension template, the mean of the training thetas, the nearest training theta,
     affine regression and CrKR (:mod:`besman.skills.zero_shot`);
   - the paper's template refined by CMA-ES from N(Theta(tau), Omega(tau)), the best of ``refine_rollouts``
     rollouts, at each K;
   - learning curves at K = ``curve_k`` (distance of the best rollout so far; rollout 0 is the start mean):
     CMA-ES tabula rasa, from the paper's template with weight-proportional, uncertainty and isotropic (same
     trace) exploration, and from the nearest training theta with its own spread; and besman's outcome-space
     refinement from its outcome template, ``outcome_throws`` throws (:mod:`besman.learning.
     outcome_refinement`);
   - contextual policy search: C-REPS and contextual CMA-ES, their settings chosen among declared candidates
     on the validation targets by one procedure, learn one policy over contexts drawn from the box, from
     theta_0 with the tabula-rasa spread, for ``contextual_rollouts`` rollouts; their mean policy is thrown
     on the grid every ``contextual_checkpoint`` rollouts;
   - variants beyond the paper: *bootstrapped* (the training tasks learned in sequence, each from the
     template of the tasks before it, Queisser and Steil 2018) and *goal only* (training and template over
     the DMP's goals and goal velocities alone, 16 of the 96 numbers, the weights kept at theta_0's: the
     null space policy search drifts in shrinks from 94 to at most 14 directions).

Distance to target is sqrt(-reward): the landing's distance for a valid throw; a failed throw (reward
<= -1000) counts as at least 31.6 m off and is counted as failed. Summaries over grid targets and seeds
together: mean +- SEM, median, failed throws and the mean of the throws that did not fail. Every method's cost
is its total rollouts (training, kernel choice and Jacobians where it uses them) for the field plot. Every
stage is written to ``DIR/work`` when it completes (atomically), so an interrupted run resumes where it
stopped; a DIR that holds a run with another configuration, or files that no run of it wrote, is refused
(:mod:`besman.experiments.throwing.output`). ``results.json`` is gathered by
:mod:`besman.experiments.throwing.results`; the paper's claims, the goals and issue 39's acceptance are judged
in :mod:`besman.experiments.throwing.claims`. The settings are :mod:`besman.experiments.throwing.config`'s;
the task, its targets, the guard and the rollouts, :mod:`besman.experiments.throwing.bench`'s.
"""

from __future__ import annotations

import json
import time

from besman.core.storage import write_atomically
from besman.experiments.throwing.config import (
    CONTEXTUAL_METHODS,
    CURVE_METHODS,
    VARIANTS,
    ZERO_SHOT_METHODS,
    ExperimentConfig,
)
from besman.experiments.throwing.results import FAILED_DISTANCE, collect_results, field_series, summary
from besman.experiments.throwing.stages import Stages
from besman.skills.pool import SkillTemplatePool

# The names that the command line and the tests import from here.
__all__ = [
    "CONTEXTUAL_METHODS",
    "CURVE_METHODS",
    "FAILED_DISTANCE",
    "VARIANTS",
    "ZERO_SHOT_METHODS",
    "Experiment",
    "ExperimentConfig",
    "field_series",
    "summary",
]


class Experiment(Stages):
    """Runs the protocol into ``directory``; ``backend`` is the task's ("threads" or "ray"). Made, it claims
    ``directory`` (refusing another configuration's run or someone else's files) until :meth:`run` ends."""

    def run(self) -> dict:
        """Runs (or resumes) every stage and writes results.json, fig5_top.png, fig5_bottom.png,
        fig_field.png and a pool (``pool/``) with the first seed's template of all K_max training tasks."""
        try:
            return self._run()
        finally:
            self.folder.release()

    def _run(self) -> dict:
        started = time.monotonic()
        results = collect_results(self)
        # The wall time of this invocation: stages resumed from DIR/work cost nothing.
        results["minutes"] = round((time.monotonic() - started) / 60, 1)
        write_atomically(self.directory / "results.json", (json.dumps(results, indent=2) + "\n").encode())
        from besman.experiments.throwing.plots import plot_results  # matplotlib only when plotting

        plot_results(results, self.directory)
        # The first seed's template of all K_max training tasks, for use: besman view --throw DIR/pool
        SkillTemplatePool(self.directory / "pool").add(
            self.templates.template(0, max(self.config.ks)), overwrite=True
        )
        return results
