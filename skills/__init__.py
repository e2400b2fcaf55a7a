"""Movement primitives and skill templates: DMPs, primitives, templates and the template pool.

Depends on numpy and scipy only; every other besman package may use it.
"""

from besman.skills.cartesian_dmp import CartesianDMP, CartesianTrajectory
from besman.skills.dmp import DMP, Trajectory
from besman.skills.forcing import ForcingBasis
from besman.skills.primitive import MovementPrimitive

__all__ = ["DMP", "CartesianDMP", "CartesianTrajectory", "ForcingBasis", "MovementPrimitive", "Trajectory"]
