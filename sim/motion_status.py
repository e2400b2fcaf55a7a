"""Where a motion stands (:class:`MotionStatus`), apart from the motions (:mod:`besman.sim.motions`, which
need MuJoCo and Ruckig): tree leaves mirror it, and building a tree or listing its node types needs
neither."""

from enum import Enum


class MotionStatus(Enum):
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
