"""Robot models and their kinematics: AILA (DFKI's mobile dual-arm robot) and the Mitsubishi PA-10.

Kinematics: :mod:`besman.robots.kinematics` (forward), :mod:`besman.robots.ik` (inverse).

Each robot lives in a folder in MuJoCo Menagerie's layout (``<robot>.xml``, ``scene.xml``, ``README.md``,
``LICENSE``, ``CHANGELOG.md``) plus a ``description.json`` with its joint groups and motion limits.
``load(name)`` compiles the scene and returns a :class:`Robot`.
"""

from besman.robots.description import DescriptionError, RobotDescription
from besman.robots.ik import IKResult, solve_ik
from besman.robots.kinematics import Pose, forward_kinematics, site_pose
from besman.robots.robot import JointGroup, Robot, available, load

__all__ = [
    "DescriptionError",
    "IKResult",
    "JointGroup",
    "Pose",
    "Robot",
    "RobotDescription",
    "available",
    "forward_kinematics",
    "load",
    "site_pose",
    "solve_ik",
]
