"""Movement primitives and skill templates: DMPs, primitives, templates and the template pool.

Depends on numpy and scipy only; every other besman package may use it.
"""
