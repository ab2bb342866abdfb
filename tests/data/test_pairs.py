"""`dancekit prepare pairs`: a folder of the user's songs (synthesised) and motion files (the BVH and AIST++
fixtures, read in place through symlinks, plus an npz) → prepare → `dancekit train` a few steps → `dancekit
dance` with that checkpoint; broken, unmatched and other-skeleton files are reported, not fatal."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import FIXTURES, _need

from dancekit.audio.io import save_wav
from dancekit.audio.synth import click_track
from dancekit.cli.main import main
from dancekit.data import PreparedData, prepare_pairs

ROOT = Path(__file__).resolve().parents[2]
SR = 22050


def _song(path: Path, bpm: float, seconds: float) -> None:
    save_wav(path, click_track(bpm=bpm, duration=seconds, sr=SR), sr=SR)


@pytest.fixture
def pairs_folder(tmp_path) -> Path:
    from dancekit.motion.formats import read_motion, write_motion

    bvh = _need(FIXTURES / "bvh" / "bandai_namco_dance_short_001.bvh")
    pkl = _need(FIXTURES / "aistpp" / "sample_smpl.pkl")
    src = tmp_path / "my dances"
    src.mkdir()
    for name, bpm in [("alpha", 100), ("beta", 120), ("gamma", 90), ("smpl", 110), ("broken", 100), ("lonely", 100)]:
        _song(src / f"{name}.wav", bpm, 9.0)
    (src / "alpha.bvh").symlink_to(bvh)  # read in place
    (src / "beta.bvh").symlink_to(bvh)
    write_motion(src / "gamma.npz", read_motion(bvh).resample(25.0).slice(250, 500))  # an npz of 10 s
    (src / "smpl.pkl").symlink_to(pkl)  # another skeleton than most pairs: reported
    (src / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{ garbage")  # unreadable: reported
    (src / "orphan.npz").write_bytes(b"not even a zip")  # no song: reported
    (src / "pairs.csv").write_text("name,start,end,genre\nalpha,0,8,hiphop\nbeta,1,9,hiphop\ngamma,,,house\n")
    return src


@pytest.mark.slow
def test_prepare_pairs_then_train_then_dance(pairs_folder, tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["prepare", "pairs", str(pairs_folder), "-o", str(data), "--presets", "revolution"]) == 0
    out = capsys.readouterr().out
    report = json.loads((data / "report.json").read_text())
    assert report["prepared"] == ["alpha", "beta", "gamma"]
    reasons = {s["file"]: s["reason"] for s in report["skipped"]}
    assert set(reasons) == {"broken.wav + broken.bvh", "smpl.wav + smpl.pkl", "lonely.wav", "orphan.npz"}
    assert "skeleton" in reasons["smpl.wav + smpl.pkl"] and "no motion" in reasons["lonely.wav"]
    assert "broken.bvh" in out and "skipped 4" in out

    prepared = PreparedData(data)
    meta = json.loads((data / "meta.json").read_text())
    assert meta["genres"] == ["hiphop", "house"] and meta["dances"]["alpha"]["genre"] == "hiphop"
    assert meta["dances"]["alpha"]["frames"] == 200 and meta["dances"]["beta"]["audio"][1:] == [1.0, 9.0]
    for name in report["prepared"]:
        f = prepared.features(name, "revolution")["features"]
        assert len(f) == prepared.frames(name) == prepared.motion(name).num_frames

    run = tmp_path / "run"
    sets = ["steps=3", "batch_size=4", "seq_len=40", "log_every=1", "threads=1", "d_model=16", "n_heads=2",
            "d_ff=32", "window=6", "decoder_hidden=16", "warmup_steps=1"]
    assert main(["train", "revolution", "--data", str(data), "--out", str(run), "--quiet",
                 *[a for s in sets for a in ("--set", s)]]) == 0
    assert (run / "model" / "model.safetensors").is_file()

    dance = tmp_path / "danced"
    assert main(["dance", str(pairs_folder / "lonely.wav"), "--checkpoint", str(run / "model"), "-o", str(dance),
                 "--format", "npz,bvh", "--quiet", "--end", "4"]) == 0
    assert sorted(p.name for p in dance.iterdir()) == ["lonely.bvh", "lonely.npz"]
    pos = np.load(dance / "lonely.npz")["positions"]
    assert pos.shape[1] == prepared.skeleton.num_joints and np.isfinite(pos).all()


@pytest.mark.slow
def test_prepare_pairs_with_workers_and_nothing_usable(pairs_folder, tmp_path):
    out, report = prepare_pairs(pairs_folder, tmp_path / "w2", presets=("revolution",), workers=2, progress=False)
    assert report["prepared"] == ["alpha", "beta", "gamma"]
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "a.wav").write_bytes(b"")
    from dancekit.errors import DatasetError

    with pytest.raises(DatasetError, match="no song and motion"):
        prepare_pairs(empty, tmp_path / "none", progress=False)
    assert not (tmp_path / "none").exists()


def test_workers_get_one_thread_each_and_the_environment_is_restored(monkeypatch):
    """prepare's worker processes inherit one thread each (N workers on N cores); a value the user set is
    kept, and the parent's environment is as before afterwards."""

    from dancekit.data import pairs

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    with pairs._one_thread_each():
        assert os.environ["OMP_NUM_THREADS"] == "1"
        assert os.environ["MKL_NUM_THREADS"] == "3"
    assert "OMP_NUM_THREADS" not in os.environ
    assert os.environ["MKL_NUM_THREADS"] == "3"
