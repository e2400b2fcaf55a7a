"""The paper's skill-template experiment on the simulated PA-10 throwing task (Metzen et al. 2014, Fig. 5),
and the field it is compared with on the same protocol.

Protocol (``../shared/reference/learning.md`` sections 3 and 3b), every setting fixed before the run:

0. **Spreads** (:meth:`Experiment.spread`): every method that starts a search with a spread of its own
   chooses it by one procedure, on ``validation_targets`` targets drawn from the box with their own seed
   (never the evaluation grid): for each of ``spreads``, CMA-ES from the method's start for
   ``curve_rollouts`` rollouts per target; the spread with the lowest mean distance of the best rollout so
   far, averaged over rollouts 1..curve_rollouts (the area under the learning curve) wins. Two methods have
   one: tabula rasa (from theta_0, the shipped throw towards (-3.5, -3.6); the training searches, the
   template's prior exploration and the contextual methods' start use it too) and CMA-ES from the nearest
   training theta (seed 0's first ``curve_k`` training tasks). These rollouts are reported apart.
1. **Training** (per seed): ``max(ks)`` targets drawn uniformly from the box, each learned by CMA-ES for
   ``training_rollouts`` rollouts from theta_0 with the tabula-rasa spread; theta_i is the best rollout's
   theta. The first K of them train everything "at K".
2. **Templates at K**: the shared-kernel template (:mod:`besman.skills.template_models`), its kernel chosen
   by leave-one-out throws at the training targets (:mod:`besman.learning.template_selection`, rollouts
   counted), prior exploration the tabula-rasa spread; and the per-dimension template of the first
   reproduction for comparison.
3. **Evaluation** on the ``grid`` x ``grid`` targets covering the box:
   - "No Learning": theta_0 everywhere;
   - zero shot at each K: the template's Theta(tau), the per-dimension template, the mean of the training
     thetas, the nearest training theta, affine regression and CrKR (:mod:`besman.skills.zero_shot`);
   - the template refined by CMA-ES from N(Theta(tau), Omega(tau)), the best of ``refine_rollouts``
     rollouts, at each K;
   - learning curves at K = ``curve_k`` (distance of the best rollout so far; rollout 0 is the start mean):
     CMA-ES tabula rasa, from the template with weight-proportional, uncertainty and isotropic (same trace)
     exploration, and from the nearest training theta with its own spread;
   - contextual policy search (:mod:`besman.learning.contextual_search`): C-REPS and contextual CMA-ES learn
     one policy over contexts drawn from the box, from theta_0 with the tabula-rasa spread, for
     ``contextual_rollouts`` rollouts; their mean policy is thrown on the grid every
     ``contextual_checkpoint`` rollouts;
   - variants beyond the paper: *bootstrapped* (the training tasks learned in sequence, each from the
     template of the tasks before it, Queisser and Steil 2018) and *goal only* (training and template over
     the DMP's goals and goal velocities alone, 16 of the 96 numbers, the weights kept at theta_0's: the
     null space policy search drifts in shrinks from 94 to at most 14 directions).

Distance to target is sqrt(-reward): the landing's distance for a valid throw; a failed throw (reward
<= -1000) counts as at least 31.6 m off and is counted as failed. Summaries over grid targets and seeds
together: mean +- SEM, median and failed throws. Every method's cost is its total rollouts (training and
kernel choice included) for the field plot. Every stage is written to ``DIR/work`` when it completes
(atomically), so an interrupted run resumes where it stopped; a DIR that holds a run with another
configuration, or files that no run of it wrote, is refused. The paper's claims and the goals are judged in
:mod:`besman.learning.throwing_claims`.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from besman.learning.contextual_search import CREPS, ContextBox, ContextualCMAES, contextual_search
from besman.learning.policy_search import WarmStart, make_optimizer, policy_search
from besman.learning.template_selection import choose_kernel
from besman.learning.throwing_claims import claims, goals, rollouts_to_reach
from besman.sim.throwing import FAILURE_REWARD, ThrowingConfig, ThrowingTask
from besman.skills import MovementPrimitive, zero_shot
from besman.skills.errors import InputError
from besman.skills.pool import SkillTemplatePool
from besman.skills.storage import (
    holds_files,
    npz_bytes,
    read_json,
    read_npz,
    remove_temporaries,
    write_atomically,
)
from besman.skills.template import SkillTemplate
from besman.skills.template_models import SharedKernel
from besman.skills.writer_lock import WriterLock

SCHEMA_VERSION = 2
ZERO_SHOT_METHODS = ("template", "per_dimension", "training_mean", "nearest_neighbour", "affine", "crkr")
CURVE_METHODS = ("tabula_rasa", "weight_proportional", "uncertainty", "isotropic", "nearest_start")
CONTEXTUAL_METHODS = ("creps", "contextual_cmaes")
VARIANTS = ("bootstrapped", "goal_only")
SPREAD_METHODS = ("tabula_rasa", "nearest_start")
FAILED_DISTANCE = math.sqrt(-FAILURE_REWARD)  # 31.6 m: a failed throw is at least this far off
BATCH = 256  # rollouts per evaluate() call: the rollout's state buffers grow with the batch
# The folders in DIR that a run writes (besides DIR itself), where a killed run leaves temporaries.
OUTPUT_FOLDERS = ("work", "pool")
VALIDATION_SEED = 20_141_000  # the spreads' validation targets: their own seed, never a grid


@dataclass(frozen=True)
class ExperimentConfig:
    """The protocol's numbers (the defaults are the full run)."""

    seeds: int = 3
    ks: tuple[int, ...] = (1, 2, 4, 6, 8, 10, 14, 20)
    training_rollouts: int = 200
    grid: int = 8
    refine_rollouts: int = 25
    curve_k: int = 10
    curve_rollouts: int = 68
    spreads: tuple[float, ...] = (0.1, 0.2, 0.3, 0.5, 1.0)
    validation_targets: int = 8
    contextual_rollouts: int = 3600
    contextual_checkpoint: int = 400
    method: str = "cmaes"
    variant: str = "paper"

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.grid < 2 or min(self.ks, default=0) < 1:
            raise InputError("need at least one seed, a grid of at least 2 x 2 and training sets of K >= 1")
        if list(self.ks) != sorted(set(self.ks)):
            raise InputError(f"ks must be increasing, got {self.ks}")
        if self.curve_k not in self.ks:
            raise InputError(f"curve_k {self.curve_k} must be one of ks {self.ks}")
        if not self.spreads or min(self.spreads) <= 0 or self.validation_targets < 1:
            raise InputError("need positive candidate spreads and at least one validation target")
        if min(self.training_rollouts, self.refine_rollouts, self.curve_rollouts) < 1:
            raise InputError("rollout budgets must be at least 1")
        if not 1 <= self.contextual_checkpoint <= self.contextual_rollouts:
            raise InputError("contextual_checkpoint must be between 1 and contextual_rollouts")

    @classmethod
    def quick(cls, seeds: int = 1) -> ExperimentConfig:
        """A small run for tests (about a minute): 3 x 3 grid, K in (1, 2, 4), short searches."""
        return cls(
            seeds=seeds,
            ks=(1, 2, 4),
            training_rollouts=17,
            grid=3,
            refine_rollouts=17,
            curve_k=4,
            curve_rollouts=17,
            spreads=(0.1, 1.0),
            validation_targets=2,
            contextual_rollouts=102,
            contextual_checkpoint=51,
        )


@dataclass
class Experiment:
    """Runs the protocol into ``directory``; ``backend`` is the task's ("threads" or "ray")."""

    config: ExperimentConfig
    directory: Path
    backend: str = "threads"
    progress: bool = True
    task: ThrowingTask = field(init=False)
    _stages: dict[str, dict[str, np.ndarray]] = field(init=False, default_factory=dict)  # read once

    def __post_init__(self) -> None:
        self.directory = Path(self.directory)
        self.task = ThrowingConfig(variant=self.config.variant).build()
        self.theta0 = self.task.default_theta()
        bounds = self.task.bounds
        axes = [np.linspace(lo, hi, self.config.grid) for lo, hi in zip(bounds.low, bounds.high, strict=True)]
        self.grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T
        self.validation = np.random.default_rng(VALIDATION_SEED).uniform(
            bounds.low, bounds.high, size=(self.config.validation_targets, len(bounds.names))
        )
        # The goal-only variant searches each DMP dimension's goal and goal velocity (the last two of its
        # N weights + 2 entries).
        per_dimension = self.task.dmp.n_params // self.task.dmp.n_dims
        self.goal_entries = np.array(
            [
                d * per_dimension + i
                for d in range(self.task.dmp.n_dims)
                for i in (per_dimension - 2, per_dimension - 1)
            ]
        )
        self._claim_directory()

    # -- bookkeeping -------------------------------------------------------------------------------------

    def _claim_directory(self) -> None:
        # The directory's one writer from here to the end of run() (or this process).
        self._lock = WriterLock(self.directory, "--out").acquire()
        try:
            self._check_directory()
        except BaseException:
            self._lock.release()  # refused: no lock file stays beside it
            raise

    def _check_directory(self) -> None:
        """Refuses a file, a run of another configuration and a folder of someone else's; in a run's folder
        (its configuration the same, or nothing in it but besman's temporaries), removes the temporaries
        that a killed run left."""
        stored = self.directory / "work" / "config.json"
        config = json.loads(json.dumps({"schema_version": SCHEMA_VERSION, **asdict(self.config)}))
        if self.directory.exists() and not self.directory.is_dir():
            raise InputError(f"{self.directory}: the output is a file, not a folder")
        if stored.exists():
            if read_json(stored) != config:
                raise InputError(
                    f"{self.directory} holds a run with another configuration ({stored}); use another --out"
                )
        elif holds_files(self.directory):
            raise InputError(
                f"{self.directory}: the folder is not empty and not a run of this experiment; "
                "use another --out"
            )
        else:
            write_atomically(stored, (json.dumps(config, indent=2) + "\n").encode())
        remove_temporaries(self.directory, OUTPUT_FOLDERS)

    def _stage(self, name: str, compute: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        """A stage's arrays: read from DIR/work if a previous run finished it, else computed and written;
        kept in memory, since templates, costs and diagnostics ask for the same training stages again."""
        if name not in self._stages:
            path = self.directory / "work" / f"{name}.npz"
            if path.exists():
                self._stages[name] = read_npz(path)
            else:
                self._stages[name] = compute()
                write_atomically(path, npz_bytes(self._stages[name]))
        return self._stages[name]

    def _bar(self, description: str, total: int):
        return tqdm(total=total, desc=description, unit="rollout", disable=not self.progress, leave=False)

    # -- evaluation ----------------------------------------------------------------------------------------

    def _rewards(self, thetas: np.ndarray, taus: np.ndarray) -> np.ndarray:
        rewards = np.empty(len(thetas))
        for start in range(0, len(thetas), BATCH):
            part = slice(start, start + BATCH)
            rewards[part] = self.task.evaluate(
                thetas[part], taus[part], backend=self.backend, nan="penalize"
            ).rewards
        return rewards

    def _distances(self, thetas: np.ndarray, taus: np.ndarray) -> np.ndarray:
        return _distances(self._rewards(thetas, taus))

    def _search(
        self,
        description: str,
        starts: list[WarmStart],
        taus: np.ndarray,
        budget: int,
        seed: int,
        embed: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        """CMA-ES from each start at its tau, in lockstep; ``embed`` maps a searched vector to theta."""
        optimizers = [
            make_optimizer(self.config.method, start, seed=seed * 100_003 + i)
            for i, start in enumerate(starts)
        ]
        size = optimizers[0].population_size
        total = len(starts) * (1 + math.ceil(budget / size) * size)
        with self._bar(description, total) as bar:
            bar.update(len(starts))
            return policy_search(
                lambda thetas, owners: self._rewards(
                    thetas if embed is None else embed(thetas), taus[owners]
                ),
                optimizers,
                budget=budget,
                progress=bar.update,
            )

    def _curves(self, description: str, starts: list[WarmStart], taus: np.ndarray, seed: int) -> np.ndarray:
        """(targets, curve_rollouts + 1) distances of the best rollout so far."""
        results = self._search(description, starts, taus, self.config.curve_rollouts, seed)
        return _distances(np.array([r.curve()[: self.config.curve_rollouts + 1, 2] for r in results]))

    # -- stage 0: spreads ------------------------------------------------------------------------------------

    def spread(self, method: str) -> dict[str, np.ndarray]:
        """The spread ``method`` starts its searches with, chosen on the validation targets (module doc)."""

        def compute():
            if method == "tabula_rasa":
                means = np.tile(self.theta0, (len(self.validation), 1))
            else:
                training = self.training(0)
                k = self.config.curve_k
                means = zero_shot.nearest_neighbour(
                    self.task.bounds.normalise(training["taus"][:k]),
                    training["thetas"][:k],
                    self.task.bounds.normalise(self.validation),
                )
            scores, rollouts = [], 0
            for i, spread in enumerate(self.config.spreads):
                starts = [WarmStart(mean, spread) for mean in means]
                curves = self._curves(f"{method} spread {spread:g}", starts, self.validation, 31 * i + 7)
                scores.append(curves[:, 1:].mean())
                rollouts += len(starts) * self.config.curve_rollouts
            return {
                "spreads": np.array(self.config.spreads),
                "scores": np.array(scores),
                "chosen": np.array(self.config.spreads[int(np.argmin(scores))]),
                "rollouts": np.array(rollouts),
            }

        return self._stage(f"spread_{method}", compute)

    @property
    def tabula_rasa_spread(self) -> float:
        return float(self.spread("tabula_rasa")["chosen"])

    # -- stage 1: training -----------------------------------------------------------------------------------

    def training_taus(self, seed: int) -> np.ndarray:
        bounds = self.task.bounds
        rng = np.random.default_rng(seed)
        return rng.uniform(bounds.low, bounds.high, size=(max(self.config.ks), len(bounds.names)))

    def training(self, seed: int) -> dict[str, np.ndarray]:
        def compute():
            taus = self.training_taus(seed)
            start = WarmStart(self.theta0, self.tabula_rasa_spread)
            results = self._search(
                f"seed {seed}: training", [start] * len(taus), taus, self.config.training_rollouts, seed
            )
            return _trained(taus, results)

        return self._stage(f"seed{seed}_training", compute)

    def bootstrapped_training(self, seed: int) -> dict[str, np.ndarray]:
        """The training tasks in sequence, each started from the template of the tasks before it."""

        def compute():
            taus, spread = self.training_taus(seed), self.tabula_rasa_spread
            runs = []
            for i, tau in enumerate(taus):
                if i == 0:
                    start = WarmStart(self.theta0, spread)
                else:
                    done = _trained(taus[:i], runs)
                    start = WarmStart(
                        *self._template(done["taus"], done["thetas"], SharedKernel()).distribution(tau)
                    )
                runs += self._search(
                    f"seed {seed}: bootstrapped {i + 1}/{len(taus)}",
                    [start],
                    tau[None],
                    self.config.training_rollouts,
                    seed * 7 + i,
                )
            return _trained(taus, runs)

        return self._stage(f"seed{seed}_bootstrapped_training", compute)

    def goal_only_training(self, seed: int) -> dict[str, np.ndarray]:
        """The training tasks learned over the goals and goal velocities alone (16 numbers)."""

        def compute():
            taus = self.training_taus(seed)
            start = WarmStart(self.theta0[self.goal_entries], self.tabula_rasa_spread)
            results = self._search(
                f"seed {seed}: goal-only training",
                [start] * len(taus),
                taus,
                self.config.training_rollouts,
                seed,
                embed=self._embed_goals,
            )
            trained = _trained(taus, results)
            trained["thetas"] = self._embed_goals(trained["thetas"])
            return trained

        return self._stage(f"seed{seed}_goal_only_training", compute)

    def _embed_goals(self, goals: np.ndarray) -> np.ndarray:
        thetas = np.tile(self.theta0, (len(goals), 1))
        thetas[:, self.goal_entries] = goals
        return thetas

    def trained(self, seed: int, source: str) -> dict[str, np.ndarray]:
        """The training set of ``source``: "training" (the paper's), "bootstrapped" or "goal_only"."""
        stages = {
            "training": self.training,
            "bootstrapped": self.bootstrapped_training,
            "goal_only": self.goal_only_training,
        }
        return stages[source](seed)

    # -- stage 2: templates ----------------------------------------------------------------------------------

    def _prior_spread(self, source: str) -> np.ndarray:
        spread = np.full(self.theta0.size, self.tabula_rasa_spread)
        if source == "goal_only":  # nothing else is ever searched
            spread = np.zeros(self.theta0.size)
            spread[self.goal_entries] = self.tabula_rasa_spread
        return spread

    def _template(self, taus, thetas, kernel: SharedKernel, source: str = "training") -> SkillTemplate:
        prototype = MovementPrimitive(self.task.dmp, "throw", robot="pa10", group="arm")
        return SkillTemplate(
            "throw",
            prototype,
            taus,
            thetas,
            self.task.bounds,
            kernel=kernel,
            prior_spread=self._prior_spread(source),
            task=f"throwing/{self.config.variant}",
        )

    def kernel_choice(self, seed: int, k: int, source: str = "training") -> dict[str, np.ndarray]:
        """The shared kernel for the first k tasks of ``source``, by leave-one-out throws."""

        def compute():
            data = self.trained(seed, source)
            choice = choose_kernel(data["taus"][:k], data["thetas"][:k], self.task.bounds, self._distances)
            return {
                "kernel": np.array(json.dumps(asdict(choice.kernel))),
                "losses": np.array(choice.losses),
                "rollouts": np.array(choice.rollouts),
            }

        return self._stage(f"seed{seed}_{source}_k{k}_kernel", compute)

    def template(self, seed: int, k: int, source: str = "training") -> SkillTemplate:
        data = self.trained(seed, source)
        kernel = SharedKernel(**json.loads(str(self.kernel_choice(seed, k, source)["kernel"])))
        template = self._template(data["taus"][:k], data["thetas"][:k], kernel, source)
        template.provenance = {"experiment": "throwing", "seed": seed, "training_tasks": k, "source": source}
        return template

    # -- stage 3: evaluation ---------------------------------------------------------------------------------

    def no_learning(self) -> np.ndarray:
        return self._stage(
            "no_learning",
            lambda: {"distances": self._distances(np.tile(self.theta0, (len(self.grid), 1)), self.grid)},
        )["distances"]

    def per_k(self, seed: int, k: int) -> dict[str, np.ndarray]:
        """Every zero-shot method's grid distances at K = k, and the template refined."""

        def compute():
            training = self.training(seed)
            taus, thetas = training["taus"][:k], training["thetas"][:k]
            template = self.template(seed, k)
            inputs, queries = self.task.bounds.normalise(taus), self.task.bounds.normalise(self.grid)
            per_dimension = SkillTemplate(
                "throw", template.prototype, taus, thetas, self.task.bounds, model="per_dimension", seed=seed
            )
            predictions = {
                "template": template.predict(self.grid)[0],
                "per_dimension": per_dimension.predict(self.grid)[0],
                "training_mean": zero_shot.training_mean(inputs, thetas, queries),
                "nearest_neighbour": zero_shot.nearest_neighbour(inputs, thetas, queries),
                "affine": zero_shot.affine_regression(inputs, thetas, queries),
                "crkr": zero_shot.crkr(inputs, thetas, queries, np.exp(-_distances(training["rewards"][:k]))),
            }
            distances = self._distances(
                np.concatenate([predictions[m] for m in ZERO_SHOT_METHODS]),
                np.tile(self.grid, (len(ZERO_SHOT_METHODS), 1)),
            ).reshape(len(ZERO_SHOT_METHODS), len(self.grid))
            starts = [WarmStart(*template.distribution(tau)) for tau in self.grid]
            results = self._search(
                f"seed {seed}: K={k} refinement", starts, self.grid, self.config.refine_rollouts, seed + 7 * k
            )
            refined = [r.curve()[min(self.config.refine_rollouts, r.rollouts), 2] for r in results]
            return {
                **{f"zero_shot_{m}": d for m, d in zip(ZERO_SHOT_METHODS, distances, strict=True)},
                "refined": _distances(np.array(refined)),
            }

        return self._stage(f"seed{seed}_k{k}", compute)

    def variant_zero_shot(self, seed: int, k: int, variant: str) -> np.ndarray:
        return self._stage(
            f"seed{seed}_{variant}_k{k}",
            lambda: {
                "distances": self._distances(self.template(seed, k, variant).predict(self.grid)[0], self.grid)
            },
        )["distances"]

    def curves(self, seed: int, method: str) -> np.ndarray:
        """(grid targets, curve_rollouts + 1) distances of the best rollout so far."""

        def compute():
            k = self.config.curve_k
            if method == "tabula_rasa":
                starts = [WarmStart(self.theta0, self.tabula_rasa_spread)] * len(self.grid)
            elif method == "nearest_start":
                training = self.training(seed)
                means = zero_shot.nearest_neighbour(
                    self.task.bounds.normalise(training["taus"][:k]),
                    training["thetas"][:k],
                    self.task.bounds.normalise(self.grid),
                )
                spread = float(self.spread("nearest_start")["chosen"])
                starts = [WarmStart(mean, spread) for mean in means]
            else:
                template = self.template(seed, k).with_exploration(method)
                starts = [WarmStart(*template.distribution(tau)) for tau in self.grid]
            offset = 1000 + CURVE_METHODS.index(method)
            return {
                "distances": self._curves(f"seed {seed}: {method}", starts, self.grid, seed * 7919 + offset)
            }

        return self._stage(f"seed{seed}_curve_{method}", compute)["distances"]

    def contextual(self, seed: int, method: str) -> dict[str, np.ndarray]:
        """The mean policy's grid distances at every checkpoint of a contextual search."""

        def compute():
            bounds = self.task.bounds
            kind = {"creps": CREPS, "contextual_cmaes": ContextualCMAES}[method]
            box = ContextBox(np.array(bounds.low), np.array(bounds.high))
            optimizer = kind(self.theta0, self.tabula_rasa_spread, seed=seed * 131 + 17, context_box=box)
            rows, checkpoints = [], []

            def on_checkpoint(rollouts, policy):
                checkpoints.append(rollouts)
                rows.append(self._distances(policy.policy_mean(self.grid), self.grid))

            with self._bar(f"seed {seed}: {method}", self.config.contextual_rollouts) as bar:
                contextual_search(
                    lambda thetas, contexts: self._rewards(thetas, contexts),
                    optimizer,
                    budget=self.config.contextual_rollouts,
                    sample_contexts=lambda rng, count: rng.uniform(
                        bounds.low, bounds.high, (count, bounds.size)
                    ),
                    seed=seed * 977 + 3,
                    checkpoint_every=self.config.contextual_checkpoint,
                    on_checkpoint=on_checkpoint,
                    progress=bar.update,
                )
            return {"rollouts": np.array(checkpoints), "distances": np.array(rows)}

        return self._stage(f"seed{seed}_{method}", compute)

    def diagnose_training(self, seed: int) -> dict:
        """How the training set looks to a template: the training thetas' own distances, how far they drifted
        from theta_0, whether theta distances follow target distances, and the kernels chosen."""
        training = self.training(seed)
        taus, thetas = training["taus"], training["thetas"]
        pairs = np.triu_indices(len(taus), 1)
        tau_gaps = np.linalg.norm(taus[:, None] - taus[None], axis=2)[pairs]
        theta_gaps = np.linalg.norm(thetas[:, None] - thetas[None], axis=2)[pairs]
        return {
            "seed": seed,
            "trained_distance": float(_distances(training["rewards"]).mean()),
            "theta_vs_tau_distance_correlation": float(np.corrcoef(tau_gaps, theta_gaps)[0, 1]),
            "theta_drift_from_theta0": float(np.linalg.norm(thetas - self.theta0, axis=1).mean()),
            "kernels": {
                str(k): {
                    "kernel": json.loads(str(choice["kernel"])),
                    "leave_one_out_distances": choice["losses"].tolist(),
                }
                for k in self.config.ks
                for choice in [self.kernel_choice(seed, k)]
            },
        }

    # -- the whole run -------------------------------------------------------------------------------------

    def run(self) -> dict:
        """Runs (or resumes) every stage and writes results.json, fig5_top.png, fig5_bottom.png,
        fig_field.png and a pool (``pool/``) with the first seed's template of all K_max training tasks."""
        try:
            return self._run()
        finally:
            self._lock.release()

    def _run(self) -> dict:
        started = time.monotonic()
        config, seeds = self.config, range(self.config.seeds)
        spreads = {method: self.spread(method) for method in SPREAD_METHODS}
        no_learning = np.tile(self.no_learning(), config.seeds)
        zero, refined, costs = {m: {} for m in ZERO_SHOT_METHODS}, {}, {}
        for k in config.ks:
            stages = [self.per_k(seed, k) for seed in seeds]
            for method in ZERO_SHOT_METHODS:
                zero[method][k] = np.concatenate([s[f"zero_shot_{method}"] for s in stages])
            refined[k] = np.concatenate([s["refined"] for s in stages])
            costs[k] = self._cost(k, "training")
        curves = {m: np.concatenate([self.curves(seed, m) for seed in seeds]) for m in CURVE_METHODS}
        contextual = {}
        for method in CONTEXTUAL_METHODS:
            stages = [self.contextual(seed, method) for seed in seeds]
            contextual[method] = (
                stages[0]["rollouts"],
                np.concatenate([s["distances"] for s in stages], axis=1),
            )
        variants = {
            v: {
                k: (np.concatenate([self.variant_zero_shot(s, k, v) for s in seeds]), self._cost(k, v))
                for k in config.ks
            }
            for v in VARIANTS
        }
        results = {
            "schema_version": SCHEMA_VERSION,
            "kind": "besman-throwing-experiment",
            "config": {**json.loads(json.dumps(asdict(config))), "backend": self.backend},
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
            "template_refined": {str(k): summary(v) for k, v in refined.items()},
            "curves": {
                m: [[r, *summary(v[:, r]).values()] for r in range(v.shape[1])] for m, v in curves.items()
            },
            "contextual": {
                m: [[int(r), *summary(d[i]).values()] for i, r in enumerate(rollouts)]
                for m, (rollouts, d) in contextual.items()
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
        results["training"] = [self.diagnose_training(seed) for seed in seeds]
        results["claims"] = claims(results)
        results["goals"] = goals(results)
        results["minutes"] = round(
            (time.monotonic() - started) / 60, 1
        )  # of this invocation (resumed stages are free)
        write_atomically(self.directory / "results.json", (json.dumps(results, indent=2) + "\n").encode())
        from besman.learning.throwing_plots import plot_results  # matplotlib only when plotting

        plot_results(results, self.directory)
        # The first seed's template of all K_max training tasks, for use: besman view --throw DIR/pool
        SkillTemplatePool(self.directory / "pool").add(self.template(0, max(config.ks)), overwrite=True)
        return results

    def _cost(self, k: int, source: str) -> dict[str, float]:
        """Mean rollouts over seeds behind the first k tasks of ``source``: their training, and the shared
        template's leave-one-out throws for its kernel."""
        seeds = range(self.config.seeds)
        return {
            "training": float(np.mean([self.trained(s, source)["rollouts"][:k].sum() for s in seeds])),
            "kernel_choice": float(
                np.mean([int(self.kernel_choice(s, k, source)["rollouts"]) for s in seeds])
            ),
        }


def _trained(taus: np.ndarray, results) -> dict[str, np.ndarray]:
    return {
        "taus": taus,
        "thetas": np.array([r.best_theta for r in results]),
        "rewards": np.array([r.best_reward for r in results]),
        "rollouts": np.array([r.rollouts + 1 for r in results]),  # the start mean's rollout included
    }


def _distances(rewards: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(-np.asarray(rewards, dtype=float), 0.0))


def summary(values: np.ndarray) -> dict:
    """Mean, its standard error, median and the number of failed throws (and how many there are)."""
    values = np.asarray(values, dtype=float)
    sem = float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else 0.0
    return {
        "mean": float(values.mean()),
        "sem": sem,
        "median": float(np.median(values)),
        "failed": int((values >= FAILED_DISTANCE - 1e-9).sum()),
        "count": len(values),
    }


def field_series(results: dict) -> dict[str, list[list[float]]]:
    """Every method as rows [total rollouts, mean, sem, median, failed] on the grid (module documentation):
    a zero-shot method at K costs K training tasks (and the template its kernel choice), a refinement its
    start's cost plus the rollouts of the new task."""
    config, costs = results["config"], {int(k): c for k, c in results["rollouts"].items()}
    training = {k: c["training"] for k, c in costs.items()}
    template = {k: c["training"] + c["kernel_choice"] for k, c in costs.items()}

    def row(x, s):
        return [float(x), s["mean"], s["sem"], s["median"], s["failed"]]

    series = {"no_learning": [row(0, results["no_learning"])]}
    for method, by_k in results["zero_shot"].items():
        cost = template if method == "template" else training
        series[f"zero_shot_{method}"] = [row(cost[int(k)], s) for k, s in by_k.items()]
    series["template_refined"] = [
        row(template[int(k)] + config["refine_rollouts"], s) for k, s in results["template_refined"].items()
    ]
    for method, rows in results["curves"].items():
        start = {"tabula_rasa": 0, "nearest_start": training[config["curve_k"]]}.get(
            method, template[config["curve_k"]]
        )
        series[f"curve_{method}"] = [[start + r[0], *r[1:]] for r in rows]
    for method, rows in results["contextual"].items():
        series[method] = [[float(r[0]), *r[1:]] for r in rows]
    for variant, by_k in results["variants"].items():
        series[f"variant_{variant}"] = [
            row(s["rollouts"]["training"] + s["rollouts"]["kernel_choice"], s) for s in by_k.values()
        ]
    return series
