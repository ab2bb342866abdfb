"""Dance Revolution inference: a song → a :class:`~dancekit.motion.Motion` (inference only).

    >>> pipe = RevolutionPipeline.from_pretrained("runs/revolution/model")   # doctest: +SKIP
    >>> motion = pipe("song.ogg", seed=0).motion                              # doctest: +SKIP

The checkpoint folder carries everything: the model configuration and weights, the feature preset,
fps and hop length the model was trained with, the pose representation, the skeleton and the
normalisation statistics (:mod:`dancekit.checkpoints`).

A dance genre can be asked for in two ways: a genre-conditioned model (``RevolutionConfig.n_genres``)
takes the genre as an input; a composite model folder may also declare *genre models* in its
``config.json`` (``"components": {"genres": {"rumba": "genres/rumba", ...}}``) — complete checkpoint
folders, e.g. the model fine-tuned on one genre's dances (``dancekit train revolution --init FOLDER
--set genres=rumba``) — which then dance that genre.

With ``genre="auto"`` (the default) the genre is read from the music when the folder also declares a
music attribute classifier (``"components": {"genre_reader": "music_attributes"}``, the classifier of
Music2Dance): the song is danced by the genre model of the genre the classifier finds. Without one, or
with ``genre="none"``, the model itself dances from the music alone.

The dance type is a latent the music does not fully determine (a waltz song can be danced as a rumba), so
the checkpoint may let the *seed* draw it (:class:`GenreDraw`, ``"sampling": {"genre_temperature": τ,
"genre_alone": w, "genre_draw_seed0": false, "genre_min_ratio": ρ}``): with ``genre="auto"`` every seed but 0
(seed 0 keeps the most likely genre unless ``genre_draw_seed0``) draws the genre model from the classifier's
posterior sharpened or softened by τ, ``q_g ∝ p_g^(1/τ)``, among the song's plausible genres only
(``p_g ≥ ρ · max(p)``), with the model alone as one more option of weight w. The draw depends on
the seed and the song's posterior only (:func:`draw_genre`; ``"genre_draw_spread": true``: seeds draw along the
golden-ratio sequence, so a few consecutive seeds already cover the options in proportion), so it is the same in
a batch and alone; the
result says what was drawn (:meth:`DanceResult.summary`: ``"as rumba (drawn by seed 3, p = 0.31)"``).
``genre="waltz"`` still forces the waltz model, and ``genre="none"`` the model alone.

A drawn genre keeps its steps but need not keep its tremor: the checkpoint's ``"stages": {"jitter_cap": ...}``
(:class:`~dancekit.pipelines.config.JitterCapConfig`) caps a drawn dance's jitter at ``scale`` times the smallest
real jitter (``"genre_stats": {"jitter": ...}``) among the song's plausible genres, by a per-dance low-pass before
the foot lock (:func:`dancekit.pipelines.stages.finish`); with ``"genre_max_jitter"`` k the draw itself skips
genres whose real jitter is over k times that of the song's most likely genre.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dancekit.checkpoints import NormStats
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.precision import to_precision
from dancekit.models.revolution import RevolutionModel, SeedVariety, decode_seeds
from dancekit.motion import Motion
from dancekit.motion.representations import decode_motion, encode_motion, get_representation
from dancekit.pipelines.base import calm_motion, check_seeds, clean_motion
from dancekit.pipelines.config import CheckpointSettings, RevolutionSampling
from dancekit.pipelines.dance import DancePipeline, GenreChoice
from dancekit.pipelines.music_attributes import MusicAttributePipeline
from dancekit.pipelines.stages import genre_jitter_table


class RevolutionPipeline(DancePipeline):
    """Generate a dance for a whole song with a trained :class:`RevolutionModel`.

    ``pipe(song, seed=0, genre="auto", start=None, end=None, beat_sync=True, cleanup=True, postprocess=True,
    variety=True)`` and ``pipe.dances(song, seeds=[...], ...)`` (:meth:`DancePipeline.dances
    <dancekit.pipelines.dance.DancePipeline.dances>`); this family's own options are those of
    :meth:`generate_batch` (``postprocess``, ``variety``). ``genre="auto"`` lets each seed draw its genre model from
    the music's genre posterior (:class:`GenreDraw`); a named genre is danced by its genre model (or the genre
    input of a genre-conditioned model); the dance has one frame per feature frame (``T = 1 + n_samples //
    hop_length`` at ``sr = fps * hop_length``), on the training skeleton (``positions3d``) or BODY_25
    (``keypoints2d``), in the skeleton's units.

    Parameters
    ----------
    model : the trained model
    meta : the checkpoint's ``config.json`` (needs ``fps`` and ``skeleton``; ``preset``,
        ``representation`` and ``hop_length`` default to ``revolution``, ``positions3d`` and 512)
    stats : the normalisation statistics (``music_mean``, ``music_std``, ``dance_mean``, ``dance_std``)
    """

    family = "revolution"
    sampling_config = RevolutionSampling
    component_names = ("genres", "genre_reader", "live")  # live: the model `dancekit live` steps

    def __init__(self, model: RevolutionModel, *, meta: dict[str, Any], stats: NormStats, folder: str = "?",
                 genre_models: dict[str, Path] | None = None, genre_reader: MusicAttributePipeline | None = None,
                 settings: CheckpointSettings | None = None):
        if not isinstance(model, RevolutionModel):
            raise CheckpointError(f"{folder} holds a {type(model).__name__}, not a Dance Revolution model")
        super().__init__(model, meta=meta, stats=stats, folder=folder, settings=settings, genre_reader=genre_reader)
        self.representation = str(meta.get("representation", "positions3d"))
        try:
            get_representation(self.representation)
        except ParameterError as exc:
            raise CheckpointError(f"checkpoint {folder}: {exc}") from None
        #: how the seed keeps changing the dance (:class:`~dancekit.models.revolution.SeedVariety`), from the
        #: checkpoint's ``"sampling": {"phrase_s": s, "state_noise": a, "latent_noise": σ, "dance_latent": τ}``; none: the paper's
        #: decoding (the seed draws the initial decoder state only). Genre models dance with their parent's.
        self.variety = variety_from_sampling(self.settings.sampling, self.fps, folder=str(folder))
        #: how the seed draws the genre model for ``genre="auto"`` (:class:`GenreDraw`, from the checkpoint's
        #: ``"sampling"`` entry; none: every seed dances the most likely genre)
        self.genre_draw = genre_draw_from_sampling(self.settings.sampling,
                                                   self.settings.stages.genre_stats.table("jitter"), folder=str(folder))
        self.genre_models = dict(genre_models or {})  # genre → checkpoint folder, loaded on first use
        self._genre_pipelines: dict[str, RevolutionPipeline] = {}
        if genre_reader is not None and genre_reader.fps != self.fps:
            raise CheckpointError(f"checkpoint {folder}: its music attribute classifier runs at {genre_reader.fps:g} "
                                  f"fps, the model at {self.fps:g} fps")
        if self.genre_models and model.config.n_genres:
            raise CheckpointError(f"checkpoint {folder}: a genre-conditioned model cannot also carry genre models")
        if len(stats.music_mean) != model.config.music_dim or len(stats.dance_mean) != model.config.pose_dim:
            raise CheckpointError(
                f"checkpoint {folder}: statistics ({len(stats.music_mean)}, {len(stats.dance_mean)}) do not match "
                f"the model (music_dim {model.config.music_dim}, pose_dim {model.config.pose_dim})"
            )

    @classmethod
    def from_parts(cls, model, *, meta, stats, folder, settings, parts, device) -> RevolutionPipeline:
        """The components its ``config.json`` declares: genre models (``"genres"``, loaded when first asked for)
        and a music attribute classifier (``"genre_reader"``, loaded here); the rest is
        :meth:`DancePipeline.from_pretrained <dancekit.pipelines.dance.DancePipeline.from_pretrained>`'s."""
        genre_models = dict(parts.get("genres", {}))
        known = set(meta.get("genres", ()))
        unknown = sorted(set(genre_models) - known) if known else []
        if unknown:
            raise CheckpointError(f"checkpoint {folder}: genre models {unknown} are not genres of its data {sorted(known)}")
        reader_folder = parts.get("genre_reader")
        reader = None if reader_folder is None else MusicAttributePipeline.from_pretrained(reader_folder, device=device)
        pipe = cls(model, meta=meta, stats=stats, folder=str(Path(folder)), genre_models=genre_models,
                   genre_reader=reader, settings=settings)
        pipe.live_folder = parts.get("live")
        return pipe

    #: the folder of the model that ``dancekit live`` steps (``"components": {"live": ...}``: a model of this
    #: family trained on the online features, whose encoder looks only as far ahead as live dancing can wait;
    #: None: live steps this model)
    live_folder = None

    def live_pipeline(self) -> RevolutionPipeline:
        """The pipeline ``dancekit live`` steps: the ``"live"`` component (loaded once, dancing with this model's
        seed variety), else this one."""
        if self.live_folder is None:
            return self
        if getattr(self, "_live_pipe", None) is None:
            live = RevolutionPipeline.from_pretrained(self.live_folder)
            if not isinstance(live, RevolutionPipeline) or live.representation != self.representation \
                    or live.fps != self.fps or live.preset != self.preset:
                raise CheckpointError(f"checkpoint {self.folder}: its live component {self.live_folder} is not a "
                                      f"{self.representation} Dance Revolution model at {self.fps:g} fps on the "
                                      f"{self.preset} features")
            live.variety = self.variety
            self._live_pipe = live
        return self._live_pipe

    def set_precision(self, precision: str) -> None:
        """Decode at ``precision`` from now on (``"fp32"``, ``"bf16"`` or ``"int8"``; genre models too)."""
        if not hasattr(self, "_fp32_model"):
            self._fp32_model = self.model
        self.model = to_precision(self._fp32_model, precision)
        self.precision = precision
        for pipe in self._genre_pipelines.values():
            pipe.set_precision(precision)

    def choose_genre(self, requested: str, probs: dict[str, float], *, seed: int) -> GenreChoice:
        """"auto": the genre seed ``seed`` draws from the music's genre posterior ``probs`` (:func:`draw_genre` with
        :attr:`genre_draw`: the most likely genre unless the checkpoint lets the seed draw; the model alone without
        ``probs``); otherwise as :meth:`DancePipeline.choose_genre <dancekit.pipelines.dance.DancePipeline.choose_genre>`."""
        if requested == "auto":
            genre, drawn_p = draw_genre(probs, seed=seed, draw=self.genre_draw)
            return GenreChoice(requested, genre, drawn_p, probs)
        return super().choose_genre(requested, probs, seed=seed)

    def danced_by(self, genre: str | None) -> str:
        """The genre model's folder for a genre this folder has a genre model of, else this folder."""
        if genre is not None and self.genre_models:
            return str(self.genre_models[genre])
        return self.folder

    def calm(self, motion: Motion, *, postprocess: bool = True, **options) -> Motion:
        """A 3D dance calmed (:func:`~dancekit.pipelines.base.calm_motion`, then with ``postprocess``
        :func:`~dancekit.pipelines.base.clean_motion`); a 2D dance is left as it is."""
        if self.representation != "positions3d":
            return motion
        motion = calm_motion(motion)
        return clean_motion(motion) if postprocess else motion

    def batch_key(self, choice: GenreChoice) -> None:
        """Every seed in one :meth:`generate_batch` call, whatever its genre: the seeds' genre models are stepped
        side by side (:func:`~dancekit.models.revolution.decode_seeds`)."""
        return None

    @torch.no_grad()
    def generate_batch(self, audio_path: str | os.PathLike, *, seeds: list[int], choices: list[GenreChoice],
                       start: float | None = None, end: float | None = None, progress: bool = False,
                       postprocess: bool = True, variety: bool = True, workers: int | None = None,
                       prefix: np.ndarray | None = None) -> list[Motion]:
        """The dances of ``seeds``, seed ``seeds[k]`` of the genre ``choices[k].genre``: danced by that genre's
        model when this folder has genre models (:meth:`genre_pipeline`), else by this model (with the genre as
        its input when it is genre-conditioned); :meth:`generate_rows` (each model's features and latents once,
        the decoder of every seed bit for bit the seed alone).

        Parameters
        ----------
        postprocess : for 3D positions, set every bone to the skeleton's rest length (keeping the generated bone
            directions, so IK/BVH export reproduces the positions exactly) and put the feet on the floor (the
            running floor of :func:`dancekit.motion.analysis.floor_curve` moved to 0)
        variety : True: the checkpoint's seed variety (:attr:`variety`: the seed perturbs the decoding at every
            phrase, so another seed is another dance all the way through); False: the paper's decoding (the seed
            draws the initial decoder state only; the dances of one song converge)
        workers : how many seeds are decoded side by side (threads; None: :func:`decode_workers`); the dances
            do not depend on it
        prefix : world positions ``(N, J, 3)`` on this model's skeleton at its fps: the dance's first N frames,
            which the decoder is fed as its previous poses (its state built from them), the dance continuing from
            the last (:meth:`generate_rows`)
        """
        vary = self.variety if variety else SeedVariety()
        rows = [(self.genre_pipeline(c.genre), None) if c.genre is not None and self.genre_models
                else (self, self._genre_index(c.genre)) for c in choices]
        return self.generate_rows(audio_path, seeds=seeds, rows=rows, start=start, end=end, progress=progress,
                                  postprocess=postprocess, variety=vary, workers=workers, prefix=prefix)

    @torch.no_grad()
    def generate(self, audio_path: str | os.PathLike, *, seed: int = 0, start: float | None = None,
                 end: float | None = None, progress: bool = False, postprocess: bool = True,
                 genre_index: int | None = None, variety: SeedVariety | None = None) -> Motion:
        """This model's own dance for the song (no genre models, no genre reading): the :class:`Motion`
        of :meth:`__call__` with ``genre_index`` the genre input of a genre-conditioned model (or None)
        and ``variety`` the seed variety (None: this checkpoint's :attr:`variety`)."""
        return self.generate_many(audio_path, seeds=[seed], start=start, end=end, progress=progress,
                                  postprocess=postprocess, genre_index=genre_index, variety=variety)[0]

    @torch.no_grad()
    def generate_many(self, audio_path: str | os.PathLike, *, seeds: list[int], start: float | None = None,
                      end: float | None = None, progress: bool = False, postprocess: bool = True,
                      genre_index: int | None = None, variety: SeedVariety | None = None,
                      workers: int | None = None) -> list[Motion]:
        """:meth:`generate` for each of ``seeds`` (:meth:`generate_rows`: the features once, the music encoded
        once)."""
        seeds = check_seeds(seeds)
        return self.generate_rows(audio_path, seeds=seeds, rows=[(self, genre_index)] * len(seeds), start=start,
                                  end=end, progress=progress, postprocess=postprocess,
                                  variety=self.variety if variety is None else variety, workers=workers)

    @torch.no_grad()
    def generate_rows(self, audio_path: str | os.PathLike, *, seeds: list[int],
                      rows: list[tuple[RevolutionPipeline, int | None]], start: float | None = None,
                      end: float | None = None, progress: bool = False, postprocess: bool = True,
                      variety: SeedVariety | None = None, workers: int | None = None,
                      prefix: np.ndarray | None = None) -> list[Motion]:
        """The dance of seed ``seeds[k]`` by the pipeline ``rows[k][0]`` (this one or one of its genre models'),
        with the genre input ``rows[k][1]`` (a genre-conditioned model; None otherwise): each pipeline's features
        read once, each (pipeline, genre) encoded once, then every seed decoded by
        :func:`~dancekit.models.revolution.decode_seeds` (bit for bit the seed alone) in ``workers`` lanes
        (None: :func:`decode_workers`), on the pipeline's skeleton at its fps (``postprocess``: see
        :meth:`generate_batch`), ``variety`` the seed variety (None: this checkpoint's). ``prefix``: world positions
        ``(N, J, 3)`` (this model's skeleton and fps), encoded and normalised by each row's pipeline: the first N
        frames of every dance, the decoder fed them as its previous poses (teacher forcing), continuing from the
        last (:func:`~dancekit.models.revolution.decode_seeds`'s ``prefixes``)."""
        seeds = check_seeds(seeds)
        if len(rows) != len(seeds):
            raise ParameterError(f"{len(rows)} rows for {len(seeds)} seeds")
        music: dict[int, torch.Tensor] = {}
        latents: dict[tuple[int, int | None], torch.Tensor] = {}
        for pipe, genre_index in rows:
            if id(pipe) not in music:
                music[id(pipe)] = torch.from_numpy(pipe.features(audio_path, start=start, end=end))[None].to(
                    pipe.model.bop.device)  # (1, T, D)
            if (id(pipe), genre_index) not in latents:
                index = None if genre_index is None else torch.tensor([genre_index])
                pipe.model._check_music(music[id(pipe)])
                latents[id(pipe), genre_index] = pipe.model._latents(music[id(pipe)], index)  # (1, T, d)
        music.clear()
        prefixes = None
        if prefix is not None:
            if self.representation != "positions3d":  # the genre models share it (genre_pipeline checks)
                raise ParameterError(f"a prefix needs a positions3d model, {self.folder} is {self.representation}")
            given = {}
            for pipe, _ in rows:
                if id(pipe) not in given:
                    x = encode_motion(Motion(skeleton=pipe.skeleton, fps=pipe.fps,
                                             positions=np.asarray(prefix, np.float32)), pipe.representation)
                    given[id(pipe)] = torch.from_numpy(
                        pipe.stats.normalize_dance(x).astype(np.float32))[None].to(pipe.model.bop.device)
            prefixes = [given[id(pipe)] for pipe, _ in rows]
        generators = [torch.Generator(device="cpu").manual_seed(s) for s in seeds]
        y = decode_seeds([pipe.model for pipe, _ in rows], [latents[id(pipe), g] for pipe, g in rows], generators,
                         self.variety if variety is None else variety, progress=progress,
                         workers=decode_workers(len(seeds)) if workers is None else workers,
                         prefixes=prefixes)  # (B, T, P)
        motions = []
        for k, (pipe, _) in enumerate(rows):
            poses = pipe.stats.denormalize_dance(y[k].cpu().numpy())  # (T, P)
            motion = decode_motion(poses, pipe.skeleton, pipe.fps, pipe.representation)
            motions.append(clean_motion(motion) if postprocess and pipe.representation == "positions3d" else motion)
        return motions

    @property
    def genres(self) -> tuple[str, ...]:
        """The genres this model can be asked for (empty: neither genre-conditioned nor with genre models)."""
        if self.model.config.n_genres:
            return tuple(self.meta.get("genres", ()))
        order = list(self.meta.get("genres", ()))
        return tuple(sorted(self.genre_models, key=lambda g: (order.index(g) if g in order else len(order), g)))

    def genre_pipeline(self, genre: str) -> RevolutionPipeline:
        """The pipeline of the genre model ``genre`` (loaded once, then cached)."""
        if genre not in self.genre_models:
            raise ParameterError(f"this model has no genre model {genre!r}; it has: {', '.join(self.genres) or 'none'}")
        if genre not in self._genre_pipelines:
            pipe = RevolutionPipeline.from_pretrained(self.genre_models[genre], device=str(self.model.bop.device))
            if pipe.genre_models or pipe.model.config.n_genres:
                raise CheckpointError(f"genre model {self.genre_models[genre]} must be a plain (unconditioned) model")
            if pipe.fps != self.fps or pipe.skeleton.joint_names != self.skeleton.joint_names \
                    or pipe.representation != self.representation:
                raise CheckpointError(f"genre model {self.genre_models[genre]} does not match its parent model "
                                      "(fps, skeleton or representation differ)")
            pipe.set_precision(getattr(self, "precision", "fp32"))
            self._genre_pipelines[genre] = pipe
        return self._genre_pipelines[genre]

    def _genre_index(self, genre: str | None) -> int | None:
        """Index of ``genre`` in :attr:`genres` (None for auto / none); ParameterError for any other genre."""
        if genre is None or genre in ("auto", "none"):
            return None
        if not self.genres:
            raise ParameterError(
                f"this Dance Revolution model is neither genre-conditioned nor has genre models; cannot dance "
                f"{genre!r} (leave the genre to 'auto': the style follows the music)"
            )
        if genre not in self.genres:
            raise ParameterError(f"unknown genre {genre!r} for this model; choose from {', '.join(self.genres)}")
        return self.genres.index(genre)


def decode_workers(rows: int) -> int:
    """How many seeds' decoders run side by side by default: one per CPU core this process may use, divided by
    torch's threads per operation, at most ``rows`` and :data:`MAX_DECODE_WORKERS`."""
    from dancekit.pipelines.parallel import usable_cores

    return max(1, min(rows, MAX_DECODE_WORKERS, usable_cores() // max(1, torch.get_num_threads())))


#: The most decoder threads :func:`decode_workers` gives: the frame loop is a Python loop, and more threads than
#: this wait on each other for the interpreter.
MAX_DECODE_WORKERS = 4


def variety_from_sampling(sampling: RevolutionSampling, fps: float, *, folder: str = "?") -> SeedVariety:
    """The checkpoint's seed variety from its sampling settings: ``phrase_s`` (seconds, converted to frames at
    ``fps``), ``state_noise``, ``latent_noise``, ``dance_latent``, ``style`` and ``style_share``; all 0: the
    paper's decoding (``SeedVariety()``)."""
    try:
        return SeedVariety(phrase=int(round(sampling.phrase_s * fps)), state_noise=sampling.state_noise,
                           latent_noise=sampling.latent_noise, dance_latent=sampling.dance_latent,
                           style=sampling.style, style_share=sampling.style_share)
    except ParameterError as exc:
        raise CheckpointError(f"checkpoint {folder}: config.json: sampling: {exc}") from None


@dataclass(frozen=True)
class GenreDraw:
    """How the seed draws the genre model for ``genre="auto"`` (inference only; issue 15).

    * ``temperature`` τ ≥ 0: seed k draws genre g with probability ``q_g ∝ p_g^(1/τ)`` from the music attribute
      classifier's posterior p (τ = 1: the posterior itself; τ < 1 sharper; τ > 1 flatter; τ = 0: no draw,
      the most likely genre, as without a draw — also the limit τ → 0).
    * ``alone`` w ∈ [0, 1): the model alone (no genre model) is one more option with probability w (the
      genres share 1 − w).
    * ``seed0``: False — seed 0 dances the most likely genre (so the default dance is the most likely one);
      True — seed 0 draws too.
    * ``min_ratio`` ρ ∈ [0, 1]: only the song's *plausible* genres are drawn — genre g is a candidate when
      ``p_g ≥ ρ · max(p)`` (ρ = 0: every genre, the third attempt's draw; ρ = 1: the most likely genre(s)
      only). The most likely genre is always a candidate.

    ``GenreDraw()`` (all off) is the dance of every seed by the most likely genre's model.
    """

    temperature: float = 0.0
    alone: float = 0.0
    seed0: bool = False
    min_ratio: float = 0.0
    #: the real training dances' median jitter per genre (m/s), as ``((genre, m/s), ...)``; needed by the two below
    genre_jitter: tuple[tuple[str, float], ...] = ()
    #: k > 0: only genres with ``genre_jitter[g] ≤ k · genre_jitter[most likely]`` are drawn (0: no such limit)
    max_jitter: float = 0.0
    #: True: seed k's uniform number is the golden-ratio sequence ``frac(k · 0.618…)`` instead of a generator's draw,
    #: so that any run of consecutive seeds spreads its draws over the options in proportion to their probability
    #: (each option's count among n ≤ 100 consecutive seeds is within 3 of n · q); False: a generator seeded by the seed
    spread: bool = False

    def __post_init__(self):
        if not (np.isfinite(self.temperature) and self.temperature >= 0):
            raise ParameterError(f"genre_temperature must be a finite number ≥ 0, got {self.temperature!r}")
        if not (np.isfinite(self.alone) and 0 <= self.alone < 1):
            raise ParameterError(f"genre_alone must be in [0, 1), got {self.alone!r}")
        if not isinstance(self.seed0, bool):
            raise ParameterError(f"genre_draw_seed0 must be true or false, got {self.seed0!r}")
        if not (np.isfinite(self.min_ratio) and 0 <= self.min_ratio <= 1):
            raise ParameterError(f"genre_min_ratio must be in [0, 1], got {self.min_ratio!r}")
        if self.genre_jitter:  # the same check as a "jitter_cap" entry's table (empty: no table)
            genre_jitter_table(self.genre_jitter)
        if not (np.isfinite(self.max_jitter) and self.max_jitter >= 0):
            raise ParameterError(f"genre_max_jitter must be a finite number ≥ 0, got {self.max_jitter!r}")
        if self.max_jitter > 0 and not self.genre_jitter:
            raise ParameterError("genre_max_jitter needs a genre_stats.jitter table")
        if not isinstance(self.spread, bool):
            raise ParameterError(f"genre_draw_spread must be true or false, got {self.spread!r}")

    @property
    def active(self) -> bool:
        return self.temperature > 0 or self.alone > 0


#: mixed into the seed of the genre draw's generator, so that it is a stream of its own (not the decoder's)
GENRE_DRAW_STREAM = 0x67656E72  # "genr"
#: round(2^64 · (√5 − 1) / 2): the golden-ratio step of a spread draw, in 64-bit fixed point
GOLDEN_STEP_64 = 0x9E3779B97F4A7C15


def draw_uniform(seed: int, *, spread: bool = False) -> float:
    """The uniform number in [0, 1) that seed ``seed`` inverts through a genre draw's options.

    ``spread=False``: one draw of a generator seeded by (:data:`GENRE_DRAW_STREAM`, seed). ``spread=True``: the
    golden-ratio (Weyl) sequence ``frac(seed · (√5 − 1) / 2)``, in exact 64-bit fixed point (the same number on
    every machine): any n consecutive seeds then fall into every interval of [0, 1) of length q about n · q
    times, so a handful of seeds already dances each option about as often as its probability says."""
    if spread:
        return ((int(seed) * GOLDEN_STEP_64) % (1 << 64)) / float(1 << 64)
    return float(np.random.default_rng([GENRE_DRAW_STREAM, int(seed) % (1 << 64)]).random())


def genre_options(probs: dict[str, float], draw: GenreDraw) -> dict[str | None, float]:
    """The options a seed draws from: genre → q_g (``q ∝ p^(1/τ)`` over the candidates ``p_g ≥ ρ · max(p)``,
    0 for the others, times 1 − w) and None (the model alone) → w; with τ = 0 the most likely genre carries all
    of 1 − w. The probabilities sum to 1."""
    names = list(probs)
    p = np.array([probs[g] for g in names], np.float64)
    if draw.temperature > 0:
        with np.errstate(divide="ignore"):
            logq = np.log(np.maximum(p, 0.0)) / draw.temperature
        q = np.exp(logq - logq.max())
        q[p < draw.min_ratio * p.max()] = 0.0  # not a plausible genre for this song
        if draw.max_jitter > 0:  # not a genre far jerkier than the song's most likely one
            table = dict(draw.genre_jitter)
            best = names[int(np.argmax(p))]
            if best in table:
                q[[g in table and table[g] > draw.max_jitter * table[best] for g in names]] = 0.0
    else:
        q = np.zeros(len(names))
        q[names.index(max(probs, key=probs.get))] = 1.0
    q = q / q.sum() * (1.0 - draw.alone)
    options: dict[str | None, float] = {g: float(v) for g, v in zip(names, q)}
    if draw.alone > 0:
        options[None] = float(draw.alone)
    return options


def draw_genre(probs: dict[str, float], *, seed: int, draw: GenreDraw) -> tuple[str | None, float | None]:
    """The genre seed ``seed`` dances for a song whose genre posterior is ``probs`` (genre → p, from
    :meth:`RevolutionPipeline.read_genre`): ``(genre, q)`` with genre None for the model alone and q the
    probability the draw gave it, or ``(most likely genre, None)`` when nothing is drawn (no ``draw``, seed 0
    without ``draw.seed0``). No posterior: ``(None, None)``.

    Deterministic per (posterior, seed): one uniform number per seed (:func:`draw_uniform`: a generator seeded by
    (stream, seed) alone, or with ``draw.spread`` the golden-ratio sequence), inverted through the options'
    cumulative probabilities (:func:`genre_options`, in the posterior's genre order, the model alone last)."""
    if not probs:
        return None, None
    best = max(probs, key=probs.get)
    if not draw.active or (seed == 0 and not draw.seed0):
        return best, None
    options = genre_options(probs, draw)
    u = draw_uniform(seed, spread=draw.spread)
    cdf = np.cumsum(list(options.values()))
    k = int(np.searchsorted(cdf, u * cdf[-1], side="right"))
    keys = list(options)
    k = min(k, len(keys) - 1)
    while options[keys[k]] <= 0:  # never an option of probability 0 (u on an edge of the cumulative sum)
        k -= 1
    return keys[k], options[keys[k]]


def genre_draw_from_sampling(sampling: RevolutionSampling, genre_jitter: dict[str, float], *,
                             folder: str = "?") -> GenreDraw:
    """The checkpoint's genre draw: ``genre_temperature`` τ, ``genre_alone`` w, ``genre_draw_seed0``,
    ``genre_min_ratio`` ρ, ``genre_max_jitter`` k (with the real jitters ``genre_jitter``, genre → m/s, from
    ``genre_stats``) and ``genre_draw_spread`` of its sampling settings; none of them: no draw."""
    try:
        return GenreDraw(temperature=sampling.genre_temperature, alone=sampling.genre_alone,
                         seed0=sampling.genre_draw_seed0, min_ratio=sampling.genre_min_ratio,
                         genre_jitter=tuple(genre_jitter.items()) if sampling.genre_max_jitter > 0 else (),
                         max_jitter=sampling.genre_max_jitter, spread=sampling.genre_draw_spread)
    except ParameterError as exc:
        raise CheckpointError(f"checkpoint {folder}: config.json: sampling: {exc}") from None
