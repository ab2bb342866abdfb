"""The clean-up stages in an online form (:class:`OnlineStages`): frame by frame, no lookahead.

Each stage is the causal counterpart of an offline one (:mod:`dancekit.pipelines.stages`), applied in order
to the poses ``(k, J, 3)`` (world positions, the skeleton's units) as the model makes them:

1. **calm** (offline: ``calm_motion`` of a song that is not music): every joint's offset from the root and the
   root's steps are scaled by a gain that glides (time constant ``calm_glide_s``) between 1 while music plays
   and ``calm`` in silence, speech or a dropped block, towards a slow running mean pose — the dancer calms and
   keeps its balance instead of freezing mid-step, and the music coming back brings the dance back;
2. **floor bounds** (offline: the root path turned back beyond 4 m, :func:`dancekit.motion.cleanup.root_path_turns`,
   which is causal): the same turns, step by step (:class:`~dancekit.motion.cleanup.RootPathTurner`) — beyond
   4 m of the start the whole figure turns about its root toward the start (at most 0.5 rad/s, eased), so a
   straight drift becomes a loop; no step takes the root beyond 12 m;
3. **smoothing** (offline: a Savitzky-Golay / low-pass filter): a one-pole low-pass at ``smooth_hz`` (times
   the calm gain squared while calming: a model fed silence trembles, the calm dancer does not); then every
   bone is set back to its rest length (bone directions kept), as the offline clean-up does;
4. **floor** (offline: the running floor moved to 0, :func:`dancekit.motion.analysis.floor_curve`): the 5th
   percentile of the lowest foot joint's height over the last ``floor_window_s`` is the floor, moved to 0 (the
   offline curve's percentile over a window that ends at the frame instead of one centred on it);
5. **ground contact** (offline: the clean-up's :func:`dancekit.motion.cleanup.ground_contact`, whose offset is
   the lowest joint's running minimum over a centred 0.2-s window, Gaussian-smoothed over 0.05 s): the minimum
   over the 0.2 s that end at the frame, smoothed by a one-pole of time constant 0.05 s, never above the lowest
   joint itself, taken off — the whole figure's slow float and bob go, while a rise over less than 0.2 s
   stays (a rise shows up to 0.2 s late in the offset: the lowest joint then stands over the floor by what it
   rose in the last 0.2 s).

6. **foot lock** (``LiveConfig.foot_lock``; offline: the ``foot_lock`` stage, :func:`dancekit.motion.footlock.lock_feet`,
   which looks ±1 s around each contact): :class:`OnlineFootLock`, causal — a foot that has been low and slow
   for :data:`~dancekit.motion.footlock.MIN_CONTACT_S` glides to a stop where it is shown (:data:`LOCK_SETTLE_S`)
   and is held there, the leg solved to it by
   :func:`~dancekit.motion.footlock.two_bone_ik`, until it lifts, speeds up or drifts
   :data:`~dancekit.motion.footlock.MAX_DRIFT_M` from the model's foot; then it is handed back over
   :data:`LOCK_RELEASE_S`.

With a jitter cap (offline: the ``jitter_cap`` stage, a low-pass whose cut-off is the highest that holds the
dance's jitter under a cap, m/s), the smoothing's cut-off is not fixed: a bank of one-poles at the offline
cap's cut-offs (:data:`~dancekit.motion.jitter.CAP_CUTOFFS_HZ`) runs beside it, each one's jitter (the
metric's: body-relative speed minus that of the 5-frame average, :func:`dancekit.motion.jitter.jitter_speed`)
followed by a running mean of time constant :data:`CAP_JITTER_S`; the cut-off glides (time constant
:data:`CAP_GLIDE_S`, in log-frequency) towards the highest one whose running jitter is under the cap
(:attr:`OnlineStages.max_jitter`, set as the genre is read; None: ``smooth_hz``).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from dancekit.errors import ParameterError
from dancekit.live.config import NUDGES, LiveConfig
from dancekit.motion.analysis import heights, horizontal_axes, leg_chains, up_sign
from dancekit.motion.cleanup import GROUND_SMOOTH_S, GROUND_WINDOW_S, RootPathTurner, turn_and_move
from dancekit.motion.footlock import (
    BLEND_S,
    CONTACT_HEIGHT_OFF_M,
    CONTACT_HEIGHT_ON_M,
    CONTACT_SPEED_OFF,
    CONTACT_SPEED_ON,
    MAX_DRIFT_M,
    MIN_CONTACT_S,
    smoothstep,
    two_bone_ik,
)
from dancekit.motion.jitter import CAP_CUTOFFS_HZ

__all__ = ["BeatNudge", "JitterBank", "OnlineFootLock", "OnlineStages", "RestBones"]

#: the floor is this percentile of the lowest foot's height over the window (the offline floor curve's)
FLOOR_PERCENTILE = 5.0
#: issue 15's still second: a body-relative mean joint speed under this (m/s); ``"pulse_moving"`` is full depth
#: from twice it on
STILL_SPEED = 0.10
#: time constant (s) of the running mean pose that calming pulls towards
MEAN_POSE_S = 2.0
#: time constant (s) of the running jitter each cut-off of the jitter cap's bank is judged by
CAP_JITTER_S = 2.0
#: time constant (s) of the smoothing cut-off's glide towards the one the jitter cap chooses (in log-frequency)
CAP_GLIDE_S = 0.5
#: the online foot lock hands a released foot back to the model over this long (s; a smoothstep from where it
#: was held to the model's foot): the offline lock's hand-over
LOCK_RELEASE_S = BLEND_S
#: a planted foot glides to a stop: the step it was taking shrinks by exp(−1 / (this × fps)) a frame (s)
LOCK_SETTLE_S = 0.04
#: a held foot whose leg, straight, falls short of it by more than this (m) is let go; less, and the leg reaches
#: as far as it can toward it (a standing dancer's legs are nearly straight: the foot then slides that little)
LOCK_REACH_SLACK_M = 0.02


class JitterBank:
    """One-pole low-passes of the poses at several cut-offs, each with its running jitter (m/s).

    Parameters
    ----------
    cutoffs : the cut-offs (Hz, highest first)
    fps : frames per second
    root : the root joint (the jitter is body-relative)
    unit_scale : metres per skeleton unit
    """

    def __init__(self, cutoffs: tuple[float, ...], *, fps: float, root: int, unit_scale: float):
        self.cutoffs = np.asarray(cutoffs, np.float64)
        self.fps, self.root, self.scale = float(fps), int(root), float(unit_scale)
        self.a = 1.0 - np.exp(-2 * np.pi * self.cutoffs / self.fps)  # (K,)
        self.b = 1.0 - np.exp(-1.0 / (CAP_JITTER_S * self.fps))
        self.y: np.ndarray | None = None  # (K, J, 3) the filters' outputs
        self.hist: deque[np.ndarray] = deque(maxlen=7)  # the last 7 frames' body-relative outputs (K, J, 3)
        #: the running jitter (m/s) of each cut-off's output; None before the first 7 frames
        self.jitter: np.ndarray | None = None

    def step(self, q: np.ndarray) -> None:
        """One frame's poses ``(J, 3)`` in."""
        if self.y is None:
            self.y = np.repeat(q[None], len(self.a), axis=0)
        else:
            self.y += self.a[:, None, None] * (q[None] - self.y)
        self.hist.append(self.y - self.y[:, self.root: self.root + 1])
        if len(self.hist) < 7:
            return
        h = self.hist  # frames t-6 … t; the jitter of frame t-3 (central differences, the 5-frame average)
        raw = np.linalg.norm(h[4] - h[2], axis=-1).mean(-1) / 2
        avg = np.linalg.norm((h[6] - h[1]) / 5 + (h[5] - h[0]) / 5, axis=-1).mean(-1) / 2  # avg(t-2) - avg(t-4)
        now = (raw - avg) * self.fps * self.scale  # (K,) m/s
        self.jitter = now if self.jitter is None else self.jitter + self.b * (now - self.jitter)

    def highest_under(self, cap: float) -> float:
        """The highest cut-off whose running jitter is at most ``cap`` (m/s); the lowest when none is (or before
        the jitter is known: the highest)."""
        if self.jitter is None:
            return float(self.cutoffs[0])
        ok = np.flatnonzero(self.jitter <= cap)
        return float(self.cutoffs[ok[0]] if len(ok) else self.cutoffs[-1])


class RestBones:
    """:func:`dancekit.motion.kinematics.normalize_bone_lengths` for NumPy poses, a level of the skeleton's tree
    at a time: positions ``(..., J, 3)`` → float64 positions with every bone at its rest length (the observed
    directions kept, the root where it is; a bone of zero length takes its rest offset), the skeleton's units.

    Parameters
    ----------
    skeleton : the dance's skeleton (parents, rest offsets)
    """

    def __init__(self, skeleton):
        parents = np.asarray(skeleton.parents)
        J = len(parents)
        self.roots = np.flatnonzero(parents < 0)
        self.child = np.flatnonzero(parents >= 0)  # every joint but the roots
        self.parent = parents[self.child]
        offsets = np.asarray(skeleton.offsets, np.float64)[:, :3]
        self.rest = np.linalg.norm(offsets, axis=-1)[self.child][:, None]  # (J - roots, 1)
        self.offsets = offsets[self.child]
        depth = np.full(J, -1)
        for j in skeleton.topological_order:
            depth[j] = 0 if parents[j] < 0 else depth[parents[j]] + 1
        #: per depth ≥ 1: the joints at that depth and their parents
        self.levels = [(np.flatnonzero(depth == k), parents[depth == k]) for k in range(1, int(depth.max()) + 1)]

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        x = np.asarray(positions, np.float64)
        v = x[..., self.child, :] - x[..., self.parent, :]  # (..., J - roots, 3) the observed bones
        n = np.sqrt(np.sum(v * v, axis=-1, keepdims=True))
        bones = np.empty_like(x)
        bones[..., self.child, :] = np.where(n > 1e-9, v / np.maximum(n, 1e-9) * self.rest, self.offsets)
        out = np.empty_like(x)
        out[..., self.roots, :] = x[..., self.roots, :]
        for joints, parents in self.levels:
            out[..., joints, :] = out[..., parents, :] + bones[..., joints, :]
        return out


class OnlineFootLock:
    """A causal foot lock: world positions ``(k, J, 3)`` (the skeleton's units, the floor at height 0) → the
    same with every planted foot held, frame by frame, state carried from call to call.

    A foot (ankle and the joints below it, :func:`~dancekit.motion.analysis.leg_chains`) is planted once it has
    been lower than ``height_on`` metres and slower than ``speed_on`` m/s (its mean joint's horizontal speed
    from the frame before) for ``min_contact_s``; the contact thresholds are the offline lock's
    (:func:`~dancekit.motion.footlock.foot_contacts`). From then its ankle is held, horizontally, where the
    shown ankle was (no jump: the hold starts where the foot is seen) after a glide to a stop (the step it was
    taking shrinking by :data:`LOCK_SETTLE_S`), the vertical the model's; the leg is
    solved to it (:func:`~dancekit.motion.footlock.two_bone_ik`, the hip fixed, the bones' lengths kept, the
    knee on its side) and the joints below the ankle follow it rigidly. The hold ends when the foot rises above
    ``height_off`` or moves faster than ``speed_off``, when the model's ankle is ``max_drift_m`` away from the
    held one, or when the straight leg falls short of it by more than :data:`LOCK_REACH_SLACK_M` (within that,
    the ankle goes as far toward it as the leg reaches); the foot then goes from where it was held to the model's
    over ``release_s`` (a smoothstep: it leaves at rest and arrives with the model foot's speed). Joints outside
    the legs are untouched.
    """

    def __init__(self, skeleton, *, fps: float, height_on: float = CONTACT_HEIGHT_ON_M,
                 height_off: float = CONTACT_HEIGHT_OFF_M, speed_on: float = CONTACT_SPEED_ON,
                 speed_off: float = CONTACT_SPEED_OFF, min_contact_s: float = MIN_CONTACT_S,
                 max_drift_m: float = MAX_DRIFT_M, release_s: float = LOCK_RELEASE_S):
        self.skeleton, self.fps = skeleton, float(fps)
        self.legs = leg_chains(skeleton)
        self.horiz = list(horizontal_axes(skeleton))
        self.scale = float(skeleton.unit_scale)  # metres per unit
        self.h_on, self.h_off, self.s_on, self.s_off = height_on, height_off, speed_on, speed_off
        self.min_frames = max(1, int(round(min_contact_s * self.fps)))
        self.max_drift = max_drift_m / self.scale  # skeleton units
        self.release = max(1, int(round(release_s * self.fps)))
        self.reach_slack = LOCK_REACH_SLACK_M / self.scale  # skeleton units
        n = len(self.legs)
        self.prev_centre: list[np.ndarray | None] = [None] * n  # the model's foot centre, the frame before
        self.count = [0] * n  # frames the foot has been low and slow
        self.anchor: list[np.ndarray | None] = [None] * n  # the held ankle (horizontal axes), None: free
        self.fade: list[tuple[np.ndarray, int] | None] = [None] * n  # where a foot let go was held, and its age
        self.shown_prev: list[np.ndarray | None] = [None] * n  # the ankle shown the frame before (horizontal axes)
        self.glide: list[np.ndarray | None] = [None] * n  # a new hold's remaining step a frame (it comes to rest)
        self.settle = float(np.exp(-1.0 / (LOCK_SETTLE_S * self.fps)))
        #: frames each leg was held so far
        self.held_frames = [0] * n

    def process(self, poses: np.ndarray) -> np.ndarray:
        """Poses ``(k, J, 3)`` → float64 poses ``(k, J, 3)``, the planted feet held (see the class)."""
        out = np.array(poses, np.float64)
        for k in range(len(out)):
            p = out[k]
            for i, (hip, knee, ankle, below) in enumerate(self.legs):
                foot = [ankle, *below]
                h = float(heights(p[foot], self.skeleton).min()) * self.scale
                centre = p[foot][:, self.horiz].mean(axis=0)
                prev = self.prev_centre[i]
                speed = 0.0 if prev is None else float(np.linalg.norm(centre - prev)) * self.fps * self.scale
                self.prev_centre[i] = centre
                model = p[ankle, self.horiz].copy()
                if self.anchor[i] is None:
                    self.count[i] = self.count[i] + 1 if (h <= self.h_on and speed <= self.s_on) else 0
                    offset = self._fading(i, model)
                    if self.count[i] >= self.min_frames:  # planted where it is shown, gliding to a stop
                        shown = model + offset
                        last = self.shown_prev[i]
                        self.anchor[i] = shown
                        self.glide[i] = np.zeros_like(shown) if last is None else (shown - last) * self.settle
                        self.fade[i] = None
                else:
                    self.anchor[i] = self.anchor[i] + self.glide[i]
                    self.glide[i] = self.glide[i] * self.settle
                    offset = self.anchor[i] - model
                    if h > self.h_off or speed > self.s_off or np.linalg.norm(offset) > self.max_drift:
                        self._let_go(i)
                        offset = self._fading(i, model)
                if self.anchor[i] is not None:
                    offset = self.anchor[i] - model
                target = p[ankle].copy()
                target[self.horiz] += offset
                reach = np.linalg.norm(p[knee] - p[hip]) + np.linalg.norm(p[ankle] - p[knee])
                if self.anchor[i] is not None and np.linalg.norm(target - p[hip]) > reach + self.reach_slack:
                    self._let_go(i)  # out of the leg's reach: the hold ends, the foot fades back to the model's
                    offset = self._fading(i, model)
                    target = p[ankle].copy()
                    target[self.horiz] += offset
                if self.anchor[i] is not None:
                    self.held_frames[i] += 1
                self.shown_prev[i] = model + offset
                if not np.any(offset):
                    continue
                new_knee, new_ankle = two_bone_ik(p[hip][None], p[knee][None], p[ankle][None], target[None])
                move = new_ankle[0] - p[ankle]
                p[knee], p[ankle] = new_knee[0], new_ankle[0]
                p[below] += move
        return out

    def _let_go(self, i: int) -> None:
        self.fade[i] = (self.anchor[i].copy(), 0)
        self.anchor[i] = None
        self.count[i] = 0

    def _fading(self, i: int, model: np.ndarray) -> np.ndarray:
        """The offset from the model's ankle ``model`` of a foot let go: ``(held − model) · (1 − S(age / release))``,
        S the smoothstep, so the foot leaves where it was held at rest and joins the model's foot with its speed
        (zeros once faded); its age advanced."""
        if self.fade[i] is None:
            return np.zeros(len(self.horiz))
        held, age = self.fade[i]
        age += 1
        x = min(1.0, age / self.release)
        self.fade[i] = None if x >= 1.0 else (held, age)
        return (held - model) * (1.0 - smoothstep(x))


class OnlineStages:
    """The online clean-up of one live dance (state carried from call to call).

    Parameters
    ----------
    skeleton : the dance's skeleton (root, up axis, rest bone lengths)
    fps : frames per second
    config : the :class:`LiveConfig` (``calm``, ``calm_glide_s``, ``smooth_hz``, ``floor_window_s``)
    cap : run the jitter cap's bank (the cap itself is :attr:`max_jitter`, set as the genre is read)
    """

    def __init__(self, skeleton, *, fps: float, config: LiveConfig | None = None, cap: bool = False):
        self.skeleton, self.fps = skeleton, float(fps)
        self.config = config or LiveConfig()
        c = self.config
        self.up = skeleton.up_index
        self.horiz = list(horizontal_axes(skeleton))
        self.root = skeleton.root
        self.a_smooth = 1.0 if not np.isfinite(c.smooth_hz) else 1.0 - np.exp(-2 * np.pi * c.smooth_hz / self.fps)
        self.a_glide = 1.0 - np.exp(-1.0 / (c.calm_glide_s * self.fps))
        self.a_mean = 1.0 - np.exp(-1.0 / (MEAN_POSE_S * self.fps))
        self.gain = 1.0
        self.mean_rel: np.ndarray | None = None
        self.prev_root_in: np.ndarray | None = None
        self.root_out = np.zeros(3)
        self.turner: RootPathTurner | None = None  # the floor bounds (from the first frame's root on)
        self.angle = 0.0  # the floor bounds' turn of the last frame (rad)
        self.smoothed: np.ndarray | None = None
        self.lows: deque[float] = deque(maxlen=max(1, int(round(c.floor_window_s * self.fps))))
        self.sign = up_sign(skeleton)
        self.contact: deque[float] = deque(maxlen=max(1, int(round(GROUND_WINDOW_S * self.fps)) | 1))
        self.a_contact = 1.0 - np.exp(-1.0 / (GROUND_SMOOTH_S * self.fps))
        self.ground: float | None = None  # the ground contact's smoothed offset
        names = list(skeleton.feet)
        self.feet = [skeleton.index(f) for f in names] or list(range(skeleton.num_joints))
        self.frames = 0
        self.rest_bones = RestBones(skeleton)
        top = c.smooth_hz if np.isfinite(c.smooth_hz) else self.fps / 2
        #: the jitter cap (m/s) the smoothing holds the dance under; None: none (the cut-off is ``smooth_hz``)
        self.max_jitter: float | None = None
        self.bank = JitterBank((top, *(f for f in CAP_CUTOFFS_HZ if f < top)), fps=self.fps, root=self.root,
                               unit_scale=float(skeleton.unit_scale)) if cap else None
        self.top = top
        #: the smoothing's cut-off now (Hz)
        self.cutoff = top
        self.a_glide_cut = 1.0 - np.exp(-1.0 / (CAP_GLIDE_S * self.fps))
        #: the foot lock (``config.foot_lock``), last
        self.lock = OnlineFootLock(skeleton, fps=self.fps) if c.foot_lock else None

    def process(self, poses: np.ndarray, music: np.ndarray) -> np.ndarray:
        """Poses ``(k, J, 3)`` and, per frame, whether music is playing (``(k,)`` bool or a 0-1 weight) → the
        cleaned poses ``(k, J, 3)`` float32."""
        poses = np.asarray(poses, np.float64)
        out = np.empty_like(poses)
        c = self.config
        for k, p in enumerate(poses):
            target = c.calm + (1.0 - c.calm) * float(music[k])
            self.gain += self.a_glide * (target - self.gain)
            root = p[self.root].copy()
            rel = p - root
            if self.mean_rel is None:
                self.mean_rel = rel.copy()
                self.prev_root_in = root.copy()
                self.root_out = root.copy()
                self.turner = RootPathTurner(root[self.horiz], unit_scale=float(self.skeleton.unit_scale),
                                             fps=self.fps)
            else:
                step = root - self.prev_root_in
                self.prev_root_in = root
                placed, self.angle = self.turner.step(step[self.horiz] * self.gain)
                self.root_out = self.root_out.copy()
                self.root_out[self.horiz] = placed
            self.root_out[self.up] = root[self.up]
            self.mean_rel += self.a_mean * (rel - self.mean_rel)
            rel = self.mean_rel + self.gain * (rel - self.mean_rel)
            q = rel + self.root_out
            if self.angle:  # the whole figure turned about the vertical axis through its root
                q = turn_and_move(q[None], skeleton=self.skeleton, angle=np.array([self.angle]),
                                  root=self.root_out[None, self.horiz])[0]
            if self.smoothed is None:
                self.smoothed = q.copy()
            a_smooth = self.a_smooth
            if self.bank is not None:
                self.bank.step(q)
                goal = self.top if self.max_jitter is None else self.bank.highest_under(self.max_jitter)
                self.cutoff = float(np.exp(np.log(self.cutoff) + self.a_glide_cut * (np.log(goal) - np.log(self.cutoff))))
                a_smooth = 1.0 - np.exp(-2 * np.pi * self.cutoff / self.fps) if self.cutoff < self.top else self.a_smooth
            a = a_smooth if self.gain >= 1.0 else 1.0 - (1.0 - a_smooth) ** (self.gain**2)
            self.smoothed += a * (q - self.smoothed)  # calmer: a lower cut-off too (gain² × smooth_hz)
            out[k] = self.smoothed
        out = self.rest_bones(out) if len(out) else out
        for k in range(len(out)):
            self.lows.append(float(out[k, self.feet, self.up].min()))
            out[k, :, self.up] -= np.percentile(self.lows, FLOOR_PERCENTILE)
            low = float((self.sign * out[k, :, self.up]).min())  # the lowest joint's height
            self.contact.append(low)
            m = min(self.contact)
            self.ground = m if self.ground is None else self.ground + self.a_contact * (m - self.ground)
            out[k, :, self.up] -= self.sign * min(self.ground, low)
        if self.lock is not None:
            out = self.lock.process(out)
        self.frames += len(out)
        return out.astype(np.float32)


class BeatNudge:
    """Beat alignment online (offline: the beat-synchronous time warp): the dance is played on a clock of its own
    whose rate stays within ``1 ± rate_bound`` (the offline warp's bound), in one of two ways (``mode``):

    * ``"target"``: the rate is nudged so that the model's next kinematic beat (a minimum of its joints' mean
      speed) lands on the tracker's predicted next music beat;
    * ``"pulse"``: the rate follows the beat, ``1 − rate_bound · cos(2π (t − b) / P)`` (b the predicted next
      beat, P the tracker's period): slowest on each beat and fastest between two, so that the dance's speed
      dips on the beats (its kinematic beats come to them) while its clock keeps the music's pace on average;
    * ``"pulse_moving"``: the pulse, its depth ``rate_bound`` only while the dancer moves: scaled by
      ``(s − 0.1) / 0.1`` (0 to 1), s the model's body-relative mean joint speed over the last second (m/s) and
      0.1 m/s issue 15's still second (:data:`STILL_SPEED`), so that a dancer near stillness is not made stiller.

    The dance clock never runs ahead of the newest frame the model has made and never falls more than
    ``max_lag_s`` behind it (between beats it drifts back to half of that, so it has room both ways); a pose
    between two model frames is interpolated linearly (the bone lengths are set afterwards by
    :class:`OnlineStages`). No beat predicted (before the tracker locks, in silence): rate 1.

    Parameters
    ----------
    fps : frames per second
    rate_bound : the rate stays within ``1 ± rate_bound``
    max_lag_s : how far the dance clock may fall behind the model (s)
    mode : ``"target"``, ``"pulse"`` or ``"pulse_moving"`` (:data:`dancekit.live.config.NUDGES`)
    root, unit_scale : the skeleton's root joint and metres per unit (``"pulse_moving"``'s body-relative speed)
    """

    def __init__(self, *, fps: float, rate_bound: float = 0.15, max_lag_s: float = 0.24, mode: str = "target",
                 root: int = 0, unit_scale: float = 1.0):
        if mode not in NUDGES:
            raise ParameterError(f"the beat nudge's mode must be one of {NUDGES}, got {mode!r}")
        self.mode = mode
        self.root, self.scale = int(root), float(unit_scale)
        self.moving: deque[float] = deque(maxlen=max(1, int(round(fps))))  # body-relative speeds (m/s), last 1 s
        self.fps, self.bound = float(fps), float(rate_bound)
        self.lag = max(1, int(round(max_lag_s * fps)))
        self.buf: deque[np.ndarray] = deque(maxlen=self.lag + 3)  # the newest model frames
        self.n = 0  # model frames received
        self.tau = 0.0  # the dance clock (a model frame index, fractional)
        self.speeds: deque[float] = deque(maxlen=3)
        self.kinematic: deque[int] = deque(maxlen=8)  # model frames of the recent speed minima
        self.rates: list[float] = []

    def process(self, poses: np.ndarray, next_beat_s: float | None, period_s: float | None = None) -> np.ndarray:
        """Model poses ``(k, J, 3)`` in → the poses ``(k, J, 3)`` shown on the dance clock; ``next_beat_s``: the
        tracker's predicted next beat (s of audio) or None; ``period_s``: its beat period (s; ``"pulse"``)."""
        poses = np.asarray(poses, np.float64)
        out = np.empty_like(poses)
        for j, p in enumerate(poses):
            if self.buf:
                self.speeds.append(float(np.linalg.norm(p - self.buf[-1], axis=-1).mean()))
                if self.mode == "pulse_moving":
                    step = (p - p[self.root]) - (self.buf[-1] - self.buf[-1][self.root])
                    self.moving.append(float(np.linalg.norm(step, axis=-1).mean()) * self.fps * self.scale)
                if len(self.speeds) == 3 and self.speeds[1] < self.speeds[0] and self.speeds[1] <= self.speeds[2]:
                    self.kinematic.append(self.n - 1)  # frame n - 1 was the slowest of its neighbours
            self.buf.append(p)
            t = self.n  # the newest model frame, and the output frame being made
            self.n += 1
            if t == 0:
                out[j] = p
                continue
            rate = 1.0 + 0.1 * ((t - self.lag / 2) - self.tau - 1.0)  # drift back to half the allowed lag
            if self.mode != "target":
                if next_beat_s is not None and period_s:
                    phase = (t - next_beat_s * self.fps) / (period_s * self.fps)
                    depth = self.bound
                    if self.mode == "pulse_moving":
                        depth *= min(1.0, max(0.0, float(np.mean(self.moving)) / STILL_SPEED - 1.0))
                    rate *= 1.0 - depth * np.cos(2 * np.pi * phase)
            elif next_beat_s is not None:
                pending = [k for k in self.kinematic if k > self.tau]
                due = next_beat_s * self.fps  # output frame of the next music beat
                if pending and due > t:
                    rate = (pending[0] - self.tau) / (due - t + 1.0)
            rate = min(1.0 + self.bound, max(1.0 - self.bound, rate))
            self.tau = min(float(t), max(float(t - self.lag), self.tau + rate))
            self.rates.append(rate)
            if len(self.rates) > 256:
                del self.rates[:-256]
            back = t - self.tau  # frames behind the newest
            i = int(np.floor(back))
            f = back - i
            a = self.buf[-1 - i]
            b = self.buf[-2 - i] if f > 0 and i + 1 < len(self.buf) else a
            out[j] = (1.0 - f) * a + f * b
        return out
