"""dancekit.evaluation and its verbs: evaluate a checkpoint end to end, baselines, comparison tables,
checkpoint selection, classifier scores."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _prepared import write_fake_prepared

from dancekit.cli.main import main
from dancekit.errors import ParameterError


@pytest.fixture(scope="module")
def data_with_audio(tmp_path_factory):
    """The tiny fake prepared dataset, its songs a synthetic 120-BPM click track (train W_1 R_1, val W_2)."""
    import soundfile as sf

    root = tmp_path_factory.mktemp("evaluation")
    data = write_fake_prepared(root / "prepared", np.random.default_rng(0))
    sr = 22050
    y = np.zeros(int(4.0 * sr), np.float32)
    for t in np.arange(0.25, 4.0, 0.5):
        i = int(t * sr)
        y[i : i + 200] = np.hanning(200) * 0.8
    sf.write(root / "clicks.wav", y, sr)
    meta = json.loads((data / "meta.json").read_text())
    for d in meta["dances"].values():
        d["audio"] = [str(root / "clicks.wav"), 0.0, d["frames"] / 25.0]
    (data / "meta.json").write_text(json.dumps(meta))
    return data


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory):
    import torch

    from dancekit.checkpoints import save_pretrained
    from dancekit.models.revolution import RevolutionConfig, RevolutionModel
    from dancekit.motion import get_skeleton

    torch.manual_seed(0)
    model = RevolutionModel(RevolutionConfig(d_model=16, n_heads=2, d_ff=32, decoder_hidden=16))
    stats = {"music_mean": np.zeros(438, np.float32), "music_std": np.ones(438, np.float32),
             "dance_mean": np.zeros(72, np.float32), "dance_std": np.full(72, 10.0, np.float32)}
    meta = {"fps": 25.0, "preset": "revolution", "representation": "positions3d", "hop_length": 512,
            "skeleton": get_skeleton("tang2018").to_dict()}
    return save_pretrained(tmp_path_factory.mktemp("ckpt") / "tiny", model, model.config, stats=stats, extra=meta)


def test_evaluate_checkpoint_end_to_end(tiny_checkpoint, data_with_audio, tmp_path, capsys):
    out = tmp_path / "eval"
    rc = main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
               "--seeds", "0-1", "-o", str(out), "--quiet", "--segment-seconds", "1"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "| FID_k (AIST++) |" in printed and "generated" in printed
    assert sorted(p.name for p in (out / "pred").glob("*.npz")) == ["DANCE_W_2__0.npz", "DANCE_W_2__1.npz"]
    report = json.loads((out / "report.json").read_text())
    assert report["counts"]["samples_per_song"] == {"DANCE_W_2": 2}
    assert report["generation"]["seeds"] == 2 and report["generation"]["split"] == "val"
    assert report["settings"]["fid_reference"] == "train"
    assert report["classifier"]["genres"] == ["waltz", "rumba", "chacha", "tango"]  # the embedded classifier
    m = report["metrics"]
    assert m["style_multimodality"] is not None and m["style_multimodality"] > 0  # two seeds, two dances
    assert m["style_acc"] in (0.0, 0.5, 1.0)
    # the beat sync (on by default): the dances before the warp are kept and the beat metrics compared
    assert sorted(p.name for p in (out / "pred_unwarped").glob("*.npz")) == ["DANCE_W_2__0.npz", "DANCE_W_2__1.npz"]
    bs = report["beat_sync"]
    assert bs["before"]["n_dances"] == bs["after"]["n_dances"] == 2 and report["generation"]["beat_sync"] is True
    if m["bas_bailando"] is None:  # the tiny untrained model may have no speed minima: NaN, written as null
        assert bs["after"]["bas_bailando"] != bs["after"]["bas_bailando"]
    else:
        assert bs["after"]["bas_bailando"] == pytest.approx(m["bas_bailando"])  # "after" is what was scored
    assert "beat sync: BAS" in printed and "seeds: mean pose distance" in printed
    assert report["seed_distance"]["pairs"] == {"seed": 1, "song": 0}
    # the same folder scored by `evaluate --pred` gives the same report
    again = tmp_path / "again.json"
    assert main(["evaluate", "--pred", str(out / "pred"), "--ref", str(data_with_audio), "--data",
                 str(data_with_audio), "--split", "val", "-o", str(again), "--segment-seconds", "1"]) == 0
    assert json.loads(again.read_text())["metrics"] == m


def test_evaluate_flags_are_checked(tiny_checkpoint, data_with_audio, tmp_path, capsys):
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "-o", str(tmp_path / "x")]) == 2
    assert "--data" in capsys.readouterr().err
    assert main(["evaluate", "--pred", str(tmp_path), "-o", str(tmp_path / "r.json")]) == 2
    assert "--ref" in capsys.readouterr().err
    assert main(["evaluate", "--pred", str(tmp_path), "--ref", str(tmp_path), "--seeds", "2",
                 "-o", str(tmp_path / "r.json")]) == 2
    assert "--seeds" in capsys.readouterr().err
    assert main(["evaluate", "--pred", str(tmp_path), "--ref", str(tmp_path), "--beat-sync", "off",
                 "-o", str(tmp_path / "r.json")]) == 2
    assert "--beat-sync" in capsys.readouterr().err


def test_evaluate_first_seed_dances_another_seed_set(tiny_checkpoint, data_with_audio, tmp_path, capsys):
    """--seeds 3-4: the files NAME__0 / NAME__1 hold the dances of seeds 3 and 4 (bit for bit the
    pipeline's), the report records the first seed; the deprecated --first-seed still reads, and a negative
    one is a one-line error naming it."""
    from dancekit.data import PreparedData
    from dancekit.motion import read_motion
    from dancekit.pipelines import load_pipeline

    out = tmp_path / "eval"
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "3-4", "-o", str(out), "--quiet", "--no-style",
                 "--segment-seconds", "1"]) == 0
    ref = PreparedData(data_with_audio).audio("DANCE_W_2")
    want = load_pipeline(str(tiny_checkpoint)).dances(ref.path, seeds=[3, 4], start=ref.start, end=ref.end)
    for k in (0, 1):
        got = read_motion(out / "pred" / f"DANCE_W_2__{k}.npz").positions
        np.testing.assert_array_equal(got, want[k].motion.positions)
    assert json.loads((out / "report.json").read_text())["generation"]["first_seed"] == 3
    capsys.readouterr()
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "1", "--first-seed", "-1", "-o", str(tmp_path / "bad"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "first seed must be a whole number >= 0, got -1" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()  # nothing half-written
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "3-4,9", "-o", str(tmp_path / "bad"), "--quiet"]) == 2
    assert "consecutive" in capsys.readouterr().err
    assert main(["evaluate", "--pred", str(tmp_path), "--ref", str(tmp_path), "--first-seed", "2",
                 "-o", str(tmp_path / "r.json")]) == 2
    assert "--first-seed" in capsys.readouterr().err


def test_baselines_and_compare(data_with_audio, tmp_path, capsys):
    split = {"train": ["DANCE_W_1", "DANCE_R_1"], "val": [], "test": ["DANCE_W_2"], "seed": 0}
    data = tmp_path / "data"
    import shutil

    shutil.copytree(data_with_audio, data)
    (data / "splits.json").write_text(json.dumps(split))
    out = tmp_path / "bl"
    assert main(["baselines", "--data", str(data), "-o", str(out), "--draws", "3"]) == 0
    printed = capsys.readouterr().out
    table = (out / "table.md").read_text()
    assert table.startswith("| metric | ground_truth | mean_pose | random_train (median of 3) | random_train min | "
                            "random_train max | nearest_music |")
    assert printed.endswith(table)
    gt = json.loads((out / "ground_truth.json").read_text())
    frozen = json.loads((out / "mean_pose.json").read_text())
    assert gt["metrics"]["fid_k"] == pytest.approx(gt["real"]["fid_k"])  # the real dances themselves
    assert frozen["metrics"]["stillness_share"] == 1.0
    choices = json.loads((out / "choices.json").read_text())
    assert set(choices) == {"random_train", "nearest_music"}
    assert len(choices["random_train"]) == 3 and all(set(c) == {"DANCE_W_2"} for c in choices["random_train"])
    # draw 0 is the earlier single draw: the first integer of the seeded generator
    assert choices["random_train"][0]["DANCE_W_2"] == split["train"][int(np.random.default_rng(0).integers(2))]
    # each draw is the chosen training dance cropped to the test dance's length, scored on its own
    from dancekit.data import PreparedData
    from dancekit.motion import read_motion

    prepared = PreparedData(data)
    n_test = prepared.motion("DANCE_W_2").num_frames
    summary = json.loads((out / "random_train.json").read_text())
    energies = []  # (FID needs more than one test dance: this fixture has one)
    for k, c in enumerate(choices["random_train"]):
        got = read_motion(out / "random_train_draws" / f"{k:02d}" / "DANCE_W_2.npz").positions
        src = prepared.motion(c["DANCE_W_2"]).to_positions()
        m = min(n_test, len(src))
        np.testing.assert_allclose(got[:m], src[:m], atol=1e-4)
        draw = json.loads((out / "random_train_draws" / f"{k:02d}.json").read_text())
        energies.append(draw["metrics"]["smoothed_energy"])
    key = "smoothed_energy"
    assert summary["metrics"][key] == pytest.approx(sorted(energies)[1])  # the middle of three
    assert summary["min"][key] == pytest.approx(min(energies)) and summary["max"][key] == pytest.approx(max(energies))
    assert main(["baselines", "--data", str(data), "-o", str(tmp_path / "bad"), "--draws", "0"]) == 2
    assert "draws must be a whole number >= 1, got 0" in capsys.readouterr().err
    assert main(["compare", f"gt={out / 'ground_truth.json'}", f"frozen={out / 'mean_pose.json'}"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "| metric | real (test) | gt | frozen |"
    assert any(line.startswith("| Stillness share") and line.endswith("| 1.000 |") for line in lines)
    assert main(["compare", "nonsense"]) == 2


def test_summarize_draws_known_answer():
    """Each metric's own median / min / max over the draws; NaN and missing values left out."""
    from dancekit.evaluation.baselines import summarize_draws

    reports = [{"metrics": {"fid_k": 30.0, "fid_g": 9.0, "acc": None}},
               {"metrics": {"fid_k": 10.0, "fid_g": float("nan"), "acc": None}},
               {"metrics": {"fid_k": 50.0, "fid_g": 13.0, "acc": None}},
               {"metrics": {"fid_k": 20.0, "fid_g": 12.0, "acc": None}}]
    s = summarize_draws(reports)
    assert s["metrics"]["fid_k"] == 25.0 and s["min"]["fid_k"] == 10.0 and s["max"]["fid_k"] == 50.0
    assert s["metrics"]["fid_g"] == 12.0 and s["min"]["fid_g"] == 9.0 and s["max"]["fid_g"] == 13.0
    assert s["metrics"]["acc"] is None and len(s["draws"]) == 4
    with pytest.raises(ParameterError):
        summarize_draws([])


def test_format_value_and_tables():
    from dancekit.evaluation import format_comparison, format_markdown, format_value

    assert format_value(-0.00001, "{:.3f}") == "0.000" and format_value(-0.00001, "{:.3f}", signed_zero=True) == "-0.000"
    assert format_value(None, "{:.2f}") == "–" and format_value(float("nan"), "{:.2f}") == "–"
    report = {"metrics": {"jitter_speed": -1e-6}, "real": {"jitter_speed": 0.04}, "notes": [],
              "counts": {"generated_files": 1, "songs": 1, "fid_reference_dances": 1},
              "settings": {"fid_reference": "ref"}}
    assert "| 0.0000 | 0.0400 |" in format_markdown(report)
    # the published comparison tables keep the sign of a rounded zero (docs/research/)
    assert "| 0.0400 | -0.0000 |" in format_comparison([("a", report)])
    with pytest.raises(ParameterError):
        format_comparison([])


def test_score_classifier_style_and_errors(data_with_audio, tiny_checkpoint, tmp_path, capsys):
    out = tmp_path / "scores.json"
    assert main(["score-classifier", "style", "--data", str(data_with_audio), "-o", str(out)]) == 0
    (scores,) = json.loads(out.read_text())
    assert scores["family"] == "style" and scores["test"] is None
    assert scores["train"]["n_dances"] == 2 and scores["val"]["n_dances"] == 1
    assert "train: 2 dances" in capsys.readouterr().out
    assert main(["score-classifier", str(tiny_checkpoint), "--data", str(data_with_audio)]) == 2
    assert "not a classifier" in capsys.readouterr().err


def test_steering_needs_genres(tiny_checkpoint, data_with_audio):
    from dancekit.data import PreparedData
    from dancekit.evaluation import load_classifier, steering
    from dancekit.pipelines import load_pipeline

    style, _ = load_classifier()
    with pytest.raises(ParameterError, match="offers no genre"):
        steering(load_pipeline(tiny_checkpoint), PreparedData(data_with_audio), style, split="val")


def test_select_checkpoint_on_a_tiny_run(data_with_audio, tmp_path, capsys):
    from dancekit.evaluation.selection import candidates, step_of, val_losses

    run = tmp_path / "run"
    assert main(["train", "revolution", "--data", str(data_with_audio), "--out", str(run), "--quiet",
                 "--set", "d_model=16", "--set", "n_heads=2", "--set", "d_ff=32", "--set", "decoder_hidden=16",
                 "--set", "seq_len=40", "--set", "batch_size=2", "--set", "steps=2", "--set", "ckpt_every=1",
                 "--set", "val_every=1", "--set", "threads=1"]) == 0
    found = candidates(run)
    assert [c.name for c in found][:2] == ["step_0000001", "step_0000002"]
    losses = val_losses(run)
    assert sorted(losses) == [1, 2] and step_of(run / "best", losses) == min(losses, key=losses.get)
    capsys.readouterr()
    assert main(["select-checkpoint", "--run", str(run), "--data", str(data_with_audio), "--seeds", "0-0",
                 "--quiet", "--install", str(tmp_path / "chosen")]) == 0
    report = json.loads((run / "selection.json").read_text())
    assert report["split"] == "val" and len(report["candidates"]) == len(found)
    assert {"style", "dance_accuracy", "stillness_max", "val_loss"} <= set(report["chosen"])
    assert (tmp_path / "chosen" / "model.safetensors").is_file()
    assert "chosen:" in capsys.readouterr().out


def test_steering_dances_each_genre_through_a_pipelines_dances_with_one_genre(data_with_audio):
    """Regression: ``steering`` gave a pipeline's ``dances`` a list of genres, which Dance Revolution's (one
    genre per call) refused ("unknown genre [...]"), so ``dancekit steering --checkpoint revolution`` failed."""
    from dancekit.data import PreparedData
    from dancekit.evaluation import load_classifier, steering
    from dancekit.motion import Motion, get_skeleton
    from dancekit.pipelines.base import DanceResult

    sk = get_skeleton("tang2018")
    base = np.load(Path(__file__).parents[1] / "golden" / "default_model.npz")["none_seed3"]
    calls = []

    class OneGenrePipeline:
        genres = ["waltz", "tango"]

        def dances(self, path, *, seeds, genre=None, start=None, end=None):
            if not isinstance(genre, str) or genre not in self.genres:
                raise ParameterError(f"unknown genre {genre!r} for this model")
            calls.append((genre, list(seeds)))
            # each (genre, seed) its own dance: the pose scaled so that the two genres move differently
            scale = 1.0 if genre == "waltz" else 0.2
            return [DanceResult(motion=Motion(skeleton=sk, fps=25.0, positions=base * scale + s), model="fake",
                                seed=s) for s in seeds]

    style, _ = load_classifier()
    data = PreparedData(data_with_audio)
    out = steering(OneGenrePipeline(), data, style, split="val", seeds=2, progress=False)
    songs = data.names("val")
    assert out["n"] == len(songs) * 2 * 2
    assert sorted(calls) == sorted([(g, [0, 1]) for _ in songs for g in ("waltz", "tango")])
    assert sum(sum(row.values()) for row in out["matrix"].values()) == out["n"]
    assert set(out["per_song"][songs[0]]) == {"waltz__0", "waltz__1", "tango__0", "tango__1"}


def test_seed_sets_score_each_set_of_seeds_as_evaluate_scores_it_alone(tiny_checkpoint, data_with_audio, tmp_path,
                                                                        capsys):
    """--seed-sets 2 on 4 seeds: each set's FID_k / FID_g is what `evaluate --pred` gives on a folder holding only
    that set's dances; --seed-sets 1 is the report's own FID."""
    import shutil

    out = tmp_path / "eval"
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "4", "--seed-sets", "2", "-o", str(out), "--quiet", "--no-style",
                 "--segment-seconds", "1"]) == 0
    assert "seed sets (2 x 2 seeds): FID_k" in capsys.readouterr().out
    report = json.loads((out / "report.json").read_text())
    sets = report["seed_sets"]
    assert sets["sets"] == 2 and sets["set_size"] == 2
    for s, row in enumerate(sets["per_set"]):
        alone = tmp_path / f"set{s}"
        alone.mkdir()
        for k in (2 * s, 2 * s + 1):
            shutil.copy(out / "pred" / f"DANCE_W_2__{k}.npz", alone / f"DANCE_W_2__{k}.npz")
        rep = tmp_path / f"set{s}.json"
        assert main(["evaluate", "--pred", str(alone), "--ref", str(data_with_audio), "--data", str(data_with_audio),
                     "--split", "val", "-o", str(rep), "--no-style", "--segment-seconds", "1"]) == 0
        m = json.loads(rep.read_text())["metrics"]
        assert row["seed_index"] == [2 * s, 2 * s + 1]
        assert row["fid_k"] == pytest.approx(m["fid_k"], rel=1e-9)
        assert row["fid_g"] == pytest.approx(m["fid_g"], rel=1e-9)
    values = [r["fid_k"] for r in sets["per_set"]]
    assert sets["fid_k"]["min"] == min(values) and sets["fid_k"]["max"] == max(values)
    one = tmp_path / "one.json"
    assert main(["evaluate", "--pred", str(out / "pred"), "--ref", str(data_with_audio), "--data", str(data_with_audio),
                 "--split", "val", "-o", str(one), "--no-style", "--segment-seconds", "1", "--seed-sets", "1"]) == 0
    rep = json.loads(one.read_text())
    assert rep["seed_sets"]["per_set"][0]["fid_k"] == pytest.approx(rep["metrics"]["fid_k"], rel=1e-9)


def test_seed_sets_and_ablate_stages_flags_are_checked(tiny_checkpoint, data_with_audio, tmp_path, capsys):
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "0-3", "--seed-sets", "3", "-o", str(tmp_path / "x"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--seed-sets 3: 4 seeds (--seeds) is not a multiple of 3" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()  # checked before any dance is written
    assert main(["evaluate", "--pred", str(tmp_path), "--ref", str(tmp_path), "--ablate-stages",
                 "-o", str(tmp_path / "r.json")]) == 2
    assert "--ablate-stages go with --checkpoint" in capsys.readouterr().err


def test_ablate_stages_ends_at_the_dances_evaluate_scores(tiny_checkpoint, data_with_audio, tmp_path, capsys):
    """--ablate-stages: one FID per stage, from the network's output to the finished dance; the last stage's dances
    are the ones the report scores, so its FID is the report's."""
    from dancekit.pipelines.stages import STAGE_NAMES

    out = tmp_path / "eval"
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "0-1", "--ablate-stages", "-o", str(out), "--quiet", "--no-style",
                 "--segment-seconds", "1"]) == 0
    assert "| FID after | raw | clean_up |" in capsys.readouterr().out
    report = json.loads((out / "report.json").read_text())
    table = report["stage_ablation"]
    assert table["stages"] == ["raw", *STAGE_NAMES] and table["dances"] == 2 and table["reference"] == "train"
    for key in ("fid_k", "fid_g"):
        assert table[key]["beat_sync"]["fid"] == pytest.approx(report["metrics"][key], rel=1e-9)
        for row in table[key].values():
            assert row["mean_term"] + row["cov_term"] == pytest.approx(row["fid"])


def test_ablate_stages_dances_the_genre_evaluate_asks_for(tiny_checkpoint, data_with_audio, tmp_path, monkeypatch):
    """--ablate-stages with --genre: the ablation's dances are asked for the same genre as the scored ones (they
    were danced as "auto" whatever --genre said)."""
    import dancekit.pipelines as pipelines

    asked = []
    real_load = pipelines.load_pipeline

    def load(*args, **kwargs):
        pipe = real_load(*args, **kwargs)
        real_dances = pipe.dances

        def dances(*a, **kw):
            asked.append(kw.get("genre", "<not given>"))
            return real_dances(*a, **kw)
        pipe.dances = dances
        return pipe
    monkeypatch.setattr(pipelines, "load_pipeline", load)
    out = tmp_path / "eval"
    assert main(["evaluate", "--checkpoint", str(tiny_checkpoint), "--data", str(data_with_audio), "--split", "val",
                 "--seeds", "0-1", "--genre", "none", "--ablate-stages", "-o", str(out), "--quiet", "--no-style",
                 "--segment-seconds", "1"]) == 0
    assert len(asked) >= 2 and set(asked) == {"none"}
    report = json.loads((out / "report.json").read_text())
    assert report["stage_ablation"]["genre"] == "none"
    assert report["stage_ablation"]["fid_k"]["beat_sync"]["fid"] == pytest.approx(report["metrics"]["fid_k"],
                                                                                   rel=1e-9)


def test_fid_against_its_own_reference_is_zero_and_grows_when_scaled():
    """Known answers of the per-stage FID: dances equal to the reference score 0 (up to the sqrtm's rounding);
    the same dances three times as large (and fast) score far from it, through the features' mean too."""
    from dancekit.evaluation.ablation import fid_against
    from dancekit.motion import get_skeleton

    sk = get_skeleton("tang2018")
    rng = np.random.default_rng(3)
    ref = [np.cumsum(rng.normal(0, 1.0, (100, sk.num_joints, 3)), axis=0) for _ in range(4)]
    for kind in ("kinetic", "geometric"):
        same = fid_against(ref, ref, fps=25.0, skeleton=sk, kind=kind, segment_seconds=1.0)
        assert abs(same["fid"]) < 1e-6 and abs(same["mean_term"]) < 1e-12
    moved = fid_against(ref, [r * 3.0 for r in ref], fps=25.0, skeleton=sk, kind="kinetic", segment_seconds=1.0)
    assert moved["fid"] > 1.0 and moved["mean_term"] > 0
