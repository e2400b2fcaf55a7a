"""Behaviour trees: movement primitives and skill templates as py_trees leaves, tree files, the runner.

Leaves are ``py_trees.behaviour.Behaviour`` subclasses that drive the simulated robot through the executor
given to ``BehaviourTree.setup(executor=...)``, using the blackboard by declared roles
(:mod:`besman.trees.base`); subtree idioms (:func:`grasp`, :func:`place`, :func:`grasp_then_place`,
:mod:`besman.trees.idioms`) compose them; :func:`load_tree` reads YAML tree files (node types in
:mod:`besman.trees.nodes`, more added by :func:`register_node_type` or installed plugins); :class:`Runner`
ticks a tree in lockstep with the simulation and logs every tick, each run ending in a :class:`RunSummary`
(the tasks that set runs up and judge them are :mod:`besman.tasks`); :mod:`besman.trees.watching` shows a
run in the browser viewer. A file names Python templates and pools only as registered
(:func:`register_template`, :func:`register_pool`) or in modules the caller allows
(:mod:`besman.trees.registry`).
"""

from besman.core.moved import old_names
from besman.trees.conditions import ArmsApart, AtPose, ObjectAt, ObjectGrasped
from besman.trees.files import TreeFileError, check_tree, describe, dump_tree, load_tree, loads_tree
from besman.trees.guards import KeepApart
from besman.trees.idioms import grasp, grasp_then_place, place, return_home
from besman.trees.leaves import ExecutePrimitive, Gripper, InstantiateSkillTemplate
from besman.trees.loops import ForEach
from besman.trees.manipulation import PerceiveObject, PlanGrasp, PlanMove, PlanPlace, PlanReturn
from besman.trees.nodes import register_node_type
from besman.trees.registry import register_pool, register_template
from besman.trees.runner import Runner, RunResult, read_log
from besman.trees.summary import RunSummary
from besman.trees.timing import Deadline, SimTimeout, Wait

__all__ = [
    "ArmsApart",
    "AtPose",
    "Deadline",
    "ExecutePrimitive",
    "ForEach",
    "Gripper",
    "InstantiateSkillTemplate",
    "KeepApart",
    "ObjectAt",
    "ObjectGrasped",
    "PerceiveObject",
    "PlanGrasp",
    "PlanMove",
    "PlanPlace",
    "PlanReturn",
    "RunResult",
    "RunSummary",
    "Runner",
    "SimTimeout",
    "TreeFileError",
    "Wait",
    "check_tree",
    "describe",
    "dump_tree",
    "grasp",
    "grasp_then_place",
    "load_tree",
    "loads_tree",
    "place",
    "read_log",
    "register_node_type",
    "register_pool",
    "register_template",
    "return_home",
]

__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
