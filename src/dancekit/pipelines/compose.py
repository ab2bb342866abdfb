"""Dance → music, the arranger's side: the dance's pulse and the music that follows it (inference only).

:class:`~dancekit.pipelines.dual.ComposePipeline` runs G_D→M (chroma + beat activation per frame) and hands
its output with the dance to :func:`follow`, which measures the dance's pulse (:func:`pulse_of`) and arranges
the music with :func:`dancekit.audio.arrange.follow_dance`. What comes from where:

* from the **dance** (no model): the tempo (the ankles' steps), the beats' phase (its kinematic beats) and the
  metre (the whole body's speed dips);
* from **G_D→M**: each bar's chord within the key (its composed chroma), the accents and the piano's
  density (its beat activation); the key is the start chord G_D→M was given;
* from the **arranger**: the voicing, the bass line and the drum pattern.
"""

from __future__ import annotations

import numpy as np

from dancekit.audio.arrange import DanceArrangement, beat_curve, dance_pulse, follow_dance
from dancekit.motion import Motion
from dancekit.motion.analysis import kinematic_beats, mean_joint_speed

#: the joints whose speed makes the tempo's pulse: the ankles (the steps)
PULSE_ROLES = ("left_ankle", "right_ankle")


def pulse_of(motion: Motion) -> np.ndarray:
    """The dance's pulse curve ``(T,)`` at ``motion.fps``: :func:`~dancekit.audio.arrange.dance_pulse` of the
    summed speed of the ankles (the steps; every joint when the skeleton has no ankles), smoothed by a
    Gaussian of 0.04 s."""
    from dancekit.motion.filters import gaussian_filter1d

    p = np.asarray(motion.to_positions(), np.float64)
    sk = motion.skeleton
    joints = [sk.index(r) for r in PULSE_ROLES] if all(sk.has(r) for r in PULSE_ROLES) else list(range(p.shape[1]))
    if len(p) < 3:
        return np.zeros(len(p))
    speed = np.linalg.norm(np.gradient(p[:, joints], axis=0), axis=-1).sum(axis=1) * motion.fps
    speed = gaussian_filter1d(speed, 0.04 * motion.fps)
    return dance_pulse(speed, fps=motion.fps)


def phase_pulse_of(motion: Motion) -> np.ndarray:
    """The curve the beats are tracked on ``(T,)``: the dance's kinematic beats
    (:func:`dancekit.motion.analysis.kinematic_beats`, the local minima of the mean joint speed), each a
    bump of the same height (:func:`~dancekit.audio.arrange.beat_curve`)."""
    if motion.num_frames < 3:
        return np.zeros(motion.num_frames)
    kb = kinematic_beats(motion.to_positions(), fps=motion.fps)
    return beat_curve(kb, num_frames=motion.num_frames, fps=motion.fps)


def metre_pulse_of(motion: Motion) -> np.ndarray:
    """The curve the metre and the downbeats are read from ``(T,)``: :func:`~dancekit.audio.arrange.dance_pulse`
    of the mean joint speed (:func:`dancekit.motion.analysis.mean_joint_speed`), deeper where the body slows
    down more (the strong beats)."""
    if motion.num_frames < 3:
        return np.zeros(motion.num_frames)
    return dance_pulse(mean_joint_speed(motion.to_positions(), fps=motion.fps), fps=motion.fps)


def follow(motion: Motion, *, key: tuple[int, bool], chroma: np.ndarray | None = None,
           activation: np.ndarray | None = None, bpm: float | None = None) -> DanceArrangement:
    """Music for ``motion`` (at the fps of ``chroma`` / ``activation``, one row per frame): the tempo of its
    steps (:func:`pulse_of`; or ``bpm``), beats on its kinematic beats (:func:`phase_pulse_of`), its metre
    (:func:`metre_pulse_of`); chords of ``key`` chosen by ``chroma``; accents from ``activation``."""
    return follow_dance(pulse_of(motion), fps=motion.fps, key=key, chroma=chroma, activation=activation, bpm=bpm,
                        phase_pulse=phase_pulse_of(motion), metre_pulse=metre_pulse_of(motion))
