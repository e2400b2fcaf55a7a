"""From recordings to building blocks: :mod:`~besman.learning.segmentation.demonstration` (recordings and
their loaders), :mod:`~besman.learning.segmentation.preprocessing` (Kalman/RTS smoothing, gaps, resampling,
hand poses), :mod:`~besman.learning.segmentation.contact` (the grip aperture and the object's marker as
contact signals), :mod:`~besman.learning.segmentation.changepoints` (exact Bayesian change-point inference),
:mod:`~besman.learning.segmentation.segmenter` (``segment(demo)``: a recording cut into movements and holds,
and boundary F1), :mod:`~besman.learning.segmentation.boundaries` (segments turned into annotated-style
ones), :mod:`~besman.learning.segmentation.labelling` (which segments are the same building block) and
:mod:`~besman.learning.segmentation.plot`.
"""

from besman.core.moved import old_names as _old_names

# The names of the module this package was (besman.learning.X), for one release.
__getattr__ = _old_names(__name__)
