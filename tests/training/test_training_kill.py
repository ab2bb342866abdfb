"""A `dancekit train` process killed with SIGKILL mid-epoch on the windowed dataset (random window offsets,
music dropout drawn by the objective), resumed with `--resume`, logs the losses of an uninterrupted run (to
1e-6) and ends with its weights."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _prepared import write_fake_prepared
from safetensors.torch import load_file

from dancekit.cli.main import main
from dancekit.training import checkpoints

ROOT = Path(__file__).resolve().parents[2]
STEPS, PER_EPOCH, CKPT = 28, 6, 5  # 26 windows // batch 4 = 6 steps an epoch; checkpoints at 5, 10, ...: mid-epoch
SETS = [f"steps={STEPS}", "batch_size=4", "seq_len=20", "stride=5", "log_every=1", "val_every=7",
        f"ckpt_every={CKPT}", "keep_checkpoints=10", "warmup_steps=2", "threads=1", "d_model=16", "n_heads=2",
        "d_ff=32", "window=6", "decoder_hidden=16", "curriculum_q=3", "curriculum_lambda=1.0",
        "music_dropout=0.5"]


def _cmd(data: Path, out: Path, *extra: str) -> list[str]:
    sets = [a for s in SETS for a in ("--set", s)]
    return [sys.executable, "-m", "dancekit.cli.main", "train", "revolution", "--data", str(data), "--out",
            str(out), "--quiet", *sets, *extra]


def _losses(run: Path) -> dict[int, float]:
    return {r["step"]: r["loss"] for r in map(json.loads, (run / "log.jsonl").read_text().splitlines())
            if "loss" in r}


@pytest.mark.slow
def test_sigkill_mid_epoch_then_resume_matches_uninterrupted_run(tmp_path, rng):
    data = write_fake_prepared(tmp_path / "prepared", rng, dim=8)
    env = {**os.environ, "OMP_NUM_THREADS": "1",
           "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    assert main(_cmd(data, straight)[3:]) == 0  # the uninterrupted run, in this process (one thread, as the others)

    proc = subprocess.Popen(_cmd(data, killed), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not checkpoints(killed) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)  # as soon as the first checkpoint (step 5, mid-epoch 0) is complete
    assert proc.wait(timeout=30) == -signal.SIGKILL
    last = checkpoints(killed)[-1]
    at = int(last.name.split("_")[1])
    assert at < STEPS and at % PER_EPOCH != 0, f"not killed mid-epoch ({last.name})"

    subprocess.run(_cmd(data, killed, "--resume"), env=env, check=True, capture_output=True, timeout=120)
    want, got = _losses(straight), _losses(killed)
    assert sorted(got) == sorted(want) == list(range(1, STEPS + 1))
    worst = max(abs(got[s] - want[s]) for s in want)
    assert worst <= 1e-6, f"resumed losses differ by up to {worst:.3g}"
    a = load_file(str(straight / "model" / "model.safetensors"))
    b = load_file(str(killed / "model" / "model.safetensors"))
    assert max(float((a[k] - b[k]).abs().max()) for k in a) <= 1e-6
