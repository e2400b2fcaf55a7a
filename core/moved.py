"""Modules that moved: their old names keep importing, as the very same module, for one release, with a
:class:`DeprecationWarning` that names the new place.

:data:`MOVED` maps each old name to its new one. :class:`MovedModules`, put on ``sys.meta_path`` as the
``besman`` package is imported (before any of its subpackages), answers an old name with the new module:
``import besman.sim.throwing`` and ``import besman.tasks.throwing.rollouts`` then give one module object,
so its classes, errors and state are the same whichever name a user's code imports.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

# Issue 53 (besman 0.x): old name -> new name.
MOVED = {
    "besman.skills.errors": "besman.core.errors",
    "besman.skills.lazy": "besman.core.lazy",
    "besman.skills.plugins": "besman.core.plugins",
    "besman.skills.reading": "besman.core.reading",
    "besman.skills.seeds": "besman.core.seeds",
    "besman.skills.storage": "besman.core.storage",
    "besman.skills.validation": "besman.core.validation",
    "besman.skills.writer_lock": "besman.core.writer_lock",
    "besman.skills.tasks": "besman.skills.task_bounds",
    "besman.learning.dataset_format": "besman.datasets.format",
    "besman.learning.dataset_reader": "besman.datasets.reader",
    "besman.learning.dataset_writer": "besman.datasets.writer",
    "besman.learning.demonstration": "besman.learning.segmentation.demonstration",
    "besman.learning.preprocessing": "besman.learning.segmentation.preprocessing",
    "besman.learning.contact": "besman.learning.segmentation.contact",
    "besman.learning.changepoints": "besman.learning.segmentation.changepoints",
    "besman.learning.segmentation_plot": "besman.learning.segmentation.plot",
    "besman.learning.boundaries": "besman.learning.segmentation.boundaries",
    "besman.learning.labelling": "besman.learning.segmentation.labelling",
    "besman.learning.pipeline_labels": "besman.learning.pipeline.labels",
    "besman.learning.pipeline_plots": "besman.learning.pipeline.plots",
    "besman.learning.pipeline_record": "besman.learning.pipeline.record",
    "besman.learning.pipeline_refinement": "besman.learning.pipeline.refinement",
    "besman.learning.pipeline_sequence": "besman.learning.pipeline.sequence_refinement",
    "besman.learning.task_structure": "besman.learning.pipeline.task_structure",
    "besman.learning.imitation": "besman.learning.pipeline.imitation",
    "besman.learning.retargeting": "besman.learning.pipeline.retargeting",
    "besman.learning.blocks": "besman.learning.pipeline.building_blocks",
    "besman.learning.dataset_demonstrations": "besman.learning.pipeline.dataset_demonstrations",
    "besman.learning.policy_search": "besman.learning.search.policy_search",
    "besman.learning.contextual_search": "besman.learning.search.contextual",
    "besman.learning.linear_gaussian": "besman.learning.search.linear_gaussian",
    "besman.learning.outcome_refinement": "besman.learning.search.outcome_refinement",
    "besman.learning.feasibility": "besman.learning.search.feasibility",
    "besman.learning.sequences": "besman.learning.search.hierarchical",
    "besman.learning.online": "besman.learning.search.online",
    "besman.sim.blocks": "besman.sim.block_simulation",
    "besman.sim.throwing": "besman.tasks.throwing.rollouts",
    "besman.sim.throw_execution": "besman.tasks.throwing.executor",
    "besman.sim.throwing_view": "besman.tasks.throwing.view",
    "besman.trees.throwing": "besman.tasks.throwing.leaves",
    "besman.learning.throwing_bench": "besman.experiments.throwing.bench",
    "besman.learning.throwing_claims": "besman.experiments.throwing.claims",
    "besman.learning.throwing_config": "besman.experiments.throwing.config",
    "besman.learning.throwing_contextual": "besman.experiments.throwing.contextual",
    "besman.learning.throwing_curves": "besman.experiments.throwing.curves",
    "besman.learning.throwing_evaluation": "besman.experiments.throwing.evaluation",
    "besman.learning.throwing_output": "besman.experiments.throwing.output",
    "besman.learning.throwing_plots": "besman.experiments.throwing.plots",
    "besman.learning.throwing_results": "besman.experiments.throwing.results",
    "besman.learning.throwing_spreads": "besman.experiments.throwing.spreads",
    "besman.learning.throwing_templates": "besman.experiments.throwing.templates",
    "besman.learning.throwing_training": "besman.experiments.throwing.training",
    "besman.learning.throwing_experiment": "besman.experiments.throwing.experiment",
    "besman.hosts": "besman.sim.hosts",
    "besman.learning.promp_baseline": "besman.tasks.pick_place.promp_baseline",
}

# Names that left a module or were renamed: module -> {old name: "new module:new name"}; "*" for every name
# of a module that became a package of the same name.
MOVED_NAMES = {
    "besman.learning.pipeline": {"*": "besman.learning.pipeline.end_to_end"},
    "besman.learning.segmentation": {"*": "besman.learning.segmentation.segmenter"},
    "besman.sim": {
        "ThrowingConfig": "besman.tasks.throwing.rollouts:ThrowingConfig",
        "ThrowingTask": "besman.tasks.throwing.rollouts:ThrowingRollouts",
        "throwing_world": "besman.tasks.throwing.world:throwing_world",
    },
    "besman.sim.world": {"throwing_world": "besman.tasks.throwing.world:throwing_world"},
    "besman.sim.manipulation": {
        name: f"besman.sim.plans:{name}"
        for name in (
            "DEFAULT_PLAN",
            "PLAN_RANGES",
            "GRASP_SUBGOALS",
            "PLACE_SUBGOALS",
            "Step",
            "PICK_STEPS",
            "PLACE_STEPS",
        )
    },
    "besman.sim.evaluation": {"BatchedTask": "besman.sim.evaluation:BatchedRollouts"},
    "besman.trees": {
        "AimThrow": "besman.tasks.throwing.leaves:AimThrow",
        "Throw": "besman.tasks.throwing.leaves:Throw",
    },
    "besman.tasks.throwing.rollouts": {"ThrowingTask": "besman.tasks.throwing.rollouts:ThrowingRollouts"},
    "besman.tasks.pick_place.episode": {"PickPlaceTask": "besman.tasks.pick_place.episode:PickPlaceRollouts"},
    "besman.tasks.pick_place.sequence": {"SequenceTask": "besman.tasks.pick_place.sequence:SequenceRollouts"},
    "besman.tasks.pick_place.blocks": {"BlockTask": "besman.tasks.pick_place.blocks:BlockRollouts"},
}


class MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names of :data:`MOVED` and loads each as its new module."""

    def find_spec(self, name: str, path=None, target=None) -> importlib.machinery.ModuleSpec | None:
        if name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(name, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        # stacklevel 2: the importing line (warnings skips importlib's own frames)
        warnings.warn(f"{spec.name} is now {MOVED[spec.name]}", DeprecationWarning, stacklevel=2)
        module = importlib.import_module(MOVED[spec.name])
        spec.loader_state = module.__spec__  # loading sets the module's __spec__ to this one: put back below
        return module

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = module.__spec__.loader_state


def install() -> None:
    """Puts :class:`MovedModules` on ``sys.meta_path`` once."""
    if not any(isinstance(finder, MovedModules) for finder in sys.meta_path):
        sys.meta_path.append(MovedModules())


def old_names(module: str):
    """The ``__getattr__`` of ``module`` for the names that left it or were renamed (:data:`MOVED_NAMES`): an
    old name gives the new one's object, for one release, with a :class:`DeprecationWarning`."""
    names = MOVED_NAMES[module]

    def __getattr__(name: str):
        if name in names:
            home, new = names[name].split(":")
        elif "*" in names and not name.startswith("_") and hasattr(importlib.import_module(names["*"]), name):
            home, new = names["*"], name
        else:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} is now {home}.{new}", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(home), new)

    return __getattr__
