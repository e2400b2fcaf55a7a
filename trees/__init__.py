"""Behaviour trees: movement primitives and skill templates as py_trees leaves, tree files, the runner.

Leaves are ``py_trees.behaviour.Behaviour`` subclasses that drive the simulated robot through the executor
given to ``BehaviourTree.setup(executor=...)``; subtrees (:func:`grasp`, :func:`place`,
:func:`grasp_then_place`) compose them; :func:`load_tree` reads YAML tree files; :class:`Runner` ticks a
tree in lockstep with the simulation and logs every tick.
"""

from besman.trees.conditions import AtPose, ObjectAt, ObjectGrasped
from besman.trees.files import TreeFileError, describe, dump_tree, load_tree, loads_tree
from besman.trees.leaves import ExecutePrimitive, Gripper, InstantiateSkillTemplate
from besman.trees.manipulation import PerceiveObject, PlanGrasp, PlanPlace, grasp, grasp_then_place, place
from besman.trees.runner import Runner, RunResult, read_log
from besman.trees.timing import SimTimeout, Wait

__all__ = [
    "AtPose",
    "ExecutePrimitive",
    "Gripper",
    "InstantiateSkillTemplate",
    "ObjectAt",
    "ObjectGrasped",
    "PerceiveObject",
    "PlanGrasp",
    "PlanPlace",
    "RunResult",
    "Runner",
    "SimTimeout",
    "TreeFileError",
    "Wait",
    "describe",
    "dump_tree",
    "grasp",
    "grasp_then_place",
    "load_tree",
    "loads_tree",
    "place",
    "read_log",
]
