"""The clean-up stages in an online form (:class:`OnlineStages`): frame by frame, no lookahead.

Each stage is the causal counterpart of an offline one (:mod:`dancekit.pipelines.stages`), applied in order
to the poses ``(k, J, 3)`` (world positions, the skeleton's units) as the model makes them:

1. **calm** (offline: ``calm_motion`` of a song that is not music): every joint's offset from the root and the
   root's steps are scaled by a gain that glides (time constant ``calm_glide_s``) between 1 while music plays
   and ``calm`` in silence, speech or a dropped block, towards a slow running mean pose — the dancer calms and
   keeps its balance instead of freezing mid-step, and the music coming back brings the dance back;
2. **smoothing** (offline: a Savitzky-Golay / low-pass filter): a one-pole low-pass at ``smooth_hz`` (times
   the calm gain squared while calming: a model fed silence trembles, the calm dancer does not);
3. **floor bounds** (offline: the root path turned back beyond 4 m): the root's steps that would leave a
   disc of :data:`FLOOR_RADIUS_CM` are not taken;
4. **floor** (offline: the running floor moved to 0): the lowest joint's lowest height over the last
   ``floor_window_s`` is the floor, moved to 0;

then every bone is set back to its rest length (bone directions kept), as the offline clean-up does.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from dancekit.live.config import LiveConfig
from dancekit.motion.kinematics import normalize_bone_lengths

__all__ = ["FLOOR_RADIUS_CM", "OnlineStages"]

#: the dance floor's radius (skeleton units: cm for tang2018); the offline clean-up turns back beyond 4 m
FLOOR_RADIUS_CM = 400.0
#: time constant (s) of the running mean pose that calming pulls towards
MEAN_POSE_S = 2.0


class OnlineStages:
    """The online clean-up of one live dance (state carried from call to call).

    Parameters
    ----------
    skeleton : the dance's skeleton (root, up axis, rest bone lengths)
    fps : frames per second
    config : the :class:`LiveConfig` (``calm``, ``calm_glide_s``, ``smooth_hz``, ``floor_window_s``)
    """

    def __init__(self, skeleton, *, fps: float, config: LiveConfig | None = None):
        self.skeleton, self.fps = skeleton, float(fps)
        self.config = config or LiveConfig()
        c = self.config
        self.up = skeleton.up_index
        self.horiz = [i for i in range(3) if i != self.up]
        self.root = skeleton.root
        self.a_smooth = 1.0 if not np.isfinite(c.smooth_hz) else 1.0 - np.exp(-2 * np.pi * c.smooth_hz / self.fps)
        self.a_glide = 1.0 - np.exp(-1.0 / (c.calm_glide_s * self.fps))
        self.a_mean = 1.0 - np.exp(-1.0 / (MEAN_POSE_S * self.fps))
        self.gain = 1.0
        self.mean_rel: np.ndarray | None = None
        self.prev_root_in: np.ndarray | None = None
        self.root_out = np.zeros(3)
        self.smoothed: np.ndarray | None = None
        self.lows: deque[float] = deque(maxlen=max(1, int(round(c.floor_window_s * self.fps))))
        self.frames = 0

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
            self.mean_rel += self.a_mean * (rel - self.mean_rel)
            rel = self.mean_rel + self.gain * (rel - self.mean_rel)
            step = root - self.prev_root_in
            self.prev_root_in = root
            step[self.horiz] *= self.gain
            nxt = self.root_out + step
            nxt[self.up] = root[self.up]
            r = np.hypot(nxt[self.horiz[0]], nxt[self.horiz[1]])
            if r > FLOOR_RADIUS_CM and r > np.hypot(self.root_out[self.horiz[0]], self.root_out[self.horiz[1]]):
                nxt[self.horiz] = self.root_out[self.horiz]  # a step off the floor is not taken
            self.root_out = nxt
            q = rel + nxt
            if self.smoothed is None:
                self.smoothed = q.copy()
            a = self.a_smooth if self.gain >= 1.0 else 1.0 - (1.0 - self.a_smooth) ** (self.gain**2)
            self.smoothed += a * (q - self.smoothed)  # calmer: a lower cut-off too (gain² × smooth_hz)
            out[k] = self.smoothed
        out = np.asarray(normalize_bone_lengths(out, self.skeleton), np.float64) if len(out) else out
        for k in range(len(out)):
            self.lows.append(float(out[k, :, self.up].min()))
            out[k, :, self.up] -= min(self.lows)
        self.frames += len(out)
        return out.astype(np.float32)
