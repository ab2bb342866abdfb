"""Where a model's FID comes from: after each pipeline stage, and from one set of seeds to another.

- :func:`stage_ablation` (``dancekit evaluate --checkpoint M --ablate-stages``): every song of a split is danced
  with the pipeline's stages off (the network's output, genre choice included), then run through
  :func:`dancekit.pipelines.stages.finish` with every stage on, as ``dancekit dance`` does; its trace keeps the
  dance after each stage (:data:`~dancekit.pipelines.stages.STAGE_NAMES`; a stage that does not apply to a dance
  passes it on unchanged). FID_k / FID_g of the dances after each stage, with the mean and covariance terms.
- :func:`seed_set_fids` (``dancekit evaluate --seed-sets K``): the seeds of every song split into ``K`` sets of
  consecutive seeds, each set's FID_k / FID_g computed alone: how much a figure measured on one set of seeds
  moves with the set.

FID as :func:`dancekit.evaluation.evaluate_motions` computes it: AIST++ kinetic / geometric features of
``segment_seconds`` segments, z-scored with the reference set's statistics, Fréchet distance to the reference.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dancekit.errors import ParameterError

KINDS = (("kinetic", "fid_k"), ("geometric", "fid_g"))


def fid_against(reference: Sequence[np.ndarray], dances: Sequence[np.ndarray], *, fps: float, skeleton: Any,
                kind: str, segment_seconds: float | None = 10.0, bug_compatible: bool = False) -> dict[str, float]:
    """FID of ``dances`` against ``reference`` (positions ``(T, J, 3)`` in the skeleton's units, at ``fps``).

    Returns ``{"fid", "mean_term", "cov_term"}``: the Fréchet distance, its squared distance between the means
    (of the z-scored features) and the rest (the covariance term, ``fid - mean_term``).
    """
    from dancekit.metrics import fid as fid_mod

    kw = {"fps": fps, "skeleton": skeleton, "kind": kind, "segment_seconds": segment_seconds,
          "bug_compatible": bug_compatible}
    ref_z, pred_z, _ = fid_mod.normalize_features(fid_mod.feature_sets(list(reference), **kw),
                                                  fid_mod.feature_sets(list(dances), **kw))
    if len(pred_z) < 2 or len(ref_z) < 2:
        raise ParameterError(f"FID needs at least 2 feature vectors on each side, got {len(pred_z)} and "
                             f"{len(ref_z)} (dances shorter than one {segment_seconds}-s segment?)")
    total = float(fid_mod.frechet_distance(pred_z, ref_z))
    mean = float(((pred_z.mean(0) - ref_z.mean(0)) ** 2).sum())
    return {"fid": total, "mean_term": mean, "cov_term": total - mean}


def stage_dances(pipe: Any, data: Any, split: str, *, seeds: int = 5, first_seed: int = 0,
                 genre: str = "auto") -> dict[str, list]:
    """Per stage (``"raw"`` first, then :data:`~dancekit.pipelines.stages.STAGE_NAMES`), the positions
    ``(T, J, 3)`` of every dance of ``split`` after that stage, songs in split order, seeds
    ``first_seed .. first_seed + seeds - 1`` of each song in turn, each danced as ``genre`` asks
    (:func:`dancekit.evaluation.generate.requested_genre`: ``"auto"``, ``"none"``, ``"true"`` or a genre name,
    as ``dancekit evaluate --genre``).

    ``pipe`` is a dance pipeline with ``dances(audio, seeds=, start=, end=, beat_sync=, cleanup=)`` and
    ``stage_options()`` (its checkpoint's :class:`~dancekit.pipelines.config.StageConfig`; each dance's jitter
    cap follows from it and the dance's genre posterior, as in ``dances``); ``data`` a
    :class:`~dancekit.data.PreparedData`.
    """
    from dancekit.evaluation.generate import requested_genre
    from dancekit.pipelines import stages as S

    if seeds < 1:
        raise ParameterError(f"seeds must be at least 1, got {seeds}")
    rows = ("raw", *S.STAGE_NAMES)
    out: dict[str, list] = {n: [] for n in rows}
    config = pipe.stage_options()  # the checkpoint's stage configuration, every stage on
    for name in data.names(split):
        ref = data.audio(name)
        beats = S.song_beats_for(ref.path, start=ref.start, end=ref.end)
        raw = pipe.dances(ref.path, seeds=list(range(first_seed, first_seed + seeds)), start=ref.start,
                          end=ref.end, genre=requested_genre(genre, data.genre(name)), beat_sync=False, cleanup=False)
        for r in raw:
            seen: dict[str, Any] = {}

            def keep(stage: str, res: Any, _seen: dict = seen) -> None:
                _seen["raw" if stage == "input" else stage] = res

            S.finish(r, S.Song(ref.path, ref.start, ref.end, beats), config, trace=keep)
            last = r
            for stage in rows:  # a stage that did not run passes the dance before it on
                last = seen.get(stage, last)
                out[stage].append(np.asarray(last.motion.to_positions(), np.float64))
    return out


def fid_by_stage(dances: Mapping[str, Sequence[np.ndarray]], reference: Sequence[np.ndarray], *, fps: float,
                 skeleton: Any, segment_seconds: float | None = 10.0, bug_compatible: bool = False) -> dict:
    """``{"stages": [names], "fid_k": {stage: {"fid", "mean_term", "cov_term"}}, "fid_g": {...}}`` for the
    dances after each stage (:func:`stage_dances`) against ``reference`` (the training dances for
    ``dancekit evaluate``)."""
    table: dict[str, Any] = {"stages": list(dances)}
    for kind, key in KINDS:
        table[key] = {stage: fid_against(reference, ds, fps=fps, skeleton=skeleton, kind=kind,
                                         segment_seconds=segment_seconds, bug_compatible=bug_compatible)
                      for stage, ds in dances.items()}
    return table


def stage_ablation(pipe: Any, data: Any, split: str, *, seeds: int = 5, first_seed: int = 0,
                   segment_seconds: float | None = 10.0, bug_compatible: bool = False,
                   reference: str = "train", genre: str = "auto") -> dict:
    """:func:`fid_by_stage` of the dances of ``split`` against real dances, with the count of dances; see the
    module docstring. ``reference``: ``"train"`` (the training dances, as ``dancekit evaluate --data``),
    ``"all"`` (every dance of the dataset) or ``"ref"`` (the real dances of ``split``); ``genre``: see
    :func:`stage_dances`."""
    if reference not in ("train", "all", "ref"):
        raise ParameterError(f"reference must be 'train', 'all' or 'ref', got {reference!r}")
    dances = stage_dances(pipe, data, split, seeds=seeds, first_seed=first_seed, genre=genre)
    names = data.names() if reference == "all" else data.names(split if reference == "ref" else "train")
    ref = [np.asarray(data.motion(n).to_positions(), np.float64) for n in names]
    table = fid_by_stage(dances, ref, fps=data.fps, skeleton=data.skeleton, segment_seconds=segment_seconds,
                         bug_compatible=bug_compatible)
    return {"split": split, "seeds": seeds, "first_seed": first_seed, "reference": reference, "genre": genre,
            "dances": len(dances["raw"]), **table}


def seed_set_fids(pred: Mapping[str, Sequence[Any]], reference: Sequence[Any], *, sets: int,
                  segment_seconds: float | None = 10.0, bug_compatible: bool = False) -> dict:
    """FID_k / FID_g of each of ``sets`` disjoint sets of consecutive seeds.

    ``pred``: song name → its dances (:class:`~dancekit.motion.Motion`) in seed order, every song with the same
    number of dances, a multiple of ``sets``; ``reference``: the FID reference motions (same skeleton and fps).
    Returns ``{"sets": K, "set_size": n, "per_set": [{"seed_index": [first, last], "fid_k", "fid_g"}, ...],
    "fid_k": {"min", "median", "max", "sd"}, "fid_g": {...}}``; ``seed_index`` counts the dances of a song
    (``NAME__k``), not the seeds themselves.
    """
    if isinstance(sets, bool) or not isinstance(sets, int) or sets < 1:
        raise ParameterError(f"the number of seed sets must be a whole number >= 1, got {sets!r}")
    counts = {len(v) for v in pred.values()}
    if len(counts) != 1:
        raise ParameterError(f"--seed-sets needs the same number of dances for every song, got {sorted(counts)}")
    n = counts.pop()
    if n % sets:
        raise ParameterError(f"--seed-sets {sets}: {n} dances per song is not a multiple of {sets}")
    first = next(iter(reference))
    fps, skeleton = float(first.fps), first.skeleton
    ref = [np.asarray(m.to_positions(), np.float64) for m in reference]
    size = n // sets
    per_set = []
    for s in range(sets):
        lo = s * size
        dances = []
        for ms in pred.values():
            for m in ms[lo:lo + size]:
                if abs(float(m.fps) - fps) > 1e-6 or m.skeleton.name != skeleton.name:
                    raise ParameterError(f"--seed-sets: a dance at {m.fps} fps on {m.skeleton.name!r}, the "
                                         f"reference at {fps} fps on {skeleton.name!r}")
                dances.append(np.asarray(m.to_positions(), np.float64))
        row: dict[str, Any] = {"seed_index": [lo, lo + size - 1]}
        for kind, key in KINDS:
            row[key] = fid_against(ref, dances, fps=fps, skeleton=skeleton, kind=kind,
                                   segment_seconds=segment_seconds, bug_compatible=bug_compatible)["fid"]
        per_set.append(row)
    summary = {key: {"min": float(np.min(v)), "median": float(np.median(v)), "max": float(np.max(v)),
                     "sd": float(np.std(v))}
               for key, v in ((key, [r[key] for r in per_set]) for _, key in KINDS)}
    return {"sets": sets, "set_size": size, "per_set": per_set, **summary}


def format_stage_ablation(table: Mapping[str, Any]) -> str:
    """The FID after each stage as a markdown table (one row per FID kind)."""
    stages = table["stages"]
    lines = ["| FID after | " + " | ".join(stages) + " |", "| --- |" + " ---: |" * len(stages)]
    for key, label in (("fid_k", "FID_k"), ("fid_g", "FID_g")):
        lines.append(f"| {label} | " + " | ".join(f"{table[key][s]['fid']:.2f}" for s in stages) + " |")
    return "\n".join(lines) + "\n"


def format_seed_sets(table: Mapping[str, Any]) -> str:
    """One line per FID kind: every set's value, then min / median / max and the standard deviation."""
    out = []
    for key, label in (("fid_k", "FID_k"), ("fid_g", "FID_g")):
        s = table[key]
        values = " ".join(f"{r[key]:.2f}" for r in table["per_set"])
        out.append(f"seed sets ({table['sets']} x {table['set_size']} seeds): {label} {values} "
                   f"(min {s['min']:.2f}, median {s['median']:.2f}, max {s['max']:.2f}, sd {s['sd']:.2f})")
    return "\n".join(out) + "\n"
