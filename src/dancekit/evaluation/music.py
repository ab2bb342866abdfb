"""Score music composed for dances (or any music) against the dances' real music, next to click-track baselines.

What ``dancekit evaluate --music DIR`` and ``dancekit evaluate --compose MODEL`` run. The metric functions are
:mod:`dancekit.metrics.music_beats` and :func:`dancekit.metrics.notes_accuracy`; this module loads the music,
forms the baselines, pools the scores over a split's dances and tables them (docs/METRICS.md, "Music").

Pieces
    A :class:`MusicPiece` is either **audio** (mono, at ``settings.sr``, 22050 Hz: the rate both published
    onset scripts load audio at), or a **click track** (its click times). For audio, the onsets are found with
    each protocol's librosa settings on every clip separately (each clip is a file in the published
    evaluations), and the beats are tracked on the whole piece (:func:`dancekit.features.beat_track`). For a
    click track the onsets and the beats are the click times (no detector, no tracker).

Notes (for the dual paper's notes accuracy)
    A composed ``.mid`` file's notes are its own (drums ignored). Audio without MIDI is written as notes the
    way ``dancekit compose`` writes G_D→M's output: its ``dual`` features (harmonic chroma and percussive beats,
    the 13 target columns of G_D→M) arranged by :func:`dancekit.audio.midi.arrange` (a triad on every beat).
    The real music is always written so, which makes it the reference of the notes accuracy; click tracks
    have no notes (–).

Per dance ``NAME`` of the split (compared over the shorter of the dance and the piece)
    ``beat_f1_music`` (beat F1 at ±``beat_tolerance`` s against the real music's tracked beats),
    ``beat_f1_dance`` (against the dance's kinematic beats, :func:`dancekit.motion.analysis.kinematic_beats`),
    ``tempo_bpm`` (60 / median inter-beat interval), ``tempo_error`` (relative to the real music's tempo
    measured the same way; a doubled or halved tempo counts fully), ``tempo_hit`` (error ≤ ``tempo_tolerance``),
    ``notes_accuracy``, and the bin counts [R, G, H] of every clip for both protocols and every clip length.

Pooled over the split (the table)
    BCS / BHS of protocol A and BCS / BHS / CSD / HSD / F1 of protocol B for every clip length
    (:func:`~dancekit.metrics.music_beats.coverage_hit_scores` on the clips of all dances together: scores
    are means over clips, as published); means over dances of the beat F1s, the tempo error and the notes
    accuracy; ``tempo_hit_share`` is the share of dances within the tolerance.

Baselines (columns of the same table; ``BASELINE_COLUMNS``)
    ``real_music`` (the real music against itself: BCS = BHS = 1 under A), ``metronome`` (clicks at the real
    music's tempo with a random phase, seeded per dance), ``metronome_fast`` / ``metronome_slow`` (tempo
    × 1.2 / × 0.8), ``dense_clicks`` (4 clicks a second), ``kinematic_clicks`` (clicks on the dance's own
    kinematic beats), ``other_music`` (the real music of the next dance of the split, cyclically) and
    ``arranged_target`` (what ``dancekit compose`` would make of a perfect G_D→M output: the real music's
    ``dual`` target arranged and rendered like composed music; ``render_target=False`` leaves it out).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancekit.errors import DatasetError, ParameterError
from dancekit.metrics import music_beats as mb
from dancekit.metrics.music import note_array, notes_accuracy

__all__ = [
    "BASELINE_COLUMNS",
    "MusicPiece",
    "MusicSettings",
    "arranged_target",
    "audio_piece",
    "click_piece",
    "compose_split",
    "evaluate_music",
    "format_music_markdown",
    "load_music_dir",
    "music_baselines",
    "music_rows",
    "music_table",
    "piece_scores",
    "pool_scores",
]

BASELINE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("real_music", "real music"),
    ("metronome", "metronome (real tempo, random phase)"),
    ("metronome_fast", "metronome +20 %"),
    ("metronome_slow", "metronome −20 %"),
    ("dense_clicks", "dense clicks (4/s)"),
    ("kinematic_clicks", "clicks on kinematic beats"),
    ("other_music", "another dance's music"),
    ("arranged_target", "real music's dual target, arranged"),
)
CLICK_BASELINES = ("metronome", "metronome_fast", "metronome_slow", "dense_clicks", "kinematic_clicks")
MUSIC_SUFFIXES = (".mid", ".midi", ".wav", ".mp3", ".ogg", ".flac")


@dataclass
class MusicSettings:
    """Every knob of the music scores (recorded in the report)."""

    clip_lengths: tuple[float | None, ...] = (2.0, 5.0, 25.0, None)  # s; None: whole dances
    bin_size: float = mb.DEFAULT_BIN  # s
    beat_tolerance: float = mb.DEFAULT_TOLERANCE  # s, beat F1 window half-width
    tempo_tolerance: float = 0.05  # relative
    wrong_tempo: tuple[float, float] = (1.2, 0.8)  # metronome_fast, metronome_slow factors
    dense_rate: float = 4.0  # clicks per second
    sr: int = mb.DETECTOR_SR  # Hz, audio rate of every piece
    notes_fps: float = 25.0  # grid of the notes accuracy
    render: str = "builtin"  # MIDI → audio: builtin | fluidsynth | auto
    seed: int = 0  # metronome phases
    baselines: bool = True
    render_target: bool = True  # the arranged_target baseline (a perfect G_D→M output, arranged and rendered)

    def __post_init__(self) -> None:
        if not self.clip_lengths:
            raise ParameterError("clip_lengths must name at least one clip length (or None for whole dances)")
        for c in self.clip_lengths:
            if c is not None and not (math.isfinite(c) and c >= self.bin_size):
                raise ParameterError(f"clip length {c} s must be a number >= the bin size ({self.bin_size} s)")
        if len(self.wrong_tempo) != 2 or any(not f > 0 or abs(f - 1) < 1e-9 for f in self.wrong_tempo):
            raise ParameterError(f"wrong_tempo must be two positive factors other than 1, got {self.wrong_tempo}")
        if self.render not in ("builtin", "fluidsynth", "auto"):
            raise ParameterError(f"render must be builtin, fluidsynth or auto, got {self.render!r}")
        for name in ("bin_size", "beat_tolerance", "tempo_tolerance", "dense_rate", "notes_fps"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be positive, got {getattr(self, name)}")


def clip_label(clip_length: float | None) -> str:
    """``"2s"``, ``"2.5s"`` or ``"whole"`` (the suffix of the clip-length metric keys)."""
    return "whole" if clip_length is None else f"{clip_length:g}s"


# ---------------------------------------------------------------------------------------------
# pieces


@dataclass
class MusicPiece:
    """One piece of music for one dance: audio ``y`` at ``sr`` (onsets detected, beats tracked) or ``clicks``
    (click times, s: the onsets and the beats). ``notes``: (N, 3) [start, end, pitch] or None; ``duration`` s."""

    duration: float
    beats: np.ndarray
    y: np.ndarray | None = None
    sr: int = mb.DETECTOR_SR
    clicks: np.ndarray | None = None
    notes: np.ndarray | None = None
    source: str = ""
    _onsets: dict = field(default_factory=dict, repr=False)

    def onsets(self, protocol: str, start: float, length: float) -> np.ndarray:
        """Onset times (s from ``start``) in the clip ``[start, start + length)``; cached per clip."""
        key = (protocol, round(start, 6), round(length, 6))
        if key not in self._onsets:
            if self.clicks is not None:
                t = self.clicks[(self.clicks >= start) & (self.clicks < start + length)] - start
            else:
                a = int(round(start * self.sr))
                b = min(len(self.y), int(round((start + length) * self.sr)))
                t = mb.onset_times(self.y[a:b], sr=self.sr, protocol=protocol, detector_sr=None)
            self._onsets[key] = np.asarray(t, np.float64)
        return self._onsets[key]


def arranged_target(y: np.ndarray, sr: int) -> Any:
    """Audio → a ``pretty_midi.PrettyMIDI`` written as compose writes G_D→M's output: the audio's ``dual``
    target (harmonic chroma + percussive beats, 25 fps) arranged by :func:`dancekit.audio.midi.arrange`."""
    from dancekit.audio.midi import arrange
    from dancekit.features import extract

    fs = extract(y, sr=sr, fps=25.0, preset="dual")
    chroma, beat = fs.block("chroma_harmonic"), fs.block("beat_percussive")[:, 0]
    return arrange(chroma, beat, fps=fs.fps).midi


def audio_piece(y: np.ndarray, *, sr: int, notes: Any = None, with_notes: bool = True,
                source: str = "") -> MusicPiece:
    """An audio piece: ``y`` (n,) float mono at ``sr`` Hz; beats tracked; notes from ``notes`` (a PrettyMIDI or
    (N, 3+) array) or, when None and ``with_notes``, transcribed as described in the module docstring."""
    from dancekit.features import beat_track

    y = np.ascontiguousarray(np.asarray(y, np.float32).reshape(-1))
    if not np.isfinite(y).all():
        raise ParameterError(f"{source or 'audio'}: contains NaN or inf samples")
    _, beats = beat_track(y=y, sr=sr) if np.any(y) else (0.0, np.zeros(0))
    if notes is not None:
        n = note_array(notes)
    elif with_notes and np.any(y) and len(y) >= sr:
        n = note_array(arranged_target(y, sr))
    else:
        n = None
    return MusicPiece(duration=len(y) / sr, beats=np.asarray(beats, np.float64), y=y, sr=sr, notes=n, source=source)


def click_piece(times: np.ndarray, *, duration: float, source: str = "") -> MusicPiece:
    """A click track: clicks at ``times`` (s) in ``[0, duration)``; they are its onsets and its beats."""
    t = mb.clicks_on(times, duration=duration)
    return MusicPiece(duration=float(duration), beats=t, clicks=t, source=source)


def _clip_notes(notes: np.ndarray | None, duration: float) -> np.ndarray | None:
    if notes is None:
        return None
    n = notes[notes[:, 0] < duration].copy()
    n[:, 1] = np.minimum(n[:, 1], duration)
    return n


# ---------------------------------------------------------------------------------------------
# scores


def piece_scores(gen: MusicPiece, ref: MusicPiece, *, kinematic: np.ndarray, duration: float,
                 settings: MusicSettings) -> dict[str, Any]:
    """Every per-dance score of ``gen`` against the real music ``ref`` and the dance's kinematic beats (s).

    The span compared is ``[0, min(duration, gen.duration, ref.duration))``. Returns a flat dict of the
    per-dance values of the module docstring plus ``counts``: {"A_2s": [[R, G, H], ...], ...}.
    """
    d = float(min(duration, gen.duration, ref.duration))
    out: dict[str, Any] = {"duration_s": d}
    counts: dict[str, list] = {}
    for protocol in ("A", "B"):
        for clip in settings.clip_lengths:
            rows = [mb.bin_counts(gen.onsets(protocol, s, n), ref.onsets(protocol, s, n), duration=n,
                                  bin_size=settings.bin_size)
                    for s, n in mb.clip_spans(d, clip_length=clip, bin_size=settings.bin_size)]
            counts[f"{protocol}_{clip_label(clip)}"] = np.asarray(rows, np.int64).reshape(-1, 3).tolist()
    out["counts"] = counts
    gb, rb = gen.beats[gen.beats < d], ref.beats[ref.beats < d]
    kb = kinematic[kinematic < d]
    out["beat_f1_music"] = mb.beat_f1(gb, rb, tolerance=settings.beat_tolerance)
    out["beat_f1_dance"] = mb.beat_f1(gb, kb, tolerance=settings.beat_tolerance)
    out["tempo_bpm"] = mb.tempo_from_beats(gb)
    out["tempo_ref_bpm"] = ref_bpm = mb.tempo_from_beats(rb)
    if math.isfinite(ref_bpm):
        out["tempo_error"] = mb.tempo_error(out["tempo_bpm"], ref_bpm)
        out["tempo_hit"] = float(mb.tempo_hit(out["tempo_bpm"], ref_bpm, tolerance=settings.tempo_tolerance))
    else:
        out["tempo_error"] = out["tempo_hit"] = float("nan")
    gn, rn = _clip_notes(gen.notes, d), _clip_notes(ref.notes, d)
    ok = gn is not None and rn is not None and len(rn) > 0
    out["notes_accuracy"] = notes_accuracy(gn, rn, fps=settings.notes_fps) if ok and len(gn) else (
        0.0 if ok else float("nan"))
    return out


def _nanmean(values: Sequence[float]) -> float:
    a = np.asarray([v for v in values if v is not None], np.float64)
    a = a[np.isfinite(a)]
    return float(a.mean()) if a.size else float("nan")


def pool_scores(per_dance: Mapping[str, Mapping[str, Any]], settings: MusicSettings) -> dict[str, float]:
    """The table's values from :func:`piece_scores` of every dance (see the module docstring)."""
    out: dict[str, float] = {}
    for protocol in ("A", "B"):
        for clip in settings.clip_lengths:
            key = f"{protocol}_{clip_label(clip)}"
            c = np.concatenate([np.asarray(v["counts"][key], np.int64).reshape(-1, 3) for v in per_dance.values()])
            s = mb.coverage_hit_scores(c, protocol=protocol)
            for name, value in s.items():
                out[f"{name}_{key.lower()}"] = float(value)
    for key in ("beat_f1_music", "beat_f1_dance", "tempo_bpm", "tempo_error", "notes_accuracy"):
        out[key] = _nanmean([v[key] for v in per_dance.values()])
    out["tempo_hit_share"] = _nanmean([v["tempo_hit"] for v in per_dance.values()])
    return out


# ---------------------------------------------------------------------------------------------
# the split: references, baselines, composed music


@dataclass
class _Dance:
    name: str
    duration: float
    kinematic: np.ndarray
    music: MusicPiece


def _load_audio(path: str | os.PathLike, sr: int, *, start: float | None = None,
                end: float | None = None) -> np.ndarray:
    from dancekit.audio.io import load

    y, _ = load(path, sr=sr, start=start, end=end)
    return np.asarray(y, np.float32)


def _split_dances(data: Any, names: Sequence[str], settings: MusicSettings,
                  progress: Callable[[str], None] | None) -> list[_Dance]:
    from dancekit.motion.analysis import kinematic_beats

    dances = []
    for n in names:
        motion = data.motion(n)
        a = data.audio(n)
        y = _load_audio(a.path, settings.sr, start=a.start, end=a.end)
        duration = motion.num_frames / motion.fps
        kin = kinematic_beats(motion.to_positions(), fps=motion.fps, skeleton=motion.skeleton)
        dances.append(_Dance(n, duration, kin, audio_piece(y, sr=settings.sr, source=f"{a.path}")))
        if progress:
            progress(f"real music of {n}: {len(dances[-1].music.beats)} beats")
    return dances


def music_baselines(dance: _Dance, other: _Dance, index: int, settings: MusicSettings) -> dict[str, MusicPiece]:
    """The baseline pieces of one dance (``BASELINE_COLUMNS``); ``index`` seeds the metronome phases."""
    d, ref = dance.duration, dance.music
    bpm = mb.tempo_from_beats(ref.beats[ref.beats < d])
    rng = np.random.default_rng([settings.seed, index])
    out = {"real_music": ref}
    if math.isfinite(bpm):
        out["metronome"] = click_piece(mb.metronome(bpm=bpm, duration=d, seed=rng), duration=d)
        fast, slow = settings.wrong_tempo
        out["metronome_fast"] = click_piece(mb.wrong_tempo_metronome(bpm=bpm, duration=d, factor=fast, seed=rng),
                                            duration=d)
        out["metronome_slow"] = click_piece(mb.wrong_tempo_metronome(bpm=bpm, duration=d, factor=slow, seed=rng),
                                            duration=d)
    out["dense_clicks"] = click_piece(mb.dense_clicks(duration=d, rate=settings.dense_rate), duration=d)
    out["kinematic_clicks"] = click_piece(dance.kinematic, duration=d)
    out["other_music"] = other.music
    if settings.render_target:
        from dancekit.audio.midi import render

        midi = arranged_target(ref.y, ref.sr)
        y, _ = render(midi, sr=ref.sr, backend=settings.render)
        out["arranged_target"] = audio_piece(y, sr=ref.sr, notes=midi, source="arranged dual target")
    return out


def load_music_dir(folder: str | os.PathLike, names: Sequence[str], settings: MusicSettings) -> dict[str, MusicPiece]:
    """Composed music of a folder: ``NAME.mid`` (notes; rendered, or ``NAME.wav`` beside it is the audio) or
    ``NAME.wav|.mp3|.ogg|.flac`` (audio; notes transcribed) for every dance ``NAME`` of ``names``."""
    import pretty_midi

    from dancekit.audio.midi import render

    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError(f"no music folder {folder}")
    out = {}
    missing = []
    for n in names:
        found = {p.suffix.lower(): p for p in folder.glob(f"{n}.*") if p.suffix.lower() in MUSIC_SUFFIXES}
        midi_path = found.get(".mid") or found.get(".midi")
        audio_path = next((found[s] for s in MUSIC_SUFFIXES[2:] if s in found), None)
        if midi_path is None and audio_path is None:
            missing.append(n)
            continue
        midi = None
        if midi_path is not None:
            try:
                midi = pretty_midi.PrettyMIDI(str(midi_path))
            except Exception as exc:  # noqa: BLE001 - any parse failure of a user file
                raise DatasetError(f"cannot read MIDI file {midi_path}: {exc}") from None
        if audio_path is not None:
            y = _load_audio(audio_path, settings.sr)
        else:
            y, _ = render(midi, sr=settings.sr, backend=settings.render)
        src = ", ".join(str(p) for p in (midi_path, audio_path) if p is not None)
        out[n] = audio_piece(y, sr=settings.sr, notes=midi, source=src)
    if missing:
        raise DatasetError(f"{folder}: no music for {len(missing)} dance(s) of the split, e.g. {missing[0]}.mid|.wav")
    return out


def compose_split(model: str | os.PathLike, data_root: str | os.PathLike, out: str | os.PathLike, *,
                  split: str = "test", seed: int = 0, tempo: str | float | None = None, render: str = "builtin",
                  progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Compose music for every dance of ``split`` with a ``dual`` model: ``out/NAME.mid`` and ``out/NAME.wav``
    (``out`` is written as a whole: it appears, or replaces an earlier one, once every piece is written).

    Returns ``{"seconds": dance seconds, "elapsed_s": composing + writing time, "model": folder}``.
    """
    from dancekit._io import atomic_dir
    from dancekit.data import PreparedData
    from dancekit.pipelines.dual import ComposePipeline

    data = PreparedData(data_root)
    pipe = ComposePipeline.from_pretrained(model)
    seconds, t0 = 0.0, time.perf_counter()
    with atomic_dir(out) as tmp:  # the folder appears once every piece is written
        for n in data.names(split):
            motion = data.motion(n)
            piece = pipe(motion, seed=seed, tempo=tempo)
            piece.write(tmp, stem=n, render=render)
            seconds += motion.num_frames / motion.fps
            if progress:
                progress(f"composed {n}: {piece.arrangement.tempo:.1f} BPM, "
                         f"{len(piece.arrangement.beat_times)} beats")
    return {"seconds": seconds, "elapsed_s": time.perf_counter() - t0, "model": str(pipe.folder)}


def evaluate_music(data_root: str | os.PathLike, *, music: Mapping[str, MusicPiece] | str | os.PathLike | None,
                   split: str = "test", settings: MusicSettings | None = None, label: str = "composed",
                   progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Score composed music (a folder, see :func:`load_music_dir`, or pieces by dance name; None: baselines
    only) for the dances of ``split`` of a prepared dataset, with the baselines.

    Returns the report: ``columns`` {column: pooled scores}, ``labels`` {column: title}, ``per_dance``
    {column: {NAME: scores}}, ``settings``, ``counts``, ``sources``, ``notes``; undefined scores (NaN) are None.
    """
    from dancekit.data import PreparedData

    settings = settings or MusicSettings()
    data = PreparedData(data_root)
    names = data.names(split)
    if not names:
        raise DatasetError(f"{data_root}: the {split} split has no dances")
    pieces = load_music_dir(music, names, settings) if isinstance(music, (str, os.PathLike)) else music
    dances = _split_dances(data, names, settings, progress)
    columns: dict[str, dict[str, Any]] = {}
    labels = {}
    if pieces is not None:
        columns["composed"] = {d.name: pieces[d.name] for d in dances}
        labels["composed"] = label
    if settings.baselines:
        for i, d in enumerate(dances):
            other = dances[(i + 1) % len(dances)]
            for key, piece in music_baselines(d, other, i, settings).items():
                columns.setdefault(key, {})[d.name] = piece
        labels.update(BASELINE_COLUMNS)
    if not columns:
        raise ParameterError("nothing to score: no composed music and no baselines")
    per_dance: dict[str, dict[str, Any]] = {}
    pooled: dict[str, dict[str, float]] = {}
    for key, by_name in columns.items():
        per_dance[key] = {d.name: piece_scores(by_name[d.name], d.music, kinematic=d.kinematic, duration=d.duration,
                                               settings=settings)
                          for d in dances if d.name in by_name}
        pooled[key] = pool_scores(per_dance[key], settings)
        if progress:
            progress(f"scored {key}")
    notes = [f"{len(dances)} dances of the {split} split, {sum(d.duration for d in dances):.0f} s."]
    targets = composer_targets(pooled, labels, settings) if "composed" in pooled and settings.baselines else None
    if targets is not None:
        notes += targets["notes"]
    if "metronome" not in pooled and settings.baselines:
        notes.append("no metronome baselines: the real music's tempo could not be measured")
    settings_out = asdict(settings)
    settings_out["clip_lengths"] = [clip_label(c) for c in settings.clip_lengths]
    from dancekit.evaluation.score import json_safe

    return {
        "kind": "music",
        "columns": json_safe(pooled),
        "labels": {k: labels[k] for k in pooled},
        "per_dance": json_safe(per_dance),
        "settings": settings_out,
        "counts": {"dances": len(dances), "seconds": sum(d.duration for d in dances), "split": split},
        "sources": {k: {n: p.source for n, p in v.items() if p.source} for k, v in columns.items()},
        "targets": json_safe(targets),
        "notes": notes,
    }


def composer_targets(pooled: Mapping[str, Mapping[str, float]], labels: Mapping[str, str],
                     settings: MusicSettings) -> dict[str, Any]:
    """The composer against its targets (issue 20): tempo within the tolerance on every dance, beat F1 against
    the real music above every click-track baseline; and the measures on which it loses to the metronome."""
    comp = pooled["composed"]
    clicks = {k: pooled[k]["beat_f1_music"] for k in CLICK_BASELINES if k in pooled}
    best = max(clicks, key=lambda k: -np.inf if not math.isfinite(clicks[k]) else clicks[k]) if clicks else None
    margin = comp["beat_f1_music"] - clicks[best] if best else float("nan")
    notes = [
        f"composer tempo within ±{settings.tempo_tolerance * 100:g} % of the real music on "
        f"{comp['tempo_hit_share'] * 100:.0f} % of the dances (target: all; mean relative error "
        f"{comp['tempo_error']:.3f})."]
    if best:
        notes.append(f"composer beat F1 vs real music {comp['beat_f1_music']:.3f}; best click track: {labels[best]} "
                     f"{clicks[best]:.3f}; margin {margin:+.3f} (target: > 0).")
    lost = []
    if "metronome" in pooled:
        met = pooled["metronome"]
        for key, label, _ in music_rows(settings.clip_lengths):
            if key.startswith("bcs_a") or key.startswith(("csd", "hsd")) or key in ("tempo_bpm", "notes_accuracy"):
                continue  # no better direction (BCS under A, spreads, tempo itself) or no metronome value
            c, m = comp.get(key), met.get(key)
            if c is None or m is None or not (math.isfinite(c) and math.isfinite(m)):
                continue
            if (c > m + 1e-12) if key == "tempo_error" else (c < m - 1e-12):
                lost.append(label)
        notes.append("composer loses to the metronome (real tempo, random phase) on: "
                     + ("; ".join(lost) if lost else "no measure") + ".")
    return {"tempo_hit_share": comp["tempo_hit_share"], "beat_f1_music": comp["beat_f1_music"],
            "best_click_baseline": best, "best_click_beat_f1": clicks.get(best, float("nan")) if best else None,
            "beat_f1_margin": margin, "loses_to_metronome_on": lost, "notes": notes}


# ---------------------------------------------------------------------------------------------
# tables


def music_rows(clip_lengths: Sequence[float | None]) -> list[tuple[str, str, str]]:
    """(key, label, format) rows of the music table for these clip lengths, in order."""
    rows = []
    for clip in clip_lengths:
        c = clip_label(clip)
        span = "whole dances" if clip is None else f"{clip:g}-s clips"
        rows += [(f"bcs_a_{c}", f"BCS, A ({span})", "{:.3f}"), (f"bhs_a_{c}", f"BHS, A ({span})", "{:.3f}")]
    for clip in clip_lengths:
        c = clip_label(clip)
        span = "whole dances" if clip is None else f"{clip:g}-s clips"
        rows += [(f"bcs_b_{c}", f"BCS, B ({span})", "{:.3f}"), (f"csd_b_{c}", f"CSD, B ({span})", "{:.3f}"),
                 (f"bhs_b_{c}", f"BHS, B ({span})", "{:.3f}"), (f"hsd_b_{c}", f"HSD, B ({span})", "{:.3f}"),
                 (f"f1_b_{c}", f"F1, B ({span})", "{:.3f}")]
    rows += [
        ("beat_f1_music", "Beat F1 vs real music (±0.1 s)", "{:.3f}"),
        ("beat_f1_dance", "Beat F1 vs dance kinematic beats (±0.1 s)", "{:.3f}"),
        ("tempo_bpm", "Tempo (BPM, mean over dances)", "{:.1f}"),
        ("tempo_error", "Tempo error vs real music (relative)", "{:.3f}"),
        ("tempo_hit_share", "Tempo within ±5 % (share of dances)", "{:.2f}"),
        ("notes_accuracy", "Notes accuracy (dual paper)", "{:.3f}"),
    ]
    return rows


def music_table(report: Mapping[str, Any]) -> str:
    """The report's markdown table: one row per score, one column per piece kind (no trailing newline)."""
    from dancekit.evaluation.report import format_value

    clips = [None if c == "whole" else float(c[:-1]) for c in report["settings"]["clip_lengths"]]
    keys = list(report["columns"])
    lines = ["| metric | " + " | ".join(report["labels"][k] for k in keys) + " |",
             "| --- |" + " ---: |" * len(keys)]
    for key, label, fmt in music_rows(clips):
        if key == "tempo_hit_share":
            label = f"Tempo within ±{report['settings']['tempo_tolerance'] * 100:g} % (share of dances)"
        values = [report["columns"][k].get(key) for k in keys]
        lines.append(f"| {label} | " + " | ".join(format_value(v, fmt) for v in values) + " |")
    return "\n".join(lines)


def format_music_markdown(report: Mapping[str, Any], *, title: str | None = None) -> str:
    """The music report as markdown: the table, then counts and notes."""
    lines = [f"### {title}", ""] if title else []
    lines.append(music_table(report))
    s = report["settings"]
    lines += ["", f"Bins of {s['bin_size']:g} s; protocol A = D2M-GAN / CDCD onsets (BCS = G/R, BHS = H/R), "
              f"B = LORIS onsets (BCS = H/G, BHS = H/R, CSD / HSD their standard deviations over clips); "
              f"scores are means over the clips of all dances. Click tracks: the clicks are the onsets and beats."]
    lines += [f"- {n}" for n in report.get("notes", [])]
    return "\n".join(lines) + "\n"


def write_report(report: Mapping[str, Any], path: str | os.PathLike) -> Path:
    """The report as JSON, atomically."""
    from dancekit._io import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(report, indent=1))
    return path
