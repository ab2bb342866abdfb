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
    music dropout (``TrainConfig.music_dropout``: a share of the windows trained with the mean music),
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
from dancekit.training.datasets import refuse_augmentations
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


class FootConstraintWindows(Music2DanceWindows):
    """:class:`Music2DanceWindows` whose items also carry the dance statistics ``"dance_mean"`` and
    ``"dance_std"`` ``(P,)``, so that the objective can denormalise for its forward kinematics; ``fps`` and
    ``skeleton`` (its name): the data's frame rate and skeleton (model-config fields)."""

    def __init__(self, windows: WindowDataset, n_genres: int, stats: NormStats):
        n = len(windows)
        super().__init__(windows, np.ones(n, np.float32), n_genres, np.zeros(n, np.int64))
        self.fps, self.skeleton = float(windows.data.fps), windows.data.skeleton.name
        self.dance_mean = torch.as_tensor(np.asarray(stats.dance_mean, np.float32))
        self.dance_std = torch.as_tensor(np.asarray(stats.dance_std, np.float32))

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        item = super().__getitem__(k)
        item["dance_mean"], item["dance_std"] = self.dance_mean, self.dance_std
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
    refuse_augmentations(config, f"{REPRESENTATION} (music2dance, foot_constraint; heading-free by construction)")
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
    return tuple(FootConstraintWindows(w, len(data.genres), stats) for w in (train, val))  # type: ignore[return-value]


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
        if ctx.config.music_dropout > 0:
            # whole windows with the mean music (zeros after normalisation): the dance type is then the only
            # style cue, so the model cannot learn to ignore it (genre steering, docs/research/gpu-round.md)
            keep = torch.rand(music.shape[0], generator=g, device=g.device) >= ctx.config.music_dropout
            music = music * keep.to(music.device, music.dtype)[:, None, None]
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


def _kinematics(c, batch: Mapping[str, torch.Tensor], x: torch.Tensor):
    """(skeleton, denormalise, feet joints, index of the toes among them) for the contact terms."""
    from dancekit.motion import get_skeleton

    sk = get_skeleton(c.skeleton)
    mean = batch["dance_mean"][0].to(x) if "dance_mean" in batch else torch.zeros(x.shape[-1]).to(x)
    std = batch["dance_std"][0].to(x) if "dance_std" in batch else torch.ones(x.shape[-1]).to(x)
    feet = tuple(sk.index(n) for n in sk.feet)
    toes = (feet.index(sk.index("left_toe")), feet.index(sk.index("right_toe")))
    return sk, (lambda z: z * std + mean), (lambda z: (z - mean) / std), feet, toes


def foot_constraint_step(model: nn.Module, batch: Mapping[str, torch.Tensor],
                         ctx: StepContext) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE + ``smooth_weight`` x acceleration² + ``contact_weight`` x contact velocity² of the Foot Constraint
    Model correcting simulated foot sliding. The MSE is to the clean dance, or with ``mse_target="input"`` to
    the corrupted input (the model then changes only what the contact and swing terms ask for).

    Corruption (in a share ``1 - clean_share`` of the windows; the rest stay clean and their target is the
    identity): ``corruption="glide"`` adds a slow drift to every lower-body column, the root's path included
    (``glide_amp`` x unit-std Gaussian noise smoothed over ``glide_sigma`` frames, normalised units: what the
    generated dances' sliding looks like, ``benchmarks/fcm_sliding.py``), and recomputes the toe end effectors
    from the drifted rotations (forward kinematics), so the input is a consistent dance whose feet slide;
    ``"paper"``: the lower-body and toe columns Gaussian-smoothed (``smooth_sigma``) plus white noise
    (``noise_std``). Validation draws from the trainer's fixed-seed generator, so validation losses compare.

    Contacts: with ``contact_speed > 0`` the contact columns given to the model are detected on the
    corrupted dance (toe ≤ 5 cm over the running floor, slower than ``contact_speed`` m/s: the contacts of
    :func:`dancekit.metrics.foot_skating`, which the pipeline detects on a generated dance, whose sliding feet
    are faster than a planted foot), else the representation's own. The contact-velocity term is
    :func:`~dancekit.models.foot_constraint.contact_velocity_loss` of the corrected dance's toes in world
    coordinates (differentiable forward kinematics, :func:`~dancekit.motion.root_delta.rootdelta_positions`;
    the batch's ``dance_mean`` / ``dance_std`` denormalise) on the clean dance's own contact columns (planted
    toes: slower than 30 cm/s, :data:`~dancekit.motion.root_delta.CONTACT_SPEED_CM_S`).

    With ``swing_weight > 0`` it adds ``swing_weight`` x :func:`~dancekit.models.foot_constraint.swing_speed_loss`
    of the knees, ankles, heels and toes (world, differentiable FK) against the clean dance's on the steps off
    its toe contacts: the term that keeps the legs moving outside contacts (logged as ``swing_short2``).

    Logs ``mse`` (the corrected lower body), ``mse_input`` (the corrupted one), ``contact_v2`` and, in
    validation, ``contact_v2_input`` ((m/s)² of the toes on contacts, corrected and corrupted).
    """
    from dancekit.models.foot_constraint import (
        contact_velocity_loss,
        detect_contacts,
        swing_speed_loss,
        unit_smooth_noise,
    )
    from dancekit.motion.root_delta import rootdelta_positions

    c = model.config
    x = batch["dance"]
    lower, toe_cols, contact_cols = list(c.lower_idx), list(c.foot_idx), list(c.contact_idx)
    g = ctx.generator
    slide = (torch.rand(x.shape[0], generator=g, device=g.device) >= c.clean_share).to(x)[:, None, None]  # (B,1,1)
    corrupted = x.clone()
    sk, denorm, norm, feet, toes = _kinematics(c, batch, x)
    scale = sk.unit_scale
    detect = dict(fps=c.fps, unit_scale=scale, speed_m_s=c.contact_speed)
    if c.corruption == "paper":
        cols = lower + toe_cols
        noise = torch.randn(x[..., cols].shape, generator=g, device=g.device).to(x)
        sliding = gaussian_smooth(x[..., cols], c.smooth_sigma) + c.noise_std * noise
        corrupted[..., cols] = slide * sliding + (1 - slide) * x[..., cols]
    else:
        drift = unit_smooth_noise(x[..., lower].shape, c.glide_sigma, generator=g, dtype=x.dtype).to(x)
        corrupted[..., lower] = x[..., lower] + slide * c.glide_amp * drift
    target_contacts = x[..., contact_cols]  # the representation's own: planted (slower than 30 cm/s)
    if c.corruption == "glide" or c.contact_speed > 0:
        with torch.no_grad():  # one forward kinematics of the corrupted dance: its toes and feet
            full = denorm(corrupted)
            p = rootdelta_positions(full, sk, joints=(sk.root,) + feet)  # (B, T, 1 + F, 3) window frame
            if c.corruption == "glide":  # toe end effectors of the drifted rotations: root-relative, heading frame
                heading = torch.cumsum(torch.cat([torch.zeros_like(full[:, :1, 3]), full[:, 1:, 3]], 1), 1)
                rel = p[:, :, [1 + t for t in toes]] - p[:, :, :1]  # (B, T, 2, 3)
                cs, sn = torch.cos(heading)[..., None], torch.sin(heading)[..., None]
                rel = torch.stack([cs * rel[..., 0] - sn * rel[..., 2], rel[..., 1], sn * rel[..., 0] + cs * rel[..., 2]], -1)
                full[..., toe_cols] = rel.flatten(-2)
            if c.contact_speed > 0:  # what the pipeline detects on a generated dance
                full[..., contact_cols] = detect_contacts(p[:, :, 1:], toes, **detect)
            corrupted[..., toe_cols + contact_cols] = norm(full)[..., toe_cols + contact_cols]
    out = model(corrupted)
    pred = out[..., lower]  # (B, T, lower)
    target = x[..., lower]
    mse = F.mse_loss(pred, target)
    if c.mse_target == "input":  # keep the input except where the contact term asks (logs still compare to clean)
        fit = F.mse_loss(pred, corrupted[..., lower])
    else:
        fit = mse
    accel = pred[:, 2:] - 2 * pred[:, 1:-1] + pred[:, :-2]
    loss = fit + c.smooth_weight * accel.pow(2).mean()
    logs = {"mse": float(mse.detach()), "mse_input": float(F.mse_loss(corrupted[..., lower], target))}
    if c.contact_weight > 0 or not ctx.training:  # validation logs it for every model
        toe_joints = (sk.index("left_toe"), sk.index("right_toe"))
        v2 = contact_velocity_loss(rootdelta_positions(denorm(out), sk, joints=toe_joints) * scale,
                                   target_contacts, fps=c.fps)
        loss = loss + c.contact_weight * v2
        logs["contact_v2"] = float(v2.detach())
    if c.swing_weight > 0 or not ctx.training:  # the legs kept moving off contact
        sides = [[sk.index(f"{side}_{j}") for j in ("knee", "ankle", "heel", "toe")] for side in ("left", "right")]
        legs = [j for side in sides for j in side]
        shape = (*x.shape[:2], 2, len(sides[0]), 3)
        moved = rootdelta_positions(denorm(out), sk, joints=tuple(legs)).reshape(shape) * scale
        with torch.no_grad():
            clean = rootdelta_positions(denorm(x), sk, joints=tuple(legs)).reshape(shape) * scale
        short = swing_speed_loss(moved, clean, target_contacts, fps=c.fps)
        loss = loss + c.swing_weight * short
        logs["swing_short2"] = float(short.detach())
        if not ctx.training:
            with torch.no_grad():
                logs["contact_v2_input"] = float(contact_velocity_loss(
                    rootdelta_positions(denorm(corrupted), sk, joints=toe_joints) * scale, target_contacts, fps=c.fps))
    return loss, logs
