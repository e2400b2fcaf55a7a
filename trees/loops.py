"""A loop over a list on the blackboard: one subtree, run once per item.

A task with several objects is one subtree run for each of them, not a copy of the subtree per object:
:class:`ForEach` reads a list of items (mappings of field -> value, e.g. ``{"object": "red", "target": [x,
y]}``) from a blackboard key when it starts, and for each item in turn writes its fields to
``/<namespace>/<field>`` and runs its child to the end. The child's behaviours read the current item from
those keys (an ``object: /sort/object`` parameter, a ``target`` remapped to ``/sort/target``). The loop
succeeds when the child has succeeded for every item, and fails at the first item whose child fails
(recovering within an item, e.g. regrasping a box that slipped, is the child's own business: a ``Retry``).

The list is read once, at the start, so a child that writes to it does not change the loop it is in.
"""

from __future__ import annotations

from collections.abc import Mapping

import py_trees
from py_trees.common import Access, Status

from besman.core.validation import checked, text
from besman.trees.base import BEHAVIOUR


class ForEach(py_trees.decorators.Decorator):
    """Runs ``child`` once per item of the list at the blackboard key ``items``; see the module
    documentation.

    Args:
        name: the node's name.
        child: the subtree run per item.
        items: the key of the list of items (mappings of field -> value).
        namespace: where each item's fields are written (``/<namespace>/<field>``).
    """

    @checked(
        name=text("a behaviour name"),
        child=BEHAVIOUR,
        items=text("a blackboard key"),
        namespace=text("a namespace"),
    )
    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, *, items: str, namespace: str) -> None:
        super().__init__(name=name, child=child)
        self.items_key, self.namespace = items, "/" + namespace.strip("/")
        self.blackboard = self.attach_blackboard_client(name=name)
        self.blackboard.register_key(key=items, access=Access.READ)
        self._items: list[Mapping] = []
        self._problem = ""
        self.index = 0  # the item being worked on

    def tick(self):
        # Decorator.tick, with the list read when the loop starts and no child run for no items.
        if self.status is not Status.RUNNING:
            self._start()
        if self._problem or not self._items:
            new_status = Status.FAILURE if self._problem else Status.SUCCESS
            self.feedback_message = self._problem or f"{self.items_key} is empty: nothing to do"
        else:
            yield from self.decorated.tick()
            new_status = self.update()
        if new_status is not Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self

    def _start(self) -> None:
        self.index, self._items, self._problem = 0, [], ""
        items = self.blackboard.get(self.items_key) if self.blackboard.exists(self.items_key) else None
        if not isinstance(items, list | tuple) or not all(isinstance(item, Mapping) for item in items):
            self._problem = f"{self.items_key} must hold a list of mappings (field -> value), got {items!r}"
            return
        self._items = list(items)
        if self._items:
            self._write(0)

    def update(self) -> Status:
        child = self.decorated.status
        total = len(self._items)
        if child is Status.FAILURE:
            self.feedback_message = (
                f"item {self.index + 1} of {total} failed: {self.decorated.feedback_message}"
            )
            return Status.FAILURE
        if child is Status.SUCCESS:
            if self.index + 1 == total:
                self.feedback_message = f"all {total} items done"
                return Status.SUCCESS
            self.decorated.stop(Status.INVALID)  # a fresh run of the child for the next item
            self._write(self.index + 1)
        self.feedback_message = f"item {self.index + 1} of {total}: {self._label()}"
        return Status.RUNNING

    def _write(self, index: int) -> None:
        self.index = index
        for field, value in self._items[index].items():
            key = f"{self.namespace}/{field}"
            self.blackboard.register_key(key=key, access=Access.WRITE)
            self.blackboard.set(key, value, overwrite=True)

    def _label(self) -> str:
        item = self._items[self.index]
        return str(item.get("object", item.get("name", ", ".join(f"{k}={v}" for k, v in item.items()))))
