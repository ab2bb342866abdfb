"""Music2Dance training (supplement §1.2): the windows (with motion clustering) and the objective.

``music2dance_windows`` is the family's dataset builder and ``music2dance_step`` its objective for the
generic trainer (:func:`dancekit.training.train`); both are named in :mod:`dancekit.registry`.

Windows
    Paired (music, dance) windows of ``config.seq_len`` frames (:class:`~dancekit.data.WindowDataset`) in the
    ``rotations_rootdelta`` representation. The two contact columns are not normalised: the builder sets
    their mean to 0 and their standard deviation to 1 in ``stats`` (which the checkpoint then saves), so
    they stay 0/1 for the BCE loss and the pipeline decodes every column alike.
Motion clustering (§1.2.2)
    k-means (``CLUSTERS`` = 8 clusters) over the training windows' joint positions (not rotations: every
    joint relative to the root, in the root's heading frame, every 4th frame). Each window carries a weight
    ``N / (K · n_c)`` (``n_c``: its cluster's size; mean 1) and the objective weights its loss by it when
    the model's ``cluster_balance`` is on (:class:`~dancekit.models.music2dance.Music2DanceConfig`), so each
    cluster counts as much as any other. The paper samples windows by cluster probability instead; the
    weighted loss has the same expected gradient and needs no sampler in the generic trainer.
Objective
    Gaussian noise on the input motion (``input_noise``) and the targets (``target_noise``) in training,
    genre dropout (``TrainConfig.genre_dropout``: a share of the windows trained without a dance type),
    and the two phases: phase 1 feeds the ground truth, phase 2 (``phase=2``, e.g. ``dancekit train
    music2dance --init RUN1/model --set phase=2``) first predicts every frame from the ground truth
    (the means of the mixture, no gradient) and then feeds those predictions back as the input.
    F_map is initialised from ``fmap_checkpoint`` (a ``music_attributes`` checkpoint) on the first step.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from torch.utils.data import Dataset

from dancekit.checkpoints.stats import NormStats
from dancekit.data import PreparedData, WindowDataset
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.foot_constraint import gaussian_smooth
from dancekit.models.music2dance import Music2DanceModel, shift_right
from dancekit.motion.root_delta import lower_body_cols, rootdelta_layout
from dancekit.training.loop import StepContext, TrainConfig

CLUSTERS = 8  # k of the motion clustering
CLUSTER_FRAME_STEP = 4  # every 4th frame of a window enters its clustering feature
REPRESENTATION = "rotations_rootdelta"


class Music2DanceWindows(Dataset):
    """A :class:`~dancekit.data.WindowDataset` whose items also carry ``"weight"`` (the cluster weight).

    Attributes the trainer reads as model-config fields: ``music_dim``, ``pose_dim``, ``n_genres`` (the
    WaveNet) and ``lower_idx``, ``foot_idx``, ``contact_idx`` (the Foot Constraint Model).
    """

    def __init__(self, windows: WindowDataset, weights: np.ndarray, n_genres: int, clusters: np.ndarray):
        self.windows, self.weights, self.n_genres, self.clusters = windows, weights, int(n_genres), clusters
        skeleton = windows.data.skeleton
        lay = rootdelta_layout(skeleton)
        self.lower_idx, self.foot_idx, self.contact_idx = lower_body_cols(skeleton), lay.toe_cols, lay.contact_cols

    music_dim = property(lambda self: self.windows.music_dim)
    pose_dim = property(lambda self: self.windows.pose_dim)

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        item = self.windows[k]
        item["weight"] = torch.tensor(float(self.weights[k]), dtype=torch.float32)
        return item


def _window_features(data: PreparedData, windows: WindowDataset) -> np.ndarray:
    """Clustering features ``(N, F)``: joint positions relative to the root in its heading frame."""
    feats, cache = [], {}
    for i, s in windows.index:
        name = windows.names[i]
        if name not in cache:
            m = data.motion(name)
            p = np.asarray(m.to_positions(), np.float64)  # (T, J, 3)
            R = m.rotations if m.rotations is not None else None
            if R is not None:
                a = np.arctan2(R[:, m.skeleton.root, 0, 2], R[:, m.skeleton.root, 2, 2])  # heading (YXZ)
            else:
                a = np.zeros(len(p))
            rel = p - p[:, m.skeleton.root : m.skeleton.root + 1]
            c, sn = np.cos(a)[:, None], np.sin(a)[:, None]
            local = np.stack([c * rel[..., 0] - sn * rel[..., 2], rel[..., 1], sn * rel[..., 0] + c * rel[..., 2]], -1)
            cache[name] = local
        feats.append(cache[name][s : s + windows.window : CLUSTER_FRAME_STEP].reshape(-1))
    return np.asarray(feats, np.float32)


def cluster_weights(features: np.ndarray, *, k: int = CLUSTERS, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """k-means labels ``(N,)`` of the windows' features and the balancing weights ``N / (K · n_c)`` ``(N,)``."""
    n = len(features)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.float32)
    k = max(1, min(int(k), n))
    from sklearn.cluster import KMeans

    labels = KMeans(n_clusters=k, n_init=3, random_state=seed).fit_predict(features)
    counts = np.bincount(labels, minlength=k)
    used = int((counts > 0).sum())
    weights = n / (used * counts[labels])
    return labels.astype(np.int64), weights.astype(np.float32)


def _rootdelta_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                       preset: str) -> tuple[WindowDataset, WindowDataset]:
    if config.representation != REPRESENTATION:
        raise ParameterError(f"music2dance trains on the {REPRESENTATION!r} representation, not "
                             f"{config.representation!r} (leave TrainConfig.representation at the family default)")
    lay = rootdelta_layout(data.skeleton)
    if len(stats.dance_mean) != lay.dim:
        raise ParameterError(f"dance statistics have {len(stats.dance_mean)} columns, {REPRESENTATION} has {lay.dim}")
    contacts = list(lay.contact_cols)
    stats.dance_mean[contacts] = 0.0  # contacts stay 0/1 (see the module docstring)
    stats.dance_std[contacts] = 1.0
    common = dict(preset=preset, window=config.seq_len, stride=config.stride, stats=stats,
                  representation=config.representation, genres=config.genres)
    train = WindowDataset(data, "train", random_offset=config.random_offset, seed=config.seed,
                          balance_genres=config.balance_genres, **common)
    return train, WindowDataset(data, "val", **common)


def _plain(windows: WindowDataset, n_genres: int) -> Music2DanceWindows:
    return Music2DanceWindows(windows, np.ones(len(windows), np.float32), n_genres, np.zeros(len(windows), np.int64))


def music2dance_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                        preset: str) -> tuple[Music2DanceWindows, Music2DanceWindows]:
    """(train, val) windows of ``config.seq_len`` frames in ``rotations_rootdelta``, raw 0/1 contacts,
    cluster weights on the training windows (validation windows weigh 1)."""
    train, val = _rootdelta_windows(data, config, stats, preset=preset)
    labels, weights = cluster_weights(_window_features(data, train), seed=config.seed)
    n_genres = len(data.genres)
    return Music2DanceWindows(train, weights, n_genres, labels), _plain(val, n_genres)


def foot_constraint_windows(data: PreparedData, config: TrainConfig, stats: NormStats, *,
                            preset: str) -> tuple[Music2DanceWindows, Music2DanceWindows]:
    """(train, val) ground-truth windows for the Foot Constraint Model (as :func:`music2dance_windows`,
    without clustering; the music is not used)."""
    train, val = _rootdelta_windows(data, config, stats, preset=preset)
    return _plain(train, len(data.genres)), _plain(val, len(data.genres))


def load_fmap(model: Music2DanceModel, folder: str) -> None:
    """Initialise the model's F_map from the trunk of the ``music_attributes`` checkpoint ``folder``."""
    from dancekit.checkpoints import load_pretrained

    classifier, meta, _ = load_pretrained(folder)
    if meta.get("model") != "music_attributes":
        raise CheckpointError(f"fmap_checkpoint {folder} holds a {meta.get('model')!r} model, not music_attributes")
    if model.fmap is None:
        raise ParameterError("fmap_checkpoint is set but music_condition is 'raw' (no F_map to initialise)")
    try:
        model.fmap.load_classifier(classifier.state_dict())
    except RuntimeError as exc:
        raise CheckpointError(f"fmap_checkpoint {folder} does not fit the model's F_map settings: {exc}") from None
    model.fmap_loaded.fill_(1)


def music2dance_step(model: nn.Module, batch: Mapping[str, torch.Tensor],
                     ctx: StepContext) -> tuple[torch.Tensor, dict[str, float]]:
    """``(L_gmm + λ · BCE) / D`` of a Music2Dance model on a batch of :func:`music2dance_windows` (see the
    module docstring for noise, genre dropout, the two phases and the cluster weights)."""
    c = model.config
    if c.fmap_checkpoint and not int(model.fmap_loaded):
        load_fmap(model, c.fmap_checkpoint)
    music, dance = batch["music"], batch["dance"]
    D = c.gmm_dim
    genre = batch["genre"].clone() if "genre" in batch and c.n_genres else None
    inputs, target = dance, dance
    if ctx.training:
        g = ctx.generator
        if genre is not None and ctx.config.genre_dropout > 0:
            drop = torch.rand(genre.shape, generator=g, device=g.device) < ctx.config.genre_dropout
            genre[drop.to(genre.device)] = -1
        if c.input_noise > 0:
            noise = torch.randn(dance[..., :D].shape, generator=g, device=g.device).to(dance)
            inputs = torch.cat([dance[..., :D] + c.input_noise * noise, dance[..., D:]], -1)
        if c.target_noise > 0:
            noise = torch.randn(dance[..., :D].shape, generator=g, device=g.device).to(dance)
            target = torch.cat([dance[..., :D] + c.target_noise * noise, dance[..., D:]], -1)
    prev = shift_right(inputs)
    if c.phase == 2:
        with torch.no_grad():
            first = model.predict(model(music, prev, genre), temperature=0.0)  # (B, T, P) one-step predictions
        prev = shift_right(first)
    weights = batch.get("weight") if c.cluster_balance else None
    params = model(music, prev, genre)
    loss, logs = model.loss(params, target, weights=weights if ctx.training else None)
    return loss, logs


def foot_constraint_step(model: nn.Module, batch: Mapping[str, torch.Tensor],
                         ctx: StepContext) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE + ``smooth_weight`` x acceleration² of the Foot Constraint Model correcting simulated foot sliding.

    The lower-body and toe columns of the ground-truth windows are smoothed (Gaussian, ``smooth_sigma``
    frames) and get Gaussian noise (``noise_std``; validation draws it from the trainer's fixed-seed
    generator, so validation losses compare), except in a share ``clean_share`` of the windows, which stay
    clean; the target is the clean lower body. Logs ``mse`` (the
    corrected lower body) and ``mse_input`` (the corrupted one: what the model starts from).
    """
    c = model.config
    x = batch["dance"]
    lower, cols = list(c.lower_idx), list(c.lower_idx) + list(c.foot_idx)
    g = ctx.generator
    noise = torch.randn(x[..., cols].shape, generator=g, device=g.device).to(x)
    slide = (torch.rand(x.shape[0], generator=g, device=g.device) >= c.clean_share).to(x)[:, None, None]  # (B,1,1)
    corrupted = x.clone()
    sliding = gaussian_smooth(x[..., cols], c.smooth_sigma) + c.noise_std * noise
    corrupted[..., cols] = slide * sliding + (1 - slide) * x[..., cols]
    pred = model(corrupted)[..., lower]  # (B, T, lower)
    target = x[..., lower]
    mse = F.mse_loss(pred, target)
    accel = pred[:, 2:] - 2 * pred[:, 1:-1] + pred[:, :-2]
    loss = mse + c.smooth_weight * accel.pow(2).mean()
    return loss, {"mse": float(mse.detach()), "mse_input": float(F.mse_loss(corrupted[..., lower], target))}
