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
:mod:`besman.learning.template_selection` (a template's kernel by leave-one-out outcomes),
:mod:`besman.learning.retargeting` (a person's movement onto AILA's arm), :mod:`besman.learning.pipeline`
(``besman learn``: recordings to a template pool of a task's :mod:`building blocks <besman.learning.blocks>`;
its stages in :mod:`besman.learning.pipeline_labels` and :mod:`besman.learning.pipeline_refinement`, its
record in :mod:`besman.learning.pipeline_record`, figures by :mod:`besman.learning.pipeline_plots`),
:mod:`besman.learning.online` (refining a template's instance in a copy of the world) and
:mod:`besman.learning.throwing_experiment` (the paper's skill-template experiment and the field, judged by
:mod:`besman.learning.throwing_claims`, drawn by :mod:`besman.learning.throwing_plots`;
:mod:`besman.learning.figures` writes PNGs).
"""

from besman.learning.changepoints import SegmentationPrior, SegmentModel
from besman.learning.contextual_search import CREPS, ContextBox, ContextualCMAES, contextual_search
from besman.learning.demonstration import Demonstration, DemonstrationError, Segment, load
from besman.learning.imitation import imitate
from besman.learning.labelling import (
    DemonstrationSegment,
    cluster,
    ground_truth_segments,
    grouping_accuracy,
    label_few_shot,
    segments_of,
)
from besman.learning.policy_search import CMAES, XNES, WarmStart, make_optimizer, policy_search
from besman.learning.preprocessing import SmoothingConfig, hand_pose, resample, smooth
from besman.learning.segmentation import Segmentation, segment
from besman.learning.sequences import SequenceResult, refine_sequence

__all__ = [
    "CMAES",
    "CREPS",
    "XNES",
    "ContextBox",
    "ContextualCMAES",
    "Demonstration",
    "DemonstrationError",
    "DemonstrationSegment",
    "Segment",
    "SegmentModel",
    "Segmentation",
    "SegmentationPrior",
    "SequenceResult",
    "SmoothingConfig",
    "WarmStart",
    "cluster",
    "contextual_search",
    "ground_truth_segments",
    "grouping_accuracy",
    "hand_pose",
    "imitate",
    "label_few_shot",
    "load",
    "make_optimizer",
    "policy_search",
    "refine_sequence",
    "resample",
    "segment",
    "segments_of",
    "smooth",
]
