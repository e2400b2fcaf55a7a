"""The learning platform end to end: from human recordings to a skill template pool that drives AILA.

:func:`learn` runs the stages of Metzen et al.'s Fig. 2 on a folder of recordings, writing each stage's
result to ``POOL/work/`` as soon as it is complete:

1. **Recordings**: every ``.tsv``, ``.csv`` or ``.npz`` in the folder is loaded and checked (the hand
   markers must be there) before anything is written.
2. **Segmentation** (``work/segments/<recording>.json``): :func:`~besman.learning.segment` per recording; a
   recording in which it finds no movement is an error.
3. **Labels** (``work/labels.json``): the movement segments of all recordings are grouped into building
   blocks - clustered (Ward, named ``block1``... in the order they come in the task) or, with
   ``examples``, labelled like the annotated segments of example recordings (1-NN). Three labels play
   AILA's blocks (``roles``): on the shared recordings the person's second pick and place is AILA's task -
   the reach to the object on the table (``block4`` / ``approach_right``), the carry to the shelf
   (``block5`` / ``move_obj_shelf``) and the return to rest (``block6`` / ``move_to_rest_down``). Per
   recording, a block's instance is the longest run of consecutive segments with its label (a movement the
   segmentation split in two is one instance).
4. **Imitation and retargeting** (``work/imitated/``, ``work/shapes/``): one Cartesian DMP per block from
   all its instances (:func:`~besman.learning.imitate`), mapped into AILA's workspace and onto its right arm
   and waist (:mod:`besman.learning.retargeting`).
5. **Refinement** (``work/refined/<block>-<k>.json``): for K training tasks per block (a Latin hypercube
   over the block's tau box), CMA-ES refines the primitive's forcing weights from the retargeted ones by
   rollouts of that block alone in MuJoCo, through the Ruckig executor, followed by the planned motions
   that decide its success (:mod:`besman.sim.blocks`: reward for success, smoothness, joint-limit margin
   and no collisions). Each task's search is seeded by the run's seed, its block and its index
   (:func:`~besman.skills.seeds.child_seed`), so an interrupted run that resumes gets the same results.
6. **Templates**: one skill template per block over its tau (the K refined thetas; the shared-kernel model
   with its default kernel, fixed before any learn, and the refinement's spread as the prior exploration of
   the forcing weights, which are all that was searched), stored in the pool with their provenance:
   recordings (file, SHA-256, frames), segment ids, workspace map, training tasks, rewards and settings.
   Beside the pool: ``summary.png``, ``segmentations.png``, ``learning_curves.png``.

``work/learn.json`` records the settings and the recordings' checksums: a rerun with the same ones resumes,
one with others is refused (``force`` starts over), and a pool learned for another robot is refused.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import qmc
from tqdm import tqdm

import besman.robots as robots
from besman.learning.demonstration import Demonstration, DemonstrationError, load, read_recording
from besman.learning.imitation import HAND_MARKERS, imitate
from besman.learning.labelling import DemonstrationSegment, cluster, ground_truth_segments, label_few_shot
from besman.learning.policy_search import CMAES, WarmStart, policy_search
from besman.learning.retargeting import fit_workspace_map, retarget
from besman.learning.segmentation import segment
from besman.sim.blocks import (
    BLOCKS,
    BlockOutcome,
    BlockTask,
    BlockTaskConfig,
    block_bounds,
    prepare,
)
from besman.sim.executor import Executor
from besman.sim.world import tabletop_world
from besman.skills import MovementPrimitive, SkillTemplate, SkillTemplatePool
from besman.skills.errors import BesmanError
from besman.skills.seeds import child_seed
from besman.skills.storage import holds_files, read_json, remove_temporaries, sha256, write_atomically
from besman.skills.writer_lock import WriterLock

SCHEMA_VERSION = 1
KIND = "besman-learn"
SUFFIXES = (".tsv", ".csv", ".npz")
CLUSTERED_ROLES = {"reach": "block4", "carry": "block5", "return": "block6"}
EXAMPLE_ROLES = {"reach": "approach_right", "carry": "move_obj_shelf", "return": "move_to_rest_down"}
# The folders in a pool that learn writes (besides the pool itself), where a killed learn leaves temporaries.
POOL_FOLDERS = ("work", "work/segments", "work/imitated", "work/shapes", "work/refined")


class LearnError(BesmanError):
    """The pipeline cannot run on this input or output; the message names the file, folder or setting."""


@dataclass(frozen=True)
class LearnSettings:
    """What a run learns and how (recorded in ``work/learn.json``).

    Attributes:
        robot: the robot the pool is for.
        tasks: training tasks K per block.
        budget: rollouts per training task (whole CMA-ES generations; the start is one more).
        seed: seeds the training tasks and every search.
        backend: "threads" (local worker processes) or "ray".
        n_blocks: building blocks to cluster into (without examples).
        examples: annotated recordings whose segments label the others (few-shot) instead of clustering.
        roles: which label plays each of AILA's blocks (empty: the defaults for clustering or examples).
        n_weights: forcing weights per joint of the retargeted primitives.
        spread: CMA-ES's initial standard deviation (theta units: 0.1 rad per unit).
    """

    robot: str = "aila"
    tasks: int = 8
    budget: int = 48
    seed: int = 0
    backend: str = "threads"
    n_blocks: int = 6
    examples: tuple[str, ...] = ()
    roles: tuple[tuple[str, str], ...] = ()
    n_weights: int = 6
    spread: float = 0.1

    def role_labels(self) -> dict[str, str]:
        given = dict(self.roles)
        unknown = sorted(set(given) - set(BLOCKS))
        if unknown:
            raise LearnError(f"roles: unknown block {unknown[0]!r}; blocks: {', '.join(BLOCKS)}")
        return {**(EXAMPLE_ROLES if self.examples else CLUSTERED_ROLES), **given}

    def check(self) -> None:
        try:
            robot = robots.describe(self.robot)
        except BesmanError as error:
            raise LearnError(f"robot: {error}") from None
        arms = list(robot.arms.values())
        if robot.tabletop is None or not arms or arms[0].gripper is None:
            raise LearnError(
                f"robot {self.robot!r}: learning refines the blocks in the robot's tabletop world, which "
                "needs a tabletop layout and a first arm with a gripper in its description"
            )
        for name, low in (("tasks", 2), ("budget", 1), ("n_blocks", 3), ("n_weights", 2)):
            if getattr(self, name) < low:
                raise LearnError(f"{name} must be at least {low}, got {getattr(self, name)}")
        if not self.spread > 0:
            raise LearnError(f"spread must be positive, got {self.spread}")
        if not self.examples:
            clusters = {f"block{k + 1}" for k in range(self.n_blocks)}
            for block, label in self.role_labels().items():
                if label not in clusters:
                    raise LearnError(
                        f"roles: {block}={label!r} names no cluster; clustering into {self.n_blocks} names "
                        f"them block1 to block{self.n_blocks} (or give --examples to use their labels)"
                    )

    def as_dict(self) -> dict:
        document = dataclasses.asdict(self)
        document["examples"] = list(self.examples)
        document["roles"] = self.role_labels()
        return document


@dataclass(frozen=True)
class LearnResult:
    """What a run produced: the pool, the per-block training results and the figures."""

    pool: Path
    templates: tuple[str, ...]
    refined: dict[str, list[dict]]
    figures: tuple[Path, ...]


# -- recordings --------------------------------------------------------------------------------------------


def recordings(folder: str | Path) -> list[Path]:
    """The recordings in ``folder`` (sorted), or a :class:`LearnError` saying why there are none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise LearnError(f"{folder}: no such demonstration folder")
    try:
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
    except OSError as error:
        raise LearnError(f"{folder}: cannot read the folder ({error.strerror})") from None
    if not files:
        raise LearnError(f"{folder}: no recordings ({', '.join(SUFFIXES)} files) in the folder")
    return files


def load_recording(path: Path) -> Demonstration:
    """A recording with the hand markers imitation follows, or a :class:`LearnError` naming the file."""
    try:
        demo = load(path)
    except DemonstrationError as error:
        raise LearnError(str(error)) from None
    except OSError as error:
        raise LearnError(f"{path}: cannot read the recording ({error.strerror})") from None
    missing = [name for name in HAND_MARKERS if name not in demo.channels]
    if missing:
        raise LearnError(
            f"{path}: no hand markers {', '.join(missing)} (has: {', '.join(sorted(demo.channels))}); "
            "learning follows the hand"
        )
    return demo


# -- the run -----------------------------------------------------------------------------------------------


class _Run:
    """One call of :func:`learn`: the folders, the settings and the stages."""

    def __init__(self, demos: Path, out: Path, settings: LearnSettings, show_progress: bool) -> None:
        self.out, self.work, self.settings = out, out / "work", settings
        self.show_progress = show_progress
        self.files = recordings(demos)
        self.demos = [load_recording(path) for path in self.files]
        self.checksums = [sha256(read_recording(path)) for path in self.files]
        self.examples = [load_recording(Path(path)) for path in settings.examples]
        for path, demo in zip(settings.examples, self.examples, strict=True):
            if not demo.segments:
                raise LearnError(f"{path}: an example needs its annotation (<stem>_manually_segmented.json)")
        annotated = {segment.label for demo in self.examples for segment in demo.segments}
        for block, label in settings.role_labels().items() if self.examples else ():
            if label not in annotated:
                raise LearnError(
                    f"roles: {block}={label!r} is not a label of the examples (they have: "
                    f"{', '.join(sorted(annotated))})"
                )
        self.record = {
            "schema_version": SCHEMA_VERSION,
            "kind": KIND,
            "robot": settings.robot,
            "settings": settings.as_dict(),
            "recordings": [
                {"file": path.name, "sha256": digest}
                for path, digest in zip(self.files, self.checksums, strict=True)
            ],
        }

    def bar(self, total: int, what: str, unit: str) -> tqdm:
        return tqdm(total=total, desc=what, unit=unit, disable=not self.show_progress, leave=False)

    # -- the output folder ---------------------------------------------------------------------------------

    def claim_output(self, force: bool) -> None:
        """Checks the output folder before anything is written (see :func:`learn`); then removes the
        temporaries that a killed learn left, if the folder is known to be besman's (its record, or nothing
        in it but besman's temporaries; never in a folder of the user's that ``force`` writes into)."""
        out, record_path = self.out, self.work / "learn.json"
        if out.exists() and not out.is_dir():
            raise LearnError(f"{out}: the output is a file, not a pool folder")
        resume = False
        if record_path.is_file():
            previous = read_json(record_path, LearnError)
            if previous.get("kind") != KIND:  # a record besman did not write: not replaced, even with --force
                raise LearnError(
                    f"{record_path}: not the record of a besman learn, so {out} is not a pool besman can "
                    "resume or replace; remove that file or choose another --out"
                )
            if previous.get("robot") != self.settings.robot and not force:
                raise LearnError(
                    f"{out}: the pool was learned for robot {previous.get('robot')!r}, not "
                    f"{self.settings.robot!r} (--force replaces it)"
                )
            ours, resume = True, previous == self.record
            if not resume:
                if not force:
                    raise LearnError(
                        f"{out}: the pool was learned from other recordings or settings (see {record_path}); "
                        "--force starts over"
                    )
                for stage in POOL_FOLDERS[1:]:  # the stale caches; anything else in work/ stays
                    shutil.rmtree(out / stage, ignore_errors=True)
        else:
            # Files, not folders or besman's temporaries: a learn killed before its record leaves those.
            ours = not holds_files(out)
            if not ours and not force:
                raise LearnError(
                    f"{out}: the folder is not empty and not a pool learned by besman "
                    "(--force writes into it)"
                )
        if not resume:
            self.work.mkdir(parents=True, exist_ok=True)
            _write_json(record_path, self.record)
        if ours:
            remove_temporaries(out, POOL_FOLDERS)

    # -- stages --------------------------------------------------------------------------------------------

    def segmentations(self) -> list[list[DemonstrationSegment]]:
        """The movement segments of each recording (cached per recording)."""
        folder = self.work / "segments"
        folder.mkdir(exist_ok=True)
        found = []
        with self.bar(len(self.demos), "segmenting", "recording") as bar:
            for path, demo, digest in zip(self.files, self.demos, self.checksums, strict=True):
                cache = folder / f"{path.stem}.json"
                document = read_json(cache, LearnError) if cache.is_file() else None
                if document is None or document.get("sha256") != digest:
                    result = segment(demo)
                    document = {
                        "schema_version": SCHEMA_VERSION,
                        "file": path.name,
                        "sha256": digest,
                        "boundaries": result.boundaries.tolist(),
                        "holds": list(result.holds),
                        "models": list(result.models),
                        "signals": list(result.signals),
                        "notes": list(result.notes),
                    }
                    _write_json(cache, document)
                bounds, holds = document["boundaries"], document["holds"]
                movements = [
                    DemonstrationSegment(demo, bounds[k], bounds[k + 1])
                    for k in range(len(holds))
                    if not holds[k]
                ]
                if not movements:
                    raise LearnError(f"{path}: the segmentation finds no movement in the recording")
                found.append(movements)
                bar.update()
        return found

    def labels(self, movements: list[list[DemonstrationSegment]]) -> dict[str, list[dict]]:
        """Each block's instances: per recording, the longest run of consecutive segments with its label."""
        cache = self.work / "labels.json"
        if cache.is_file():
            return read_json(cache, LearnError)["blocks"]
        flat = [s for per_demo in movements for s in per_demo]
        if self.examples:
            examples = [s for demo in self.examples for s in ground_truth_segments(demo)]
            examples = [s for s in examples if not s.label.endswith("_part") and s.label != "idle"]
            names = label_few_shot(examples, flat)
            method = "few-shot (1-NN) from " + ", ".join(Path(p).name for p in self.settings.examples)
        else:
            if len(flat) < self.settings.n_blocks:
                raise LearnError(
                    f"the recordings hold {len(flat)} movements, fewer than the {self.settings.n_blocks} "
                    "building blocks to cluster them into"
                )
            clusters = cluster(flat, self.settings.n_blocks)
            phases = {
                c: np.median([_phase(s) for s, k in zip(flat, clusters, strict=True) if k == c])
                for c in set(clusters)
            }
            order = sorted(phases, key=phases.get)
            names = [f"block{order.index(c) + 1}" for c in clusters]
            method = f"clustering (Ward) into {self.settings.n_blocks}, named in the order of the task"
        labelled, position = [], 0
        for per_demo in movements:
            labelled.append(names[position : position + len(per_demo)])
            position += len(per_demo)
        blocks = {}
        for block, label in self.settings.role_labels().items():
            instances = []
            for path, digest, per_demo, per_names in zip(
                self.files, self.checksums, movements, labelled, strict=True
            ):
                run = _longest_run(per_demo, per_names, label)
                if run is not None:
                    first, last = run
                    demo = per_demo[first].demo
                    instances.append(
                        {
                            "file": path.name,
                            "sha256": digest,
                            "segments": list(range(first, last + 1)),
                            "start": per_demo[first].start,
                            "end": per_demo[last].end,
                            "start_frame": int(demo.frames[per_demo[first].start]),
                            "end_frame": int(demo.frames[per_demo[last].end]),
                        }
                    )
            if not instances:
                raise LearnError(
                    f"no movement was labelled {label!r} (the {block} block); labels found: "
                    f"{', '.join(sorted(set(names)))}"
                )
            blocks[block] = instances
        _write_json(cache, {"schema_version": SCHEMA_VERSION, "method": method, "blocks": blocks})
        return blocks

    def shapes(self, blocks: dict[str, list[dict]]) -> dict[str, Path]:
        """Each block imitated (Cartesian, the person's frame) and retargeted to AILA (joint space); the
        workspace map goes with each shape's provenance."""
        shapes = {block: self.work / "shapes" / f"{block}.json" for block in BLOCKS}
        if all(path.is_file() for path in shapes.values()):
            return shapes
        demos = {path.name: demo for path, demo in zip(self.files, self.demos, strict=True)}
        imitated = {}
        for block, instances in blocks.items():
            path = self.work / "imitated" / f"{block}.json"
            if not path.is_file():
                segments = [
                    DemonstrationSegment(demos[i["file"]], i["start"], i["end"], block) for i in instances
                ]
                imitate(segments, name=block).save(path)
            imitated[block] = MovementPrimitive.load(path)
        world = tabletop_world(robot=self.settings.robot)
        arm = Executor(world).arm
        starts = {block: prepare(world, block, _centre(block, world)) for block in BLOCKS}
        mapping = fit_workspace_map(
            imitated["reach"].dmp.position.goal,
            imitated["carry"].dmp.position.goal,
            arm.site_pose(starts["reach"].goal).position,
            arm.site_pose(starts["carry"].goal).position,
        )
        for block, path in shapes.items():
            if not path.is_file():
                start = starts[block]
                shape = retarget(
                    imitated[block], mapping, arm, start.start, start.goal, n_weights=self.settings.n_weights
                )
                shape.provenance["segments"] = blocks[block]
                shape.save(path)
        return shapes

    def refine(self, shapes: dict[str, Path]) -> dict[str, list[dict]]:
        """Each block's K training tasks refined by CMA-ES (each task's result cached)."""
        settings, results = self.settings, {}
        folder = self.work / "refined"
        folder.mkdir(exist_ok=True)
        total = len(BLOCKS) * settings.tasks
        done = sum((folder / f"{b}-{k}.json").is_file() for b in BLOCKS for k in range(settings.tasks))
        with self.bar(total, "refining", "task") as tasks_bar:
            tasks_bar.update(done)
            for index, block in enumerate(BLOCKS):
                bounds = block_bounds(block, settings.robot)
                unit = qmc.LatinHypercube(d=len(bounds.names), seed=child_seed(settings.seed, index)).random(
                    settings.tasks
                )
                taus = qmc.scale(unit, bounds.low, bounds.high)
                task = None
                results[block] = []
                for k, tau in enumerate(taus):
                    path = folder / f"{block}-{k}.json"
                    if not path.is_file():
                        task = task or BlockTask(
                            BlockTaskConfig(block, str(shapes[block]), robot=settings.robot)
                        )
                        with self.bar(
                            settings.budget + 1, f"{block} {k + 1}/{settings.tasks}", "rollout"
                        ) as bar:
                            document = _refine_task(
                                task,
                                tau,
                                settings,
                                seed=child_seed(settings.seed, index, k),
                                progress=bar.update,
                            )
                        _write_json(
                            path, {"schema_version": SCHEMA_VERSION, "block": block, "task": k, **document}
                        )
                        tasks_bar.update()
                    results[block].append(read_json(path, LearnError))
        return results

    def templates(self, shapes: dict[str, Path], refined: dict[str, list[dict]]) -> tuple[str, ...]:
        pool = SkillTemplatePool(self.out)
        for block in BLOCKS:
            prototype = MovementPrimitive.load(shapes[block])
            runs = refined[block]
            template = SkillTemplate(
                block,
                prototype,
                np.array([run["tau"] for run in runs]),
                np.array([run["theta"] for run in runs]),
                block_bounds(block, self.settings.robot),
                prior_spread=np.where(_forcing_weights(prototype), self.settings.spread, 0.0),
                seed=self.settings.seed,
                task=f"pick-place/{robot_name(self.settings.robot)}",
                provenance={
                    "learner": "besman.learning.pipeline.learn",
                    "robot": self.settings.robot,
                    "recordings": self.record["recordings"],
                    "instances": prototype.provenance.get("segments", []),
                    "workspace_map": prototype.provenance["retargeting"]["map"],
                    "training": [
                        {
                            "tau": run["tau"],
                            "reward": run["reward"],
                            "start_reward": run["start_reward"],
                            "success": run["outcome"]["success"],
                        }
                        for run in runs
                    ],
                    "settings": self.record["settings"],
                },
            )
            pool.add(template, overwrite=True)
        return BLOCKS


def learn(
    demos: str | Path,
    out: str | Path,
    settings: LearnSettings = LearnSettings(),
    *,
    force: bool = False,
    progress: bool = True,
) -> LearnResult:
    """Learns a skill template pool ``out`` from the recordings in ``demos``; see the module documentation.

    Every input is checked before anything is written: the recordings (a folder with readable recordings
    that have the hand markers, and the examples' annotations) and the output (a file; a non-empty folder
    that is not a pool learned by besman, unless ``force``; a pool learned for another robot or from other
    recordings or settings, unless ``force``, which then starts over). A rerun after an interruption resumes;
    a second learn into ``out`` while one runs is refused (:class:`~besman.skills.writer_lock.WriterLock`).
    """
    settings.check()
    with WriterLock(out, "--out"):  # one learn per pool at a time
        run = _Run(Path(demos), Path(out), settings, progress)
        run.claim_output(force)
        movements = run.segmentations()
        blocks = run.labels(movements)
        shapes = run.shapes(blocks)
        refined = run.refine(shapes)
        templates = run.templates(shapes, refined)
        from besman.learning.pipeline_plots import write_figures  # matplotlib only when it is needed

        figures = write_figures(run.out, run.demos, run.files, movements, blocks, refined)
    return LearnResult(run.out, templates, refined, figures)


# -- helpers -----------------------------------------------------------------------------------------------


def _refine_task(
    task: BlockTask, tau: np.ndarray, settings: LearnSettings, seed: int, progress: Callable[[int], None]
) -> dict:
    """CMA-ES over the shape's forcing weights for one tau; the best theta, its outcome and the curve."""
    theta0 = task.shape.theta.copy()
    weights = _forcing_weights(task.shape)
    outcomes: dict[bytes, BlockOutcome] = {}

    def objective(candidates: np.ndarray, owners: np.ndarray) -> np.ndarray:
        thetas = np.tile(theta0, (len(candidates), 1))
        thetas[:, weights] = candidates
        evaluation = task.evaluate(thetas, np.tile(tau, (len(candidates), 1)), backend=settings.backend)
        for candidate, detail in zip(candidates, evaluation.details, strict=True):
            outcomes[candidate.tobytes()] = detail
        progress(len(candidates))
        return evaluation.rewards

    search = CMAES(WarmStart(theta0[weights], settings.spread), seed=seed)
    result = policy_search(objective, [search], budget=settings.budget)[0]
    theta = theta0.copy()
    theta[weights] = result.best_theta
    return {
        "tau": [float(v) for v in tau],
        "theta": theta.tolist(),
        "reward": result.best_reward,
        "start_reward": result.start_reward,
        "rollouts": result.rollouts + 1,
        "curve": result.curve().tolist(),
        "outcome": dataclasses.asdict(outcomes[result.best_theta.tobytes()]),
        "start_outcome": dataclasses.asdict(outcomes[theta0[weights].tobytes()]),
    }


def _forcing_weights(shape: MovementPrimitive) -> np.ndarray:
    """A mask of theta's forcing weights (each DMP dimension's N weights, not its goal and goal velocity):
    what refinement searches."""
    mask = np.zeros((shape.dmp.n_dims, shape.dmp.n_weights + 2), dtype=bool)
    mask[:, : shape.dmp.n_weights] = True
    return mask.ravel()


def _phase(segment: DemonstrationSegment) -> float:
    times = segment.demo.times
    return float(((times[segment.start] + times[segment.end]) / 2 - times[0]) / (times[-1] - times[0]))


def _longest_run(
    segments: list[DemonstrationSegment], names: list[str], label: str
) -> tuple[int, int] | None:
    """First and last index of the longest (in samples) run of adjacent segments (sharing a boundary, no
    pause between them) named ``label``; None if no segment is."""
    best, first = None, None
    for k, name in enumerate(names):
        if name != label:
            first = None
            continue
        if first is None or segments[k - 1].end != segments[k].start:
            first = k
        if (
            best is None
            or segments[k].end - segments[first].start > segments[best[1]].end - segments[best[0]].start
        ):
            best = (first, k)
    return best


def robot_name(robot: str) -> str:
    """The name a robot (a shipped name or a folder) gives itself in its description."""
    return robots.describe(robot).name


def _centre(block: str, world) -> np.ndarray:
    bounds = block_bounds(block, world.layout)
    return (np.asarray(bounds.low) + np.asarray(bounds.high)) / 2


def _write_json(path: Path, document: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(path, (json.dumps(document, indent=1) + "\n").encode("utf-8"))
