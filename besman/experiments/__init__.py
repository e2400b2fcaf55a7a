"""Experiments: studies that run tasks from the registry (:mod:`besman.tasks`) with learning, and judge
them. :mod:`besman.experiments.throwing` is the paper's (``besman experiment throwing``)."""
