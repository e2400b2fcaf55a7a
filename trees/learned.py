"""The tree of a learned task, assembled from what its recordings show
(:mod:`besman.learning.pipeline.task_structure`).

Each block becomes the subtree that does what the recordings show across it, with the block's skill
template as its learned motion:

- a block after which the hand closes (it ends ``holding``) is a ``Grasp`` of the object (the template is
  its reach; descend, close and lift are planned), guarded by ``holding?`` so that a retry does not grasp
  what is already held;
- a block during which the object is held and after which the hand opens (it ends ``placed``) is a
  ``Place`` at the task's target (the template is its carry; set down, release and retreat are planned;
  its last leaf checks ``placed?``);
- a block that changes neither (the hand moves free) is a ``ReturnHome`` (the template is its move home).

A grasp and the place that follows it can fail (a missed grasp, a slip, a placement off its target): the
two are retried together, up to ``attempts`` times, each try first checking ``placed?`` (the condition the
place ends in) and acting only if it does not hold - a try that failed after the object was placed (its
retreat, say) does not reach for the placed object again. The blocks run in the recorded order, in one
``Sequence``. :func:`learned_tree` gives the file's document; :func:`write_learned_tree` writes it beside
the pool (``POOL/tree.yaml``, with ``pool: .``), where ``besman run`` finds the templates. It runs the
templates zero-shot (their means for the moves planned); a ``refine_above`` on a leaf refines an unsure
instance online, as in ``examples/trees/grasp_then_place_learned.yaml``.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import yaml

from besman.core.errors import InputError
from besman.core.storage import write_atomically
from besman.learning.pipeline.task_structure import TaskStructure
from besman.trees.files import FORMAT_VERSION

ATTEMPTS = 3  # tries of a grasp and its place, as the hand-written learned tree has
FILE = "tree.yaml"


def learned_tree(
    structure: TaskStructure,
    *,
    task: str,
    object: str,
    target: str,
    pool: str = ".",
    attempts: int = ATTEMPTS,
    subgoals: dict[str, dict[str, float]] | None = None,
) -> dict:
    """The tree file's document for ``structure``, on ``task``: ``object`` is what the hand grasps and
    places, ``target`` the blackboard key of where it goes, ``pool`` the templates' pool (relative to the
    file), ``subgoals`` per block the plan's numbers that its refinement chose (a sequence refinement's:
    :func:`~besman.learning.pipeline.sequence_refinement.subgoals`; the defaults where a block has none)."""
    subgoals = subgoals or {}
    learned = {"pool": pool}  # zero-shot: the templates' means (add refine_above to refine online)
    steps, pending = [], None  # pending: (block, step) of a grasp waiting for the place that follows it
    for block in structure.order:
        ends, held = structure.after[block], structure.holding[block]
        if ends == "holding":
            pending = (block, _grasp(block, object, target, {**learned, **subgoals.get(block, {})}))
            continue
        if ends == "placed":
            place = {
                "Place": {
                    "name": f"{block}: place the {object}",
                    "object": object,
                    "namespace": f"{block}_place",
                    "target": target,
                    "template": block,
                    **learned,
                    **subgoals.get(block, {}),
                }
            }
            unit = f"{pending[0]}, {block}" if pending else block
            placed = {"ObjectAt": {"name": "placed?", "object": object, "remap": {"target": target}}}
            steps.append(_retried(unit, [pending[1], place] if pending else [place], attempts, placed))
            pending = None
            continue
        if held:
            raise InputError(
                f"block {block!r} moves the object in the hand without a release after it; a learned tree "
                "has no leaf for that (carry it to a place, then open the hand)"
            )
        if pending:
            steps.append(_retried(pending[0], [pending[1]], attempts))
            pending = None
        steps.append({"ReturnHome": {"name": f"{block}: return home", "pool": pool, "template": block}})
    if pending:
        steps.append(_retried(pending[0], [pending[1]], attempts))
    return {
        "besman_tree": FORMAT_VERSION,
        "task": task,
        "root": {
            "Sequence": {"name": f"{task}, as the recordings show it", "memory": True, "children": steps}
        },
    }


def _grasp(block: str, object: str, target: str, learned: dict) -> dict:
    """A grasp of ``object`` by ``block``'s template, skipped if it is already held."""
    return {
        "Selector": {
            "name": f"{block}: hold the {object}",
            "memory": True,
            "children": [
                {"ObjectGrasped": {"name": "holding?", "object": object}},
                {
                    "Grasp": {
                        "name": f"{block}: grasp the {object}",
                        "object": object,
                        "namespace": f"{block}_grasp",
                        "attempts": 2,
                        "target": target,
                        "template": block,
                        **learned,
                    }
                },
            ],
        }
    }


def _retried(blocks: str, children: list[dict], attempts: int, done: dict | None = None) -> dict:
    """``children`` (the steps of ``blocks``) in a sequence, tried up to ``attempts`` times; with ``done``
    (the condition the steps end in), each try first checks it and acts only where it does not hold: a
    try that failed after it held (a retreat after a correct placement) does not start the steps again."""
    steps = {"Sequence": {"name": f"{blocks}: steps", "memory": True, "children": children}}
    if done is not None:
        steps = {"Selector": {"name": f"{blocks}: done or do", "memory": True, "children": [done, steps]}}
    return {"Retry": {"name": f"{blocks}: retried", "attempts": attempts, "child": steps}}


def write_learned_tree(pool: str | Path, structure: TaskStructure, **options) -> Path:
    """Writes :func:`learned_tree` (``options`` as there) to ``POOL/tree.yaml``, with a header saying how
    the recordings decided it; returns the path."""
    path = Path(pool) / FILE
    orders = "; ".join(f"{order} ({count})" for order, count in structure.orders.items())
    said = (
        f"Learned by besman learn from the recordings (besman.trees.learned): the blocks in the order "
        f"{' -> '.join(structure.order)}: {structure.decided} (orders seen: {orders}). The hand closes after "
        "a block at whose end the object starts moving with the hand (the grasp, then holding?) and opens "
        "after one at whose end it stops (the place, then placed?)."
    )
    header = "".join(f"# {line}\n" for line in textwrap.wrap(said, 100))
    text = header + yaml.safe_dump(learned_tree(structure, **options), sort_keys=False)
    write_atomically(path, text.encode("utf-8"))
    return path
