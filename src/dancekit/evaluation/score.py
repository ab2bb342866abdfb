"""Score generated dances against the real ones: every metric of :mod:`dancekit.metrics`, one report.

:func:`evaluate_motions` scores :class:`~dancekit.motion.Motion` objects (with a style classifier,
:class:`~dancekit.pipelines.StylePipeline`, for the style metrics); :func:`evaluate_dirs` reads them from
folders (what ``dancekit evaluate --pred DIR --ref DIR`` runs).

Files
    ``pred``: a folder of motion ``.npz`` files named after the reference dance whose music
    they were generated for: ``NAME.npz``, or ``NAME__<k>.npz`` for several dances per song
    (``k`` any text; all of them count for multimodality). ``ref``: a folder of real dances
    ``NAME.npz``, or a prepared dataset folder (then its ``test`` split is the reference).

Music (for the beat metrics and ACC)
    With a prepared dataset (``data``), the music beats of ``NAME`` are the ``beat_times``
    of ``dances/NAME/features_<preset>.npz`` (preset ``revolution`` if prepared, else the first
    one; seconds from the start of the dance) and its genre is ``meta.json``'s genre. With an
    audio folder (``audio_dir``), ``NAME.wav|.mp3|.ogg|.flac`` is loaded and beat-tracked
    (:func:`dancekit.features.beat_track`); the dance is taken to start with the file, and no
    genre is known (ACC is skipped). Without either, the beat metrics and ACC are skipped.

FID reference set
    The distribution the generated dances are compared with: ``"ref"`` (the reference
    dances; the real dances then score FID 0), ``"train"`` or ``"all"`` (the training split or
    every dance of the prepared dataset). The default is ``"train"`` when a prepared dataset
    is given and ``"ref"`` otherwise. The "real" column of the report evaluates the
    reference dances themselves against the same set.

Every setting used goes into the report's ``settings``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancekit.errors import CheckpointError, DatasetError, ParameterError
from dancekit.metrics import beat as beat_mod
from dancekit.metrics import fid as fid_mod
from dancekit.metrics import physics, stability
from dancekit.metrics.distance import mean_joint_distance
from dancekit.metrics.style import dance_genre, multimodality, style_diversity
from dancekit.motion.analysis import resample_positions

__all__ = ["EvalSettings", "dance_metrics", "evaluate_dirs", "evaluate_motions", "group_predictions",
           "load_classifier"]

AUDIO_SUFFIXES = (".wav", ".mp3", ".ogg", ".flac")
SAMPLE_SEP = "__"


@dataclass
class EvalSettings:
    """Every knob of :func:`evaluate_motions` (recorded in the report)."""

    sigma: float = beat_mod.DEFAULT_SIGMA  # BAS Gaussian, s
    tolerance: float = beat_mod.DEFAULT_TOLERANCE  # beat hit, s
    beat_smooth: float = beat_mod.DEFAULT_SMOOTH  # speed smoothing for kinematic beats, s
    segment_seconds: float | None = 10.0  # FID_k / FID_g segments (None: whole dances)
    bug_compatible: bool = False  # reproduce the reference kinetic / geometric features
    diversity_pairs: int = 500
    seed: int = 0
    freeze_window: float = 10.0  # s
    stillness_window: float = 1.0  # s
    stillness_threshold: float = 0.10  # m/s
    smooth_frames: int = 5  # smoothed energy / jitter moving average, frames
    fid_reference: str | None = None  # "ref" | "train" | "all" (None: train with data, else ref)

    def __post_init__(self) -> None:
        if not self.sigma > 0 or not self.tolerance >= 0:
            raise ParameterError(f"sigma must be > 0 and tolerance >= 0 seconds, got {self.sigma}, {self.tolerance}")
        if self.fid_reference not in (None, "ref", "train", "all"):
            raise ParameterError(f"fid_reference must be 'ref', 'train' or 'all', got {self.fid_reference!r}")
        if self.segment_seconds is not None and not self.segment_seconds > 0:
            raise ParameterError(f"segment_seconds must be positive or None, got {self.segment_seconds}")


# ---------------------------------------------------------------------------------------------
# per-dance metrics


def _nanmean(values: Sequence[float]) -> float:
    arr = np.asarray([v for v in values if v is not None], dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    return float(arr.mean()) if arr.size else float("nan")


def dance_metrics(positions: np.ndarray, *, fps: float, skeleton: Any, music_beats: np.ndarray | None,
                  settings: EvalSettings) -> dict[str, float]:
    """Every per-dance metric of one dance (flat dict of floats)."""
    out: dict[str, float] = {}
    if music_beats is not None:
        b = beat_mod.beat_metrics(positions, music_beats, fps=fps, skeleton=skeleton, sigma=settings.sigma,
                                  tolerance=settings.tolerance, smooth=settings.beat_smooth)
        out.update({
            "bas_bailando": b["bas_bailando"],
            "bas_aist": b["bas_aist"],
            "beat_coverage": b["beat_coverage"],
            "beat_hit_rate": b["beat_hit_rate"],
            "beats_alignment_dual": b["beat_hit_rate_dual"],
        })
    out["freeze_score"] = stability.freeze_score(positions, fps=fps, skeleton=skeleton, window=settings.freeze_window)
    out["stillness_share"] = stability.stillness_share(
        positions, fps=fps, skeleton=skeleton, window=settings.stillness_window, threshold=settings.stillness_threshold
    )
    out["smoothed_energy"] = stability.smoothed_energy(positions, fps=fps, skeleton=skeleton,
                                                       window_frames=settings.smooth_frames)
    j = stability.jitter(positions, fps=fps, skeleton=skeleton, window_frames=settings.smooth_frames)
    out["jitter_speed"] = j["speed_residual"]
    out["jerk"] = j["jerk"]
    out["foot_skating_ratio"] = physics.foot_skating(positions, fps=fps, skeleton=skeleton)["ratio"]
    out["pfc"] = physics.pfc(positions, fps=fps, skeleton=skeleton)
    out["bone_length_variation"] = physics.bone_length_variation(positions, skeleton=skeleton)["mean"]
    out["ground_penetration_m"] = physics.ground_penetration(positions, skeleton=skeleton)["mean_depth"]
    out["torso_lean_deg"] = physics.torso_lean(positions, skeleton=skeleton)["median_deg"]
    return out


# ---------------------------------------------------------------------------------------------
# the whole evaluation


def _sample_index(path: Path) -> int:
    """k of ``NAME__k.npz`` (0 for ``NAME.npz``), for ordering a song's dances by seed."""
    tail = path.stem.rsplit(SAMPLE_SEP, 1)[1] if SAMPLE_SEP in path.stem else "0"
    return int(tail) if tail.isdigit() else 0


def group_predictions(paths: Sequence[Path]) -> dict[str, list[Path]]:
    """Group prediction files by the reference dance they belong to (``NAME`` or ``NAME__k``)."""
    groups: dict[str, list[Path]] = {}
    for p in sorted(paths):
        stem = p.stem
        name = stem.split(SAMPLE_SEP, 1)[0] if SAMPLE_SEP in stem else stem
        groups.setdefault(name, []).append(p)
    return groups


def evaluate_motions(
    pred: Mapping[str, Sequence[Any]],
    ref: Mapping[str, Any],
    *,
    music_beats: Mapping[str, np.ndarray] | None = None,
    genres: Mapping[str, str] | None = None,
    fid_reference: Sequence[Any] | None = None,
    classifier: Any = None,
    settings: EvalSettings | None = None,
) -> dict[str, Any]:
    """Evaluate generated :class:`~dancekit.motion.Motion` objects against real ones.

    Parameters
    ----------
    pred : reference name → the generated motions for that dance's music
    ref : reference name → the real motion (ground truth; its music, genre and length)
    music_beats : reference name → music beat times (s from the dance start); None skips beats
    genres : reference name → genre of the music; None skips ACC
    fid_reference : the real motions forming the FID reference distribution (default: ``ref``)
    classifier : a :class:`~dancekit.pipelines.StylePipeline`, or None to skip the style metrics
    settings : :class:`EvalSettings`

    Returns
    -------
    The report dict: ``settings``, ``counts``, ``metrics`` (generated), ``real`` (the reference
    dances, same metrics), ``per_dance``, ``fid_curve``, ``fid_breakdown`` (the features each FID comes from,
    :func:`dancekit.metrics.fid.fid_breakdown`), ``classifier``, ``notes``.
    """
    settings = settings or EvalSettings()
    notes: list[str] = []
    if not pred:
        raise ParameterError("no generated dances to evaluate")
    missing = sorted(set(pred) - set(ref))
    if missing:
        raise DatasetError(f"generated dances for unknown reference dances: {missing[:5]} (reference has {len(ref)})")
    skeleton = next(iter(ref.values())).skeleton
    for name, motions in pred.items():
        for m in motions:
            if tuple(m.skeleton.joint_names) != tuple(skeleton.joint_names):
                raise ParameterError(
                    f"generated dance for {name} uses skeleton {m.skeleton.name!r}, the reference {skeleton.name!r}"
                )
    names = sorted(pred)
    ref_names = sorted(ref)
    fid_ref = list(fid_reference) if fid_reference is not None else [ref[n] for n in ref_names]
    fid_ref_fps = fid_ref[0].fps
    if any(abs(m.fps - fid_ref_fps) > 1e-6 for m in fid_ref):
        raise ParameterError("the FID reference dances must share one frame rate")

    # --- per dance ------------------------------------------------------------------------
    per_dance: dict[str, dict[str, float]] = {}
    flat_pred: list[tuple[str, Any]] = [(n, m) for n in names for m in pred[n]]
    for k, (name, m) in enumerate(flat_pred):
        beats = music_beats.get(name) if music_beats is not None else None
        row = dance_metrics(m.to_positions(), fps=m.fps, skeleton=m.skeleton, music_beats=beats, settings=settings)
        gt = ref[name]
        p = resample_positions(np.asarray(m.to_positions(), np.float64), orig_fps=m.fps,
                               target_fps=gt.fps) * m.skeleton.unit_scale
        g = np.asarray(gt.to_positions(), np.float64) * gt.skeleton.unit_scale
        row["fd_dual_mean_joint_distance_cm"] = 100.0 * mean_joint_distance(p, g)
        per_dance[f"{name}#{k}"] = row
    real_rows = {}
    for name in names:
        gt = ref[name]
        beats = music_beats.get(name) if music_beats is not None else None
        row = dance_metrics(gt.to_positions(), fps=gt.fps, skeleton=gt.skeleton, music_beats=beats, settings=settings)
        row["fd_dual_mean_joint_distance_cm"] = 0.0
        real_rows[name] = row
    keys = list(next(iter(per_dance.values())).keys())
    metrics = {k: _nanmean([r[k] for r in per_dance.values()]) for k in keys}
    real = {k: _nanmean([r[k] for r in real_rows.values()]) for k in keys}
    for k in ("smoothed_energy", "jitter_speed", "jerk", "foot_skating_ratio"):
        ratio = metrics[k] / real[k] if real[k] else float("nan")
        metrics[f"{k}_ratio"] = ratio
        real[f"{k}_ratio"] = 1.0

    # --- AIST++ FID_k / FID_g --------------------------------------------------------------
    sets = {}
    for label, motions in (("pred", [m for _, m in flat_pred]), ("real", [ref[n] for n in names])):
        by_fps: dict[float, list] = {}
        for m in motions:  # in the reference skeleton's units
            scale = m.skeleton.unit_scale / skeleton.unit_scale
            by_fps.setdefault(float(m.fps), []).append(np.asarray(m.to_positions(), np.float64) * scale)
        sets[label] = by_fps
    ref_pos = [m.to_positions() for m in fid_ref]
    breakdown: dict[str, list[dict]] = {}
    for kind, short in (("kinetic", "k"), ("geometric", "g")):
        fr = fid_mod.feature_sets(ref_pos, fps=fid_ref_fps, skeleton=skeleton, kind=kind,
                                  segment_seconds=settings.segment_seconds, bug_compatible=settings.bug_compatible)
        for label, by_fps in sets.items():
            fp = np.concatenate([
                fid_mod.feature_sets(ps, fps=f, skeleton=skeleton, kind=kind, segment_seconds=settings.segment_seconds,
                                     bug_compatible=settings.bug_compatible)
                for f, ps in by_fps.items()
            ])
            fr_z, fp_z, keep = fid_mod.normalize_features(fr, fp)
            target = metrics if label == "pred" else real
            if len(fp_z) >= 2 and keep.any():
                value, info = fid_mod.frechet_distance(fp_z, fr_z, return_info=True)
                target[f"fid_{short}"] = value
                target[f"div_{short}"] = fid_mod.average_pairwise_distance(fp_z)
                if label == "pred":
                    names_kept = np.asarray(fid_mod.feature_names(kind, skeleton))[keep]
                    top = fid_mod.fid_breakdown(fp_z, fr_z, names_kept, top=5)
                    breakdown[f"fid_{short}"] = top
                    if top and top[0]["share"] >= 0.5:
                        notes.append(
                            f"FID_{short}: {top[0]['share']:.0%} of its per-feature distance is one feature, "
                            f"{top[0]['feature']} (generated mean {top[0]['mean_z']:+.1f} reference SDs from the "
                            f"reference mean); see the report's fid_breakdown"
                        )
                if info["retried"]:
                    notes.append(f"FID_{short} ({label}): sqrtm needed {info['offset']:.3g} * I (max imag {info['max_imag']:.3g})")
            else:
                target[f"fid_{short}"] = target[f"div_{short}"] = float("nan")
                notes.append(f"FID_{short} ({label}): fewer than 2 feature vectors; skipped")
        fr_z, keep = fid_mod.normalize_features(fr)
        metrics[f"div_{short}_ref"] = fid_mod.average_pairwise_distance(fr_z)
        metrics[f"fid_{short}_dims"] = int(keep.sum())

    # --- style classifier: FID, ACC, Diversity, Multimodality, FID curve ------------------
    fid_curve: list[float] = []
    clf_info = None
    if classifier is not None:
        classifier.check_skeleton(skeleton)
        ref_w = np.concatenate([classifier.embed(m.to_positions(), fps=m.fps, skeleton=m.skeleton)[0] for m in fid_ref])
        clf_info = {"genres": classifier.genres, "window_frames": classifier.window, "fps": classifier.fps,
                    "path": str(getattr(classifier, "folder", "")), "n_reference_windows": int(len(ref_w))}
        for label, items in (("pred", flat_pred), ("real", [(n, ref[n]) for n in names])):
            target = metrics if label == "pred" else real
            windows, dance_feats, music, correct = [], [], [], []
            for name, m in items:
                f, logp = classifier.embed(m.to_positions(), fps=m.fps, skeleton=m.skeleton)
                windows.append(f)
                dance_feats.append(f.mean(axis=0))
                music.append(name)
                if genres is not None and name in genres and genres[name] in classifier.genres:
                    correct.append(dance_genre(logp) == classifier.genres.index(genres[name]))
            allw = np.concatenate(windows)
            target["style_fid"] = fid_mod.frechet_distance(allw, ref_w) if len(allw) >= 2 else float("nan")
            target["style_acc"] = float(np.mean(correct)) if correct else float("nan")
            dfe = np.stack(dance_feats)
            target["style_diversity"] = style_diversity(dfe, music, pairs=settings.diversity_pairs, seed=settings.seed)
            target["style_multimodality"] = multimodality(dfe, music)
            if label == "pred":
                fid_curve = stability.windowed_fid(windows, ref_w)
        if genres is None:
            notes.append("no genres known (no prepared dataset): ACC skipped")
    else:
        notes.append("no style classifier: FID / ACC / Diversity / Multimodality skipped")
    if music_beats is None:
        notes.append("no music (no prepared dataset or audio folder): beat metrics skipped")

    n_samples = {n: len(pred[n]) for n in names}
    return {
        "settings": {**dataclasses.asdict(settings), "fps": sorted({float(m.fps) for _, m in flat_pred}),
                     "reference_fps": sorted({float(ref[n].fps) for n in names}),
                     "style_window_seconds": (classifier.window / classifier.fps) if classifier is not None else None},
        "counts": {"generated_files": len(flat_pred), "songs": len(names), "samples_per_song": n_samples,
                   "reference_dances": len(ref_names), "fid_reference_dances": len(fid_ref)},
        "metrics": json_safe(metrics),
        "real": json_safe(real),
        "per_dance": {k: json_safe(v) for k, v in per_dance.items()},
        "fid_curve": json_safe(fid_curve),
        "fid_breakdown": json_safe(breakdown),
        "classifier": clf_info,
        "notes": notes,
    }


def json_safe(x: Any) -> Any:
    """Floats with NaN / inf replaced by None (valid JSON)."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


# ---------------------------------------------------------------------------------------------
# folders


def _read_dir(folder: Path, what: str) -> list[Path]:
    if not folder.is_dir():
        raise DatasetError(f"{what} folder not found: {folder}")
    files = sorted(folder.glob("*.npz"))
    if not files:
        raise DatasetError(f"no .npz motions in {what} folder {folder}")
    return files


def _music_from_audio(audio_dir: Path, names: Sequence[str]) -> dict[str, np.ndarray]:
    from dancekit.audio import load
    from dancekit.features import beat_track

    if not audio_dir.is_dir():
        raise DatasetError(f"audio folder not found: {audio_dir}")
    out = {}
    for name in names:
        path = next((audio_dir / f"{name}{s}" for s in AUDIO_SUFFIXES if (audio_dir / f"{name}{s}").is_file()), None)
        if path is None:
            raise DatasetError(f"no audio for {name} in {audio_dir} (looked for {name}{{{','.join(AUDIO_SUFFIXES)}}})")
        y, sr = load(path)
        out[name] = beat_track(y=y, sr=sr)[1]
    return out


def evaluate_dirs(
    pred_dir: str | os.PathLike,
    ref_dir: str | os.PathLike,
    *,
    data: str | os.PathLike | None = None,
    audio_dir: str | os.PathLike | None = None,
    classifier: Any = "default",
    settings: EvalSettings | None = None,
    preset: str | None = None,
    split: str = "test",
    seed_sets: int | None = None,
) -> dict[str, Any]:
    """Evaluate a folder of generated ``.npz`` dances (see the module docstring for the layout).

    Parameters
    ----------
    pred_dir : folder of ``NAME.npz`` / ``NAME__k.npz`` generated dances
    ref_dir : folder of real ``NAME.npz`` dances, or a prepared dataset folder (its test split)
    data : prepared dataset folder (music beats, genres, the ``train`` / ``all`` FID reference)
    audio_dir : folder of ``NAME.<wav|mp3|ogg|flac>`` songs (when there is no prepared dataset)
    classifier : a :class:`~dancekit.pipelines.StylePipeline`, a checkpoint folder or model name,
        ``"default"`` (the embedded classifier; skipped with a note if it is missing) or None (skip the
        style metrics)
    settings : :class:`EvalSettings`
    preset : feature preset whose ``beat_times`` are used (default ``revolution`` if prepared)
    split : the split of a prepared ``ref_dir`` that holds the reference dances (default ``test``)
    seed_sets : K: the report's ``seed_sets`` entry gives FID_k / FID_g of K disjoint sets of consecutive seeds
        (``NAME__k`` in the order of k; :func:`dancekit.evaluation.ablation.seed_set_fids`), against the same
        FID reference

    Raises
    ------
    DatasetError
        For missing folders or files, or generated dances whose name matches no reference dance.
    """
    from dancekit.motion import read_motion

    settings = settings or EvalSettings()
    pred_dir, ref_dir = Path(pred_dir), Path(ref_dir)
    groups = group_predictions(_read_dir(pred_dir, "generated"))
    prepared = None
    if data is not None:
        from dancekit.data import PreparedData

        prepared = PreparedData(data)
    if (ref_dir / "meta.json").is_file():
        from dancekit.data import PreparedData

        ref_data = PreparedData(ref_dir)
        prepared = prepared or ref_data
        ref = {n: ref_data.motion(n) for n in ref_data.names(split)}
        ref_source = f"{ref_dir} ({split} split)"
    else:
        ref = {p.stem: read_motion(p) for p in _read_dir(ref_dir, "reference")}
        ref_source = str(ref_dir)
    unknown = sorted(set(groups) - set(ref))
    if unknown:
        bad = [str(groups[n][0]) for n in unknown[:3]]
        raise DatasetError(f"generated dances name no reference dance in {ref_source}: {bad}")
    pred = {n: [read_motion(p) for p in ps] for n, ps in groups.items()}

    music_beats = genres = None
    if prepared is not None:
        preset = preset or ("revolution" if "revolution" in prepared.presets else prepared.presets[0])
        music_beats, genres = {}, {}
        for n in pred:
            if n not in prepared.meta["dances"]:
                raise DatasetError(f"dance {n} is not in the prepared dataset {prepared.root}")
            music_beats[n] = np.asarray(prepared.features(n, preset)["beat_times"], np.float64)
            genres[n] = prepared.genre(n)
    elif audio_dir is not None:
        music_beats = _music_from_audio(Path(audio_dir), sorted(pred))

    mode = settings.fid_reference or ("train" if prepared is not None else "ref")
    if mode != "ref" and prepared is None:
        raise ParameterError(f"fid_reference={mode!r} needs a prepared dataset (--data)")
    if mode == "ref":
        fid_reference = [ref[n] for n in sorted(ref)]
    else:
        names = prepared.names("train") if mode == "train" else prepared.names()
        fid_reference = [prepared.motion(n) for n in names]

    model, clf_note = load_classifier(classifier)
    report = evaluate_motions(pred, ref, music_beats=music_beats, genres=genres, fid_reference=fid_reference,
                              classifier=model, settings=dataclasses.replace(settings, fid_reference=mode))
    report["seed_distance"] = _seed_distance(pred)
    if seed_sets is not None:
        from dancekit.evaluation.ablation import seed_set_fids

        by_seed = {n: [read_motion(p) for p in sorted(ps, key=_sample_index)] for n, ps in groups.items()}
        report["seed_sets"] = seed_set_fids(by_seed, fid_reference, sets=seed_sets,
                                            segment_seconds=settings.segment_seconds,
                                            bug_compatible=settings.bug_compatible)
    report["settings"].update({
        "pred_dir": str(pred_dir), "ref": ref_source, "data": str(data) if data is not None else None,
        "audio_dir": str(audio_dir) if audio_dir is not None else None,
        "beat_source": (f"prepared features_{preset}.npz beat_times" if prepared is not None
                        else "beat_track on the audio files" if audio_dir is not None else None),
    })
    if clf_note:
        report["notes"].append(clf_note)
    return report


def load_classifier(classifier: Any = "default") -> tuple[Any, str | None]:
    """The style classifier of an evaluation and a note for the report (or None).

    ``"default"``: the embedded classifier (:data:`~dancekit.pipelines.style.DEFAULT_STYLE_MODEL`; a note
    instead when it cannot be found); a string or path: that checkpoint folder or model name; None: no
    classifier; anything else is taken as a loaded :class:`~dancekit.pipelines.StylePipeline`.
    """
    from dancekit.pipelines.style import DEFAULT_STYLE_MODEL, StylePipeline

    if isinstance(classifier, str) and classifier == "default":
        try:
            return StylePipeline.from_pretrained(DEFAULT_STYLE_MODEL), None
        except (CheckpointError, ParameterError) as exc:
            return None, f"the shipped style classifier is missing: {exc}"
    if isinstance(classifier, str | os.PathLike):
        return StylePipeline.from_pretrained(classifier), None
    return classifier, None


def _seed_distance(pred: Mapping[str, Sequence[Any]]) -> dict[str, Any]:
    """The report's ``seed_distance`` entry (:func:`dancekit.evaluation.stages.seed_distance`)."""
    from dancekit.evaluation.stages import seed_distance

    return seed_distance(pred)
