"""Dance every song of a split with a model, and score the dances: ``dancekit evaluate --checkpoint``.

For every dance of the split, the model dances to the same slice of the same song
(:meth:`PreparedData.audio <dancekit.data.PreparedData.audio>`) with ``seeds`` seeds, written as
``NAME__k.npz`` (``NAME.npz`` with one seed; multimodality needs several); the folder is then scored
exactly as ``dancekit evaluate --pred OUT/pred --ref DATA --data DATA --split SPLIT`` would.
"""

from __future__ import annotations

import inspect
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from dancekit._io import atomic_path
from dancekit.errors import ParameterError
from dancekit.evaluation.score import SAMPLE_SEP, EvalSettings, evaluate_dirs

__all__ = ["GENRE_CHOICES", "dance_split", "evaluate_checkpoint", "requested_genre"]

#: ``genre`` values with a meaning of their own (any other value is a genre name for every song).
GENRE_CHOICES = ("auto", "none", "true")


def requested_genre(genre: str, song_genre: str) -> str | None:
    """What to ask the pipeline for: ``"auto"`` → None (the genre read from the music when the model has a
    music attribute classifier, else the model alone), ``"true"`` → the song's own genre, anything else
    (``"none"``: the model alone, or a genre name) as it is."""
    return {"auto": None, "true": song_genre}.get(genre, genre)


def dance_split(pipe: Any, data: Any, split: str, out_dir: str | os.PathLike, *, seeds: int = 5,
                genre: str = "auto", progress: bool = True, beat_sync: bool | None = None,
                unwarped_dir: str | os.PathLike | None = None, first_seed: int = 0) -> dict[str, float]:
    """Generate ``seeds`` dances for every song of ``split`` into ``out_dir`` (its old ``.npz`` files are
    removed first).

    ``beat_sync``: None leaves the pipeline's default; True / False switch its beat-synchronous stage.
    With ``unwarped_dir`` (and ``beat_sync`` not False) every dance is also written there as it was
    before the warp: for a pipeline whose ``dances`` takes a ``stage_trace``, the dance its last stage
    before the warp gave (the written dance is the pipeline's own, bit for bit what ``dancekit dance``
    gives, also where a stage looks at the warped dance, e.g. a jitter cap held to the end); otherwise the
    pipeline dances without the warp, then :func:`dancekit.pipelines.stages.beat_sync` warps it.

    Parameters
    ----------
    pipe : a dance pipeline (``pipe(audio, seed=, start=, end=, genre=)`` → :class:`~dancekit.pipelines.DanceResult`;
        when it has ``pipe.dances(audio, seeds=[...], ...)``, the seeds of a song are danced at once)
    data : a :class:`~dancekit.data.PreparedData`
    split : the split whose songs are danced
    seeds : dances per song (seeds ``first_seed .. first_seed + seeds - 1``, written as ``NAME__0`` …
        ``NAME__{seeds-1}``)
    first_seed : the first seed (default 0; another seed set of the same model, e.g. to see how much the
        metrics move between sets of ``seeds`` seeds)
    genre : see :func:`requested_genre`

    Returns
    -------
    ``{"files": n, "seconds": seconds of dance, "elapsed_s": wall time}``
    """
    from tqdm import tqdm

    from dancekit.motion import write_motion

    if seeds < 1:
        raise ParameterError(f"seeds must be at least 1, got {seeds}")
    if isinstance(first_seed, bool) or not isinstance(first_seed, int) or first_seed < 0:
        raise ParameterError(f"the first seed must be a whole number >= 0, got {first_seed!r}")
    numbers = list(range(first_seed, first_seed + seeds))
    names = data.names(split)
    if not names:
        raise ParameterError(f"the {split!r} split of {data.root} has no dances")
    out = Path(out_dir)
    split_warp = unwarped_dir is not None and beat_sync is not False
    dirs = [out] + ([Path(unwarped_dir)] if split_warp else [])
    for d in dirs:
        d.mkdir(parents=True, exist_ok=True)
        for old in d.glob("*.npz"):
            old.unlink()
    batch = getattr(pipe, "dances", None)  # a pipeline that dances several seeds at once (equal results)
    traced = split_warp and batch is not None and "stage_trace" in inspect.signature(batch).parameters
    if traced:  # the pipeline's own warp; the dance before it from the stages' trace
        kwargs = {"beat_sync": True}
    else:  # None: the pipeline's default; split: the warp after it, here
        kwargs = {} if beat_sync is None and not split_warp else {"beat_sync": bool(beat_sync) and not split_warp}
    t0 = time.perf_counter()
    seconds, files = 0.0, 0
    before: dict[int, Any] = {}  # per seed index of the song, the dance before its warp

    def keep(k: int, stage: str, result: Any) -> None:
        if stage != "beat_sync":
            before[k] = result

    for name in tqdm(names, desc="generate", unit="song", disable=not progress):
        ref = data.audio(name)
        beats = None
        want = requested_genre(genre, data.genre(name))
        before.clear()
        if traced:
            results = batch(ref.path, seeds=numbers, start=ref.start, end=ref.end, genre=want, stage_trace=keep,
                            **kwargs)
        elif batch is not None:
            results = batch(ref.path, seeds=numbers, start=ref.start, end=ref.end, genre=want, **kwargs)
        else:
            results = [pipe(ref.path, seed=n, start=ref.start, end=ref.end, genre=want, **kwargs) for n in numbers]
        for k, result in enumerate(results):
            stem = name if seeds == 1 else f"{name}{SAMPLE_SEP}{k}"
            if traced:
                write_motion(Path(unwarped_dir) / f"{stem}.npz", before[k].motion)
            elif split_warp:
                from dancekit.pipelines import stages

                write_motion(Path(unwarped_dir) / f"{stem}.npz", result.motion)
                if beats is None:
                    beats = stages.song_beats_for(ref.path, start=ref.start, end=ref.end)
                options = pipe.stage_options().beat_sync.warp_options() if hasattr(pipe, "stage_options") else None
                result = stages.beat_sync(result, ref.path, start=ref.start, end=ref.end, beats=beats, options=options)
            motion = result.motion
            write_motion(out / f"{stem}.npz", motion)
            seconds += motion.duration
            files += 1
    return {"files": files, "seconds": seconds, "elapsed_s": time.perf_counter() - t0}


def evaluate_checkpoint(
    checkpoint: str | os.PathLike,
    data: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    split: str = "test",
    seeds: int = 5,
    genre: str = "auto",
    settings: EvalSettings | None = None,
    classifier: Any = "default",
    progress: bool = True,
    beat_sync: bool = True,
    precision: str = "fp32",
    first_seed: int = 0,
    seed_sets: int | None = None,
    ablate_stages: bool = False,
) -> dict[str, Any]:
    """Dance every song of ``split`` with a model and score the dances against the real ones.

    Writes ``OUT/pred/*.npz`` (:func:`dance_split`) and ``OUT/report.json`` (:func:`evaluate_dirs` with the
    prepared dataset as reference, music and FID reference); returns the report, whose ``generation``
    entry records the model, seeds, genre and timing.

    Parameters
    ----------
    checkpoint : a checkpoint folder or a model name (``dancekit models``)
    data : prepared dataset folder
    out_dir : output folder
    split, seeds, genre, first_seed : see :func:`dance_split`
    settings, classifier : see :func:`~dancekit.evaluation.evaluate_dirs`
    beat_sync : the pipeline's beat-synchronous stage on (default) or off; when on, the dances before the
        warp go to ``OUT/pred_unwarped`` and the report's ``beat_sync`` entry compares the beat metrics
        before and after it (:func:`dancekit.evaluation.stages.beat_sync_comparison`)
    precision : decoding precision, ``"fp32"``, ``"bf16"`` or ``"int8"`` (:func:`dancekit.pipelines.load_pipeline`)
    seed_sets : K: the report's ``seed_sets`` entry, FID of K disjoint sets of the seeds
        (:func:`~dancekit.evaluation.evaluate_dirs`)
    ablate_stages : also dance the split with the stages off and score the dances after each stage: the
        report's ``stage_ablation`` entry (:func:`dancekit.evaluation.ablation.stage_ablation`; the FID
        reference is the training split, the segments and feature code those of ``settings``)
    """
    from dancekit.data import PreparedData
    from dancekit.pipelines import load_pipeline

    prepared = PreparedData(data)
    pipe = load_pipeline(checkpoint, precision=precision)
    out = Path(out_dir)
    pred = out / "pred"
    unwarped = out / "pred_unwarped"
    gen = dance_split(pipe, prepared, split, pred, seeds=seeds, genre=genre, progress=progress, beat_sync=beat_sync,
                      unwarped_dir=unwarped if beat_sync else None, first_seed=first_seed)
    report = evaluate_dirs(pred, data, data=data, classifier=classifier, settings=settings, split=split,
                           seed_sets=seed_sets)
    if ablate_stages:
        from dancekit.evaluation.ablation import stage_ablation

        s = settings or EvalSettings()
        report["stage_ablation"] = stage_ablation(pipe, prepared, split, seeds=seeds, first_seed=first_seed,
                                                  segment_seconds=s.segment_seconds,
                                                  bug_compatible=s.bug_compatible,
                                                  reference=s.fid_reference or "train", genre=genre)
    if beat_sync:
        report["beat_sync"] = _beat_sync_section(pred, unwarped, prepared, report)
    report["generation"] = {"checkpoint": str(checkpoint), "split": split, "seeds": seeds, "first_seed": first_seed,
                            "genre": genre,
                            "beat_sync": bool(beat_sync), "precision": precision,
                            "files": gen["files"], "seconds": round(gen["seconds"], 3),
                            "elapsed_s": round(gen["elapsed_s"], 3)}
    with atomic_path(out / "report.json") as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    return report


def _beat_sync_section(pred: Path, unwarped: Path, prepared: Any, report: dict[str, Any]) -> dict[str, Any]:
    """The report's ``beat_sync`` entry: beat metrics before / after the warp, the prepared beat times."""
    from dancekit.evaluation.score import group_predictions
    from dancekit.evaluation.stages import beat_sync_comparison
    from dancekit.motion import read_motion

    def load(folder: Path) -> dict[str, list]:
        groups = group_predictions(sorted(folder.glob("*.npz")))
        return {n: [read_motion(p) for p in ps] for n, ps in groups.items()}

    settings = report.get("settings", {})
    preset = "revolution" if "revolution" in prepared.presets else prepared.presets[0]
    after = load(pred)
    beats = {n: np.asarray(prepared.features(n, preset)["beat_times"], np.float64) for n in after}
    return beat_sync_comparison(load(unwarped), after, beats, sigma=settings.get("sigma", 0.05),
                                tolerance=settings.get("tolerance", 0.1))
