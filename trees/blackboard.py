"""The blackboard layout of besman trees, in one place.

Keys are grouped by skill instance: each instance has its own namespace (``/grasp``, ``/place``, ...), so two
instances of a skill never share keys. Leaves address keys by role; ``namespace`` and ``remap`` choose the
key (:mod:`besman.trees.base`). Defaults:

- ``/task/place`` - the place target (x, y); written by the runner (``--set place=x,y``), read by
  ``Place`` through its ``target`` remapped to it.
- ``/task/<name>`` - numbers given on the command line (``--set name=...``); read by leaves remapped to them.
  A demo may put a list of items there for a loop (``/task/objects`` of the sort demo: ``{object, target}``).
- ``/<ns>/<field>`` - the current item's fields, written by ``ForEach`` (namespace ``<ns>``) before each run
  of its child (``/sort/object``, ``/sort/target``).
- ``/<ns>/object_position`` - (x, y, z) of the object; ``PerceiveObject`` writes, ``PlanGrasp`` reads.
- ``/<ns>/reach``, ``/<ns>/descend``, ``/<ns>/lift`` - movement primitives; ``PlanGrasp`` writes, the
  ``ExecutePrimitive`` leaves of the grasp subtree read.
- ``/<ns>/target`` - (x, y) or (x, y, z); the tree's author or a remap provides it, ``PlanPlace`` and
  ``ObjectAt`` read it.
- ``/<ns>/carry``, ``/<ns>/place``, ``/<ns>/retreat`` - movement primitives; ``PlanPlace`` writes, the
  place subtree's ``ExecutePrimitive`` leaves read.
- ``/<ns>/tau`` - task parameters; provided by the author or a remap, read by ``InstantiateSkillTemplate``.
- ``/<ns>/primitive`` - a movement primitive; ``InstantiateSkillTemplate`` writes, ``ExecutePrimitive`` reads.
- ``/<ns>/configuration`` - joint values; provided by the author or a remap, read by ``AtPose``.
- ``/<ns>/goal`` - a hand pose ``{position, yaw}``; a remap (``/task/ready``) provides it, ``PlanMove`` reads.
- ``/<ns>/motion`` - a movement primitive to that pose; ``PlanMove`` writes, ``ExecutePrimitive`` reads.
- ``/<ns>/shape`` - a learned return (``InstantiateSkillTemplate`` writes it), read by ``PlanReturn``.
- ``/<ns>/return`` - a movement primitive back to the home configuration; ``PlanReturn`` writes, the return
  subtree's ``ExecutePrimitive`` reads.

:func:`set_task_values` writes the ``/task`` values of a run. A task's own leaves document their keys
(the throwing task's: :mod:`besman.tasks.throwing.leaves`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import py_trees

TASK_NAMESPACE = "/task"


def set_task_values(values: Mapping[str, object]) -> None:
    """Writes ``/task/<name>`` for each value (through a client of its own, as py_trees wants)."""
    client = py_trees.blackboard.Client(name="task values")
    for name, value in values.items():
        key = f"{TASK_NAMESPACE}/{name}"
        client.register_key(key=key, access=py_trees.common.Access.WRITE)
        # Numbers become arrays; names and structured values (a pose, a list of items for a loop) stay as
        # they are.
        structured = isinstance(value, str | Mapping) or (
            isinstance(value, list | tuple)
            and (not value or any(isinstance(item, Mapping) for item in value))
        )
        client.set(key, value if structured else np.asarray(value, dtype=float), overwrite=True)


def task_keys_read(root: py_trees.behaviour.Behaviour) -> set[str]:
    """The names of the ``/task/<name>`` values that the nodes of a tree read (after their remaps)."""
    prefix = f"{TASK_NAMESPACE}/"
    keys = set()
    for node in root.iterate():
        for client in node.blackboards:
            for key in client.read:
                remapped = client.remappings.get(key, key)
                if remapped.startswith(prefix):
                    keys.add(remapped[len(prefix) :])
    return keys
