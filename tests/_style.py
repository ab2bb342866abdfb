"""Train a tiny style classifier on in-memory dances through the generic loop (family "style"), for tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def fit_tiny_style_classifier(train: list[tuple[np.ndarray, int]], val: list[tuple[np.ndarray, int]], *,
                              skeleton, fps: float, genres: list[str], out_dir: Path, window: int, stride: int,
                              epochs: int = 4, batch_size: int = 16, channels: int = 16, feature_dim: int = 8):
    """Windows (:func:`style_window_sets`), :func:`dancekit.training.train` with :func:`style_step` for
    ``epochs`` passes, and the run's ``best/`` (lowest validation loss) loaded as a :class:`StylePipeline`."""
    from dancekit.models.style import StyleClassifier, StyleClassifierConfig
    from dancekit.pipelines import StylePipeline
    from dancekit.training import TrainConfig
    from dancekit.training import train as run_training
    from dancekit.training.datasets import style_window_sets
    from dancekit.training.loop import seed_everything
    from dancekit.training.objectives import style_step

    train_set, val_set = style_window_sets(train, val, skeleton=skeleton, fps=fps, genres=genres, window=window,
                                           stride=stride)
    config = StyleClassifierConfig(in_dim=train_set.in_dim, genres=genres, window=window, fps=fps, channels=channels,
                                   feature_dim=feature_dim, class_weights=train_set.class_weights)
    seed_everything(0)
    model = StyleClassifier(config)
    spe = max(1, len(train_set) // batch_size)
    tc = TrainConfig(steps=epochs * spe, batch_size=batch_size, lr=2e-3, warmup_steps=min(50, spe), weight_decay=1e-4,
                     log_every=spe, val_every=spe, ckpt_every=epochs * spe, keep_checkpoints=1, threads=1,
                     seq_len=window, stride=stride, random_offset=False)
    run_training(model, train_set, val_set if len(val_set) else None, tc, step_fn=style_step, out_dir=out_dir,
          stats=train_set.stats, meta={"skeleton": skeleton.to_dict(), "fps": fps, "genres": genres},
          progress=False)
    return StylePipeline.from_pretrained(out_dir / ("best" if (out_dir / "best").is_dir() else "model"))
