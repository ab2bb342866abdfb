"""Training settings in two groups, combined by :class:`TrainConfig`.

* :class:`OptimConfig` — the generic optimisation and loop settings that :class:`~dancekit.training.Trainer`
  reads, the same for every model family: length, batch size, optimiser, learning-rate schedule, seeding,
  logging, validation and checkpoint cadence, device.
* :class:`DataConfig` — what a family's dataset builder (:mod:`dancekit.training.datasets`) and objective
  (:mod:`dancekit.training.objectives`) read: the training windows, augmentation, genre selection and the
  curriculum of autoregressive decoders. The loop never reads these.

:class:`TrainConfig` is both at once, with flat fields: ``dancekit train --set key=value`` sets any field by
name, a family's ``train_defaults`` (:mod:`dancekit.registry`) override any of them, and every checkpoint
saves ``dataclasses.asdict(config)`` under ``"train"`` — the same flat dict as before the split, so the
checkpoints written earlier (a subset of these fields) load with the defaults for the missing ones.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from dancekit.errors import CheckpointError, ParameterError
from dancekit.training.schedules import CURRICULA, LR_SCHEDULES

PRECISIONS = ("fp32", "bf16", "fp16")
OPTIMIZERS = ("adamw", "rmsprop")


def _positive_int(config: object, names: tuple[str, ...], *, optional: bool = False) -> None:
    cls = type(config).__name__
    for name in names:
        value = getattr(config, name)
        if optional and value is None:
            continue
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            what = "a positive integer or None" if optional else "a positive integer"
            raise ParameterError(f"{cls}.{name} must be {what}, got {value!r}")


@dataclass
class OptimConfig:
    """Generic optimisation and loop settings (any model family).

    Length: ``steps`` optimisation steps, or ``epochs`` passes over the training set when set.
    ``optimizer``: AdamW (default) or RMSprop (the Music2Dance paper's, supplement §1.2), with ``lr`` (linear warm-up over ``warmup_steps``, then ``lr_schedule``: cosine down to
    ``min_lr`` at the last step, or constant), gradient clipping at ``grad_clip``. On GPUs:
    ``grad_accum_steps`` micro-batches per step and mixed ``precision`` (bf16 / fp16 autocast).
    ``batch_size`` is the global batch: under torchrun each of N processes takes ``batch_size / N`` items.
    """

    steps: int = 3000
    epochs: int | None = None
    batch_size: int = 16
    lr: float = 1e-3
    optimizer: str = "adamw"  # adamw | rmsprop (weight_decay applies to both)
    lr_schedule: str = "cosine"  # cosine | constant
    warmup_steps: int = 100
    min_lr: float = 1e-5
    weight_decay: float = 0.0
    grad_clip: float | None = 1.0  # max global gradient norm (None: no clipping)
    seed: int = 0  # initial weights (dancekit train), dropout, shuffling, window offsets, objectives' draws
    log_every: int = 25
    val_every: int = 250
    val_batches: int | None = None  # validate on at most this many batches (None: all)
    ckpt_every: int = 500
    keep_checkpoints: int = 3  # resumable step folders to keep
    num_workers: int = 0
    threads: int | None = 2  # torch.set_num_threads (None: leave as is)
    device: str = "cpu"  # cpu | cuda (under torchrun: cuda:LOCAL_RANK) | cuda:N | mps
    # a global batch in this many micro-batches (memory), one optimiser step; the same batches and updates
    grad_accum_steps: int = 1
    precision: str = "fp32"  # fp32 | bf16 | fp16 (autocast; fp16 with a gradient scaler, CUDA only)
    find_unused_parameters: bool = False  # DistributedDataParallel: parameters may get no gradient in a step

    def __post_init__(self) -> None:
        _positive_int(self, ("steps", "batch_size", "log_every", "val_every", "ckpt_every", "keep_checkpoints",
                             "grad_accum_steps"))
        if self.optimizer not in OPTIMIZERS:
            raise ParameterError(f"{type(self).__name__}.optimizer must be one of {OPTIMIZERS}, got {self.optimizer!r}")
        if self.precision not in PRECISIONS:
            raise ParameterError(f"{type(self).__name__}.precision must be one of {PRECISIONS}, got {self.precision!r}")
        _positive_int(self, ("epochs", "val_batches", "threads"), optional=True)
        if not self.lr > 0:
            raise ParameterError(f"{type(self).__name__}.lr must be positive, got {self.lr!r}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ParameterError(f"{type(self).__name__}.lr_schedule must be one of {LR_SCHEDULES}, "
                                 f"got {self.lr_schedule!r}")
        if self.warmup_steps < 0 or self.min_lr < 0 or self.weight_decay < 0 or self.num_workers < 0:
            raise ParameterError(f"{type(self).__name__}.warmup_steps, min_lr, weight_decay and num_workers "
                                 "must be >= 0")
        if self.grad_clip is not None and not self.grad_clip > 0:
            raise ParameterError(f"{type(self).__name__}.grad_clip must be positive or None, got {self.grad_clip!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral) or self.seed < 0:
            raise ParameterError(f"{type(self).__name__}.seed must be a non-negative integer, got {self.seed!r}")


@dataclass
class DataConfig:
    """Per-family data and curriculum settings, read by dataset builders and objectives (not by the loop).

    The data fields (``seq_len``, ``stride``, ``random_offset``, ``balance_genres``, ``genres``,
    ``representation``) shape the training windows (:func:`dancekit.training.datasets.music_dance_windows`);
    the dropouts and the ``curriculum*`` fields are read by the objectives of autoregressive families
    (:func:`dancekit.training.schedules.auto_condition_p`).
    """

    seq_len: int = 240  # frames per training window
    stride: int | None = None  # between window starts (None: seq_len // 4)
    random_offset: bool = True  # jitter window starts by up to one stride (a function of seed, epoch, window)
    # oversample the windows of minority genres (WindowDataset). An epoch then holds more windows (about
    # 2.7x on tang2018), so an epoch-based curriculum grows p that much more slowly per step: scale
    # curriculum_lambda up accordingly (3000 balanced steps at the default λ reach only p = 9).
    balance_genres: bool = False
    genre_dropout: float = 0.3  # genre-conditioned models: share of windows trained as "auto"
    genres: list[str] | None = None  # train and validate on these genres' dances only (None: all)
    music_dropout: float = 0.0  # share of training windows whose music is replaced by the mean (zeros)
    representation: str = "positions3d"  # positions3d | keypoints2d
    augment_mirror: float = 0.0  # probability of a training window's left-right mirror image (positions3d)
    augment_heading: bool = False  # turn each training window by a random angle about the up axis (positions3d, rot6d)
    augment_tempo: float = 0.0  # joint tempo change of music and motion by up to ± this share (e.g. 0.05; positions3d, rot6d)
    # curriculum of autoregressive decoders (dynamic auto-condition)
    curriculum: str = "linear"  # teacher_forcing | const | linear | quadratic | exponential
    curriculum_lambda: float = 0.25  # λ per epoch
    curriculum_q: int = 10  # ground-truth frames per period
    curriculum_p: int = 10  # p of the "const" curriculum
    curriculum_p_max: int | None = 30
    val_p: int = 20  # fixed p of the validation loss, so that it compares across steps and runs

    def __post_init__(self) -> None:
        cls = type(self).__name__
        _positive_int(self, ("seq_len",))
        _positive_int(self, ("stride",), optional=True)
        if self.curriculum not in CURRICULA:
            raise ParameterError(f"{cls}.curriculum must be one of {CURRICULA}, got {self.curriculum!r}")
        if not 0.0 <= self.music_dropout <= 1.0 or not 0.0 <= self.genre_dropout <= 1.0:
            raise ParameterError(f"{cls}.music_dropout and genre_dropout must be in [0, 1]")
        if self.genres is not None and (not isinstance(self.genres, (list, tuple)) or not self.genres
                                        or not all(isinstance(g, str) for g in self.genres)):
            raise ParameterError(f"{cls}.genres must be a non-empty list of genre names or None, got {self.genres!r}")
        if self.curriculum_q < 0 or self.curriculum_p < 0 or self.curriculum_lambda < 0 or self.val_p < 0:
            raise ParameterError(f"{cls}.curriculum_q, curriculum_p, curriculum_lambda and val_p must be >= 0")


@dataclass
class TrainConfig(DataConfig, OptimConfig):
    """All the settings of a training run: :class:`OptimConfig` fields, then :class:`DataConfig` fields.

    Saved in every checkpoint under ``"train"`` (flat); :meth:`from_saved` reads such a dict back.

    Examples
    --------
    >>> c = TrainConfig(steps=500, seq_len=120, curriculum="quadratic")
    >>> isinstance(c, OptimConfig) and c.optim().steps == 500 and c.data().seq_len == 120
    True
    """

    def __post_init__(self) -> None:
        OptimConfig.__post_init__(self)
        DataConfig.__post_init__(self)

    def optim(self) -> OptimConfig:
        """The generic optimisation settings alone."""
        return OptimConfig(**{name: getattr(self, name) for name in OptimConfig.__dataclass_fields__})

    def data(self) -> DataConfig:
        """The per-family data and curriculum settings alone."""
        return DataConfig(**{name: getattr(self, name) for name in DataConfig.__dataclass_fields__})

    @classmethod
    def from_saved(cls, saved: Mapping[str, Any], *, source: object = "checkpoint",
                   defaults: Mapping[str, Any] | None = None, **overrides: Any) -> TrainConfig:
        """The settings saved in a checkpoint's ``"train"`` dict, over ``defaults`` and under ``overrides``.

        Fields missing from ``saved`` (a checkpoint older than the field) take ``defaults`` (a family's
        ``train_defaults``), else the dataclass defaults.

        Raises
        ------
        CheckpointError
            When ``saved`` holds a setting this version does not know (the message names ``source``).
        """
        unknown = sorted(set(saved) - set(cls.__dataclass_fields__))
        if unknown:
            raise CheckpointError(f"{source}: training settings {unknown} are unknown to this version")
        return cls(**{**(defaults or {}), **saved, **overrides})
