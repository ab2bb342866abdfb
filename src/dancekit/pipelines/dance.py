"""The base of every dance pipeline (music → motion), as diffusers' ``DiffusionPipeline``.

:class:`DancePipeline` does what every dance family shares: :meth:`~DancePipeline.from_pretrained` (the folder
resolved, the model, its statistics, its components and its settings loaded, the stage configuration parsed
once, the decoding precision set), :meth:`~DancePipeline.features`, :meth:`~DancePipeline.read_genre`,
:meth:`~DancePipeline.stage_options`, and :meth:`~DancePipeline.dances` / ``__call__``: the song's features and
beat strength once, the genre read once and chosen per seed, one call of the family's generation step per batch
of seeds that dance alike, a dance of an input that does not look like music calmed, then the stages of
:func:`~dancekit.pipelines.stages.finish` per dance.

A family writes its generation step, :meth:`~DancePipeline.generate_batch` ``(audio_path, *, seeds, choices,
start, end, progress, **options) -> list[Motion]`` (its own keyword options, e.g. a sampling temperature, are
arguments of it, and ``dances`` / ``__call__`` take them), and names its ``family``, its ``sampling_config`` and
the ``components`` it understands. Where its genres work otherwise than "read the most likely genre from the
music for ``"auto"``", it overrides the small hooks the steps call: :meth:`~DancePipeline.reads_genre` (when the
music's genre is read), :meth:`~DancePipeline.choose_genre` (what a seed dances: revolution's seed draws its
genre), :meth:`~DancePipeline.batch_key` (which seeds share a generation call), :meth:`~DancePipeline.danced_by`
and :meth:`~DancePipeline.calm`.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from dancekit.checkpoints import NormStats, components, load_pretrained, resolve_model
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.precision import check_precision, to_precision
from dancekit.motion import Motion, Skeleton
from dancekit.pipelines.base import (
    DanceResult,
    calm_motion,
    check_seeds,
    clean_motion,
    song_feature_set,
    song_features,
)
from dancekit.pipelines.config import (
    CheckpointSettings,
    EditConfig,
    NoSampling,
    StageConfig,
    checkpoint_settings,
)
from dancekit.pipelines.stages import Song, finish, seed_trace

__all__ = ["DancePipeline", "GenreChoice"]


@dataclass(frozen=True)
class GenreChoice:
    """What one seed of a :meth:`DancePipeline.dances` call dances (:meth:`DancePipeline.choose_genre`).

    Attributes
    ----------
    requested : the genre asked for: "auto", "none" or a genre of the model
    genre : the genre danced (None: the model alone)
    drawn_p : the probability with which the seed drew ``genre`` (None: not drawn)
    probs : the music's genre probabilities the dance carries (``DanceResult.genre_probs``; the stages read them)
    """

    requested: str
    genre: str | None = None
    drawn_p: float | None = None
    probs: dict[str, float] = field(default_factory=dict)



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
        """The probability of each of :attr:`genres` for the song (excerpt) read by the ``genre_reader``,
        renormalised over them; empty without a reader or without genres to dance."""
        if self.genre_reader is None or not self.genres:
            return {}
        probs = self.genre_reader(audio_path, start=start, end=end)
        probs = {g: probs[g] for g in self.genres if g in probs}
        total = sum(probs.values())
        return {g: p / total for g, p in probs.items()} if total > 0 else {}

    # --- the hooks of dances(): a family overrides those where its genres work otherwise ---------------------

    def reads_genre(self, requested: list[str], *, music: bool, config: StageConfig) -> bool:
        """Whether :meth:`dances` reads the music's genre (:meth:`read_genre`, once per call): ``requested`` the
        genre asked for per seed, ``music`` whether the input looks like music, ``config`` the stages that will
        run. Here: when a seed asks for "auto" and the input looks like music (no genre is read from what is not)."""
        return music and "auto" in requested

    def choose_genre(self, requested: str, probs: dict[str, float], *, seed: int) -> GenreChoice:
        """What the seed ``seed`` dances when ``requested`` ("auto", "none" or one of :attr:`genres`, checked
        already) was asked for and the music's genre probabilities are ``probs`` (empty: not read). Here: "auto"
        dances the most likely genre (the model alone without ``probs``) and carries ``probs``; "none" the model
        alone; a genre that genre."""
        if requested == "auto":
            return GenreChoice(requested, max(probs, key=probs.get) if probs else None, None, probs)
        return GenreChoice(requested, None if requested == "none" else requested)

    def batch_key(self, choice: GenreChoice) -> Hashable:
        """The seeds whose choices have one key are generated in one :meth:`generate_batch` call (in the order of
        the keys' first seeds). Here: one batch per genre danced."""
        return choice.genre

    def danced_by(self, genre: str | None) -> str:
        """The folder of the model that dances ``genre`` (``DanceResult.danced_by``). Here: this checkpoint's."""
        return self.folder

    def calm(self, motion: Motion, **options) -> Motion:
        """The dance of an input that does not look like music, calmed: :func:`~dancekit.pipelines.base.calm_motion`
        (40 % of the movement) then :func:`~dancekit.pipelines.base.clean_motion` (positions only, rest bone
        lengths, feet on the floor). ``options``: the call's options of :meth:`generate_batch`."""
        return clean_motion(calm_motion(motion))

    def generate_batch(self, audio_path: str | os.PathLike, *, seeds: list[int], choices: list[GenreChoice],
                       start: float | None = None, end: float | None = None, progress: bool = False,
                       **options) -> list[Motion]:
        """The family's generation step: one :class:`~dancekit.motion.Motion` per seed of ``seeds`` (the model's
        own dance, on :attr:`skeleton` at :attr:`fps`, one frame per feature frame; the same for a seed alone and in
        a batch), ``choices[k]`` what seed ``seeds[k]`` dances (all of one :meth:`batch_key`). A family's own
        keyword options (e.g. a sampling temperature) are keyword arguments here; :meth:`dances` passes them."""
        raise NotImplementedError(f"{type(self).__name__} must define generate_batch()")

    # --- the shared skeleton ---------------------------------------------------------------------------------

    @torch.no_grad()
    def __call__(self, audio_path: str | os.PathLike, *, seed: int = 0, **kwargs) -> DanceResult:
        """The dance of ``seed`` (:meth:`dances` with one seed; the same keyword arguments)."""
        return self.dances(audio_path, seeds=[seed], **kwargs)[0]

    @torch.no_grad()
    def dances(self, audio_path: str | os.PathLike, *, seeds: list[int], start: float | None = None,
               end: float | None = None, genre: str | list[str | None] | None = None, progress: bool = False,
               beat_sync: bool = True, cleanup: bool = True,
               stage_trace: Callable[[int, str, DanceResult], None] | None = None, edit: EditConfig | None = None,
               workers: int = 1, **options) -> list[DanceResult]:
        """One dance per seed for the song (excerpt ``[start, end)`` s); ``dances(song, seeds=[0, 1, 2])[k]`` is bit
        for bit ``pipe(song, seed=[0, 1, 2][k])``.

        The steps: the song's features and beat strength once; the music's genre read once where
        :meth:`reads_genre` says so and chosen per seed (:meth:`choose_genre`); :meth:`generate_batch` once per
        :meth:`batch_key`; a dance of an input that does not look like music (beat strength below
        :data:`dancekit.features.MUSIC_BEAT_STRENGTH`: silence, noise, speech, birdsong) calmed (:meth:`calm`);
        then the checkpoint's stages switched by ``beat_sync`` / ``cleanup``
        (:func:`~dancekit.pipelines.stages.finish`, the song's beats tracked once).

        Parameters
        ----------
        seeds : the seeds (a seed may repeat)
        start, end : the excerpt in seconds (None: from the beginning / to the end)
        genre : "auto" or None (the genre read from the music where the model has a music attribute classifier,
            else the model alone), "none" (the model alone), one of :attr:`genres`, or a list of those, one per seed
        progress : a progress bar over the generation
        beat_sync, cleanup : the shared stages (:mod:`dancekit.pipelines.stages`): the warp onto the song's beats;
            the clean-up, smoothing, energy lift, jitter cap and foot lock
        stage_trace : called as ``stage_trace(k, name, result)`` for the dance of ``seeds[k]`` at each step of
            :func:`~dancekit.pipelines.stages.finish` (``"input"``, then each stage that ran)
        edit : the user's constraints (:class:`~dancekit.pipelines.config.EditConfig`: a prefix, keyframes, a
            path, kept body parts), run by :func:`~dancekit.pipelines.stages.finish` (a path before the foot lock,
            the rest after every stage); None: none. A family whose :meth:`generate_batch` takes a ``prefix``
            (Dance Revolution) is also given the prefix's positions: the model continues the prefix (its decoder
            fed the prefix's poses), then the edit stage keeps the prefix exactly and fades the seam
        workers : processes that share the seeds (:func:`~dancekit.pipelines.parallel.fork_map`: forked after the
            song is read, each decoding and finishing a contiguous part of the seeds; Linux only, else one). Each
            dance is the same bit for bit; ``stage_trace`` runs everything in this process
        options : the family's own options, the keyword arguments of its :meth:`generate_batch`

        Raises
        ------
        ParameterError
            For no seeds, a genre the model does not know, or a bad option.
        TypeError
            For an option the family does not have.
        """
        from dancekit.features import MUSIC_BEAT_STRENGTH

        seeds = check_seeds(seeds)
        wanted = list(genre) if isinstance(genre, (list, tuple)) else [genre] * len(seeds)
        if len(wanted) != len(seeds):
            raise ParameterError(f"{len(wanted)} genres for {len(seeds)} seeds")
        requested = ["auto" if g is None else str(g) for g in wanted]
        for g in dict.fromkeys(requested):
            self._check_genre(g)
        self._check_options(options)
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ParameterError(f"workers must be an integer >= 1, got {workers!r}")
        strength = song_feature_set(audio_path, fps=self.fps, preset=self.preset, hop_length=self.hop_length,
                                    start=start, end=end).beat_strength
        measured = strength is not None and bool(np.isfinite(strength))
        music = not (measured and strength < MUSIC_BEAT_STRENGTH)  # not measured: as music
        config = self.stage_options(beat_sync=beat_sync, cleanup=cleanup)
        if edit is not None:
            config = dataclasses.replace(config, edit=edit)
        probs = (self.read_genre(audio_path, start=start, end=end)
                 if self.reads_genre(requested, music=music, config=config) else {})
        choices = [self.choose_genre(r, probs, seed=s) for r, s in zip(requested, seeds)]
        keys = [self.batch_key(c) for c in choices]
        if edit is not None and edit.prefix is not None and "prefix" in inspect.signature(self.generate_batch).parameters:
            from dancekit.pipelines.stages import read_edit_motion

            options = {**options, "prefix": read_edit_motion(edit.prefix, self.skeleton, self.fps, "prefix")}
        song = Song(audio_path, start, end)  # its beats tracked once, for the first dance that needs them

        def part(ks: list[int]) -> list[DanceResult]:  # the dances of seeds[k] for k in ks
            motions: dict[int, Motion] = {}
            for key in dict.fromkeys(keys[k] for k in ks):
                rows = [k for k in ks if keys[k] == key]
                done = self.generate_batch(audio_path, seeds=[seeds[k] for k in rows],
                                           choices=[choices[k] for k in rows], start=start, end=end,
                                           progress=progress and ks[0] == 0, **options)
                if len(done) != len(rows):
                    raise RuntimeError(f"{type(self).__name__}.generate_batch gave {len(done)} dances for {len(rows)} "
                                       "seeds")
                motions.update(zip(rows, done))
            results = []
            for k in ks:
                seed, choice, motion = seeds[k], choices[k], motions[k]
                result = DanceResult(motion=motion if music else self.calm(motion, **options), model=self.folder,
                                     seed=seed, genre_requested=choice.requested, genre=choice.genre,
                                     genre_probs=dict(choice.probs), danced_by=self.danced_by(choice.genre),
                                     beat_strength=float(strength) if measured else None, looks_like_music=music,
                                     genre_drawn_p=choice.drawn_p)
                results.append(finish(result, song, config, trace=seed_trace(stage_trace, k)))
            return results

        n = min(workers, len(seeds)) if stage_trace is None else 1
        if n > 1:
            from dancekit.pipelines.parallel import fork_map

            bounds = np.linspace(0, len(seeds), n + 1).round().astype(int)
            parts = [list(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]
            return [r for rs in fork_map(part, parts) for r in rs]
        return part(list(range(len(seeds))))

    def _check_genre(self, genre: str) -> None:
        if genre in ("auto", "none") or genre in self.genres:
            return
        if not self.genres:
            raise ParameterError(f"this {self.family or type(self).__name__} model has no genres; cannot dance "
                                 f"{genre!r} (use --genre auto or none)")
        raise ParameterError(f"unknown genre {genre!r} for this model; choose from {', '.join(self.genres)}, "
                             "auto or none")

    def _check_options(self, options: dict[str, Any]) -> None:
        params = inspect.signature(self.generate_batch).parameters
        if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
            return
        named = {"seeds", "choices", "start", "end", "progress"}
        unknown = [k for k in options if k not in params or k in named]
        if unknown:
            raise TypeError(f"{type(self).__name__}.dances() got an unexpected keyword argument {unknown[0]!r}")
