"""Training: one generic loop, stateless schedules, per-family objectives and datasets, run assembly.

* :class:`Trainer` / :func:`train` — the loop (:mod:`dancekit.training.loop`)
* :class:`TrainConfig` = :class:`OptimConfig` (generic) + :class:`DataConfig` (per family)
  (:mod:`dancekit.training.config`)
* :func:`assemble_run` / :class:`TrainRun` — a family's model, data and settings from a prepared dataset,
  ``--set`` overrides, ``--resume`` and ``--init``, as ``dancekit train`` does (:mod:`dancekit.training.runs`)

Model families are declared in :mod:`dancekit.registry`; checkpoints are written with
:mod:`dancekit.checkpoints` (which the pipelines read too).
"""

from dancekit.training.config import DataConfig, OptimConfig, TrainConfig
from dancekit.training.loop import StepContext, Trainer, TrainResult, checkpoints, evaluate, train
from dancekit.training.objectives import revolution_step
from dancekit.training.runs import TrainRun, assemble_run, parse_sets
from dancekit.training.schedules import CURRICULA, auto_condition_p, learning_rate

__all__ = [
    "CURRICULA",
    "DataConfig",
    "OptimConfig",
    "StepContext",
    "TrainConfig",
    "TrainResult",
    "TrainRun",
    "Trainer",
    "assemble_run",
    "auto_condition_p",
    "checkpoints",
    "evaluate",
    "learning_rate",
    "parse_sets",
    "revolution_step",
    "train",
]
