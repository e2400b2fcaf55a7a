"""``besman learn``: recordings (or a robot's dataset) to a template pool of a task's building blocks
(:mod:`~besman.learning.pipeline.building_blocks`). :mod:`~besman.learning.pipeline.end_to_end` runs the
stages:
:mod:`~besman.learning.pipeline.labels` (recordings loaded, segmented and labelled),
:mod:`~besman.learning.pipeline.task_structure` (the blocks' order as the recordings show it),
:mod:`~besman.learning.pipeline.imitation` and :mod:`~besman.learning.pipeline.retargeting` (a primitive per
block, on the robot), :mod:`~besman.learning.pipeline.refinement` and
:mod:`~besman.learning.pipeline.sequence_refinement` (refined block by block or as one sequence); its
record in :mod:`~besman.learning.pipeline.record`, its figures in :mod:`~besman.learning.pipeline.plots`;
a robot's demonstrations from a LeRobot dataset in :mod:`~besman.learning.pipeline.dataset_demonstrations`.
"""

from besman.core.moved import old_names as _old_names

# The names of the module this package was (besman.learning.X), for one release.
__getattr__ = _old_names(__name__)
