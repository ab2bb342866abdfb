"""The dance stages without SciPy (issue 13's cold start): the NumPy 1-D filters of
:mod:`dancekit.motion._filters` against ``scipy.ndimage`` on random inputs for the modes and sizes the
stages use, the beat warp's banded NumPy solver against the sparse KKT solve (``spsolve``) it replaced,
and a fresh process running the stages' functions that imports neither ``scipy.ndimage`` nor
``scipy.sparse``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from dancekit.motion import _filters as F
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


def test_the_banded_warp_solver_equals_the_sparse_kkt_solve(monkeypatch):
    rng = np.random.default_rng(0)
    solves = {"bounded": 0, "sparse": 0}
    numpy_solve = timewarp._BandedKKT.solve

    def counted(self, fixed, fixed_val):
        solves["bounded"] += bool(np.any(self.q != self.a[0]))  # a rate bound penalised in this solve
        return numpy_solve(self, fixed, fixed_val)

    def no_sparse(self, fixed, fixed_val):
        solves["sparse"] += 1
        raise AssertionError("a small warp went to spsolve")

    cases = []
    for _ in range(12):
        fps = float(rng.choice([25.0, 30.0, 60.0]))
        T = int(rng.integers(40, 2500))
        bound = float(rng.choice([0.15, 0.05]))
        cases.append(dict(pairs=_pairs(rng, T, fps, bound), n_frames=T, fps=fps, max_rate_change=bound))
    with monkeypatch.context() as m:
        m.setattr(timewarp._BandedKKT, "solve", counted)
        m.setattr(timewarp._BandedKKT, "_spsolve", no_sparse)
        ours = [timewarp.warp_rates(**kw) for kw in cases]
    assert solves["sparse"] == 0 and solves["bounded"] >= 3  # the rate bounds were active in several solves
    with monkeypatch.context() as m:
        m.setattr(timewarp, "NUMPY_KKT_MAX", 0)  # every system to spsolve: the solve before issue 13's change
        ref = [timewarp.warp_rates(**kw) for kw in cases]
    for kw, a, b in zip(cases, ours, ref, strict=True):
        assert np.isfinite(b).all()
        # to 1e-3 frame: the rate bounds are stiff penalties (BOUND_WEIGHT × the smoothness weight), whose
        # conditioning costs the two solves some digits (they differ by ~1e-4 frame on a 1600-frame song)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-3, err_msg=f"T={kw['n_frames']} fps={kw['fps']}")


def _dense(d0: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    m = np.diag(d0)
    for k, b in ((1, d1), (2, d2)):
        if len(b):
            m = m + np.diag(b, k) + np.diag(b, -k)
    return m


def test_the_banded_pieces_against_dense_linear_algebra():
    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 47, 48, 49, 97, 300):
        bands = timewarp._bands(n, 1e-3, 156.25, 6103.5)
        Q = _dense(*bands)
        d1 = np.diff(np.eye(n), axis=0)
        d2 = np.diff(np.eye(n), 2, axis=0)
        np.testing.assert_allclose(Q, 1e-3 * np.eye(n) + 156.25 * d1.T @ d1 + 6103.5 * d2.T @ d2, rtol=1e-14, atol=1e-9)
        f = np.flatnonzero(rng.random(n) < 0.7)  # isolated fixed rates too: free rows 1, 2, 3 apart
        Mf = Q[np.ix_(f, f)]
        b = timewarp._free_bands(bands, f)
        np.testing.assert_array_equal(_dense(*b), Mf)
        if len(f):
            rhs = rng.normal(size=(len(f), 3))
            np.testing.assert_allclose(timewarp._Pentadiagonal(*b).solve(rhs), np.linalg.solve(Mf, rhs),
                                       rtol=1e-6, atol=1e-9)


def test_a_large_warp_goes_to_spsolve(monkeypatch):
    calls = []
    monkeypatch.setattr(timewarp, "NUMPY_KKT_MAX", 100)
    real = timewarp._BandedKKT._spsolve
    monkeypatch.setattr(timewarp._BandedKKT, "_spsolve", lambda self, *a: calls.append(1) or real(self, *a))
    s = timewarp.warp_rates(pairs=np.array([[1.0, 1.05], [2.0, 2.0]]), n_frames=126, fps=25.0)
    assert calls and s[0] == 0 and s[-1] == pytest.approx(125, abs=1e-6)


def test_the_dance_stages_import_no_scipy_ndimage_or_sparse():
    code = """
import sys
import numpy as np
from dancekit.motion import get_skeleton
from dancekit.motion.analysis import floor_curve, kinematic_beats
from dancekit.motion.cleanup import ground_offset
from dancekit.motion.footlock import _jitter_ratio, lock_feet
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
    golden = Path(__file__).parent / "golden" / "default_model.npz"
    import os

    import dancekit

    src = str(Path(dancekit.__file__).resolve().parents[1])  # the dancekit under test, in the child too
    env = dict(os.environ, PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code, str(golden)], capture_output=True, text=True, check=True,
                         env=env)
    assert out.stdout.strip() == ""
