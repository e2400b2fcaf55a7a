"""Movement primitives and what they are made of: DMPs, Cartesian DMPs, primitives and their files.

- :mod:`besman.skills.dmp`, :mod:`besman.skills.cartesian_dmp` - the DMP kinds, generated exactly and for
  whole populations; :mod:`besman.skills.dmp_core` - what they share (settings, theta scaling, the ridge
  fit, the :class:`Primitive` protocol); :mod:`besman.skills.forcing`, :mod:`besman.skills.transformation` -
  the forcing term and the transformation system, derived and cited.
- :mod:`besman.skills.primitive` - a DMP with its metadata, saved as JSON + NPZ (:mod:`besman.core.storage`:
  atomic writes, JSON fields and schema versions checked, never pickle).
- :mod:`besman.skills.template` - skill templates Psi = (Theta, Omega) over the task parameters
  (:mod:`besman.skills.task_bounds`: task boxes): :mod:`besman.skills.template_models` - Theta as one
  combination of whole training thetas per task (or a Gaussian process per theta dimension) and a
  per-coordinate uncertainty between a prior exploration and the data (:mod:`besman.skills.shared_kernel`: the
  shared model's hyperparameters); :mod:`besman.skills.zero_shot` - the zero-shot
  predictors a template is compared with; :mod:`besman.skills.pool` - the template pool, a directory of
  JSON + NPZ entries, a mapping of names to templates.
- :mod:`besman.skills.quaternion` - unit quaternions (w, x, y, z); :mod:`besman.core.validation` - argument
  checks, at every package's public functions; :mod:`besman.core.errors` - :class:`BesmanError`, the base
  of every error besman raises for bad input.

Imports numpy, scipy and scikit-learn and no other besman package, so every other besman package may use it.
"""

from besman.core.lazy import lazy_names

# Each name and the module it comes from, imported when first used: the command line imports
# ``besman.core.errors`` and must not pay for scipy and scikit-learn to print its help.
_EXPORTS = {
    "besman.core.errors": ("ArgumentTypeError", "BesmanError", "InputError"),
    "cartesian_dmp": ("CartesianDMP", "CartesianTrajectory"),
    "dmp": ("DMP", "Trajectory"),
    "dmp_core": ("DMPSettings", "Primitive"),
    "forcing": ("ForcingBasis",),
    "pool": ("PoolError", "SkillTemplatePool"),
    "primitive": ("MovementPrimitive",),
    "task_bounds": ("TaskBounds",),
    "template": ("SkillTemplate",),
}


__getattr__, __dir__, __all__ = lazy_names(__name__, _EXPORTS)
