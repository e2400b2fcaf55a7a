"""Learning: from demonstrations and by trial, in three subsystems.

- :mod:`besman.learning.segmentation` - recordings smoothed, cut into movements and holds by Bayesian
  change-point inference, and labelled into building blocks.
- :mod:`besman.learning.pipeline` - ``besman learn``: the blocks imitated as primitives, retargeted, refined
  and generalised into a skill template pool.
- :mod:`besman.learning.search` - policy search (CMA-ES, xNES, optimisers by name), sequences of blocks
  refined together (hierarchical credit assignment), contextual search, outcome-space refinement, the
  feasibility guard and online refinement.

Beside them: :mod:`besman.learning.template_selection` (a template's kernel by outcomes at held-out targets)
and :mod:`besman.learning.figures` (PNGs written atomically). LeRobot datasets are :mod:`besman.datasets`'s;
the throwing experiment is :mod:`besman.experiments.throwing`'s.
"""

from besman.core.lazy import lazy_names
from besman.learning.search.contextual import contextual_search
from besman.learning.search.policy_search import policy_search

# Where each name lives; imported on first use, so that one module of the package (the recordings' loader,
# the online refinement a tree leaf uses) does not bring scipy and scikit-learn with it. The two functions
# named as their modules are imported above: importing a module binds its name in the package, over a lazy
# name.
_HOMES = {
    "CMAES": "besman.learning.search.policy_search",
    "CREPS": "besman.learning.search.contextual",
    "XNES": "besman.learning.search.policy_search",
    "ContextBox": "besman.learning.search.contextual",
    "ContextualCMAES": "besman.learning.search.contextual",
    "Demonstration": "besman.learning.segmentation.demonstration",
    "DemonstrationError": "besman.learning.segmentation.demonstration",
    "DemonstrationSegment": "besman.learning.segmentation.labelling",
    "Segment": "besman.learning.segmentation.demonstration",
    "SegmentModel": "besman.learning.segmentation.changepoints",
    "Segmentation": "besman.learning.segmentation.segmenter",
    "SegmentationPrior": "besman.learning.segmentation.changepoints",
    "SequenceResult": "besman.learning.search.hierarchical",
    "SmoothingConfig": "besman.learning.segmentation.preprocessing",
    "WarmStart": "besman.learning.search.policy_search",
    "cluster": "besman.learning.segmentation.labelling",
    "ground_truth_segments": "besman.learning.segmentation.labelling",
    "grouping_accuracy": "besman.learning.segmentation.labelling",
    "hand_pose": "besman.learning.segmentation.preprocessing",
    "imitate": "besman.learning.pipeline.imitation",
    "label_few_shot": "besman.learning.segmentation.labelling",
    "load": "besman.learning.segmentation.demonstration",
    "make_optimizer": "besman.learning.search.policy_search",
    "refine_sequence": "besman.learning.search.hierarchical",
    "resample": "besman.learning.segmentation.preprocessing",
    "segment": "besman.learning.segmentation.segmenter",
    "segments_of": "besman.learning.segmentation.labelling",
    "smooth": "besman.learning.segmentation.preprocessing",
}
__all__ = ["contextual_search", "policy_search", *_HOMES]


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
