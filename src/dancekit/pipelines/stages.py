"""Pipeline stages every dance model shares: beat-synchronous output and the physical clean-up.

Both run on the :class:`~dancekit.pipelines.DanceResult` of any dance pipeline (the model's motion on its
own skeleton, 3D positions), on by default (``pipe(song, beat_sync=False, cleanup=False)`` gives the
model's own output):

* **beat sync** (:func:`beat_sync`): the song (excerpt) is beat-tracked on the fine grid
  (:func:`dancekit.features.pulse.song_beats`); a song without a clear pulse (speech, a bird, a whale's
  song) is left unwarped, with a note. Otherwise the dance is time-warped so that its kinematic beats
  (speed minima) land on the song's beats: :func:`dancekit.motion.timewarp.beat_warp` (dynamic
  programming over candidate pairings, the local speed kept within ±15 %, a smooth rate; a checkpoint's
  ``"stages": {"beat_sync": ...}`` entry may set other bounds, :class:`~dancekit.pipelines.config.BeatSyncConfig`).
* **clean-up** (:func:`clean_up`): the figure's root path is kept within a dance floor (turned back
  toward its start beyond 4 m, never farther than 12 m) and its lowest joint put on the floor
  (:mod:`dancekit.motion.cleanup`).
* **smoothing** (:func:`smooth`): a jittery dance gets a Savitzky-Golay filter whose window is chosen per
  dance (:mod:`dancekit.motion.footlock`); a smooth one is left alone. A dance whose genre was asked for by
  name is brought to that genre's own jitter-to-energy ratio when the model's checkpoint carries one
  (:func:`smoothing_target`: real cha-chas and tangos have 2-4x the high-frequency motion of waltzes).
* **foot lock** (:func:`foot_lock`): planted feet held where they were planted, the legs solved by two-bone
  IK, the body lowered where a held foot is out of reach, blended in and out (:mod:`dancekit.motion.footlock`).
* **energy** (:func:`lift_energy`): for a model whose checkpoint asks for it (an ``"energy"`` entry,
  :class:`~dancekit.pipelines.config.EnergyConfig`), a dance whose smoothed energy is under the entry's floor (m/s) has the slow
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
from dancekit.pipelines.config import (  # noqa: F401 (the defaults, re-exported)
    NOISY_RATIO,
    SMOOTH_FILTER,
    SMOOTH_TARGET,
    SMOOTH_TARGET_NOISY,
    STAGE_NAMES,
    EditConfig,
    FootLockConfig,
    GenreStats,
    JitterCapConfig,
    SmoothConfig,
    StageConfig,
)

__all__ = ["NOISY_RATIO", "SMOOTH_FILTER", "SMOOTH_TARGET", "SMOOTH_TARGET_NOISY", "STAGES", "STAGE_NAMES", "Song",
           "StageContext", "beat_sync", "clean_up", "finish", "foot_lock", "genre_jitter_cap", "genre_jitter_table",
           "jitter_cap_for", "lift_energy", "plausible_jitter_cap", "reground", "seed_trace", "settle", "smooth",
           "smoothing_target", "song_beats_for", "edit_dance", "stage_edit"]

#: The cut-off (Hz) of the light low-pass after the foot lock (:func:`settle`); 0: none.
SETTLE_HZ = 0.0


def _is_3d(motion: Motion) -> bool:
    p = motion.positions if motion.positions is not None else None
    return motion.num_frames >= 3 and (p is None or (p.ndim == 3 and p.shape[-1] == 3))


def song_beats_for(audio_path: str | os.PathLike, *, start: float | None = None, end: float | None = None):
    """The :class:`~dancekit.features.pulse.SongBeats` of the song (excerpt), times from the excerpt's start."""
    from dancekit.features.pulse import song_beats_file

    return song_beats_file(audio_path, start=start, end=end)


def beat_sync(result: DanceResult, audio_path: str | os.PathLike, *, start: float | None = None,
              end: float | None = None, beats=None, options: dict | None = None) -> DanceResult:
    """The result with its motion time-warped onto the song's beats (a new :class:`DanceResult`; a note
    in ``notes`` says how many beats were matched, or why the dance was left unwarped).

    ``beats``: a :class:`~dancekit.features.pulse.SongBeats` already tracked (else the song is tracked).
    ``options``: :func:`~dancekit.motion.timewarp.beat_warp` keyword arguments
    (:meth:`~dancekit.pipelines.config.BeatSyncConfig.warp_options`; none: its defaults).
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
                              **(options or {}))
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
    when the model's checkpoint asks for it (:class:`~dancekit.pipelines.config.RegroundConfig`). The stages after the clean-up (the
    low-passes, the lock's IK) can lift a lively model's dance off the floor again; this one lets it touch
    the floor at least once in every window, while a rise shorter than ``window_s / 2`` stays.

    ``max_float_cm``: when the regrounded dance still floats higher than this (its lowest joint's median
    height over the local floor, :func:`dancekit.motion.floor.floor_float_cm`, cm), shorter windows are
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


def smooth(result: DanceResult, *, target: float | None = None, kind: str | None = None,
           config: SmoothConfig | None = None, genre_stats: GenreStats | None = None) -> DanceResult:
    """The result with frame-to-frame noise filtered out; a dance already smooth enough is returned as it is.

    ``kind`` (default :data:`SMOOTH_FILTER`): ``"lowpass"``, a zero-phase windowed-sinc FIR low-pass whose
    cut-off is the highest of :data:`dancekit.motion.jitter.CUTOFFS_HZ` that brings the dance's
    jitter-to-energy ratio to ``target`` (:func:`dancekit.motion.jitter.lowpass_cutoff`); ``"savgol"``, a
    Savitzky-Golay filter whose window is the shortest that does
    (:func:`dancekit.motion.jitter.smoothing_window`). ``target`` default: the genre's target of
    :func:`smoothing_target` (``config``'s genres, ``genre_stats``' ratios), else ``config.target``
    (:data:`SMOOTH_TARGET`), or ``config.target_noisy`` (:data:`SMOOTH_TARGET_NOISY`) for a dance beyond
    ``config.noisy_ratio`` (:data:`NOISY_RATIO`); ``kind`` default ``config.filter``. A motion
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
    config = SmoothConfig() if config is None else config
    kind = config.filter if kind is None else kind
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # (T, J, 3); the helpers work in float64 piece by piece
    if target is None:
        target = smoothing_target(result, config, genre_stats)
    if target is None:
        target = config.target_noisy if _jitter_ratio(p, sk, fps) > config.noisy_ratio else config.target
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


def smoothing_target(result: DanceResult, config: SmoothConfig,
                     genre_stats: GenreStats | None = None) -> float | None:
    """The jitter-to-energy ratio :func:`smooth` brings ``result`` to when ``config`` targets the genre danced
    (``config.genre_targets``: its real ratio in ``genre_stats.smoothing`` × ``config.scale``) and that genre
    was asked for by name (``result.genre_requested`` is a genre, not "auto" / "none"), or, with
    ``config.drawn``, also when the genre was read from the music or drawn by the seed (``result.genre``: the
    genre model that danced it); None otherwise (the stage's own targets apply: the model alone, a genre
    without a target)."""
    ratios = {} if genre_stats is None else genre_stats.table("smoothing")
    targets = {g: ratios[g] * config.scale for g in config.genre_targets if g in ratios}
    drawn = config.drawn
    genre = result.genre
    if genre is None or str(genre) not in targets:
        return None
    named = result.genre_requested not in (None, "auto", "none") and genre == result.genre_requested
    return targets[str(genre)] if named or (drawn and result.genre_requested in (None, "auto")) else None


def foot_lock(result: DanceResult, config: FootLockConfig | None = None,
              genre_stats: GenreStats | None = None) -> DanceResult:
    """The result with its planted feet pinned (:func:`dancekit.motion.footlock.lock_feet`: contacts from
    foot height and speed, the foot held where it was planted, the leg solved by two-bone IK, blended in
    and out), with ``config``'s settings (None: the defaults). With ``config.plant``, the lock holds the feet
    no longer than the genre's real planted-foot share (``genre_stats.planted_share``, :func:`plant_target`,
    :func:`~dancekit.motion.footlock.lock_feet_to_share`).
    Only the legs change; a motion with rotations has its leg rotations updated
    (:func:`~dancekit.motion.footlock.leg_rotations`). Skeletons without legs are returned unchanged."""
    from dancekit.motion.footlock import leg_chains, leg_rotations, lock_feet

    motion = result.motion
    if not _is_3d(motion) or not leg_chains(motion.skeleton):
        return result
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # lock_feet works on its own float64 copy
    config = FootLockConfig() if config is None else config
    options = config.lock_options()
    share = genre_stats.table("planted_share") if config.plant and genre_stats is not None else None
    target = plant_target(result, genre_share=share)
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
    filtered dance, parents first), piece by piece (:func:`dancekit.motion.filters.chunks`); a motion with
    rotations has its rotations and root translation filtered instead (re-orthonormalised, whole-song, as
    :func:`smooth` does) and its positions recomputed from them, so a held foot moves a little there.
    ``ratio_target`` (and no ``cutoff``): the cut-off is chosen per dance, the highest of
    :data:`dancekit.motion.jitter.CUTOFFS_HZ` that brings the dance's jitter-to-energy ratio to the target
    (:func:`dancekit.motion.jitter.lowpass_cutoff`); a dance already at or under it is left alone.
    ``max_jitter`` (m/s; and no ``cutoff``): the cut-off is chosen per dance, the highest of
    :data:`dancekit.motion.jitter.CAP_CUTOFFS_HZ` that brings the dance's jitter under the cap
    (:func:`dancekit.motion.jitter.jitter_cutoff`; a genre model drawn by the seed, issue 15); a dance
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
    floor (no ``lift_energy`` settings in the checkpoint, :class:`~dancekit.pipelines.config.EnergyConfig`, or no genre known for a
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
    """A per-genre jitter table (genre name -> real dances' median jitter, m/s; ``dancekit.training.genre_stats
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


def plausible_jitter_cap(probs: dict[str, float], *, genre_jitter: dict[str, float], scale: float,
                         min_ratio: float) -> float | None:
    """The per-dance jitter cap (m/s, the ``max_jitter`` of :func:`finish`) for a song whose genre posterior is
    ``probs`` (genre → p): ``scale`` × the smallest real jitter ``genre_jitter[g]`` (m/s, the real training
    dances' median per genre, :func:`dancekit.training.genre_stats.genre_stats`, its ``jitter`` table) among the song's plausible genres
    (``p_g ≥ min_ratio · max(p)``, genres in the table). None (no cap) without a posterior, a scale or a
    plausible genre in the table. A genre asked for by name is ``probs = {genre: 1.0}``."""
    if not probs or not scale > 0 or not genre_jitter:
        return None
    top = max(probs.values())
    plausible = [genre_jitter[g] for g, p in probs.items() if g in genre_jitter and p >= min_ratio * top]
    return float(scale * min(plausible)) if plausible else None


def jitter_cap_for(result: DanceResult, config: JitterCapConfig | None,
                   genre_stats: GenreStats | None = None) -> float | None:
    """The jitter cap (m/s) of one dance, or None (no cap): :func:`genre_jitter_cap` of the dance's genre
    posterior read from the music (``result.genre_probs``) and the genre it danced (``result.genre``). None for
    a dance whose input does not look like music."""
    if config is None or not result.looks_like_music:
        return None
    return genre_jitter_cap(config, genre_stats, probs=result.genre_probs or {}, genre=result.genre)


def genre_jitter_cap(config: JitterCapConfig | None, genre_stats: GenreStats | None, *, probs: dict[str, float],
                     genre: str | None) -> float | None:
    """The jitter cap (m/s) of a dance of ``genre`` (None: the model alone) on music whose genre posterior is
    ``probs`` (genre → p; empty: not read), or None (no cap): ``config.max_jitter`` when set; else
    :func:`plausible_jitter_cap` over ``probs`` with the real jitters of ``genre_stats.jitter`` — not for the
    most likely genre's dance unless ``config.all`` —, or, for a genre asked for by name (no posterior) with
    ``config.named``, over that genre alone. None without a ``config``, or without a posterior or a named genre.
    The offline stage (:func:`jitter_cap_for`) and the live one (:mod:`dancekit.live`) share it."""
    if config is None:
        return None
    if config.max_jitter is not None:
        return config.max_jitter
    if not probs:
        if not config.named or genre is None:
            return None
        probs = {genre: 1.0}
    elif genre is not None and genre == max(probs, key=probs.get) and not config.all:
        return None
    table = {} if genre_stats is None else genre_stats.table("jitter")
    return plausible_jitter_cap(probs, genre_jitter=table, scale=config.scale, min_ratio=config.min_ratio)


@dataclasses.dataclass
class Song:
    """The song (excerpt ``[start, end)`` s) a dance was made for; its beats (:func:`song_beats_for`) tracked
    on first use and kept, so that the dances of one song share them."""

    path: str | os.PathLike
    start: float | None = None
    end: float | None = None
    beats: object | None = None

    def song_beats(self):
        if self.beats is None:
            self.beats = song_beats_for(self.path, start=self.start, end=self.end)
        return self.beats


@dataclasses.dataclass
class StageContext:
    """What a stage knows beside the dance and its own settings: the song, the checkpoint's genre statistics,
    the dance's jitter cap (m/s, None: none; :func:`jitter_cap_for`) and the cut-off (Hz) the cap is to use on
    this pass of the stages after it (None: chosen per dance; set by :func:`finish` for
    :attr:`~dancekit.pipelines.config.JitterCapConfig.to_end`); ``chosen`` keeps the cut-off the first pass chose."""

    song: Song
    genre_stats: GenreStats
    max_jitter: float | None = None
    cap_cutoff: float | None = None
    chosen: list[float] = dataclasses.field(default_factory=list)


def stage_clean_up(result: DanceResult, config, ctx: StageContext) -> DanceResult:
    """:func:`clean_up`: rigid per frame (the root path turned back within the dance floor, the lowest joint on
    the floor); fps, frame count, bone lengths and the rotations of the non-root joints unchanged."""
    return clean_up(result)


def stage_smooth(result: DanceResult, config: SmoothConfig, ctx: StageContext) -> DanceResult:
    """:func:`smooth`: only a jittery dance is filtered (zero-phase, same fps and frame count); bone lengths exact."""
    return smooth(result, config=config, genre_stats=ctx.genre_stats)


def stage_lift_energy(result: DanceResult, config, ctx: StageContext) -> DanceResult:
    """:func:`lift_energy`: a dance under its energy floor (m/s) lifted (no settings: unchanged); fps, frame
    count, bone lengths and the lowest joint's height over the floor unchanged."""
    if config is None:
        return result
    energy = ctx.genre_stats.table("energy")
    return lift_energy(result, floor=config.floor, fraction=config.fraction, genre_energy=energy or None,
                       max_gain=config.max_gain, mean_s=config.mean_s, band_hz=config.band_hz, damp=config.damp,
                       root=config.root, legs=config.legs)


def stage_jitter_cap(result: DanceResult, config: JitterCapConfig, ctx: StageContext) -> DanceResult | None:
    """A per-dance low-pass (:func:`settle`) that brings the dance's jitter under ``ctx.max_jitter`` (m/s): the
    highest cut-off of :data:`dancekit.motion.jitter.CAP_CUTOFFS_HZ` that does, or ``ctx.cap_cutoff`` on a
    later pass; a dance under the cap is left alone. None (the stage does not apply) without a cap. Fps and
    frame count unchanged; bone lengths exact."""
    if ctx.max_jitter is None:
        return None
    cutoff = ctx.cap_cutoff
    if cutoff is None and config.to_end and _is_3d(result.motion):  # chosen here (as settle would), and kept
        from dancekit.motion.jitter import jitter_cutoff

        m = result.motion
        ctx.chosen.append(jitter_cutoff(m.to_positions(), skeleton=m.skeleton, fps=m.fps,
                                        max_jitter=float(ctx.max_jitter)))
        cutoff = ctx.chosen[0]
        if not cutoff:  # under the cap already
            return result
    if cutoff is None:  # the highest cut-off that brings the dance under the cap (0: none needed)
        return settle(result, max_jitter=ctx.max_jitter)
    return _with_note(settle(result, cutoff=cutoff), _calmed(cutoff))


def stage_foot_lock(result: DanceResult, config: FootLockConfig, ctx: StageContext) -> DanceResult:
    """:func:`foot_lock`: only the legs change (the body lowered where a held foot is out of reach); fps and
    frame count unchanged."""
    return foot_lock(result, config, ctx.genre_stats)


def stage_settle(result: DanceResult, config, ctx: StageContext) -> DanceResult:
    """:func:`settle`: a light zero-phase low-pass after the lock (none without a cut-off); a held foot stays held."""
    return settle(result, **config.settle_options())


def stage_reground(result: DanceResult, config, ctx: StageContext) -> DanceResult:
    """:func:`reground`: a vertical shift per frame (the lowest joint on the floor once in every window)."""
    return reground(result, **config.reground_options())


def stage_beat_sync(result: DanceResult, config, ctx: StageContext) -> DanceResult:
    """:func:`beat_sync`: the frames re-timed onto the song's beats (same fps and frame count; poses are
    interpolated between frames); a song without a clear beat or a dance calmed for not-music is left as it is."""
    needs = _is_3d(result.motion) and result.looks_like_music
    return beat_sync(result, ctx.song.path, start=ctx.song.start, end=ctx.song.end,
                     beats=ctx.song.song_beats() if needs else None, options=config.warp_options())


def read_edit_motion(file: str, skeleton, fps: float, what: str) -> np.ndarray:
    """The positions ``(T, J, 3)`` of a motion file on ``skeleton`` at ``fps`` (mapped by role from another
    skeleton, resampled from another frame rate)."""
    from dancekit.motion.formats import read_motion

    m = read_motion(file)
    if not m.skeleton.same_as(skeleton):
        from dancekit.motion.retarget import MAP_REQUIRED, map_by_role

        missing = [r for r in MAP_REQUIRED if not m.skeleton.has(r)]
        if missing or m.skeleton.dims != 3:
            raise ParameterError(f"{file}: the {what} is on skeleton {m.skeleton.name!r}, which has no rig mapping "
                                 f"to {skeleton.name!r} (missing roles: {', '.join(missing) or '3D'})")
        m = map_by_role(m, skeleton)
    if m.fps != fps:
        m = m.resample(fps)
    return np.asarray(m.to_positions(), np.float64)


def stage_path(result: DanceResult, config: EditConfig) -> DanceResult:
    """The dance moved onto the edit's path (:func:`dancekit.motion.edit.follow_path`): what :func:`finish` runs
    before the foot lock when a path is given, so that the lock, the settle and the beat sync treat the moved
    dance as any other (the feet planted by the model's own lock, not locked twice). Positions only."""
    from dancekit.motion import edit

    m = result.motion
    if not _is_3d(m):
        raise ParameterError("edit: only a 3D dance can be edited")
    points, times = edit.read_path(config.path)
    p = edit.follow_path(m.to_positions(), skeleton=m.skeleton, fps=m.fps, points=points, times=times)
    return dataclasses.replace(result, motion=Motion(skeleton=m.skeleton, fps=m.fps, positions=p.astype(np.float32)))


def stage_edit(result: DanceResult, config: EditConfig, ctx: StageContext,
               lock: FootLockConfig | None = None, *, path_before_lock: bool = False) -> DanceResult:
    """The user's edit (:class:`~dancekit.pipelines.config.EditConfig`, :mod:`dancekit.motion.edit`), in this
    order: the prefix (kept exactly, the dance aligned and faded onto it), the path (then the feet held again
    by :func:`foot_lock` with ``lock``, when the foot lock is on; with ``path_before_lock`` the dance was already
    moved onto the path before the foot lock (:func:`stage_path`): it is only put back on it exactly, the few
    centimetres the beat sync's retiming moved it along, and not locked again), the kept body parts, the
    keyframes (exact at their frames, so last). Same fps and frame count; the result holds positions only (the
    edited joints no longer follow the rotations). A contradiction (keys on kept joints, keys within the prefix
    or its fade, a prefix not shorter than the dance) is a ParameterError naming the file."""
    from dancekit.motion import edit

    m = result.motion
    if not _is_3d(m):
        raise ParameterError("edit: only a 3D dance can be edited")
    sk, fps = m.skeleton, m.fps
    p = np.asarray(m.to_positions(), np.float64)
    n_pre, notes = 0, []
    if config.prefix is not None:
        pre = read_edit_motion(config.prefix, sk, fps, "prefix")
        if len(pre) >= len(p):
            raise ParameterError(f"{config.prefix}: the prefix ({len(pre) / fps:.2f} s) is not shorter than the "
                                 f"dance ({len(p) / fps:.2f} s)")
        p, n_pre = edit.continue_from(pre, p, skeleton=sk, fps=fps, crossfade_s=config.crossfade_s), len(pre)
        notes.append(f"continued from {Path(config.prefix).name} ({n_pre / fps:.1f} s)")
    if config.path is not None:
        points, times = edit.read_path(config.path)
        p = edit.follow_path(p, skeleton=sk, fps=fps, points=points, times=times)
        if lock is not None and not path_before_lock:
            moved = dataclasses.replace(result, motion=Motion(skeleton=sk, fps=fps, positions=p.astype(np.float32)))
            p = np.asarray(foot_lock(moved, lock, ctx.genre_stats).motion.to_positions(), np.float64)
        notes.append(f"on the path {Path(config.path).name}")
    kept: tuple[int, ...] = ()
    if config.keep is not None:
        take = read_edit_motion(config.take, sk, fps, "take")
        if len(take) < len(p):
            raise ParameterError(f"{config.take}: the take ({len(take) / fps:.2f} s) is shorter than the dance "
                                 f"({len(p) / fps:.2f} s)")
        kept = edit.body_part_joints(sk, config.keep)
        p = edit.keep_joints(p, take, skeleton=sk, joints=kept)
        notes.append(f"{config.keep if isinstance(config.keep, str) else ','.join(config.keep)} kept from "
                     f"{Path(config.take).name}")
    if config.keyframes is not None:
        try:
            wants_beats = '"beat"' in Path(config.keyframes).read_text()
        except (OSError, UnicodeDecodeError):
            wants_beats = False  # read_keyframes names the problem
        beats = ctx.song.song_beats().times if wants_beats else None
        keys = edit.read_keyframes(config.keyframes, skeleton=sk, fps=fps, num_frames=len(p), beats=beats,
                                   max_speed=config.max_speed)
        both = sorted({sk.joint_names[j] for k in keys for j in k.joints} & {sk.joint_names[j] for j in kept})
        if both:
            raise ParameterError(f"{config.keyframes}: keys on kept joints ({', '.join(both)}): the take fixes them")
        support = config.support_s * fps
        early = [k for k in keys if k.frame < n_pre + support] if n_pre else []
        if early:
            raise ParameterError(f"{config.keyframes}: a key at {early[0].frame / fps:.2f} s falls within the prefix "
                                 f"or its {config.support_s:g} s after ({n_pre / fps:.2f} s)")
        p = edit.apply_keyframes(p, keys=keys, fps=fps, support_s=config.support_s)
        notes.append(f"{len(keys)} keys from {Path(config.keyframes).name}")
    out = Motion(skeleton=sk, fps=fps, positions=p.astype(np.float32))
    return _with_note(dataclasses.replace(result, motion=out), "edited: " + "; ".join(notes))


def edit_dance(result: DanceResult, edit: EditConfig, audio: Song | str | os.PathLike,
               config: StageConfig | None = None) -> DanceResult:
    """A finished dance (e.g. one of a pipeline's ``dances``) through the edit stage alone (:func:`stage_edit`):
    a path moves the finished dance and its feet are locked again with ``config``'s foot lock when it is on
    (None: the defaults), where :func:`finish` (``dances(..., edit=...)``, ``dancekit dance --path``) moves the
    dance before its foot lock. ``audio``: the song (its beats, for keys given by beat)."""
    config = StageConfig() if config is None else config
    song = audio if isinstance(audio, Song) else Song(audio)
    ctx = StageContext(song=song, genre_stats=config.genre_stats)
    return stage_edit(result, edit, ctx, lock=config.foot_lock if "foot_lock" in config.order() else None)


#: stage name → its function ``(result, its settings, StageContext) -> result`` (None: the stage does not apply)
STAGES: dict[str, Callable] = {"clean_up": stage_clean_up, "smooth": stage_smooth, "lift_energy": stage_lift_energy,
                               "jitter_cap": stage_jitter_cap, "foot_lock": stage_foot_lock, "settle": stage_settle,
                               "reground": stage_reground, "beat_sync": stage_beat_sync}


def _run(result: DanceResult, names, config: StageConfig, ctx: StageContext, steps: list | None) -> DanceResult:
    for name in names:
        out = STAGES[name](result, getattr(config, name), ctx)
        if out is None:  # does not apply to this dance
            continue
        result = out
        if steps is not None:
            steps.append((name, result))
    return result


def finish(result: DanceResult, audio: Song | str | os.PathLike, config: StageConfig | None = None,
           trace: Callable[[str, DanceResult], None] | None = None) -> DanceResult:
    """The dance through the stages ``config`` enables, in the order of :meth:`StageConfig.order
    <dancekit.pipelines.config.StageConfig.order>`: the clean-up, the smoothing, the energy lift, the jitter cap
    (before the lock, or after its settle), the foot lock, the settle, the regrounding, the beat sync.

    ``audio``: the song (a :class:`Song`, whose beats many dances share, or a path); ``config``: the
    checkpoint's :class:`~dancekit.pipelines.config.StageConfig` switched for this run (None: the defaults).
    With the jitter cap's ``to_end``, while the finished dance's jitter is over its cap the stages from the cap
    (or the lock) on run again from the same input with the next lower cut-off
    (:data:`dancekit.motion.jitter.CAP_CUTOFFS_HZ`), down to the lowest. ``trace``: called as
    ``trace("input", result)``, then ``trace(name, result)`` after each stage that ran (with ``to_end``, the
    stages after the cap as last run).

    ``config.edit`` (the user's constraints) runs after every other stage (:func:`stage_edit`), but a path
    enters before the jitter cap and the foot lock (:func:`stage_path`, traced as ``"path"``): the feet of the
    moved dance are planted by the model's own lock, as an unedited dance's are."""
    config = StageConfig() if config is None else config
    song = audio if isinstance(audio, Song) else Song(audio)
    ctx = StageContext(song=song, genre_stats=config.genre_stats,
                       max_jitter=jitter_cap_for(result, config.jitter_cap, config.genre_stats))
    steps: list | None = [("input", result)] if trace is not None else None  # kept only for a trace
    order = config.order()
    lock = [n for n in ("jitter_cap", "foot_lock", "settle", "reground") if n in order]
    split = order.index(lock[0]) if lock else len(order)
    head = _run(result, order[:split], config, ctx, steps)
    early_path = config.edit is not None and config.edit.path is not None and bool(lock) and _is_3d(head.motion)
    if early_path:  # the path before the lock: the lock and the stages after it plant the moved feet
        head = stage_path(head, config.edit)
        if steps is not None:
            steps.append(("path", head))
    kept = None if steps is None else len(steps)
    out = _run(head, order[split:], config, ctx, steps)
    cap = config.jitter_cap
    if cap is not None and cap.to_end and "jitter_cap" in order and ctx.max_jitter is not None \
            and _is_3d(out.motion):
        from dancekit.motion.jitter import CAP_CUTOFFS_HZ, jitter_speed

        first = ctx.chosen[0] if ctx.chosen else 0.0
        for c in (c for c in CAP_CUTOFFS_HZ if not first or c < first):
            m = out.motion
            if jitter_speed(m.to_positions(), skeleton=m.skeleton, fps=m.fps) <= ctx.max_jitter:
                break
            if steps is not None:
                del steps[kept:]
            ctx.cap_cutoff = c
            out = _run(head, order[split:], config, ctx, steps)
    if config.edit is not None and config.edit.active:  # the user's constraints, after every other stage
        out = stage_edit(out, config.edit, ctx, lock=config.foot_lock if "foot_lock" in order else None,
                         path_before_lock=early_path)
        if steps is not None:
            steps.append(("edit", out))
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
