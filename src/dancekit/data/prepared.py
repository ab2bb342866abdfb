"""Prepared paired datasets: preparation of tang2018, whole-dance splits, and reading back.

Layout written by :func:`prepare_tang2018` (``dancekit prepare tang2018 SRC -o DIR``)::

    DIR/meta.json      source, fps, hop_length, skeleton, presets, genres,
                       dances: {name: {genre, frames, floor_offset, audio: [path, start_s, end_s]}}
    DIR/splits.json    {"train": [...], "val": [...], "test": [...], "seed": 0, "method": ...}
    DIR/dances/<name>/motion.npz              the public npz schema (positions, rotations, ...)
    DIR/dances/<name>/features_<preset>.npz   features (T, D) float32, names, beat_times, fps, preset

Alignment: frame ``i`` of a tang2018 dance plays at ``start_position / 25 + i / 25`` s of its song.
Features are computed on the slice ``[start, start + T / fps)`` of the song, which gives
``1 + T`` feature frames (centred frames, ``sr = fps * hop_length``); the last one is dropped so
feature frame ``i`` is motion frame ``i`` and both have exactly ``T`` frames.

The floor: the tang2018 capture drifts vertically. The floor sits at a different height in every
dance and moves *during* a dance (the lowest foot's running 5th percentile over 3 s wanders by
7–50 cm within one dance; e.g. DANCE_W_31 by 51 cm). Each dance is therefore shifted along the up
axis frame by frame so that its floor is at 0, the floor at frame t being the 5th percentile of
the lowest foot joint's height in a 3-second window around t, smoothed by a 1-second moving
average (:func:`floor_curve`). ``meta.json`` records the range of the removed curve as
``floor_offset`` ([min, max], skeleton units).
"""

from __future__ import annotations

import json
import os
import random
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._checks import check_fps
from dancekit._io import atomic_dir
from dancekit.errors import DatasetError, ParameterError
from dancekit.motion import Motion, Skeleton
from dancekit.motion.analysis import floor_curve

GENRES = ("waltz", "rumba", "chacha", "tango")
TANG2018_GENRE_CODES = {"W": "waltz", "R": "rumba", "C": "chacha", "T": "tango"}
DEFAULT_PRESETS = ("revolution", "music2dance", "dual")


@dataclass(frozen=True)
class AudioRef:
    """Where a dance's music is: ``path`` from ``start`` to ``end`` seconds."""

    path: str
    start: float
    end: float


def tang2018_genre(name: str) -> str:
    """Genre of a tang2018 dance from its folder name ``DANCE_<G>_<n>``."""
    parts = Path(name).name.split("_")
    if len(parts) < 3 or parts[1] not in TANG2018_GENRE_CODES:
        raise DatasetError(f"not a tang2018 dance folder name (DANCE_<W|R|C|T>_<n>): {name}")
    return TANG2018_GENRE_CODES[parts[1]]


def split_by_genre(
    names_by_genre: dict[str, list[str]], *, seed: int = 0, test_fraction: float = 0.15, val_fraction: float = 0.1
) -> dict[str, list[str]]:
    """Split whole dances into train / val / test, stratified by genre, with a fixed seed.

    Per genre with ``n`` dances: ``n_test = max(1, round(test_fraction * n))`` when ``n >= 3``
    (else 0) and ``n_val = max(1, round(val_fraction * n))`` when ``n >= 4`` (else 0); the rest
    is training data, so a genre with one or two dances is only ever trained on.
    """
    rng = random.Random(seed)
    out: dict[str, list[str]] = {"train": [], "val": [], "test": []}
    for genre in sorted(names_by_genre):
        names = sorted(names_by_genre[genre])
        rng.shuffle(names)
        n = len(names)
        n_test = max(1, round(test_fraction * n)) if n >= 3 else 0
        n_val = max(1, round(val_fraction * n)) if n >= 4 else 0
        out["test"] += names[:n_test]
        out["val"] += names[n_test : n_test + n_val]
        out["train"] += names[n_test + n_val :]
    return {k: sorted(v) for k, v in out.items()}


def level_tang2018(folder: str | os.PathLike, *, fps: float = 25.0) -> tuple[Motion, Any, np.ndarray]:
    """A raw tang2018 dance (``DANCE_<G>_<n>/``) as :func:`prepare_tang2018` writes its motion: read, resampled to
    ``fps`` when recorded at another rate, and moved along the up axis frame by frame so that its floor
    (:func:`~dancekit.motion.analysis.floor_curve`) is at 0 (the module docstring says why).

    Returns
    -------
    ``(motion, audio, floor)``: the dance (positions only, ``(T, J, 3)`` float32, skeleton units, at ``fps``), its
    song (``audio.path``, ``audio.start`` s) as :func:`~dancekit.motion.formats.read_tang2018` gives it, and the
    removed floor curve ``(T,)`` float64 (skeleton units).
    """
    from dancekit.motion.formats import read_tang2018

    motion, audio = read_tang2018(folder)
    if abs(motion.fps - fps) > 1e-6:
        motion = motion.resample(fps)
    skel = motion.skeleton
    positions = motion.to_positions().astype(np.float64)  # (T, J, 3)
    floor = floor_curve(positions, skel, fps=fps)  # (T,)
    positions[..., skel.up_index] -= floor[:, None]
    return Motion(skeleton=skel, fps=fps, positions=positions.astype(np.float32)), audio, floor


def prepare_tang2018(
    src: str | os.PathLike,
    out: str | os.PathLike,
    *,
    fps: float = 25.0,
    presets: tuple[str, ...] = DEFAULT_PRESETS,
    seed: int = 0,
    hop_length: int = 512,
    progress: bool = True,
) -> Path:
    """Prepare the tang2018 dances in ``src`` into the folder ``out``.

    Writes aligned music features for every preset, the motion (world positions with the floor
    at 0, and IK rotations), ``splits.json`` (whole dances, stratified by genre) and ``meta.json``.
    The folder appears only once complete (written beside it, then renamed).

    Parameters
    ----------
    src : folder holding ``DANCE_<G>_<n>/`` sub-folders (``audio.mp3``, ``config.json``, ``skeletons.json``)
    out : folder to create (replaced if it exists)
    fps : motion and feature frame rate; tang2018 is recorded at 25 fps and resampled otherwise
    presets : music feature presets to compute
    """
    from tqdm import tqdm

    from dancekit.features import PRESET_DIMS, extract_file
    from dancekit.motion.formats import write_motion

    src = Path(src)
    if not src.is_dir():
        raise DatasetError(f"tang2018 source folder not found: {src}")
    folders = sorted(p for p in src.iterdir() if p.is_dir() and p.name.startswith("DANCE_"))
    if not folders:
        raise DatasetError(f"no DANCE_<G>_<n> folders in {src}")
    for p in presets:
        if p not in PRESET_DIMS:
            raise ParameterError(f"unknown feature preset {p!r}; choose from {sorted(PRESET_DIMS)}")
    fps = check_fps(fps)

    dances: dict[str, dict] = {}
    names_by_genre: dict[str, list[str]] = {}
    skeleton_dict = None
    with atomic_dir(out) as tmp:
        bar = tqdm(folders, desc="prepare tang2018", unit="dance", disable=not progress)
        for folder in bar:
            bar.set_postfix_str(folder.name)
            genre = tang2018_genre(folder.name)
            motion, audio, floor = level_tang2018(folder, fps=fps)
            skel = motion.skeleton
            positions = motion.positions
            T = len(positions)
            start = float(audio.start)
            end = start + T / fps
            feats = {}
            raw_frames = None
            for preset in presets:
                fs = extract_file(audio.path, fps=fps, preset=preset, start=start, end=end, hop_length=hop_length)
                f = np.asarray(fs.features, np.float32)
                if abs(len(f) - T) > 2:
                    raise DatasetError(
                        f"{folder}: {preset} features have {len(f)} frames for {T} motion frames (alignment broken)"
                    )
                feats[preset] = fs
                raw_frames = len(f)
                T = min(T, len(f))
            motion = Motion(skeleton=skel, fps=fps, positions=positions[:T]).with_rotations()
            dance_dir = tmp / "dances" / folder.name
            dance_dir.mkdir(parents=True)
            write_motion(dance_dir / "motion.npz", motion)
            for preset, fs in feats.items():
                beat_times = np.asarray(fs.beat_times, np.float64)
                np.savez(
                    dance_dir / f"features_{preset}.npz",
                    features=np.asarray(fs.features[:T], np.float32),
                    names=np.asarray(list(fs.names)),
                    beat_times=beat_times[beat_times < T / fps],
                    fps=np.float64(fps),
                    preset=np.asarray(preset),
                )
            dances[folder.name] = {
                "genre": genre,
                "frames": int(T),
                "floor_offset": [float(floor.min()), float(floor.max())],
                "feature_frames_raw": int(raw_frames) if raw_frames is not None else None,
                "audio": [str(Path(audio.path).resolve()), start, start + T / fps],
            }
            names_by_genre.setdefault(genre, []).append(folder.name)
            skeleton_dict = skel.to_dict()
        splits = split_by_genre(names_by_genre, seed=seed)
        splits["seed"] = seed
        splits["method"] = "whole dances, stratified by genre (dancekit.data.split_by_genre)"
        meta = {
            "source": "tang2018",
            "source_path": str(src.resolve()),
            "fps": fps,
            "hop_length": hop_length,
            "skeleton": skeleton_dict,
            "presets": list(presets),
            "genres": list(GENRES),
            "dances": dances,
        }
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1))
        (tmp / "splits.json").write_text(json.dumps(splits, indent=1))
    return Path(out)


class PreparedData:
    """Read access to a prepared dataset folder (see the module docstring for the layout)."""

    def __init__(self, root: str | os.PathLike):
        self.root = Path(root)
        meta_path, splits_path = self.root / "meta.json", self.root / "splits.json"
        for p in (meta_path, splits_path):
            if not p.is_file():
                raise DatasetError(
                    f"not a prepared dataset: {p} is missing (run `dancekit prepare tang2018 SRC -o {self.root}`)"
                )
        try:
            self.meta = json.loads(meta_path.read_text())
            self.splits = json.loads(splits_path.read_text())
        except json.JSONDecodeError as exc:
            raise DatasetError(f"corrupt dataset file in {self.root}: {exc}") from exc
        self.fps = float(self.meta["fps"])
        self.genres: tuple[str, ...] = tuple(self.meta["genres"])
        self.presets: tuple[str, ...] = tuple(self.meta["presets"])
        self.skeleton = Skeleton.from_dict(self.meta["skeleton"])
        self._motion_cache: dict[str, Motion] = {}

    def names(self, split: str | None = None) -> list[str]:
        """Dance names of ``split`` ("train", "val", "test") or of the whole dataset."""
        if split is None:
            return sorted(self.meta["dances"])
        if split not in ("train", "val", "test"):
            raise ParameterError(f"unknown split {split!r}; choose train, val or test")
        return list(self.splits[split])

    def _check(self, name: str) -> dict:
        try:
            return self.meta["dances"][name]
        except KeyError:
            raise DatasetError(f"no dance named {name!r} in {self.root}") from None

    def genre(self, name: str) -> str:
        return self._check(name)["genre"]

    def genre_index(self, name: str) -> int:
        return self.genres.index(self.genre(name))

    def frames(self, name: str) -> int:
        return int(self._check(name)["frames"])

    def audio(self, name: str) -> AudioRef:
        path, start, end = self._check(name)["audio"]
        return AudioRef(path=path, start=float(start), end=float(end))

    def motion(self, name: str) -> Motion:
        """The dance as a :class:`Motion` (world positions, floor at 0, and IK rotations)."""
        self._check(name)
        if name not in self._motion_cache:
            from dancekit.motion.formats import read_motion

            self._motion_cache[name] = read_motion(self.root / "dances" / name / "motion.npz")
        return self._motion_cache[name]

    def features(self, name: str, preset: str) -> dict[str, np.ndarray]:
        """Music features of a dance: ``features`` (T, D), ``names``, ``beat_times`` (s), ``fps``, ``preset``."""
        self._check(name)
        path = self.root / "dances" / name / f"features_{preset}.npz"
        if not path.is_file():
            raise DatasetError(f"no {preset!r} features for {name}: {path} is missing (prepared presets: {self.presets})")
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
