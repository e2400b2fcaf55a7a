"""The task's structure as the recordings show it: the order of its blocks, where the hand closes and opens
between them, and what each block changes - what a tree is assembled from, the contrary of segmentation.

Per recording, the labelled instances of the task's blocks (``work/labels.json``) come in an order, and the
object's marker says whether the hand holds the object during each: a held object moves with the hand, a
free one rests, so the object's displacement over a block, as a share of the hand's, is near 1 or near 0
(:data:`HOLDING_SHARE` between them; on the shared recordings it is 1.15-1.23 for every carry and 0.00-0.01
for every reach and return but one mislabelled reach, 1.45). From that:

- **order**: the order most recordings show (counted over the recordings that have every block); a tie
  goes to the order of the blocks' median start, as a share of each recording's length.
- **holding**: per block, whether the object is held during it, by majority over the recordings (a tie:
  not held); the votes are kept.
- **events**: between two blocks, ``close`` where the object is free in the first and held in the second
  (a grasp), ``open`` where it is held and then free (a release), none otherwise; after the last block,
  ``open`` if it holds the object (a task ends with the hand empty, the object put down).
- **conditions**: a block followed by ``close`` ends ``holding``; one followed by ``open`` ends with the
  object ``placed``; the others change neither.

:func:`task_structure` decides from the per-recording sequences; :func:`recorded_blocks` reads one
recording's. The tree that runs it is built by :mod:`besman.trees.learned`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from besman.learning.pipeline.record import LearnError
from besman.learning.segmentation.demonstration import Demonstration

OBJECT_MARKER = "Box back"  # the object's marker on the shared recordings
HAND_MARKER = "Hand top"
HOLDING_SHARE = 0.5  # the object moves at least this share of the hand's displacement over a block: held
SMALLEST_MOVE = 0.02  # m: a block over which the hand moves less says nothing about holding


@dataclass(frozen=True)
class RecordedBlock:
    """One block's instance in one recording: its samples and whether the object moved with the hand
    (None: the object's marker is missing there, or the hand hardly moved)."""

    block: str
    start: int
    end: int
    holding: bool | None


@dataclass(frozen=True)
class TaskStructure:
    """What the recordings say about the task's sequence (see the module documentation).

    Attributes:
        order: the blocks in the order the task does them.
        holding: per block, whether the object is in the hand during it.
        events: per block, the gripper event after it: "close", "open" or None.
        after: per block, the condition it ends in: "holding", "placed" or None.
        orders: every complete order seen, with how many recordings show it.
        votes: per block, how many recordings saw it held and free.
        decided: how the order was decided, in words.
    """

    order: tuple[str, ...]
    holding: dict[str, bool]
    events: dict[str, str | None]
    after: dict[str, str | None]
    orders: dict[str, int]
    votes: dict[str, dict[str, int]]
    decided: str

    def as_dict(self) -> dict:
        return {
            "order": list(self.order),
            "holding": self.holding,
            "events": self.events,
            "after": self.after,
            "orders": self.orders,
            "votes": self.votes,
            "decided": self.decided,
        }

    @classmethod
    def from_dict(cls, document: dict) -> TaskStructure:
        return cls(
            tuple(document["order"]),
            dict(document["holding"]),
            dict(document["events"]),
            dict(document["after"]),
            dict(document["orders"]),
            {block: dict(votes) for block, votes in document["votes"].items()},
            document["decided"],
        )


def recorded_blocks(
    demo: Demonstration, instances: dict[str, tuple[int, int]], held: np.ndarray | None = None
) -> list[RecordedBlock]:
    """One recording's block instances (block -> first and last sample), in the order they start, each with
    whether the object moved with the hand over it - or, for a robot's recording, whether its gripper was
    closed (``held``, per sample) over the middle half of it."""
    hand = demo.channels.get(HAND_MARKER)
    item = demo.channels.get(OBJECT_MARKER)
    found = []
    for block, (start, end) in sorted(instances.items(), key=lambda entry: entry[1][0]):
        holding = None
        if held is not None:
            quarter = (end - start) // 4
            holding = bool(np.median(held[start + quarter : end - quarter + 1]))
        elif hand is not None and item is not None:
            moved = np.linalg.norm(hand[end] - hand[start])
            carried = np.linalg.norm(item[end] - item[start])
            if np.isfinite(moved) and np.isfinite(carried) and moved >= SMALLEST_MOVE:
                holding = bool(carried / moved >= HOLDING_SHARE)
        found.append(RecordedBlock(block, int(start), int(end), holding))
    return found


def task_structure(recordings: list[list[RecordedBlock]], blocks: tuple[str, ...]) -> TaskStructure:
    """The task's structure from each recording's blocks (:func:`recorded_blocks`) for the task's
    ``blocks``; see the module documentation."""
    complete = [r for r in recordings if sorted(b.block for b in r) == sorted(blocks)]
    if not complete:
        raise LearnError(
            f"no recording shows every block of the task ({', '.join(blocks)}): the order cannot be read"
        )
    orders = Counter(" -> ".join(b.block for b in r) for r in complete)
    ranked = orders.most_common()
    tied = [order for order, count in ranked if count == ranked[0][1]]
    if len(tied) == 1:
        order = tuple(tied[0].split(" -> "))
        decided = f"{ranked[0][1]} of {len(complete)} recordings with every block show this order"
    else:
        phase = {
            block: float(
                np.median([b.start / max(r[-1].end, 1) for r in complete for b in r if b.block == block])
            )
            for block in blocks
        }
        order = tuple(sorted(blocks, key=phase.get))
        decided = (
            f"orders tied at {ranked[0][1]} of {len(complete)} recordings; ordered by the blocks' median "
            "start (a share of each recording's length)"
        )
    votes = {block: {"held": 0, "free": 0} for block in blocks}
    for recording in recordings:
        for found in recording:
            if found.block in votes and found.holding is not None:
                votes[found.block]["held" if found.holding else "free"] += 1
    holding = {block: votes[block]["held"] > votes[block]["free"] for block in blocks}
    events, after = {}, {}
    for block, following in zip(order, (*order[1:], None), strict=True):
        event = None
        held_next = False if following is None else holding[following]  # a task ends with the hand empty
        if holding[block] != held_next:
            event = "close" if held_next else "open"
        events[block] = event
        after[block] = {"close": "holding", "open": "placed"}.get(event)
    return TaskStructure(order, holding, events, after, dict(orders), votes, decided)
