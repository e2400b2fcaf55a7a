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

from besman.core.lazy import lazy_names

# Where each name lives; imported on first use, so that loading, showing or checking a tree file does not
# bring the runner (MuJoCo) with it.
_HOMES = {
    "conditions": ("ArmsApart", "AtPose", "ObjectAt", "ObjectGrasped"),
    "files": ("TreeFileError", "check_tree", "describe", "dump_tree", "load_tree", "loads_tree"),
    "guards": ("KeepApart",),
    "idioms": ("grasp", "grasp_then_place", "place", "return_home"),
    "leaves": ("ExecutePrimitive", "Gripper", "InstantiateSkillTemplate"),
    "loops": ("ForEach",),
    "manipulation": ("PerceiveObject", "PlanGrasp", "PlanMove", "PlanPlace", "PlanReturn"),
    "nodes": ("register_node_type",),
    "registry": ("register_pool", "register_template"),
    "runner": ("Runner", "RunResult", "read_log"),
    "summary": ("RunSummary",),
    "timing": ("Deadline", "SimTimeout", "Wait"),
}

__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES)
