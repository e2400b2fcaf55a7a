"""What a learn is asked to do, and whether its output folder may take it: :class:`LearnSettings`, the run's
record (``work/learn.json``) and :func:`claim_output`.

The record holds the task, the robot, the settings and the recordings' checksums. A learn into a folder
whose record is the same resumes; a record of another task or robot, or of other recordings or settings,
is refused unless ``force`` (which starts over). A record written before learn.json named its task has no
``task``: it counts as one of other settings.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from besman.core.errors import BesmanError, InputError
from besman.core.storage import holds_files, read_json, remove_temporaries, write_atomically
from besman.learning.pipeline.building_blocks import BuildingBlocks
from besman.learning.search.policy_search import check_optimizer

SCHEMA_VERSION = 1
KIND = "besman-learn"
# The folders in a pool that learn writes (besides the pool itself), where a killed learn leaves temporaries.
POOL_FOLDERS = ("work", "work/segments", "work/imitated", "work/shapes", "work/refined")


class LearnError(BesmanError):
    """The pipeline cannot run on this input or output; the message names the file, folder or setting."""


REFINEMENTS = ("blocks", "sequence", "sequence-by-block")


@dataclass(frozen=True)
class LearnSettings:
    """What a run learns and how (recorded in ``work/learn.json``).

    Attributes:
        tasks: training tasks K per block.
        budget: rollouts per training task (whole CMA-ES generations; the start is one more).
        seed: seeds the training tasks and every search.
        backend: "threads" (local worker processes) or "ray".
        n_blocks: building blocks to cluster into (without examples).
        examples: annotated recordings whose segments label the others (few-shot) instead of clustering.
        roles: which label plays each of the task's blocks (empty: the task's defaults for clustering or
            examples).
        n_weights: forcing weights per joint of the retargeted primitives.
        spread: the search's initial standard deviation (theta units: 0.1 rad per unit).
        optimizer: the policy search's optimiser by name (``"cmaes"``, ``"xnes"`` or a registered one:
            :func:`~besman.learning.search.policy_search.optimizer_names`).
        refinement: how the blocks are refined: ``"blocks"`` each alone, from the planned starts, for its
            own reward; ``"sequence"`` all together on whole-task rollouts with perturbations, each block
            credited with its cost-to-go; ``"sequence-by-block"`` on the same rollouts, one block after
            the other for its own cost (the comparison); see
            :mod:`besman.learning.pipeline.sequence_refinement`.
    """

    tasks: int = 8
    budget: int = 48
    seed: int = 0
    backend: str = "threads"
    n_blocks: int = 6
    examples: tuple[str, ...] = ()
    roles: tuple[tuple[str, str], ...] = ()
    n_weights: int = 6
    spread: float = 0.1
    refinement: str = "blocks"
    optimizer: str = "cmaes"

    def role_labels(self, blocks: BuildingBlocks, robot: bool = False) -> dict[str, str]:
        """The label that plays each block: the task's default for how the recordings are labelled (like
        the examples; a ``robot``'s by its gripper's events; clustered), unless ``roles`` names another."""
        given = dict(self.roles)
        unknown = sorted(set(given) - set(blocks.names))
        if unknown:
            raise LearnError(
                f"roles: unknown block {unknown[0]!r}; blocks of {blocks.task}: {', '.join(blocks.names)}"
            )
        labelled = "examples" if self.examples else "gripper" if robot else "clustered"
        if labelled not in blocks.roles:
            raise LearnError(f"task {blocks.task} names no roles for recordings labelled by {labelled}")
        return {**blocks.roles[labelled], **given}

    def check(self, blocks: BuildingBlocks) -> None:
        for name, low in (("tasks", 2), ("budget", 1), ("n_blocks", 3), ("n_weights", 2)):
            if getattr(self, name) < low:
                raise LearnError(f"{name} must be at least {low}, got {getattr(self, name)}")
        try:
            check_optimizer(self.optimizer)
        except InputError as error:
            raise LearnError(str(error)) from None
        if self.refinement not in REFINEMENTS:
            raise LearnError(f"refinement must be one of {', '.join(REFINEMENTS)}, got {self.refinement!r}")
        if self.refinement != "blocks" and blocks.sequence is None:
            raise LearnError(f"task {blocks.task} has no whole-task rollouts: refinement must be 'blocks'")
        if not self.spread > 0:
            raise LearnError(f"spread must be positive, got {self.spread}")
        if not self.examples:
            clusters = {f"block{k + 1}" for k in range(self.n_blocks)}
            for block, label in self.role_labels(blocks).items():
                if label not in clusters:
                    raise LearnError(
                        f"roles: {block}={label!r} names no cluster; clustering into {self.n_blocks} names "
                        f"them block1 to block{self.n_blocks} (or give --examples to use their labels)"
                    )

    def as_dict(self, blocks: BuildingBlocks) -> dict:
        """The settings as the record holds them: with the robot, and the role of every block."""
        document = {"robot": blocks.robot, **dataclasses.asdict(self)}
        document["examples"] = list(self.examples)
        document["roles"] = self.role_labels(blocks)
        for name, default in (("refinement", "blocks"), ("optimizer", "cmaes")):
            if document[name] == default:  # the records of pools learned before there was a choice
                del document[name]
        return document


def learn_record(
    blocks: BuildingBlocks, settings: LearnSettings, files: list[Path], checksums: list[str]
) -> dict:
    """The record of a run (``work/learn.json``): what a rerun must match to resume."""
    return {
        "schema_version": SCHEMA_VERSION,
        "kind": KIND,
        "task": blocks.task,
        "robot": blocks.robot,
        "settings": settings.as_dict(blocks),
        "recordings": [
            {"file": path.name, "sha256": digest} for path, digest in zip(files, checksums, strict=True)
        ],
    }


def claim_output(out: Path, record: dict, force: bool) -> None:
    """Checks the output folder before anything is written (see
    :func:`~besman.learning.pipeline.end_to_end.learn`) and writes ``record`` unless the run resumes; then
    removes the temporaries that a killed learn left, if the folder is known to be besman's (its record, or
    nothing in it but besman's temporaries; never in a folder of the user's that ``force`` writes into)."""
    record_path = out / "work" / "learn.json"
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
        for key in ("task", "robot"):
            if key in previous and previous[key] != record[key] and not force:
                raise LearnError(
                    f"{out}: the pool was learned for {key} {previous[key]!r}, not {record[key]!r} "
                    "(--force replaces it)"
                )
        ours, resume = True, previous == record
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
                f"{out}: the folder is not empty and not a pool learned by besman (--force writes into it)"
            )
    if not resume:
        write_json(record_path, record)
    if ours:
        remove_temporaries(out, POOL_FOLDERS)


def write_json(path: Path, document: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(path, (json.dumps(document, indent=1) + "\n").encode("utf-8"))


def progress_bar(total: int, what: str, unit: str, shown: bool) -> tqdm:
    """A bar of a stage's progress that goes when the stage ends (none unless ``shown``)."""
    return tqdm(total=total, desc=what, unit=unit, disable=not shown, leave=False)
