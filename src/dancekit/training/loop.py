"""One generic training loop for every model family: :class:`Trainer` (and :func:`train`, its one-call form).

The loop knows nothing about a family: a ``step_fn(model, batch, ctx) -> (loss, logs)`` computes the
loss of a batch (see :mod:`dancekit.training.objectives`). The trainer owns the optimiser (AdamW or RMSprop), the
learning-rate schedule, gradient clipping, seeding, the progress bar, validation, checkpoints and
resumption, in one method each (:meth:`Trainer.build`, :meth:`~Trainer.step`, :meth:`~Trainer.validate`,
:meth:`~Trainer.save_checkpoint`, :meth:`~Trainer.resume`, :meth:`~Trainer.fit`). It reads only the
generic :class:`~dancekit.training.config.OptimConfig` fields of its configuration; the step functions
read the rest (``ctx.config``).

Output folder layout (``out_dir``)::

    checkpoints/step_0000500/   resumable: config.json + model.safetensors + stats.npz + training_state.pt
    model/                      the latest weights (a plain checkpoint for pipelines)
    best/                       the weights with the lowest validation loss (when validating)
    log.jsonl                   one JSON record per log / validation event

Every folder is written beside its final place and renamed when complete
(:func:`dancekit._io.atomic_dir`), so an interrupted run never leaves a half-written checkpoint, and
``resume=True`` continues from the newest complete one. A resumed run reproduces an uninterrupted one
on CPU: the checkpoint holds the weights, the optimiser state, the step and the states of the torch /
NumPy / Python random generators and of the objectives' generator; everything else that shapes a batch
is a pure function of (seed, epoch): the shuffled batches (:func:`epoch_batches`) and a dataset's own
randomness through its ``set_epoch(epoch)`` (:class:`~dancekit.data.WindowDataset`'s window offsets).

Data parallelism: a subclass can override the hooks :meth:`Trainer.shard_batch` (this process's share of a
global batch), :attr:`Trainer.is_main_process` (only the main process writes files and shows progress),
:meth:`Trainer.unwrap` (the bare model to save, e.g. ``DistributedDataParallel.module``), :meth:`Trainer.wrap`,
:meth:`Trainer.seed`, :meth:`Trainer.reduce_mean`, :meth:`Trainer.gather_objects` and :meth:`Trainer.barrier`.
:class:`dancekit.training.distributed.DistributedTrainer` is that subclass for torchrun, and :func:`train` uses it
when started by torchrun.

GPUs: ``grad_accum_steps`` splits each (per-process) batch into micro-batches whose gradients add up to the
batch's (one optimiser step); ``precision="bf16"`` / ``"fp16"`` runs the step function under autocast (fp16
with a gradient scaler, saved with the optimiser). The CUDA random states are saved and restored too.
"""

from __future__ import annotations

import contextlib
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
from dancekit.training.config import OptimConfig, TrainConfig
from dancekit.training.schedules import learning_rate

STATE_FILE = "training_state.pt"


@dataclass
class StepContext:
    """What a ``step_fn`` may need besides the model and the batch."""

    step: int  # optimisation step about to be taken (0-based)
    epoch: int  # completed epochs, the ``t`` of curricula
    training: bool  # False during validation
    generator: torch.Generator  # for the model's own sampling (e.g. initial decoder states)
    config: TrainConfig  # the configuration given to the trainer


StepFn = Callable[[nn.Module, dict[str, torch.Tensor], StepContext], tuple[torch.Tensor, Mapping[str, float]]]


@dataclass
class TrainResult:
    """What :meth:`Trainer.fit` (:func:`train`) did."""

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
    state = {
        "torch": torch.get_rng_state(),
        "numpy": [np_state[0], torch.from_numpy(np_state[1].astype(np.int64)), *np_state[2:]],
        "python": _to_lists(random.getstate()),
        "generator": generator.get_state(),
    }
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def _to_lists(x: Any) -> Any:
    return [_to_lists(v) for v in x] if isinstance(x, tuple | list) else x


def _to_tuples(x: Any) -> Any:
    return tuple(_to_tuples(v) for v in x) if isinstance(x, list) else x


def _set_rng_state(state: Mapping[str, Any], generator: torch.Generator) -> None:
    torch.set_rng_state(state["torch"])
    name, keys, *rest = state["numpy"]
    np.random.set_state((name, keys.numpy().astype(np.uint32), *rest))
    random.setstate(_to_tuples(state["python"]))
    generator.set_state(state["generator"].cpu())
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all([s.cpu() for s in state["cuda"]])


def epoch_batches(n: int, batch_size: int, *, seed: int, epoch: int) -> list[list[int]]:
    """The shuffled batches of ``n`` items in one epoch (the last partial batch dropped, unless it is the only
    one), a pure function of (seed, epoch) so resumption is exact."""
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    perm = torch.randperm(n, generator=g).tolist()
    if n < batch_size:
        return [perm]
    return [perm[i * batch_size : (i + 1) * batch_size] for i in range(n // batch_size)]


def _plain(obj: Any) -> Any:
    return obj.tolist() if hasattr(obj, "tolist") else str(obj)


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
    config: OptimConfig,
    step: int = 0,
    epoch: int = 0,
) -> float:
    """Mean loss of ``step_fn`` over ``dataset`` (in order, eval mode, a fixed generator seed).

    Reads ``config.device``, ``seed``, ``batch_size``, ``num_workers`` and ``val_batches``; the step
    function gets ``config`` as ``ctx.config``.
    """
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


def _split(batch: Any, n: int) -> list[Any]:
    """``batch`` (tensors, mappings, sequences of them) in ``n`` micro-batches along the first dimension (fewer
    when it holds fewer items)."""
    n = max(1, min(n, _batch_size(batch)))
    if isinstance(batch, torch.Tensor):
        return list(torch.tensor_split(batch, n))
    if isinstance(batch, Mapping):
        parts = {k: _split(v, n) if isinstance(v, torch.Tensor | Mapping | list | tuple) else [v] * n
                 for k, v in batch.items()}
        return [{k: v[i] for k, v in parts.items()} for i in range(n)]
    columns = [_split(v, n) for v in batch]
    return [type(batch)(c[i] for c in columns) for i in range(n)]


def _batch_size(batch: Any) -> int:
    if isinstance(batch, torch.Tensor):
        return int(batch.shape[0])
    if isinstance(batch, Mapping):
        return _batch_size(next(iter(batch.values())))
    return _batch_size(batch[0])


Callback = Callable[[dict[str, Any]], None]


class Trainer:
    """Train a model with a step function: build, then step / validate / checkpoint, resumable.

    Parameters
    ----------
    model : an ``nn.Module`` of a registered family with a dataclass ``model.config``
    train_set, val_set : map-style datasets whose items collate into the batches ``step_fn`` expects
        (``val_set`` may be None: no validation, no ``best/``). A training set with a ``set_epoch(epoch)``
        method gets it called before each epoch (e.g. :class:`~dancekit.data.WindowDataset`'s offsets).
    config : the run's settings (:class:`~dancekit.training.TrainConfig`); the trainer reads its
        :class:`~dancekit.training.config.OptimConfig` fields, ``step_fn`` gets all of it as ``ctx.config``
    step_fn : ``step_fn(model, batch, ctx) -> (loss, logs)``: the scalar loss to minimise and a mapping of
        numbers to log (see :mod:`dancekit.training.objectives`)
    out_dir : run folder (created by :meth:`build`)
    stats : normalisation statistics saved with every checkpoint (``NormStats`` or arrays)
    meta : more entries for every checkpoint's ``config.json`` (representation, preset, fps, skeleton)
    progress : show a tqdm bar (loss, learning rate, ETA) on stderr
    callbacks : called with every log record (a dict); an exception raised there stops training (the
        checkpoints written so far stay resumable)

    Raises
    ------
    ParameterError
        When the model has no dataclass ``config`` or the training set is empty.

    Examples
    --------
    >>> trainer = Trainer(model, train_set, val_set, TrainConfig(steps=100), step_fn=revolution_step,
    ...                   out_dir="runs/a")  # doctest: +SKIP
    >>> result = trainer.fit(resume=True)  # doctest: +SKIP
    """

    def __init__(
        self,
        model: nn.Module,
        train_set: Dataset,
        val_set: Dataset | None,
        config: OptimConfig,
        *,
        step_fn: StepFn,
        out_dir: str | Path,
        stats: Any = None,
        meta: Mapping[str, Any] | None = None,
        progress: bool = True,
        callbacks: Iterable[Callback] = (),
    ):
        if not hasattr(model, "config") or not dataclasses.is_dataclass(model.config):
            raise ParameterError(f"{type(model).__name__} needs a dataclass `config` attribute to be checkpointed")
        if len(train_set) == 0:
            raise ParameterError("the training set is empty (no window fits in any training dance?)")
        self.model, self.train_set, self.val_set, self.config = model, train_set, val_set, config
        self.step_fn, self.out_dir, self.stats = step_fn, Path(out_dir), stats
        self.extra = {**(meta or {}), "train": dataclasses.asdict(config)}  # in every checkpoint's config.json
        self.progress, self.callbacks = progress, list(callbacks)
        self.device = torch.device(config.device)
        self.steps_per_epoch = max(1, len(train_set) // config.batch_size)
        self.total_steps = config.epochs * self.steps_per_epoch if config.epochs else config.steps
        # state: what a checkpoint saves and :meth:`resume` restores (with the random generators)
        self.global_step = 0  # optimisation steps taken
        self.history: list[dict[str, Any]] = []
        self.best_val: float | None = None
        self.optimizer: torch.optim.Optimizer | None = None
        self.generator: torch.Generator | None = None  # the step functions' (ctx.generator)
        self.autocast_dtype: torch.dtype | None = None  # mixed precision (build)
        self.scaler: torch.amp.GradScaler | None = None  # fp16
        self.rank, self.world_size = 0, 1  # this process among the data-parallel ones
        self.writes = 0  # files and folders this process wrote (log.jsonl, checkpoints, best/)

    # ---- hooks for data parallelism (a single process: the identity) ------------------------------------

    @property
    def is_main_process(self) -> bool:
        """Whether this process writes checkpoints and logs and shows progress (rank 0 under DDP)."""
        return True

    def unwrap(self) -> nn.Module:
        """The bare model, whose ``config`` and ``state_dict`` are saved (``model.module`` of a DDP wrapper)."""
        return getattr(self.model, "module", self.model)

    def shard_batch(self, indices: list[int]) -> list[int]:
        """This process's items of a global batch (all of them; under DDP e.g. ``indices[rank::world_size]``)."""
        return indices

    def seed(self) -> int:
        """The seed of this process's random generators (under DDP: ``seed + rank``)."""
        return self.config.seed

    def wrap(self, model: nn.Module) -> nn.Module:
        """The model the steps run (e.g. a ``DistributedDataParallel`` wrapper); :meth:`unwrap` gives it back."""
        return model

    def reduce_mean(self, value: float) -> float:
        """``value`` averaged over the processes (one process: itself)."""
        return value

    def gather_objects(self, obj: Any) -> list[Any]:
        """Every process's ``obj``, in rank order (one process: ``[obj]``)."""
        return [obj]

    def barrier(self) -> None:
        """Wait for every process (one process: nothing to wait for)."""

    # ---- build -----------------------------------------------------------------------------------------

    def build(self) -> None:
        """Create the run folder, set threads and device, seed every generator, make the optimiser.

        The order (seeding, then the step functions' generator, then the optimiser) fixes what a seed
        trains to; :meth:`resume` then overwrites the states from a checkpoint.
        """
        self.out_dir.mkdir(parents=True, exist_ok=True)
        if self.config.threads:
            torch.set_num_threads(self.config.threads)
        self.model.to(self.device)
        seed_everything(self.seed())
        self.generator = torch.Generator(device=self.device).manual_seed(self.seed())
        self.model = self.wrap(self.model)
        self.optimizer = self.configure_optimizer()
        precision = self.config.precision
        if precision == "fp16" and self.device.type != "cuda":
            raise ParameterError(f"precision fp16 needs a CUDA device (this run's is {self.device}); use bf16")
        self.autocast_dtype = {"bf16": torch.bfloat16, "fp16": torch.float16}.get(precision)
        self.scaler = torch.amp.GradScaler("cuda") if precision == "fp16" else None

    def configure_optimizer(self) -> torch.optim.Optimizer:
        """``config.optimizer`` (AdamW or RMSprop) over every parameter (the rate is set each step from the schedule)."""
        c = self.config
        if c.optimizer == "rmsprop":
            return torch.optim.RMSprop(self.model.parameters(), lr=c.lr, weight_decay=c.weight_decay)
        return torch.optim.AdamW(self.model.parameters(), lr=c.lr, weight_decay=c.weight_decay)

    # ---- data --------------------------------------------------------------------------------------------

    def epoch_loader(self, epoch: int, *, start: int = 0) -> DataLoader:
        """The batches of ``epoch`` from its ``start``-th on (mid-epoch resumption), this process's shares.

        Calls ``train_set.set_epoch(epoch)`` when the dataset has it, before any worker copies the dataset.
        """
        if hasattr(self.train_set, "set_epoch"):
            self.train_set.set_epoch(epoch)
        c = self.config
        batches = [self.shard_batch(b) for b in
                   epoch_batches(len(self.train_set), c.batch_size, seed=c.seed, epoch=epoch)[start:]]
        # its own generator: creating a loader must not consume the global RNG (exact resumption)
        return DataLoader(self.train_set, batch_sampler=batches, num_workers=c.num_workers,
                          generator=torch.Generator().manual_seed(c.seed + epoch))

    # ---- step, validate -------------------------------------------------------------------------------

    def learning_rate(self, step: int) -> float:
        c = self.config
        return learning_rate(step, base_lr=c.lr, total_steps=self.total_steps, warmup_steps=c.warmup_steps,
                             kind=c.lr_schedule, min_lr=min(c.min_lr, c.lr))

    def step(self, batch: Any, *, epoch: int) -> dict[str, Any]:
        """One optimisation step on ``batch``; returns ``{**logs of step_fn, "loss": float, "lr": float}``.

        Raises
        ------
        FloatingPointError
            When the loss is NaN or infinite.
        """
        assert self.optimizer is not None and self.generator is not None, "call build() first"
        lr = self.learning_rate(self.global_step)
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        ctx = StepContext(step=self.global_step, epoch=epoch, training=True, generator=self.generator,
                          config=self.config)
        batch = _to_device(batch, self.device)
        parts = _split(batch, self.config.grad_accum_steps) if self.config.grad_accum_steps > 1 else [batch]
        total = _batch_size(batch)
        self.optimizer.zero_grad(set_to_none=True)
        loss_value, logs = 0.0, {}
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            # DDP: gradients are averaged over the processes once, after the last micro-batch
            sync = contextlib.nullcontext() if last or not hasattr(self.model, "no_sync") else self.model.no_sync()
            with sync:
                with torch.autocast(self.device.type, dtype=self.autocast_dtype,
                                    enabled=self.autocast_dtype is not None):
                    loss, logs = self.step_fn(self.model, part, ctx)
                loss = loss.float() * (_batch_size(part) / total)
                loss_value += float(loss.detach())
                (self.scaler.scale(loss) if self.scaler is not None else loss).backward()
        loss_value = self.reduce_mean(loss_value)
        if not math.isfinite(loss_value):
            raise FloatingPointError(f"the training loss became {loss_value} at step {self.global_step}")
        if self.scaler is not None:
            self.scaler.unscale_(self.optimizer)
        if self.config.grad_clip is not None:
            torch.nn.utils.clip_grad_norm_(self.model.parameters(), self.config.grad_clip)
        if self.scaler is not None:
            self.scaler.step(self.optimizer)
            self.scaler.update()
        else:
            self.optimizer.step()
        self.global_step += 1
        return {**logs, "loss": loss_value, "lr": lr}

    def validate(self, *, epoch: int) -> float:
        """Mean validation loss (:func:`evaluate`) of the current weights; NaN without a validation set."""
        if self.val_set is None or not len(self.val_set):
            return float("nan")
        return evaluate(self.unwrap(), self.val_set, self.step_fn, config=self.config, step=self.global_step,
                        epoch=epoch)

    def log(self, record: dict[str, Any]) -> None:
        """Append ``record`` to the history and ``log.jsonl``; call the callbacks."""
        self.history.append(record)
        if self.is_main_process:
            with atomic_path(self.out_dir / "log.jsonl") as tmp:
                tmp.write_text("".join(json.dumps(r) + "\n" for r in self.history))
            self.writes += 1
        for cb in self.callbacks:
            cb(record)

    # ---- checkpoint, resume ----------------------------------------------------------------------------

    def save_checkpoint(self) -> Path | None:
        """Write ``checkpoints/step_N/`` (resumable) and ``model/``; prune old checkpoints.

        Returns the checkpoint folder (None outside the main process, which writes nothing).
        """
        assert self.optimizer is not None and self.generator is not None, "call build() first"
        rng_all = self.gather_objects(_rng_state(self.generator))  # every process's generators
        if not self.is_main_process:
            self.barrier()  # until the main process has written it
            return None
        model, step = self.unwrap(), self.global_step
        state = {
            "step": step,
            "optimizer": self.optimizer.state_dict(),
            "rng": rng_all[0],
            "rng_ranks": rng_all,
            "history": json.dumps(self.history),
            "best_val": self.best_val,
        }
        if self.scaler is not None:
            state["scaler"] = self.scaler.state_dict()
        folder = self.out_dir / "checkpoints" / f"step_{step:07d}"
        with atomic_dir(folder) as tmp:
            write_pretrained(tmp, model, model.config, stats=self.stats, extra=self.extra)
            torch.save(state, tmp / STATE_FILE)
        with atomic_dir(self.out_dir / "model") as tmp:
            write_pretrained(tmp, model, model.config, stats=self.stats, extra={**self.extra, "step": step})
        self.writes += 2
        for old in checkpoints(self.out_dir)[: -self.config.keep_checkpoints]:
            shutil.rmtree(old, ignore_errors=True)
        self.barrier()
        return folder

    def save_best(self, val_loss: float) -> None:
        """Write ``best/`` (the current weights and their validation loss)."""
        if not self.is_main_process:
            return
        model = self.unwrap()
        with atomic_dir(self.out_dir / "best") as tmp:
            write_pretrained(tmp, model, model.config, stats=self.stats,
                             extra={**self.extra, "step": self.global_step, "val_loss": val_loss})
        self.writes += 1

    def resume(self) -> Path | None:
        """Continue from the newest complete checkpoint in ``out_dir``; returns it (None: there is none).

        Raises
        ------
        CheckpointError
            When the checkpoint does not match the model (the message names the differing fields) or
            cannot be read.
        """
        if self.optimizer is None:
            self.build()
        found = checkpoints(self.out_dir)
        if not found:
            if self.progress and self.is_main_process:
                print(f"no checkpoint in {self.out_dir / 'checkpoints'}: starting from step 0")
            return None
        self.load_checkpoint(found[-1])
        return found[-1]

    def load_checkpoint(self, folder: Path) -> None:
        """Restore weights, optimiser, step, history, best validation loss and random generators from ``folder``."""
        from safetensors.torch import load_file

        assert self.optimizer is not None and self.generator is not None, "call build() first"
        model = self.unwrap()
        saved = read_config(folder)
        # compared as saved in config.json: tuples are lists there, NumPy numbers plain ones
        current = json.loads(json.dumps(dataclasses.asdict(model.config), default=_plain))
        if saved["config"] != current:
            diff = sorted(k for k in set(saved["config"]) | set(current) if saved["config"].get(k) != current.get(k))
            raise CheckpointError(f"cannot resume from {folder}: the model configuration differs in {diff}")
        try:
            model.load_state_dict(load_file(str(folder / WEIGHTS_FILE), device=str(self.device)))
            state = torch.load(folder / STATE_FILE, map_location="cpu", weights_only=True)
            self.optimizer.load_state_dict(state["optimizer"])  # moved to the parameters' device
            # each process its own generators when resumed with as many processes as saved them
            ranks = state.get("rng_ranks") or [state["rng"]]
            _set_rng_state(ranks[self.rank] if len(ranks) == self.world_size else ranks[0], self.generator)
            if self.scaler is not None and "scaler" in state:
                self.scaler.load_state_dict(state["scaler"])
        except (RuntimeError, OSError, KeyError, ValueError) as exc:
            raise CheckpointError(f"cannot resume from {folder}: {exc}") from exc
        self.global_step = int(state["step"])
        self.history = json.loads(state["history"])
        self.best_val = state["best_val"]

    # ---- the loop ---------------------------------------------------------------------------------------

    def fit(self, *, resume: bool = False) -> TrainResult:
        """Train to ``total_steps``: :meth:`step`, then :meth:`after_step` (log, validate, checkpoint).

        ``resume=True`` first restores the newest checkpoint of ``out_dir`` (:meth:`resume`; none: from step 0).

        Raises
        ------
        CheckpointError
            When resuming from a checkpoint that does not match the model.
        FloatingPointError
            When the loss becomes NaN or infinite.
        """
        from tqdm import tqdm

        if self.optimizer is None:
            self.build()
        if resume:
            self.resume()
        total = self.total_steps
        self._bar = tqdm(total=total, initial=self.global_step, unit="step", dynamic_ncols=True,
                         desc=f"train {getattr(self.unwrap(), 'family', '')}".strip(),
                         disable=not (self.progress and self.is_main_process))
        self._losses: list[float] = []  # training losses since the last log record
        self._t_start = time.perf_counter()
        self.model.train()
        try:
            while self.global_step < total:
                epoch = self.global_step // self.steps_per_epoch
                for batch in self.epoch_loader(epoch, start=self.global_step % self.steps_per_epoch):
                    self.after_step(self.step(batch, epoch=epoch), epoch=epoch)
                    if self.global_step >= total:
                        break
        finally:
            self._bar.close()
        last = {key: next((r[key] for r in reversed(self.history) if key in r), None) for key in ("loss", "val_loss")}
        return TrainResult(step=self.global_step, epoch=self.global_step // self.steps_per_epoch,
                           train_loss=last["loss"], val_loss=last["val_loss"], best_val_loss=self.best_val,
                           out_dir=self.out_dir, history=list(self.history))

    def after_step(self, record: dict[str, Any], *, epoch: int) -> None:
        """Progress; every ``log_every`` steps a log record (the mean loss since the last one); every ``val_every``
        a validation (and ``best/`` when it is the lowest); every ``ckpt_every`` a checkpoint; all three at the end."""
        c, step, done = self.config, self.global_step, self.global_step == self.total_steps
        logs = dict(record)
        lr, loss = logs.pop("lr"), logs.pop("loss")
        self._losses.append(loss)
        self._bar.update(1)
        self._bar.set_postfix(loss=f"{loss:.4f}", lr=f"{lr:.2e}", **logs)
        if step % c.log_every == 0 or done:
            self.log({"step": step, "epoch": epoch, "loss": sum(self._losses) / len(self._losses), "lr": lr, **logs,
                      "elapsed_s": round(time.perf_counter() - self._t_start, 3)})
            self._losses = []
        if self.val_set is not None and len(self.val_set) and (step % c.val_every == 0 or done):
            val_loss = self.validate(epoch=epoch)
            self.log({"step": step, "epoch": epoch, "val_loss": val_loss})
            if self.progress and self.is_main_process:
                self._bar.write(f"step {step}: val_loss {val_loss:.4f}")
            if self.best_val is None or val_loss < self.best_val:
                self.best_val = val_loss
                self.save_best(val_loss)
        if step % c.ckpt_every == 0 or done:
            self.save_checkpoint()

def train(
    model: nn.Module,
    train_set: Dataset,
    val_set: Dataset | None,
    config: OptimConfig,
    *,
    step_fn: StepFn,
    out_dir: str | Path,
    resume: bool = False,
    stats: Any = None,
    meta: Mapping[str, Any] | None = None,
    progress: bool = True,
    callbacks: Iterable[Callback] = (),
) -> TrainResult:
    """Train ``model`` on ``train_set`` with ``step_fn``; validate, checkpoint, resume: ``Trainer(...).fit(resume=...)``.

    Parameters
    ----------
    model, train_set, val_set, config, step_fn, out_dir, stats, meta, progress, callbacks
        as for :class:`Trainer`
    resume : continue from the newest complete checkpoint in ``out_dir`` (starts afresh when there is
        none); the model configuration must be the checkpoint's

    Under ``torchrun`` (``WORLD_SIZE`` > 1) every process calls this with the same arguments and it trains
    with a :class:`~dancekit.training.distributed.DistributedTrainer` (one share of each batch per process,
    rank 0 writes); see :mod:`dancekit.training.distributed`.

    Returns
    -------
    :class:`TrainResult`

    Raises
    ------
    ParameterError
        When the model has no dataclass ``config`` or the training set is empty.
    CheckpointError
        When resuming from a checkpoint that does not match ``model``.
    FloatingPointError
        When the loss becomes NaN or infinite.
    """
    cls = Trainer
    if _launched_by_torchrun():
        from dancekit.training.distributed import DistributedTrainer as cls  # noqa: N813
    trainer = cls(model, train_set, val_set, config, step_fn=step_fn, out_dir=out_dir, stats=stats, meta=meta,
                  progress=progress, callbacks=callbacks)
    try:
        return trainer.fit(resume=resume)
    finally:
        if cls is not Trainer:
            from dancekit.training.distributed import close

            close()


def _launched_by_torchrun() -> bool:
    import os

    return int(os.environ.get("WORLD_SIZE", "1")) > 1
