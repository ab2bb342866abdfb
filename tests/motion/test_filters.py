"""The dance stages without SciPy (issue 13's cold start): the NumPy 1-D filters of
:mod:`dancekit.motion.filters` against ``scipy.ndimage`` on random inputs for the modes and sizes the
stages use, the beat warp's banded solve against a dense one, and a fresh process running the stages'
functions that imports neither ``scipy.ndimage`` nor ``scipy.sparse``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from dancekit.motion import filters as F
from dancekit.motion import timewarp

LENGTHS = [1, 2, 3, 5, 64, 1537, 20_000]  # 20 000 > PIECE: the rank filters' pieces are joined
SIZES = [1, 2, 3, 4, 5, 7, 25, 75, 76, 151]  # odd windows of the stages, even ones of floor_curve's fps


@pytest.fixture(params=LENGTHS)
def x(request) -> np.ndarray:
    rng = np.random.default_rng(request.param)
    x = rng.normal(size=request.param) * 30.0 + 5.0
    if request.param > 10:
        x[::7] = x[3]  # ties, as a planted foot's constant height has
    return x


def test_rank_filters_are_bit_equal_to_scipy(x):
    for size in SIZES:
        np.testing.assert_array_equal(F.minimum_filter1d(x, size), ndimage.minimum_filter1d(x, size, mode="nearest"))
        np.testing.assert_array_equal(F.maximum_filter1d(x, size), ndimage.maximum_filter1d(x, size, mode="nearest"))
        for q in (0.0, 5.0, 37.5, 50.0, -5.0, 99.0):
            np.testing.assert_array_equal(F.percentile_filter1d(x, q, size),
                                          ndimage.percentile_filter(x, q, size=size, mode="nearest"))


def test_linear_filters_equal_scipy(x):
    for size in SIZES:
        np.testing.assert_allclose(F.uniform_filter1d(x, size), ndimage.uniform_filter1d(x, size, mode="nearest"),
                                   rtol=0, atol=1e-12 * max(1.0, np.abs(x).max()))
    for sigma in (0.5, 1.25, 2.5, 3.0, 12.5, 40.0):
        np.testing.assert_allclose(F.gaussian_filter1d(x, sigma),
                                   ndimage.gaussian_filter1d(x, sigma, mode="nearest"),
                                   rtol=0, atol=1e-12 * max(1.0, np.abs(x).max()))


def test_filters_along_an_axis_of_a_dance():
    p = np.random.default_rng(5).normal(size=(300, 23, 3)) * 50.0
    for axis in (0, 1):
        np.testing.assert_allclose(F.uniform_filter1d(p, 5, axis=axis),
                                   ndimage.uniform_filter1d(p, 5, axis=axis, mode="nearest"), rtol=0, atol=1e-11)
        np.testing.assert_allclose(F.gaussian_filter1d(p, 2.5, axis=axis),
                                   ndimage.gaussian_filter1d(p, 2.5, axis=axis, mode="nearest"), rtol=0, atol=1e-11)
    assert F.gaussian_filter1d(p, 2.5, axis=0).shape == p.shape


def test_a_window_the_percentile_does_not_fit_is_a_named_error():
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError):
        F.percentile_filter1d(np.zeros(5), 100.0, 4)
    with pytest.raises(ParameterError):
        F.minimum_filter1d(np.zeros(5), 0)


def _pairs(rng, T: int, fps: float, bound: float) -> np.ndarray:
    """Matched beats as :func:`match_beats` gives them: increasing, every pair (and the anchors) within a
    mean rate of ``1 ± 0.8 bound`` of the previous one."""
    D = (T - 1) / fps
    m = np.arange(rng.uniform(0.3, 0.7), D - 0.3, rng.uniform(0.35, 0.9))
    m = m[rng.random(len(m)) < 0.6]
    chain = [(0.0, 0.0)]
    for mi in m:
        dm = mi - chain[-1][0]
        k = chain[-1][1] + dm * (1 + rng.uniform(-0.8, 0.8) * bound)
        if abs((D - k) / (D - mi) - 1) < 0.8 * bound:
            chain.append((mi, k))
    return np.asarray(chain[1:]).reshape(-1, 2)


def _dense_source(knots: np.ndarray, w_pair: float, n: int, a: tuple) -> np.ndarray:
    """The unbounded programme of :func:`timewarp._bounded_source` solved densely: explicit difference
    matrices of the source frames, the pairs' interpolation rows, ``s[0] = 0`` and ``s[n] = n`` held, the
    normal equations by ``np.linalg.solve``."""
    D1 = np.diff(np.eye(n + 1), axis=0)  # (n, n + 1): the rates
    D2, D3 = np.diff(D1, axis=0), np.diff(D1, 2, axis=0)
    x, y = knots[1:-1, 0], knots[1:-1, 1]
    P = np.zeros((len(x), n + 1))
    i0 = np.clip(np.floor(x).astype(int), 0, n - 1)
    P[np.arange(len(x)), i0] = 1 - (x - i0)
    P[np.arange(len(x)), i0 + 1] = x - i0
    H = a[0] * D1.T @ D1 + a[1] * D2.T @ D2 + a[2] * D3.T @ D3 + w_pair * P.T @ P
    g = a[0] * D1.T @ np.ones(n) + w_pair * P.T @ y
    g -= H[:, n] * n  # s[n] = n held (s[0] = 0 adds nothing)
    s = np.zeros(n + 1)
    s[n] = n
    s[1:n] = np.linalg.solve(H[1:n, 1:n], g[1:n])
    return s


def test_the_banded_warp_solver_equals_a_dense_solve():
    rng = np.random.default_rng(0)
    for _ in range(8):
        fps = float(rng.choice([25.0, 30.0, 60.0]))
        T = int(rng.integers(5, 400))
        n = T - 1
        pairs = _pairs(rng, T, fps, 0.15) * fps
        knots = np.concatenate([[[0.0, 0.0]], pairs, [[n, n]]])
        L = max(1.0, float(rng.uniform(0.1, 0.8)) * fps)
        a = (1e-3, L**2, L**4 / 4)
        w = float(rng.choice([1.0, 1e3]))
        # a wide box and no step bound: nothing is penalised, one banded solve against the dense one
        rates = timewarp._bounded_source(knots, w, n, a, -10.0, 10.0, np.inf, 1e6)
        ref = _dense_source(knots, w, n, a)
        np.testing.assert_allclose(np.concatenate([[0.0], np.cumsum(rates)]), ref, rtol=0, atol=1e-6 * n,
                                   err_msg=f"T={T} fps={fps}")


def test_the_dance_stages_import_no_scipy_ndimage_or_sparse():
    code = """
import sys
import numpy as np
from dancekit.motion import get_skeleton
from dancekit.motion.analysis import floor_curve, kinematic_beats
from dancekit.motion.cleanup import ground_offset
from dancekit.motion.footlock import lock_feet
from dancekit.motion.jitter import jitter_ratio as _jitter_ratio
from dancekit.motion.timewarp import beat_warp
sk = get_skeleton("tang2018")
p = np.load(sys.argv[1])["none_seed3"].astype(np.float64)  # a real dance of the embedded model (8 s)
floor_curve(p, sk, fps=25.0)
ground_offset(p, skeleton=sk, fps=25.0)
kinematic_beats(p, fps=25.0)
_jitter_ratio(p, sk, 25.0)
lock_feet(p, skeleton=sk, fps=25.0)
beat_warp(p, music_beats=np.arange(0.5, 8.0, 60 / 112), fps=25.0)
bad = sorted(m for m in sys.modules if m.startswith(("scipy.ndimage", "scipy.sparse")))
print(",".join(bad))
"""
    golden = Path(__file__).parents[1] / "golden" / "default_model.npz"
    import os

    import dancekit

    src = str(Path(dancekit.__file__).resolve().parents[1])  # the dancekit under test, in the child too
    env = dict(os.environ, PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code, str(golden)], capture_output=True, text=True, check=True,
                         env=env, timeout=120)
    assert out.stdout.strip() == ""
