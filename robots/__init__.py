"""Robot models and their kinematics: AILA (DFKI's mobile dual-arm robot), the Mitsubishi PA-10 and a
Universal Robots UR5e with a Robotiq 2F-85 gripper (MuJoCo Menagerie's models).

Kinematics: :mod:`besman.robots.kinematics` (forward), :mod:`besman.robots.ik` (inverse). Which robots there
are and their descriptions, without MuJoCo: :mod:`besman.robots.catalogue`.

Each robot lives in a folder in MuJoCo Menagerie's layout (``README.md``, ``LICENSE``, ``CHANGELOG.md``, and
for a model of our own ``<robot>.xml`` and ``scene.xml``) plus a ``description.json``: its model (a file, or
Menagerie's with parts attached), joint groups, motion limits, arms with their tool frames and grippers, and
its tabletop layout. ``load(name)`` assembles and compiles the model and returns a :class:`Robot`.
"""

from besman.core.lazy import lazy_names

# Where each name lives; imported on first use, so that reading a description (listing and showing tasks)
# does not bring scipy's linear algebra and the inverse kinematics with it.
_HOMES = {
    "assembly": ("build_spec",),
    "catalogue": ("available", "choose", "describe"),
    "description": ("DescriptionError", "RobotDescription"),
    "gripper": ("Gripper",),
    "ik": ("IKResult", "solve_ik"),
    "kinematics": ("Pose", "forward_kinematics", "site_pose"),
    "robot": ("JointGroup", "Robot", "RobotArm", "compile_spec", "load"),
}


__getattr__, __dir__, __all__ = lazy_names(__name__, _HOMES)
