"""Dual learning inference (MM 2021): music → dance with G_M→D, dance → music with G_D→M (inference only).

    >>> dance = DualPipeline.from_pretrained("runs/dual/model")("song.ogg", seed=0).motion     # doctest: +SKIP
    >>> piece = ComposePipeline.from_pretrained("runs/dual/model")(motion, seed=0)            # doctest: +SKIP
    >>> piece.write("out/", stem="dance")      # dance.mid + dance.wav                       # doctest: +SKIP

Both read one ``dual`` checkpoint folder (both generators are one model). Its ``stats.npz`` holds the
training statistics of every column; the chroma + beat columns of the music and the 6D columns of the
dance stay raw (``music_raw_from`` / ``dance_raw_from`` of the model configuration), as in training.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dancekit.checkpoints import NormStats, load_pretrained, resolve_model
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.dual import PITCH_CLASSES, DualModel, chord_token
from dancekit.motion import Motion, Skeleton
from dancekit.motion.representations import decode_rot6d, encode_motion
from dancekit.pipelines.config import CheckpointSettings, DualSampling, StageConfig, checkpoint_settings
from dancekit.pipelines.dance import DancePipeline, GenreChoice


def _load(folder: str | os.PathLike, device: str) -> tuple[DualModel, dict[str, Any], NormStats, Path]:
    folder = resolve_model(folder)
    model, meta, arrays = load_pretrained(folder, device=device)
    stats = NormStats.from_arrays(arrays, source=str(folder))  # a copy: the raw columns are set below
    model, meta, stats = _checked(model, meta, stats, folder)
    return model, meta, stats, Path(folder)


def _checked(model, meta: dict[str, Any], stats: NormStats, folder) -> tuple[DualModel, dict[str, Any], NormStats]:
    """A loaded dual checkpoint checked (the family, fps and skeleton, the statistics' sizes, rot6d), with the
    raw columns of its statistics (chroma + beat, the 6D) set to mean 0 and std 1, as in training."""
    if not isinstance(model, DualModel):
        raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a dual-learning model")
    missing = [k for k in ("skeleton", "fps") if k not in meta]
    if missing:
        raise CheckpointError(f"checkpoint {folder}: config.json lacks {missing}")
    c = model.config
    if len(stats.music_mean) != c.music_dim or len(stats.dance_mean) != c.pose_dim:
        raise CheckpointError(f"checkpoint {folder}: statistics do not match the model's music_dim / pose_dim")
    stats.music_mean[c.music_raw_from:], stats.music_std[c.music_raw_from:] = 0.0, 1.0
    stats.dance_mean[c.dance_raw_from:], stats.dance_std[c.dance_raw_from:] = 0.0, 1.0
    if meta.get("representation", "rot6d") != "rot6d":
        raise CheckpointError(f"checkpoint {folder}: a dual model works on rot6d, not {meta['representation']!r}")
    return model.eval(), meta, stats


class DualPipeline(DancePipeline):
    """Music → dance with G_M→D: a song → :class:`~dancekit.pipelines.DanceResult`.

    ``pipe(song, seed=0, start=None, end=None, beat_sync=True, cleanup=True, start_pose=None, smooth_frames=None,
    lowpass_hz=None)`` and ``pipe.dances(song, seeds=[...], ...)`` (:meth:`DancePipeline.dances
    <dancekit.pipelines.dance.DancePipeline.dances>`); this family's own options are those of
    :meth:`generate_batch`. The model has no genre input: ``genre`` must be None, "auto" or "none"; ``seed`` draws
    the start pose from the model's pool unless ``start_pose`` is given."""

    family = "dual"
    sampling_config = DualSampling

    def __init__(self, model: DualModel, *, meta: dict[str, Any], stats: NormStats, folder: str = "?",
                 genre_reader=None, settings: CheckpointSettings | None = None):
        #: ``genre_reader``: a :class:`~dancekit.pipelines.music_attributes.MusicAttributePipeline` (the
        #: checkpoint's ``"genre_reader"`` component) or None: the model has no genre input, but the energy stage's
        #: floor and the jitter cap follow the genres the music calls for (:meth:`reads_genre`)
        super().__init__(model, meta=meta, stats=stats, folder=folder, settings=settings, genre_reader=genre_reader)
        sampling = self.settings.sampling
        self.smooth_frames = sampling.smooth_frames  # the checkpoint's sampling setting
        #: the checkpoint's low-pass cut-off (Hz); when set, used instead of smooth_frames
        self.lowpass_hz = sampling.lowpass_hz
        #: how the root's 6D is decoded: "gram_schmidt" (as in training) or "procrustes" (chosen on the validation
        #: songs for the shipped model: its root heading column is short and noisy, docs/DUAL.md)
        self.root_decode = sampling.root_6d_decode

    @classmethod
    def from_parts(cls, model, *, meta, stats, folder, settings, parts, device) -> DualPipeline:
        """The dual checkpoint's checks (:func:`_checked`: the family, the raw statistics columns, rot6d) and its
        ``"genre_reader"``; the rest is :meth:`DancePipeline.from_pretrained
        <dancekit.pipelines.dance.DancePipeline.from_pretrained>`'s."""
        model, meta, stats = _checked(model, meta, stats, folder)
        reader = None
        if "genre_reader" in parts:
            from dancekit.pipelines.music_attributes import MusicAttributePipeline

            reader = MusicAttributePipeline.from_pretrained(parts["genre_reader"], device=device)
        return cls(model, meta=meta, stats=stats, folder=str(folder), genre_reader=reader, settings=settings)

    def start_pose(self, pose: Motion | np.ndarray | None, seed: int) -> torch.Tensor:
        """The decoder's start token (P,): the first frame of ``pose`` (a Motion on the model's skeleton, or a
        rot6d vector), else a start pose drawn from the model's pool with ``seed``."""
        if pose is None:
            return self.model.sample_start_pose(torch.Generator().manual_seed(int(seed)))
        if isinstance(pose, Motion):
            pose = encode_motion(on_model_skeleton(pose.slice(0, 1), self.skeleton), "rot6d")[0]
        x = np.asarray(pose, np.float32).reshape(-1)
        if x.shape != (self.model.config.pose_dim,):
            raise ParameterError(f"a start pose must have {self.model.config.pose_dim} rot6d values, got {x.shape}")
        return torch.from_numpy(self.stats.normalize_dance(x))

    def reads_genre(self, requested: list[str], *, music: bool, config: StageConfig) -> bool:
        """The model has no genre input; the music's genres are read (for any input, whatever genre is asked for)
        where a stage follows them: the energy lift with a ``genre_stats.energy`` table, or the jitter cap."""
        if self.genre_reader is None:
            return False
        energy = "lift_energy" in config.enabled and config.lift_energy is not None and bool(config.genre_stats.energy)
        return energy or ("jitter_cap" in config.enabled and config.jitter_cap is not None)

    def read_genre(self, audio_path: str | os.PathLike, *, start: float | None = None,
                   end: float | None = None) -> dict[str, float]:
        """The classifier's probability of each genre it knows for the song (excerpt), as it gives them."""
        return {} if self.genre_reader is None else self.genre_reader(audio_path, start=start, end=end)

    def choose_genre(self, requested: str, probs: dict[str, float], *, seed: int) -> GenreChoice:
        """The model alone (it has no genres), carrying the music's genre probabilities for the stages."""
        return GenreChoice(requested, None, None, probs)

    @torch.no_grad()
    def generate_batch(self, audio_path: str | os.PathLike, *, seeds: list[int], choices: list[GenreChoice],
                       start: float | None = None, end: float | None = None, progress: bool = False,
                       start_pose: Motion | np.ndarray | None = None, smooth_frames: int | None = None,
                       lowpass_hz: float | None = None) -> list[Motion]:
        """G_M→D's dances of ``seeds`` (the features once, each seed from its start pose on its own), filtered over
        time (:meth:`output_filter`) and decoded from rot6d.

        Parameters
        ----------
        start_pose : the first pose of every dance (a Motion on the model's skeleton, or a rot6d vector); None: each
            seed draws its start pose from the model's pool (the paper's diverse generation)
        smooth_frames : a centred moving average of that many frames over G_M→D's output (translation and 6D
            columns; the 6D are re-orthonormalised when decoded), 1 = none; default: the checkpoint's
            ``smooth_frames`` (chosen on the validation songs, docs/DUAL.md), else 1
        lowpass_hz : instead of the moving average, a zero-phase 4th-order Butterworth low-pass with this cut-off
            (Hz, :func:`lowpass`) over G_M→D's output; default: the checkpoint's ``lowpass_hz``. Giving
            ``smooth_frames`` alone uses the moving average; giving both is an error.
        """
        feats = torch.from_numpy(self.features(audio_path, start=start, end=end))[None]  # (1, T, 53)
        s = torch.stack([self.start_pose(start_pose, seed) for seed in seeds])  # (B, P)
        # each seed on its own, as a batch of one: the batched products round differently for every batch size
        # (and row), so a batch would not give bit for bit the dance of the seed alone
        y = np.stack([self.model.generate_dance(feats, start=s[k : k + 1],
                                                generator=torch.Generator().manual_seed(int(seed)))[0].cpu().numpy()
                      for k, seed in enumerate(seeds)])  # (B, T, P)
        return [decode_rot6d(self.stats.denormalize_dance(self.output_filter(y[k], smooth_frames, lowpass_hz)),
                             self.skeleton, self.fps, root_decode=self.root_decode) for k in range(len(seeds))]

    def output_filter(self, y: np.ndarray, smooth_frames: int | None = None,
                      lowpass_hz: float | None = None) -> np.ndarray:
        """G_M→D's output ``y (T, P)`` (normalised rot6d) filtered over time as the arguments or the checkpoint's
        settings say: the Butterworth low-pass when a cut-off applies, else the moving average."""
        if smooth_frames is not None and lowpass_hz is not None:
            raise ParameterError("give smooth_frames or lowpass_hz, not both")
        if lowpass_hz is None and smooth_frames is None:
            lowpass_hz = self.lowpass_hz
        if lowpass_hz is not None:
            return lowpass(y, cutoff_hz=lowpass_hz, fps=self.fps)
        return moving_average(y, self.smooth_frames if smooth_frames is None else int(smooth_frames))


@dataclass
class ComposeResult:
    """Music composed for a dance: G_D→M's chroma + beats, and the MIDI / audio made from them.

    Attributes
    ----------
    chroma : (T, 12) composed chroma in [0, 1], one row per motion frame
    beat : (T,) composed beat activation in [0, 1]
    fps : frames per second of both
    start_chord : the start token's chord, e.g. "A minor"
    arrangement : :class:`dancekit.audio.midi.Arrangement` (beats, chords, tempo, the PrettyMIDI object)
    seed : the random seed
    """

    chroma: np.ndarray
    beat: np.ndarray
    fps: float
    start_chord: str
    arrangement: Any
    seed: int

    def write(self, out_dir: str | os.PathLike, *, stem: str = "music", sr: int = 22050,
              render: str = "auto") -> dict[str, Path]:
        """Write ``stem.mid`` and ``stem.wav`` (FluidSynth when available, else the built-in synthesiser)."""
        from dancekit.audio.midi import write_arrangement

        return write_arrangement(self.arrangement, out_dir, stem=stem, sr=sr, backend=render)


class ComposePipeline:
    """Dance → music with G_D→M: a :class:`Motion` on the model's skeleton → :class:`ComposeResult`."""

    def __init__(self, model: DualModel, *, meta: dict[str, Any], stats: NormStats, folder: str = "?"):
        self.model, self.meta, self.stats, self.folder = model, meta, stats, str(folder)
        self.fps = float(meta["fps"])
        self.skeleton = Skeleton.from_dict(meta["skeleton"])
        # beat picking, the checkpoint's composing settings (chosen on the validation dances, docs/DUAL.md)
        sampling = checkpoint_settings(meta, folder=folder, sampling=DualSampling).sampling
        self.beat_threshold = sampling.beat_threshold
        self.beat_min_gap = sampling.beat_min_gap
        # "dance" (the arranger that follows the dance, pipelines/compose.py), or G_D→M's own beats: "auto"
        # (thresholded peaks) or "periodic"
        self.beat_tempo = sampling.beat_tempo

    @classmethod
    def from_pretrained(cls, folder: str | os.PathLike, *, device: str = "cpu") -> ComposePipeline:
        model, meta, stats, folder = _load(folder, device)
        return cls(model, meta=meta, stats=stats, folder=str(folder))

    @torch.no_grad()
    def __call__(self, motion: Motion, *, seed: int = 0, tempo: str | float | None = None,
                 root: int | str | None = None, minor: bool | None = None) -> ComposeResult:
        """Compose chroma + beats for ``motion`` and arrange them (chords on the beats, bass, drums).

        Parameters
        ----------
        motion : a 3D dance (resampled to the model's fps when it differs); a dance on another skeleton is
            mapped to the model's joints by role (:func:`dancekit.motion.retarget.map_by_role`)
        seed : draws the start chord (root of 12 pitch classes × major / minor) unless given
        tempo : "dance" (music that follows the dance: its tempo, beats and metre; G_D→M's chroma choosing the
            chords of the key and its beat activation the accents, :mod:`dancekit.pipelines.compose`), a BPM (the
            same at that tempo), "auto" (G_D→M's beats: peaks of its beat activation, chords on every beat,
            :func:`dancekit.audio.midi.arrange`), "periodic" (beats on the activation's periodicity,
            :func:`dancekit.audio.midi.periodic_beats`), or None: the checkpoint's ``beat_tempo`` setting
            ("dance" when it has none)
        root, minor : the start chord (e.g. ``root="A", minor=True``)
        """
        if not isinstance(motion, Motion):
            raise ParameterError(f"compose needs a Motion, got {type(motion).__name__}")
        motion = on_model_skeleton(motion, self.skeleton)
        if abs(motion.fps - self.fps) > 1e-6:
            motion = motion.resample(self.fps)
        g = torch.Generator().manual_seed(int(seed))
        if root is None:
            root = int(torch.randint(12, (1,), generator=g))
        if minor is None:
            minor = bool(torch.randint(2, (1,), generator=g))
        token = chord_token(root, bool(minor))
        y = torch.from_numpy(self.stats.normalize_dance(encode_motion(motion, "rot6d")))[None]  # (1, T, P)
        out = self.model.generate_music(y, start=token[None])[0].cpu().numpy()  # (T, 13)
        from dancekit.audio.midi import arrange

        chroma, beat = out[:, :12], out[:, 12]
        root_name = PITCH_CLASSES[int(root)] if not isinstance(root, str) else root
        tempo = self.beat_tempo if tempo is None else tempo
        if tempo in ("auto", "periodic"):
            arrangement = arrange(chroma, beat, fps=self.fps, tempo=tempo, threshold=self.beat_threshold,
                                  min_gap=self.beat_min_gap)
        else:
            from dancekit.pipelines.compose import follow

            arrangement = follow(motion, key=(PITCH_CLASSES.index(root_name), bool(minor)), chroma=chroma, activation=beat,
                                 bpm=None if tempo == "dance" else _bpm(tempo))
        return ComposeResult(chroma=chroma, beat=beat, fps=self.fps, seed=int(seed),
                             start_chord=f"{root_name} {'minor' if minor else 'major'}", arrangement=arrangement)


def _bpm(tempo: str | float) -> float:
    try:
        return float(tempo)
    except (TypeError, ValueError):
        raise ParameterError(f"tempo must be 'dance', 'auto', 'periodic' or a number of BPM, got {tempo!r}") from None


def moving_average(y: np.ndarray, frames: int) -> np.ndarray:
    """Centred moving average of ``frames`` (odd or even, ≥ 1) frames over ``y (T, P)``; the ends average the
    frames that exist. ``frames=1`` returns ``y``."""
    if not isinstance(frames, int) or frames < 1:
        raise ParameterError(f"smooth_frames must be a positive integer, got {frames!r}")
    if frames == 1 or len(y) == 0:
        return y
    a, b = (frames - 1) // 2, frames // 2
    c = np.cumsum(np.pad(np.asarray(y, np.float64), ((1, 0), (0, 0))), axis=0)  # (T + 1, P)
    idx = np.arange(len(y))
    lo, hi = np.clip(idx - a, 0, len(y)), np.clip(idx + b + 1, 0, len(y))
    return ((c[hi] - c[lo]) / (hi - lo)[:, None]).astype(y.dtype)


def lowpass(y: np.ndarray, *, cutoff_hz: float, fps: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass over time of ``y (T, P)`` sampled at ``fps``: ``order`` poles, run
    forwards and backwards (:func:`scipy.signal.sosfiltfilt`), so a sinusoid of frequency f keeps the
    amplitude ``1 / (1 + (f / cutoff_hz) ** (2 * order))`` (½ at the cut-off) and no phase shift; a constant
    stays constant. Odd padding at the ends (shortened for short inputs); fewer than 2 frames are returned as
    they are. Unlike a moving average it has no side lobes: it keeps the motion below the cut-off and removes
    the flicker above it (docs/DUAL.md)."""
    if not (isinstance(cutoff_hz, (int, float)) and 0 < cutoff_hz < fps / 2):
        raise ParameterError(f"lowpass_hz must be between 0 and the Nyquist frequency {fps / 2:g} Hz, got {cutoff_hz!r}")
    y = np.asarray(y)
    if len(y) < 2:
        return y
    from scipy.signal import butter, sosfiltfilt

    sos = butter(int(order), float(cutoff_hz), fs=float(fps), output="sos")
    padlen = min(3 * (2 * len(sos) + 1), len(y) - 1)
    return sosfiltfilt(sos, np.asarray(y, np.float64), axis=0, padlen=padlen).astype(y.dtype)


def on_model_skeleton(motion: Motion, skeleton: Skeleton) -> Motion:
    """``motion`` on the model's ``skeleton``: as it is when the joints are the same, else mapped by joint role
    (:func:`dancekit.motion.retarget.map_by_role`); a 2D dance or one lacking the limb and head roles is refused
    with a :class:`ParameterError` naming what is missing."""
    if motion.skeleton.dims == 3 and list(motion.skeleton.joint_names) == list(skeleton.joint_names):
        return motion
    if motion.skeleton.dims != 3:
        raise ParameterError(f"this model dances on the 3D {skeleton.name!r} skeleton; the motion is on the 2D "
                             f"{motion.skeleton.name!r} skeleton and cannot be mapped to it")
    from dancekit.motion.retarget import map_by_role

    return map_by_role(motion, skeleton)
