"""The learning platform end to end: from human recordings to a skill template pool that drives a robot.

:func:`learn` runs the stages of Metzen et al.'s Fig. 2 on a folder of recordings for a task's building
blocks (:class:`~besman.learning.pipeline.building_blocks.BuildingBlocks`: which blocks, in which order, how
the recordings label them, where each begins and how a rollout of one is scored), writing each stage's result
to ``POOL/work/`` as soon as it is complete:

1. **Recordings** (:mod:`besman.learning.pipeline.labels`): every ``.tsv``, ``.csv`` or ``.npz`` in the
   folder is loaded and checked (the hand markers must be there) before anything is written. A LeRobot
   dataset of the robot's own episodes instead (:mod:`besman.learning.pipeline.dataset_demonstrations`) is
   labelled by its gripper's events, its structure read from them, and its blocks imitated in the robot's
   joint space (:func:`~besman.learning.pipeline.refinement.joint_shapes`), with no retargeting.
2. **Segmentation** (``work/segments/<recording>.json``): :func:`~besman.learning.segment` per recording; a
   recording in which it finds no movement is an error.
3. **Labels** (``work/labels.json``): the movement segments of all recordings are grouped into building
   blocks - clustered (Ward, named ``block1``... in the order they come in the task) or, with
   ``examples``, labelled like the annotated segments of example recordings (1-NN). One label plays each
   of the task's blocks (``roles``; the task's defaults for clustering and for examples). Per recording, a
   block's instance is the longest run of consecutive segments with its label (a movement the segmentation
   split in two is one instance).
   **Structure** (``work/structure.json``, :mod:`besman.learning.pipeline.task_structure`): the order of the
   blocks in the recordings, whether the object is held during each (its marker moves with the hand), so
   where the hand closes and opens between them and what each block ends in (holding, placed): what the
   task's tree is assembled from (``besman learn`` writes it as ``POOL/tree.yaml``,
   :mod:`besman.trees.learned`).
4. **Imitation and retargeting** (:mod:`besman.learning.pipeline.refinement`; ``work/imitated/``,
   ``work/shapes/``): one Cartesian DMP per block from all its instances (:func:`~besman.learning.imitate`),
   mapped into the robot's workspace by the map that sends the goals of the task's two anchor blocks onto
   theirs, and onto the robot's arm (:mod:`besman.learning.pipeline.retargeting`).
5. **Refinement** (``work/refined/<block>-<k>.json``): for K training tasks per block (a Latin hypercube
   over the block's tau box), CMA-ES refines the primitive's forcing weights from the retargeted ones by
   rollouts of that block alone in MuJoCo, through the Ruckig executor, followed by what decides its
   success (the task's rollouts and reward). Each task's search is seeded by the run's seed, its block and
   its index (:func:`~besman.core.seeds.child_seed`), so an interrupted run that resumes gets the same
   results. With ``refinement="sequence"`` (``work/refined/sequence-<k>.json``) every block's forcing
   weights and subgoals are refined together instead, per training task, on whole-task rollouts with the
   task's perturbations, each block credited with its cost-to-go
   (:mod:`besman.learning.pipeline.sequence_refinement`).
6. **Templates**: one skill template per block over its tau (the K refined thetas; the shared-kernel model
   with its default kernel, fixed before any learn, and the refinement's spread as the prior exploration of
   the forcing weights, which are all that was searched), for ``<task>/<robot>``, stored in the pool with
   their provenance: recordings (file, SHA-256, frames), segment ids, workspace map, training tasks,
   rewards and settings. Beside the pool: ``summary.png``, ``segmentations.png``, ``learning_curves.png``
   (:mod:`besman.learning.pipeline.plots`).

``work/learn.json`` records the task, the robot, the settings and the recordings' checksums
(:mod:`besman.learning.pipeline.record`): a rerun with the same ones resumes, one with others is refused
(``force`` starts over), and a pool learned for another task or robot is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from besman.core.storage import read_json, sha256
from besman.core.writer_lock import WriterLock
from besman.learning.pipeline.building_blocks import BuildingBlocks
from besman.learning.pipeline.labels import (
    label_blocks,
    load_examples,
    load_recording,
    recordings,
    segment_recordings,
)
from besman.learning.pipeline.record import (
    SCHEMA_VERSION,
    LearnError,
    LearnSettings,
    claim_output,
    learn_record,
    write_json,
)
from besman.learning.pipeline.refinement import block_shapes, joint_shapes, refine_blocks, store_templates
from besman.learning.pipeline.sequence_refinement import refine_sequences
from besman.learning.pipeline.task_structure import TaskStructure, recorded_blocks, task_structure
from besman.learning.segmentation.demonstration import read_recording
from besman.learning.segmentation.labelling import DemonstrationSegment

__all__ = ["LearnError", "LearnResult", "LearnSettings", "learn"]
DEFAULT_SETTINGS = LearnSettings()


@dataclass(frozen=True)
class LearnResult:
    """What a run produced: the pool, the per-block training results, the task's structure as the
    recordings show it and the figures."""

    pool: Path
    templates: tuple[str, ...]
    refined: dict[str, list[dict]]
    structure: TaskStructure
    figures: tuple[Path, ...]


class _Run:
    """One call of :func:`learn`: its inputs, loaded and checked, and its stages, each on what the stages
    before it found."""

    def __init__(
        self, demos: Path, out: Path, settings: LearnSettings, blocks: BuildingBlocks, shown: bool
    ) -> None:
        self.out, self.work = out, out / "work"
        self.settings, self.blocks, self.shown = settings, blocks, shown
        self.robot = None  # a robot's recordings (a LeRobot dataset): name -> RobotRecording
        if (Path(demos) / "meta" / "info.json").is_file():  # a LeRobot dataset of the robot's episodes
            try:
                from besman.learning.pipeline.dataset_demonstrations import robot_recordings
            except ImportError as error:
                raise LearnError(
                    f"--demos {demos}: a dataset needs {error.name}: pip install 'besman[datasets]'"
                ) from None
            from besman.sim.executor import Executor

            arm = Executor(blocks.world(blocks.centre)).arm
            found = robot_recordings(demos, arm, blocks.task)
            self.robot = {recording.name: recording for recording in found}
            self.files = [Path(recording.name) for recording in found]
            self.demos = [recording.demo for recording in found]
            self.checksums = [recording.checksum for recording in found]
        else:
            self.files = recordings(demos)
            self.demos = [load_recording(path) for path in self.files]
            self.checksums = [sha256(read_recording(path)) for path in self.files]
        self.role_labels = settings.role_labels(blocks, robot=self.robot is not None)
        self.examples = load_examples(settings.examples, self.role_labels)
        self.record = learn_record(blocks, settings, self.files, self.checksums)

    def segmentations(self) -> list[list[DemonstrationSegment]]:
        return segment_recordings(self.files, self.demos, self.checksums, self.work / "segments", self.shown)

    def labels(self, movements: list[list[DemonstrationSegment]]) -> dict[str, list[dict]]:
        return label_blocks(
            movements,
            self.files,
            self.checksums,
            self.examples,
            self.settings,
            self.role_labels,
            self.work / "labels.json",
            None if self.robot is None else [self.robot[path.name].held for path in self.files],
        )

    def structure(self, instances: dict[str, list[dict]]) -> TaskStructure:
        cache = self.work / "structure.json"
        if cache.is_file():
            return TaskStructure.from_dict(read_json(cache, LearnError)["structure"])
        recorded = []
        for path, demo in zip(self.files, self.demos, strict=True):
            found = {
                b: (i["start"], i["end"])
                for b, runs in instances.items()
                for i in runs
                if i["file"] == path.name
            }
            held = None if self.robot is None else self.robot[path.name].held
            recorded.append(recorded_blocks(demo, found, held))
        structure = task_structure(recorded, self.blocks.names)
        write_json(cache, {"schema_version": SCHEMA_VERSION, "structure": structure.as_dict()})
        return structure

    def shapes(self, instances: dict[str, list[dict]]) -> dict[str, Path]:
        if self.robot is not None:
            joints = {name: (r.demo.times, r.joints) for name, r in self.robot.items()}
            return joint_shapes(instances, joints, self.blocks, self.settings.n_weights, self.work)
        demos = {path.name: demo for path, demo in zip(self.files, self.demos, strict=True)}
        return block_shapes(instances, demos, self.blocks, self.settings.n_weights, self.work)

    def refine(self, shapes: dict[str, Path]) -> dict[str, list[dict]]:
        if self.settings.refinement == "blocks":
            return refine_blocks(shapes, self.blocks, self.settings, self.work / "refined", self.shown)
        return refine_sequences(shapes, self.blocks, self.settings, self.work / "refined", self.shown)

    def templates(self, shapes: dict[str, Path], refined: dict[str, list[dict]]) -> tuple[str, ...]:
        return store_templates(self.out, shapes, refined, self.blocks, self.settings, self.record)


def learn(
    demos: str | Path,
    out: str | Path,
    settings: LearnSettings = DEFAULT_SETTINGS,
    *,
    blocks: BuildingBlocks,
    force: bool = False,
    progress: bool = True,
) -> LearnResult:
    """Learns a skill template pool ``out`` of the task's building ``blocks`` from the recordings in
    ``demos``; see the module documentation.

    The pool is for the blocks' task and robot. Every input is checked before anything is written: the
    settings (and their roles against the blocks), the recordings (a folder with readable recordings that
    have the hand markers, and the examples' annotations) and the output (a file; a non-empty folder that is
    not a pool learned by besman, unless ``force``; a pool learned for another task or robot or from other
    recordings or settings, unless ``force``, which then starts over). A rerun after an interruption
    resumes; a second learn into ``out`` while one runs is refused
    (:class:`~besman.core.writer_lock.WriterLock`).
    """
    settings.check(blocks)
    with WriterLock(out, "--out"):  # one learn per pool at a time
        run = _Run(Path(demos), Path(out), settings, blocks, progress)
        claim_output(run.out, run.record, force)
        movements = run.segmentations()
        instances = run.labels(movements)
        structure = run.structure(instances)
        shapes = run.shapes(instances)
        refined = run.refine(shapes)
        templates = run.templates(shapes, refined)
        from besman.learning.pipeline.plots import write_figures  # matplotlib only when it is needed

        figures = write_figures(run.out, run.demos, run.files, movements, instances, refined)
    return LearnResult(run.out, templates, refined, structure, figures)
