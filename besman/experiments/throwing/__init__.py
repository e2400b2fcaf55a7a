"""The paper's skill-template experiment on the throwing task (Metzen et al., KI 2014, Fig. 5), besman's
outcome template and the field: :mod:`~besman.experiments.throwing.experiment` runs it on the registry's
``throwing`` task (settings: :mod:`~besman.experiments.throwing.config`; what every stage throws on:
:mod:`~besman.experiments.throwing.bench`); its stages :mod:`~besman.experiments.throwing.spreads`,
:mod:`~besman.experiments.throwing.training`, :mod:`~besman.experiments.throwing.templates`,
:mod:`~besman.experiments.throwing.evaluation`, :mod:`~besman.experiments.throwing.curves` and
:mod:`~besman.experiments.throwing.contextual`; its ``results.json``
(:mod:`~besman.experiments.throwing.results`) judged by :mod:`~besman.experiments.throwing.claims` and drawn
by :mod:`~besman.experiments.throwing.plots`; its output folder :mod:`~besman.experiments.throwing.output`.
"""
