"""Distributed data parallel training on PyTorch's own engine (``torchrun`` + ``DistributedDataParallel``).

``dancekit train ...`` runs unchanged under ``torchrun --nproc_per_node=N`` (and on several nodes through
torchrun's rendezvous): :func:`train` sees the ``WORLD_SIZE`` / ``RANK`` / ``LOCAL_RANK`` variables that
torchrun sets and trains with a :class:`DistributedTrainer` instead of the single-process
:class:`~dancekit.training.Trainer`:

* the process group is initialised from the torchrun environment (``env://``) with the ``nccl`` backend
  when the run's device is CUDA (each process on ``cuda:LOCAL_RANK``), ``gloo`` on the CPU;
* the model is wrapped in :class:`DistributedDataParallel` (a wrapper that also exposes the bare model's
  ``config`` and ``family``, so step functions read ``model.config`` as before); the optimiser sees the
  same parameters;
* ``batch_size`` is the global batch: each epoch's batches (:func:`~dancekit.training.loop.epoch_batches`,
  the same on every rank) are split ``indices[rank::world_size]``, so the ranks see disjoint items and the
  averaged gradients are those of the whole batch;
* each rank's random generators are seeded ``seed + rank`` (rank 0: as a single process); every checkpoint
  holds all ranks' generator states and a resume with the same world size restores each rank's own;
* the logged training loss and the validation loss are averaged over the ranks (validation: each rank
  scores ``val_set[rank::world_size]``; sums and counts are all-reduced);
* rank 0 alone writes checkpoints, ``log.jsonl`` and the progress bar; the saved weights are the bare
  model's (no ``module.`` prefix), so ``load_pretrained`` / ``from_pretrained`` read them as usual.

Checkpoints are written by rank 0 and read by every rank on ``--resume``: on several nodes, ``--out`` must
be on a shared file system.

``DANCEKIT_DEBUG_DDP=DIR`` makes every rank append the dataset indices of each of its batches to
``DIR/batches_rank{RANK}.jsonl`` and write, at the end, ``DIR/final_rank{RANK}.json``: the SHA-256 of its
final weights and the number of files it wrote in the run folder (outside the run folder; for tests and
debugging).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import torch
from torch import distributed as dist
from torch import nn
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import Dataset, Subset

from dancekit.errors import ParameterError
from dancekit.training.loop import StepFn, Trainer, TrainResult, evaluate

DEBUG_ENV = "DANCEKIT_DEBUG_DDP"


def launched_by_torchrun() -> bool:
    """Whether this process is one of several started by ``torchrun`` (``WORLD_SIZE`` > 1 in the environment)."""
    return int(os.environ.get("WORLD_SIZE", "1")) > 1


def rank() -> int:
    """This process's global rank (0 without torchrun)."""
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank()
    return int(os.environ.get("RANK", "0"))


def is_main_process() -> bool:
    """Whether this process is rank 0 (the one that prints and writes files); True without torchrun."""
    return rank() == 0


def device_for(device: str) -> torch.device:
    """The device of this process for a run configured on ``device``: ``cuda`` becomes ``cuda:LOCAL_RANK``."""
    dev = torch.device(device)
    if dev.type == "cuda" and dev.index is None and launched_by_torchrun():
        return torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
    return dev


def init_process_group(device: torch.device) -> None:
    """Join torchrun's process group (``env://``): ``nccl`` for CUDA devices, ``gloo`` otherwise. Idempotent."""
    if dist.is_initialized():
        return
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(backend="nccl" if device.type == "cuda" else "gloo")


class _DDP(DistributedDataParallel):
    """``DistributedDataParallel`` that also answers the bare model's ``config`` and ``family``."""

    @property
    def config(self) -> Any:
        return self.module.config

    @property
    def family(self) -> str:
        return getattr(self.module, "family", "")


def _shard(dataset: Dataset, r: int, world: int) -> Dataset:
    return Subset(dataset, list(range(r, len(dataset), world)))


class DistributedTrainer(Trainer):
    """:class:`~dancekit.training.Trainer` for one process of a torchrun job (see the module docstring).

    Built like a ``Trainer`` (the bare model); :meth:`build` joins the process group and wraps the model.

    Raises
    ------
    ParameterError
        When the global ``batch_size`` is not a multiple of the number of processes or the training set
        has fewer items than processes.
    """

    def __init__(self, model: nn.Module, train_set: Dataset, val_set: Dataset | None, config: Any, *,
                 step_fn: StepFn, out_dir: str | Path, **kwargs: Any):
        super().__init__(model, train_set, val_set, config, step_fn=step_fn, out_dir=out_dir, **kwargs)
        self.device = device_for(config.device)
        init_process_group(self.device)
        self.rank, self.world_size = dist.get_rank(), dist.get_world_size()
        self.progress = self.progress and self.rank == 0
        if config.batch_size % self.world_size:
            raise ParameterError(f"batch_size {config.batch_size} (the global batch) must be a multiple of the "
                                 f"{self.world_size} processes")
        if len(train_set) < config.batch_size:
            raise ParameterError(f"the training set holds {len(train_set)} items, fewer than one global batch "
                                 f"of {config.batch_size} shared by {self.world_size} processes")
        debug = os.environ.get(DEBUG_ENV)
        self._debug_dir = Path(debug) if debug else None

    # ---- hooks ----------------------------------------------------------------------------------------

    @property
    def is_main_process(self) -> bool:
        return self.rank == 0

    def shard_batch(self, indices: list[int]) -> list[int]:
        share = indices[self.rank::self.world_size]
        if self._debug_dir is not None:
            self._debug_dir.mkdir(parents=True, exist_ok=True)
            with (self._debug_dir / f"batches_rank{self.rank}.jsonl").open("a") as f:
                f.write(json.dumps(share) + "\n")
        return share

    def fit(self, *, resume: bool = False) -> TrainResult:
        result = super().fit(resume=resume)
        if self._debug_dir is not None:
            self._debug_dir.mkdir(parents=True, exist_ok=True)
            (self._debug_dir / f"final_rank{self.rank}.json").write_text(json.dumps(
                {"sha256": weights_sha256(self.unwrap()), "writes": self.writes, "step": self.global_step}))
        return result

    def seed(self) -> int:
        return self.config.seed + self.rank

    def wrap(self, model: nn.Module) -> nn.Module:
        ids = [self.device.index] if self.device.type == "cuda" else None
        return _DDP(model, device_ids=ids, find_unused_parameters=self.config.find_unused_parameters)

    def reduce_mean(self, value: float) -> float:
        t = torch.tensor([value], dtype=torch.float64, device=self._comm_device)
        dist.all_reduce(t)
        return float(t[0]) / self.world_size

    @property
    def _comm_device(self) -> torch.device:
        return self.device if dist.get_backend() == "nccl" else torch.device("cpu")

    def gather_objects(self, obj: Any) -> list[Any]:
        out: list[Any] = [None] * self.world_size
        dist.all_gather_object(out, obj)
        return out

    def barrier(self) -> None:
        dist.barrier()

    def validate(self, *, epoch: int) -> float:
        if self.val_set is None or not len(self.val_set):
            return float("nan")
        part = _shard(self.val_set, self.rank, self.world_size)
        mean = evaluate(self.unwrap(), part, self.step_fn, config=self.config, step=self.global_step,
                        epoch=epoch) if len(part) else float("nan")
        count = len(part) if self.config.val_batches is None else min(
            len(part), self.config.val_batches * self.config.batch_size)
        t = torch.tensor([mean * count if count else 0.0, float(count)], dtype=torch.float64,
                         device=self._comm_device)
        dist.all_reduce(t)
        return float(t[0] / t[1]) if t[1] > 0 else float("nan")


def weights_sha256(model: nn.Module) -> str:
    """SHA-256 of a model's state dict (names and float32 bytes, in order)."""
    h = hashlib.sha256()
    for name, t in model.state_dict().items():
        h.update(name.encode())
        h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def close() -> None:
    """Leave the process group (after training; safe to call when there is none)."""
    if dist.is_available() and dist.is_initialized():
        dist.destroy_process_group()


def is_wrapped(model: nn.Module) -> bool:
    return isinstance(model, DistributedDataParallel)

