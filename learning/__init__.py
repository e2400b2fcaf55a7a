"""Learning: demonstrations, preprocessing, segmentation, labelling, imitation, policy search, templates.

So far: :mod:`besman.learning.demonstration` (recordings and their loaders),
:mod:`besman.learning.preprocessing` (Kalman/RTS smoothing, gaps, resampling, hand poses) and
:mod:`besman.learning.segmentation` (exact Bayesian change-point inference: evidences, MAP, change-point
probabilities, posterior samples; ``segment(demo)``) and :mod:`besman.learning.segmentation_plot`.
"""

from besman.learning.demonstration import Demonstration, DemonstrationError, Segment, load
from besman.learning.preprocessing import SmoothingConfig, hand_pose, resample, smooth
from besman.learning.segmentation import Segmentation, SegmentationPrior, SegmentModel, segment

__all__ = [
    "Demonstration",
    "DemonstrationError",
    "Segment",
    "SegmentModel",
    "Segmentation",
    "SegmentationPrior",
    "SmoothingConfig",
    "hand_pose",
    "load",
    "resample",
    "segment",
    "smooth",
]
