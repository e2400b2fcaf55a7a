"""The tree learned from the recordings: the blocks' order, the gripper events from the object's marker, the
conditions, and the tree file (``POOL/tree.yaml``) - on synthetic recordings of two block orders and on the
shared ones."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import run_cli

from besman.core.errors import InputError
from besman.learning.pipeline.task_structure import recorded_blocks, task_structure
from besman.learning.segmentation.demonstration import Demonstration
from besman.trees.learned import learned_tree, write_learned_tree

ROOT = Path(__file__).resolve().parents[1]
POOLS = ROOT / "examples" / "pools"
BLOCKS = ("reach", "carry", "return")
RATE = 60.0
# Where the hand goes in each block of the synthetic person: from, to (m); the object rides along where held.
MOVES = {"reach": ((0.0, 0.3, 0.2), (0.4, 0.0, 0.05)), "carry": ((0.4, 0.0, 0.05), (0.3, -0.4, 0.25))}
MOVES["return"] = ((0.3, -0.4, 0.25), (0.0, 0.3, 0.2))


def synthetic(order: tuple[str, ...], held: set[str] = frozenset({"carry"}), seed: int = 0):
    """A recording of the hand doing ``order``'s moves (one second each, a pause between) and the object
    moving with it in the ``held`` blocks: the recording and its blocks' sample ranges."""
    rng = np.random.default_rng(seed)
    hand, box, instances = [], [], {}
    where = np.array([0.4, 0.0, 0.0])  # the object, on the table
    for block in order:
        start, goal = (np.array(p) for p in MOVES[block])
        s = np.linspace(0.0, 1.0, int(RATE))[:, None]
        path = start + (10 * s**3 - 15 * s**4 + 6 * s**5) * (goal - start)
        first = len(hand)
        hand.extend(path)
        box.extend(path - [0.0, 0.0, 0.05] if block in held else np.tile(where, (len(path), 1)))
        if block in held:
            where = box[-1].copy()
        instances[block] = (first, len(hand) - 1)
        hand.extend(np.tile(path[-1], (20, 1)))  # a pause
        box.extend(np.tile(where, (20, 1)))
    noise = rng.normal(0.0, 2e-4, (len(hand), 3))
    times = np.arange(len(hand)) / RATE
    channels = {"Hand top": np.array(hand) + noise, "Box back": np.array(box) + noise}
    return Demonstration(times, np.arange(len(hand)), channels, source=f"synthetic {order}"), instances


def structure_of(*recordings):
    return task_structure([recorded_blocks(demo, found) for demo, found in recordings], BLOCKS)


def steps(document: dict) -> list[str]:
    """The types of the root sequence's children, and of what a retry holds."""
    found = []
    for child in document["root"]["Sequence"]["children"]:
        kind, body = next(iter(child.items()))
        if kind == "Retry":
            child = body["child"]
            if "Selector" in child:  # the condition the steps end in, checked first
                done, child = child["Selector"]["children"]
                found.append(f"Retry[{next(iter(done))} or ")
            else:
                found.append("Retry[")
            inner = child["Sequence"]["children"]
            found[-1] += ", ".join(next(iter(c)) for c in inner) + "]"
        else:
            found.append(kind)
    return found


def tree_of(structure) -> dict:
    return learned_tree(structure, task="pick-place", object="box", target="/task/place")


def test_the_recorded_order_and_the_objects_marker_make_the_tree():
    structure = structure_of(*(synthetic(BLOCKS, seed=k) for k in range(3)))
    assert structure.order == BLOCKS
    assert structure.holding == {"reach": False, "carry": True, "return": False}
    assert structure.events == {"reach": "close", "carry": "open", "return": None}
    assert structure.after == {"reach": "holding", "carry": "placed", "return": None}
    assert structure.decided == "3 of 3 recordings with every block show this order"
    assert steps(tree_of(structure)) == ["Retry[ObjectAt or Selector, Place]", "ReturnHome"]


def test_recordings_of_another_order_give_another_tree():
    """The person first goes to rest, then picks and places: the return comes first, the grasp and place
    after it, and nothing follows the place."""
    order = ("return", "reach", "carry")
    structure = structure_of(*(synthetic(order, seed=k) for k in range(3)))
    assert structure.order == order and structure.events == {
        "return": None,
        "reach": "close",
        "carry": "open",
    }
    assert steps(tree_of(structure)) == ["ReturnHome", "Retry[ObjectAt or Selector, Place]"]
    assert tree_of(structure) != tree_of(structure_of(synthetic(BLOCKS)))


def test_where_recordings_disagree_most_decide_and_a_tie_goes_to_the_median_start():
    usual, other = ("reach", "carry", "return"), ("return", "reach", "carry")
    found = structure_of(synthetic(usual, seed=1), synthetic(other, seed=2), synthetic(usual, seed=3))
    assert found.order == usual and found.orders == {
        "reach -> carry -> return": 2,
        "return -> reach -> carry": 1,
    }
    assert found.decided.startswith("2 of 3 recordings")
    tied = structure_of(synthetic(usual, seed=1), synthetic(other, seed=2))
    assert "tied" in tied.decided and len(tied.order) == 3
    # One recording in which the reach moved the object (a mislabelled segment) is outvoted.
    outvoted = structure_of(
        synthetic(usual, {"carry", "reach"}, 1), synthetic(usual, seed=2), synthetic(usual, seed=3)
    )
    assert outvoted.votes["reach"] == {"held": 1, "free": 2} and outvoted.holding["reach"] is False


def test_a_block_that_carries_the_object_on_without_a_release_has_no_leaf():
    """Held through the carry and the return: the carry ends holding, not placed."""
    structure = structure_of(synthetic(BLOCKS, {"carry", "return"}))
    assert structure.events == {"reach": "close", "carry": None, "return": "open"}
    with pytest.raises(InputError, match="block 'carry' moves the object in the hand without a release"):
        tree_of(structure)


def test_the_learned_trees_of_the_committed_pools_are_what_the_learner_makes_and_pass_the_check(capsys):
    """Each committed pool's tree is its recorded structure made into a tree, and ``besman tree check``
    passes it (its templates and the pool where the tree says)."""
    from besman.learning.pipeline.task_structure import TaskStructure

    for robot in ("aila", "ur5e", "openarm"):
        pool = POOLS / f"pick_place_{robot}"
        document = json.loads((pool / "work" / "structure.json").read_text())["structure"]
        structure = TaskStructure.from_dict(document)
        assert structure.order == BLOCKS and structure.orders == {"reach -> carry -> return": 15}
        written = yaml.safe_load((pool / "tree.yaml").read_text())
        assert written == tree_of(structure), robot
        code, out, _ = run_cli(capsys, "tree", "check", str(pool / "tree.yaml"))
        assert code == 0, out


def test_subgoals_go_to_the_grasp_and_the_place(tmp_path):
    structure = structure_of(synthetic(BLOCKS))
    shutil.copytree(
        POOLS / "pick_place_aila", tmp_path / "pool", ignore=shutil.ignore_patterns("work", "*.png")
    )
    subgoals = {"reach": {"approach_height": 0.12, "descend_time": 1.4}, "carry": {"clearance": 0.05}}
    path = write_learned_tree(
        tmp_path / "pool", structure, task="pick-place", object="box", target="/task/place", subgoals=subgoals
    )
    text = path.read_text()
    assert text.startswith("# Learned by besman learn from the recordings")
    document = yaml.safe_load(text)
    retry = document["root"]["Sequence"]["children"][0]["Retry"]["child"]["Selector"]["children"][1]
    retry = retry["Sequence"]["children"]
    grasp = retry[0]["Selector"]["children"][1]["Grasp"]
    assert grasp["approach_height"] == 0.12 and grasp["descend_time"] == 1.4
    assert retry[1]["Place"]["clearance"] == 0.05
