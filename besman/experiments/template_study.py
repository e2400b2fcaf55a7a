"""A template study of an open-loop task: one tau learned from its demonstration, then a skill template over
tau, judged on held-out taus beside the task's scripted baselines.

A task whose policy search runs open loop (:class:`~besman.sim.open_loop.OpenLoopRollouts`: ball-in-a-cup,
the puck strike) says what is its own in a :class:`Study` (its demonstration, its baselines, its search's
spread, how a training evaluation is made robust, its kernels, whether its training tasks are refined
together); :class:`Experiment` runs the protocol every such study shares, every setting fixed before the run
and none chosen on the held-out taus:

0. **Held-out taus**: ``held_out`` taus, a Latin hypercube over the task's box with seed
   :data:`HELD_OUT_SEED` (the task's benchmark's). Nothing is trained, chosen or tuned on them; they are only
   evaluated, by the study's baselines too (the scripted baseline: the best hand-written motion).
1. **One tau from the demonstration** (:meth:`Experiment.single`): CMA-ES from the imitated demonstration
   (``WarmStart(theta_demo, sigma)``, its default population of 16), the task's plain reward, at the
   held-out taus nearest ``single_quantiles`` of the box (the same fraction of every coordinate), one search
   per seed, ``single_budget`` rollouts each (not stopped at the first success, for the cost curves).
   Reported: the rollouts to the first success (the start mean is rollout 0, not counted) and the curves of
   success so far and of the best cost so far (the reward without the success bonus, negated).
2. **Training tasks** (per seed s, :meth:`Experiment.training`): K = ``k`` taus, a Latin hypercube with seed
   :data:`TRAINING_SEED` + s (none equal to a held-out tau: checked), learned as a chain: first the study's
   ``first`` task, then again and again the unsolved task nearest (in box widths) to a solved one, each
   warm-started from the theta of the solved task nearest to it (the first from the imitated
   demonstration). A training evaluation is the study's robust one (the mean reward over the study's
   ``neighbourhood`` of tau). A start that already scores above the study's ``training_target`` is kept;
   otherwise CMA-ES at ``sigma`` searches until an evaluation does, or ``training_budget`` evaluations (in
   whole generations: up to one population more), and the best is kept. Stopping there keeps neighbouring
   thetas close.
3. **The template** (:meth:`Experiment.template`): the shared-kernel
   :class:`~besman.skills.template.SkillTemplate` of the first K training tasks of the draw. The templates
   of fewer tasks (the curve over ``ks``) take the first K of the draw, trained in the chain of all ``k``.
   Where the study refines its training tasks together (``joint_sigma``, and the config's
   ``joint_budget``), contextual CMA-ES (:class:`~besman.learning.search.contextual.ContextualCMAES`, an
   affine policy theta = W [1, tau]) starts from the least-squares affine fit of the K chained thetas with
   spread ``joint_sigma`` and searches on rollouts at those K taus (drawn uniformly) for ``joint_budget``
   rollouts; the template is then the policy's mean at the K taus with the study's first kernel, whose
   affine drift reproduces the policy (K must be at least tau's dimension + 2: the drift, and Omega's
   leave-one-out residuals; with fewer tasks, as below).
   Otherwise the kernel is chosen among the study's ``kernels`` by leave-one-out over the training tasks
   (each predicted from the others and evaluated there robustly, counted): the highest mean reward wins,
   ties to the first; with fewer than 3 tasks the study's ``few_tasks_kernel``.
4. **Evaluation** on the held-out taus, per seed and K: zero shot (the template's mean, one rollout) and,
   where that misses, refinement by CMA-ES from N(Theta(tau), Omega(tau)) with the study's
   ``refine_population`` for ``refine_budget`` more rollouts, stopped at the first success. Each refinement
   is judged (:func:`~besman.learning.search.acceptance.judge`): its start and its best theta within the
   budget evaluated :data:`REEVALUATIONS` more times, paired, beside the search's own rewards of them; the
   best is kept only where its improvement exceeds the noise (the spread of the start's rewards), and whether
   the theta kept succeeds again exactly where the search found a success is reported.

Everything is seeded and the rollouts are deterministic: the same command writes the same numbers (apart from
the wall times). Every search's seed is derived from the run's seed, its stage and its keys
(:func:`~besman.core.seeds.child_seed`), so no two searches share a random stream. The study's module says
how its settings were chosen.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from besman import examples
from besman.core.errors import InputError
from besman.core.seeds import child_seed
from besman.learning.search.acceptance import reevaluated_searches
from besman.learning.search.contextual import (
    ContextBox,
    ContextualCMAES,
    ContextualCMAESConfig,
    contextual_search,
)
from besman.learning.search.linear_gaussian import context_features
from besman.learning.search.policy_search import WarmStart, make_optimizer, policy_search
from besman.learning.template_selection import predictions
from besman.sim.open_loop import SUCCESS
from besman.skills import MovementPrimitive
from besman.skills.pool import SkillTemplatePool
from besman.skills.shared_kernel import SharedKernel
from besman.skills.template import SkillTemplate
from besman.tasks import task as registered

# 2: the keys of any tau (held_out, single.taus, training_taus), not a length's; 3: each refinement's verdict
SCHEMA_VERSION = 3
HELD_OUT_SEED = 1
TRAINING_SEED = 10  # + the seed: the training taus' Latin hypercube
REEVALUATIONS = 2  # more evaluations of each refinement's start and best theta, for its verdict
# The searches' seeds: child_seed(seed, STAGE, its keys), unrelated between stages, seeds, K and tasks.
SINGLE, TRAINING, JOINT_POLICY, JOINT_CONTEXTS, REFINEMENT = range(1, 6)


@dataclass(frozen=True)
class Config:
    """The protocol's sizes."""

    seeds: int = 5
    k: int = 10
    ks: tuple[int, ...] = (1, 2, 3, 4, 6, 8, 10)
    held_out: int = 50
    training_budget: int = 150
    refine_budget: int = 10
    single_seeds: int = 5
    single_quantiles: tuple[float, ...] = (0.1, 0.5, 0.9)
    single_budget: int = 200
    joint_budget: int = 0  # rollouts of the training tasks' refinement together (0: none)

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.k < 1 or self.held_out < 1 or self.single_seeds < 1:
            raise InputError("need at least one seed, training task, held-out tau and single-tau seed")
        if list(self.ks) != sorted(set(self.ks)) or self.ks[-1] != self.k or self.ks[0] < 1:
            raise InputError(f"ks must increase from 1 or more to k = {self.k}, got {self.ks}")
        if min(self.training_budget, self.refine_budget, self.single_budget) < 1 or self.joint_budget < 0:
            raise InputError("rollout budgets must be at least 1 (the joint refinement's at least 0)")


Baseline = Callable[[object, np.ndarray], object]  # (rollouts, taus (N, d)) -> their Evaluation


@dataclass(frozen=True)
class Study:
    """What one task's template study says about itself; see the module documentation for where each
    part enters the protocol."""

    experiment: str  # the results' name and the command's: besman experiment NAME
    task: str  # the registry's task
    robot: str
    template: str  # the template's name in a pool
    demonstration: str  # a file in examples/data
    imitate: Callable  # (rollouts, times, joints) -> theta
    load_demonstration: Callable  # (path) -> (times, joints)
    baselines: tuple[tuple[str, Baseline], ...]  # ("scripted_baseline", ...) first, on the held-out taus
    sigma: float  # CMA-ES's spread from the demonstration and from a solved task; the template's prior
    training_target: float  # a training search stops at a robust reward above this
    neighbourhood: Callable[[np.ndarray, object], np.ndarray]  # (tau (d,), box) -> taus (r, d) it averages
    first: Callable[[np.ndarray], int]  # the training taus (K, d) -> the index learned first
    refine_population: int
    kernels: tuple[SharedKernel, ...]
    few_tasks_kernel: SharedKernel
    config: Config
    quick: Config
    joint_sigma: float | None = None  # the training tasks refined together from this spread (None: not)
    tau_label: str = "tau"  # for reports and plots
    cost_label: str = "cost"

    def __post_init__(self) -> None:
        where = f"study {self.experiment}"
        if not self.baselines or self.baselines[0][0] != "scripted_baseline":
            raise InputError(f"{where}: baselines must start with 'scripted_baseline' (the plots' reference)")
        if not self.kernels:
            raise InputError(f"{where}: kernels must name at least one kernel")
        if self.refine_population < 1 or not self.sigma > 0:
            raise InputError(
                f"{where}: refine_population must be >= 1 and sigma > 0, got {self.refine_population}, "
                f"{self.sigma}"
            )
        for config in (self.config, self.quick):
            outside = [q for q in config.single_quantiles if not 0.0 <= q <= 1.0]
            if outside:
                raise InputError(f"{where}: single_quantiles must lie in [0, 1], got {outside}")
            if (self.joint_sigma is None) != (config.joint_budget == 0):
                raise InputError(
                    f"{where}: joint_sigma {self.joint_sigma} and joint_budget {config.joint_budget}: a "
                    "joint refinement needs both (or neither)"
                )

    @property
    def demonstration_path(self) -> Path:
        return examples.path("data") / self.demonstration


def successes(evaluation) -> np.ndarray:
    return np.array([detail.success for detail in evaluation.details])


def costs(evaluation) -> np.ndarray:
    """The reward without the success bonus, negated (every success scores > 0, every miss <= 0)."""
    return successes(evaluation).astype(float) - evaluation.rewards


def nearest(taus: np.ndarray, tau: np.ndarray, scale: np.ndarray, among) -> int:
    """The index in ``among`` of the tau nearest ``tau`` in box widths (the first of equals)."""
    return min(among, key=lambda j: float(np.linalg.norm((taus[j] - tau) / scale)))


@dataclass
class Experiment:
    study: Study
    config: Config | None = None
    progress: bool = False

    def __post_init__(self) -> None:
        study = self.study
        self.config = self.config or study.config
        if (study.joint_sigma is None) != (self.config.joint_budget == 0):
            raise InputError(
                f"study {study.experiment}: joint_sigma {study.joint_sigma} and joint_budget "
                f"{self.config.joint_budget}: a joint refinement needs both (or neither)"
            )
        self.registered = registered(study.task)
        self.task = self.registered.batched(study.robot)
        self.box = self.task.bounds
        self.scale = np.asarray(self.box.high, dtype=float) - np.asarray(self.box.low, dtype=float)
        self.theta_demo = study.imitate(self.task, *study.load_demonstration(study.demonstration_path))
        self.held_out = self.registered.spread(study.robot, self.config.held_out, HELD_OUT_SEED)
        self.rollouts: dict[str, int] = {}

    def say(self, text: str) -> None:
        if self.progress:
            print(f"[{time.strftime('%H:%M:%S')}] {text}", file=sys.stderr, flush=True)

    def evaluate(self, thetas, taus, what: str):
        thetas = np.array(thetas, dtype=float, ndmin=2)
        taus = np.asarray(taus, dtype=float).reshape(len(thetas), -1)
        self.rollouts[what] = self.rollouts.get(what, 0) + len(thetas)
        return self.task.evaluate(thetas, taus)

    def tau_text(self, tau) -> str:
        return ", ".join(f"{value:.4f}" for value in np.atleast_1d(tau))

    # -- 0. what needs no learning --------------------------------------------------------------------------

    def baselines(self) -> dict:
        taus, n = self.held_out, len(self.held_out)
        results = {}
        for name, baseline in self.study.baselines:  # their own motions, a rollout per held-out tau
            results[name] = successes(baseline(self.task, taus)).astype(int).tolist()
            self.rollouts["baselines"] = self.rollouts.get("baselines", 0) + n
        imitated = self.evaluate(np.repeat(self.theta_demo[None], n, 0), taus, "baselines")
        results["demonstration_imitated"] = successes(imitated).astype(int).tolist()
        return results

    # -- 1. one tau from the demonstration ------------------------------------------------------------------

    def single_taus(self) -> np.ndarray:
        low = np.asarray(self.box.low, dtype=float)
        return np.array(
            [
                self.held_out[
                    nearest(self.held_out, low + q * self.scale, self.scale, range(len(self.held_out)))
                ]
                for q in self.config.single_quantiles
            ]
        )

    def single(self) -> dict:
        config, sigma, out = self.config, self.study.sigma, []
        for t, tau in enumerate(self.single_taus()):
            self.say(
                f"one {self.study.tau_label} from the demonstration, {self.tau_text(tau)}: "
                f"{config.single_seeds} seeds x {config.single_budget} rollouts"
            )
            found: dict[int, tuple[list, list]] = {}

            def objective(thetas, owners, tau=tau, found=found):
                evaluation = self.evaluate(thetas, np.tile(tau, (len(thetas), 1)), "single")
                for owner, s, c in zip(owners, successes(evaluation), costs(evaluation), strict=True):
                    rows = found.setdefault(int(owner), ([], []))
                    rows[0].append(bool(s))
                    rows[1].append(float(c))
                return evaluation.rewards

            optimizers = [
                make_optimizer("cmaes", WarmStart(self.theta_demo, sigma), seed=child_seed(seed, SINGLE, t))
                for seed in range(config.single_seeds)
            ]
            policy_search(objective, optimizers, budget=config.single_budget)
            curves = []
            for seed in range(config.single_seeds):
                success, cost = (np.array(x) for x in found[seed])
                # Rollout 0 is the start mean (the imitated demonstration); rollouts 1.. are the search's.
                success, cost = success[: config.single_budget + 1], cost[: config.single_budget + 1]
                first = np.flatnonzero(success[1:])
                curves.append(
                    {
                        "seed": seed,
                        "rollouts_to_first_success": int(first[0]) + 1 if first.size else None,
                        "success_so_far": np.maximum.accumulate(success).astype(int).tolist(),
                        "best_cost_so_far": np.round(np.minimum.accumulate(cost), 4).tolist(),
                    }
                )
            firsts = [c["rollouts_to_first_success"] for c in curves]
            solved = [f for f in firsts if f is not None]
            out.append(
                {
                    "tau": np.round(tau, 4).tolist(),
                    "rollouts_to_first_success": firsts,
                    # A mean over every seed, or none: a mean over the seeds that succeeded would flatter.
                    "mean_rollouts_to_first_success": float(np.mean(firsts))
                    if len(solved) == len(firsts)
                    else None,
                    "seeds_succeeded": len(solved),
                    "curves": curves,
                }
            )
        return {"budget": config.single_budget, "sigma": sigma, "taus": out}

    # -- 2. training tasks ----------------------------------------------------------------------------------

    def training_taus(self, seed: int) -> np.ndarray:
        taus = self.registered.spread(self.study.robot, self.config.k, TRAINING_SEED + seed)
        if (taus[:, None, :] == self.held_out[None, :, :]).all(axis=2).any():
            raise InputError(f"a training {self.study.tau_label} is one of the held-out ones")
        return taus

    def robust_rewards(self, thetas: np.ndarray, tau: np.ndarray, what: str) -> np.ndarray:
        around = self.study.neighbourhood(np.asarray(tau, dtype=float), self.box)
        evaluation = self.evaluate(
            np.repeat(thetas, len(around), axis=0), np.tile(around, (len(thetas), 1)), what
        )
        return evaluation.rewards.reshape(len(thetas), len(around)).mean(axis=1)

    def chain(self, taus: np.ndarray) -> list[int]:
        """The order the training tasks are learned in: the study's first, then the nearest to the solved."""
        order = [self.study.first(taus)]
        while len(order) < len(taus):
            unsolved = [i for i in range(len(taus)) if i not in order]
            order.append(
                min(
                    unsolved,
                    key=lambda i: min(np.linalg.norm((taus[i] - taus[j]) / self.scale) for j in order),
                )
            )
        return order

    def training(self, seed: int) -> dict:
        """The seed's K training taus (in draw order) with their thetas, learned as a chain."""
        study, taus = self.study, self.training_taus(seed)
        thetas = np.zeros((len(taus), self.task.n_params))
        rewards = np.zeros(len(taus))
        evaluations = np.zeros(len(taus), dtype=int)
        starts = [-1] * len(taus)
        solved: list[int] = []
        for order, i in enumerate(self.chain(taus)):
            tau = taus[i]
            if solved:
                starts[i] = nearest(taus, tau, self.scale, solved)
                start = thetas[starts[i]]
            else:
                start = self.theta_demo
            self.say(f"seed {seed}: training {study.tau_label} {order + 1}/{len(taus)}, {self.tau_text(tau)}")
            (reward,) = self.robust_rewards(start[None], tau, "training")
            if solved and reward > study.training_target:  # the nearest solved task's theta does here too
                thetas[i], rewards[i], evaluations[i] = start, reward, 1
            else:
                (result,) = policy_search(
                    lambda thetas_, _, tau=tau: self.robust_rewards(thetas_, tau, "training"),
                    [
                        make_optimizer(
                            "cmaes", WarmStart(start, study.sigma), seed=child_seed(seed, TRAINING, i)
                        )
                    ],
                    budget=self.config.training_budget,
                    evaluate_start=False,
                    target_reward=study.training_target,
                )
                best = result.best_reward > reward
                thetas[i] = result.best_theta if best else start
                rewards[i] = max(result.best_reward, reward)
                evaluations[i] = result.rollouts + 1
            solved.append(int(i))
        succeeded = successes(self.evaluate(thetas, taus, "training checks"))
        return {
            "taus": taus,
            "thetas": thetas,
            "robust_rewards": rewards,
            "evaluations": evaluations,
            "started_from": starts,
            "succeeds_at_its_tau": succeeded,
        }

    # -- 3. the template ------------------------------------------------------------------------------------

    def choose_kernel(self, taus: np.ndarray, thetas: np.ndarray) -> tuple[SharedKernel, list[float]]:
        """Leave-one-out over the training tasks (see the module documentation)."""
        kernels = self.study.kernels
        if len(taus) < 3:
            return self.study.few_tasks_kernel, []
        if len(kernels) == 1:
            return kernels[0], []
        predicted, where = [], []
        for kernel in kernels:
            for i in range(len(taus)):
                others = np.arange(len(taus)) != i
                predicted.append(
                    predictions(taus[others], thetas[others], self.box, kernel, taus[i : i + 1])[0]
                )
                where.append(taus[i])
        rewards = np.concatenate(
            [
                self.robust_rewards(theta[None], tau, "kernel choice")
                for theta, tau in zip(predicted, where, strict=True)
            ]
        )
        means = rewards.reshape(len(kernels), len(taus)).mean(axis=1)
        return kernels[int(np.argmax(means))], [round(float(m), 4) for m in means]

    def refined_jointly(self, taus: np.ndarray, thetas: np.ndarray, seed: int) -> tuple[np.ndarray, dict]:
        """The K training thetas refined together by contextual CMA-ES (module documentation, step 3)."""
        budget = self.config.joint_budget
        box = ContextBox(np.asarray(self.box.low, dtype=float), np.asarray(self.box.high, dtype=float))
        features = context_features(box.normalise(taus), "affine")
        fitted = np.linalg.lstsq(features, thetas, rcond=None)[0]
        optimizer = ContextualCMAES(
            fitted[0],
            self.study.joint_sigma,
            seed=child_seed(seed, JOINT_POLICY, len(taus)),
            context_box=box,
            config=ContextualCMAESConfig(),
            coefficients=fitted,
        )
        rates: list[float] = []

        def check(rollouts: int, policy) -> None:
            rates.append(
                float(successes(self.evaluate(policy.policy_mean(taus), taus, "joint checks")).mean())
            )

        contextual_search(
            lambda thetas_, contexts: self.evaluate(thetas_, contexts, "joint refinement").rewards,
            optimizer,
            budget=budget,
            sample_contexts=lambda rng, count: taus[rng.integers(0, len(taus), count)],
            seed=child_seed(seed, JOINT_CONTEXTS, len(taus)),
            checkpoint_every=max(1, budget // 10),
            on_checkpoint=check,
        )
        return optimizer.policy_mean(taus), {"training_success_at_checkpoints": rates}

    def template(self, training: dict, k: int, seed: int) -> tuple[SkillTemplate, dict]:
        study = self.study
        taus, thetas = training["taus"][:k], training["thetas"][:k]
        # An affine policy's template needs m + 2 tasks (its drift, and Omega's leave-one-out residuals).
        joint = study.joint_sigma is not None and k >= len(self.box.names) + 2
        if joint:
            self.say(
                f"seed {seed}: the {k} training tasks refined together ({self.config.joint_budget} rollouts)"
            )
            thetas, facts = self.refined_jointly(taus, thetas, seed)
            kernel = study.kernels[0]
        else:
            kernel, losses = self.choose_kernel(taus, thetas)
            facts = {"kernel_losses": losses}
        quick = " --quick" if self.config == study.quick else ""
        prototype = MovementPrimitive(self.task.dmp, study.template, robot=study.robot, group="arm")
        refined_together = (
            (
                "; then refined together by contextual CMA-ES (an affine policy from the least-squares fit "
                f"of the chained thetas, sigma {study.joint_sigma}, {self.config.joint_budget} rollouts at "
                "the training taus), kept as the policy's mean at them, with an affine drift"
            )
            if joint
            else ""
        )
        template = SkillTemplate(
            study.template,
            prototype,
            taus,
            thetas,
            self.box,
            kernel=kernel,
            prior_spread=study.sigma,
            task=study.task,
            provenance={
                "experiment": f"besman.experiments.{study.experiment}",
                "command": f"besman experiment {study.task}{quick}",
                "seed": seed,
                "training_tasks": k,
                "training_taus": np.round(taus, 4).tolist(),
                "training": (
                    "a chain from the demonstration, each task from the nearest solved task's theta; CMA-ES "
                    f"(sigma {study.sigma}) until a robust evaluation scores above {study.training_target}, "
                    f"for at most {self.config.training_budget} evaluations (in whole generations) after "
                    f"the start's{refined_together}"
                ),
                "kernel": f"see besman.experiments.{study.experiment}",
                "demonstration": f"examples/data/{study.demonstration} (synthetic)",
            },
        )
        return template, facts

    # -- 4. evaluation --------------------------------------------------------------------------------------

    def evaluate_template(self, template: SkillTemplate, seed: int, k: int) -> dict:
        taus = self.held_out
        means = template.predict(taus)[0]
        zero_shot = self.evaluate(means, taus, "zero shot")
        zero = successes(zero_shot)
        refined, again = zero.copy(), zero.copy()
        spent = np.zeros(len(taus), dtype=int)
        misses = np.flatnonzero(~zero)
        verdicts = []
        if misses.size:
            budget = self.config.refine_budget
            optimizers = []
            for i in misses:
                mean, covariance = template.distribution(taus[i])
                optimizers.append(
                    make_optimizer(
                        "cmaes",
                        WarmStart(mean, covariance),
                        seed=child_seed(seed, REFINEMENT, k, int(i)),
                        population_size=min(self.study.refine_population, budget),
                    )
                )
            succeeded: dict[int, list[bool]] = {}

            def objective(thetas, owners):
                evaluation = self.evaluate(thetas, taus[misses[owners]], "refinement")
                for owner, s in zip(owners, successes(evaluation), strict=True):
                    succeeded.setdefault(int(owner), []).append(bool(s))
                return evaluation.rewards

            searched = policy_search(
                objective, optimizers, budget=budget, evaluate_start=False, target_reward=SUCCESS
            )
            for owner, i in enumerate(misses):
                tries = succeeded.get(owner, [])[:budget]
                refined[i] = any(tries)
                spent[i] = (tries.index(True) + 1) if any(tries) else len(tries)
            bests = [result.best_within(budget) for result in searched]
            verdicts, again[misses] = self.verdicts(
                means[misses], zero_shot.rewards[misses], bests, taus[misses]
            )
        return {
            "seed": seed,
            "k": k,
            "zero_shot": zero.astype(int).tolist(),
            "refined": refined.astype(int).tolist(),
            "refinement_rollouts": spent.tolist(),
            "refinement_verdicts": [
                {"tau_index": int(i), **verdict} for i, verdict in zip(misses, verdicts, strict=True)
            ],
            "kept_succeeds_again": again.astype(int).tolist(),
            "zero_shot_rate": float(zero.mean()),
            "refined_rate": float(refined.mean()),
        }

    def verdicts(self, starts, start_rewards, bests, taus) -> tuple[list[dict], np.ndarray]:
        """Each refinement's verdict (module documentation, step 4): the ``starts`` (whose rewards were
        ``start_rewards``) and the searches' ``bests`` within their budget ((theta, reward) pairs) evaluated
        :data:`REEVALUATIONS` more times at their ``taus`` in one batch; and whether the theta kept succeeded
        on its last evaluation."""
        caught = []

        def evaluate(thetas, owners):
            evaluation = self.evaluate(thetas, taus[owners], "refinement verdicts")
            caught.extend(successes(evaluation))
            return evaluation.rewards

        searched = [(start, best) for start, (_, best) in zip(start_rewards, bests, strict=True)]
        thetas = np.array([theta for theta, _ in bests])
        judged = reevaluated_searches(evaluate, starts, thetas, searched, REEVALUATIONS)
        caught = np.reshape(caught, (2, len(starts), REEVALUATIONS))
        verdicts = [verdict.to_json() for verdict in judged]
        kept = [caught[int(verdict.accepted), i, -1] for i, verdict in enumerate(judged)]
        return verdicts, np.array(kept)

    # -- the whole run --------------------------------------------------------------------------------------

    def run(self, pool: Path | None = None) -> dict:
        started = time.monotonic()
        config, study = self.config, self.study
        self.say(f"baselines on the {len(self.held_out)} held-out {study.tau_label}s")
        results: dict = {
            "schema_version": SCHEMA_VERSION,
            "experiment": study.experiment,
            "task": study.task,
            "robot": study.robot,
            "tau": list(self.box.names),
            "tau_label": study.tau_label,
            "cost_label": study.cost_label,
            "config": asdict(config),
            "settings": {
                "sigma": study.sigma,
                "training_target": study.training_target,
                "refine_population": study.refine_population,
                "held_out_seed": HELD_OUT_SEED,
                "training_seed": f"{TRAINING_SEED} + seed",
                "kernels": [asdict(kernel) for kernel in study.kernels],
                "joint_sigma": study.joint_sigma,
            },
            "held_out": np.round(self.held_out, 4).tolist(),
            "baselines": [name for name, _ in study.baselines] + ["demonstration_imitated"],
            **self.baselines(),
        }
        results["single"] = self.single()
        seeds = []
        for seed in range(config.seeds):
            training = self.training(seed)
            per_k = []
            for k in config.ks:
                template, facts = self.template(training, k, seed)
                self.say(
                    f"seed {seed}: template of K = {k} on {len(self.held_out)} held-out {study.tau_label}s"
                )
                evaluated = self.evaluate_template(template, seed, k)
                evaluated["kernel"] = asdict(template.kernel)
                evaluated.update(facts)
                per_k.append(evaluated)
                if pool is not None and seed == 0 and k == config.k:
                    SkillTemplatePool(pool).add(template, overwrite=True)
            seeds.append(
                {
                    "seed": seed,
                    "training_taus": np.round(training["taus"], 4).tolist(),
                    "training_evaluations": training["evaluations"].tolist(),
                    "training_started_from": training["started_from"],
                    "training_robust_rewards": np.round(training["robust_rewards"], 4).tolist(),
                    "training_succeeds_at_its_tau": training["succeeds_at_its_tau"].astype(int).tolist(),
                    "per_k": per_k,
                }
            )
        results["templates"] = seeds
        results["summary"] = summarise(results)
        results["rollouts"] = dict(self.rollouts)
        results["minutes"] = round((time.monotonic() - started) / 60, 1)
        self.task.close()
        return results


def summarise(results: dict) -> dict:
    k = results["config"]["k"]
    finals = [next(e for e in s["per_k"] if e["k"] == k) for s in results["templates"]]
    refined_spent = [
        r for e in finals for r, z in zip(e["refinement_rollouts"], e["zero_shot"], strict=True) if not z
    ]
    verdicts = [v for e in finals for v in e["refinement_verdicts"]]
    single = results["single"]["taus"]
    middle = single[len(single) // 2]
    return {
        "k": k,
        **{f"{name}_rate": float(np.mean(results[name])) for name in results["baselines"]},
        "zero_shot_rate_per_seed": [e["zero_shot_rate"] for e in finals],
        "zero_shot_rate": float(np.mean([e["zero_shot_rate"] for e in finals])),
        "refined_rate_per_seed": [e["refined_rate"] for e in finals],
        "refined_rate": float(np.mean([e["refined_rate"] for e in finals])),
        "refinement_rollouts_of_misses_mean": float(np.mean(refined_spent)) if refined_spent else 0.0,
        "refinements": len(verdicts),
        "refinements_kept": sum(v["accepted"] for v in verdicts),
        "refinement_noise_max": max((v["noise"] for v in verdicts), default=0.0),
        "kept_succeed_again_where_refined": all(e["kept_succeeds_again"] == e["refined"] for e in finals),
        "single_tau": middle["tau"],
        "single_mean_rollouts_to_first_success": middle["mean_rollouts_to_first_success"],
        "single_all": [[entry["tau"], entry["mean_rollouts_to_first_success"]] for entry in single],
    }


def report(results: dict) -> str:
    s = results["summary"]
    rates = ", ".join(f"{name.replace('_', ' ')} {s[f'{name}_rate']:.0%}" for name in results["baselines"])
    lines = [f"held-out taus: {len(results['held_out'])}; {rates}"]
    for entry in results["single"]["taus"]:
        lines.append(
            f"one tau from the demonstration, {entry['tau']}: rollouts to the first success "
            f"{entry['rollouts_to_first_success']} "
            + (
                f"(mean {entry['mean_rollouts_to_first_success']})"
                if entry["mean_rollouts_to_first_success"] is not None
                else f"({entry['seeds_succeeded']} of {len(entry['curves'])} seeds within the budget)"
            )
        )
    lines.append(
        f"template, K = {s['k']}: zero shot {[f'{r:.0%}' for r in s['zero_shot_rate_per_seed']]} "
        f"(mean {s['zero_shot_rate']:.1%}); after <= {results['config']['refine_budget']} more rollouts "
        f"{[f'{r:.0%}' for r in s['refined_rate_per_seed']]} (mean {s['refined_rate']:.1%})"
    )
    lines.append(
        f"refinements judged: {s['refinements_kept']} of {s['refinements']} kept (improvement > noise; noise "
        f"{s['refinement_noise_max']:.3g} at most); the theta kept succeeds again exactly where refined: "
        + ("yes" if s["kept_succeed_again_where_refined"] else "NO")
    )
    lines.append(f"rollouts {results['rollouts']}, {results['minutes']} min")
    return "\n".join(lines)
