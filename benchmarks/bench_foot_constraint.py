"""Table 2 analogue: test-split MSE of Foot Constraint Model runs (Music2Dance §4.5).

    PYTHONPATH=src python benchmarks/bench_foot_constraint.py data/tang2018 runs/fc_conv runs/fc_lstm

For each run folder (``dancekit train foot_constraint --out RUN``), the lower-body MSE (normalised columns) on the
test dances in 240-frame windows, with foot sliding simulated as in training (Gaussian smoothing + noise, a
fixed seed), next to the MSE of the sliding input itself (no post-process).
"""

from __future__ import annotations

import sys

import torch

from dancekit.checkpoints import NormStats, load_pretrained
from dancekit.data import PreparedData, WindowDataset
from dancekit.training import StepContext, TrainConfig
from dancekit.training.m2d import foot_constraint_step


def lower_body_mse(data: PreparedData, run: str, *, window: int = 240, seed: int = 123) -> tuple[float, float, int]:
    """(MSE corrected, MSE of the sliding input, windows) of the run's model on the test split."""
    model, _, arrays = load_pretrained(f"{run}/model")
    model.eval()
    model.config.clean_share = 0.0  # every test window slides (the training's clean share is not scored here)
    stats = NormStats(**{k: arrays[k] for k in ("music_mean", "music_std", "dance_mean", "dance_std")})
    ds = WindowDataset(data, "test", preset="music2dance", window=window, stride=window, stats=stats,
                       representation="rotations_rootdelta")
    ctx = StepContext(step=0, epoch=0, training=False, generator=torch.Generator().manual_seed(seed),
                      config=TrainConfig())
    mse = mse_in = 0.0
    with torch.no_grad():
        for i in range(0, len(ds), 16):
            batch = torch.utils.data.default_collate([ds[j] for j in range(i, min(len(ds), i + 16))])
            _, logs = foot_constraint_step(model, batch, ctx)
            mse += logs["mse"] * len(batch["dance"])
            mse_in += logs["mse_input"] * len(batch["dance"])
    return mse / len(ds), mse_in / len(ds), len(ds)


if __name__ == "__main__":
    torch.set_num_threads(1)
    prepared = PreparedData(sys.argv[1])
    for run_dir in sys.argv[2:]:
        corrected, sliding, n = lower_body_mse(prepared, run_dir)
        print(f"{run_dir}: test windows {n}, MSE corrected {corrected:.4f} (sliding input {sliding:.4f})")
