"""Training: one generic loop, stateless schedules, per-family objectives and datasets.

Model families are declared in :mod:`dancekit.registry`; checkpoints are written with
:mod:`dancekit.checkpoints` (which the pipelines read too).
"""

from dancekit.training.loop import StepContext, TrainConfig, TrainResult, checkpoints, evaluate, train
from dancekit.training.objectives import revolution_step
from dancekit.training.schedules import CURRICULA, auto_condition_p, learning_rate

__all__ = [
    "CURRICULA",
    "StepContext",
    "TrainConfig",
    "TrainResult",
    "auto_condition_p",
    "checkpoints",
    "evaluate",
    "learning_rate",
    "revolution_step",
    "train",
]
