"""Learning: from demonstrations (recordings, smoothing, segmentation, labelling, imitation) and by trial.

:mod:`besman.learning.demonstration` (recordings and their loaders),
:mod:`besman.learning.preprocessing` (Kalman/RTS smoothing, gaps, resampling, hand poses) and
:mod:`besman.learning.changepoints` (exact Bayesian change-point inference: evidences, MAP, change-point
probabilities, posterior samples, several signals observed jointly), :mod:`besman.learning.contact` (the
grip aperture and the object's marker as contact signals), :mod:`besman.learning.segmentation`
(``segment(demo)``: a recording cut into movements and holds, hyperparameters by marginal likelihood, and
boundary F1), :mod:`besman.learning.segmentation_plot`,
:mod:`besman.learning.labelling` (building blocks: clustering, few-shot 1-NN),
:mod:`besman.learning.imitation` (a Cartesian-DMP primitive per building block),
:mod:`besman.learning.policy_search` (CMA-ES and xNES refining theta on batched rollouts),
:mod:`besman.learning.sequences` (a task's blocks refined together on whole-task rollouts, each credited with
its cost-to-go, or block by block),
:mod:`besman.learning.contextual_search` (C-REPS and contextual CMA-ES: one policy over all tasks),
:mod:`besman.learning.template_selection` (a template's kernel by outcomes at held-out targets),
:mod:`besman.learning.feasibility` (the free guard: a proposal whose reference fails pulled back before any
rollout), :mod:`besman.learning.outcome_refinement` (Gauss-Newton steps in outcome space with Broyden's
corrections),
:mod:`besman.learning.retargeting` (a person's movement onto AILA's arm), :mod:`besman.learning.pipeline`
(``besman learn``: recordings to a template pool of a task's :mod:`building blocks <besman.learning.blocks>`;
its stages in :mod:`besman.learning.pipeline_labels` and :mod:`besman.learning.pipeline_refinement`, its
record in :mod:`besman.learning.pipeline_record`, figures by :mod:`besman.learning.pipeline_plots`),
:mod:`besman.learning.online` (refining a template's instance in a copy of the world),
:mod:`besman.learning.dataset_format`, :mod:`~besman.learning.dataset_writer` and
:mod:`~besman.learning.dataset_reader` (LeRobot v3.0 datasets, written an episode at a time and read back) and
:mod:`besman.learning.throwing_experiment` (the paper's skill-template experiment, besman's outcome template
and the field, judged by
:mod:`besman.learning.throwing_claims`, drawn by :mod:`besman.learning.throwing_plots`;
:mod:`besman.learning.figures` writes PNGs).
"""

from besman.learning.contextual_search import contextual_search
from besman.learning.policy_search import policy_search
from besman.skills.lazy import lazy_names

# Where each name lives; imported on first use, so that one module of the package (the recordings' loader,
# the online refinement a tree leaf uses) does not bring scipy and scikit-learn with it. The two functions
# named as their modules are imported above: importing a module binds its name in the package, over a lazy
# name.
_HOMES = {
    "CMAES": "policy_search",
    "CREPS": "contextual_search",
    "XNES": "policy_search",
    "ContextBox": "contextual_search",
    "ContextualCMAES": "contextual_search",
    "Demonstration": "demonstration",
    "DemonstrationError": "demonstration",
    "DemonstrationSegment": "labelling",
    "Segment": "demonstration",
    "SegmentModel": "changepoints",
    "Segmentation": "segmentation",
    "SegmentationPrior": "changepoints",
    "SequenceResult": "sequences",
    "SmoothingConfig": "preprocessing",
    "WarmStart": "policy_search",
    "cluster": "labelling",
    "ground_truth_segments": "labelling",
    "grouping_accuracy": "labelling",
    "hand_pose": "preprocessing",
    "imitate": "imitation",
    "label_few_shot": "labelling",
    "load": "demonstration",
    "make_optimizer": "policy_search",
    "refine_sequence": "sequences",
    "resample": "preprocessing",
    "segment": "segmentation",
    "segments_of": "labelling",
    "smooth": "preprocessing",
}
__all__ = ["contextual_search", "policy_search", *_HOMES]


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
