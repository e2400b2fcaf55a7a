"""The throwing experiment's stages wired together (:class:`Stages`): each made once, handed the ones it
reads. The experiment runs them (:mod:`besman.experiments.throwing.experiment`) and its ``results.json``
gathers them (:mod:`besman.experiments.throwing.results`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from besman.experiments.throwing.bench import ThrowingBench
from besman.experiments.throwing.config import ExperimentConfig
from besman.experiments.throwing.contextual import ContextualSearches
from besman.experiments.throwing.curves import LearningCurves
from besman.experiments.throwing.evaluation import GridEvaluation
from besman.experiments.throwing.output import RunFolder
from besman.experiments.throwing.spreads import Spreads
from besman.experiments.throwing.template_builder import TemplateBuilder
from besman.experiments.throwing.templates import Templates
from besman.experiments.throwing.training import TrainingSets


@dataclass
class Stages:
    """Every stage of a run into ``directory``, wired to those it reads (``backend``: the task's, "threads"
    or "ray"). Made, it claims ``directory`` (refusing another configuration's run or someone else's
    files)."""

    config: ExperimentConfig
    directory: Path
    backend: str = "threads"
    progress: bool = True

    def __post_init__(self) -> None:
        self.directory = Path(self.directory)
        self.bench = ThrowingBench(self.config, self.backend, self.progress)
        self.folder = RunFolder(self.directory, self.config)
        self.spreads = Spreads(self.bench, self.folder)
        builder = TemplateBuilder(self.bench, self.spreads)
        self.training = TrainingSets(self.bench, self.folder, self.spreads, builder)
        self.templates = Templates(self.bench, self.folder, self.training, builder)
        self.evaluation = GridEvaluation(self.bench, self.folder, self.training, self.templates)
        self.curves = LearningCurves(self.bench, self.folder, self.spreads, self.training, self.templates)
        self.contextual = ContextualSearches(self.bench, self.folder, self.spreads)
