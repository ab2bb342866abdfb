"""The windowed-sinc FIR low-pass of the smoothing stages (issue 15: jitter without losing energy): its kernel
is scipy's ``firwin`` design, it is zero-phase (``np.convolve`` of the odd-reflected signal), a sine below
the cut-off passes and one above is removed, the chunked rows equal the one-pass filter bit for bit, and the
stage after the foot lock (:func:`dancekit.pipelines.stages.settle`) keeps bone lengths and a held foot."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dancekit.motion.filters as filters
import dancekit.motion.footlock as footlock
import dancekit.motion.jitter as jitter
from dancekit.errors import ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.filters import fir_lowpass, lowpass_kernel, lowpass_taps
from dancekit.pipelines.base import DanceResult
from dancekit.pipelines.stages import settle

FPS = 25.0
SK = get_skeleton("tang2018")


@pytest.mark.parametrize("cutoff", [2.0, 3.0, 4.0, 6.0, 8.0])
@pytest.mark.parametrize("window", ["hamming", "hann", "blackman", ("kaiser", 5.0)])
def test_kernel_is_scipys_firwin(cutoff, window):
    from scipy.signal import firwin

    n = lowpass_taps(cutoff, fps=FPS)
    assert n % 2 == 1
    np.testing.assert_allclose(lowpass_kernel(cutoff, fps=FPS, window=window),
                               firwin(n, cutoff, window=window, fs=FPS), rtol=0, atol=1e-12)
    np.testing.assert_allclose(lowpass_kernel(cutoff, fps=FPS, numtaps=41),
                               firwin(41, cutoff, window="hamming", fs=FPS), rtol=0, atol=1e-12)


def test_filter_is_convolution_with_odd_reflected_ends():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(300, 4))
    h = lowpass_kernel(3.0, fps=FPS)
    half = len(h) // 2
    ext = np.concatenate([2 * x[:1] - x[half:0:-1], x, 2 * x[-1:] - x[-2:-half - 2:-1]])
    ref = np.stack([np.convolve(ext[:, i], h, mode="valid") for i in range(4)], axis=1)
    np.testing.assert_allclose(fir_lowpass(x, h), ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fir_lowpass(x.T, h, axis=1), ref.T, rtol=0, atol=1e-12)


@pytest.mark.parametrize("cutoff", [3.0, 4.0])
def test_sine_below_passes_and_sine_above_is_removed(cutoff):
    """Known answers from the design (not from this code): a Hamming window's transition band is ~3.3 fps / N
    wide around the cut-off, its stop band below -50 dB; so a sine at a third of the cut-off passes within
    1 % and one at twice the cut-off comes out below 1 % of its amplitude (away from the ends)."""
    t = np.arange(1000) / FPS
    h = lowpass_kernel(cutoff, fps=FPS)
    inner = slice(len(h), -len(h))
    low = np.sin(2 * np.pi * cutoff / 3 * t + 0.3)
    high = np.sin(2 * np.pi * 2 * cutoff * t + 0.7)
    np.testing.assert_allclose(fir_lowpass(low, h)[inner], low[inner], atol=0.01)
    assert np.abs(fir_lowpass(high, h)[inner]).max() < 0.01
    both = fir_lowpass(low + high, h)
    np.testing.assert_allclose(both[inner], low[inner], atol=0.02)
    line = 3.0 * t - 2.0  # unit gain at 0 Hz and odd-reflected ends: a straight line is kept to the ends
    np.testing.assert_allclose(fir_lowpass(line, h), line, atol=1e-9)


def test_bad_designs_are_named_errors():
    with pytest.raises(ParameterError):
        lowpass_kernel(13.0, fps=FPS)  # above Nyquist
    with pytest.raises(ParameterError):
        lowpass_kernel(3.0, fps=FPS, numtaps=20)  # even: not zero-phase
    with pytest.raises(ParameterError):
        lowpass_kernel(3.0, fps=FPS, window="triangle")


@pytest.fixture(scope="module")
def dance() -> np.ndarray:
    rng = np.random.default_rng(3)
    rest = np.zeros((SK.num_joints, 3))
    for j in SK.topological_order:
        if SK.parents[j] >= 0:
            rest[j] = rest[SK.parents[j]] + SK.offsets[j]
    T = 700
    t = np.arange(T)[:, None, None] / FPS
    freq = rng.uniform(0.3, 2.0, size=(1, SK.num_joints, 3))
    wobble = 6.0 * np.sin(2 * np.pi * freq * t + rng.uniform(0, 6, size=freq.shape))
    travel = np.concatenate([30 * np.sin(0.2 * t), 0 * t, 20 * np.cos(0.13 * t)], axis=-1)
    return (rest[None] + wobble + travel + rng.normal(scale=1.5, size=(T, SK.num_joints, 3))).astype(np.float32)


@pytest.mark.parametrize("cutoff", [3.0, 6.0])
def test_rows_in_pieces_equal_the_whole_filter(dance, cutoff):
    h = lowpass_kernel(cutoff, fps=FPS)
    whole = fir_lowpass(dance, h)
    pieces = [filters.lowpass_rows(dance, h, a, b) for a, b in filters.chunks(len(dance), 61)]
    np.testing.assert_array_equal(np.concatenate(pieces), whole)


def test_jitter_ratio_of_the_lowpass_in_pieces(dance, monkeypatch):
    whole = jitter.jitter_ratio(fir_lowpass(dance, lowpass_kernel(3.0, fps=FPS)), SK, FPS)
    monkeypatch.setattr(filters, "CHUNK", 61)
    got = jitter.jitter_ratio(dance, SK, FPS, cutoff=3.0)
    assert got == pytest.approx(whole, rel=1e-12)
    assert got < 0.5 * jitter.jitter_ratio(dance, SK, FPS)  # the frame noise is gone


def test_lowpass_cutoff_reaches_the_target(dance):
    ratios = {c: jitter.jitter_ratio(dance, SK, FPS, cutoff=c) for c in jitter.CUTOFFS_HZ}
    assert all(ratios[a] > ratios[b] for a, b in zip(jitter.CUTOFFS_HZ[:-1], jitter.CUTOFFS_HZ[1:]))
    target = ratios[4.0] * (1 + 1e-9)  # the highest cut-off within the target is 4 Hz
    assert jitter.lowpass_cutoff(dance, skeleton=SK, fps=FPS, target=target) == 4.0
    assert jitter.lowpass_cutoff(dance, skeleton=SK, fps=FPS, target=0.0) == jitter.CUTOFFS_HZ[-1]
    assert jitter.lowpass_cutoff(fir_lowpass(dance, lowpass_kernel(2.0, fps=FPS)), skeleton=SK, fps=FPS,
                                   target=0.5) == 0.0  # smooth already: left alone


def test_settle_keeps_bones_and_filters_in_pieces(dance, monkeypatch):
    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=dance), model="m", seed=0)
    p = dance.astype(np.float64)
    out = settle(res, cutoff=3.0).motion.positions.astype(np.float64)
    for j in SK.topological_order:
        q = SK.parents[j]
        if q >= 0:
            np.testing.assert_allclose(np.linalg.norm(out[:, j] - out[:, q], axis=-1),
                                       np.linalg.norm(p[:, j] - p[:, q], axis=-1), rtol=1e-5)
    assert np.abs(out - p).max() > 1.0  # it did filter (cm); the jitter it removes: the held-feet test below
    monkeypatch.setattr(filters, "CHUNK", 97)
    np.testing.assert_array_equal(settle(res, cutoff=3.0).motion.positions, out.astype(np.float32))
    assert settle(res, cutoff=0).motion is res.motion


@pytest.mark.slow
def test_settle_keeps_held_feet_held(prepared_tang2018):
    """On the embedded model's own dances and a real one, locked: inside every hold (6 frames from its ends)
    the settled ankle stays within 1 cm of where the lock holds it. (The genre models trained with the speed
    term hold a foot for under 0.5 s in the 8-s golden clips, so a real waltz brings the long holds.)"""
    from pathlib import Path

    checked = 0
    for key in ("none_seed3", "auto_seed0", "rumba_seed1"):
        checked += _held_frames_checked(np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")[key])
    real = prepared_tang2018.motion("DANCE_W_10").to_positions()[:500]
    checked += _held_frames_checked(real)
    assert checked >= 10  # the real waltz alone has 22


def _held_frames_checked(p: np.ndarray) -> int:
    p = p.astype(np.float64)
    locked, rep = footlock.lock_feet(p, skeleton=SK, fps=FPS, return_report=True)
    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=locked.astype(np.float32)), model="m", seed=0)
    out = settle(res, cutoff=3.0).motion.positions.astype(np.float64)
    assert jitter.jitter_ratio(out, SK, FPS) < 0.8 * jitter.jitter_ratio(locked, SK, FPS)
    checked = 0
    for leg, (_hip, _knee, ankle, _below) in enumerate(footlock.leg_chains(SK)):
        for s, e in footlock._runs(rep.held[:, leg]):
            if e - s >= 12:
                inner = slice(s + 6, e - 5)
                assert np.linalg.norm(out[inner, ankle] - locked[inner, ankle], axis=-1).max() * SK.unit_scale < 0.01
                checked += 1
    return checked


def test_settle_filters_rotations_consistently(dance):
    m = Motion(skeleton=SK, fps=FPS, positions=dance[:200]).with_rotations()
    out = settle(DanceResult(motion=m, model="m", seed=0), cutoff=3.0).motion
    assert out.rotations.shape == m.rotations.shape
    r = out.rotations.astype(np.float64)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-5)
    fk = Motion(skeleton=SK, fps=FPS, rotations=out.rotations, root_translation=out.root_translation).to_positions()
    np.testing.assert_allclose(fk, out.positions, atol=1e-3)  # positions from the filtered rotations
    assert jitter.jitter_ratio(out.positions, SK, FPS) < jitter.jitter_ratio(m.to_positions(), SK, FPS)


def _ancestors(j: int) -> set[int]:
    out = set()
    while SK.parents[j] >= 0:
        j = SK.parents[j]
        out.add(j)
    return out


def test_the_settle_settings_come_from_the_checkpoint(tmp_path):
    import json
    from pathlib import Path

    import dancekit.pipelines.stages as stages
    from dancekit.errors import CheckpointError
    from dancekit.pipelines.config import read_stage_config

    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    assert read_stage_config(folder / "revolution").settle.settle_options() == {"cutoff": 3.0}
    assert read_stage_config(folder / "music2dance").settle.settle_options() == {}
    assert read_stage_config(folder / "dual").settle.settle_options() == {}
    bad = tmp_path / "m"
    bad.mkdir()
    cfg = json.loads((folder / "revolution" / "config.json").read_text())
    cfg["stages"]["settle"] = {"cutoff": 3}
    (bad / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(CheckpointError, match=f"{bad}: config.json: unknown key stages.settle.cutoff "):
        read_stage_config(bad)
    cfg["stages"]["settle"] = {"cutoff_hz": "3"}  # a string where a number goes
    (bad / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(CheckpointError, match=r"stages.settle.cutoff_hz must be a number in \[0, inf\) \(Hz\), got '3'"):
        read_stage_config(bad)


def test_finish_settles_after_the_lock_for_the_model_that_asks(monkeypatch):
    from pathlib import Path

    import dancekit.pipelines.stages as stages

    p = np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")["none_seed3"]
    folder = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
    calls = []
    real = stages.settle
    monkeypatch.setattr(stages, "settle", lambda r, **kw: calls.append(kw) or real(r, **kw))
    from dancekit.pipelines.config import read_stage_config

    for model, want in ((str(folder / "revolution"), {"cutoff": 3.0}), (str(folder / "music2dance"), {})):
        res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=model, seed=0)
        config = read_stage_config(model)
        config = dataclasses.replace(config, jitter_cap=None, lift_energy=None, reground=None)  # the lock's block only
        out = stages.finish(res, "unused.wav", config.switched(beat_sync=False))
        assert calls[-1] == want
        cleaned = stages.smooth(stages.clean_up(res), config=config.smooth, genre_stats=config.genre_stats)
        locked = stages.foot_lock(cleaned, config.foot_lock, config.genre_stats)
        same = np.array_equal(out.motion.positions, locked.motion.positions)
        assert same == (not want)  # only the model that asks is low-passed
    stages.finish(res, "unused.wav", config.switched(beat_sync=False, foot_lock=False))
    assert len(calls) == 2  # no lock: no settle


def test_smoothing_with_the_lowpass_keeps_bones_and_an_unknown_filter_is_named(dance):
    from dancekit.pipelines.stages import smooth

    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=dance), model="m", seed=0)
    out = smooth(res, kind="lowpass", target=0.0)
    assert out.notes and out.notes[-1].endswith("-Hz low-pass)")
    p, q = dance.astype(np.float64), out.motion.positions.astype(np.float64)
    for j in SK.topological_order:
        if SK.parents[j] >= 0:
            np.testing.assert_allclose(np.linalg.norm(q[:, j] - q[:, SK.parents[j]], axis=-1),
                                       np.linalg.norm(p[:, j] - p[:, SK.parents[j]], axis=-1), rtol=1e-5)
    with pytest.raises(ParameterError, match="unknown smoothing filter 'median'"):
        smooth(res, kind="median")


def _planted_share(p: np.ndarray) -> float:
    """Share of (frame, foot) pairs whose lowest foot joint is within 3 cm of the local floor (lowest point of
    the lowest joint within ±1 s) and moves slower than 0.15 m/s: issue 15's planted-foot measure."""
    from scipy.ndimage import minimum_filter1d

    assert SK.up_axis == "y"
    h = p[..., 1] * SK.unit_scale * 100.0  # (T, J) cm, height above the capture's origin
    local = minimum_filter1d(h.min(axis=1), size=2 * int(FPS) + 1, mode="nearest")
    out = []
    for side in ("left", "right"):
        foot = [SK.index(f"{side}_{j}") for j in ("ankle", "heel", "toe")]
        speed = np.linalg.norm(np.gradient(p[:, foot], axis=0), axis=-1) * FPS * SK.unit_scale
        low = h[:, foot].argmin(axis=1)
        t = np.arange(len(p))
        out.append((h[:, foot][t, low] - local <= 3.0) & (speed[t, low] < 0.15))
    return float(np.mean(out))


def test_the_jitter_cap_comes_before_the_lock_so_planted_feet_stay_planted():
    """The per-dance jitter cap of a drawn genre (issue 15) is a low-pass down to 1 Hz: after the foot lock it
    lifted the feet off the floor (this dance: planted share 0.35 → 0.15); before it, the lock plants the
    calmed dance's feet."""
    from pathlib import Path

    import dancekit.pipelines.stages as stages
    from dancekit.metrics import stability

    p = np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")["none_seed3"]
    model = str(Path(stages.__file__).resolve().parent.parent / "assets" / "models" / "revolution")
    res = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p), model=model, seed=0)
    from dancekit.pipelines.config import JitterCapConfig, read_stage_config

    config = read_stage_config(model).switched(beat_sync=False)
    plain = stages.finish(res, "unused.wav", config).motion.positions.astype(np.float64)
    config = dataclasses.replace(config, jitter_cap=JitterCapConfig(max_jitter=1e-9))
    capped = stages.finish(res, "unused.wav", config).motion.positions.astype(np.float64)

    def jitter(x):
        return stability.jitter(x, fps=FPS, skeleton=SK)["speed_residual"]

    assert jitter(capped) < 0.8 * jitter(plain)  # the cap (the lowest cut-off) did filter
    assert _planted_share(plain) > 0.1
    assert _planted_share(capped) >= 0.8 * _planted_share(plain)
