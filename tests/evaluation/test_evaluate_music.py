"""``dancekit evaluate`` on music (dancekit.evaluation.music): the baselines' known answers and the CLI.

A tiny prepared dataset of two 8-s "test" dances whose real music is an arranged 120 BPM piece (chords, bass,
drums on every beat) rendered with the built-in synthesiser. Expected values are worked out from the
definitions, not from the code: the real music against itself covers and hits every bin it has (BCS = BHS = 1
under A); a click track's beats are its clicks, so a metronome's tempo is exactly the real music's measured
tempo (× 1.2 / × 0.8 for the wrong-tempo ones) and clicks on the dance's kinematic beats have beat F1 = 1
against them; 4 clicks a second put a click in every 1-s bin (G = bins per clip).
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from dancekit.evaluation.music import MusicSettings, evaluate_music, format_music_markdown

SR = 22050
DUR = 8.0
DANCES = ("DANCE_W_1", "DANCE_R_2")


def _piece(bpm: float, root: int, dur: float = DUR):
    """An arranged piece at ``bpm``: (audio at SR, PrettyMIDI)."""
    from dancekit.audio.midi import arrange, synthesize

    fps = 25.0
    T = int(dur * fps)
    beat = np.zeros(T)
    beat[np.round(np.arange(0.25, dur - 0.2, 60.0 / bpm) * fps).astype(int)] = 1.0
    chroma = np.zeros((T, 12))
    chroma[:, [root % 12, (root + 4) % 12, (root + 7) % 12]] = 1.0
    midi = arrange(chroma, beat, fps=fps).midi
    y = synthesize(midi, sr=SR)[: int(dur * SR)]
    return y, midi


@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory):
    """Two test dances with swaying random-walk motion and 120 / 100 BPM music (real music as WAV)."""
    from dancekit.audio.io import save_wav
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.formats import write_motion

    root = tmp_path_factory.mktemp("music_eval") / "data"
    rng = np.random.default_rng(0)
    skel = get_skeleton("tang2018")
    meta_dances, music = {}, {}
    for name, bpm, key in zip(DANCES, (120.0, 100.0), (0, 9)):
        folder = root / "dances" / name
        folder.mkdir(parents=True)
        T = int(DUR * 25)
        t = np.arange(T) / 25.0
        pos = rng.normal(0, 1, (1, skel.num_joints, 3)) * 20 + np.sin(2 * np.pi * t * 1.3)[:, None, None] * 10
        write_motion(folder / "motion.npz", Motion(skeleton=skel, fps=25.0, positions=pos.astype(np.float32)))
        y, midi = _piece(bpm, key)
        save_wav(folder / "real.wav", y, sr=SR)
        music[name] = (y, midi)
        meta_dances[name] = {"genre": "waltz", "frames": T, "audio": [str(folder / "real.wav"), 0.0, DUR]}
    meta = {"source": "test", "fps": 25.0, "hop_length": 512, "skeleton": skel.to_dict(), "presets": [],
            "genres": ["waltz", "rumba", "chacha", "tango"], "dances": meta_dances}
    (root / "meta.json").write_text(json.dumps(meta))
    (root / "splits.json").write_text(json.dumps({"train": [], "val": [], "test": list(DANCES), "seed": 0}))
    return root, music


SETTINGS = MusicSettings(clip_lengths=(2.0, 5.0, None))


@pytest.fixture(scope="module")
def baseline_report(tiny_data):
    root, _ = tiny_data
    return evaluate_music(root, music=None, split="test", settings=SETTINGS)


@pytest.mark.slow
def test_real_music_against_itself_scores_one(baseline_report):
    real = baseline_report["columns"]["real_music"]
    for clip in ("2s", "5s", "whole"):
        assert real[f"bcs_a_{clip}"] == 1.0 and real[f"bhs_a_{clip}"] == 1.0
        assert real[f"bcs_b_{clip}"] == 1.0 and real[f"bhs_b_{clip}"] == 1.0 and real[f"f1_b_{clip}"] == 1.0
    assert real["beat_f1_music"] == 1.0
    assert real["tempo_error"] == 0.0 and real["tempo_hit_share"] == 1.0
    assert real["notes_accuracy"] == 1.0
    # the table shows it, in the real-music column
    table = format_music_markdown(baseline_report)
    row = next(line for line in table.splitlines() if line.startswith("| BHS, A (2-s clips)"))
    header = table.splitlines()[0].split("|")
    assert row.split("|")[header.index(" real music ")].strip() == "1.000"


def test_metronome_rows_are_computed_from_click_times(baseline_report):
    per = baseline_report["per_dance"]
    for name in DANCES:
        ref_bpm = per["real_music"][name]["tempo_ref_bpm"]
        assert 110 < ref_bpm < 130 if name == DANCES[0] else 92 < ref_bpm < 108  # the tracker reads the piece
        # a click track's beats are its clicks: its tempo is exactly the one it was built at
        assert per["metronome"][name]["tempo_bpm"] == pytest.approx(ref_bpm, rel=1e-9)
        assert per["metronome_fast"][name]["tempo_bpm"] == pytest.approx(1.2 * ref_bpm, rel=1e-9)
        assert per["metronome_slow"][name]["tempo_bpm"] == pytest.approx(0.8 * ref_bpm, rel=1e-9)
        assert per["metronome_fast"][name]["tempo_error"] == pytest.approx(0.2, abs=1e-9)
        assert per["metronome"][name]["tempo_hit"] == 1.0 and per["metronome_slow"][name]["tempo_hit"] == 0.0
        # clicks on the kinematic beats are those beats
        assert per["kinematic_clicks"][name]["beat_f1_dance"] == 1.0
        # 4 clicks a second: every 1-s bin of every clip has one (G = bins per clip), under both protocols
        for proto in ("A", "B"):
            assert [c[1] for c in per["dense_clicks"][name]["counts"][f"{proto}_2s"]] == [2, 2, 2, 2]
            assert [c[1] for c in per["dense_clicks"][name]["counts"][f"{proto}_5s"]] == [5]
            assert [c[1] for c in per["dense_clicks"][name]["counts"][f"{proto}_whole"]] == [8]
        assert per["metronome"][name]["notes_accuracy"] is None  # a click track has no notes (NaN, None in JSON)
    cols = baseline_report["columns"]
    assert cols["metronome"]["tempo_hit_share"] == 1.0 and cols["metronome_fast"]["tempo_hit_share"] == 0.0
    assert cols["dense_clicks"]["bhs_a_whole"] == 1.0  # dense clicks game the bins: every reference bin is hit
    assert cols["dense_clicks"]["bcs_a_whole"] >= 1.0
    # another dance's music: the other piece (100 vs 120 BPM) is a tempo miss
    assert cols["other_music"]["tempo_hit_share"] == 0.0
    # the real music (itself an arrangement) re-arranged from its dual target keeps its tempo and its notes
    assert cols["arranged_target"]["tempo_hit_share"] == 1.0
    assert cols["arranged_target"]["notes_accuracy"] == 1.0


def test_report_lists_every_baseline_in_one_table(baseline_report):
    table = format_music_markdown(baseline_report)
    header = table.splitlines()[0]
    for label in ("real music", "metronome (real tempo, random phase)", "metronome +20 %", "metronome −20 %",
                  "dense clicks (4/s)", "clicks on kinematic beats", "another dance's music",
                  "real music's dual target, arranged"):
        assert f" {label} |" in header
    for row in ("BCS, A (2-s clips)", "BHS, B (whole dances)", "HSD, B (5-s clips)", "F1, B (2-s clips)",
                "Beat F1 vs real music", "Beat F1 vs dance kinematic beats", "Tempo error vs real music",
                "Notes accuracy (dual paper)"):
        assert f"| {row}" in table


@pytest.mark.slow
def test_cli_scores_a_music_folder(tiny_data, tmp_path, capsys):
    """A folder holding copies of the real music (WAV) and a MIDI-only piece, through ``dancekit evaluate --music``."""
    from dancekit.cli.main import main

    root, music = tiny_data
    folder = tmp_path / "composed"
    folder.mkdir()
    shutil.copy(root / "dances" / DANCES[0] / "real.wav", folder / f"{DANCES[0]}.wav")
    music[DANCES[1]][1].write(str(folder / f"{DANCES[1]}.mid"))  # MIDI only: rendered by the built-in synth
    out = tmp_path / "report.json"
    rc = main(["evaluate", "--music", str(folder), "--data", str(root), "--split", "test", "--clip-lengths",
               "2,whole", "--no-baselines", "--quiet", "-o", str(out)])
    assert rc == 0
    report = json.loads(out.read_text())
    first = report["per_dance"]["composed"][DANCES[0]]
    assert first["counts"]["A_whole"][0][0] == first["counts"]["A_whole"][0][2]  # a copy hits every reference bin
    assert first["beat_f1_music"] == 1.0
    second = report["per_dance"]["composed"][DANCES[1]]
    assert second["tempo_hit"] == 1.0  # the same arrangement, rendered from its MIDI
    assert 0.0 <= second["notes_accuracy"] <= 1.0
    assert list(report["columns"]) == ["composed"]
    assert "| BCS, A (2-s clips) |" in capsys.readouterr().out


def test_cli_missing_music_is_one_line_error(tiny_data, tmp_path, capsys):
    from dancekit.cli.main import main

    root, _ = tiny_data
    folder = tmp_path / "empty"
    folder.mkdir()
    out = tmp_path / "report.json"
    rc = main(["evaluate", "--music", str(folder), "--data", str(root), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(folder) in err
    assert not out.exists()


def test_cli_music_needs_data(tmp_path, capsys):
    from dancekit.cli.main import main

    rc = main(["evaluate", "--music", str(tmp_path), "-o", str(tmp_path / "r.json")])
    assert rc == 2 and "--data" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_composes_and_scores_with_a_dual_checkpoint(tiny_data, tmp_path, capsys):
    """``--compose``: an untrained tiny dual model composes music for both dances, which is then scored."""
    import torch

    from dancekit.checkpoints import save_pretrained
    from dancekit.cli.main import main
    from dancekit.models.dual import DualConfig, DualModel
    from dancekit.motion import get_skeleton

    root, _ = tiny_data
    cfg = DualConfig(music_dim=53, music_raw_from=40, pose_dim=171, window=10, m2d_d_model=16, m2d_layers=1,
                     m2d_heads=2, m2d_ff=16, d2m_d_model=16, d2m_layers=1, d2m_heads=2, d2m_ff=16)
    torch.manual_seed(0)
    stats = {"music_mean": np.zeros(53, np.float32), "music_std": np.ones(53, np.float32),
             "dance_mean": np.zeros(171, np.float32), "dance_std": np.ones(171, np.float32)}
    ckpt = tmp_path / "dual"
    save_pretrained(ckpt, DualModel(cfg), cfg, stats=stats,
                    extra={"representation": "rot6d", "preset": "dual", "fps": 25.0, "hop_length": 512,
                           "skeleton": get_skeleton("tang2018").to_dict()})
    out = tmp_path / "eval"
    rc = main(["evaluate", "--compose", str(ckpt), "--data", str(root), "--clip-lengths", "whole", "--quiet",
               "-o", str(out)])
    assert rc == 0
    for name in DANCES:
        assert (out / "music" / f"{name}.mid").is_file() and (out / "music" / f"{name}.wav").is_file()
    report = json.loads((out / "report.json").read_text())
    assert report["generation"]["seconds"] == pytest.approx(2 * DUR)
    assert list(report["columns"])[:2] == ["composed", "real_music"]
    assert set(report["per_dance"]["composed"]) == set(DANCES)
    assert (out / "table.md").read_text().startswith(f"| metric | composed ({ckpt}) | real music |")
    assert "composed 16 s of music" in capsys.readouterr().out


def test_composer_targets_name_the_best_click_track_and_the_lost_measures():
    from dancekit.evaluation.music import BASELINE_COLUMNS, composer_targets

    s = MusicSettings(clip_lengths=(None,))
    base = {"bcs_a_whole": 1.0, "bhs_a_whole": 1.0, "bcs_b_whole": 0.5, "bhs_b_whole": 1.0, "f1_b_whole": 0.6,
            "csd_b_whole": 0.1, "hsd_b_whole": 0.0, "beat_f1_dance": 0.2, "tempo_bpm": 100.0, "tempo_error": 0.0,
            "tempo_hit_share": 1.0, "notes_accuracy": float("nan")}
    pooled = {"composed": {**base, "beat_f1_music": 0.50, "tempo_error": 0.02, "tempo_hit_share": 0.5,
                           "bhs_a_whole": 0.7, "beat_f1_dance": 0.3, "bcs_a_whole": 3.0},
              "metronome": {**base, "beat_f1_music": 0.45},
              "dense_clicks": {**base, "beat_f1_music": 0.55},
              "kinematic_clicks": {**base, "beat_f1_music": 0.20}}
    t = composer_targets(pooled, dict(BASELINE_COLUMNS), s)
    assert t["best_click_baseline"] == "dense_clicks"
    assert t["beat_f1_margin"] == pytest.approx(-0.05)
    # worse than the metronome: BHS A (0.7 < 1), tempo error (0.02 > 0), tempo hits (0.5 < 1); not beat F1 (0.5 >
    # 0.45), not the dance's beats (0.3 > 0.2), and BCS A (3 vs 1) has no better direction
    assert t["loses_to_metronome_on"] == ["BHS, A (whole dances)", "Tempo error vs real music (relative)",
                                          "Tempo within ±5 % (share of dances)"]
    assert any("margin -0.050" in n for n in t["notes"])
