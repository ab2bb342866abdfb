"""Pipeline stages every dance model shares: beat-synchronous output and the physical clean-up.

Both run on the :class:`~dancekit.pipelines.DanceResult` of any dance pipeline (the model's motion on its
own skeleton, 3D positions), on by default (``pipe(song, beat_sync=False, cleanup=False)`` gives the
model's own output):

* **beat sync** (:func:`beat_sync`): the song (excerpt) is beat-tracked on the fine grid
  (:func:`dancekit.features.pulse.song_beats`); a song without a clear pulse (speech, a bird, a whale's
  song) is left unwarped, with a note. Otherwise the dance is time-warped so that its kinematic beats
  (speed minima) land on the song's beats: :func:`dancekit.motion.timewarp.beat_warp` (dynamic
  programming over candidate pairings, the local speed kept within ±15 %, a smooth rate).
* **clean-up** (:func:`clean_up`): the figure's root path is kept within a dance floor (turned back
  toward its start beyond 4 m, never farther than 12 m) and its lowest joint put on the floor
  (:mod:`dancekit.motion.cleanup`).
* **smoothing** (:func:`smooth`): a jittery dance gets a Savitzky-Golay filter whose window is chosen per
  dance (:mod:`dancekit.motion.footlock`); a smooth one is left alone. A dance whose genre was asked for by
  name is brought to that genre's own jitter-to-energy ratio when the model's checkpoint carries one
  (:func:`genre_smoothing_targets`: real cha-chas and tangos have 2-4x the high-frequency motion of waltzes).
* **foot lock** (:func:`foot_lock`): planted feet held where they were planted, the legs solved by two-bone
  IK, the body lowered where a held foot is out of reach, blended in and out (:mod:`dancekit.motion.footlock`).

:func:`finish` runs them (clean-up, smoothing, foot lock, then the warp) and records what happened in
``result.notes`` (the summary line).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from dancekit.errors import CheckpointError
from dancekit.motion import Motion
from dancekit.pipelines.base import DanceResult

__all__ = ["NOISY_RATIO", "SMOOTH_TARGET", "SMOOTH_TARGET_NOISY", "beat_sync", "clean_up", "finish", "foot_lock",
           "foot_lock_options", "genre_smoothing_targets", "smooth", "smoothing_target", "song_beats_for"]

#: The jitter-to-energy ratio (:func:`dancekit.motion.footlock.smoothing_window`) the smoothing stage brings a
#: jittery dance down to: about the 80th percentile of the real training dances' (0.055-0.28, median 0.065);
#: a dance beyond :data:`NOISY_RATIO` (more than nearly every real dance: frame-to-frame noise, the dual
#: model's 0.31-0.33) is brought to :data:`SMOOTH_TARGET_NOISY`, the real median. Chosen on the validation
#: songs (``benchmarks/bench_feet.py --grid``, docs/STAGES.md).
SMOOTH_TARGET = 0.09
SMOOTH_TARGET_NOISY = 0.065
NOISY_RATIO = 0.2


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
    source, pairs = beat_warp(motion.to_positions(), music_beats=beats.times, fps=motion.fps)
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


def smooth(result: DanceResult, *, target: float | None = None) -> DanceResult:
    """The result with frame-to-frame noise filtered out (:func:`dancekit.motion.footlock.smooth_positions`:
    a Savitzky-Golay filter whose window is the shortest that brings the dance's jitter-to-energy ratio to
    ``target``, default :func:`smoothing_target`: :data:`SMOOTH_TARGET`, or :data:`SMOOTH_TARGET_NOISY` for a
    dance beyond :data:`NOISY_RATIO`, or the requested genre's ratio of the model's checkpoint; a dance already
    that smooth is returned as it is). A motion
    with rotations has its rotations filtered (re-orthonormalised) and its positions recomputed from them;
    a positions-only motion takes its bone directions from the filtered dance and keeps each frame's bone
    lengths; so bone lengths stay exact either way."""
    from dancekit.motion.footlock import _jitter_ratio, _savgol, chunks, savgol_rows, smoothing_window

    motion = result.motion
    if not _is_3d(motion):
        return result
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # (T, J, 3); the helpers work in float64 piece by piece
    if target is None:
        target = smoothing_target(result)
    if target is None:
        target = SMOOTH_TARGET_NOISY if _jitter_ratio(p, sk, fps) > NOISY_RATIO else SMOOTH_TARGET
    window = smoothing_window(p, skeleton=sk, fps=fps, target=target)
    if window <= 1:
        return result
    if motion.rotations is None:
        out = np.empty(p.shape, np.float32)
        for a, b in chunks(len(p)):  # the filter is local: piece by piece, the same numbers as one pass
            q = savgol_rows(p, window, 3, a, b)
            o = q.copy()  # bone directions from the filtered dance, each frame's own bone lengths kept
            x = np.asarray(p[a:b], np.float64)
            for j in sk.topological_order:
                parent = sk.parents[j]
                if parent >= 0:
                    d = q[:, j] - q[:, parent]
                    length = np.linalg.norm(x[:, j] - x[:, parent], axis=-1, keepdims=True)
                    o[:, j] = o[:, parent] + length * d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True),
                                                                     1e-12)
            out[a:b] = o
        smoothed = Motion(skeleton=sk, fps=fps, positions=out)
    else:
        import torch

        from dancekit.motion.kinematics import rig_forward_kinematics

        p = np.asarray(p, np.float64)
        rot = _savgol(np.asarray(motion.rotations, np.float64).reshape(len(p), -1, 9), window, 3)
        u, _, vt = np.linalg.svd(rot.reshape(len(p), -1, 3, 3))
        d = np.sign(np.linalg.det(u @ vt))
        u[..., :, -1] *= d[..., None]
        rot = u @ vt
        tr = _savgol(np.asarray(motion.root_translation, np.float64), window, 3)
        pos = rig_forward_kinematics(torch.from_numpy(rot), torch.from_numpy(tr), sk).numpy()
        smoothed = Motion(skeleton=sk, fps=fps, positions=pos.astype(np.float32),
                          rotations=rot.astype(motion.rotations.dtype), root_translation=tr.astype(np.float32))
    return _with_note(dataclasses.replace(result, motion=smoothed), f"smoothed ({window}-frame filter)")


def smoothing_target(result: DanceResult) -> float | None:
    """The jitter-to-energy ratio :func:`smooth` brings ``result`` to when it was danced in a genre asked for
    by name (``result.genre_requested`` is a genre, not "auto" / "none") and the model's checkpoint has a
    target for it (:func:`genre_smoothing_targets`); None otherwise (the stage's own targets apply)."""
    if result.genre_requested in (None, "auto", "none") or result.genre != result.genre_requested:
        return None
    return genre_smoothing_targets(result.model).get(str(result.genre))


def genre_smoothing_targets(model: str | os.PathLike | None) -> dict[str, float]:
    """Per genre, the jitter-to-energy ratio (:func:`dancekit.motion.footlock.smoothing_window`) that the
    smoothing stage brings a dance of that genre to when the genre was asked for by name: the checkpoint's
    ``"smoothing": {"genre_targets": {genre: ratio}}`` (for the embedded music2dance: the median of the real
    training dances of each genre, ``benchmarks/genre_smoothing_targets.py``; docs/MUSIC2DANCE.md). ``{}``
    for a folder without the entry or that is not a checkpoint."""
    from dancekit.checkpoints.hub import read_meta

    if not model:
        return {}
    try:
        spec = read_meta(model).get("smoothing") or {}
    except (CheckpointError, OSError):
        return {}
    targets = spec.get("genre_targets", {}) if isinstance(spec, dict) else None
    if not isinstance(spec, dict) or set(spec) - {"genre_targets"} or not isinstance(targets, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < 10 for v in targets.values()):
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'smoothing' takes "
                              f"{{'genre_targets': {{genre: ratio in (0, 10)}}}}, got {spec!r}")
    return {str(g): float(v) for g, v in targets.items()}


def foot_lock(result: DanceResult) -> DanceResult:
    """The result with its planted feet pinned (:func:`dancekit.motion.footlock.lock_feet`: contacts from
    foot height and speed, the foot held where it was planted, the leg solved by two-bone IK, blended in
    and out), with the settings of the model's checkpoint (:func:`foot_lock_options` of ``result.model``).
    Only the legs change; a motion with rotations has its leg rotations updated
    (:func:`~dancekit.motion.footlock.leg_rotations`). Skeletons without legs are returned unchanged."""
    from dancekit.motion.footlock import leg_chains, leg_rotations, lock_feet

    motion = result.motion
    if not _is_3d(motion) or not leg_chains(motion.skeleton):
        return result
    sk, fps = motion.skeleton, motion.fps
    p = motion.to_positions()  # lock_feet works on its own float64 copy
    locked = lock_feet(p, skeleton=sk, fps=fps, **foot_lock_options(result.model))
    rot = tr = None
    if motion.rotations is not None:
        rot = leg_rotations(motion.rotations, np.asarray(p, np.float64), locked,
                            skeleton=sk).astype(motion.rotations.dtype)
        tr = locked[:, sk.root].astype(np.float32)  # the body may have been lowered
    out = Motion(skeleton=sk, fps=fps, positions=locked.astype(np.float32), rotations=rot, root_translation=tr)
    return dataclasses.replace(result, motion=out)


def foot_lock_options(model: str | os.PathLike | None) -> dict[str, float]:
    """The :func:`~dancekit.motion.footlock.lock_feet` settings a model's checkpoint folder carries in its
    ``config.json`` (``"foot_lock": {"min_hold_s": s}``), chosen on the validation songs (docs/STAGES.md):
    the embedded Dance Revolution's dances have many short stops near the floor, and holding them for
    0.12-0.4 s makes the foot stop and go (jitter); the embedded music2dance's geometric FID rises without
    its short holds, so it keeps the defaults. ``{}`` (the defaults) for a folder without the entry or that
    is not a checkpoint."""
    from dancekit.checkpoints.hub import read_meta

    if not model:
        return {}
    try:
        spec = read_meta(model).get("foot_lock") or {}
    except (CheckpointError, OSError):
        return {}
    allowed = {"min_hold_s"}
    if not isinstance(spec, dict) or not set(spec) <= allowed:
        raise CheckpointError(f"corrupt checkpoint file {Path(model) / 'config.json'}: 'foot_lock' takes "
                              f"{sorted(allowed)}, got {spec!r}")
    return {k: float(v) for k, v in spec.items()}


def finish(result: DanceResult, audio_path: str | os.PathLike, *, start: float | None = None,
           end: float | None = None, beat_sync_on: bool = True, cleanup_on: bool = True,
           foot_lock_on: bool | None = None, smooth_on: bool | None = None, beats=None) -> DanceResult:
    """The stages as switched, in this order: the clean-up (it moves frames rigidly), the smoothing (only
    a jittery dance is filtered), the foot lock (after the smoothing, so a pinned foot stays pinned), then
    the beat sync (so the speed minima it aligns are those of the final dance). ``foot_lock_on`` and
    ``smooth_on`` follow ``cleanup_on`` unless given. ``beats``: the song's
    :class:`~dancekit.features.pulse.SongBeats` when already tracked (many dances of one song), else tracked
    here when needed."""
    if cleanup_on:
        result = clean_up(result)
    if cleanup_on if smooth_on is None else smooth_on:
        result = smooth(result)
    if cleanup_on if foot_lock_on is None else foot_lock_on:
        result = foot_lock(result)
    if beat_sync_on:
        result = beat_sync(result, audio_path, start=start, end=end, beats=beats)
    return result


def _with_note(result: DanceResult, note: str) -> DanceResult:
    return dataclasses.replace(result, notes=[*result.notes, note])
