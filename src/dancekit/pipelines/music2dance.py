"""Music2Dance inference: a song → a dance with the WaveNet of §4.4 (inference only).

    >>> pipe = Music2DancePipeline.from_pretrained("runs/m2d/model")          # doctest: +SKIP
    >>> result = pipe("song.ogg", seed=0, genre="waltz", temperature=1.0)      # doctest: +SKIP

The checkpoint folder carries the model (with its F_map), the feature preset, fps and hop length, the
skeleton, the genres (dance types, in the order of the model's genre condition) and the normalisation
statistics (the contact columns have mean 0 and std 1: they are 0/1 flags). A folder may also declare a
music attribute classifier (``"components": {"genre_reader": "music_attributes"}``) that reads the dance
type from the music for ``genre="auto"``.

F_map (its BiLSTM) runs on windows as long as the training windows (``train.seq_len`` of the checkpoint),
each frame's music condition taken from the window where it is farthest from the edges, so a 10-minute
song is conditioned as the training windows were. Generation samples the mixture frame by frame (each frame O(layers), :meth:`Music2DanceModel.generate`), so
different seeds give different dances; the motion is decoded from ``rotations_rootdelta`` (integrated root
deltas + forward kinematics of the rotations) and put on the floor: the running floor of the feet
(:func:`~dancekit.motion.analysis.floor_curve`) is moved to height 0 at every frame, so the dancer
neither sinks nor floats away however long the song.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from dancekit.checkpoints import NormStats
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.music2dance import Music2DanceModel
from dancekit.motion import Motion, Skeleton
from dancekit.motion.analysis import floor_curve
from dancekit.motion.root_delta import decode_rootdelta
from dancekit.pipelines.base import DanceResult, calm_if_not_music, check_seeds
from dancekit.pipelines.config import CheckpointSettings, Music2DanceSampling, checkpoint_settings
from dancekit.pipelines.dance import DancePipeline
from dancekit.pipelines.music_attributes import MusicAttributePipeline
from dancekit.pipelines.stages import Song, finish, seed_trace


class Music2DancePipeline(DancePipeline):
    """Generate a dance for a whole song with a trained :class:`Music2DanceModel`.

    Parameters
    ----------
    model : the trained model
    meta : the checkpoint's ``config.json`` (needs ``fps``, ``skeleton``; ``genres`` for a genre condition)
    stats : the normalisation statistics
    genre_reader : a music attribute classifier for ``genre="auto"`` (or None)
    """

    family = "music2dance"
    sampling_config = Music2DanceSampling
    component_names = ("genre_reader", "foot_constraint")  # the foot model: dancekit dance --foot-constraint

    def __init__(self, model: Music2DanceModel, *, meta: dict[str, Any], stats: NormStats, folder: str = "?",
                 genre_reader: MusicAttributePipeline | None = None, settings: CheckpointSettings | None = None):
        if not isinstance(model, Music2DanceModel):
            raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a Music2Dance model")
        for key in ("fps", "skeleton"):
            if key not in meta:
                raise CheckpointError(f"checkpoint {folder}: config.json has no {key!r} entry")
        if meta.get("representation", "rotations_rootdelta") != "rotations_rootdelta":
            raise CheckpointError(f"checkpoint {folder}: a Music2Dance model needs the rotations_rootdelta "
                                  f"representation, not {meta.get('representation')!r}")
        self.model = model.eval()
        self.meta, self.folder, self.stats = meta, str(folder), stats
        self.fps = float(meta["fps"])
        self.preset = str(meta.get("preset", "music2dance"))
        self.hop_length = int(meta.get("hop_length", 512))
        self.skeleton = Skeleton.from_dict(meta["skeleton"])
        self._genres = tuple(meta.get("genres", ()))[: model.config.n_genres]
        self.genre_reader = genre_reader
        #: the checkpoint's stage settings and sampling (:func:`~dancekit.pipelines.config.checkpoint_settings`)
        self.settings = settings if settings is not None else checkpoint_settings(meta, folder=folder,
                                                                                  sampling=Music2DanceSampling)
        sampling = self.settings.sampling
        #: sampling temperature when a call names none: the checkpoint's ``"sampling": {"temperature": t}``
        #: (chosen on the validation songs for the embedded model), else 1 (the mixture as trained)
        self.temperature = sampling.temperature
        #: correlation of the sampling noise from frame to frame (:meth:`Music2DanceModel.generate`), the
        #: checkpoint's ``"sampling": {"noise_correlation": ρ}`` (default 0: independent, the paper's)
        self.noise_correlation = sampling.noise_correlation
        #: Gaussian smoothing (frames) of the sampled features before decoding, contacts excepted (the
        #: checkpoint's ``"sampling": {"smooth_sigma": s}``; default 0: none)
        self.smooth_sigma = sampling.smooth_sigma
        #: guidance of the dance type when a call names none (:meth:`Music2DanceModel.guided_genre_vector`):
        #: the checkpoint's ``"sampling": {"genre_scale": α}`` (chosen on the validation songs for the
        #: embedded model), else 1 (the model as trained)
        self.genre_scale = sampling.genre_scale
        #: sampling per genre when that genre is asked for by name (``genre="tango"``, ``--genre tango``): the
        #: checkpoint's ``"sampling": {"genres": {genre: {"temperature": t, "noise_correlation": ρ, "smooth_sigma": s,
        #: "genre_scale": α}}}`` (any subset; the rest as :attr:`temperature` etc.), chosen on the validation
        #: songs for the embedded model so that the style classifier reads the genre back; "auto", "none" and
        #: the genres not listed keep the plain settings
        unknown = [g for g, _ in sampling.genres if g not in self.genres]
        if unknown:
            raise CheckpointError(f"checkpoint {folder}: config.json: sampling.genres.{unknown[0]} is not a genre of "
                                  f"the model ({', '.join(self.genres) or 'none'})")
        self.genre_sampling = {g: spec.settings() for g, spec in sampling.genres}
        if len(stats.music_mean) != model.config.music_dim or len(stats.dance_mean) != model.config.pose_dim:
            raise CheckpointError(f"checkpoint {folder}: statistics ({len(stats.music_mean)}, {len(stats.dance_mean)}) "
                                  f"do not match the model ({model.config.music_dim}, {model.config.pose_dim})")

    @property
    def genres(self) -> tuple[str, ...]:
        """The dance types of the model's genre condition (in its order)."""
        return self._genres

    def _genre(self, genre: str | None, audio_path, start, end) -> tuple[str, str | None, dict[str, float]]:
        requested = "auto" if genre is None else str(genre)
        if requested == "none":
            return requested, None, {}
        if requested == "auto":
            if self.genre_reader is None or not self.genres:
                return requested, None, {}
            probs = self.genre_reader(audio_path, start=start, end=end)
            probs = {g: probs[g] for g in self.genres if g in probs}
            total = sum(probs.values())
            if total <= 0:
                return requested, None, {}
            probs = {g: p / total for g, p in probs.items()}
            return requested, max(probs, key=probs.get), probs
        if requested not in self.genres:
            known = ", ".join(self.genres) or "none (the model has no dance-type condition)"
            raise ParameterError(f"unknown genre {requested!r} for this model; choose from {known}, auto or none")
        return requested, requested, {}

    @torch.no_grad()
    def __call__(self, audio_path: str | os.PathLike, *, seed: int = 0, genre: str | None = None,
                 temperature: float | None = None, start: float | None = None, end: float | None = None,
                 progress: bool = False, beat_sync: bool = True, cleanup: bool = True,
                 genre_scale: float | None = None) -> DanceResult:
        """A dance for the song ``audio_path`` (or its excerpt ``[start, end)`` seconds).

        Parameters
        ----------
        seed : seeds the mixture sampling; the same seed gives the same dance
        genre : a dance type of :attr:`genres`; "auto"/None: read from the music by the folder's classifier when
            it has one (else "none"); "none": no dance type (the model's own learned "none" condition)
        temperature : scales the sampled variances (and sharpens the mixture weights); 0 takes the means;
            None: the checkpoint's default (:attr:`temperature`)
        start, end : excerpt in seconds
        beat_sync, cleanup : the shared pipeline stages (:mod:`dancekit.pipelines.stages`)
        genre_scale : guidance α of the dance type (``g_∅ + α (g - g_∅)``, see
            :meth:`Music2DanceModel.guided_genre_vector`); None: the checkpoint's default (:attr:`genre_scale`)

        Returns
        -------
        :class:`DanceResult` whose ``.motion`` has one frame per feature frame, rotations on the skeleton's
        rig and world positions (skeleton units), feet on the floor.

        Raises
        ------
        ParameterError
            For an unknown genre or a negative temperature.
        """
        return self.dances(audio_path, seeds=[seed], genre=genre, temperature=temperature, start=start, end=end,
                           progress=progress, beat_sync=beat_sync, cleanup=cleanup, genre_scale=genre_scale)[0]

    @torch.no_grad()
    def dances(self, audio_path: str | os.PathLike, *, seeds: list[int], genre: str | list[str | None] | None = None,
               temperature: float | None = None, start: float | None = None, end: float | None = None,
               progress: bool = False, music: np.ndarray | None = None, beat_sync: bool = True,
               cleanup: bool = True, genre_scale: float | None = None,
               stage_trace: Callable[[int, str, DanceResult], None] | None = None) -> list[DanceResult]:
        """One dance per seed for the song (the features and the genre reading once, each seed's frame loop on
        its own): ``dances(song, seeds=[0, 1, 2])[k]`` is bit for bit ``pipe(song, seed=[0, 1, 2][k])``. Arguments as
        :meth:`__call__`; ``genre`` may also be a list, one genre per seed (a row's dance type). ``music``:
        the song's features ``(T, music_dim)`` at the checkpoint's preset and fps, computed already (e.g. a
        prepared dataset's), instead of extracting them from ``audio_path``. Rows whose genre is named and has
        an entry in :attr:`genre_sampling` sample with it over the plain settings (one batch per such genre);
        ``temperature`` / ``genre_scale`` given here override both.
        ``stage_trace``: called as ``stage_trace(k, name, result)`` for the dance of ``seeds[k]`` at each step of
        :func:`~dancekit.pipelines.stages.finish` (its ``trace``: ``"input"``, then each stage that ran)."""
        seeds = check_seeds(seeds)
        wanted = list(genre) if isinstance(genre, (list, tuple)) else [genre] * len(seeds)
        if len(wanted) != len(seeds):
            raise ParameterError(f"{len(wanted)} genres for {len(seeds)} seeds")
        # rows whose genre is named and has its own sampling settings: one batch per such genre
        keys = [str(g) if g is not None and str(g) in self.genre_sampling else None for g in wanted]
        if len(set(keys)) > 1:
            out: list[DanceResult | None] = [None] * len(seeds)
            for key in dict.fromkeys(keys):
                rows = [k for k, x in enumerate(keys) if x == key]
                part = self.dances(audio_path, seeds=[seeds[k] for k in rows], genre=[wanted[k] for k in rows],
                                   temperature=temperature, start=start, end=end, progress=progress, music=music,
                                   beat_sync=beat_sync, cleanup=cleanup, genre_scale=genre_scale)
                for k, r in zip(rows, part):
                    out[k] = r
            return out
        steer = self.genre_sampling.get(keys[0], {}) if keys[0] is not None else {}
        noise_correlation = steer.get("noise_correlation", self.noise_correlation)
        smooth_sigma = steer.get("smooth_sigma", self.smooth_sigma)
        if temperature is None:
            temperature = steer.get("temperature", self.temperature)
        if genre_scale is None:
            genre_scale = steer.get("genre_scale", self.genre_scale)
        if not temperature >= 0:
            raise ParameterError(f"temperature must be >= 0, got {temperature!r}")
        genre_scale = float(genre_scale)
        if not (np.isfinite(genre_scale) and genre_scale >= 0):
            raise ParameterError(f"genre_scale must be a finite number >= 0, got {genre_scale!r}")
        read = {g: self._genre(g, audio_path, start, end) for g in dict.fromkeys(wanted)}  # (requested, danced, probs)
        if music is None:
            feats = self.features(audio_path, start=start, end=end)
        else:
            music = np.asarray(music, np.float32)
            if music.ndim != 2 or music.shape[1] != self.model.config.music_dim:
                raise ParameterError(f"music features must be (T, {self.model.config.music_dim}), got {music.shape}")
            feats = self.stats.normalize_music(music).astype(np.float32)
        x = torch.from_numpy(feats)[None]  # (1, T, D)
        B = len(seeds)
        index = torch.tensor([self.genres.index(read[g][1]) if read[g][1] is not None else -1 for g in wanted])
        gens = [torch.Generator().manual_seed(s) for s in seeds]
        window = self.meta.get("train", {}).get("seq_len")  # F_map on windows as long as the training ones
        x = x.to(self.model.genre_embedding.weight.device).expand(B, -1, -1)
        y = self.model.generate(x, index, temperature=temperature, generator=gens, progress=progress,
                                fmap_window=window, noise_correlation=noise_correlation,
                                genre_scale=genre_scale)  # (B, T, P)
        if smooth_sigma > 0:
            from dancekit.models.foot_constraint import gaussian_smooth

            D = self.model.config.gmm_dim
            y = torch.cat([torch.cat([gaussian_smooth(row[None, :, :D], smooth_sigma), row[None, :, D:]], -1)
                           for row in y])  # row by row: each seed's dance as it is alone
        out = []
        song = Song(audio_path, start, end)  # its beats tracked once, for the first dance that needs them
        config = self.stage_options(beat_sync=beat_sync, cleanup=cleanup)
        for k, (seed, g) in enumerate(zip(seeds, wanted)):
            requested, danced, probs = read[g]
            poses = self.stats.denormalize_dance(y[k].cpu().numpy().astype(np.float64))
            motion = on_the_floor(decode_rootdelta(poses, self.skeleton, self.fps))
            out.append(DanceResult(motion=motion, model=self.folder, seed=seed, genre_requested=requested,
                                   genre=danced, genre_probs=probs, danced_by=self.folder))
            out[-1] = calm_if_not_music(out[-1], audio_path, fps=self.fps, preset=self.preset,
                                        hop_length=self.hop_length, start=start, end=end)
            out[-1] = finish(out[-1], song, config, trace=seed_trace(stage_trace, k))
        return out


def on_the_floor(motion: Motion) -> Motion:
    """The motion moved vertically so that its running floor (:func:`floor_curve`) is at 0 at every frame."""
    sk = motion.skeleton
    pos = np.asarray(motion.to_positions(), np.float64)
    floor = floor_curve(pos, sk, fps=motion.fps)  # (T,)
    pos[..., sk.up_index] -= floor[:, None]
    tr = np.asarray(motion.root_translation, np.float64).copy()
    tr[:, sk.up_index] -= floor
    return Motion(skeleton=sk, fps=motion.fps, positions=pos.astype(np.float32),
                  rotations=np.asarray(motion.rotations, np.float32), root_translation=tr.astype(np.float32))
