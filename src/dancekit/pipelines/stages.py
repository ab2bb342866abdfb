"""Pipeline stages every dance model shares: beat-synchronous output and the physical clean-up.

Both run on the :class:`~dancekit.pipelines.DanceResult` of any dance pipeline (the model's motion on its
own skeleton, 3D positions), on by default (``pipe(song, beat_sync=False, cleanup=False)`` gives the
model's own output):

* **beat sync** (:func:`beat_sync`): the song (excerpt) is beat-tracked on the fine grid
  (:func:`dancekit.features.pulse.song_beats`); a song without a clear pulse (speech, a bird, a whale's
  song) is left unwarped, with a note. Otherwise the dance is time-warped so that its kinematic beats
  (speed minima) land on the song's beats: :func:`dancekit.motion.timewarp.beat_warp` (dynamic
  programming over candidate pairings, the local speed kept within ±15 %, a smooth rate; a checkpoint's
  ``"beat_sync"`` entry may set other bounds, :func:`beat_sync_options`).
* **clean-up** (:func:`clean_up`): the figure's root path is kept within a dance floor (turned back
  toward its start beyond 4 m, never farther than 12 m) and its lowest joint put on the floor
  (:mod:`dancekit.motion.cleanup`).
* **smoothing** (:func:`smooth`): a jittery dance gets a Savitzky-Golay filter whose window is chosen per
  dance (:mod:`dancekit.motion.footlock`); a smooth one is left alone. A dance whose genre was asked for by
  name is brought to that genre's own jitter-to-energy ratio when the model's checkpoint carries one
  (:func:`genre_smoothing_targets`: real cha-chas and tangos have 2-4x the high-frequency motion of waltzes).
* **foot lock** (:func:`foot_lock`): planted feet held where they were planted, the legs solved by two-bone
  IK, the body lowered where a held foot is out of reach, blended in and out (:mod:`dancekit.motion.footlock`).
* **energy** (:func:`lift_energy`): for a model whose checkpoint asks for it (an ``"energy"`` entry,
  :func:`energy_options`), a dance whose smoothed energy is under the entry's floor (m/s) has the slow
  band of its deviation from its moving-mean pose scaled up until it reaches it (:mod:`dancekit.motion.energy`:
  one gain per dance, at most ``max_gain``; the flicker band untouched), then put back on the floor.
* **settle** (:func:`settle`): for a model whose checkpoint asks for it, a light zero-phase windowed-sinc
  low-pass of the whole body after the lock (Dance Revolution: 3 Hz), softening the lock's stop and go.

:func:`finish` runs them (clean-up, smoothing, energy, foot lock, settle, then the warp) and records what happened in
``result.notes`` (the summary line).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dancekit.errors import CheckpointError, ParameterError
from dancekit.motion import Motion
from dancekit.motion.skeleton import keep_bone_lengths
from dancekit.pipelines.base import DanceResult

__all__ = ["BEAT_SYNC_KEYS", "ENERGY_KEYS", "FOOT_LOCK_KEYS", "NOISY_RATIO", "SMOOTHING_KEYS", "SMOOTH_FILTER", "SMOOTH_TARGET", "SMOOTH_TARGET_NOISY",
           "STAGE_NAMES",
           "beat_sync", "beat_sync_options", "clean_up", "energy_options", "finish", "foot_lock", "foot_lock_options", "genre_jitter_table", "genre_smoothing_targets", "jitter_cap_from_entry", "jitter_cap_setting", "lift_energy", "plausible_jitter_cap", "seed_trace", "settle", "settle_options", "smooth",
           "smoothing_options", "smoothing_target", "song_beats_for"]

#: The jitter-to-energy ratio (:func:`dancekit.motion.footlock.smoothing_window`) the smoothing stage brings a
#: jittery dance down to: about the 80th percentile of the real training dances' (0.055-0.28, median 0.065);
#: a dance beyond :data:`NOISY_RATIO` (more than nearly every real dance: frame-to-frame noise, the dual
#: model's 0.31-0.33) is brought to :data:`SMOOTH_TARGET_NOISY`, the real median. Chosen on the validation
#: songs (``benchmarks/bench_feet.py --grid``, docs/STAGES.md).
SMOOTH_TARGET = 0.09
SMOOTH_TARGET_NOISY = 0.065
NOISY_RATIO = 0.2
#: The stages of :func:`finish`, in the order it runs them (the names its ``trace`` is called with, after
#: ``"input"``): the per-dance jitter cap runs before the foot lock, or after the lock's settle with
#: ``jitter_after_lock``.
STAGE_NAMES = ("clean_up", "smooth", "lift_energy", "jitter_cap", "foot_lock", "settle", "reground", "beat_sync")
#: The cut-off (Hz) of the light low-pass after the foot lock (:func:`settle`); 0: none.
SETTLE_HZ = 0.0
#: The smoothing stage's filter (:func:`smooth`): ``"lowpass"`` or ``"savgol"``.
SMOOTH_FILTER = "savgol"


def _is_3d(motion: Motion) -> bool:
    p = motion.positions if motion.positions is not None else None
    return motion.num_frames >= 3 and (p is None or (p.ndim == 3 and p.shape[-1] == 3))


def song_beats_for(audio_path: str | os.PathLike, *, start: float | None = None, end: float | None = None):
    """The :class:`~dancekit.features.pulse.SongBeats` of the song (excerpt), times from the excerpt's start."""
    from dancekit.features.pulse import song_beats_file

    return song_beats_file(audio_path, start=start, end=end)


def beat_sync(result: DanceResult, audio_path: str | os.PathLike, *, start: float | None = None,
              end: float | None = None, beats=None) -> DanceResult:
    """The result with its motion time-warped onto the song's beats (a new :class:`DanceResult`; a note
    in ``notes`` says how many beats were matched, or why the dance was left unwarped).

    ``beats``: a :class:`~dancekit.features.pulse.SongBeats` already tracked (else the song is tracked).
    """
    from dancekit.motion.timewarp import beat_warp, warp_motion

    motion = result.motion
    if not _is_3d(motion):
        return _with_note(result, "not beat-synced (not a 3D dance)")
    if not result.looks_like_music:  # the pipeline found no beat strength (danced calmly): nothing to sync to
        return _with_note(result, "not beat-synced")
    beats = song_beats_for(audio_path, start=start, end=end) if beats is None else beats
    if not beats.has_beat:
        from dancekit.features.pulse import MIN_BEATS

        clarity = 0.0 if abs(beats.clarity) < 0.005 else beats.clarity
        why = (f"only {len(beats.times)} beats found" if len(beats.times) < MIN_BEATS
               else f"pulse clarity {clarity:.2f}")
        return _with_note(result, f"not beat-synced: the song has no clear beat ({why})")
    source, pairs = beat_warp(motion.to_positions(), music_beats=beats.times, fps=motion.fps,
                              **beat_sync_options(result.model))
    n_music = int(np.sum((beats.times > 0) & (beats.times < motion.duration)))
    if len(pairs) == 0:
        return _with_note(result, f"not beat-synced: no movement beat near the song's {n_music} beats")
    warped = warp_motion(motion, source_frames=source)
    note = f"beat-synced ({len(pairs)} of {n_music} beats at {beats.tempo:.0f} BPM)"
    return _with_note(dataclasses.replace(result, motion=warped), note)


def clean_up(result: DanceResult) -> DanceResult:
    """The result with its motion cleaned up (:mod:`dancekit.motion.cleanup`: the root path turned back
    within a dance floor, the lowest joint on the floor). Both are rigid per frame, so a motion with
    rotations keeps them (its root rotation turned, its root translation moved); 2D dances are returned
    unchanged."""
    from dancekit.motion.analysis import horizontal_axes, up_sign
    from dancekit.motion.cleanup import ground_offset, root_path_turns, turn_and_move

    motion = result.motion
    if not _is_3d(motion):
        return result
    sk, fps = motion.skeleton, motion.fps
    p = np.asarray(motion.to_positions(), np.float64)
    angle, root = root_path_turns(p, skeleton=sk, fps=fps)
    p = turn_and_move(p, skeleton=sk, angle=angle, root=root)
    p[..., sk.up_index] -= up_sign(sk) * ground_offset(p, skeleton=sk, fps=fps)[:, None]
    rot = tr = None
    if motion.rotations is not None:
        a, b = horizontal_axes(sk)
        turn = np.zeros((len(angle), 3, 3))
        turn[:, sk.up_index, sk.up_index] = 1.0
        turn[:, a, a] = turn[:, b, b] = np.cos(angle)
        turn[:, a, b] = -np.sin(angle)
        turn[:, b, a] = np.sin(angle)
        rot = np.array(motion.rotations, np.float64)
        rot[:, sk.root] = turn @ rot[:, sk.root]
        rot = rot.astype(motion.rotations.dtype)
        tr = p[:, sk.root].astype(np.float32)
    cleaned = Motion(skeleton=sk, fps=fps, positions=p.astype(np.float32), rotations=rot, root_translation=tr)
    return dataclasses.replace(result, motion=cleaned)


#: The windows :func:`reground` tries after the checkpoint's own when the dance still floats over its
#: ``max_float_cm`` (fractions of that window, longest first).
REGROUND_SHORTER = (0.6, 0.4, 0.25)


def reground(result: DanceResult, *, window_s: float, max_float_cm: float | None = None) -> DanceResult:
    """The result with its lowest joint put back on the floor (:func:`dancekit.motion.cleanup.ground_contact`
    over a centred ``window_s`` window, s): a vertical shift per frame, run after the foot lock and its settle
    when the model's checkpoint asks for it (:func:`ground_options`). The stages after the clean-up (the
    low-passes, the lock's IK) can lift a lively model's dance off the floor again; this one lets it touch
    the floor at least once in every window, while a rise shorter than ``window_s / 2`` stays.

    ``max_float_cm``: when the regrounded dance still floats higher than this (its lowest joint's median
    height over the local floor, :func:`dancekit.motion.footlock.floor_float_cm`, cm), shorter windows are
    tried in turn (``REGROUND_SHORTER`` × ``window_s``) and the first that brings it to the bound is kept (the
    shortest when none does). A dance under the bound keeps the checkpoint's window, so only the dances a
    strong low-pass lifted are touched. A motion with rotations keeps them (its root translation moved); 2D
    dances are returned unchanged."""
    from dancekit.motion.cleanup import ground_contact
    from dancekit.motion.floor import floor_float_cm

    motion = result.motion
    if not _is_3d(motion):
        return result
    sk, fps = motion.skeleton, motion.fps
    before = np.asarray(motion.to_positions(), np.float64)
    windows = [window_s] + ([window_s * f for f in REGROUND_SHORTER] if max_float_cm is not None else [])
    for w in windows:
        p = ground_contact(before, skeleton=sk, fps=fps, window_s=w)  # (T, J, 3), shifted along the up axis
        if max_float_cm is None or floor_float_cm(p, skeleton=sk, fps=fps) <= max_float_cm:
            break
    tr = None
    if motion.rotations is not None:  # the same shift on the root translation
        tr = (motion.root_translation + (p[:, sk.root] - before[:, sk.root])).astype(np.float32)
    out = Motion(skeleton=sk, fps=fps, positions=p.astype(np.float32), rotations=motion.rotations, root_translation=tr)
    return dataclasses.replace(result, motion=out)


def ground_options(model: str | os.PathLike | None) -> dict[str, float]:
    """The :func:`reground` settings a model's checkpoint folder carries in its ``config.json`` (``"ground":
    {"after_lock_s": s}``, the window in seconds, and optionally ``"max_float_cm": cm``, the float above
    which shorter windows are tried), chosen on the validation songs (docs/BENCHMARKS.md, "Livelier genre
    models", "Fifteenth session"); ``{}`` (no second grounding) for a folder without the entry or that is not
    a checkpoint. A window or bound that is not a positive finite number, or a bound without a window, is a
    :class:`~dancekit.errors.CheckpointError` naming the ``config.json``."""
    spec = _stage_entry(model, "ground", {"after_lock_s", "max_float_cm"})
    if ("max_float_cm" in spec and "after_lock_s" not in spec) or not all(
            np.isfinite(v) and v > 0 for v in spec.values()):
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'ground' takes a positive "
                              f"after_lock_s (s) and optionally a positive max_float_cm, got {spec!r}")
    if "after_lock_s" not in spec:
        return {}
    out = {"window_s": spec["after_lock_s"]}
    if "max_float_cm" in spec:
        out["max_float_cm"] = spec["max_float_cm"]
    return out


def smooth(result: DanceResult, *, target: float | None = None, kind: str | None = None) -> DanceResult:
    """The result with frame-to-frame noise filtered out; a dance already smooth enough is returned as it is.

    ``kind`` (default :data:`SMOOTH_FILTER`): ``"lowpass"``, a zero-phase windowed-sinc FIR low-pass whose
    cut-off is the highest of :data:`dancekit.motion.footlock.CUTOFFS_HZ` that brings the dance's
    jitter-to-energy ratio to ``target`` (:func:`dancekit.motion.footlock.lowpass_cutoff`); ``"savgol"``, a
    Savitzky-Golay filter whose window is the shortest that does
    (:func:`dancekit.motion.footlock.smoothing_window`). ``target`` default :func:`smoothing_target`:
    :data:`SMOOTH_TARGET`, or :data:`SMOOTH_TARGET_NOISY` for a dance beyond :data:`NOISY_RATIO`, or the
    requested genre's ratio of the model's checkpoint. A motion
    with rotations has its rotations filtered (re-orthonormalised) and its positions recomputed from them;
    a positions-only motion takes its bone directions from the filtered dance and keeps each frame's bone
    lengths; so bone lengths stay exact either way."""
    from dancekit.motion.filters import chunks, fir_lowpass, lowpass_kernel, lowpass_rows, savgol_rows
    from dancekit.motion.filters import savgol as _savgol
    from dancekit.motion.jitter import jitter_ratio as _jitter_ratio
    from dancekit.motion.jitter import lowpass_cutoff, smoothing_window

    motion = result.motion
    if not _is_3d(motion):
        return result
    kind = SMOOTH_FILTER if kind is None else kind
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # (T, J, 3); the helpers work in float64 piece by piece
    if target is None:
        target = smoothing_target(result)
    if target is None:
        target = SMOOTH_TARGET_NOISY if _jitter_ratio(p, sk, fps) > NOISY_RATIO else SMOOTH_TARGET
    if kind == "lowpass":
        cutoff = lowpass_cutoff(p, skeleton=sk, fps=fps, target=target)
        if cutoff <= 0:
            return result
        h = lowpass_kernel(cutoff, fps=fps)

        def rows(x, a, b):
            return lowpass_rows(x, h, a, b)

        def whole(x):
            return fir_lowpass(x, h)

        note = f"smoothed ({cutoff:g}-Hz low-pass)"
    elif kind == "savgol":
        window = smoothing_window(p, skeleton=sk, fps=fps, target=target)
        if window <= 1:
            return result

        def rows(x, a, b):
            return savgol_rows(x, window, 3, a, b)

        def whole(x):
            return _savgol(x, window, 3)

        note = f"smoothed ({window}-frame filter)"
    else:
        raise ParameterError(f"unknown smoothing filter {kind!r}: lowpass or savgol")
    if motion.rotations is None:
        out = np.empty(p.shape, np.float32)
        for a, b in chunks(len(p)):  # the filter is local: piece by piece, the same numbers as one pass
            out[a:b] = keep_bone_lengths(rows(p, a, b), p[a:b], sk)
        smoothed = Motion(skeleton=sk, fps=fps, positions=out)
    else:
        smoothed = _rotations_filtered(motion, whole)
    return _with_note(dataclasses.replace(result, motion=smoothed), note)


def _rotations_filtered(motion: Motion, whole) -> Motion:
    """``motion`` (with rotations) with ``whole`` (a zero-phase filter over axis 0 of a float64 array) applied
    to its rotation matrices (re-orthonormalised by SVD) and root translation, positions by forward
    kinematics: bone lengths exact."""
    import torch

    from dancekit.motion.kinematics import rig_forward_kinematics

    n = len(motion.rotations)
    rot = whole(np.asarray(motion.rotations, np.float64).reshape(n, -1, 9))
    u, _, vt = np.linalg.svd(rot.reshape(n, -1, 3, 3))
    u[..., :, -1] *= np.sign(np.linalg.det(u @ vt))[..., None]
    rot = u @ vt
    tr = whole(np.asarray(motion.root_translation, np.float64))
    pos = rig_forward_kinematics(torch.from_numpy(rot), torch.from_numpy(tr), motion.skeleton).numpy()
    return Motion(skeleton=motion.skeleton, fps=motion.fps, positions=pos.astype(np.float32),
                  rotations=rot.astype(motion.rotations.dtype), root_translation=tr.astype(np.float32))


def smoothing_target(result: DanceResult) -> float | None:
    """The jitter-to-energy ratio :func:`smooth` brings ``result`` to when the model's checkpoint has a target
    for the genre danced (:func:`genre_smoothing_targets`) and that genre was asked for by name
    (``result.genre_requested`` is a genre, not "auto" / "none"), or, with the entry's ``"drawn": true``,
    also when the genre was read from the music or drawn by the seed (``result.genre``: the genre model that
    danced it); None otherwise (the stage's own targets apply: the model alone, a genre without a target)."""
    targets, drawn = smoothing_options(result.model)
    genre = result.genre
    if genre is None or str(genre) not in targets:
        return None
    named = result.genre_requested not in (None, "auto", "none") and genre == result.genre_requested
    return targets[str(genre)] if named or (drawn and result.genre_requested in (None, "auto")) else None


def genre_smoothing_targets(model: str | os.PathLike | None) -> dict[str, float]:
    """Per genre, the jitter-to-energy ratio (:func:`dancekit.motion.footlock.smoothing_window`) that the
    smoothing stage brings a dance of that genre to: the checkpoint's ``"smoothing": {"genre_targets":
    {genre: ratio}}`` (the median of the real training dances of each genre,
    ``benchmarks/genre_tables.py smoothing``; docs/MUSIC2DANCE.md) times its ``"scale"`` (default 1).
    ``{}`` for a folder without the entry or that is not a checkpoint."""
    return smoothing_options(model)[0]


SMOOTHING_KEYS = ("genre_targets", "drawn", "scale")


def smoothing_options(model: str | os.PathLike | None) -> tuple[dict[str, float], bool]:
    """``(targets, drawn)`` from the checkpoint's ``"smoothing"`` entry: the per-genre targets of
    :func:`genre_smoothing_targets` (already scaled) and whether they also apply to a genre read from the
    music or drawn by the seed (``"drawn"``, default false: only a genre asked for by name). ``({}, False)``
    for a folder without the entry or that is not a checkpoint.

    Raises
    ------
    CheckpointError
        Naming the ``config.json``: an unknown key, a target outside (0, 10), a ``scale`` that is not a
        number in (0, 10], a ``drawn`` that is not true / false."""
    spec = _raw_entry(model, "smoothing")
    targets = spec.get("genre_targets", {}) if isinstance(spec, dict) else None
    scale = spec.get("scale", 1.0) if isinstance(spec, dict) else None
    drawn = spec.get("drawn", False) if isinstance(spec, dict) else None
    if not isinstance(spec, dict) or set(spec) - set(SMOOTHING_KEYS) or not isinstance(targets, dict) or not all(
            _is_number(v) and 0 < v < 10 for v in targets.values()) or not (_is_number(scale) and 0 < scale <= 10) \
            or not isinstance(drawn, bool):
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'smoothing' takes "
                              f"{{'genre_targets': {{genre: ratio in (0, 10)}}, 'scale': number in (0, 10], "
                              f"'drawn': true / false}}, got {spec!r}")
    return {str(g): float(v) * float(scale) for g, v in targets.items()}, drawn


def foot_lock(result: DanceResult) -> DanceResult:
    """The result with its planted feet pinned (:func:`dancekit.motion.footlock.lock_feet`: contacts from
    foot height and speed, the foot held where it was planted, the leg solved by two-bone IK, blended in
    and out), with the settings of the model's checkpoint (:func:`foot_lock_options` of ``result.model``).
    Where the checkpoint gives its genres' real planted-foot shares (:func:`plant_options`), the lock holds
    the feet no longer than that (:func:`plant_target`, :func:`~dancekit.motion.footlock.lock_feet_to_share`).
    Only the legs change; a motion with rotations has its leg rotations updated
    (:func:`~dancekit.motion.footlock.leg_rotations`). Skeletons without legs are returned unchanged."""
    from dancekit.motion.footlock import leg_chains, leg_rotations, lock_feet

    motion = result.motion
    if not _is_3d(motion) or not leg_chains(motion.skeleton):
        return result
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # lock_feet works on its own float64 copy
    options = foot_lock_options(result.model)
    target = plant_target(result, **plant_options(result.model))
    if target is None:
        locked = lock_feet(p, skeleton=sk, fps=fps, **options)
    else:  # no longer than the genre's real dancers plant their feet
        from dancekit.motion.footlock import lock_feet_to_share

        locked, _ = lock_feet_to_share(p, skeleton=sk, fps=fps, target=target, **options)
    rot = tr = None
    if motion.rotations is not None:
        rot = leg_rotations(motion.rotations, np.asarray(p, np.float64), locked,
                            skeleton=sk).astype(motion.rotations.dtype)
        tr = locked[:, sk.root].astype(np.float32)  # the body may have been lowered
    out = Motion(skeleton=sk, fps=fps, positions=locked.astype(np.float32), rotations=rot, root_translation=tr)
    return dataclasses.replace(result, motion=out)


def settle(result: DanceResult, *, cutoff: float | None = None, legs: bool = True,
           ratio_target: float | None = None, max_jitter: float | None = None) -> DanceResult:
    """The result with a light zero-phase low-pass (:func:`dancekit.motion.filters.lowpass_kernel` at
    ``cutoff`` Hz, default :data:`SETTLE_HZ`; ``0``: off) on every joint's position, run after the foot lock:
    the lock's stop-and-go (a foot handed over between holds, the knee solved frame by frame) is softened,
    while a held foot stays where it is (a constant passes a unit-gain low-pass unchanged: only the
    hold's first and last few frames are eased). Each frame's bone lengths are kept (bone directions from the
    filtered dance, parents first), piece by piece (:func:`dancekit.motion.footlock.chunks`); a motion with
    rotations has its rotations and root translation filtered instead (re-orthonormalised, whole-song, as
    :func:`smooth` does) and its positions recomputed from them, so a held foot moves a little there.
    ``ratio_target`` (and no ``cutoff``): the cut-off is chosen per dance, the highest of
    :data:`dancekit.motion.footlock.CUTOFFS_HZ` that brings the dance's jitter-to-energy ratio to the target
    (:func:`dancekit.motion.footlock.lowpass_cutoff`); a dance already at or under it is left alone.
    ``max_jitter`` (m/s; and no ``cutoff``): the cut-off is chosen per dance, the highest of
    :data:`dancekit.motion.footlock.CAP_CUTOFFS_HZ` that brings the dance's jitter under the cap
    (:func:`dancekit.motion.footlock.jitter_cutoff`; a genre model drawn by the seed, issue 15); a dance
    already under it is left alone, a filtered one gets a note. :func:`finish` runs this one *before* the foot
    lock (a cut-off down to 1 Hz after it would lift the planted feet)."""
    from dancekit.motion.filters import chunks, lowpass_kernel, lowpass_rows

    motion = result.motion
    note = None
    if ratio_target is not None and cutoff is None and _is_3d(motion):  # per dance: only a jittery one
        from dancekit.motion.jitter import lowpass_cutoff

        cutoff = lowpass_cutoff(motion.to_positions(), skeleton=motion.skeleton, fps=motion.fps,
                                target=float(ratio_target))
    if max_jitter is not None and cutoff is None and _is_3d(motion):  # per dance: only a jittery one
        from dancekit.motion.jitter import jitter_cutoff

        cutoff = jitter_cutoff(motion.to_positions(), skeleton=motion.skeleton, fps=motion.fps,
                               max_jitter=float(max_jitter))
        note = _calmed(cutoff)
    cutoff = SETTLE_HZ if cutoff is None else float(cutoff)
    if not cutoff or not _is_3d(motion):
        return result
    sk, fps = motion.skeleton, motion.fps
    h = lowpass_kernel(cutoff, fps=fps)
    p = motion.to_positions()
    if len(p) < len(h):
        return result
    from dancekit.motion.footlock import leg_chains

    keep = sorted({j for hip, knee, ankle, below in leg_chains(sk) for j in (hip, knee, ankle, *below)}) \
        if not legs else []
    if motion.rotations is not None:  # the rotations filtered as the smoothing stage does, positions by FK
        from dancekit.motion.filters import fir_lowpass

        out = dataclasses.replace(result, motion=_rotations_filtered(motion, lambda x: fir_lowpass(x, h)))
        return _with_note(out, note) if note else out
    out = np.empty(p.shape, np.float32)
    for a, b in chunks(len(p)):
        q = lowpass_rows(p, h, a, b)
        if keep:  # the legs as locked: only the rest of the body filtered
            q[:, keep] = np.asarray(p[a:b, keep], np.float64)
        out[a:b] = keep_bone_lengths(q, p[a:b], sk)
    out = dataclasses.replace(result, motion=Motion(skeleton=sk, fps=fps, positions=out))
    return _with_note(out, note) if note else out


def settle_options(model: str | os.PathLike | None) -> dict[str, float]:
    """The :func:`settle` settings a model's checkpoint folder carries in its ``config.json`` (``"settle":
    {"cutoff_hz": hz}`` or ``{"ratio_target": r}``, the cut-off chosen per dance), chosen on the validation
    songs (docs/STAGES.md): the embedded Dance Revolution's dances take a 3-Hz low-pass after the lock; the
    embedded music2dance's geometric FID rises with any fixed one (+3-28 % on validation). ``{}`` (no
    low-pass, :data:`SETTLE_HZ`) for a folder without the entry or that is not a checkpoint. A negative or
    non-finite cut-off, a non-positive ratio or both keys is a :class:`~dancekit.errors.CheckpointError`
    naming the ``config.json``."""
    spec = _stage_entry(model, "settle", {"cutoff_hz", "ratio_target"})
    bad = [k for k, v in spec.items() if not (np.isfinite(v) and (v > 0 or (k == "cutoff_hz" and v == 0)))]
    bad += ["both cutoff_hz and ratio_target"] if len(spec) > 1 else []
    if bad:
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'settle' takes a cutoff_hz "
                              f"(Hz, 0: none) or a positive ratio_target, not both; got {bad[0]} in {spec!r}")
    out = {"cutoff": spec["cutoff_hz"]} if "cutoff_hz" in spec else {}
    return {**out, "ratio_target": spec["ratio_target"]} if "ratio_target" in spec else out


#: The keys a checkpoint's ``"foot_lock"`` entry may carry (:func:`foot_lock_options`): the shortest hold (s),
#: how far the original ankle may move from a held foot before it is re-planted (``max_drift_m``, m), the
#: hand-over to and from a hold (``blend_s``, s) and the contact thresholds of
#: :func:`dancekit.motion.footlock.foot_contacts` (metres above the local floor, m/s; a contact starts below
#: ``*_on`` and lasts while the foot stays below ``*_off``).
FOOT_LOCK_KEYS = ("min_hold_s", "max_drift_m", "blend_s", "height_on", "height_off", "speed_on", "speed_off")


def foot_lock_options(model: str | os.PathLike | None) -> dict[str, float]:
    """The :func:`~dancekit.motion.footlock.lock_feet` settings a model's checkpoint folder carries in its
    ``config.json`` (``"foot_lock": {"min_hold_s": s, "max_drift_m": m, "blend_s": s, "height_on": m,
    "height_off": m, "speed_on": m/s, "speed_off": m/s}``, any of them, :data:`FOOT_LOCK_KEYS`), chosen on
    the validation songs (docs/STAGES.md): the embedded Dance Revolution's dances have many short stops near
    the floor, and holding them for 0.12-0.4 s makes the foot stop and go (jitter); the embedded dual
    model's feet glide near the floor faster than the default 0.5 m/s contact speed, so it takes faster and
    higher contacts, longer holds (re-planted after 0.6 m, at least 0.32 s) and a longer hand-over; the embedded
    music2dance's geometric FID rises without its short holds, so it keeps the defaults. ``{}`` (the
    defaults) for a folder without the entry or that is not a checkpoint. A value that is not a positive
    number, or an ``*_on`` threshold above its ``*_off`` (either side taken from the defaults when absent),
    is a :class:`~dancekit.errors.CheckpointError` naming the ``config.json``."""
    from dancekit.motion import footlock as fl

    spec = _stage_entry(model, "foot_lock", set(FOOT_LOCK_KEYS))
    default = {"height_on": fl.CONTACT_HEIGHT_ON_M, "height_off": fl.CONTACT_HEIGHT_OFF_M,
               "speed_on": fl.CONTACT_SPEED_ON, "speed_off": fl.CONTACT_SPEED_OFF}
    full = {**default, **spec}
    bad = [k for k, v in spec.items() if not (np.isfinite(v) and v > 0)]
    bad += [f"{q}_on > {q}_off" for q in ("height", "speed") if full[f"{q}_on"] > full[f"{q}_off"]]
    if bad:
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'foot_lock' needs positive "
                              f"numbers with *_on <= *_off, got {bad[0]} in {spec!r}")
    return spec


def plant_options(model: str | os.PathLike | None) -> dict:
    """The planted-share target a model's checkpoint folder carries in its ``config.json`` (``"plant":
    {"genre_share": {genre: share}}``: each genre's real planted-foot share, the mean over its training
    dances of :func:`dancekit.motion.footlock.planted_share`), chosen per model on the validation songs
    (docs/BENCHMARKS.md, issue 15). ``{}`` (the lock as set) for a folder without the entry or that is not a
    checkpoint. An entry that is not ``{"genre_share": {genre: share in (0, 1]}}`` is a
    :class:`~dancekit.errors.CheckpointError` naming the ``config.json``."""
    spec = _raw_entry(model, "plant")
    if not spec:
        return {}
    table = spec.get("genre_share") if isinstance(spec, dict) else None
    if set(spec) != {"genre_share"} or not isinstance(table, dict) or not table or not all(
            _is_number(v) and 0 < v <= 1 for v in table.values()):
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'plant' takes "
                              f"{{\"genre_share\": {{genre: share in (0, 1]}}}}, got {spec!r}")
    return {"genre_share": {str(g): float(v) for g, v in table.items()}}


def plant_target(result: DanceResult, *, genre_share: dict[str, float] | None = None) -> float | None:
    """The planted-foot share :func:`foot_lock` keeps ``result`` under: the real share of the genre danced
    (``result.genre``), or, for a dance of the model alone, the shares weighted by the genre probabilities
    read from the music (``result.genre_probs``, over the genres of the table, renormalised); None (the lock
    as set) without a table or when neither applies."""
    if not genre_share:
        return None
    if result.genre in genre_share:
        return float(genre_share[result.genre])
    return posterior_mean(result, genre_share)


def posterior_mean(result: DanceResult, table: dict[str, float]) -> float | None:
    """The mean of a per-genre ``table`` weighted by the genre probabilities read from the music
    (``result.genre_probs``, over the genres of the table, renormalised); None when none of them was read."""
    probs = {g: p for g, p in (result.genre_probs or {}).items() if g in table and p > 0}
    if not probs:
        return None
    return float(sum(p * table[g] for g, p in probs.items()) / sum(probs.values()))


#: The keys a checkpoint's ``"beat_sync"`` entry may carry (:func:`beat_sync_options`), all
#: :func:`dancekit.motion.timewarp.beat_warp` arguments: the bound on the warp's local speed change
#: (``max_rate_change``, a fraction: the rate stays within ``1 ± it``), the bound between two matched beats
#: (``pair_rate_change``, ≤ ``max_rate_change``), the farthest a kinematic beat is moved (``max_shift``, s), the
#: landing tolerance of unpaired kinematic beats in the pairing (``between_tolerance``, s; 0: off), the time
#: scale of the rate's smoothness (``smooth_s``, s), the bound on the rate's change from one frame to the
#: next (``max_rate_step``, a fraction per frame; default 0.02: no visible speed jump) and whether the pairing
#: already skips steps that bound cannot follow (``step_pairing``, true / false; default true).
BEAT_SYNC_KEYS = ("max_rate_change", "pair_rate_change", "max_shift", "between_tolerance", "smooth_s",
                  "max_rate_step", "step_pairing")


def beat_sync_options(model: str | os.PathLike | None) -> dict[str, float | bool]:
    """The :func:`~dancekit.motion.timewarp.beat_warp` settings a model's checkpoint folder carries in its
    ``config.json`` (``"beat_sync": {"max_rate_change": f, "pair_rate_change": f, "max_shift": s,
    "between_tolerance": s, "smooth_s": s, "max_rate_step": f, "step_pairing": true/false}``, any of them,
    :data:`BEAT_SYNC_KEYS`). The embedded dual and music2dance carry one (±30 % and ±40 %, docs/STAGES.md);
    ``{}``, the defaults (speed change ±15 %, ±13 % between matched beats, 0.6 s, a rate step of at most 2 %
    per frame, the pairing aware of it), for a folder without the entry or that is not a checkpoint. A rate
    outside (0, 1), a ``pair_rate_change`` above the ``max_rate_change`` (either side from the defaults when
    absent), a ``max_shift``, ``smooth_s`` or ``max_rate_step`` that is not positive, a negative
    ``between_tolerance`` or a ``step_pairing`` that is not true / false is a
    :class:`~dancekit.errors.CheckpointError` naming the ``config.json``."""
    from dancekit.motion import timewarp as tw

    spec = _stage_entry(model, "beat_sync", set(BEAT_SYNC_KEYS) - {"step_pairing"}, flags={"step_pairing"})
    full = {"max_rate_change": tw.DEFAULT_MAX_RATE_CHANGE, "pair_rate_change": tw.DEFAULT_PAIR_RATE_CHANGE, **spec}
    bad = [k for k in ("max_rate_change", "pair_rate_change") if k in spec and not 0 < spec[k] < 1]
    bad += [k for k in ("max_shift", "smooth_s", "max_rate_step") if k in spec
            and not (np.isfinite(spec[k]) and spec[k] > 0)]
    bad += [k for k in ("between_tolerance",) if k in spec and not (np.isfinite(spec[k]) and spec[k] >= 0)]
    if full["pair_rate_change"] > full["max_rate_change"]:
        bad.append("pair_rate_change > max_rate_change")
    if bad:
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'beat_sync' needs rates in "
                              f"(0, 1) with pair_rate_change <= max_rate_change, positive max_shift, smooth_s and "
                              f"max_rate_step and between_tolerance >= 0, got {bad[0]} in {spec!r}")
    return spec


#: The keys a checkpoint's ``"energy"`` entry may carry (:func:`energy_options`): a fixed smoothed-energy
#: ``floor`` (m/s), or a ``fraction`` of the real dances' smoothed energy per genre (``genre_energy``: {genre:
#: m/s}, the genre read from the music; the fixed floor, when given too, applies where no genre is known), the
#: largest gain ``max_gain`` (>= 1), the moving mean the deviation is taken from (``mean_s``, s) and the cut-off
#: of the deviation's band that the gain scales (``band_hz``, Hz, below the motion's Nyquist frequency).
#: :mod:`dancekit.motion.energy`.
ENERGY_KEYS = ("floor", "fraction", "genre_energy", "max_gain", "mean_s", "band_hz", "damp", "root", "legs")


def energy_options(model: str | os.PathLike | None) -> dict:
    """The :func:`lift_energy` settings a model's checkpoint folder carries in its ``config.json`` (``"energy":
    {"floor": m/s}`` or ``{"fraction": f, "genre_energy": {genre: m/s}}`` (or both), plus any of ``"max_gain":
    g, "mean_s": s, "band_hz": hz``, defaults :mod:`dancekit.motion.energy`'s), chosen per model on the
    validation songs (docs/STAGES.md). ``{}`` (no lift) for a folder without the entry or that is not a
    checkpoint. An unknown key, a non-number, a non-positive ``floor``, ``fraction``, ``mean_s``, ``band_hz`` or
    genre energy, a ``max_gain`` under 1, or neither a floor nor a fraction with genre energies is a
    :class:`~dancekit.errors.CheckpointError` naming the ``config.json``."""
    spec = _raw_entry(model, "energy")
    if not spec:
        return {}

    table = spec.get("genre_energy", {}) if isinstance(spec, dict) else None
    bad = [] if isinstance(spec, dict) else ["not a mapping"]
    if not bad:
        bad += [f"unknown key {k!r}" for k in sorted(set(spec) - set(ENERGY_KEYS))]
        bad += [f"{k} not a positive number" for k in ("floor", "fraction", "mean_s", "band_hz")
                if k in spec and not (_is_number(spec[k]) and spec[k] > 0)]
        bad += ["damp outside [0, 1]"] if "damp" in spec and not (_is_number(spec["damp"]) and 0 <= spec["damp"] <= 1) \
            else []
        bad += [f"{k} not 0 or 1" for k in ("root", "legs") if k in spec and spec[k] not in (0, 1)]
        bad += ["max_gain < 1"] if "max_gain" in spec and not (_is_number(spec["max_gain"]) and spec["max_gain"] >= 1) \
            else []
        bad += [] if isinstance(table, dict) and all(_is_number(v) and v > 0 for v in table.values()) \
            else ["genre_energy not {genre: positive m/s}"]
        bad += [] if "floor" in spec or ("fraction" in spec and table) else ["neither a floor nor a fraction with "
                                                                               "genre_energy"]
    if bad:
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'energy' takes a positive "
                              f"floor (m/s) or fraction with genre_energy {{genre: m/s}}, max_gain >= 1 and positive "
                              f"mean_s and band_hz; {bad[0]} in {spec!r}")
    out = {k: float(v) for k, v in spec.items() if k != "genre_energy"}
    if table:
        out["genre_energy"] = {str(g): float(v) for g, v in table.items()}
    return out


def energy_floor(result: DanceResult, *, floor: float | None = None, fraction: float | None = None,
                 genre_energy: dict[str, float] | None = None) -> float | None:
    """The smoothed-energy floor (m/s) :func:`lift_energy` lifts ``result`` to: ``fraction`` × the genre's real
    energy (``genre_energy``) weighted by the genre probabilities read from the music (``result.genre_probs``,
    over the genres of the table, renormalised), or of the genre danced (``result.genre``) when none were read;
    else ``floor``; None (no lift) when neither applies."""
    if fraction is not None and genre_energy:
        mean = posterior_mean(result, genre_energy)
        if mean is not None:
            return float(fraction * mean)
        if result.genre in genre_energy:
            return float(fraction * genre_energy[result.genre])
    return None if floor is None else float(floor)


def lift_energy(result: DanceResult, *, floor: float | None = None, fraction: float | None = None,
                genre_energy: dict[str, float] | None = None, max_gain: float | None = None,
                mean_s: float | None = None, band_hz: float | None = None, damp: float | None = None,
                root: float | None = None, legs: float | None = None) -> DanceResult:
    """The result with its motion lifted towards the floor of :func:`energy_floor` (``floor`` m/s, or
    ``fraction`` of the real energy of the genres read from the music) of smoothed energy
    (:mod:`dancekit.motion.energy`: the ``band_hz`` low band of each joint's deviation from its ``mean_s``
    moving mean scaled by one gain per dance in ``[1, max_gain]``, the band above it by ``gain ** -damp``; the
    root translation kept, bone lengths exact; ``root`` 0: the root's orientation not lifted (rotation
    motions); ``legs`` 0: the legs not lifted), then the change the lift made to the clean-up's ground offset
    (:func:`~dancekit.motion.cleanup.ground_offset`) taken off, so the lowest joint stays on the floor. No
    floor (no ``"energy"`` entry in the checkpoint, :func:`energy_options`, or no genre known for a
    genre-only entry), a 2D dance, a dance already at the floor or one calmed because its input does not look
    like music (``result.looks_like_music`` False): the result itself, unchanged. A motion with
    rotations has its local rotations lifted and its positions recomputed by forward kinematics. A note gives
    the gain and the floor. A ``band_hz`` at or above half the frame rate is a
    :class:`~dancekit.errors.CheckpointError` naming the model's ``config.json``."""
    from dancekit.motion import energy as en
    from dancekit.motion.analysis import up_sign
    from dancekit.motion.cleanup import ground_offset

    motion = result.motion
    floor = energy_floor(result, floor=floor, fraction=fraction, genre_energy=genre_energy)
    if floor is None or not _is_3d(motion) or not result.looks_like_music:  # a calmed non-music dance stays calm
        return result
    sk, fps = motion.skeleton, motion.fps
    opts = {"max_gain": en.DEFAULT_MAX_GAIN if max_gain is None else float(max_gain),
            "mean_s": en.DEFAULT_MEAN_S if mean_s is None else float(mean_s),
            "band_hz": en.DEFAULT_BAND_HZ if band_hz is None else float(band_hz),
            "damp": 0.0 if damp is None else float(damp)}
    if not opts["band_hz"] < fps / 2:
        raise CheckpointError(f"corrupt checkpoint file {Path(result.model) / 'config.json'}: 'energy' band_hz "
                              f"must be below {fps / 2:g} Hz (half the {fps:g}-fps frame rate), got {opts['band_hz']}")
    rot = tr = None
    if motion.rotations is None:
        p, gain = en.lift_positions(motion.to_positions(), skeleton=sk, fps=fps, floor=float(floor),
                                    legs=legs is None or bool(legs), **opts)
    else:
        import torch

        from dancekit.motion.kinematics import rig_forward_kinematics

        tr = np.asarray(motion.root_translation, np.float64)

        def fk(r: np.ndarray) -> np.ndarray:
            return rig_forward_kinematics(torch.from_numpy(r), torch.from_numpy(tr), sk).numpy()

        rot, gain = en.lift_rotations(motion.rotations, fk=fk, skeleton=sk, fps=fps, floor=float(floor),
                                      root=root is None or bool(root), legs=legs is None or bool(legs), **opts)
        p = fk(rot) if gain > 1.0 else None
    if gain <= 1.0:
        return result
    # the lowest joint kept where it was relative to the floor: only the change the lift made to the
    # clean-up's ground offset is taken off (a dance whose feet the lift did not move stays at its height)
    offset = up_sign(sk) * (ground_offset(p, skeleton=sk, fps=fps)
                            - ground_offset(motion.to_positions(), skeleton=sk, fps=fps))
    p[..., sk.up_index] -= offset[:, None]
    if rot is not None:
        tr = tr.copy()
        tr[:, sk.up_index] -= offset
        rot, tr = rot.astype(motion.rotations.dtype), tr.astype(np.float32)
    lifted = Motion(skeleton=sk, fps=fps, positions=np.asarray(p, np.float32), rotations=rot, root_translation=tr)
    return _with_note(dataclasses.replace(result, motion=lifted), f"energy lifted (gain {gain:.2f} to {floor:.2f} m/s)")


def _is_number(v) -> bool:
    """A finite int or float, not a bool (a checkpoint entry's number)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def genre_jitter_table(table) -> dict[str, float]:
    """A per-genre jitter table (genre name -> real dances' median jitter, m/s; ``benchmarks/genre_tables.py
    jitter``) checked, as floats: the check of the genre draw's ``"genre_jitter"`` and of a ``"jitter_cap"``
    entry's. A table that is not a non-empty mapping of names to finite numbers > 0 (not booleans) is a
    :class:`~dancekit.errors.ParameterError` naming ``genre_jitter``."""
    items = table.items() if isinstance(table, dict) else table
    try:
        pairs = [(g, v) for g, v in items]
    except (TypeError, ValueError):
        pairs = None
    if not (pairs and all(isinstance(g, str) and _is_number(v) and v > 0 for g, v in pairs)):
        shown = table if pairs is None else dict(pairs)
        raise ParameterError(f"genre_jitter must map genres to positive m/s, got {shown!r}")
    return {g: float(v) for g, v in pairs}


def _raw_entry(model: str | os.PathLike | None, key: str):
    """The checkpoint folder's ``config.json`` entry ``key`` as stored (unchecked); ``{}`` for no model, a
    folder without the entry, or one that is not a checkpoint."""
    from dancekit.checkpoints.hub import read_meta

    if not model:
        return {}
    try:
        return read_meta(model).get(key) or {}
    except (CheckpointError, OSError):
        return {}


def _stage_entry(model: str | os.PathLike | None, key: str, allowed: set[str],
                 flags: set[str] = frozenset()) -> dict[str, float | bool]:
    """The checkpoint folder's ``config.json`` entry ``key`` (a dict of numbers whose keys are in
    ``allowed``, and of true / false for the keys in ``flags``); ``{}`` for no model, a folder without the
    entry, or one that is not a checkpoint. A malformed entry is a :class:`~dancekit.errors.CheckpointError`
    naming the file."""
    spec = _raw_entry(model, key)
    if not isinstance(spec, dict) or not set(spec) <= allowed | flags or not all(
            isinstance(v, bool) if k in flags else isinstance(v, (int, float)) and not isinstance(v, bool)
            for k, v in spec.items()):
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: '{key}' takes "
                              f"numbers for {sorted(allowed)}"
                              + (f" and true / false for {sorted(flags)}" if flags else "") + f", got {spec!r}")
    return {k: v if k in flags else float(v) for k, v in spec.items()}


JITTER_CAP_KEYS = ("genre_jitter", "jitter_cap", "jitter_cap_min_ratio", "after_lock", "to_end")


def plausible_jitter_cap(probs: dict[str, float], *, genre_jitter: dict[str, float], scale: float,
                         min_ratio: float) -> float | None:
    """The per-dance jitter cap (m/s, the ``max_jitter`` of :func:`finish`) for a song whose genre posterior is
    ``probs`` (genre → p): ``scale`` × the smallest real jitter ``genre_jitter[g]`` (m/s, the real training
    dances' median per genre, ``benchmarks/genre_tables.py jitter``) among the song's plausible genres
    (``p_g ≥ min_ratio · max(p)``, genres in the table). None (no cap) without a posterior, a scale or a
    plausible genre in the table. A genre asked for by name is ``probs = {genre: 1.0}``."""
    if not probs or not scale > 0 or not genre_jitter:
        return None
    top = max(probs.values())
    plausible = [genre_jitter[g] for g, p in probs.items() if g in genre_jitter and p >= min_ratio * top]
    return float(scale * min(plausible)) if plausible else None


def jitter_cap_from_entry(spec, *, folder: str | os.PathLike = "?", key: str = "jitter_cap") -> dict | None:
    """A checkpoint's jitter cap entry ``{"genre_jitter": {genre: m/s}, "jitter_cap": s,
    "jitter_cap_min_ratio": ρ, "after_lock": bool, "to_end": bool}`` (ρ default 0.5, the two flags default
    false) checked: ``{"genre_jitter", "scale", "min_ratio"}`` (the keyword arguments of
    :func:`plausible_jitter_cap`) plus ``"after_lock"`` (the ``jitter_after_lock`` of :func:`finish`: the cap's
    low-pass after the foot lock and its settle instead of before the lock) and ``"to_end"`` (its
    ``jitter_to_end``: the cap holds for the finished dance); None for no entry.

    Raises
    ------
    CheckpointError
        Naming ``config.json`` and ``key``, for an entry that is not an object, an unknown key, a table that
        does not map genres to positive m/s, a scale that is not a finite number > 0, ρ outside [0, 1], or an
        ``after_lock`` or ``to_end`` that is not true / false."""
    if spec is None:
        return None
    where = f"checkpoint {folder}: bad {key!r} entry in config.json"

    if not isinstance(spec, dict) or set(spec) - set(JITTER_CAP_KEYS):
        raise CheckpointError(f"{where}: takes {list(JITTER_CAP_KEYS)}, got {spec!r}")
    table = spec.get("genre_jitter")
    try:  # a mapping (JSON object), not a list of pairs
        table = genre_jitter_table(table if isinstance(table, dict) else None)
    except ParameterError:
        raise CheckpointError(f"{where}: genre_jitter must map genres to positive m/s, got {spec['genre_jitter']!r}"
                              if "genre_jitter" in spec else f"{where}: genre_jitter is missing") from None
    scale = spec.get("jitter_cap")
    if not (_is_number(scale) and scale > 0):
        raise CheckpointError(f"{where}: jitter_cap must be a finite number > 0, got {scale!r}")
    ratio = spec.get("jitter_cap_min_ratio", 0.5)
    if not (_is_number(ratio) and 0 <= ratio <= 1):
        raise CheckpointError(f"{where}: jitter_cap_min_ratio must be in [0, 1], got {ratio!r}")
    flags = {k: spec.get(k, False) for k in ("after_lock", "to_end")}
    for k, v in flags.items():
        if not isinstance(v, bool):
            raise CheckpointError(f"{where}: {k} must be true or false, got {v!r}")
    return {"genre_jitter": table, "scale": float(scale), "min_ratio": float(ratio), **flags}


def jitter_cap_setting(spec, *, folder: str | os.PathLike = "?") -> tuple[dict | None, bool, bool]:
    """A checkpoint's ``"jitter_cap"`` entry as a pipeline keeps it: ``(cap, after_lock, to_end)``, ``cap`` the
    keyword arguments of :func:`plausible_jitter_cap` (None: no entry, then both flags false) and the two flags
    the ``jitter_after_lock`` / ``jitter_to_end`` of :func:`finish`; checked by :func:`jitter_cap_from_entry`."""
    cap = jitter_cap_from_entry(spec, folder=folder)
    if cap is None:
        return None, False, False
    return cap, bool(cap.pop("after_lock")), bool(cap.pop("to_end"))


def finish(result: DanceResult, audio_path: str | os.PathLike, *, start: float | None = None,
           end: float | None = None, beat_sync_on: bool = True, cleanup_on: bool = True,
           foot_lock_on: bool | None = None, smooth_on: bool | None = None, energy_on: bool | None = None,
           beats=None, max_jitter: float | None = None, jitter_after_lock: bool = False,
           jitter_to_end: bool = False, trace: Callable[[str, DanceResult], None] | None = None) -> DanceResult:
    """The stages as switched, in this order: the clean-up (it moves frames rigidly), the smoothing (only
    a jittery dance is filtered), the energy lift the model's checkpoint asks for (:func:`lift_energy`,
    :func:`energy_options`: only a dance under its floor; after the smoothing, so the flicker it removed is
    not measured as energy), the foot lock (after the smoothing and the lift, so a pinned foot stays pinned)
    and, with it, the light low-pass after the lock that the model's checkpoint asks for (:func:`settle`,
    :func:`settle_options`: a held foot stays held), then the beat sync (so the speed minima it aligns are
    those of the final dance). ``foot_lock_on``, ``smooth_on`` and ``energy_on`` follow ``cleanup_on`` unless
    given. ``beats``: the song's :class:`~dancekit.features.pulse.SongBeats` when already tracked (many
    dances of one song), else tracked here when needed. ``max_jitter`` (m/s): before the foot lock, a
    per-dance low-pass caps the dance's jitter (:func:`settle`; a genre model the seed drew, issue 15), so the
    lock plants the calmed dance's feet (after the lock, a 1-Hz cap lifted the feet off the floor);
    ``jitter_after_lock``: that low-pass runs after the foot lock and its settle instead (the jitter measured
    closer to its final value: the lock adds some back; a checkpoint's ``"after_lock"``,
    :func:`jitter_cap_from_entry`). ``jitter_to_end``: the cap holds for the finished dance, not only where
    the low-pass runs: when the stages after it (the lock's stop-and-go, the regrounding, the warp's speed
    changes) bring the jitter back over ``max_jitter``, they are run again from the cap on with its next lower
    cut-off (:data:`dancekit.motion.footlock.CAP_CUTOFFS_HZ`; from the highest for a dance the cap had left
    alone), down to the lowest (a checkpoint's ``"to_end"``, :func:`jitter_cap_from_entry`, or revolution's
    ``"jitter_cap_to_end"``). Last in the lock's block, the second grounding the checkpoint asks for
    (:func:`reground`, :func:`ground_options`). ``trace``: called as ``trace("input", result)`` with the dance
    as given, then as ``trace(name, result)`` after each stage that ran, with the names of :data:`STAGE_NAMES`
    in that order (a stage-by-stage look at one dance, e.g. ``benchmarks/stage_ablation.py``, or the dance
    before its warp, as ``dancekit evaluate`` keeps it; the ``"jitter_cap"`` and ``"reground"`` stages only
    where they apply; with ``jitter_to_end``, the stages after the cap as last run)."""
    steps: list[tuple[str, DanceResult]] = [("input", result)]  # kept only for a trace (memory: long songs)

    def done(name: str, out: DanceResult) -> DanceResult:
        if trace is not None:
            steps.append((name, out))
        return out

    locking = cleanup_on if foot_lock_on is None else foot_lock_on
    chosen: list[float] = []  # the cut-off the cap chose (Hz, 0: none), for jitter_to_end

    def cap(r: DanceResult, cutoff: float | None) -> DanceResult:
        if cutoff is None and jitter_to_end and _is_3d(r.motion):  # chosen here (as settle would), and kept
            from dancekit.motion.jitter import jitter_cutoff

            m = r.motion
            chosen.append(jitter_cutoff(m.to_positions(), skeleton=m.skeleton, fps=m.fps, max_jitter=float(max_jitter)))
            cutoff = chosen[0]
            if not cutoff:  # under the cap already
                return r
        if cutoff is None:  # the highest cut-off that brings the dance under the cap (0: none needed)
            return settle(r, max_jitter=max_jitter)
        return _with_note(settle(r, cutoff=cutoff), _calmed(cutoff))

    def from_the_lock(r: DanceResult, cutoff: float | None) -> DanceResult:
        """The lock's block and the beat sync, the cap's low-pass at ``cutoff`` Hz (None: as it chooses)."""
        if locking:
            if max_jitter is not None and not jitter_after_lock:  # before the lock: it plants the calmed feet
                r = done("jitter_cap", cap(r, cutoff))
            r = done("foot_lock", foot_lock(r))
            r = done("settle", settle(r, **settle_options(r.model)))
            if max_jitter is not None and jitter_after_lock:  # after: the jitter the lock added back is measured
                r = done("jitter_cap", cap(r, cutoff))
            ground = ground_options(r.model)
            if ground:  # a lively model's dance, lifted again by the low-passes and the lock's IK
                r = done("reground", reground(r, **ground))
        if beat_sync_on:
            r = done("beat_sync", beat_sync(r, audio_path, start=start, end=end, beats=beats))
        return r

    if cleanup_on:
        result = done("clean_up", clean_up(result))
    if cleanup_on if smooth_on is None else smooth_on:
        result = done("smooth", smooth(result))
    if cleanup_on if energy_on is None else energy_on:
        result = done("lift_energy", lift_energy(result, **energy_options(result.model)))
    head = len(steps)
    out = from_the_lock(result, None)
    if jitter_to_end and max_jitter is not None and locking and _is_3d(out.motion):
        from dancekit.motion.jitter import CAP_CUTOFFS_HZ, jitter_speed

        first = chosen[0] if chosen else 0.0
        for c in (c for c in CAP_CUTOFFS_HZ if not first or c < first):
            m = out.motion
            if jitter_speed(m.to_positions(), skeleton=m.skeleton, fps=m.fps) <= max_jitter:
                break
            del steps[head:]
            out = from_the_lock(result, c)
    if trace is not None:
        for name, r in steps:
            trace(name, r)
    return out


def seed_trace(stage_trace: Callable[[int, str, DanceResult], None] | None,
               k: int) -> Callable[[str, DanceResult], None] | None:
    """The :func:`finish` ``trace`` of the ``k``-th dance of a pipeline's ``dances``, from its ``stage_trace``
    (called as ``stage_trace(k, name, result)``); None for none."""
    if stage_trace is None:
        return None
    return lambda name, result: stage_trace(k, name, result)


def _calmed(cutoff: float) -> str:
    """The note of the jitter cap's low-pass at ``cutoff`` Hz."""
    return f"calmed to the song's genres ({cutoff:g}-Hz low-pass)"


def _with_note(result: DanceResult, note: str) -> DanceResult:
    return dataclasses.replace(result, notes=[*result.notes, note])
