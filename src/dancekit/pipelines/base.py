"""What every dance pipeline shares: the result object and loading a pipeline by model name or folder.

    >>> from dancekit.pipelines import load_pipeline          # doctest: +SKIP
    >>> result = load_pipeline()("song.mp3", seed=0)           # doctest: +SKIP
    >>> result.motion, result.genre, result.summary()          # doctest: +SKIP

Inference only: nothing here (or in any pipeline) imports the training or dataset packages.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancekit import registry
from dancekit.checkpoints.hub import read_meta, resolve_model
from dancekit.errors import CheckpointError, ParameterError
from dancekit.motion import Motion
from dancekit.motion.analysis import floor_curve
from dancekit.motion.kinematics import normalize_bone_lengths


@dataclass
class DanceResult:
    """A generated dance and what the pipeline decided to make it.

    Attributes
    ----------
    motion : the dance (:class:`~dancekit.motion.Motion`, the model's skeleton, units and fps)
    model : the model folder that was asked for (a genre model may have danced it: ``danced_by``)
    seed : the random seed
    genre_requested : the genre asked for ("auto", "none" or a genre name)
    genre : the genre danced (None: the model alone, its style left to the music)
    genre_probs : the probability of each genre read from the music (empty unless read)
    danced_by : the folder of the model that generated the motion (the genre model's, or ``model``)
    beat_strength : how strongly the song pulses at a danceable tempo (0 … 1,
        :func:`dancekit.features.beat_strength`; None: not measured)
    looks_like_music : False when ``beat_strength`` is below :data:`dancekit.features.MUSIC_BEAT_STRENGTH`
        (silence, noise, speech, a bird or a whale): the input was danced calmly (:func:`calm_motion`)
        and no genre was read from it
    genre_drawn_p : the probability with which the seed drew ``genre`` (or the model alone, ``genre`` None)
        from the music's genre posterior (:class:`~dancekit.pipelines.revolution.GenreDraw`); None: not
        drawn (the most likely genre, the genre asked for, or no genre)
    notes : what the pipeline stages did (:mod:`dancekit.pipelines.stages`), e.g. ``"beat-synced (52 of
        109 beats at 129 BPM)"`` or why the dance was left unwarped; part of :meth:`summary`
    """

    motion: Motion
    model: str
    seed: int
    genre_requested: str = "none"
    genre: str | None = None
    genre_probs: dict[str, float] = field(default_factory=dict)
    danced_by: str = ""
    beat_strength: float | None = None
    looks_like_music: bool = True
    notes: list[str] = field(default_factory=list)
    genre_drawn_p: float | None = None

    @property
    def genre_source(self) -> str | None:
        """How the genre was decided: "music" (read by the classifier), "given", or None (no genre)."""
        if self.genre is None:
            return None
        return "music" if self.genre_probs and self.genre_requested in ("auto", None) else "given"

    def summary(self) -> str:
        """A few words on the decisions, e.g. ``"as waltz (read from the music, p = 0.46); beat-synced (52 of
        109 beats at 129 BPM)"``, or ``"calmly (it does not look like music: beat strength 0.10 < 0.19)"``
        (empty: nothing to say)."""
        from dancekit.features import MUSIC_BEAT_STRENGTH

        parts = []
        if self.genre_drawn_p is not None:
            what = f"as {self.genre}" if self.genre is not None else "by the model alone"
            parts.append(f"{what} (drawn by seed {self.seed}, p = {self.genre_drawn_p:.2f})")
        elif self.genre is not None and self.genre_source == "music":
            parts.append(f"as {self.genre} (read from the music, p = {self.genre_probs[self.genre]:.2f})")
        elif self.genre is not None:
            parts.append(f"as {self.genre}")
        if not self.looks_like_music:
            strength = float("nan") if self.beat_strength is None else self.beat_strength
            parts.append(f"calmly (it does not look like music: beat strength {strength:.2f} "
                         f"< {MUSIC_BEAT_STRENGTH:.2f})")
        return "; ".join(parts + list(self.notes))


#: The most seeds ``dancekit dance --seeds`` takes in one pass: each is a whole dance in memory.
MAX_SEEDS = 64


def check_seeds(seeds) -> list[int]:
    """``seeds`` (an iterable of integers) as a list of Python ints, in order (a seed may repeat: with another
    genre per row, say).

    Raises
    ------
    ParameterError
        For no seeds or a non-integer.
    """
    if isinstance(seeds, (int, np.integer)) or isinstance(seeds, (str, bytes)):
        raise ParameterError(f"seeds must be a list of integers, got {seeds!r}")
    out = []
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)):
            raise ParameterError(f"seeds must be integers, got {s!r}")
        out.append(int(s))
    if not out:
        raise ParameterError("at least one seed is needed")
    return out


def parse_seeds(text: str) -> list[int]:
    """Seeds written as ``dancekit dance --seeds`` takes them: ``"0-7"`` (a range, both ends included),
    ``"0,3,9"``, or both (``"0-3,10,20-21"``); every seed in ``[0, 2**63)``.

    Raises
    ------
    ParameterError
        For anything else (a reversed range, a repeated seed, a negative number, more than :data:`MAX_SEEDS`).
    """
    seeds: list[int] = []
    for part in str(text).split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            a = int(lo)
            b = int(hi) if sep else a
        except ValueError:
            raise ParameterError(f"seeds must look like 0-7 or 0,3,9, got {text!r}") from None
        if a < 0 or b < a or b >= 2**63:
            raise ParameterError(f"bad seed range {part!r} in {text!r} (non-negative, low-high)")
        if b - a >= MAX_SEEDS:
            raise ParameterError(f"{b - a + 1} seeds in {part!r}; at most {MAX_SEEDS} in one pass")
        seeds.extend(range(a, b + 1))
    if len(set(seeds)) != len(seeds):
        raise ParameterError(f"seeds repeat in {text!r} (the same seed gives the same dance)")
    if len(seeds) > MAX_SEEDS:
        raise ParameterError(f"{len(seeds)} seeds in {text!r}; at most {MAX_SEEDS} in one pass")
    return check_seeds(seeds)


def load_pipeline(model: str | os.PathLike | None = None, checkpoint: str | os.PathLike | None = None,
                  *, device: str = "cpu", precision: str = "fp32") -> Any:
    """The inference pipeline of a model: a name (the user's models folder, then the embedded models) or a
    checkpoint folder (``checkpoint``, or a path given as ``model``); ``None``: the default model.

    The pipeline class comes from the family's entry in :mod:`dancekit.registry`. ``precision``: ``"fp32"``
    (the model as trained), ``"bf16"`` or ``"int8"`` decoding for the autoregressive families
    (:func:`dancekit.models.precision.to_precision`).

    Raises
    ------
    ParameterError
        For an unknown model name or precision, or a reduced precision for a model that has none.
    CheckpointError
        For a folder that is not a checkpoint, or holds a family without a pipeline.
    """
    from dancekit.models.precision import check_precision

    check_precision(precision)
    folder = resolve_model(checkpoint if checkpoint is not None else model)
    family = read_meta(folder)["model"]
    try:
        cls = registry.get(family).load("pipeline")
    except (ParameterError, ImportError, AttributeError) as exc:
        raise CheckpointError(f"{folder} holds a {family!r} model, which has no pipeline: {exc}") from exc
    if precision == "fp32":
        return cls.from_pretrained(Path(folder), device=device)
    if not getattr(cls, "supports_precision", False):  # the dance pipelines (dancekit.pipelines.dance) do
        raise ParameterError(f"precision {precision!r} is not available for {family!r} models (only fp32)")
    return cls.from_pretrained(Path(folder), device=device, precision=precision)


#: How much of its movement a dance keeps when the input does not look like music (:func:`calm_motion`).
CALM = 0.4


def calm_motion(motion: Motion, *, amount: float = CALM) -> Motion:
    """A calmer version of a position-based dance: every joint's offset from the root, and the root's path,
    pulled towards their mean over the dance so that only ``amount`` of the movement remains (speeds scale
    by ``amount`` too). Bone lengths change with it: callers restore them (``clean_motion``).

    Parameters
    ----------
    motion : a :class:`~dancekit.motion.Motion` with positions ``(T, J, 2|3)``; joint 0 is the root
    amount : 0 (a still mean pose) … 1 (unchanged)
    """
    if not 0.0 <= amount <= 1.0:
        raise ParameterError(f"amount must be in [0, 1], got {amount!r}")
    pos = np.asarray(motion.to_positions(), np.float64)  # (T, J, D)
    root = pos[:, :1]
    rel = pos - root
    rel = rel.mean(axis=0) + amount * (rel - rel.mean(axis=0))
    root = root.mean(axis=0) + amount * (root - root.mean(axis=0))
    return Motion(skeleton=motion.skeleton, fps=motion.fps, positions=(root + rel).astype(np.float32))


def clean_motion(motion: Motion) -> Motion:
    """Rest bone lengths and feet on the floor for a generated 3D :class:`Motion` (positions only)."""
    skeleton = motion.skeleton
    positions = np.asarray(normalize_bone_lengths(motion.to_positions(), skeleton), np.float64)  # (T, J, 3)
    positions[..., skeleton.up_index] -= floor_curve(positions, skeleton, fps=motion.fps)[:, None]
    return Motion(skeleton=skeleton, fps=motion.fps, positions=positions.astype(np.float32))


def song_feature_set(audio_path: str | os.PathLike, *, fps: float, preset: str, hop_length: int,
                     start: float | None = None, end: float | None = None) -> Any:
    """A song's (excerpt's) :class:`~dancekit.features.FeatureSet` (:func:`dancekit.features.extract_file`, with
    its cache: :func:`song_features` on the same arguments then reads it back from the cache)."""
    from dancekit.features import extract_file

    return extract_file(audio_path, fps=fps, preset=preset, start=start, end=end, hop_length=hop_length)


def song_features(audio_path: str | os.PathLike, *, fps: float, preset: str, hop_length: int, music_dim: int,
                  start: float | None = None, end: float | None = None) -> np.ndarray:
    """A song's (excerpt's) music features ``(T, music_dim)`` float32, unnormalised, at a checkpoint's fps,
    preset and hop length (:func:`dancekit.features.extract_file`, with its cache).

    Raises
    ------
    AudioError
        For a missing, unreadable or too short song.
    CheckpointError
        When the preset's features do not have the model's ``music_dim`` columns.
    """
    fs = song_feature_set(audio_path, fps=fps, preset=preset, start=start, end=end, hop_length=hop_length)
    feats = np.asarray(fs.features, np.float32)
    if feats.ndim != 2 or feats.shape[1] != music_dim:
        raise CheckpointError(f"the {preset!r} features of {audio_path} have shape {feats.shape}, but the model "
                              f"expects {music_dim} columns")
    return feats
