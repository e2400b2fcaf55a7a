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
    "besman.learning.pipeline.imitation": ("imitate",),
    "besman.learning.search.contextual": ("CREPS", "ContextBox", "ContextualCMAES"),
    "besman.learning.search.hierarchical": ("SequenceResult", "refine_sequence"),
    "besman.learning.search.policy_search": ("CMAES", "WarmStart", "XNES", "make_optimizer"),
    "besman.learning.segmentation.changepoints": ("SegmentModel", "SegmentationPrior"),
    "besman.learning.segmentation.demonstration": ("Demonstration", "DemonstrationError", "Segment", "load"),
    "besman.learning.segmentation.labelling": (
        "DemonstrationSegment",
        "cluster",
        "ground_truth_segments",
        "grouping_accuracy",
        "label_few_shot",
        "segments_of",
    ),
    "besman.learning.segmentation.preprocessing": ("SmoothingConfig", "hand_pose", "resample", "smooth"),
    "besman.learning.segmentation.segmenter": ("Segmentation", "segment"),
}


__getattr__, __dir__, _lazy = lazy_names(__name__, _HOMES)
__all__ = ["contextual_search", "policy_search", *_lazy]
