"""The dance floor's turns (:func:`dancekit.motion.cleanup.root_path_turns`) against the rule written as a loop over
frames on NumPy arrays: the same numbers, bit for bit, on paths that reach the turning radius and the hard one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dancekit.motion import get_skeleton
from dancekit.motion.cleanup import root_path_turns

FPS = 25.0
SK = get_skeleton("tang2018")


def _turns_frame_by_frame(root: np.ndarray, *, R: float, H: float, turn_rate: float, alpha: float):
    """The rule (skeleton units): beyond R of the start, while the step leads outward, the heading turns toward
    the start at ``turn_rate`` rad/s through a first-order lag ``alpha``; a step crossing H loses its outward
    part."""
    def rotate(v, angle):
        c, s = math.cos(angle), math.sin(angle)
        return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])

    start, steps = root[0].copy(), np.diff(root, axis=0)
    new, angle = np.empty_like(root), np.zeros(len(root))
    new[0] = start
    theta = omega = 0.0
    for t in range(1, len(root)):
        c = new[t - 1] - start
        step = rotate(steps[t - 1], theta)
        target = 0.0
        if float(np.hypot(*c)) > R and float(c @ step) > 0:
            target = turn_rate if c[0] * step[1] - c[1] * step[0] > 0 else -turn_rate
        omega += alpha * (target - omega)
        theta += omega / FPS
        step = rotate(steps[t - 1], theta)
        nxt = new[t - 1] + step
        if np.hypot(*(nxt - start)) > H:
            out = (nxt - start) / np.hypot(*(nxt - start))
            step = step - max(0.0, float(step @ out)) * out
            nxt = new[t - 1] + step
        new[t], angle[t] = nxt, theta
    return angle, new


@pytest.mark.parametrize("radius_m, hard_m", [(4.0, 12.0), (0.5, 1.0)])
def test_root_path_turns_are_the_frame_by_frame_rule_bit_for_bit(radius_m, hard_m):
    rng = np.random.default_rng(5)
    T = 600
    p = np.zeros((T, SK.num_joints, 3))
    p[:, :, 1] = 90.0
    drift = np.cumsum(rng.normal([1.5, 0.0, 0.8], [3.0, 0.0, 3.0], (T, 3)), axis=0)  # cm per frame
    p += drift[:, None, :]
    angle, root = root_path_turns(p, skeleton=SK, fps=FPS, radius_m=radius_m, hard_radius_m=hard_m)
    want_angle, want_root = _turns_frame_by_frame(p[:, SK.root][:, [0, 2]], R=radius_m * 100, H=hard_m * 100,
                                                  turn_rate=0.5, alpha=1.0 - math.exp(-1.0 / (0.5 * FPS)))
    assert np.array_equal(angle, want_angle) and np.array_equal(root, want_root)
    assert np.abs(angle).max() > 0.1  # it turned
    if hard_m < 2:
        assert np.hypot(*(root - root[0]).T).max() > 0.99 * hard_m * 100  # and met the hard radius
