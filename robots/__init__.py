"""Robot models and their kinematics: AILA (DFKI's mobile dual-arm robot), the Mitsubishi PA-10 and a
Universal Robots UR5e with a Robotiq 2F-85 gripper (MuJoCo Menagerie's models).

Kinematics: :mod:`besman.robots.kinematics` (forward), :mod:`besman.robots.ik` (inverse).

Each robot lives in a folder in MuJoCo Menagerie's layout (``README.md``, ``LICENSE``, ``CHANGELOG.md``, and
for a model of our own ``<robot>.xml`` and ``scene.xml``) plus a ``description.json``: its model (a file, or
Menagerie's with parts attached), joint groups, motion limits, arms with their tool frames and grippers, and
its tabletop layout. ``load(name)`` assembles and compiles the model and returns a :class:`Robot`.
"""

from besman.robots.assembly import build_spec
from besman.robots.description import DescriptionError, RobotDescription
from besman.robots.gripper import Gripper
from besman.robots.ik import IKResult, solve_ik
from besman.robots.kinematics import Pose, forward_kinematics, site_pose
from besman.robots.robot import JointGroup, Robot, RobotArm, available, choose, compile_spec, describe, load

__all__ = [
    "DescriptionError",
    "Gripper",
    "IKResult",
    "JointGroup",
    "Pose",
    "Robot",
    "RobotArm",
    "RobotDescription",
    "available",
    "build_spec",
    "choose",
    "compile_spec",
    "describe",
    "forward_kinematics",
    "load",
    "site_pose",
    "solve_ik",
]
