"""Editing a finished dance (dancekit.motion.edit and the "edit" stage): known answers on synthetic dances."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dancekit.errors import ParameterError
from dancekit.motion import edit, get_skeleton

SK = get_skeleton("tang2018")  # centimetres, y up
FPS = 25.0


def _dance(T: int = 200, seed: int = 0) -> np.ndarray:
    """A smooth synthetic dance (T, 23, 3) cm: the rest pose swaying, walking slowly along x."""
    rng = np.random.default_rng(seed)
    rest = np.asarray(SK.rest_positions() if hasattr(SK, "rest_positions") else np.cumsum(SK.offsets, 0), float)
    t = np.arange(T)[:, None, None] / FPS
    amp = rng.uniform(1, 5, (1, SK.num_joints, 3))
    ph = rng.uniform(0, 6, (1, SK.num_joints, 3))
    p = rest[None] + amp * np.sin(2 * math.pi * 1.3 * t + ph)
    p[..., 0] += 20.0 * t[..., 0]
    p[..., 1] += 100.0
    return p


def _write(tmp_path, name, obj):
    f = tmp_path / name
    f.write_text(json.dumps(obj))
    return f


def test_keys_exact_smooth_and_local(tmp_path):
    p = _dance()
    wrist = SK.joint_names.index("left_wrist")
    k1 = (p[50, wrist] + [10.0, -5.0, 8.0]).tolist()
    k2 = (p[70, wrist] + [-6.0, 9.0, 0.0]).tolist()  # 0.8 s apart: the two bumps overlap
    f = _write(tmp_path, "keys.json", [{"time": 2.0, "pose": {"left_wrist": k1}},
                                       {"frame": 70, "pose": {"left_wrist": k2}}])
    keys = edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    out = edit.apply_keyframes(p, keys=keys, fps=FPS)
    np.testing.assert_allclose(out[50, wrist], k1, atol=1e-9)
    np.testing.assert_allclose(out[70, wrist], k2, atol=1e-9)
    corr = out - p
    # untouched: other joints everywhere, the wrist farther than 1 s (25 frames) from both keys
    others = [j for j in range(SK.num_joints) if j != wrist]
    assert np.array_equal(out[:, others], p[:, others])
    assert np.array_equal(out[:25, wrist], p[:25, wrist]) and np.array_equal(out[96:, wrist], p[96:, wrist])
    # smooth: the correction's second difference stays small (a C2 bump of half-width 25 frames: bound by hand,
    # |w| * max|phi''| / 25^2 with phi'' <= 20 at the centre; the weights are below 3 * the residual here)
    d2 = np.abs(np.diff(corr[:, wrist], 2, axis=0)).max()
    assert d2 < 3 * 13.0 * 20 / 25**2
    assert np.abs(corr[:, wrist]).max() > 5  # the correction did something


def test_key_correction_exact_where_bumps_overlap():
    res = np.array([[10.0, 0.0], [-4.0, 2.0], [3.0, 3.0]])
    c = edit.key_correction(120, np.array([40, 50, 58]), res, support=25.0)
    np.testing.assert_allclose(c[[40, 50, 58]], res, atol=1e-9)
    assert np.array_equal(c[:16], np.zeros((16, 2))) and np.array_equal(c[83:], np.zeros((37, 2)))


def test_wendland_bump_known_values():
    np.testing.assert_allclose(edit.wendland(np.array([0.0, 0.5, 1.0, 2.0])), [1.0, 0.0625 * 3.0, 0.0, 0.0])


def test_keys_refused(tmp_path):
    p = _dance()
    w = p[10, 0].tolist()
    far = (p[10, 0] + [300.0, 0, 0]).tolist()  # 3 m in 0.2 s: 15 m/s
    f = _write(tmp_path, "fast.json", [{"frame": 10, "pose": {"head_right": w}},
                                       {"frame": 15, "pose": {"head_right": far}}])
    with pytest.raises(ParameterError, match="fast.json.*m/s"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    f = _write(tmp_path, "late.json", [{"time": 9.0, "pose": {"head_right": w}}])
    with pytest.raises(ParameterError, match="late.json.*outside the dance"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))
    f = _write(tmp_path, "name.json", [{"time": 1.0, "pose": {"nose": w}}])
    with pytest.raises(ParameterError, match="name.json.*nose"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p))


def test_path_followed_sway_kept(tmp_path):
    p = _dance(T=250)
    f = _write(tmp_path, "path.json", {"points": [[0, 0], [2, 0], [2, 2]]})
    pts, times = edit.read_path(f)
    out = edit.follow_path(p, skeleton=SK, fps=FPS, points=pts, times=times)
    target = edit.path_positions(pts, times, num_frames=len(p), fps=FPS)
    root = out[:, SK.root][:, [0, 2]] * SK.unit_scale
    rms = float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1))))
    assert rms < 0.10
    # a rigid horizontal shift per frame: heights and the pose relative to the root unchanged
    np.testing.assert_allclose(out[..., 1], p[..., 1], atol=1e-9)
    np.testing.assert_allclose(out - out[:, SK.root:SK.root + 1], p - p[:, SK.root:SK.root + 1], atol=1e-9)
    # the constant-speed walk: 4 m over 9.96 s, the corner at the middle
    np.testing.assert_allclose(target[len(p) // 2 - 1], [2.0, 0.0], atol=0.02)


def test_path_refused(tmp_path):
    f = _write(tmp_path, "far.json", {"points": [[0, 0], [5, 0]]})
    with pytest.raises(ParameterError, match="far.json.*dance floor"):
        edit.read_path(f)
    f = _write(tmp_path, "times.json", {"points": [[0, 0], [1, 0]], "times": [1.0, 0.5]})
    with pytest.raises(ParameterError, match="times.json"):
        edit.read_path(f)


def test_keep_upper_equals_take():
    p, take = _dance(seed=0), _dance(seed=1) + [50.0, 3.0, -20.0]
    joints = edit.body_part_joints(SK, "upper")
    assert SK.root not in joints and SK.joint_names.index("left_knee") not in joints
    assert SK.joint_names.index("left_wrist") in joints
    out = edit.keep_joints(p, take, skeleton=SK, joints=joints)
    r = SK.root
    np.testing.assert_allclose(out[:, joints] - out[:, r:r + 1], take[:, joints] - take[:, r:r + 1], atol=1e-3)
    rest = [j for j in range(SK.num_joints) if j not in joints]
    assert np.array_equal(out[:, rest], p[:, rest])
    with pytest.raises(ParameterError, match="nose"):
        edit.body_part_joints(SK, "left_wrist,nose")


def test_prefix_kept_and_seam_continuous():
    p, pre = _dance(T=200, seed=0), _dance(T=60, seed=2) + [30.0, 0.0, 40.0]
    out = edit.continue_from(pre, p, skeleton=SK, fps=FPS)
    np.testing.assert_allclose(out[:60], pre, atol=1e-4)
    # no jump at the seam: the step at the seam no larger than the largest step of the two dances around it
    step = np.linalg.norm(out[60] - out[59], axis=-1).max()
    assert step <= 1.5 * max(np.linalg.norm(np.diff(pre, axis=0), axis=-1).max(),
                             np.linalg.norm(np.diff(p, axis=0), axis=-1).max())
    # and no kink: the acceleration across the seam no larger than the largest of the two dances (the
    # velocity carried over; a pose-only fade leaves the velocity jump, a spike)
    acc = np.linalg.norm(np.diff(out, 2, axis=0), axis=-1).max(axis=1)
    assert acc[56:62].max() <= max(np.linalg.norm(np.diff(d, 2, axis=0), axis=-1).max() for d in (pre, p))
    # after the fade: the dance's own motion, moved rigidly (pairwise joint distances equal)
    a, b = out[150], p[150]
    np.testing.assert_allclose(np.linalg.norm(a[:, None] - a[None], axis=-1),
                               np.linalg.norm(b[:, None] - b[None], axis=-1), atol=1e-6)
    with pytest.raises(ParameterError, match="shorter"):
        edit.continue_from(p, pre, skeleton=SK, fps=FPS)


# --- the edit stage through `dancekit dance` on a 4-s excerpt of a test song (the embedded models) -------------

SONG = "Kevin_MacLeod_-_Vibe_Ace.ogg"
EXCERPT = ["--start", "10", "--end", "14", "--format", "npz", "--quiet"]


def _cli(music_dir, out, *flags, model="revolution"):
    from dancekit.cli.main import main

    return main(["dance", str(music_dir / SONG), "-o", str(out), "--model", model, *EXCERPT, *flags])


def _positions(out):
    from dancekit.motion.formats import read_motion

    return read_motion(out / SONG.replace(".ogg", ".npz")).to_positions().astype(np.float64)


@pytest.fixture(scope="module")
def base(music_dir, tmp_path_factory):
    """The unedited dance (seed 0) and a second one (seed 1) of the excerpt: positions (T, 23, 3) cm."""
    root = tmp_path_factory.mktemp("edit_base")
    assert _cli(music_dir, root / "s0") == 0 and _cli(music_dir, root / "s1", "--seed", "1") == 0
    return root, _positions(root / "s0"), _positions(root / "s1")


@pytest.fixture(scope="module")
def music_dir():  # the conftest fixture's folder, for the module-scoped `base`
    from conftest import MUSIC, _need

    return _need(MUSIC)


@pytest.mark.shared
def test_cli_keyframes(base, music_dir, tmp_path):
    root, p0, _ = base
    lw = SK.joint_names.index("left_wrist")
    want = p0[50, lw] + [10.0, 8.0, -5.0]
    keys = _write(tmp_path, "keys.json", [{"time": 2.0, "pose": {"left_wrist": want.tolist()}}])
    assert _cli(music_dir, tmp_path / "o", "--keyframes", str(keys)) == 0
    p = _positions(tmp_path / "o")
    np.testing.assert_allclose(p[50, lw], want, atol=1e-3)  # float32 output, cm
    assert np.array_equal(p[:25], p0[:25]) and np.array_equal(p[76:], p0[76:])  # > 1 s from the key


@pytest.mark.shared
def test_cli_path(base, music_dir, tmp_path):
    path = _write(tmp_path, "path.json", {"points": [[0, 0], [1, 0], [1, 1]]})
    assert _cli(music_dir, tmp_path / "o", "--path", str(path)) == 0
    p = _positions(tmp_path / "o")
    pts, times = edit.read_path(path)
    target = edit.path_positions(pts, times, num_frames=len(p), fps=FPS)
    rms = float(np.sqrt(np.mean(np.sum((p[:, SK.root][:, [0, 2]] * SK.unit_scale - target) ** 2, axis=1))))
    assert rms <= 0.10


@pytest.mark.shared
def test_cli_keep(base, music_dir, tmp_path):
    root, p0, p1 = base
    take = root / "s1" / SONG.replace(".ogg", ".npz")
    assert _cli(music_dir, tmp_path / "o", "--keep", "upper", "--from", str(take)) == 0
    p = _positions(tmp_path / "o")
    j, r = list(edit.body_part_joints(SK, "upper")), SK.root
    np.testing.assert_allclose(p[:, j] - p[:, r:r + 1], p1[:, j] - p1[:, r:r + 1], atol=1e-3)
    legs = [k for k in range(SK.num_joints) if k not in j]
    assert np.array_equal(p[:, legs], p0[:, legs])


@pytest.mark.shared
def test_cli_prefix(base, music_dir, tmp_path):
    from dancekit.motion import Motion
    from dancekit.motion.formats import write_motion

    _, p0, p1 = base
    pre = p1[:40] + [30.0, 0.0, -20.0]
    write_motion(tmp_path / "pre.npz", Motion(skeleton=SK, fps=FPS, positions=pre.astype(np.float32)))
    assert _cli(music_dir, tmp_path / "o", "--prefix", str(tmp_path / "pre.npz")) == 0
    p = _positions(tmp_path / "o")
    np.testing.assert_allclose(p[:40], pre, atol=1e-4)
    assert len(p) == len(p0)
    # no spike at the seam: the acceleration there no larger than the largest in either dance
    acc = np.linalg.norm(np.diff(p, 2, axis=0), axis=-1).max(axis=1)
    own = max(np.linalg.norm(np.diff(d, 2, axis=0), axis=-1).max() for d in (p0, p1))
    assert acc[36:44].max() <= own


@pytest.mark.shared
def test_revolution_continues_the_prefix(base, music_dir, tmp_path):
    """Dance Revolution is given the prefix (its decoder fed the prefix's poses): its own dance, before any stage,
    starts with the prefix's poses (root-relative), and the conditioned continuation leaves a smaller pose gap
    for the edit stage's fade at the seam than the unconditioned dance of the same seed."""
    from dancekit.motion import Motion
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.config import EditConfig

    _, p0, p1 = base
    pre = p1[40:80] + [30.0, 0.0, -20.0]
    write_motion(tmp_path / "pre.npz", Motion(skeleton=SK, fps=FPS, positions=pre.astype(np.float32)))
    pipe = load_pipeline("revolution")
    start, end = float(EXCERPT[1]), float(EXCERPT[3])
    raw = {}
    for edit_config in (None, EditConfig(prefix=str(tmp_path / "pre.npz"))):
        steps = {}  # the model's own dance is the trace's "input" (the edit stage comes after it)
        pipe.dances(str(music_dir / SONG), seeds=[0], start=start, end=end, cleanup=False, beat_sync=False,
                    edit=edit_config, stage_trace=lambda k, name, result, steps=steps: steps.__setitem__(name, result))
        raw[edit_config is None] = np.asarray(steps["input"].motion.to_positions(), np.float64)
    r = SK.root
    rel = raw[False][:40] - raw[False][:40, r:r + 1]
    np.testing.assert_allclose(rel, pre - pre[:, r:r + 1], atol=1e-3)

    def gap(p):  # frame 40's pose (root-relative) against the prefix's last
        return float(np.linalg.norm((p[40] - p[40, r]) - (pre[-1] - pre[-1, r]), axis=-1).mean())

    assert gap(raw[False]) < gap(raw[True])


@pytest.mark.shared
def test_music2dance_continues_the_prefix(base, music_dir, tmp_path):
    """Music2Dance is given the prefix (its WaveNet fed the prefix's features, rotations by IK): its own dance,
    before any stage, holds the prefix's poses (turned to the same heading, root-relative) up to the feature
    smoothing and the model skeleton's rest bones (measured: 8-12 cm at the worst joint; the same seed without the
    prefix: 28-84 cm)."""
    from dancekit.motion import Motion
    from dancekit.motion.edit import _yaw
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.config import EditConfig

    _, _, p1 = base
    pre = p1[40:80]
    write_motion(tmp_path / "pre.npz", Motion(skeleton=SK, fps=FPS, positions=pre.astype(np.float32)))
    pipe = load_pipeline("music2dance")
    steps = {}
    pipe.dances(str(music_dir / SONG), seeds=[0], start=float(EXCERPT[1]), end=float(EXCERPT[3]), cleanup=False,
                beat_sync=False, edit=EditConfig(prefix=str(tmp_path / "pre.npz")),
                stage_trace=lambda k, name, result: steps.__setitem__(name, result))
    raw = np.asarray(steps["input"].motion.to_positions(), np.float64)
    r = SK.root

    def turned(pose, yaw):
        rel = pose - pose[r]
        c, s = math.cos(yaw), math.sin(yaw)
        out = rel.copy()
        out[:, 0], out[:, 2] = c * rel[:, 0] - s * rel[:, 2], s * rel[:, 0] + c * rel[:, 2]
        return out

    worst = [np.linalg.norm(turned(raw[f], _yaw(pre, SK, f) - _yaw(raw, SK, f)) - (pre[f] - pre[f, r]), axis=-1).max()
             for f in range(35)]
    assert float(np.median(worst)) < 15.0


@pytest.mark.shared
@pytest.mark.parametrize("flags, words", [
    (lambda t, take: ["--keep", "upper"], "go together"),
    (lambda t, take: ["--prefix", take, "--path", str(_write(t, "p.json", {"points": [[0, 0], [1, 0]]}))],
     "cannot be given with a path"),
    (lambda t, take: ["--keep", "left_wrist", "--from", take, "--keyframes",
                      str(_write(t, "k.json", [{"time": 1.0, "pose": {"left_wrist": [0, 100, 0]}}]))],
     "keys on kept joints"),
    (lambda t, take: ["--prefix", take], "not shorter than the dance"),
    (lambda t, take: ["--path", str(_write(t, "far.json", {"points": [[0, 0], [0, 6]]}))], "far.json"),
])
def test_cli_contradictions_refused(base, music_dir, tmp_path, capsys, flags, words):
    root, _, _ = base
    take = str(root / "s1" / SONG.replace(".ogg", ".npz"))
    out = tmp_path / "o"
    code = _cli(music_dir, out, *flags(tmp_path, take))
    err = capsys.readouterr().err
    assert code != 0 and words in err and err.strip().count("\n") == 0, err
    assert not out.exists() or list(out.iterdir()) == []


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("model", ["music2dance", "dual"])
def test_cli_edit_other_models(music_dir, tmp_path, model):
    """Keys and a path with the two other models: the stage works on any finished dance."""
    assert _cli(music_dir, tmp_path / "u", model=model) == 0
    p0 = _positions(tmp_path / "u")
    lw = SK.joint_names.index("left_wrist")
    want = p0[50, lw] + [5.0, 5.0, 5.0]
    keys = _write(tmp_path, "keys.json", [{"time": 2.0, "pose": {"left_wrist": want.tolist()}}])
    path = _write(tmp_path, "path.json", {"points": [[0, 0], [1, 1]]})
    assert _cli(music_dir, tmp_path / "o", "--keyframes", str(keys), "--path", str(path), model=model) == 0
    p = _positions(tmp_path / "o")
    np.testing.assert_allclose(p[50, lw], want, atol=1e-3)
    target = edit.path_positions(*edit.read_path(path), num_frames=len(p), fps=FPS)
    root = p[:, SK.root][:, [0, 2]] * SK.unit_scale
    assert float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1)))) <= 0.10


def test_finish_runs_the_edit_stage_last(tmp_path):
    """Python API: ``finish(result, song, dataclasses.replace(config, edit=EditConfig(...)))``."""
    import dataclasses

    from dancekit.motion import Motion
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import EditConfig, StageConfig
    from dancekit.pipelines.stages import finish

    p = _dance()
    wrist = SK.joint_names.index("left_wrist")
    want = (p[60, wrist] + [5.0, 5.0, 5.0]).tolist()
    keys = _write(tmp_path, "keys.json", [{"frame": 60, "pose": {"left_wrist": want}}])
    result = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32)), model="x", seed=0)
    config = StageConfig().switched(beat_sync=False, cleanup=False)
    names = []
    out = finish(result, "no-song.wav", dataclasses.replace(config, edit=EditConfig(keyframes=str(keys))),
                 trace=lambda name, r: names.append(name))
    assert names[-1] == "edit" and out.notes[-1].startswith("edited: 1 keys")
    np.testing.assert_allclose(out.motion.positions[60, wrist], want, atol=1e-3)
    with pytest.raises(ParameterError, match="go together"):
        EditConfig(keep="upper")


def test_finish_moves_the_dance_onto_the_path_before_the_foot_lock(tmp_path):
    """With a path, finish moves the dance onto it before the foot lock (the lock plants the moved feet once)
    and after the last stage only puts the root back on the path: the result is the path's shift of the dance
    the last stage gave, not locked a second time."""
    import dataclasses

    from dancekit.motion import Motion
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import EditConfig, StageConfig
    from dancekit.pipelines.stages import finish

    p = _dance(T=250)
    path = _write(tmp_path, "path.json", {"points": [[0, 0], [1.5, 0], [1.5, 1.5]]})
    result = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=p.astype(np.float32)), model="x", seed=0)
    config = dataclasses.replace(StageConfig().switched(beat_sync=False), edit=EditConfig(path=str(path)))
    steps = []
    out = finish(result, "no-song.wav", config, trace=lambda name, r: steps.append((name, r)))
    names = [n for n, _ in steps]
    assert names[-1] == "edit" and names.index("path") < names.index("foot_lock")
    pts, times = edit.read_path(path)
    last = steps[-2][1].motion.to_positions()
    np.testing.assert_allclose(out.motion.positions,
                               edit.follow_path(last, skeleton=SK, fps=FPS, points=pts, times=times), atol=1e-3)
    target = edit.path_positions(pts, times, num_frames=len(p), fps=FPS)
    root = out.motion.positions[:, SK.root][:, [0, 2]] * SK.unit_scale
    assert float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1)))) < 0.10


def test_keys_on_beats(tmp_path):
    p = _dance()
    f = _write(tmp_path, "beats.json", [{"beat": 2, "pose": {"head_right": p[40, 0].tolist()}}])
    keys = edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p), beats=[0.5, 1.0, 1.55, 2.0])
    assert [k.frame for k in keys] == [39]  # 1.55 s at 25 fps: frame 38.75, the nearest 39
    with pytest.raises(ParameterError, match="beats.json.*beat 2 is not among the song's 2"):
        edit.read_keyframes(f, skeleton=SK, fps=FPS, num_frames=len(p), beats=[0.5, 1.0])


def test_path_sway_capped():
    p = _dance(T=250)
    p[:, :, 0] += 30.0 * np.sin(2 * math.pi * 2.0 * np.arange(250) / FPS)[:, None]  # a 21-cm RMS sway at 2 Hz
    pts = np.array([[0.0, 0.0], [2.0, 0.0]])
    out = edit.follow_path(p, skeleton=SK, fps=FPS, points=pts)
    root = out[:, SK.root][:, [0, 2]] * SK.unit_scale
    target = edit.path_positions(pts, None, num_frames=len(p), fps=FPS)
    rms = float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1))))
    assert 0.045 <= rms <= 0.0501  # the sway kept, scaled to its 5-cm cap


def test_prefix_without_rig_mapping_refused(tmp_path):
    from dancekit.motion import Motion
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines.base import DanceResult
    from dancekit.pipelines.config import EditConfig
    from dancekit.pipelines.stages import edit_dance

    sk2 = get_skeleton("body25")
    write_motion(tmp_path / "flat.npz", Motion(skeleton=sk2, fps=FPS, positions=np.ones((20, sk2.num_joints, 2),
                                                                                        np.float32)))
    result = DanceResult(motion=Motion(skeleton=SK, fps=FPS, positions=_dance().astype(np.float32)), model="x",
                         seed=0)
    with pytest.raises(ParameterError, match="flat.npz.*no rig mapping"):
        edit_dance(result, EditConfig(prefix=str(tmp_path / "flat.npz")), "no-song.wav")
