"""Distributed data parallel under torchrun (gloo, 2 CPU processes): `dancekit train` unchanged.

Asserts that both ranks end with identical weights (and the saved ones), that only rank 0 wrote files or
printed, that the ranks saw disjoint shares of the same global batches, that the checkpoint loads with
`load_pretrained` (no `module.` prefix), and that the step objectives read a wrapped model's config.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import _proc
import pytest
import torch
from _prepared import write_fake_prepared
from torch import nn
from torch.utils.data import Dataset

from dancekit.checkpoints import load_pretrained
from dancekit.errors import ParameterError
from dancekit.training import OptimConfig, Trainer
from dancekit.training.distributed import weights_sha256
from dancekit.training.loop import epoch_batches

ROOT = Path(__file__).resolve().parents[2]
SETS = ["steps=4", "batch_size=4", "seq_len=20", "stride=5", "log_every=1", "val_every=2", "ckpt_every=2",
        "warmup_steps=1", "threads=1", "d_model=16", "n_heads=2", "d_ff=32", "window=6", "decoder_hidden=16",
        "curriculum_q=3", "music_dropout=0.5"]


def _torchrun(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    # the rendezvous on a free loopback port (--standalone) and the node's address given (--local-addr), so no
    # host name is looked up; a timeout ends torchrun with its two ranks (_proc.run: the process group)
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
           "--local-addr=127.0.0.1", "-m", "dancekit.cli.main", *args]
    return _proc.run(cmd, env=env, capture_output=True, text=True, timeout=120, cwd=ROOT)


@pytest.mark.slow
def test_train_under_torchrun_two_ranks(tmp_path, rng):
    data = write_fake_prepared(tmp_path / "prepared", rng, dim=8)
    run, debug = tmp_path / "run", tmp_path / "debug"
    env = {**os.environ, "DANCEKIT_DEBUG_DDP": str(debug), "OMP_NUM_THREADS": "1", "GLOO_SOCKET_IFNAME": "lo",
           "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    sets = [a for s in SETS for a in ("--set", s)]
    proc = _torchrun(["train", "revolution", "--data", str(data), "--out", str(run), "--quiet", *sets], env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]

    # identical final weights on both ranks, equal to the saved model's
    final = [json.loads((debug / f"final_rank{r}.json").read_text()) for r in (0, 1)]
    assert final[0]["step"] == final[1]["step"] == 4
    assert final[0]["sha256"] == final[1]["sha256"]
    model, meta, _ = load_pretrained(run / "model")  # unwrapped: no `module.` prefix
    assert weights_sha256(model) == final[0]["sha256"]
    assert not any(k.startswith("module.") for k in model.state_dict())

    # only rank 0 wrote files and printed
    assert final[0]["writes"] > 0 and final[1]["writes"] == 0
    assert proc.stdout.count("trained revolution to step 4") == 1
    assert sorted(p.name for p in run.iterdir()) == ["best", "checkpoints", "log.jsonl", "model"]
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in log if "loss" in r] == [1, 2, 3, 4]
    assert all(r["val_loss"] == r["val_loss"] for r in log if "val_loss" in r)  # reduced, not NaN

    # disjoint shares of the global batches of `epoch_batches`, 2 items each
    seen = [[json.loads(line) for line in (debug / f"batches_rank{r}.jsonl").read_text().splitlines()]
            for r in (0, 1)]
    assert len(seen[0]) == len(seen[1]) == 6  # the shares of epoch 0's 6 batches (26 windows // 4)
    for b0, b1, b in zip(seen[0], seen[1], epoch_batches(26, 4, seed=0, epoch=0), strict=True):
        assert len(b0) == len(b1) == 2 and not set(b0) & set(b1) and sorted(b0 + b1) == sorted(b)
    state = torch.load(run / "checkpoints" / "step_0000004" / "training_state.pt", weights_only=True)
    assert len(state["rng_ranks"]) == 2  # every rank's random generators are saved
    assert not torch.equal(state["rng_ranks"][0]["torch"], state["rng_ranks"][1]["torch"])
    assert meta["model"] == "revolution"


def test_epoch_batches_shard_disjoint_and_complete():
    batches = epoch_batches(26, 4, seed=0, epoch=1)
    for b in batches:
        shares = [b[r::2] for r in range(2)]
        assert sorted(shares[0] + shares[1]) == sorted(b) and not set(shares[0]) & set(shares[1])


@dataclasses.dataclass
class _LinConfig:
    dim: int = 3


class _Lin(nn.Module):
    def __init__(self, config: _LinConfig):
        super().__init__()
        self.config = config
        self.lin = nn.Linear(config.dim, 1)


class _Pairs(Dataset):
    def __init__(self):
        g = torch.Generator().manual_seed(0)
        self.x, self.y = torch.randn(16, 3, generator=g), torch.randn(16, 1, generator=g)

    def __len__(self):
        return 16

    def __getitem__(self, k):
        return {"x": self.x[k], "y": self.y[k]}


def _mse(model, batch, ctx):
    return ((model.lin(batch["x"]) - batch["y"]) ** 2).mean(), {}


def _steps(trainer: Trainer, n: int) -> list[float]:
    """``n`` optimisation steps of ``trainer`` (no checkpoints: the toy model is not a registered family)."""
    trainer.build()
    losses = []
    for batch in trainer.epoch_loader(0):
        losses.append(trainer.step(batch, epoch=0)["loss"])
        if len(losses) == n:
            return losses
    return losses


@pytest.mark.parametrize("accum", [1, 2, 4])
def test_gradient_accumulation_takes_the_whole_batch_step(tmp_path, accum):
    """Micro-batches of a batch add up to the whole batch's gradient: the same weights after 3 steps."""
    weights, grads, losses = [], [], []
    for k in (1, accum):
        torch.manual_seed(0)
        model = _Lin(_LinConfig())
        cfg = OptimConfig(steps=3, batch_size=8, warmup_steps=0, grad_clip=None, threads=1, grad_accum_steps=k)
        trainer = Trainer(model, _Pairs(), None, cfg, step_fn=_mse, out_dir=tmp_path / f"acc{k}", progress=False)
        losses.append(_steps(trainer, 3))
        grads.append(torch.cat([p.grad.flatten() for p in model.parameters()]))  # of the last step
        weights.append(torch.cat([p.detach().flatten() for p in model.parameters()]))
    assert torch.allclose(weights[0], weights[1], atol=1e-6)
    assert torch.allclose(grads[0], grads[1], atol=1e-6)
    assert losses[0] == pytest.approx(losses[1], abs=1e-6)


def test_mixed_precision_bf16_trains_and_fp16_needs_cuda(tmp_path):
    torch.manual_seed(0)
    trainer = Trainer(_Lin(_LinConfig()), _Pairs(), None, OptimConfig(steps=2, batch_size=8, precision="bf16",
                      threads=1), step_fn=_mse, out_dir=tmp_path / "bf16", progress=False)
    losses = _steps(trainer, 2)
    assert trainer.autocast_dtype == torch.bfloat16 and all(math.isfinite(x) for x in losses)
    with pytest.raises(ParameterError, match="fp16 needs a CUDA device"):
        Trainer(_Lin(_LinConfig()), _Pairs(), None, OptimConfig(steps=1, batch_size=8, precision="fp16"),
                step_fn=_mse, out_dir=tmp_path / "fp16", progress=False).build()
    with pytest.raises(ParameterError, match="precision"):
        OptimConfig(precision="fp8")


_WRAPPED_STEP = """
import datetime, math, os, sys
import torch
import torch.distributed as dist
from dancekit.models.revolution import RevolutionConfig, RevolutionModel
from dancekit.training import StepContext, TrainConfig, revolution_step
from dancekit.training.distributed import _DDP

torch.manual_seed(0)
store = dist.FileStore(sys.argv[1], 1)
dist.init_process_group("gloo", store=store, rank=0, world_size=1, timeout=datetime.timedelta(seconds=60))
model = _DDP(RevolutionModel(RevolutionConfig(music_dim=8, pose_dim=72, d_model=16, n_heads=2, d_ff=32,
                                              window=6, decoder_hidden=16, n_genres=4)))
cfg = TrainConfig(music_dropout=0.5, genre_dropout=0.5, curriculum_q=3)
batch = {"music": torch.randn(2, 12, 8), "dance": torch.randn(2, 12, 72), "genre": torch.tensor([0, 1])}
ctx = StepContext(step=0, epoch=0, training=True, generator=torch.Generator().manual_seed(0), config=cfg)
loss, _ = revolution_step(model, batch, ctx)
loss.backward()
grads = sum(p.grad is not None for p in model.module.parameters())
print(model.config.n_genres, math.isfinite(float(loss.detach())), grads, len(list(model.module.parameters())),
      flush=True)
# no teardown: a DDP reducer freed while its gloo worker still releases a finished allreduce can deadlock the
# interpreter (the freeing thread holds the GIL and joins the worker, which waits for the GIL)
os._exit(0)
"""


def test_objective_reads_a_wrapped_models_config_and_draws_on_the_generators_device(tmp_path):
    """revolution_step on a DDP-style wrapper (gloo, one process) with genre and music dropout: it reads the
    wrapped model's config and every parameter gets a gradient. In a child process of its own (bounded)."""
    # A file store and the loopback interface: no port to collide on, no host name to resolve (a CI machine
    # whose host name is not in /etc/hosts would otherwise wait on DNS), and a short timeout instead of 30 min.
    env = {**os.environ, "GLOO_SOCKET_IFNAME": "lo", "OMP_NUM_THREADS": "1",
           "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = _proc.run([sys.executable, "-c", _WRAPPED_STEP, str(tmp_path / "store")], env=env,
                     capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    n_genres, finite, with_grad, params = proc.stdout.split()
    assert (n_genres, finite) == ("4", "True")
    assert int(with_grad) == int(params) > 0
