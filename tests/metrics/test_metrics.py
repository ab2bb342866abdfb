"""Known-answer tests of dancekit.metrics on synthetic dances (and a few on real tang2018 dances)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dancekit.errors import ParameterError
from dancekit.metrics import (
    beat_align_score,
    beat_coverage,
    beat_hit_rate,
    beat_l1,
    bone_length_variation,
    chroma_l1,
    estimate_key,
    fid_diversity,
    foot_skating,
    frechet_distance,
    frechet_distance_from_stats,
    freeze_score,
    geometric_features,
    ground_penetration,
    jitter,
    kinematic_beats,
    kinetic_features,
    mean_joint_distance,
    normalize_features,
    notes_accuracy,
    pfc,
    smoothed_energy,
    stillness_share,
    transpose_to_c,
    windowed_fid,
)
from dancekit.metrics.fid import GEOMETRIC_FEATURE_NAMES, average_pairwise_distance, body_dimensions, segments
from dancekit.motion import get_skeleton

SK = get_skeleton("tang2018")  # cm, y up


def rest_pose(skeleton=SK) -> np.ndarray:
    """Rest joint positions (J, 3) from the skeleton offsets, toes at height 0."""
    rest = np.zeros((skeleton.num_joints, 3))
    for j in skeleton.topological_order:
        p = skeleton.parents[j]
        rest[j] = skeleton.offsets[j] + (rest[p] if p >= 0 else 0.0)
    feet = [skeleton.index(f) for f in skeleton.feet]
    rest[:, 1] -= rest[feet, 1].min()
    return rest


def frozen(T: int = 250) -> np.ndarray:
    return np.repeat(rest_pose()[None], T, axis=0)


def moving(T: int = 250, fps: float = 25.0, seed: int = 0) -> np.ndarray:
    """Every joint oscillates (body-relative speeds of tens of cm/s) and the body travels."""
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None] / fps
    J = SK.num_joints
    amp = rng.uniform(5.0, 15.0, size=(1, J, 3))  # cm
    freq = rng.uniform(0.5, 2.0, size=(1, J, 3))  # Hz
    phase = rng.uniform(0, 2 * np.pi, size=(1, J, 3))
    p = frozen(T) + amp * np.sin(2 * np.pi * freq * t + phase)
    p[..., 0] += 20.0 * t[..., 0]  # travel 20 cm/s along x
    return p


# ------------------------------------------------------------------------------------ Fréchet


def test_frechet_distance_of_a_set_against_itself_is_zero(rng):
    x = rng.normal(size=(200, 8)) @ rng.normal(size=(8, 8))
    assert frechet_distance(x, x) == pytest.approx(0.0, abs=1e-6)


def test_frechet_distance_of_a_singular_set_against_itself_is_zero(rng):
    x = rng.normal(size=(10, 32))  # fewer samples than dimensions: rank-deficient covariance
    assert frechet_distance(x, x) == pytest.approx(0.0, abs=1e-6)


def _frechet_oracle(mu1, s1, mu2, s2) -> float:
    """Closed-form d² = |mu1 - mu2|² + tr(S1 + S2 - 2 (S1 S2)^½), with tr (S1 S2)^½ = tr (S1^½ S2 S1^½)^½
    (similar matrices): square roots of symmetric PSD matrices only, by eigendecomposition in float64."""

    def psd_sqrt(a):
        w, v = np.linalg.eigh((a + a.T) / 2)
        return (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T

    h = psd_sqrt(np.asarray(s1, np.float64))
    cross = np.trace(psd_sqrt(h @ s2 @ h))
    diff = np.asarray(mu1, np.float64) - mu2
    return float(diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * cross)


def test_frechet_distance_known_answers(rng):
    x = rng.normal(size=(500, 3))
    assert frechet_distance(x, x + [3.0, 0.0, 4.0]) == pytest.approx(25.0, rel=1e-9)  # same covariance
    d = frechet_distance_from_stats(np.zeros(2), np.diag([1.0, 4.0]), np.zeros(2), np.diag([4.0, 1.0]))
    assert d == pytest.approx(2.0, abs=1e-9)  # 5 + 5 - 2 * (2 + 2)


def test_frechet_distance_unequal_covariances_known_answers(rng):
    # diagonal, by hand: |(1, 2)|² + (1 + 9) + (4 + 16) - 2 (sqrt(1 * 4) + sqrt(9 * 16)) = 5 + 30 - 28 = 7
    d = frechet_distance_from_stats(np.array([1.0, 2.0]), np.diag([1.0, 9.0]), np.zeros(2), np.diag([4.0, 16.0]))
    assert d == pytest.approx(7.0, abs=1e-9)
    # one Gaussian a scaled copy of the other: S2 = 4 S1, so d² = tr S1 + 4 tr S1 - 2 tr(2 S1) = tr S1 = 6
    s1 = np.array([[2.0, 0.5, 0.0], [0.5, 1.0, 0.3], [0.0, 0.3, 3.0]])
    assert frechet_distance_from_stats(np.zeros(3), s1, np.zeros(3), 4.0 * s1) == pytest.approx(6.0, rel=1e-9)
    # general non-commuting covariances of different traces: the closed form through symmetric square roots
    a, b = rng.normal(size=(4, 4)), rng.normal(size=(4, 6))
    s1, s2 = a @ a.T + 0.1 * np.eye(4), b @ b.T
    mu1, mu2 = rng.normal(size=4), rng.normal(size=4)
    assert abs(np.trace(s1) - np.trace(s2)) > 1.0 and not np.allclose(s1 @ s2, s2 @ s1)
    assert frechet_distance_from_stats(mu1, s1, mu2, s2) == pytest.approx(_frechet_oracle(mu1, s1, mu2, s2), rel=1e-9)
    # from samples: y = x L^T + m has exactly the covariance L S_x L^T (the sample statistics are what is compared)
    x = rng.normal(size=(300, 4))
    y = x @ rng.normal(size=(4, 4)).T + [1.0, -2.0, 0.5, 0.0]
    expected = _frechet_oracle(x.mean(0), np.cov(x, rowvar=False), y.mean(0), np.cov(y, rowvar=False))
    assert expected > 1.0
    assert frechet_distance(x, y) == pytest.approx(expected, rel=1e-9)
    assert frechet_distance(y, x) == pytest.approx(expected, rel=1e-9)


def test_frechet_distance_reports_its_sqrtm_policy(rng):
    # (1) a singular covariance: S1 = a a^T with a = (2, 1, -1) (rank 1). S1 S2 = a (S2 a)^T has one non-zero
    # eigenvalue a^T S2 a = 32, so tr (S1 S2)^½ = sqrt(32) and, with |mu1 - mu2|² = 3,
    # d² = 3 + tr S1 + tr S2 - 2 sqrt(32) = 3 + 6 + 18 - 8 sqrt(2). Whether scipy's sqrtm of this singular
    # product passes the check depends on the BLAS kernel of the machine, so this asserts the result and the
    # documented policy for whichever branch was taken, never which one.
    a = np.array([2.0, 1.0, -1.0])
    s1 = np.outer(a, a)
    s2 = np.array([[8.0, -2.0, -2.0], [-2.0, 5.0, 5.0], [-2.0, 5.0, 5.0]])
    exact = 27.0 - 8.0 * math.sqrt(2.0)
    assert _frechet_oracle(np.zeros(3), s1, np.ones(3), s2) == pytest.approx(exact, abs=1e-6)  # sqrt of rounding
    value, info = frechet_distance_from_stats(np.zeros(3), s1, np.ones(3), s2, return_info=True)
    # the policy's offset, eps * (mean variance) = 1e-6 * (6 + 18) / 6, bounds the error either way
    assert abs(value - exact) < 10 * math.sqrt(4e-6)
    if info["retried"]:
        o, eye = info["offset"], np.eye(3)
        assert o == pytest.approx(4e-6, rel=1e-12) and info["max_imag"] <= 1e-3 * 12.0
        assert value == pytest.approx(
            _frechet_oracle(np.zeros(3), s1 + o * eye, np.ones(3), s2 + o * eye) - 6 * o, abs=1e-9)
    else:
        assert info["offset"] == 0.0
    value_fine = frechet_distance_from_stats(np.zeros(3), s1, np.ones(3), s2, eps=1e-12)
    assert value_fine == pytest.approx(exact, abs=1e-4)
    # (2) fewer samples than dimensions (rank-deficient covariances): whatever sqrtm returns, the value is the
    # closed form and any imaginary part kept is below the tolerance
    x = rng.normal(size=(5, 12))
    y = rng.normal(size=(5, 12)) + 1.0
    value, info = frechet_distance(x, y, return_info=True)
    sx, sy = np.cov(x, rowvar=False), np.cov(y, rowvar=False)
    assert value == pytest.approx(_frechet_oracle(x.mean(0), sx, y.mean(0), sy), rel=1e-5)
    assert info["max_imag"] <= 1e-3 * max(1.0, np.abs(sx @ sy).max())
    # (3) imag_tol=0 rejects any imaginary part: the value stays the closed form
    value0 = frechet_distance(x, y, imag_tol=0.0)
    assert value0 == pytest.approx(value, rel=1e-4)


def test_frechet_distance_retry_policy_is_the_documented_one(monkeypatch):
    # The retry branch forced, independently of the machine's BLAS: a sqrtm that fails (NaN) on its first call.
    # The policy then adds eps * (mean variance) * I to both covariances and reports it.
    import dancekit.metrics.fid as fid

    real_sqrtm, calls = fid.linalg.sqrtm, []

    def flaky_sqrtm(m, *args, **kwargs):
        calls.append(np.array(m))
        return np.full_like(m, np.nan) if len(calls) == 1 else real_sqrtm(m, *args, **kwargs)

    monkeypatch.setattr(fid.linalg, "sqrtm", flaky_sqrtm)
    s1 = np.diag([4.0, 1.0, 1.0])
    s2 = np.diag([1.0, 9.0, 4.0])
    value, info = frechet_distance_from_stats(np.zeros(3), s1, np.zeros(3), s2, eps=1e-3, return_info=True)
    offset = 1e-3 * (6.0 + 14.0) / 6.0
    assert info["retried"] is True and info["offset"] == pytest.approx(offset, rel=1e-12) and len(calls) == 2
    np.testing.assert_allclose(calls[1], (s1 + offset * np.eye(3)) @ (s2 + offset * np.eye(3)), rtol=1e-12)
    # diagonal case, by hand: sum over i of (sqrt(a_i + o) - sqrt(b_i + o))², less nothing else (traces cancel
    # the 2 D o the offsets add: d² = tr S1 + tr S2 - 2 tr((S1+oI)(S2+oI))^½)
    a, b = np.array([4.0, 1.0, 1.0]), np.array([1.0, 9.0, 4.0])
    expected = a.sum() + b.sum() - 2 * np.sqrt((a + offset) * (b + offset)).sum()
    assert value == pytest.approx(expected, rel=1e-9)
    # and with a working sqrtm no offset is added: (2-1)² + (1-3)² + (1-2)² = 6
    monkeypatch.setattr(fid.linalg, "sqrtm", real_sqrtm)
    value, info = frechet_distance_from_stats(np.zeros(3), s1, np.zeros(3), s2, return_info=True)
    assert info["retried"] is False and value == pytest.approx(6.0, rel=1e-9)


def test_frechet_distance_rejects_bad_input(rng):
    with pytest.raises(ParameterError, match="at least 2 samples"):
        frechet_distance(rng.normal(size=(1, 3)), rng.normal(size=(5, 3)))
    with pytest.raises(ParameterError, match="same D"):
        frechet_distance(rng.normal(size=(4, 3)), rng.normal(size=(5, 2)))


# ------------------------------------------------------------------------------------ kinetic


def test_kinetic_features_constant_velocity_known_answer():
    fps, T = 30.0, 60
    t = np.arange(T)[:, None, None] / fps
    p = frozen(T) + t * np.array([100.0, 50.0, 0.0])  # cm/s: 1 m/s along x, 0.5 m/s up
    k = kinetic_features(p, fps=fps, skeleton=SK).reshape(-1, 3)
    assert k.shape == (SK.num_joints, 3)
    np.testing.assert_allclose(k[:, 0], 1.0, rtol=1e-9)  # horizontal KE, m²/s²
    np.testing.assert_allclose(k[:, 1], 0.25, rtol=1e-9)  # vertical KE
    np.testing.assert_allclose(k[:, 2], 0.0, atol=1e-6)  # no acceleration


def test_kinetic_features_constant_acceleration_known_answer():
    fps, T = 25.0, 50
    t = np.arange(T)[:, None, None] / fps
    p = frozen(T) + 0.5 * t**2 * np.array([0.0, 0.0, 300.0])  # 3 m/s² along z
    ee = kinetic_features(p, fps=fps, skeleton=SK).reshape(-1, 3)[:, 2]
    np.testing.assert_allclose(ee, 3.0, rtol=1e-6)


def test_kinetic_features_do_not_depend_on_units():
    p = moving()
    sk_m = SK.replace(units="m")
    np.testing.assert_allclose(
        kinetic_features(p, fps=25, skeleton=SK), kinetic_features(p / 100.0, fps=25, skeleton=sk_m), rtol=1e-9
    )


def test_frozen_dance_has_zero_kinetic_energy():
    np.testing.assert_allclose(kinetic_features(frozen(), fps=25, skeleton=SK), 0.0, atol=1e-9)


def test_bug_compatible_flag_changes_only_the_energy_expenditure():
    p = moving()
    good = kinetic_features(p, fps=25, skeleton=SK).reshape(-1, 3)
    bug = kinetic_features(p, fps=25, skeleton=SK, bug_compatible=True).reshape(-1, 3)
    np.testing.assert_allclose(good[:, :2], bug[:, :2])
    assert not np.allclose(good[:, 2], bug[:, 2])
    # the reference's v1 = p[m] - p[m-1] / dt: for a frozen dance away from the origin it is not 0
    assert kinetic_features(frozen(), fps=25, skeleton=SK, bug_compatible=True).reshape(-1, 3)[:, 2].max() > 1.0


def test_kinetic_features_reject_bad_input():
    with pytest.raises(ParameterError, match="fps"):
        kinetic_features(moving(), fps=0, skeleton=SK)
    with pytest.raises(ParameterError, match="joints"):
        kinetic_features(np.zeros((10, 5, 3)), fps=25, skeleton=SK)
    with pytest.raises(ParameterError, match="at least 3"):
        kinetic_features(frozen(2), fps=25, skeleton=SK)


# ---------------------------------------------------------------------------------- geometric


def test_geometric_features_shape_and_range():
    g = geometric_features(moving(), fps=25, skeleton=SK)
    assert g.shape == (32,) == (len(GEOMETRIC_FEATURE_NAMES),)
    assert (g >= 0).all() and (g <= 1).all()


def test_geometric_root_fast_threshold_and_bug_compatible_frame_time():
    hl = body_dimensions(SK)["hl"]  # metres
    assert hl == pytest.approx(np.linalg.norm(SK.offsets[SK.index("left_elbow")]) / 100.0)
    i = GEOMETRIC_FEATURE_NAMES.index("root_fast")
    fps, T = 25.0, 50
    t = np.arange(T)[:, None, None] / fps

    def glide(speed_ms: float) -> np.ndarray:
        return frozen(T) + t * np.array([speed_ms * 100.0, 0.0, 0.0])

    threshold = 2.3 * hl  # m/s
    assert geometric_features(glide(1.5 * threshold), fps=fps, skeleton=SK)[i] == 1.0
    assert geometric_features(glide(0.5 * threshold), fps=fps, skeleton=SK)[i] == 0.0
    # the reference divides by a fixed 1/120 s: at 25 fps every speed looks 4.8x faster
    assert geometric_features(glide(0.5 * threshold), fps=fps, skeleton=SK, bug_compatible=True)[i] == 1.0


def test_geometric_hand_above_neck():
    i = GEOMETRIC_FEATURE_NAMES.index("r_hand_above_neck")
    p = frozen(20)
    assert geometric_features(p, fps=25, skeleton=SK)[i] == 0.0
    p[:, SK.index("right_wrist"), 1] = p[:, SK.index("right_shoulder"), 1] + 40.0  # hand 40 cm above the shoulders
    assert geometric_features(p, fps=25, skeleton=SK)[i] == 1.0


def test_fid_of_frozen_dances_far_exceeds_real_dances(tang2018_dir):
    from dancekit.motion.formats import read_tang2018

    names = ["DANCE_W_1", "DANCE_W_4", "DANCE_W_5", "DANCE_R_2", "DANCE_C_2", "DANCE_W_6", "DANCE_W_7", "DANCE_R_3"]
    real = [read_tang2018(tang2018_dir / n)[0].to_positions() for n in names]
    ref, held_out = real[:6], real[6:]
    frozen_set = [np.repeat(d.mean(axis=0, keepdims=True), len(d), axis=0) for d in held_out]
    kw = dict(fps=25.0, skeleton=SK, kind="kinetic", segment_seconds=10.0)
    fid_real = fid_diversity(held_out, ref, **kw)["fid"]
    fid_frozen = fid_diversity(frozen_set, ref, **kw)["fid"]
    assert fid_frozen > 5 * fid_real
    np.testing.assert_allclose(kinetic_features(frozen_set[0], fps=25, skeleton=SK), 0.0, atol=1e-9)
    # the same set against itself
    assert fid_diversity(ref, ref, **kw)["fid"] == pytest.approx(0.0, abs=1e-6)


def test_normalize_features_drops_constant_reference_columns(rng):
    ref = np.c_[rng.normal(size=(20, 2)), np.ones(20)]
    other = rng.normal(size=(5, 3))
    ref_z, other_z, keep = normalize_features(ref, other)
    assert keep.tolist() == [True, True, False]
    assert ref_z.shape == (20, 2) and other_z.shape == (5, 2)
    np.testing.assert_allclose(ref_z.mean(0), 0.0, atol=1e-12)
    np.testing.assert_allclose(ref_z.std(0), 1.0)


def test_average_pairwise_distance_known_answer():
    assert average_pairwise_distance(np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 0.0]])) == pytest.approx(10.0 / 3)


def test_segments_cut_whole_seconds():
    segs = segments(np.zeros((260, 2, 3)), fps=25, seconds=4.0)
    assert [len(s) for s in segs] == [100, 100]
    assert len(segments(np.zeros((50, 2, 3)), fps=25, seconds=4.0)[0]) == 50


# ----------------------------------------------------------------------------------- beats


def beat_dance(fps: float, *, period: float = 0.5, t0: float = 0.25, duration: float = 10.0) -> np.ndarray:
    """The body travels along x with speed 1 - cos(2π (t - t0) / period): minima exactly at t0 + k·period."""
    t = np.arange(int(round(duration * fps))) / fps
    x = (t - t0) - period / (2 * np.pi) * np.sin(2 * np.pi * (t - t0) / period)  # metres
    return frozen(len(t)) + (100.0 * x)[:, None, None] * np.array([1.0, 0.0, 0.0])


@pytest.mark.parametrize("fps", [25.0, 60.0])
def test_speed_minima_on_the_beats_align(fps):
    music = 0.25 + 0.5 * np.arange(20)
    p = beat_dance(fps)
    k = kinematic_beats(p, fps=fps, skeleton=SK)
    duration = (len(p) - 1) / fps
    assert beat_coverage(k, music, duration=duration) == pytest.approx(1.0, abs=0.06)
    assert beat_align_score(k, music, sigma=0.05, convention="bailando", duration=duration) > 0.9
    assert beat_align_score(k, music, sigma=0.05, convention="aist", duration=duration) > 0.9
    assert beat_hit_rate(k, music, tolerance=0.1, duration=duration) == 1.0
    # half a beat off: both drop sharply
    off = music + 0.25
    assert beat_align_score(k, off, sigma=0.05, duration=duration) < 0.05
    assert beat_hit_rate(k, off, tolerance=0.1, duration=duration) < 0.05


def test_beat_align_score_known_answer():
    # one music beat 0.05 s from the nearest kinematic beat: exp(-1/2)
    assert beat_align_score([1.0, 3.0], [1.05], sigma=0.05) == pytest.approx(np.exp(-0.5))
    assert beat_align_score([1.0, 3.0], [1.05], sigma=0.05, convention="aist") == pytest.approx(
        (np.exp(-0.5) + np.exp(-(1.95**2) / 0.005)) / 2
    )
    assert np.isnan(beat_align_score([], [], sigma=0.05))
    with pytest.raises(ParameterError, match="convention"):
        beat_align_score([1.0], [1.0], convention="other")


# ----------------------------------------------------------------------------------- physics


def test_foot_sliding_on_the_floor_raises_the_skating_ratio():
    fps, T = 25.0, 100
    planted = frozen(T)
    planted[:, SK.index("left_wrist"), 0] += 10 * np.sin(np.arange(T) / 5)  # only an arm moves
    t = np.arange(T)[:, None, None] / fps
    sliding = frozen(T) + t * np.array([50.0, 0.0, 0.0])  # the whole body glides at 0.5 m/s, feet on the floor
    a = foot_skating(planted, fps=fps, skeleton=SK)
    b = foot_skating(sliding, fps=fps, skeleton=SK)
    assert a["ratio"] == 0.0 and a["contact_share"] > 0
    assert b["ratio"] == 1.0 and b["slide_speed_mean"] == pytest.approx(0.5)
    lifted = sliding + np.array([0.0, 30.0, 0.0])  # 30 cm above a fixed floor: no contact at all
    assert np.isnan(foot_skating(lifted, fps=fps, skeleton=SK, floor=0.0)["ratio"])


def test_pfc_is_zero_without_root_acceleration_or_with_planted_feet():
    assert pfc(frozen(), fps=25, skeleton=SK) == 0.0
    p = moving()
    assert pfc(p, fps=25, skeleton=SK) > 0.0


def test_bone_length_variation_and_ground_penetration():
    assert bone_length_variation(moving(), skeleton=SK)["mean"] > 0.01
    rigid = frozen() + np.arange(250)[:, None, None] * np.array([1.0, 0.0, 0.0])
    assert bone_length_variation(rigid, skeleton=SK)["mean"] == pytest.approx(0.0, abs=1e-12)
    sunk = frozen() - np.array([0.0, 5.0, 0.0])  # 5 cm below the floor
    g = ground_penetration(sunk, skeleton=SK)
    assert g["mean_depth"] == pytest.approx(0.05) and g["frame_share"] == 1.0
    assert ground_penetration(frozen(), skeleton=SK)["mean_depth"] == 0.0


# --------------------------------------------------------------------------------- stability


def test_stillness_share_frozen_and_moving():
    assert stillness_share(frozen(), fps=25, skeleton=SK) == 1.0
    assert stillness_share(moving(), fps=25, skeleton=SK) == 0.0
    # a body gliding across the floor in a frozen pose is still (body-relative speed)
    t = np.arange(250)[:, None, None] / 25
    assert stillness_share(frozen() + t * np.array([100.0, 0, 0]), fps=25, skeleton=SK) == 1.0


def test_freeze_score():
    p = moving(T=25 * 30)
    assert freeze_score(p, fps=25, skeleton=SK) == pytest.approx(1.0, rel=0.3)
    stops = p.copy()
    stops[25 * 15 :] = stops[25 * 15]  # freezes after 15 s
    assert freeze_score(stops, fps=25, skeleton=SK) < 0.01


def test_smoothed_energy_and_jitter(rng):
    still = frozen()
    j = jitter(still, fps=25, skeleton=SK)
    assert j["speed_residual"] == pytest.approx(0.0, abs=1e-9) and j["jerk"] == pytest.approx(0.0, abs=1e-9)
    shaky = still + rng.normal(scale=1.0, size=still.shape)  # 1 cm of frame-to-frame noise
    assert jitter(shaky, fps=25, skeleton=SK)["speed_residual"] > 0.1  # m/s removed by the 5-frame average
    p = moving()
    noisy = p + rng.normal(scale=1.0, size=p.shape)
    assert jitter(noisy, fps=25, skeleton=SK)["jerk"] > 3 * jitter(p, fps=25, skeleton=SK)["jerk"]
    assert smoothed_energy(still, fps=25, skeleton=SK) == pytest.approx(0.0, abs=1e-9)
    assert smoothed_energy(p, fps=25, skeleton=SK) > 0.1


def test_windowed_fid(rng):
    # 6 generated dances; window k of dance i is row i of a window set: window 0 is the reference itself,
    # window 1 the reference shifted by c, window 2 the reference scaled by 2 (present in 5 dances: its own
    # reference is the first 5 rows), window 3 exists in one dance only (below min_samples: NaN)
    ref = rng.normal(size=(6, 3)) @ np.diag([1.0, 2.0, 0.5]) + [0.3, -1.0, 2.0]
    c = np.array([1.0, -2.0, 2.0])  # |c|² = 9
    pred = [np.stack([ref[i], ref[i] + c, 2.0 * ref[i]]) for i in range(6)]
    pred[5] = pred[5][:2]
    pred[0] = np.concatenate([pred[0], ref[:1]])
    curve = windowed_fid(pred, ref)
    assert len(curve) == 4 and np.isnan(curve[3])
    assert curve[0] == pytest.approx(0.0, abs=1e-9)
    assert curve[1] == pytest.approx(9.0, rel=1e-9)
    # window 2 holds 2x the first 5 rows only: the Fréchet distance of exactly those rows to the reference
    assert curve[2] == pytest.approx(frechet_distance(2.0 * ref[:5], ref), rel=1e-12)
    # the same with 6 dances in window 2: S2 = 4 S, so d² = |mu|² + tr S + 4 tr S - 2 tr(2 S) = |mu|² + tr S
    full = windowed_fid([np.stack([ref[i], 2.0 * ref[i]]) for i in range(6)], ref)
    mu, S = ref.mean(0), np.cov(ref, rowvar=False)
    assert full[0] == pytest.approx(0.0, abs=1e-9)
    assert full[1] == pytest.approx(mu @ mu + np.trace(S), rel=1e-9)
    assert np.isnan(windowed_fid(pred, ref, min_samples=7)).all()


# ------------------------------------------------------------------------------ dance → music


C_MAJOR_TUNE = np.array(
    [[i * 0.5, i * 0.5 + 0.5, p] for i, p in enumerate([60, 64, 67, 72, 67, 64, 60, 62, 65, 69, 67, 65, 64, 62, 60, 60])]
)


def test_estimate_key():
    assert estimate_key(C_MAJOR_TUNE)[:2] == (0, "major")
    a_minor = C_MAJOR_TUNE.copy()
    a_minor[:, 2] = [57, 60, 64, 69, 64, 60, 57, 59, 62, 64, 60, 59, 57, 56, 57, 57]
    assert estimate_key(a_minor)[:2] == (9, "minor")


@pytest.mark.parametrize("shift", [0, 3, -2, 5])
def test_notes_accuracy_of_identical_and_transposed_copies_is_one(shift):
    copy = C_MAJOR_TUNE.copy()
    copy[:, 2] += shift
    assert notes_accuracy(copy, C_MAJOR_TUNE) == 1.0
    assert transpose_to_c(copy)[1] == -shift


def test_notes_accuracy_of_a_different_tune_is_low():
    other = C_MAJOR_TUNE[::-1].copy()
    other[:, :2] = C_MAJOR_TUNE[:, :2]
    assert notes_accuracy(other, C_MAJOR_TUNE) < 0.5


def test_notes_accuracy_reads_pretty_midi():
    import pretty_midi

    pm = pretty_midi.PrettyMIDI()
    inst = pretty_midi.Instrument(program=0)
    for s, e, p in C_MAJOR_TUNE:
        inst.notes.append(pretty_midi.Note(velocity=90, pitch=int(p) + 2, start=float(s), end=float(e)))
    pm.instruments.append(inst)
    assert notes_accuracy(pm, C_MAJOR_TUNE) == 1.0


def test_chroma_and_beat_l1_known_answers():
    a = np.eye(12)[[0, 4, 7]]
    b = np.eye(12)[[0, 5, 7]]
    assert chroma_l1(a, a) == 0.0
    assert chroma_l1(a, b) == pytest.approx(2.0 / 3)
    assert beat_l1(np.array([1, 0, 0, 1.0]), np.array([1, 0, 1, 0.0])) == pytest.approx(0.5)
    with pytest.raises(ParameterError, match="chroma"):
        chroma_l1(np.zeros((3, 11)), np.zeros((3, 11)))


# ------------------------------------------------------------------------------ joint distance


def test_mean_joint_distance():
    p = moving()
    assert mean_joint_distance(p, p) == 0.0
    assert mean_joint_distance(p + [3.0, 4.0, 0.0], p) == pytest.approx(5.0)
    with pytest.raises(ParameterError, match="frames"):
        mean_joint_distance(p[:10], p, crop=False)


def test_fid_breakdown_known_answers():
    """One-dimensional Fréchet distances worked by hand: column a's generated values sit 3 SDs off
    with the reference's spread (d = 9), column b's sit on the reference mean with no spread (d = 1)."""
    from dancekit.metrics import fid_breakdown

    ref_z = np.array([[-1.0, -1.0], [1.0, 1.0]])  # both columns: mean 0, std 1
    pred_z = np.array([[2.0, 0.0], [4.0, 0.0]])
    out = fid_breakdown(pred_z, ref_z, ["a", "b"])
    assert [o["feature"] for o in out] == ["a", "b"]
    assert out[0]["d"] == pytest.approx(9.0) and out[1]["d"] == pytest.approx(1.0)
    assert out[0]["share"] == pytest.approx(0.9) and out[1]["share"] == pytest.approx(0.1)
    assert out[0]["mean_z"] == pytest.approx(3.0) and out[0]["std_z"] == pytest.approx(1.0)
    assert out[1]["std_z"] == 0.0
    assert len(fid_breakdown(pred_z, ref_z, ["a", "b"], top=1)) == 1
    with pytest.raises(ParameterError):
        fid_breakdown(pred_z, ref_z, ["a"])


def test_feature_names_match_the_feature_vectors():
    from dancekit.metrics import feature_names

    names = feature_names("kinetic", SK)
    assert len(names) == 3 * SK.num_joints and names[:3] == (f"{SK.joint_names[0]}:KE_h",
                                                             f"{SK.joint_names[0]}:KE_v", f"{SK.joint_names[0]}:EE")
    assert feature_names("geometric", SK) == GEOMETRIC_FEATURE_NAMES
    with pytest.raises(ParameterError):
        feature_names("spectral", SK)


def test_torso_lean_known_answers():
    """The shoulders' midpoint straight above the pelvis is 0 degrees; tipped 30 degrees forward, 30; the
    median and 90th percentile over frames that lean 0, 10, 20, ..., 90 degrees are 45 and 81."""
    from dancekit.metrics import torso_lean

    pelvis, ls, rs = SK.index("pelvis"), SK.index("left_shoulder"), SK.index("right_shoulder")
    angles = np.radians(np.arange(0, 100, 10))
    p = np.zeros((len(angles), SK.num_joints, 3))
    p[:, pelvis] = [5.0, 90.0, -3.0]
    torso = 50.0 * np.stack([np.zeros_like(angles), np.cos(angles), np.sin(angles)], axis=1)  # tips along z
    p[:, ls] = p[:, pelvis] + torso + [15.0, 0.0, 0.0]
    p[:, rs] = p[:, pelvis] + torso - [15.0, 0.0, 0.0]
    out = torso_lean(p, skeleton=SK)
    assert out["median_deg"] == pytest.approx(45.0) and out["p90_deg"] == pytest.approx(81.0)
    assert torso_lean(p[:1], skeleton=SK)["median_deg"] == pytest.approx(0.0, abs=1e-6)
    assert torso_lean(p[3:4], skeleton=SK)["median_deg"] == pytest.approx(30.0)
    p[0, ls] = p[0, rs] = p[0, pelvis]
    with pytest.raises(ParameterError, match="torso lean"):
        torso_lean(p, skeleton=SK)
