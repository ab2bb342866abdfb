"""The base of every dance pipeline (music → motion), as diffusers' ``DiffusionPipeline``.

:class:`DancePipeline` does what every dance family shares: :meth:`~DancePipeline.from_pretrained` (the folder
resolved, the model, its statistics, its components and its settings loaded, the stage configuration parsed
once, the decoding precision set), :meth:`~DancePipeline.features`, :meth:`~DancePipeline.read_genre`,
:meth:`~DancePipeline.stage_options` and :meth:`~DancePipeline.dances` (the genre read once, the family's
generation step, a dance that does not look like music calmed, the stages of
:func:`~dancekit.pipelines.stages.finish` per dance). A family writes its generation step,
:meth:`~DancePipeline.generate` ``(audio_path, *, seeds, start, end, genre, progress) -> list[Motion]``, and
names its ``family``, its ``sampling_config`` and the ``components`` it understands; a family whose generation
is tied to its genre handling (revolution's genre models, music2dance's per-genre sampling, dual's start poses)
overrides :meth:`~DancePipeline.dances` as well.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from dancekit.checkpoints import NormStats, components, load_pretrained, resolve_model
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.precision import check_precision, to_precision
from dancekit.motion import Motion, Skeleton
from dancekit.pipelines.base import DanceResult, calm_if_not_music, check_seeds, song_features
from dancekit.pipelines.config import CheckpointSettings, NoSampling, StageConfig, checkpoint_settings
from dancekit.pipelines.stages import Song, finish, seed_trace

__all__ = ["DancePipeline"]


class DancePipeline:
    """A song → dances pipeline of one checkpoint (subclassed once per family).

    Parameters
    ----------
    model : the family's model (in eval mode from here on)
    meta : the checkpoint's ``config.json`` (needs ``fps`` and ``skeleton``)
    stats : the normalisation statistics
    folder : the checkpoint folder (stamped on every dance as ``result.model``)
    settings : the parsed ``stages`` / ``sampling`` / ``genre_stats`` (None: parsed from ``meta`` here)
    genre_reader : a music attribute classifier (the ``"genre_reader"`` component) or None
    """

    #: the registry name of the family (:mod:`dancekit.registry`)
    family: ClassVar[str] = ""
    #: the family's sampling settings dataclass (the checkpoint's ``"sampling"`` entry)
    sampling_config: ClassVar[type] = NoSampling
    #: the components a checkpoint of this family may declare (``"components"`` in its ``config.json``)
    component_names: ClassVar[tuple[str, ...]] = ("genre_reader",)
    #: the pipeline decodes at ``"fp32"``, ``"bf16"`` or ``"int8"`` (:func:`dancekit.models.precision.to_precision`)
    supports_precision: ClassVar[bool] = True

    def __init__(self, model: torch.nn.Module, *, meta: dict[str, Any], stats: NormStats, folder: str = "?",
                 settings: CheckpointSettings | None = None, genre_reader=None):
        for key in ("fps", "skeleton"):
            if key not in meta:
                raise CheckpointError(f"checkpoint {folder}: config.json has no {key!r} entry")
        self.model = model.eval()
        self.meta, self.stats, self.folder = meta, stats, str(folder)
        self.fps = float(meta["fps"])
        self.hop_length = int(meta.get("hop_length", 512))
        self.preset = str(meta.get("preset", self.family))
        self.skeleton = Skeleton.from_dict(meta["skeleton"])
        self.genre_reader = genre_reader
        #: the checkpoint's stage settings and sampling (:func:`~dancekit.pipelines.config.checkpoint_settings`)
        self.settings = settings if settings is not None else checkpoint_settings(meta, folder=folder,
                                                                                  sampling=self.sampling_config)
        self.precision = "fp32"

    @classmethod
    def from_pretrained(cls, folder: str | os.PathLike, *, device: str = "cpu", precision: str = "fp32"):
        """Load a checkpoint folder (``dancekit train FAMILY``, ``save_pretrained``) or a model name
        (:func:`dancekit.checkpoints.resolve_model`): the model, its statistics, its components (a
        ``"genre_reader"`` is loaded here), its settings (parsed once); ``precision``: ``"fp32"``, ``"bf16"`` or
        ``"int8"`` decoding.

        Raises
        ------
        CheckpointError
            For a missing or corrupt folder, one that holds another family, a component this family does not
            understand, or a bad or unknown setting (naming the key and the folder).
        """
        check_precision(precision)
        folder = Path(resolve_model(folder))
        model, meta, arrays = load_pretrained(folder, device=device)
        stats = NormStats.from_arrays(arrays, source=str(folder))
        parts = components(folder, meta)
        unknown = sorted(set(parts) - set(cls.component_names))
        if unknown:
            raise CheckpointError(f"checkpoint {folder}: unknown components {unknown} for a {cls.family} model "
                                  f"(it understands {', '.join(repr(c) for c in cls.component_names) or 'none'})")
        settings = checkpoint_settings(meta, folder=folder, sampling=cls.sampling_config)
        pipe = cls.from_parts(model, meta=meta, stats=stats, folder=folder, settings=settings, parts=parts,
                              device=device)
        pipe.set_precision(precision)
        return pipe

    @classmethod
    def from_parts(cls, model, *, meta: dict[str, Any], stats: NormStats, folder: Path, settings: CheckpointSettings,
                   parts: dict[str, Any], device: str):
        """The pipeline from a loaded checkpoint (:meth:`from_pretrained`'s last step; a family with more
        components loads them here)."""
        reader = None
        if "genre_reader" in parts:
            from dancekit.pipelines.music_attributes import MusicAttributePipeline

            reader = MusicAttributePipeline.from_pretrained(parts["genre_reader"], device=device)
        return cls(model, meta=meta, stats=stats, folder=str(folder), settings=settings, genre_reader=reader)

    def set_precision(self, precision: str) -> None:
        """Decode at ``precision`` from now on (``"fp32"``, ``"bf16"`` or ``"int8"``)."""
        check_precision(precision)
        if not hasattr(self, "_fp32_model"):
            self._fp32_model = self.model
        self.model = to_precision(self._fp32_model, precision)
        self.precision = precision

    def stage_options(self, **switches) -> StageConfig:
        """The checkpoint's stage configuration switched as given (:meth:`StageConfig.switched
        <dancekit.pipelines.config.StageConfig.switched>`: ``beat_sync``, ``cleanup``, ``foot_lock``, ``smooth``,
        ``energy``): what :func:`~dancekit.pipelines.stages.finish` runs; :meth:`dances` passes it, and so does
        ``dancekit dance`` when it runs the stages itself (a foot model, ``--smooth`` / ``--foot-lock``)."""
        return self.settings.stages.switched(**switches)

    @property
    def genres(self) -> tuple[str, ...]:
        """The genres this model can be asked for (none here: a family with genres says which)."""
        return ()

    def features(self, audio_path: str | os.PathLike, *, start: float | None = None,
                 end: float | None = None) -> np.ndarray:
        """Normalised music features ``(T, music_dim)`` of the song (excerpt) at the checkpoint's fps and preset."""
        feats = song_features(audio_path, fps=self.fps, preset=self.preset, hop_length=self.hop_length,
                              music_dim=self.model.config.music_dim, start=start, end=end)
        return self.stats.normalize_music(feats)

    def read_genre(self, audio_path: str | os.PathLike, *, start: float | None = None,
                   end: float | None = None) -> dict[str, float]:
        """The probability of each genre for the song (excerpt) read by the ``genre_reader`` (renormalised over
        its genres); empty without a reader."""
        if self.genre_reader is None:
            return {}
        probs = self.genre_reader(audio_path, start=start, end=end)
        total = sum(probs.values())
        return {g: p / total for g, p in probs.items()} if total > 0 else {}

    def generate(self, audio_path: str | os.PathLike, *, seeds: list[int], start: float | None = None,
                 end: float | None = None, genre: str | None = None, progress: bool = False) -> list[Motion]:
        """The family's generation step: one :class:`~dancekit.motion.Motion` per seed (the model's own dance,
        on :attr:`skeleton` at :attr:`fps`, one frame per feature frame), the same for a seed alone and in a batch."""
        raise NotImplementedError(f"{type(self).__name__} must define generate()")

    @torch.no_grad()
    def __call__(self, audio_path: str | os.PathLike, *, seed: int = 0, **kwargs) -> DanceResult:
        """The dance of ``seed`` (:meth:`dances` with one seed; the same keyword arguments)."""
        return self.dances(audio_path, seeds=[seed], **kwargs)[0]

    @torch.no_grad()
    def dances(self, audio_path: str | os.PathLike, *, seeds: list[int], start: float | None = None,
               end: float | None = None, genre: str | None = None, progress: bool = False, beat_sync: bool = True,
               cleanup: bool = True,
               stage_trace: Callable[[int, str, DanceResult], None] | None = None) -> list[DanceResult]:
        """One dance per seed for the song (excerpt ``[start, end)`` s): the genre read once (``genre`` "auto" or
        None, with a ``genre_reader``), :meth:`generate`, a dance of an input that does not look like music
        calmed (:func:`~dancekit.pipelines.base.calm_if_not_music`), then the stages switched by ``beat_sync`` /
        ``cleanup`` (:func:`~dancekit.pipelines.stages.finish`, ``stage_trace(k, name, result)`` per stage).

        Raises
        ------
        ParameterError
            For an empty ``seeds`` or a genre the model does not know."""
        seeds = check_seeds(seeds)
        requested = "auto" if genre is None else str(genre)
        if requested not in ("auto", "none") and requested not in self.genres:
            raise ParameterError(f"unknown genre {requested!r} for this model; choose from "
                                 f"{', '.join(self.genres) or 'none (it has no genres)'}, auto or none")
        probs = self.read_genre(audio_path, start=start, end=end) if requested == "auto" else {}
        danced = requested if requested in self.genres else None
        motions = self.generate(audio_path, seeds=seeds, start=start, end=end, genre=danced, progress=progress)
        song = Song(audio_path, start, end)  # its beats tracked once, for the first dance that needs them
        config = self.stage_options(beat_sync=beat_sync, cleanup=cleanup)
        results = []
        for k, (seed, motion) in enumerate(zip(seeds, motions)):
            result = DanceResult(motion=motion, model=self.folder, seed=seed, genre_requested=requested,
                                 genre=danced, genre_probs=dict(probs), danced_by=self.folder)
            result = calm_if_not_music(result, audio_path, fps=self.fps, preset=self.preset,
                                       hop_length=self.hop_length, start=start, end=end)
            results.append(finish(result, song, config, trace=seed_trace(stage_trace, k)))
        return results
