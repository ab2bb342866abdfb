"""Table 2 analogue: test-split MSE of Foot Constraint Model runs (Music2Dance §4.5).

    PYTHONPATH=src python benchmarks/bench_foot_constraint.py data/tang2018 runs/fc_conv runs/fc_lstm

For each run folder (``dancekit train foot_constraint --out RUN``), the lower-body MSE (normalised columns) on the
test dances in 240-frame windows, with foot sliding simulated as in training (a fixed seed), next to the MSE of
the sliding input itself (no post-process), and the contact velocity² ((m/s)² of the toes on the real dance's
planted frames, ``contact_velocity_loss``) after and before. Every run is scored with the corruption and contact
settings of the FIRST run (``corruption``, ``glide_amp``, ``glide_sigma``, ``noise_std``, ``smooth_sigma``,
``contact_speed``), so the rows compare.
"""

from __future__ import annotations

import sys

import torch

from dancekit.checkpoints import NormStats, load_pretrained
from dancekit.data import PreparedData, WindowDataset
from dancekit.training import StepContext, TrainConfig
from dancekit.training.m2d import foot_constraint_step

SHARED = ("corruption", "glide_amp", "glide_sigma", "noise_std", "smooth_sigma", "contact_speed")


def lower_body_mse(data: PreparedData, run: str, *, window: int = 240, seed: int = 123,
                   like: dict | None = None) -> tuple[float, float, float, float, int]:
    """(MSE corrected, MSE of the sliding input, contact v² corrected, contact v² input, windows) of the run's
    model on the test split; ``like``: corruption settings to use instead of the run's own."""
    model, _, arrays = load_pretrained(f"{run}/model")
    model.eval()
    model.config.clean_share = 0.0  # every test window slides (the training's clean share is not scored here)
    for k, v in (like or {}).items():
        setattr(model.config, k, v)
    stats = NormStats(**{k: arrays[k] for k in ("music_mean", "music_std", "dance_mean", "dance_std")})
    ds = WindowDataset(data, "test", preset="music2dance", window=window, stride=window, stats=stats,
                       representation="rotations_rootdelta")
    ctx = StepContext(step=0, epoch=0, training=False, generator=torch.Generator().manual_seed(seed),
                      config=TrainConfig())
    sums = dict.fromkeys(("mse", "mse_input", "contact_v2", "contact_v2_input"), 0.0)
    with torch.no_grad():
        for i in range(0, len(ds), 16):
            batch = torch.utils.data.default_collate([ds[j] for j in range(i, min(len(ds), i + 16))])
            batch["dance_mean"] = torch.from_numpy(stats.dance_mean)[None]
            batch["dance_std"] = torch.from_numpy(stats.dance_std)[None]
            _, logs = foot_constraint_step(model, batch, ctx)
            for k in sums:
                sums[k] += logs[k] * len(batch["dance"])
    return (*(sums[k] / len(ds) for k in sums), len(ds))


if __name__ == "__main__":
    torch.set_num_threads(1)
    prepared = PreparedData(sys.argv[1])
    first = load_pretrained(f"{sys.argv[2]}/model")[0].config
    like = {k: getattr(first, k) for k in SHARED}
    print(f"corruption of {sys.argv[2]}: {like}")
    for run_dir in sys.argv[2:]:
        corrected, sliding, v2, v2_in, n = lower_body_mse(prepared, run_dir, like=like)
        print(f"{run_dir}: test windows {n}, MSE corrected {corrected:.4f} (sliding input {sliding:.4f}), "
              f"contact v² {v2:.4f} (sliding input {v2_in:.4f}) (m/s)²")
