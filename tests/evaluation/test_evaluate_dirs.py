"""``dancekit evaluate`` and :func:`dancekit.evaluation.evaluate_dirs` on synthetic folders."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dancekit.cli.main import main
from dancekit.errors import DatasetError
from dancekit.evaluation import EvalSettings, evaluate_dirs, format_markdown, group_predictions
from dancekit.motion import Motion, get_skeleton, write_motion

SK = get_skeleton("tang2018")


def rest_pose() -> np.ndarray:
    rest = np.zeros((SK.num_joints, 3))
    for j in SK.topological_order:
        p = SK.parents[j]
        rest[j] = SK.offsets[j] + (rest[p] if p >= 0 else 0.0)
    rest[:, 1] -= rest[[SK.index(f) for f in SK.feet], 1].min()
    return rest


def dance(seed: int, seconds: float = 24.0, fps: float = 25.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fps))[:, None, None] / fps
    J = SK.num_joints
    amp = rng.uniform(3.0, 12.0, size=(1, J, 3))
    freq = rng.uniform(0.3, 1.5, size=(1, J, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, J, 3))
    return (rest_pose()[None] + amp * np.sin(2 * np.pi * freq * t + phase)).astype(np.float32)


def swing(seconds: float, fps: float, *, period: float = 1.0, shift: float = 0.0) -> np.ndarray:
    """Every joint swings back and forth as ``cos(2 pi (t - shift) / period)`` (its own amplitude, same phase):
    the mean joint speed is proportional to ``|sin|``, so the dance stops (kinematic beats) exactly at
    ``t = shift + k period / 2``."""
    t = np.arange(int(round(seconds * fps)))[:, None, None] / fps
    amp = np.linspace(3.0, 12.0, SK.num_joints)[None, :, None] * np.array([1.0, 0.3, 0.6])  # cm
    return (rest_pose()[None] + amp * np.cos(2 * np.pi * (t - shift) / period)).astype(np.float32)


@pytest.fixture
def folders(tmp_path):
    ref, pred = tmp_path / "ref", tmp_path / "pred"
    ref.mkdir()
    pred.mkdir()
    for k in range(4):
        p = dance(k)
        write_motion(ref / f"D{k}.npz", Motion(skeleton=SK, fps=25.0, positions=p))
        write_motion(pred / f"D{k}.npz", Motion(skeleton=SK, fps=25.0, positions=p))  # a perfect copy
        frozen = np.repeat(p[:1], len(p), axis=0)
        write_motion(pred / f"D{k}__frozen.npz", Motion(skeleton=SK, fps=25.0, positions=frozen))
    return ref, pred


def test_group_predictions(tmp_path):
    paths = [tmp_path / n for n in ("A.npz", "A__1.npz", "A__x.npz", "B_2.npz")]
    assert {k: len(v) for k, v in group_predictions(paths).items()} == {"A": 3, "B_2": 1}


def test_evaluate_perfect_copies(folders, tmp_path):
    ref, pred = folders
    copies = tmp_path / "copies"
    copies.mkdir()
    for f in ref.glob("*.npz"):
        (copies / f.name).write_bytes(f.read_bytes())
    report = evaluate_dirs(copies, ref, classifier=None, settings=EvalSettings(segment_seconds=6.0))
    m = report["metrics"]
    assert m["fid_k"] == pytest.approx(0.0, abs=1e-6) and m["fid_g"] == pytest.approx(0.0, abs=1e-6)
    assert m["fd_dual_mean_joint_distance_cm"] == 0.0
    assert m["smoothed_energy_ratio"] == pytest.approx(1.0)
    assert report["settings"]["fid_reference"] == "ref" and report["settings"]["segment_seconds"] == 6.0
    assert report["counts"] == {"generated_files": 4, "songs": 4, "samples_per_song": {f"D{k}": 1 for k in range(4)},
                                "reference_dances": 4, "fid_reference_dances": 4}
    assert "bas_bailando" not in m  # no music given


def test_cli_evaluate_writes_report_and_table(folders, tmp_path, capsys):
    ref, pred = folders
    out = tmp_path / "report.json"
    rc = main(["evaluate", "--pred", str(pred), "--ref", str(ref), "-o", str(out), "--no-style",
               "--segment-seconds", "6"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "| FID_k (AIST++) |" in printed and "Stillness share" in printed
    report = json.loads(out.read_text())
    m, real = report["metrics"], report["real"]
    # half of the generated dances are frozen: half of the windows are still, FID_k is large
    assert m["stillness_share"] == pytest.approx(0.5)
    assert real["stillness_share"] == 0.0
    assert m["fid_k"] > 1.0 and real["fid_k"] == pytest.approx(0.0, abs=1e-6)
    assert report["counts"]["samples_per_song"] == {f"D{k}": 2 for k in range(4)}
    assert len(report["per_dance"]) == 8
    assert not list(tmp_path.glob(".report.json*"))  # written atomically, no temp file left


def test_cli_evaluate_with_audio_beats(tmp_path):
    """A 120 BPM click track (beats every 0.5 s) and two dances whose speed minima are known by construction:
    D0 stops on every beat, D1 half a beat (0.25 s) off. The beat tracker's beats sit within one hop
    (256 / 22050 s = 11.6 ms, twice that at most) of the clicks, so for D0 every kinematic beat hits
    (hit rate 1, coverage 15/15) and BAS >= exp(-0.0232² / (2 * 0.05²)) = 0.898; for D1 no kinematic beat is
    within 0.2 s of a music beat (hit rates 0, coverage 16/15) and BAS <= exp(-0.227² / (2 * 0.05²)) < 1e-4."""
    from dancekit.audio import save_wav, synth

    fps = 20.0  # beats at whole frames: 0.5 s = 10 frames, 0.25 s = 5 frames
    ref, pred, audio = tmp_path / "ref", tmp_path / "pred", tmp_path / "audio"
    for d in (ref, pred, audio):
        d.mkdir()
    for k, shift in enumerate((0.0, 0.25)):
        write_motion(ref / f"D{k}.npz", Motion(skeleton=SK, fps=fps, positions=dance(k, seconds=8.0, fps=fps)))
        write_motion(pred / f"D{k}.npz", Motion(skeleton=SK, fps=fps, positions=swing(8.0, fps, shift=shift)))
        save_wav(audio / f"D{k}.wav", synth.click_track(bpm=120, duration=8.0, sr=22050), sr=22050)
    out = tmp_path / "r.json"
    assert main(["evaluate", "--pred", str(pred), "--ref", str(ref), "--audio", str(audio), "-o", str(out),
                 "--no-style", "--segment-seconds", "4"]) == 0
    report = json.loads(out.read_text())
    assert report["settings"]["beat_source"] == "beat_track on the audio files"
    on, off = report["per_dance"]["D0#0"], report["per_dance"]["D1#1"]
    assert on["beat_hit_rate"] == 1.0 and on["beats_alignment_dual"] == 1.0
    assert on["beat_coverage"] == pytest.approx(15 / 15)
    assert 0.898 <= on["bas_bailando"] <= 1.0 and 0.898 <= on["bas_aist"] <= 1.0
    assert off["beat_hit_rate"] == 0.0 and off["beats_alignment_dual"] == 0.0
    assert off["beat_coverage"] == pytest.approx(16 / 15)
    assert off["bas_bailando"] < 1e-4 and off["bas_aist"] < 1e-4
    m = report["metrics"]  # means over the generated dances
    assert m["beat_hit_rate"] == pytest.approx(0.5)
    assert m["bas_bailando"] == pytest.approx((on["bas_bailando"] + off["bas_bailando"]) / 2)


def test_cli_evaluate_unknown_names_fail_cleanly(folders, tmp_path, capsys):
    ref, pred = folders
    write_motion(pred / "NOPE.npz", Motion(skeleton=SK, fps=25.0, positions=dance(9)))
    rc = main(["evaluate", "--pred", str(pred), "--ref", str(ref), "-o", str(tmp_path / "r.json"), "--no-style"])
    assert rc == 2
    assert "NOPE.npz" in capsys.readouterr().err
    with pytest.raises(DatasetError, match="not found"):
        evaluate_dirs(tmp_path / "missing", ref, classifier=None)


def test_format_markdown_skips_missing_rows():
    report = {"metrics": {"fid_k": 1.5}, "real": {"fid_k": 0.0}, "counts": {"generated_files": 1, "songs": 1,
              "fid_reference_dances": 2}, "settings": {"fid_reference": "ref"}, "notes": ["n"]}
    text = format_markdown(report)
    assert "| FID_k (AIST++) | 1.50 | 0.00 |" in text and "BAS" not in text and "- n" in text


def _prepared(root, dances: dict[str, np.ndarray], splits: dict[str, list[str]], beats: np.ndarray):
    """A minimal prepared-dataset folder (the layout of dancekit.data.prepare_tang2018)."""
    meta = {"source": "synthetic", "fps": 25.0, "hop_length": 512, "skeleton": SK.to_dict(),
            "presets": ["revolution"], "genres": ["waltz", "rumba", "chacha", "tango"], "dances": {}}
    for k, (name, p) in enumerate(dances.items()):
        d = root / "dances" / name
        d.mkdir(parents=True)
        write_motion(d / "motion.npz", Motion(skeleton=SK, fps=25.0, positions=p))
        np.savez(d / "features_revolution.npz", features=np.zeros((len(p), 4), np.float32),
                 names=np.asarray(["a", "b", "c", "d"]), beat_times=beats, fps=np.float64(25.0),
                 preset=np.asarray("revolution"))
        meta["dances"][name] = {"genre": "waltz" if k % 2 == 0 else "rumba", "frames": len(p),
                                "audio": ["song.wav", 0.0, len(p) / 25.0]}
    (root / "meta.json").write_text(json.dumps(meta))
    (root / "splits.json").write_text(json.dumps({**splits, "seed": 0}))


def test_evaluate_with_a_prepared_dataset(tmp_path):
    """Generated dances that are not the reference ones, with answers known by construction: D3 (a swing that
    stops on every music beat) moved 3 cm along x and 4 cm along z, D4 with twice its motion."""
    from dancekit.metrics import beat_align_score, kinematic_beats, smoothed_energy

    data = tmp_path / "data"
    dances = {f"D{k}": dance(k, seconds=12.0) for k in (0, 1, 2, 4)}
    dances["D3"] = swing(12.0, 25.0, period=0.8)  # stops every 0.4 s = 10 frames
    beats = 0.4 * np.arange(1, 30)  # 0.4 .. 11.6 s: the music beats, on D3's stops
    _prepared(data, dances, {"train": ["D0", "D1", "D2"], "val": [], "test": ["D3", "D4"]}, beats)
    pred = tmp_path / "pred"
    pred.mkdir()
    moved = (dances["D3"] + np.array([3.0, 0.0, 4.0], np.float32)).astype(np.float32)
    rest = rest_pose().astype(np.float32)
    doubled = (rest + 2.0 * (dances["D4"] - rest)).astype(np.float32)
    write_motion(pred / "D3.npz", Motion(skeleton=SK, fps=25.0, positions=moved))
    write_motion(pred / "D4.npz", Motion(skeleton=SK, fps=25.0, positions=doubled))
    settings = EvalSettings(segment_seconds=4.0)
    report = evaluate_dirs(pred, data, data=data, classifier=None, settings=settings)
    assert report["settings"]["fid_reference"] == "train"
    assert report["settings"]["beat_source"] == "prepared features_revolution.npz beat_times"
    assert report["counts"]["fid_reference_dances"] == 3 and report["counts"]["reference_dances"] == 2

    def bas(p):  # the per-dance BAS computed directly
        return beat_align_score(kinematic_beats(p, fps=25.0), beats, duration=(len(p) - 1) / 25.0)

    d3, d4 = report["per_dance"]["D3#0"], report["per_dance"]["D4#1"]
    # D3: a rigid move of the reference by |(3, 0, 4)| = 5 cm, its stops exactly on the beats
    assert d3["fd_dual_mean_joint_distance_cm"] == pytest.approx(5.0, rel=1e-5)
    assert d3["bas_bailando"] == pytest.approx(1.0) and d3["bas_aist"] == pytest.approx(1.0)
    assert d3["beat_hit_rate"] == 1.0 and d3["beat_coverage"] == 1.0
    # D4: the mean joint distance to its reference and the BAS, computed directly
    direct = float(np.linalg.norm(doubled.astype(np.float64) - dances["D4"], axis=-1).mean())
    assert direct > 1.0 and d4["fd_dual_mean_joint_distance_cm"] == pytest.approx(direct, rel=1e-6)
    assert d4["bas_bailando"] == pytest.approx(bas(doubled), rel=1e-9)
    # twice the motion is twice the (body-relative, smoothed) speed; a rigid move changes no speed
    se3, se4 = (smoothed_energy(dances[n], fps=25.0, skeleton=SK) for n in ("D3", "D4"))
    assert d3["smoothed_energy"] == pytest.approx(se3, rel=1e-5)
    assert d4["smoothed_energy"] == pytest.approx(2.0 * se4, rel=1e-5)
    # the "real" column scores the reference dances themselves, the "generated" one the predictions
    m, real = report["metrics"], report["real"]
    assert real["smoothed_energy"] == pytest.approx((se3 + se4) / 2, rel=1e-5)
    assert m["smoothed_energy"] == pytest.approx((se3 + 2.0 * se4) / 2, rel=1e-5)
    assert m["smoothed_energy_ratio"] == pytest.approx((se3 + 2.0 * se4) / (se3 + se4), rel=1e-5)
    assert real["bas_bailando"] == pytest.approx((1.0 + bas(dances["D4"])) / 2, rel=1e-9)
    assert m["bas_bailando"] == pytest.approx((1.0 + bas(doubled)) / 2, rel=1e-9)
    assert real["fd_dual_mean_joint_distance_cm"] == 0.0
    assert m["fd_dual_mean_joint_distance_cm"] == pytest.approx((5.0 + direct) / 2, rel=1e-5)
    # FID against the training split: both sets are away from it, the doubled motion differently so
    assert real["fid_k"] > 0 and m["fid_k"] > 0 and m["fid_k"] != pytest.approx(real["fid_k"], rel=1e-3)
    # FID against the reference dances themselves: the reference scores 0, the predictions clearly more;
    # moved copies of both (FID_k and FID_g do not see a horizontal translation) score 0 again
    by_ref = evaluate_dirs(pred, data, data=data, classifier=None,
                           settings=EvalSettings(segment_seconds=4.0, fid_reference="ref"))
    assert by_ref["real"]["fid_k"] == pytest.approx(0.0, abs=1e-6)
    assert by_ref["real"]["fid_g"] == pytest.approx(0.0, abs=1e-6)
    assert by_ref["metrics"]["fid_k"] > 1.0
    copies = tmp_path / "copies"
    copies.mkdir()
    for n in ("D3", "D4"):
        shifted = (dances[n] + np.array([3.0, 0.0, 4.0], np.float32)).astype(np.float32)
        write_motion(copies / f"{n}.npz", Motion(skeleton=SK, fps=25.0, positions=shifted))
    moved_only = evaluate_dirs(copies, data, data=data, classifier=None,
                               settings=EvalSettings(segment_seconds=4.0, fid_reference="ref"))["metrics"]
    assert moved_only["fid_k"] == pytest.approx(0.0, abs=1e-4) and moved_only["fid_g"] == pytest.approx(0.0, abs=1e-4)
    # the validation split as the reference: the same dances named as validation dances
    (data / "splits.json").write_text(json.dumps({"train": ["D0", "D1", "D2"], "val": ["D3", "D4"], "test": [],
                                                  "seed": 0}))
    val = evaluate_dirs(pred, data, data=data, classifier=None, settings=settings, split="val")
    assert val["counts"]["reference_dances"] == 2 and val["metrics"]["fid_k"] == pytest.approx(m["fid_k"])
    assert val["per_dance"]["D4#1"]["fd_dual_mean_joint_distance_cm"] == pytest.approx(direct, rel=1e-6)
    with pytest.raises(DatasetError):  # nothing in the (now empty) test split to compare with
        evaluate_dirs(pred, data, data=data, classifier=None, settings=settings)


def test_evaluate_real_dances_with_the_shipped_classifier(tang2018_dir):
    from dancekit.checkpoints import MODELS_DIR
    from dancekit.evaluation import evaluate_motions
    from dancekit.motion.formats import read_tang2018
    from dancekit.pipelines import StylePipeline

    assert (MODELS_DIR / "style" / "config.json").is_file(), f"no packaged style classifier in {MODELS_DIR / 'style'}"
    genres = {"DANCE_C_6": "chacha", "DANCE_R_2": "rumba", "DANCE_W_1": "waltz"}  # test split
    ref = {n: read_tang2018(tang2018_dir / n)[0] for n in genres}
    frozen = {n: Motion(skeleton=m.skeleton, fps=m.fps, positions=np.repeat(m.to_positions()[:1], m.num_frames, 0))
              for n, m in ref.items()}
    pred = {n: [ref[n], frozen[n]] for n in genres}
    report = evaluate_motions(pred, ref, genres=genres, classifier=StylePipeline.from_pretrained(),
                              settings=EvalSettings(segment_seconds=10.0))
    real, m = report["real"], report["metrics"]
    # the feature covariance has eigenvalues from 1e-7 to 3e3: sqrtm's rounding is ~1e-5 here
    assert real["style_acc"] == 1.0 and real["style_fid"] == pytest.approx(0.0, abs=1e-3)
    assert m["style_fid"] > 1.0 and m["style_multimodality"] > 0
    assert len(report["fid_curve"]) >= 10 and report["classifier"]["genres"] == ["waltz", "rumba", "chacha", "tango"]


def test_fid_breakdown_names_a_feature_the_reference_barely_shows(tmp_path):
    """The reference dances keep the right foot down except for 1 s of one dance; the generated ones lift it
    (60 cm: above the 1.2-humerus threshold of Müller's r_foot_raised) the whole time. That one nearly
    constant reference column then decides FID_g, and the report says so. (Lifting the foot also bends
    the knee, so the reference dances bend it often too, knee 30 cm forward: r_knee_bent varies there.)"""
    from dancekit.evaluation import evaluate_motions

    foot = [SK.index(j) for j in ("right_ankle", "right_heel", "right_toe")]
    ref, pred = {}, {}
    for k in range(4):
        p = dance(k, seconds=12.0)
        if k == 0:
            p[25:50, foot, 1] += 60.0  # 1 s of one reference dance
        p[(k * 50) % 300 : (k * 50) % 300 + 150, SK.index("right_knee"), 2] += 30.0
        ref[f"D{k}"] = Motion(skeleton=SK, fps=25.0, positions=p)
        lifted = dance(k + 10, seconds=12.0)
        lifted[:, foot, 1] += 60.0
        pred[f"D{k}"] = [Motion(skeleton=SK, fps=25.0, positions=lifted)]
    report = evaluate_motions(pred, ref, classifier=None, settings=EvalSettings(segment_seconds=4.0))
    top = report["fid_breakdown"]["fid_g"]
    assert top[0]["feature"] == "r_foot_raised" and top[0]["share"] > 0.5
    assert top[0]["mean_z"] > 3.0 and [t["d"] for t in top] == sorted((t["d"] for t in top), reverse=True)
    assert any("FID_g" in n and "r_foot_raised" in n for n in report["notes"])
    assert len(report["fid_breakdown"]["fid_k"]) == 5 and ":" in report["fid_breakdown"]["fid_k"][0]["feature"]
