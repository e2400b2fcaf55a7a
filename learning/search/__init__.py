"""Learning by trial: :mod:`~besman.learning.search.policy_search` (CMA-ES, xNES and optimisers chosen by
name, refining theta on batched rollouts), :mod:`~besman.learning.search.hierarchical` (a sequence of blocks
refined together, each credited with its cost-to-go), :mod:`~besman.learning.search.contextual` (C-REPS and
contextual CMA-ES over :mod:`~besman.learning.search.linear_gaussian` policies),
:mod:`~besman.learning.search.outcome_refinement` (Gauss-Newton steps in outcome space),
:mod:`~besman.learning.search.feasibility` (a proposal whose reference fails pulled back before any rollout)
and :mod:`~besman.learning.search.online` (a template's instance refined in a copy of the world).
"""
