"""Style (genre) classifier and the metrics built on its features (Dance Revolution Table 2).

The classifier recognises the genre of a dance from motion alone. Its penultimate
activations are the feature space of the Dance Revolution metrics:

* **FID** — Fréchet distance between the window features of the generated dances and of
  the real dances (classifier features are used as they are, not z-scored);
* **ACC** — share of generated dances classified as the genre of their music (a dance's
  genre: the mean log-probability over its windows);
* **Diversity** — mean feature distance over random pairs of generated dances for
  *different* music (Lee et al. 2019; Dance Revolution samples 500 pairs);
* **Multimodality** — mean feature distance among the dances generated for the *same* music
  (5 per song in the paper), averaged over songs.

A dance's feature vector is the mean of its window features.

Input representation (per frame, at the classifier's fps)
    Every joint relative to the pelvis, rotated about the up axis into the body's heading
    frame (x = the body's left, from the hip and shoulder lines; y = up; z = forward), in
    metres (3J); their velocities in m/s (3J); the root velocity in the heading frame (m/s, 3)
    and the yaw rate (rad/s, 1): ``6J + 4`` values (142 for tang2018), standardised with the
    training statistics (``stats.npz``: ``input_mean``, ``input_std``). Motion at another fps
    is resampled linearly to the classifier's fps.

Network
    Three 1-D convolutions over time (kernel 5; the last two with stride 2), GELU, a mean over
    time, a linear layer to ``feature_dim`` (the features), dropout and a linear layer to the
    genres. Windows of ``window`` frames (4 s) are cut every 0.5 s from the training dances,
    plus their mirror images; the loss is class-weighted cross-entropy (weights inversely
    proportional to each genre's window count: tang2018 has 26 waltzes and one tango).

Checkpoints are the project's self-describing folders (``config.json`` +
``model.safetensors`` + ``stats.npz``, :mod:`dancekit.checkpoints`, family
``"style"``); ``config.json`` also records the skeleton, fps, genres and the test scores.
A trained classifier ships in ``dancekit/assets/models/style/``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancekit._io import atomic_path
from dancekit.errors import CheckpointError, ParameterError
from dancekit.metrics._common import check_fps, check_positions, root_index, to_metres
from dancekit.metrics.fid import average_pairwise_distance, frechet_distance
from dancekit.motion.analysis import heading_axes as _heading_axes
from dancekit.motion.analysis import horizontal_axes, resample_positions

if TYPE_CHECKING:  # pragma: no cover
    from dancekit.motion import Skeleton

__all__ = [
    "DEFAULT_CLASSIFIER",
    "StyleClassifier",
    "StyleClassifierConfig",
    "StyleModel",
    "balanced_accuracy",
    "evaluate_classifier",
    "fit_style_classifier",
    "load_style_classifier",
    "multimodality",
    "style_diversity",
    "style_fid",
    "style_input",
    "train_style_classifier",
]

#: The classifier shipped with the package.
DEFAULT_CLASSIFIER = Path(__file__).resolve().parents[1] / "assets" / "models" / "style"
FAMILY = "style"


# ---------------------------------------------------------------------------------------------
# input representation


def style_input(positions: np.ndarray, *, fps: float, skeleton: Skeleton) -> np.ndarray:
    """Per-frame classifier input ``(T, 6J + 4)`` float32 (unnormalised; see the module docstring)."""
    fps = check_fps(fps)
    p = to_metres(check_positions(positions, skeleton, min_frames=2), skeleton)
    lateral, ups, forward = _heading_axes(p, skeleton)
    R = np.stack([lateral, ups, forward], axis=1)  # (T, 3, 3): world -> body rows
    root = p[:, root_index(skeleton)]
    local = np.einsum("tij,tkj->tki", R, p - root[:, None, :])  # (T, J, 3)
    local_v = np.gradient(local, axis=0) * fps
    root_v = np.einsum("tij,tj->ti", R, np.gradient(root, axis=0) * fps)
    # yaw rate: signed angle between consecutive lateral axes about up
    lat_next = np.gradient(lateral, axis=0)
    yaw = np.sum(np.cross(lateral, lat_next) * ups, axis=-1) * fps
    T = len(p)
    out = np.concatenate([local.reshape(T, -1), local_v.reshape(T, -1), root_v, yaw[:, None]], axis=1)
    return out.astype(np.float32)


def _mirror(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Mirror image of a dance: reflect a horizontal axis and swap left and right joints."""
    out = np.array(positions, dtype=np.float64)[:, skeleton.mirror_permutation()]
    out[..., horizontal_axes(skeleton)[0]] *= -1.0
    return out


# ---------------------------------------------------------------------------------------------
# the network


@dataclass
class StyleClassifierConfig:
    """Hyper-parameters of :class:`StyleClassifier` (saved in ``config.json``)."""

    in_dim: int  # D = 6J + 4
    genres: list[str]
    window: int = 100  # frames per window (4 s at 25 fps)
    fps: float = 25.0
    channels: int = 64
    feature_dim: int = 32
    kernel_size: int = 5
    dropout: float = 0.2
    class_weights: list[float] | None = None  # per genre, for the training loss

    def __post_init__(self) -> None:
        if self.in_dim < 1 or self.channels < 1 or self.feature_dim < 1 or self.window < 8:
            raise ParameterError(f"bad StyleClassifierConfig sizes: {self}")
        if len(self.genres) < 2:
            raise ParameterError(f"a style classifier needs at least 2 genres, got {self.genres}")
        if self.class_weights is not None and len(self.class_weights) != len(self.genres):
            raise ParameterError("class_weights must have one weight per genre")


class StyleClassifier(nn.Module):
    """1-D convolutional genre classifier over windows ``(B, L, D)`` of normalised inputs."""

    family: ClassVar[str] = FAMILY

    def __init__(self, config: StyleClassifierConfig):
        super().__init__()
        self.config = config
        c, k = config.channels, config.kernel_size
        self.convs = nn.ModuleList(
            [
                nn.Conv1d(config.in_dim, c, k, padding=k // 2),
                nn.Conv1d(c, c, k, stride=2, padding=k // 2),
                nn.Conv1d(c, c, k, stride=2, padding=k // 2),
            ]
        )
        self.proj = nn.Linear(c, config.feature_dim)
        self.drop = nn.Dropout(config.dropout)
        self.head = nn.Linear(config.feature_dim, len(config.genres))
        weights = config.class_weights or [1.0] * len(config.genres)
        self.register_buffer("class_weights", torch.tensor(weights, dtype=torch.float32), persistent=False)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Penultimate features ``(B, feature_dim)`` of windows ``x (B, L, D)``."""
        h = x.transpose(1, 2)  # (B, D, L)
        for conv in self.convs:
            h = F.gelu(conv(h))  # (B, C, L')
        h = h.mean(dim=2)  # (B, C)
        return F.gelu(self.proj(h))  # (B, F)

    def forward(
        self, x: torch.Tensor, targets: torch.Tensor | None = None
    ) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """Logits ``(B, G)``; with ``targets (B,)`` also the class-weighted cross-entropy."""
        logits = self.head(self.drop(self.features(x)))  # (B, G)
        if targets is None:
            return logits
        return logits, F.cross_entropy(logits, targets, weight=self.class_weights)


# ---------------------------------------------------------------------------------------------
# inference wrapper


class StyleModel:
    """A trained classifier with its input statistics, skeleton and frame rate.

    Use :func:`load_style_classifier` to read one from a checkpoint folder.
    """

    def __init__(self, model: StyleClassifier, *, skeleton: Skeleton, mean: np.ndarray, std: np.ndarray,
                 meta: dict | None = None):
        self.model = model.eval()
        self.config = model.config
        self.skeleton = skeleton
        self.mean = np.asarray(mean, np.float32)
        self.std = np.asarray(std, np.float32)
        self.meta = dict(meta or {})
        if self.mean.shape != (self.config.in_dim,) or self.std.shape != (self.config.in_dim,):
            raise CheckpointError(f"style classifier statistics must have {self.config.in_dim} values")

    @property
    def genres(self) -> list[str]:
        return list(self.config.genres)

    @property
    def fps(self) -> float:
        return float(self.config.fps)

    @property
    def window(self) -> int:
        return int(self.config.window)

    def check_skeleton(self, skeleton: Skeleton) -> None:
        """Raise :class:`ParameterError` unless ``skeleton`` has the classifier's joints."""
        if tuple(skeleton.joint_names) != tuple(self.skeleton.joint_names):
            raise ParameterError(
                f"the style classifier was trained on skeleton {self.skeleton.name!r} "
                f"({self.skeleton.num_joints} joints); this dance uses {skeleton.name!r} ({skeleton.num_joints})"
            )

    def windows(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None,
                stride: int | None = None) -> np.ndarray:
        """Normalised consecutive windows ``(K, L, D)`` of one dance.

        Windows are ``window`` frames long at the classifier's fps and start every ``stride``
        frames (default: ``window``, i.e. non-overlapping); a dance shorter than one window
        (but at least 1 s long) is a single shorter window.
        """
        skeleton = skeleton or self.skeleton
        self.check_skeleton(skeleton)
        fps = check_fps(fps)
        p = resample_positions(check_positions(positions, skeleton, min_frames=2), orig_fps=fps, target_fps=self.fps)
        x = (style_input(p, fps=self.fps, skeleton=skeleton) - self.mean) / self.std
        L = self.window
        if len(x) < L:
            if len(x) < self.fps:
                raise ParameterError(f"dance too short for the style classifier: {len(x) / self.fps:.2f} s < 1 s")
            return x[None]
        step = int(stride or L)
        return np.stack([x[s : s + L] for s in range(0, len(x) - L + 1, step)])

    @torch.no_grad()
    def embed(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None,
              stride: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(features (K, F), log_probs (K, G))`` of the consecutive windows of one dance."""
        w = torch.from_numpy(np.ascontiguousarray(self.windows(positions, fps=fps, skeleton=skeleton,
                                                               stride=stride)))
        feats, logp = [], []
        for chunk in torch.split(w, 256):
            f = self.model.features(chunk)
            feats.append(f)
            logp.append(F.log_softmax(self.model.head(f), dim=-1))
        return torch.cat(feats).numpy().astype(np.float64), torch.cat(logp).numpy().astype(np.float64)

    def predict(self, positions: np.ndarray, *, fps: float, skeleton: Skeleton | None = None) -> int:
        """Genre index of a whole dance: argmax of the mean window log-probability."""
        _, logp = self.embed(positions, fps=fps, skeleton=skeleton)
        return int(np.argmax(logp.mean(axis=0)))


def load_style_classifier(path: str | os.PathLike | None = None) -> StyleModel:
    """Read a style classifier checkpoint folder (default: the one shipped with dancekit).

    Raises
    ------
    CheckpointError
        If the folder is missing, incomplete or not a style classifier.
    """
    from dancekit.checkpoints import load_pretrained
    from dancekit.motion import Skeleton

    folder = Path(path) if path is not None else DEFAULT_CLASSIFIER
    model, meta, stats = load_pretrained(folder)
    if meta.get("model") != FAMILY:
        raise CheckpointError(f"{folder} is a {meta.get('model')!r} checkpoint, not a style classifier")
    for key in ("input_mean", "input_std"):
        if key not in stats:
            raise CheckpointError(f"{folder}/stats.npz has no {key!r}")
    if "skeleton" not in meta:
        raise CheckpointError(f"{folder}/config.json has no skeleton")
    skeleton = Skeleton.from_dict(meta["skeleton"])
    return StyleModel(model, skeleton=skeleton, mean=stats["input_mean"], std=stats["input_std"], meta=meta)


# ---------------------------------------------------------------------------------------------
# training


class _Windows(torch.utils.data.Dataset):
    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.x = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))
        self.y = torch.from_numpy(np.asarray(y, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.y)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return {"x": self.x[i], "y": self.y[i]}


def _style_step(model: StyleClassifier, batch: dict[str, torch.Tensor], ctx: Any) -> tuple[torch.Tensor, dict]:
    logits, loss = model(batch["x"], batch["y"])
    acc = float((logits.argmax(-1) == batch["y"]).float().mean())
    return loss, {"acc": round(acc, 4)}


def _cut(x: np.ndarray, window: int, stride: int) -> list[np.ndarray]:
    if len(x) < window:
        return []
    return [x[s : s + window] for s in range(0, len(x) - window + 1, stride)]


def balanced_accuracy(y_true: Sequence[int], y_pred: Sequence[int]) -> float:
    """Mean over the classes present in ``y_true`` of the per-class recall."""
    t, p = np.asarray(y_true), np.asarray(y_pred)
    if len(t) == 0:
        return float("nan")
    return float(np.mean([np.mean(p[t == c] == c) for c in np.unique(t)]))


def fit_style_classifier(
    train: Sequence[tuple[np.ndarray, int]],
    *,
    skeleton: Skeleton,
    fps: float,
    genres: Sequence[str],
    out_dir: str | os.PathLike,
    val: Sequence[tuple[np.ndarray, int]] = (),
    window_seconds: float = 4.0,
    stride_seconds: float = 0.5,
    epochs: int = 30,
    batch_size: int = 64,
    lr: float = 2e-3,
    channels: int = 64,
    feature_dim: int = 32,
    dropout: float = 0.2,
    mirror: bool = True,
    seed: int = 0,
    threads: int | None = 1,
    progress: bool = True,
) -> StyleModel:
    """Train a style classifier on ``(positions (T, J, 3), genre index)`` dances.

    Uses the project's generic loop (:func:`dancekit.training.train`) with a class-weighted
    cross-entropy; the run folder ``out_dir`` gets ``model/``, ``best/`` (lowest validation
    loss, when ``val`` is given), ``checkpoints/`` and ``log.jsonl``. Returns the best model.
    """
    from dancekit.checkpoints import load_pretrained
    from dancekit.training import TrainConfig
    from dancekit.training import train as run_training

    fps = check_fps(fps)
    genres = [str(g) for g in genres]
    L = max(8, int(round(window_seconds * fps)))
    stride = max(1, int(round(stride_seconds * fps)))

    def inputs(dances: Sequence[tuple[np.ndarray, int]], *, augment: bool) -> tuple[list[np.ndarray], list[int]]:
        xs, ys = [], []
        for positions, label in dances:
            if not 0 <= int(label) < len(genres):
                raise ParameterError(f"genre index {label} out of range for genres {genres}")
            variants = [positions, _mirror(positions, skeleton)] if augment else [positions]
            for v in variants:
                for w in _cut(style_input(v, fps=fps, skeleton=skeleton), L, stride):
                    xs.append(w)
                    ys.append(int(label))
        return xs, ys

    xs, ys = inputs(train, augment=mirror)
    if not xs:
        raise ParameterError(f"no training dance is at least {window_seconds} s long")
    x = np.stack(xs)
    y = np.asarray(ys)
    flat = x.reshape(-1, x.shape[-1]).astype(np.float64)
    mean = flat.mean(0).astype(np.float32)
    std = np.maximum(flat.std(0), 1e-3).astype(np.float32)
    counts = np.bincount(y, minlength=len(genres)).astype(np.float64)
    weights = np.where(counts > 0, counts.sum() / (np.count_nonzero(counts) * np.maximum(counts, 1)), 0.0)
    config = StyleClassifierConfig(
        in_dim=int(x.shape[-1]), genres=genres, window=L, fps=fps, channels=channels,
        feature_dim=feature_dim, dropout=dropout, class_weights=[float(w) for w in weights],
    )
    torch.manual_seed(seed)
    model = StyleClassifier(config)
    train_set = _Windows((x - mean) / std, y)
    val_set = None
    if val:
        vx, vy = inputs(val, augment=False)
        if vx:
            val_set = _Windows((np.stack(vx) - mean) / std, np.asarray(vy))
    steps_per_epoch = max(1, len(train_set) // batch_size)
    tc = TrainConfig(
        steps=max(1, epochs * steps_per_epoch), batch_size=batch_size, lr=lr, warmup_steps=min(50, steps_per_epoch),
        weight_decay=1e-4, seed=seed, log_every=max(1, steps_per_epoch), val_every=max(1, steps_per_epoch),
        ckpt_every=max(1, epochs * steps_per_epoch), keep_checkpoints=1, threads=threads, seq_len=L,
        stride=stride, random_offset=False,
    )
    meta = {"skeleton": skeleton.to_dict(), "fps": fps, "genres": genres, "input": "style_input v1 (6J+4)",
            "window_seconds": window_seconds, "stride_seconds": stride_seconds, "mirror": mirror,
            "train_windows": int(len(train_set)), "class_counts": counts.astype(int).tolist()}
    stats = {"input_mean": mean, "input_std": std}
    result = run_training(model, train_set, val_set, tc, step_fn=_style_step, out_dir=out_dir,
                          stats=stats, meta=meta, progress=progress)
    best = Path(out_dir) / ("best" if (Path(out_dir) / "best").is_dir() else "model")
    model, meta_loaded, stats_loaded = load_pretrained(best)
    meta_loaded["history_tail"] = result.history[-4:]
    return StyleModel(model, skeleton=skeleton, mean=stats_loaded["input_mean"], std=stats_loaded["input_std"],
                      meta=meta_loaded)


def evaluate_classifier(model: StyleModel, dances: Sequence[tuple[np.ndarray, int]], *, fps: float) -> dict:
    """Accuracy and balanced accuracy of a classifier on labelled dances, per window and per dance."""
    win_true, win_pred, dance_true, dance_pred = [], [], [], []
    for positions, label in dances:
        _, logp = model.embed(positions, fps=fps)
        pred = logp.argmax(axis=1)
        win_true += [int(label)] * len(pred)
        win_pred += pred.tolist()
        dance_true.append(int(label))
        dance_pred.append(int(np.argmax(logp.mean(axis=0))))
    wt, wp = np.asarray(win_true), np.asarray(win_pred)
    return {
        "window_accuracy": float(np.mean(wt == wp)) if len(wt) else float("nan"),
        "window_balanced_accuracy": balanced_accuracy(wt, wp),
        "dance_accuracy": float(np.mean(np.asarray(dance_true) == np.asarray(dance_pred))) if dance_true else float("nan"),
        "dance_balanced_accuracy": balanced_accuracy(dance_true, dance_pred),
        "n_windows": int(len(wt)),
        "n_dances": int(len(dance_true)),
        "dance_predictions": [[model.genres[t], model.genres[p]] for t, p in zip(dance_true, dance_pred)],
    }


def train_style_classifier(
    data: Any,
    out_dir: str | os.PathLike,
    *,
    epochs: int = 30,
    seed: int = 0,
    progress: bool = True,
    **kwargs: Any,
) -> tuple[StyleModel, dict]:
    """Train the style classifier on a prepared dataset's training split.

    Parameters
    ----------
    data : a :class:`~dancekit.data.PreparedData` or its folder
    out_dir : run folder; the final checkpoint (best weights, test scores in ``config.json``
        under ``"test"``) is written to ``out_dir/classifier``
    epochs, seed, progress, **kwargs : passed to :func:`fit_style_classifier`

    Returns
    -------
    ``(model, report)`` where ``report`` holds the accuracy and balanced accuracy on the
    validation and test dances (per window and per whole dance).
    """
    from dancekit.checkpoints import save_pretrained
    from dancekit.data import PreparedData

    if not isinstance(data, PreparedData):
        data = PreparedData(data)

    def labelled(split: str) -> list[tuple[np.ndarray, int]]:
        return [(data.motion(n).to_positions(), data.genre_index(n)) for n in data.names(split)]

    out_dir = Path(out_dir)
    train_dances = labelled("train")
    val_dances = labelled("val")
    test_dances = labelled("test")
    model = fit_style_classifier(
        train_dances, skeleton=data.skeleton, fps=data.fps, genres=list(data.genres), out_dir=out_dir / "run",
        val=val_dances, epochs=epochs, seed=seed, progress=progress, **kwargs,
    )
    report = {
        "train": evaluate_classifier(model, train_dances, fps=data.fps),
        "val": evaluate_classifier(model, val_dances, fps=data.fps) if val_dances else None,
        "test": evaluate_classifier(model, test_dances, fps=data.fps) if test_dances else None,
        "test_names": data.names("test"),
    }
    extra = {k: v for k, v in model.meta.items() if k not in ("model", "config")}
    extra["scores"] = report
    save_pretrained(out_dir / "classifier", model.model, model.config,
                    stats={"input_mean": model.mean, "input_std": model.std}, extra=extra)
    with atomic_path(out_dir / "report.json") as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    return model, report


# ---------------------------------------------------------------------------------------------
# metrics on classifier features


def style_diversity(features: np.ndarray, music: Sequence[str], *, pairs: int = 500, seed: int = 0) -> float:
    """Mean distance over random pairs of dance features ``(N, F)`` for different music.

    Up to ``pairs`` distinct pairs are drawn (all of them when there are fewer), seeded.
    """
    f = np.asarray(features, np.float64)
    music = list(music)
    if len(music) != len(f):
        raise ParameterError(f"{len(f)} feature vectors but {len(music)} music names")
    cand = [(i, j) for i in range(len(f)) for j in range(i + 1, len(f)) if music[i] != music[j]]
    if not cand:
        return float("nan")
    rng = np.random.default_rng(seed)
    if len(cand) > pairs:
        cand = [cand[k] for k in rng.choice(len(cand), size=pairs, replace=False)]
    return float(np.mean([np.linalg.norm(f[i] - f[j]) for i, j in cand]))


def multimodality(features: np.ndarray, music: Sequence[str]) -> float:
    """Mean pairwise feature distance among dances for the same music, averaged over songs with ≥ 2 dances."""
    f = np.asarray(features, np.float64)
    music = list(music)
    if len(music) != len(f):
        raise ParameterError(f"{len(f)} feature vectors but {len(music)} music names")
    per_song = []
    for song in sorted(set(music)):
        idx = [i for i, m in enumerate(music) if m == song]
        if len(idx) >= 2:
            per_song.append(average_pairwise_distance(f[idx]))
    return float(np.mean(per_song)) if per_song else float("nan")


def style_fid(pred_windows: np.ndarray, ref_windows: np.ndarray) -> float:
    """FID between two sets of window features ``(N, F)`` and ``(M, F)``."""
    return float(frechet_distance(pred_windows, ref_windows))


def config_dict(model: StyleModel) -> dict:
    """The classifier's configuration as a plain dict (for reports)."""
    return dataclasses.asdict(model.config)
