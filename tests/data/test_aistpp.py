"""`dancekit prepare aistpp` on a tiny AIST++ release built here from the AIST++ pkl fixture (read in place
through symlinks) and synthesised songs: official splits kept, ignored / songless / broken / unsplit
sequences reported, not fatal; two worker processes give the same dataset as one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import FIXTURES, _need

from dancekit.audio.io import save_wav
from dancekit.audio.synth import click_track
from dancekit.cli.main import main
from dancekit.data import PreparedData
from dancekit.data.aistpp import music_id, prepare_aistpp
from dancekit.errors import DatasetError

GOOD = ["gBR_sBM_cAll_d04_mBR0_ch01", "gPO_sFM_cAll_d10_mPO1_ch02", "gBR_sBM_cAll_d05_mBR0_ch03",
        "gKR_sBM_cAll_d28_mKR3_ch05"]


@pytest.fixture
def release(tmp_path) -> Path:
    pkl = _need(FIXTURES / "aistpp" / "sample_smpl.pkl")
    src = tmp_path / "aist_plusplus_final"
    for d in ("motions", "wavs", "splits"):
        (src / d).mkdir(parents=True)
    for name in [*GOOD, "gLO_sBM_cAll_d13_mLO2_ch04", "gHO_sBM_cAll_d19_mHO9_ch01", "gJS_sBM_cAll_d01_mJS4_ch02"]:
        (src / "motions" / f"{name}.pkl").symlink_to(pkl)
    (src / "motions" / "gWA_sBM_cAll_d25_mWA5_ch01.pkl").write_bytes(b"\x80\x04broken pickle")
    (src / "motions" / "notes.txt").write_text("hello")
    for mid, bpm in [("mBR0", 110), ("mPO1", 120), ("mLO2", 100), ("mKR3", 95), ("mJS4", 105), ("mWA5", 90)]:
        save_wav(src / "wavs" / f"{mid}.wav", click_track(bpm=bpm, duration=3.0, sr=22050), sr=22050)
    (src / "splits" / "crossmodal_train.txt").write_text(f"{GOOD[0]}\n{GOOD[2]}\ngWA_sBM_cAll_d25_mWA5_ch01\n"
                                                        f"{GOOD[3]}\n")
    (src / "splits" / "crossmodal_val.txt").write_text(f"{GOOD[1]}\n")
    (src / "splits" / "crossmodal_test.txt").write_text("gLO_sBM_cAll_d13_mLO2_ch04\n")
    (src / "ignore_list.txt").write_text("gLO_sBM_cAll_d13_mLO2_ch04\n")
    return src


def test_music_id():
    assert music_id("gBR_sBM_cAll_d04_mBR0_ch01") == ("BR", "mBR0")
    assert music_id("gJB_sFM_c01_d09_mJB5_ch10") == ("JB", "mJB5")
    assert music_id("my_dance") is None


@pytest.mark.slow
def test_prepare_aistpp_reports_and_keeps_official_splits(release, tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["prepare", "aistpp", str(release), "-o", str(data), "--presets", "revolution", "--workers", "2"]) == 0
    out = capsys.readouterr().out
    report = json.loads((data / "report.json").read_text())
    assert report["prepared"] == sorted(GOOD)
    reasons = {s["file"]: s["reason"] for s in report["skipped"]}
    assert reasons["motions/gLO_sBM_cAll_d13_mLO2_ch04.pkl"] == "in ignore_list.txt"
    assert "no song mHO9" in reasons["motions/gHO_sBM_cAll_d19_mHO9_ch01.pkl"]
    assert reasons["motions/gJS_sBM_cAll_d01_mJS4_ch02.pkl"] == "in none of the crossmodal splits"
    assert "mWA5.wav + gWA_sBM_cAll_d25_mWA5_ch01.pkl" in reasons and "notes.txt" in " ".join(reasons)
    assert len(reasons) == 5 and "skipped 5" in out
    splits = json.loads((data / "splits.json").read_text())
    assert (splits["train"], splits["val"], splits["test"]) == (sorted([GOOD[0], GOOD[2], GOOD[3]]), [GOOD[1]], [])
    meta = json.loads((data / "meta.json").read_text())
    assert meta["source"] == "aistpp" and meta["genres"] == ["BR", "KR", "PO"] and meta["skeleton"]["name"] == "smpl"
    from dancekit.motion.formats import read_motion

    frames = read_motion(FIXTURES / "aistpp" / "sample_smpl.pkl").resample(25.0).num_frames  # from 60 fps
    prepared = PreparedData(data)
    for name in GOOD:
        assert prepared.frames(name) == prepared.motion(name).num_frames == frames
        assert prepared.features(name, "revolution")["features"].shape == (frames, 438)
    # one worker gives the same dataset (workers run BLAS on one thread each: features equal to float32 noise)
    one, _ = prepare_aistpp(release, tmp_path / "one", presets=("revolution",), workers=1, progress=False)
    for name in GOOD:
        a, b = PreparedData(one), prepared
        np.testing.assert_allclose(a.features(name, "revolution")["features"],
                                   b.features(name, "revolution")["features"], rtol=0, atol=1e-4)
        np.testing.assert_array_equal(a.motion(name).to_positions(), b.motion(name).to_positions())


def test_not_a_release(tmp_path):
    with pytest.raises(DatasetError, match="not an AIST\\+\\+ release"):
        prepare_aistpp(tmp_path, tmp_path / "out")
    assert not (tmp_path / "out").exists()
