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
from typing import Any

import numpy as np
import torch

from dancekit.checkpoints import NormStats
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.music2dance import Music2DanceModel
from dancekit.motion import Motion
from dancekit.motion.analysis import floor_curve
from dancekit.motion.root_delta import decode_rootdelta, encode_rootdelta
from dancekit.pipelines.config import CheckpointSettings, Music2DanceSampling
from dancekit.pipelines.dance import DancePipeline, GenreChoice
from dancekit.pipelines.music_attributes import MusicAttributePipeline


class Music2DancePipeline(DancePipeline):
    """Generate a dance for a whole song with a trained :class:`Music2DanceModel`.

    ``pipe(song, seed=0, genre="auto", start=None, end=None, beat_sync=True, cleanup=True, temperature=None,
    genre_scale=None)`` and ``pipe.dances(song, seeds=[...], ...)`` (:meth:`DancePipeline.dances
    <dancekit.pipelines.dance.DancePipeline.dances>`, ``genre`` also a list: one dance type per seed); this family's
    own options are those of :meth:`generate_batch` (``temperature``, ``genre_scale``, ``music``). The dance has one
    frame per feature frame, rotations on the skeleton's rig and world positions (skeleton units), feet on the floor.

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
        super().__init__(model, meta=meta, stats=stats, folder=folder, settings=settings, genre_reader=genre_reader)
        self._genres = tuple(meta.get("genres", ()))[: model.config.n_genres]
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

    def reads_genre(self, requested: list[str], *, music: bool, config) -> bool:
        """When a seed asks for "auto" (the dance type is read from any input, music or not)."""
        return "auto" in requested

    def batch_key(self, choice: GenreChoice) -> str | None:
        """Seeds whose genre is named and has its own sampling (:attr:`genre_sampling`) are one batch per such
        genre; all others one batch (each row with its own dance type)."""
        return choice.requested if choice.requested in self.genre_sampling else None

    @torch.no_grad()
    def generate_batch(self, audio_path: str | os.PathLike, *, seeds: list[int], choices: list[GenreChoice],
                       start: float | None = None, end: float | None = None, progress: bool = False,
                       temperature: float | None = None, genre_scale: float | None = None,
                       music: np.ndarray | None = None, prefix: np.ndarray | None = None) -> list[Motion]:
        """The dances of ``seeds`` (each seed's frame loop on its own, one dance type per row), sampled with the
        settings of the batch's named genre (:attr:`genre_sampling`) over the plain ones.

        Parameters
        ----------
        temperature : scales the sampled variances (and sharpens the mixture weights); 0 takes the means;
            None: the checkpoint's (:attr:`temperature`, or the named genre's)
        genre_scale : guidance α of the dance type (``g_∅ + α (g - g_∅)``, see
            :meth:`Music2DanceModel.guided_genre_vector`); None: the checkpoint's (:attr:`genre_scale`, or the
            named genre's)
        music : the song's features ``(T, music_dim)`` at the checkpoint's preset and fps, computed already (e.g. a
            prepared dataset's), instead of extracting them from ``audio_path``
        prefix : world positions ``(N, J, 3)`` on this model's skeleton at its fps: the dance's first N frames
            (their ``rotations_rootdelta`` features, the rotations by inverse kinematics), fed to the WaveNet as its
            previous frames (:meth:`Music2DanceModel.generate`'s ``prefix``): the dance continues from the last

        Raises
        ------
        ParameterError
            For a negative temperature or genre scale, or ``music`` of the wrong shape.
        """
        key = self.batch_key(choices[0])
        steer = self.genre_sampling.get(key, {}) if key is not None else {}
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
        if music is None:
            feats = self.features(audio_path, start=start, end=end)
        else:
            music = np.asarray(music, np.float32)
            if music.ndim != 2 or music.shape[1] != self.model.config.music_dim:
                raise ParameterError(f"music features must be (T, {self.model.config.music_dim}), got {music.shape}")
            feats = self.stats.normalize_music(music).astype(np.float32)
        x = torch.from_numpy(feats)[None]  # (1, T, D)
        B = len(seeds)
        index = torch.tensor([self.genres.index(c.genre) if c.genre is not None else -1 for c in choices])
        gens = [torch.Generator().manual_seed(s) for s in seeds]
        window = self.meta.get("train", {}).get("seq_len")  # F_map on windows as long as the training ones
        x = x.to(self.model.genre_embedding.weight.device).expand(B, -1, -1)
        given = None
        if prefix is not None:
            rows = encode_rootdelta(Motion(skeleton=self.skeleton, fps=self.fps,
                                           positions=np.asarray(prefix, np.float32)))  # (N, P), IK rotations
            given = torch.from_numpy(self.stats.normalize_dance(rows).astype(np.float32))[None].to(x.device)
        y = self.model.generate(x, index, temperature=temperature, generator=gens, progress=progress,
                                fmap_window=window, noise_correlation=noise_correlation,
                                genre_scale=genre_scale, prefix=given)  # (B, T, P)
        if smooth_sigma > 0:
            from dancekit.models.foot_constraint import gaussian_smooth

            D = self.model.config.gmm_dim
            y = torch.cat([torch.cat([gaussian_smooth(row[None, :, :D], smooth_sigma), row[None, :, D:]], -1)
                           for row in y])  # row by row: each seed's dance as it is alone
        return [on_the_floor(decode_rootdelta(self.stats.denormalize_dance(y[k].cpu().numpy().astype(np.float64)),
                                              self.skeleton, self.fps)) for k in range(B)]


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
