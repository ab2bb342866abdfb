"""One generic training loop for every model family.

The loop knows nothing about a family: a ``step_fn(model, batch, ctx) -> (loss, logs)`` computes the
loss of a batch (see :mod:`dancekit.training.objectives`). The loop owns the optimiser (AdamW), the
learning-rate schedule, gradient clipping, seeding, the progress bar, validation, checkpoints and
resumption.

Output folder layout (``out_dir``)::

    checkpoints/step_0000500/   resumable: config.json + model.safetensors + stats.npz + training_state.pt
    model/                      the latest weights (a plain checkpoint for pipelines)
    best/                       the weights with the lowest validation loss (when validating)
    log.jsonl                   one JSON record per log / validation event

Every folder is written beside its final place and renamed when complete
(:func:`dancekit._io.atomic_dir`), so an interrupted run never leaves a half-written checkpoint, and
``resume=True`` continues from the newest complete one (weights, optimiser state, step, and the
states of the torch / NumPy / Python random generators, so a resumed run reproduces an
uninterrupted one on CPU).
"""

from __future__ import annotations

import dataclasses
import json
import math
import random
import shutil
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.data import DataLoader, Dataset

from dancekit._io import atomic_dir, atomic_path
from dancekit.checkpoints.folder import WEIGHTS_FILE, read_config, write_pretrained
from dancekit.errors import CheckpointError, ParameterError
from dancekit.training.schedules import CURRICULA, LR_SCHEDULES, learning_rate

STATE_FILE = "training_state.pt"


@dataclass
class TrainConfig:
    """Settings of :func:`train` (saved in every checkpoint under ``"train"``).

    Length: ``steps`` optimisation steps, or ``epochs`` passes over the training windows when set.
    The data fields (``seq_len``, ``stride``, ``random_offset``, ``representation``) are read by
    whoever builds the datasets (``dancekit train``); the ``curriculum*`` fields by the objectives of
    autoregressive families (:func:`dancekit.training.schedules.auto_condition_p`).
    """

    steps: int = 3000
    epochs: int | None = None
    batch_size: int = 16
    lr: float = 1e-3
    lr_schedule: str = "cosine"  # cosine | constant
    warmup_steps: int = 100
    min_lr: float = 1e-5
    weight_decay: float = 0.0
    grad_clip: float | None = 1.0  # max global gradient norm (None: no clipping)
    seed: int = 0
    log_every: int = 25
    val_every: int = 250
    val_batches: int | None = None  # validate on at most this many batches (None: all)
    ckpt_every: int = 500
    keep_checkpoints: int = 3  # resumable step folders to keep
    num_workers: int = 0
    threads: int | None = 2  # torch.set_num_threads (None: leave as is)
    device: str = "cpu"
    # data
    seq_len: int = 240  # frames per training window
    stride: int | None = None  # between window starts (None: seq_len // 4)
    random_offset: bool = True  # jitter window starts by up to one stride
    # oversample the windows of minority genres (WindowDataset). An epoch then holds more windows (about
    # 2.7x on tang2018), so an epoch-based curriculum grows p that much more slowly per step: scale
    # curriculum_lambda up accordingly (3000 balanced steps at the default λ reach only p = 9).
    balance_genres: bool = False
    genre_dropout: float = 0.3  # genre-conditioned models: share of windows trained as "auto"
    genres: list[str] | None = None  # train and validate on these genres' dances only (None: all)
    music_dropout: float = 0.0  # share of training windows whose music is replaced by the mean (zeros)
    representation: str = "positions3d"  # positions3d | keypoints2d
    # curriculum of autoregressive decoders (dynamic auto-condition)
    curriculum: str = "linear"  # teacher_forcing | const | linear | quadratic | exponential
    curriculum_lambda: float = 0.25  # λ per epoch
    curriculum_q: int = 10  # ground-truth frames per period
    curriculum_p: int = 10  # p of the "const" curriculum
    curriculum_p_max: int | None = 30
    val_p: int = 20  # fixed p of the validation loss, so that it compares across steps and runs

    def __post_init__(self) -> None:
        positive = ("steps", "batch_size", "log_every", "val_every", "ckpt_every", "keep_checkpoints", "seq_len")
        for name in positive:
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ParameterError(f"TrainConfig.{name} must be a positive integer, got {value!r}")
        for name in ("epochs", "stride", "val_batches", "threads"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, int) or value < 1):
                raise ParameterError(f"TrainConfig.{name} must be a positive integer or None, got {value!r}")
        if not self.lr > 0:
            raise ParameterError(f"TrainConfig.lr must be positive, got {self.lr!r}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ParameterError(f"TrainConfig.lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}")
        if self.curriculum not in CURRICULA:
            raise ParameterError(f"TrainConfig.curriculum must be one of {CURRICULA}, got {self.curriculum!r}")
        if self.warmup_steps < 0 or self.min_lr < 0 or self.weight_decay < 0 or self.num_workers < 0:
            raise ParameterError("TrainConfig.warmup_steps, min_lr, weight_decay and num_workers must be >= 0")
        if self.grad_clip is not None and not self.grad_clip > 0:
            raise ParameterError(f"TrainConfig.grad_clip must be positive or None, got {self.grad_clip!r}")
        if not 0.0 <= self.music_dropout <= 1.0 or not 0.0 <= self.genre_dropout <= 1.0:
            raise ParameterError("TrainConfig.music_dropout and genre_dropout must be in [0, 1]")
        if self.genres is not None and (not isinstance(self.genres, (list, tuple)) or not self.genres
                                        or not all(isinstance(g, str) for g in self.genres)):
            raise ParameterError(f"TrainConfig.genres must be a non-empty list of genre names or None, got {self.genres!r}")
        if self.curriculum_q < 0 or self.curriculum_p < 0 or self.curriculum_lambda < 0 or self.val_p < 0:
            raise ParameterError("TrainConfig.curriculum_q, curriculum_p, curriculum_lambda and val_p must be >= 0")


@dataclass
class StepContext:
    """What a ``step_fn`` may need besides the model and the batch."""

    step: int  # optimisation step about to be taken (0-based)
    epoch: int  # completed epochs, the ``t`` of curricula
    training: bool  # False during validation
    generator: torch.Generator  # for the model's own sampling (e.g. initial decoder states)
    config: TrainConfig


StepFn = Callable[[nn.Module, dict[str, torch.Tensor], StepContext], tuple[torch.Tensor, Mapping[str, float]]]


@dataclass
class TrainResult:
    """What :func:`train` did."""

    step: int
    epoch: int
    train_loss: float | None
    val_loss: float | None
    best_val_loss: float | None
    out_dir: Path
    history: list[dict[str, Any]] = field(default_factory=list)


# --------------------------------------------------------------------------------------------------


def seed_everything(seed: int) -> None:
    """Seed Python's ``random``, NumPy's global generator and torch."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def _rng_state(generator: torch.Generator) -> dict[str, Any]:
    np_state = np.random.get_state()
    return {
        "torch": torch.get_rng_state(),
        "numpy": [np_state[0], torch.from_numpy(np_state[1].astype(np.int64)), *np_state[2:]],
        "python": _to_lists(random.getstate()),
        "generator": generator.get_state(),
    }


def _to_lists(x: Any) -> Any:
    return [_to_lists(v) for v in x] if isinstance(x, tuple | list) else x


def _to_tuples(x: Any) -> Any:
    return tuple(_to_tuples(v) for v in x) if isinstance(x, list) else x


def _set_rng_state(state: Mapping[str, Any], generator: torch.Generator) -> None:
    torch.set_rng_state(state["torch"])
    name, keys, *rest = state["numpy"]
    np.random.set_state((name, keys.numpy().astype(np.uint32), *rest))
    random.setstate(_to_tuples(state["python"]))
    generator.set_state(state["generator"])


def _epoch_batches(n: int, batch_size: int, *, seed: int, epoch: int) -> list[list[int]]:
    """The shuffled batches of one epoch, a pure function of (seed, epoch) so resumption is exact."""
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    perm = torch.randperm(n, generator=g).tolist()
    if n < batch_size:
        return [perm]
    return [perm[i * batch_size : (i + 1) * batch_size] for i in range(n // batch_size)]


def _to_device(batch: Any, device: torch.device) -> Any:
    if isinstance(batch, torch.Tensor):
        return batch.to(device)
    if isinstance(batch, Mapping):
        return {k: _to_device(v, device) for k, v in batch.items()}
    if isinstance(batch, list | tuple):
        return type(batch)(_to_device(v, device) for v in batch)
    return batch


def checkpoints(out_dir: str | Path) -> list[Path]:
    """Complete resumable checkpoints of a run folder, oldest first."""
    root = Path(out_dir) / "checkpoints"
    if not root.is_dir():
        return []
    found = [p for p in root.glob("step_*") if p.is_dir() and (p / STATE_FILE).is_file() and (p / WEIGHTS_FILE).is_file()]
    return sorted(found, key=lambda p: int(p.name.split("_")[1]))


@torch.no_grad()
def evaluate(
    model: nn.Module,
    dataset: Dataset,
    step_fn: StepFn,
    *,
    config: TrainConfig,
    step: int = 0,
    epoch: int = 0,
) -> float:
    """Mean loss of ``step_fn`` over ``dataset`` (in order, eval mode, a fixed generator seed)."""
    was_training = model.training
    model.eval()
    device = torch.device(config.device)
    generator = torch.Generator(device=device).manual_seed(config.seed + 7919)
    loader = DataLoader(dataset, batch_size=config.batch_size, shuffle=False, num_workers=config.num_workers,
                        generator=torch.Generator().manual_seed(config.seed))
    total, count = 0.0, 0
    try:
        for i, batch in enumerate(loader):
            if config.val_batches is not None and i >= config.val_batches:
                break
            batch = _to_device(batch, device)
            ctx = StepContext(step=step, epoch=epoch, training=False, generator=generator, config=config)
            loss, _ = step_fn(model, batch, ctx)
            size = _batch_size(batch)
            total += float(loss) * size
            count += size
    finally:
        model.train(was_training)
    return total / count if count else float("nan")


def _batch_size(batch: Any) -> int:
    if isinstance(batch, torch.Tensor):
        return int(batch.shape[0])
    if isinstance(batch, Mapping):
        return _batch_size(next(iter(batch.values())))
    return _batch_size(batch[0])


def train(
    model: nn.Module,
    train_set: Dataset,
    val_set: Dataset | None,
    config: TrainConfig,
    *,
    step_fn: StepFn,
    out_dir: str | Path,
    resume: bool = False,
    stats: Any = None,
    meta: Mapping[str, Any] | None = None,
    progress: bool = True,
    callbacks: Iterable[Callable[[dict[str, Any]], None]] = (),
) -> TrainResult:
    """Train ``model`` on ``train_set`` with ``step_fn``; validate, checkpoint, resume.

    Parameters
    ----------
    model : an ``nn.Module`` of a registered family with a dataclass ``model.config``
    train_set, val_set : map-style datasets whose items collate into the batches ``step_fn`` expects
        (``val_set`` may be None: no validation, no ``best/``)
    config : :class:`TrainConfig`
    step_fn : ``step_fn(model, batch, ctx) -> (loss, logs)``: the scalar loss to minimise and a
        mapping of numbers to log (see :mod:`dancekit.training.objectives`)
    out_dir : run folder (created)
    resume : continue from the newest complete checkpoint in ``out_dir`` (starts afresh when there is
        none); the model configuration must be the checkpoint's
    stats : normalisation statistics saved with every checkpoint (``NormStats`` or arrays)
    meta : more entries for every checkpoint's ``config.json`` (representation, preset, fps, skeleton)
    progress : show a tqdm bar (loss, learning rate, ETA) on stderr
    callbacks : called with every log record (a dict)

    Returns
    -------
    :class:`TrainResult`

    Raises
    ------
    CheckpointError
        When resuming from a checkpoint that does not match ``model``.
    FloatingPointError
        When the loss becomes NaN or infinite.
    """
    from tqdm import tqdm

    if not hasattr(model, "config") or not dataclasses.is_dataclass(model.config):
        raise ParameterError(f"{type(model).__name__} needs a dataclass `config` attribute to be checkpointed")
    if len(train_set) == 0:
        raise ParameterError("the training set is empty (no window fits in any training dance?)")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if config.threads:
        torch.set_num_threads(config.threads)
    device = torch.device(config.device)
    model.to(device)
    seed_everything(config.seed)
    generator = torch.Generator(device=device).manual_seed(config.seed)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)

    steps_per_epoch = max(1, len(train_set) // config.batch_size)
    total = config.epochs * steps_per_epoch if config.epochs else config.steps
    extra = {**(meta or {}), "train": dataclasses.asdict(config)}

    step, history, best_val = 0, [], None
    if resume and (found := checkpoints(out_dir)):
        step, history, best_val = _load_checkpoint(found[-1], model, optimizer, generator, device)
    elif resume and progress:
        print(f"no checkpoint in {out_dir / 'checkpoints'}: starting from step 0")

    def log(record: dict[str, Any]) -> None:
        history.append(record)
        with atomic_path(out_dir / "log.jsonl") as tmp:
            tmp.write_text("".join(json.dumps(r) + "\n" for r in history))
        for cb in callbacks:
            cb(record)

    def save(step: int) -> None:
        state = {
            "step": step,
            "optimizer": optimizer.state_dict(),
            "rng": _rng_state(generator),
            "history": json.dumps(history),
            "best_val": best_val,
        }
        with atomic_dir(out_dir / "checkpoints" / f"step_{step:07d}") as tmp:
            write_pretrained(tmp, model, model.config, stats=stats, extra=extra)
            torch.save(state, tmp / STATE_FILE)
        with atomic_dir(out_dir / "model") as tmp:
            write_pretrained(tmp, model, model.config, stats=stats, extra={**extra, "step": step})
        for old in checkpoints(out_dir)[: -config.keep_checkpoints]:
            shutil.rmtree(old, ignore_errors=True)

    bar = tqdm(total=total, initial=step, desc=f"train {getattr(model, 'family', '')}".strip(),
               disable=not progress, dynamic_ncols=True, unit="step")
    model.train()
    run_loss, run_n, last_logs = 0.0, 0, {}
    train_loss = val_loss = None
    t_start = time.perf_counter()
    while step < total:
        epoch = step // steps_per_epoch
        batches = _epoch_batches(len(train_set), config.batch_size, seed=config.seed, epoch=epoch)
        batches = batches[step % steps_per_epoch :]
        # its own generator: creating a loader must not consume the global RNG (exact resumption)
        loader = DataLoader(train_set, batch_sampler=batches, num_workers=config.num_workers,
                            generator=torch.Generator().manual_seed(config.seed + epoch))
        for batch in loader:
            lr = learning_rate(step, base_lr=config.lr, total_steps=total, warmup_steps=config.warmup_steps,
                               kind=config.lr_schedule, min_lr=min(config.min_lr, config.lr))
            for group in optimizer.param_groups:
                group["lr"] = lr
            ctx = StepContext(step=step, epoch=epoch, training=True, generator=generator, config=config)
            loss, logs = step_fn(model, _to_device(batch, device), ctx)
            loss_value = float(loss.detach())
            if not math.isfinite(loss_value):
                raise FloatingPointError(f"the training loss became {loss_value} at step {step}")
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            if config.grad_clip is not None:
                torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
            optimizer.step()
            step += 1
            run_loss += loss_value
            run_n += 1
            last_logs = dict(logs)
            bar.update(1)
            bar.set_postfix(loss=f"{loss_value:.4f}", lr=f"{lr:.2e}", **{k: v for k, v in last_logs.items()})

            if step % config.log_every == 0 or step == total:
                train_loss = run_loss / run_n
                log({"step": step, "epoch": epoch, "loss": train_loss, "lr": lr, **last_logs,
                     "elapsed_s": round(time.perf_counter() - t_start, 3)})
                run_loss, run_n = 0.0, 0
            if val_set is not None and len(val_set) and (step % config.val_every == 0 or step == total):
                val_loss = evaluate(model, val_set, step_fn, config=config, step=step, epoch=epoch)
                log({"step": step, "epoch": epoch, "val_loss": val_loss})
                if progress:
                    bar.write(f"step {step}: val_loss {val_loss:.4f}")
                if best_val is None or val_loss < best_val:
                    best_val = val_loss
                    with atomic_dir(out_dir / "best") as tmp:
                        write_pretrained(tmp, model, model.config, stats=stats,
                                         extra={**extra, "step": step, "val_loss": val_loss})
            if step % config.ckpt_every == 0 or step == total:
                save(step)
            if step >= total:
                break
    bar.close()
    if train_loss is None:
        train_loss = next((r["loss"] for r in reversed(history) if "loss" in r), None)
    if val_loss is None:
        val_loss = next((r["val_loss"] for r in reversed(history) if "val_loss" in r), None)
    return TrainResult(step=step, epoch=step // steps_per_epoch, train_loss=train_loss, val_loss=val_loss,
                       best_val_loss=best_val, out_dir=out_dir, history=list(history))


def _load_checkpoint(folder: Path, model: nn.Module, optimizer: torch.optim.Optimizer,
                     generator: torch.Generator, device: torch.device) -> tuple[int, list, float | None]:
    from safetensors.torch import load_file

    saved = read_config(folder)
    current = dataclasses.asdict(model.config)
    if saved["config"] != current:
        diff = sorted(k for k in set(saved["config"]) | set(current) if saved["config"].get(k) != current.get(k))
        raise CheckpointError(f"cannot resume from {folder}: the model configuration differs in {diff}")
    try:
        model.load_state_dict(load_file(str(folder / WEIGHTS_FILE), device=str(device)))
        state = torch.load(folder / STATE_FILE, map_location=device, weights_only=True)
        optimizer.load_state_dict(state["optimizer"])
        _set_rng_state(state["rng"], generator)
    except (RuntimeError, OSError, KeyError, ValueError) as exc:
        raise CheckpointError(f"cannot resume from {folder}: {exc}") from exc
    return int(state["step"]), json.loads(state["history"]), state["best_val"]
