"""Experiments: studies that run tasks from the registry (:mod:`besman.tasks`) with learning, and judge
them. :mod:`besman.experiments.throwing` is the paper's (``besman experiment throwing``);
:mod:`besman.experiments.template_study` is the study of a skill template over tau that the open-loop tasks
share (``besman experiment ball-in-cup``, ``besman experiment puck-strike``)."""
