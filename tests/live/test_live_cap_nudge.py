"""The jitter cap and the beat nudge live (issue 43): the genre read from the music heard so far, the bank of
low-passes and their running jitter, the smoothing held under the cap, the session's wiring, and each family's
beat nudge."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from dancekit.errors import ParameterError
from dancekit.live import LiveConfig
from dancekit.live.genre import OnlineGenreReader
from dancekit.live.stages import JitterBank, OnlineStages
from dancekit.motion.jitter import jitter_speed


@pytest.fixture(scope="module")
def m2d():
    from dancekit.pipelines import load_pipeline

    return load_pipeline("music2dance")


@pytest.mark.parametrize("n", [130, 750, 1000, 1125, 1700])
def test_genre_reader_equals_the_whole_prefix_read_offline(m2d, n):
    """Rows fed in uneven blocks: each reading is ``predict_song`` of the prefix heard (renormalised over the
    dance model's genres): one window while the prefix is under the classifier's window (750 frames), then its
    complete windows with the one flush with the end; 1125 - 750 is a multiple of the hop (no extra window)."""
    reader = m2d.genre_reader
    rng = np.random.default_rng(n)
    raw = reader.music_mean + reader.music_std * rng.normal(size=(n, len(reader.music_mean))).astype(np.float32)
    online = OnlineGenreReader(reader, genres=tuple(m2d.genres), after_s=4.0, every_s=1.0)
    a = 0
    for k in rng.integers(1, 9, size=n):
        online.push(raw[a : a + k])
        a += k
        if a >= n:
            break
    heard = online.heard
    assert heard > 0 and online.probs
    want = reader.model.predict_song((raw[:heard] - reader.music_mean) / reader.music_std)
    want = {g: float(want[reader.genres.index(g)]) for g in m2d.genres}
    total = sum(want.values())
    for g in m2d.genres:
        assert online.probs[g] == pytest.approx(want[g] / total, abs=1e-5)


def test_genre_reader_waits_for_its_first_seconds(m2d):
    reader = OnlineGenreReader(m2d.genre_reader, genres=tuple(m2d.genres), after_s=4.0)
    rows = np.tile(m2d.genre_reader.music_mean, (99, 1))
    assert not reader.push(rows) and reader.probs == {}
    assert reader.push(rows[:1]) and set(reader.probs) == set(m2d.genres)
    with pytest.raises(ParameterError, match="every_s"):
        OnlineGenreReader(m2d.genre_reader, genres=tuple(m2d.genres), every_s=0)


def _jittery(T=1500, J=6, fps=25.0, noise=0.6, seed=0):
    """A smooth dance (cm: joints on 1-Hz and 0.4-Hz circles about a walking root) with white tremor."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / fps
    p = np.zeros((T, J, 3))
    p[:, :, 0] = 40 * t[:, None] / t[-1]
    for j in range(1, J):
        p[:, j, 0] += 20 * np.cos(2 * np.pi * (0.4 + 0.6 * (j % 2)) * t + j)
        p[:, j, 1] += 100 + 10 * j
        p[:, j, 2] += 20 * np.sin(2 * np.pi * 0.4 * t + j)
    return p + noise * rng.normal(size=p.shape)


def test_jitter_bank_follows_the_metric_of_each_low_pass():
    """Each cut-off's running jitter, made a running arithmetic mean (its weight 1/k at the k-th frame), is
    the metric's jitter (:func:`jitter_speed`, one pass over the whole stream) of that one-pole's output (scipy's
    ``lfilter``): equal but for the metric's 3 edge frames at each end (1 % here)."""
    from dancekit.pipelines import load_pipeline

    fps = 25.0
    sk = load_pipeline("revolution").skeleton
    p = _jittery(J=sk.num_joints)
    cutoffs = (6.0, 3.0, 1.0)
    bank = JitterBank(cutoffs, fps=fps, root=sk.root, unit_scale=float(sk.unit_scale))
    for k, q in enumerate(p):
        bank.b = 1.0 / max(1, k - 5)  # the k - 5 th value of the jitter (the first at k = 6)
        bank.step(q)
    for c, got in zip(cutoffs, bank.jitter):
        a = 1.0 - np.exp(-2 * np.pi * c / fps)
        zi = scipy.signal.lfilter_zi([a], [1.0, a - 1.0])[:, None, None] * p[:1]
        y, _ = scipy.signal.lfilter([a], [1.0, a - 1.0], p, axis=0, zi=zi)
        assert got == pytest.approx(jitter_speed(y, skeleton=sk, fps=fps), rel=0.02)
    assert bank.jitter[0] > bank.jitter[1] > bank.jitter[2]
    assert bank.highest_under(float(bank.jitter[1]) * 1.001) == 3.0
    assert bank.highest_under(0.0) == 1.0


def _trembling(sk, T=1500, fps=25.0, tremor=0.04, seed=0):
    """The rest pose turning about the vertical through its root (a 0.5-Hz sway of 0.5 rad plus a white tremor
    of ``tremor`` rad) as the root walks: every bone at its rest length, the jitter body-relative."""
    from dancekit.motion.analysis import horizontal_axes, rest_pose

    rng = np.random.default_rng(seed)
    t = np.arange(T) / fps
    rest = rest_pose(sk) - rest_pose(sk)[sk.root]
    a, b = horizontal_axes(sk)
    th = 0.5 * np.sin(2 * np.pi * 0.5 * t) + tremor * rng.normal(size=T)
    p = np.repeat(rest[None], T, axis=0)
    p[:, :, a] = np.cos(th)[:, None] * rest[:, a] - np.sin(th)[:, None] * rest[:, b] + 30 * t[:, None]
    p[:, :, b] = np.sin(th)[:, None] * rest[:, a] + np.cos(th)[:, None] * rest[:, b]
    return p


def test_online_stages_hold_the_jitter_under_the_cap():
    """A trembling dance through the online stages, capped at 0.6 × its uncapped jitter: the smoothing's
    cut-off comes down and the output's jitter (after the first 4 s) is under 1.1 × the cap (the running mean
    lets it swing about the cap); with the bank but no cap the output is the uncapped one, bit for bit. The foot
    lock is off: the walking figure's held feet would add their own jitter."""
    from dancekit.pipelines import load_pipeline

    fps = 25.0
    sk = load_pipeline("revolution").skeleton
    p = _trembling(sk)
    music = np.ones(len(p), bool)

    def run(stages, cap=None):
        stages.max_jitter = cap
        return np.concatenate([stages.process(p[k : k + 5], music[k : k + 5]) for k in range(0, len(p), 5)])

    plain = run(OnlineStages(sk, fps=fps, config=LiveConfig(foot_lock=False)))
    nocap = run(OnlineStages(sk, fps=fps, config=LiveConfig(foot_lock=False), cap=True))
    np.testing.assert_array_equal(plain, nocap)
    free = jitter_speed(plain[100:], skeleton=sk, fps=fps)
    cap = 0.6 * free
    stages = OnlineStages(sk, fps=fps, config=LiveConfig(foot_lock=False), cap=True)
    capped = run(stages, cap)
    got = jitter_speed(capped[100:], skeleton=sk, fps=fps)
    assert got < 1.1 * cap, (free, got, cap)  # uncapped: 1.67 × the cap
    assert stages.cutoff < LiveConfig().smooth_hz


def test_session_caps_music2dance_from_the_genre_read(m2d):
    """jitter_cap on: music2dance reads the genre (its reader has the session's preset), a genre asked for by
    name is capped at its own real jitter at once; revolution (its reader of another preset) and the switch off:
    no cap, no bank."""
    from dancekit.live.session import LiveSession

    table = m2d.settings.stages.genre_stats.table("jitter")
    on = LiveSession("music2dance", pipe=m2d, config=LiveConfig(jitter_cap=True))
    assert on.genre_reader is not None and on.stages.bank is not None and on.stages.max_jitter is None
    named = LiveSession("music2dance", pipe=m2d, config=LiveConfig(jitter_cap=True), genre="tango")
    assert named.genre_reader is None and named.stages.max_jitter == pytest.approx(table["tango"])
    off = LiveSession("music2dance", pipe=m2d, config=LiveConfig())
    assert off.genre_reader is None and off.stages.bank is None
    rev = LiveSession("revolution", config=LiveConfig(jitter_cap=True))
    assert rev.genre_reader is None and rev.stages.bank is None
    with pytest.raises(ParameterError, match="LiveConfig.jitter_cap"):
        LiveConfig(jitter_cap=1)


def test_each_family_dances_its_beat_nudge(m2d):
    """beat_nudge None: music2dance pulses on the beat, revolution nudges its kinematic beats (each chosen on the
    validation songs); a nudge asked for by name wins."""
    from dancekit.live.session import LiveSession

    assert LiveSession("music2dance", pipe=m2d).nudge.mode == "pulse"
    assert LiveSession("revolution").nudge.mode == "target"
    assert LiveSession("music2dance", pipe=m2d, config=LiveConfig(beat_nudge="target")).nudge.mode == "target"
    assert LiveSession("revolution", config=LiveConfig(beat_nudge="pulse")).nudge.mode == "pulse"


def test_both_families_hold_their_feet_unless_asked_not_to(m2d):
    """foot_lock (True by default: chosen on the validation songs for both models) reaches the session's stages."""
    from dancekit.live.session import LiveSession

    for family, kw in (("revolution", {}), ("music2dance", {"pipe": m2d})):
        assert LiveSession(family, **kw).stages.lock is not None
        assert LiveSession(family, config=LiveConfig(foot_lock=False), **kw).stages.lock is None


def _bent_stance(sk, T, fps):
    """The rest pose with the hips 5 cm lower and the knees bent forward over feet that stay where they were
    (each leg solved by two-bone IK toward the pose's front), lowest joint on the floor: a stance whose feet
    have room to be held where they were planted."""
    from dancekit.motion.analysis import horizontal_axes, leg_chains, rest_pose
    from dancekit.motion.footlock import two_bone_ik

    p = rest_pose(sk)
    up = sk.up_index
    p[:, up] -= p[:, up].min()
    legs = leg_chains(sk)
    feet = {j for _h, _k, ankle, below in legs for j in (ankle, *below)}
    knees = {k for _h, k, _a, _b in legs}
    body = [j for j in range(sk.num_joints) if j not in feet | knees]
    p[body, up] -= 5.0
    a, _b = horizontal_axes(sk)
    for hip, knee, ankle, _below in legs:
        pole = np.zeros((1, 3))
        pole[0, a] = 1.0
        p[knee] = two_bone_ik(p[hip][None], p[knee][None], p[ankle][None], p[ankle][None], pole=pole)[0][0]
    return np.repeat(p[None], T, axis=0), legs


def test_online_foot_lock_holds_a_sliding_foot_where_it_was_planted():
    """A stance whose left foot slides on the floor (±8 cm, 0.5 Hz: under the contact speed) while the rest
    stands: from the third frame (the contact's 0.12 s) the left ankle glides to a stop — the step d it was
    taking shrinking by e⁻¹ a frame (0.04 s at 25 fps), so it comes to rest d e⁻¹ / (1 − e⁻¹) = d / (e − 1)
    beyond where it was shown then — and stays there; thigh and shin keep their lengths; every joint outside the left leg's knee and foot is the
    input's; a lifted foot is left alone; the state carries across blocks (blocks of 7 = one call)."""
    from dancekit.live.stages import OnlineFootLock
    from dancekit.motion.analysis import horizontal_axes
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline("revolution").skeleton
    fps, T = 25.0, 100
    p, legs = _bent_stance(sk, T, fps)
    a, b = horizontal_axes(sk)
    hip, knee, ankle, below = legs[0]
    foot = [ankle, *below]
    t = np.arange(T) / fps
    p[:, foot, a] += 8.0 * np.sin(2 * np.pi * 0.5 * t)[:, None]  # cm; at most 0.25 m/s
    out = OnlineFootLock(sk, fps=fps).process(p)
    rest = p[2, ankle][[a, b]] + (p[2, ankle] - p[1, ankle])[[a, b]] / (np.e - 1)
    np.testing.assert_allclose(out[12:, ankle][:, [a, b]], np.repeat(rest[None], T - 12, axis=0), atol=1e-3)
    np.testing.assert_allclose(out[:3, ankle], p[:3, ankle], atol=1e-9)  # shown as the model's until planted
    assert np.abs(out[:, ankle, a] - p[:, ankle, a]).max() > 9.5  # held against the slide (8 + 8 sin(0.08 pi) cm)
    for j0, j1 in ((hip, knee), (knee, ankle)):
        np.testing.assert_allclose(np.linalg.norm(out[:, j1] - out[:, j0], axis=1),
                                   np.linalg.norm(p[:, j1] - p[:, j0], axis=1), atol=1e-6)
    others = [j for j in range(sk.num_joints) if j not in (knee, *foot)]
    np.testing.assert_array_equal(out[:, others], p[:, others])
    lock = OnlineFootLock(sk, fps=fps)
    np.testing.assert_allclose(np.concatenate([lock.process(p[k : k + 7]) for k in range(0, T, 7)]), out, atol=1e-9)
    from dancekit.motion.analysis import rest_pose

    standing = np.repeat(rest_pose(sk)[None], T, axis=0)  # straight legs, still feet: held, nothing moved
    standing[..., sk.up_index] -= standing[0, :, sk.up_index].min()
    for h, k, an, _below in legs:  # each knee on its hip-ankle line: the leg exactly straight
        standing[:, k] = standing[:, h] + 0.5 * (standing[:, an] - standing[:, h])
    lock = OnlineFootLock(sk, fps=fps)
    np.testing.assert_array_equal(lock.process(standing), standing)
    assert lock.held_frames == [T - 2, T - 2]
    lifted = p.copy()
    lifted[:, foot, sk.up_index] += 10.0  # 10 cm over the floor: no contact
    np.testing.assert_array_equal(OnlineFootLock(sk, fps=fps).process(lifted), lifted)


def test_online_foot_lock_lets_a_drifting_foot_go_without_a_jump():
    """A foot gliding one way at 0.3 m/s (slow and low: a contact) is held until the model's foot is 20 cm
    from it, then handed back over 0.32 s and planted again where it is shown (0.12 s later, mid-way): it is
    held again and again, never more than 20 cm (plus the hand-back's frames of glide) from the model's; handed
    back, it leaves at rest (its first step under the model's 1.2 cm) and its steps are at most the model's plus
    the smoothstep's steepest slope (1.5 / 8 frames) times the gap, which the model's glide widens to at most
    20 + 9 × 1.2 cm; the right foot, still, is held throughout."""
    from dancekit.live.stages import OnlineFootLock
    from dancekit.motion.analysis import horizontal_axes
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline("revolution").skeleton
    fps, T = 25.0, 100
    p, legs = _bent_stance(sk, T, fps)
    a, _b = horizontal_axes(sk)
    _hip, _knee, ankle, below = legs[0]
    p[:, [ankle, *below], a] += 30.0 * (np.arange(T) / fps)[:, None]  # cm: 0.3 m/s
    lock = OnlineFootLock(sk, fps=fps)
    out = lock.process(p)
    gap = np.abs(out[:, ankle, a] - p[:, ankle, a])
    step = 30.0 / fps
    assert gap.max() <= 20.0 + 9 * step + 1e-9
    steps = np.abs(np.diff(out[:, ankle, a]))
    assert steps.max() <= step + (20.0 + 9 * step) * 1.5 / 8 + 1e-9
    still = steps < 0.05  # cm a frame: at rest, a planted foot's glide to a stop included
    assert still.sum() > 0.4 * T  # held for much of the time
    holds = np.flatnonzero(np.diff(still.astype(int)) == 1)  # a still run starting: a new hold
    assert len(holds) >= 2 and gap[holds + 1].max() < 20.0  # planted again, nearer the model's foot
    ends = np.flatnonzero(np.diff(still.astype(int)) == -1) + 1  # the first step of each hand-back
    assert len(ends) >= 2 and steps[ends].max() < step
    assert 0 < lock.held_frames[0] < T and lock.held_frames[1] == T - 2  # the right foot (still) held throughout


def test_live_config_foot_lock_is_a_flag():
    assert LiveConfig().foot_lock and not LiveConfig(foot_lock=False).foot_lock
    with pytest.raises(ParameterError, match="LiveConfig.foot_lock must be true or false"):
        LiveConfig(foot_lock="yes")
