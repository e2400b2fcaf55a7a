"""Moved to :mod:`besman.sim.hosts` (the simulation's servers use it); this name keeps working for one
release, with a DeprecationWarning."""

import warnings

from besman.sim.hosts import *  # noqa: F403

warnings.warn("besman.hosts is now besman.sim.hosts", DeprecationWarning, stacklevel=2)
