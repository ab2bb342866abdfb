"""Training: one generic loop, self-describing checkpoints, stateless schedules, per-family objectives."""

from dancekit.training.checkpoint import (
    families,
    get_family,
    load_pretrained,
    read_config,
    register_family,
    save_pretrained,
)
from dancekit.training.loop import StepContext, TrainConfig, TrainResult, checkpoints, evaluate, train
from dancekit.training.objectives import OBJECTIVES, revolution_step
from dancekit.training.schedules import CURRICULA, auto_condition_p, learning_rate

__all__ = [
    "CURRICULA",
    "OBJECTIVES",
    "StepContext",
    "TrainConfig",
    "TrainResult",
    "auto_condition_p",
    "checkpoints",
    "evaluate",
    "families",
    "get_family",
    "learning_rate",
    "load_pretrained",
    "read_config",
    "register_family",
    "revolution_step",
    "save_pretrained",
    "train",
]
