"""Per-family training objectives: ``step_fn(model, batch, ctx) -> (loss, logs)`` for :func:`train`.

A step function maps a collated batch to the scalar loss, reading what it needs from the
:class:`~dancekit.training.loop.StepContext` (step, epoch, the training configuration, a generator).
A family names its objective in :mod:`dancekit.registry` (``objective="dancekit.training.objectives:..."``).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import nn

from dancekit.training.loop import StepContext
from dancekit.training.schedules import auto_condition_p


def revolution_p(model: nn.Module, ctx: StepContext) -> int:
    """``p`` of the decoder input for a Dance Revolution model.

    Training: the curriculum of ``ctx.config`` at ``ctx.epoch`` (always 0, teacher forcing, for the LSTM
    baseline). Validation: the fixed ``ctx.config.val_p`` for every model, so that validation losses
    compare across steps, runs and curricula (with the growing training ``p`` they would not).
    """
    if not ctx.training:
        return ctx.config.val_p
    if getattr(model.config, "baseline", False):
        return 0
    c = ctx.config
    return auto_condition_p(ctx.epoch, kind=c.curriculum, lam=c.curriculum_lambda, p_const=c.curriculum_p,
                            p_max=c.curriculum_p_max)


def revolution_step(
    model: nn.Module, batch: Mapping[str, torch.Tensor], ctx: StepContext
) -> tuple[torch.Tensor, dict[str, float]]:
    """L1 loss (Eq. 5) of a Dance Revolution model under the dynamic auto-condition.

    ``batch``: ``{"music": (B, L, D), "dance": (B, L, P), ...}`` normalised windows (a collated
    :class:`~dancekit.data.WindowDataset`). ``p`` from :func:`revolution_p`; ``q = ctx.config.curriculum_q``.
    """
    p = revolution_p(model, ctx)
    genre = None
    n_genres = getattr(model.config, "n_genres", 0)
    if n_genres and "genre" in batch:
        # genre dropout: a share of the windows is trained as "auto" so the model also dances
        # without a genre, from the music alone (validation: always auto, i.e. music only)
        genre = batch["genre"].clone()
        if ctx.training:
            drop = torch.rand(genre.shape, generator=ctx.generator, device=ctx.generator.device) < ctx.config.genre_dropout
            genre[drop.to(genre.device)] = -1
        else:
            genre[:] = -1
    music = batch["music"]
    if ctx.training and ctx.config.music_dropout > 0:
        # music dropout: some windows see the mean music (zeros after normalisation), so the decoder
        # must also dance from its own motion prior (e.g. a genre model keeps its genre on new songs)
        keep = torch.rand(music.shape[0], generator=ctx.generator, device=ctx.generator.device) >= ctx.config.music_dropout
        music = music * keep.to(music.device, music.dtype)[:, None, None]
    _, loss = model(music, batch["dance"], schedule_p=p, schedule_q=ctx.config.curriculum_q,
                    generator=ctx.generator, genre=genre)
    return loss, {"p": p}


def music_attributes_step(
    model: nn.Module, batch: Mapping[str, torch.Tensor], ctx: StepContext
) -> tuple[torch.Tensor, dict[str, float]]:
    """Cross-entropy of a music attribute classifier: ``batch["music"]`` (B, L, D) → ``batch["genre"]`` (B,).

    Logs the batch accuracy as ``acc``. Class balance comes from the data (``balance_genres``).
    """
    logits = model(batch["music"])  # (B, n_classes)
    loss = torch.nn.functional.cross_entropy(logits, batch["genre"])
    acc = (logits.argmax(-1) == batch["genre"]).float().mean().item()
    return loss, {"acc": acc}


def style_step(
    model: nn.Module, batch: Mapping[str, torch.Tensor], ctx: StepContext
) -> tuple[torch.Tensor, dict[str, float]]:
    """Class-weighted cross-entropy of a style classifier: ``batch["x"]`` (B, L, D) normalised
    :func:`~dancekit.models.style.style_input` windows → ``batch["y"]`` (B,) genre indices.

    Logs the batch accuracy as ``acc``. The class weights are the model's (``config.class_weights``).
    """
    logits, loss = model(batch["x"], batch["y"])  # (B, G), scalar
    acc = float((logits.argmax(-1) == batch["y"]).float().mean())
    return loss, {"acc": round(acc, 4)}


def dual_step(
    model: nn.Module, batch: Mapping[str, torch.Tensor], ctx: StepContext
) -> tuple[torch.Tensor, dict[str, float]]:
    """All losses of the dual-learning model (MM 2021 §3.4) on a batch of :func:`~dancekit.training.datasets.dual_windows`.

    ``batch``: ``{"music": (B, T, 53), "dance": (B, T, P), ...}`` with the chroma + beat and 6D columns raw.
    The model routes each loss to its generator (:class:`~dancekit.models.dual.DualModel`); this logs each
    part. In training, the windows' first poses join the model's start-pose pool (sampled at inference).
    """
    if ctx.training:
        model.remember_start_poses(batch["dance"])
    loss, parts = model(batch["music"], batch["dance"])
    return loss, {name: float(value.detach()) for name, value in parts.items()}
