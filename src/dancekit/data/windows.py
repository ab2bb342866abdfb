"""A torch ``Dataset`` of fixed-length (music, dance) windows from a prepared dataset."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from dancekit.checkpoints.stats import NormStats
from dancekit.data.prepared import PreparedData
from dancekit.errors import ParameterError
from dancekit.motion.representations import encode_motion


def load_pairs(
    data: PreparedData, names: list[str], *, preset: str, representation: str = "positions3d"
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Whole-dance ``(music (T, D), dance (T, P))`` float32 pairs, unnormalised, in ``names`` order."""
    pairs = []
    for name in names:
        music = np.asarray(data.features(name, preset)["features"], np.float32)
        dance = encode_motion(data.motion(name), representation)
        T = min(len(music), len(dance))
        pairs.append((music[:T], dance[:T]))
    return pairs


def compute_stats(data: PreparedData, *, preset: str, representation: str = "positions3d") -> NormStats:
    """Normalisation statistics on the *training split only*."""
    pairs = load_pairs(data, data.names("train"), preset=preset, representation=representation)
    return NormStats.compute([m for m, _ in pairs], [d for _, d in pairs])


def _resample(x: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Rows of ``x (T, F)`` linearly interpolated at fractional frame ``times (L,)`` (0 ≤ times ≤ T − 1)."""
    i0 = np.floor(times).astype(int)
    i1 = np.minimum(i0 + 1, len(x) - 1)
    f = (times - i0)[:, None]
    return ((1 - f) * x[i0] + f * x[i1]).astype(np.float32)


def _turn(v: np.ndarray, a: int, b: int, c: float, s: float) -> None:
    """Turn the 2-vectors ``(v[..., a], v[..., b])`` in place by the angle whose cosine and sine are ``c``, ``s``."""
    x, y = v[..., a].copy(), v[..., b].copy()
    v[..., a], v[..., b] = c * x - s * y, s * x + c * y


def augment_positions3d(dance: np.ndarray, *, skeleton, mirror: bool = False, heading: float = 0.0) -> np.ndarray:
    """A ``positions3d`` window ``(L, 3J + 3)`` (unnormalised) mirrored and/or turned about the up axis.

    ``mirror``: the world x coordinate negated and left/right joints swapped (the skeleton's mirror
    permutation), as :meth:`dancekit.motion.Motion.mirror`. ``heading``: a rotation by this angle (radians)
    about the up axis of the root-relative joints and of the root's horizontal velocity (root height unchanged).
    Both are exact for this representation: the mirrored / turned dance re-encoded gives the same array.
    """
    J = skeleton.num_joints
    up = skeleton.up_index
    h0, h1 = (a for a in range(3) if a != up)
    out = np.array(dance, dtype=np.float64)
    local = out[:, : 3 * J].reshape(len(out), J, 3)
    vel = out[:, 3 * J : 3 * J + 2]  # (L, 2): velocity along h0, h1
    if mirror:
        local[..., 0] = -local[..., 0]
        local[:] = local[:, skeleton.mirror_permutation()]
        if 0 in (h0, h1):
            vel[:, (h0, h1).index(0)] *= -1.0
    if heading:
        c, s_ = np.cos(heading), np.sin(heading)
        _turn(local, h0, h1, c, s_)
        _turn(vel, 0, 1, c, s_)
    return out.astype(np.float32)


def augment_rot6d(dance: np.ndarray, *, skeleton, heading: float = 0.0) -> np.ndarray:
    """A ``rot6d`` window ``(L, 3 + 6·J_rig)`` (unnormalised) turned by ``heading`` radians about the up axis
    through the origin: the root translation and the root's rotation (its 6D, the first two columns of its world
    rotation) are turned, the other joints' rotations are local to their parents and stay. Exact: the turned
    dance's positions are the original's turned (forward kinematics commutes with a rotation of the root).

    There is no mirror for rotations here: a mirror image on the skeleton's own rig needs left and right bones
    that are each other's mirror images, and tang2018's markers are not (forearm, wrist and hand markers differ
    by up to 13 cm, the two head markers are a chain), so mirroring stays a ``positions3d`` augmentation.
    """
    from dancekit.motion.representations import ROT6D_TRANSLATION

    out = np.array(dance, dtype=np.float64)
    if heading:
        up = skeleton.up_index
        h0, h1 = (a for a in range(3) if a != up)
        c, s_ = np.cos(heading), np.sin(heading)
        root = skeleton.rig().root
        cols = [slice(0, ROT6D_TRANSLATION)]  # the root translation, then the root's two rotation columns
        base = ROT6D_TRANSLATION + 6 * root
        cols += [slice(base, base + 3), slice(base + 3, base + 6)]
        for sl in cols:
            _turn(out[:, sl], h0, h1, c, s_)
    return out.astype(np.float32)


class WindowDataset(Dataset):
    """Windows of ``window`` frames from every dance of ``split``.

    Items are dicts ``{"music": (L, D) float32, "dance": (L, P) float32, "genre": int64 scalar,
    "index": int64 scalar}``, both normalised with ``stats`` (computed on the training split when
    not given; pass the training set's ``stats`` to the validation set).

    Windows start every ``stride`` frames (default ``window // 4``); with ``random_offset=True``
    each item is shifted by a random amount in ``[0, stride)`` (data augmentation). Dances shorter
    than ``window`` are skipped and listed in ``skipped``.

    The offset of item ``k`` is a pure function of ``(seed, epoch, k)`` (drawn from
    ``np.random.default_rng([seed, epoch, k])``); the trainer calls :meth:`set_epoch` before each epoch,
    as with torch's ``DistributedSampler``. The dataset thus holds no random state that advances: a
    resumed run sees the batches of an uninterrupted one, and DataLoader worker processes or
    data-parallel ranks (each with a copy of the dataset) draw the same offset for the same item.

    ``balance_genres=True`` repeats the windows of each genre ``min(max_repeat, round(n_max / n_g))``
    times, where ``n_g`` is the genre's window count and ``n_max`` the largest one, so a minority
    genre (tango: one dance in tang2018) is seen about as often as the majority (waltz: 19 training
    dances). With ``random_offset`` the repeats are different crops.

    ``genres`` keeps only the dances of these genres (names as in ``data.genres``), e.g. to
    fine-tune a genre-specific model; the normalisation statistics stay those of the whole split.

    Augmentations true to dance (issue 15; ``positions3d``, and ``rot6d`` but its mirror), drawn per item from
    ``np.random.default_rng([seed, epoch, k, 1])`` like the offsets: ``mirror`` the probability of the
    left–right mirror image (:func:`augment_positions3d`), ``heading=True`` a uniform random turn of the whole
    dance about the up axis (:func:`augment_rot6d` for ``rot6d``), ``tempo`` t a joint tempo change of music and
    motion by a factor r ∈ [1 − t, 1 + t] (both resampled linearly at r frames per frame; ``positions3d``'s
    per-frame root velocity scaled by r, ``rot6d``'s root position and 6D columns interpolated as they are).
    """

    def __init__(
        self,
        data: PreparedData,
        split: str,
        *,
        preset: str = "revolution",
        window: int = 240,
        stride: int | None = None,
        stats: NormStats | None = None,
        representation: str = "positions3d",
        random_offset: bool = False,
        seed: int = 0,
        balance_genres: bool = False,
        max_repeat: int = 8,
        genres: Sequence[str] | None = None,
        mirror: float = 0.0,
        heading: bool = False,
        tempo: float = 0.0,
    ):
        if not 0.0 <= mirror <= 1.0 or not 0.0 <= tempo < 0.5:
            raise ParameterError(f"mirror must be in [0, 1] and tempo in [0, 0.5), got {mirror!r}, {tempo!r}")
        if (mirror or heading or tempo) and representation not in ("positions3d", "rot6d"):
            raise ParameterError(f"the heading / tempo augmentations need positions3d or rot6d, got {representation!r}")
        if mirror and representation != "positions3d":
            raise ParameterError("the mirror augmentation needs positions3d (a mirror of rotations needs a left-right "
                                 f"symmetric rig), got {representation!r}")
        self.mirror, self.heading, self.tempo = float(mirror), bool(heading), float(tempo)
        self.skeleton = data.skeleton
        if window < 2:
            raise ParameterError(f"window must be at least 2 frames, got {window}")
        self.data, self.split, self.preset, self.window = data, split, preset, int(window)
        self.stride = int(stride or max(1, window // 4))
        self.representation = representation
        self.random_offset = random_offset
        if not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
        self.seed = int(seed)
        self.epoch = 0
        self.stats = stats if stats is not None else compute_stats(data, preset=preset, representation=representation)
        self.names = data.names(split)
        if genres is not None:
            unknown = sorted(set(genres) - set(data.genres))
            if unknown:
                raise ParameterError(f"unknown genre(s) {unknown} for {data.root}; choose from {list(data.genres)}")
            keep = set(genres)
            self.names = [n for n in self.names if data.genre(n) in keep]
        pairs = load_pairs(data, self.names, preset=preset, representation=representation)
        self.music = [self.stats.normalize_music(m) for m, _ in pairs]
        self.dance = [self.stats.normalize_dance(d) for _, d in pairs]
        self.genres = [data.genre_index(n) for n in self.names]
        self.index: list[tuple[int, int]] = []
        self.skipped: list[str] = []
        for i, (m, _) in enumerate(pairs):
            T = len(m)
            if T < self.window:
                self.skipped.append(self.names[i])
                continue
            for s in range(0, T - self.window + 1, self.stride):
                self.index.append((i, s))
        self.repeats: dict[int, int] = {}
        if balance_genres and self.index:
            counts: dict[int, int] = {}
            for i, _ in self.index:
                counts[self.genres[i]] = counts.get(self.genres[i], 0) + 1
            n_max = max(counts.values())
            self.repeats = {g: max(1, min(int(max_repeat), round(n_max / n))) for g, n in counts.items()}
            self.index = [w for w in self.index for _ in range(self.repeats[self.genres[w[0]]])]

    @property
    def music_dim(self) -> int:
        return int(self.music[0].shape[1]) if self.music else 0

    @property
    def pose_dim(self) -> int:
        return int(self.dance[0].shape[1]) if self.dance else 0

    def __len__(self) -> int:
        return len(self.index)

    def set_epoch(self, epoch: int) -> None:
        """Select the random offsets of training epoch ``epoch`` (>= 0)."""
        if isinstance(epoch, bool) or not isinstance(epoch, (int, np.integer)) or epoch < 0:
            raise ParameterError(f"epoch must be a non-negative integer, got {epoch!r}")
        self.epoch = int(epoch)

    def offset(self, k: int) -> int:
        """Random shift of item ``k`` in the current epoch, in ``[0, stride)`` (0 without ``random_offset``)."""
        if not self.random_offset:
            return 0
        return int(np.random.default_rng([self.seed, self.epoch, int(k)]).integers(0, self.stride))

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        i, s = self.index[k]
        if self.random_offset:
            T = len(self.music[i])
            s = min(s + self.offset(k % len(self.index)), T - self.window)  # k % n: a negative index too
        if self.mirror or self.heading or self.tempo:
            music, dance = self._augmented(i, s, k % len(self.index))
        else:
            music, dance = self.music[i][s : s + self.window], self.dance[i][s : s + self.window]
        return {
            "music": torch.from_numpy(music),
            "dance": torch.from_numpy(dance),
            "genre": torch.tensor(self.genres[i], dtype=torch.int64),
            "index": torch.tensor(i, dtype=torch.int64),
        }

    def _augmented(self, i: int, s: int, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Window ``k`` (dance ``i`` from frame ``s``) under its draw of the augmentations, normalised."""
        rng = np.random.default_rng([self.seed, self.epoch, int(k), 1])
        r = 1.0 + rng.uniform(-self.tempo, self.tempo) if self.tempo else 1.0
        flip = bool(rng.random() < self.mirror) if self.mirror else False
        turn = float(rng.uniform(0.0, 2.0 * np.pi)) if self.heading else 0.0
        T, L = len(self.music[i]), self.window
        if (L - 1) * r > T - 1:
            r = (T - 1) / (L - 1)
        s = min(s, int(np.floor(T - 1 - (L - 1) * r)))
        times = s + np.arange(L) * r
        music = _resample(self.music[i], times) if r != 1.0 else self.music[i][s : s + L]
        raw = self.stats.denormalize_dance(self.dance[i][int(np.floor(times[0])) : int(np.ceil(times[-1])) + 1])
        dance = _resample(raw, times - np.floor(times[0])) if r != 1.0 else raw[:L]
        if self.representation == "rot6d":
            dance = augment_rot6d(dance, skeleton=self.skeleton, heading=turn)
        else:
            J = self.skeleton.num_joints
            dance[:, 3 * J : 3 * J + 2] *= r  # per-frame root displacement at r source frames per frame
            dance = augment_positions3d(dance, skeleton=self.skeleton, mirror=flip, heading=turn)
        return np.ascontiguousarray(music, np.float32), self.stats.normalize_dance(dance).astype(np.float32)
