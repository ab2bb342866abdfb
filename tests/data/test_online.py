"""`dancekit prepare online`: a prepared dataset copied with the features a live session computes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dancekit.errors import DatasetError, ParameterError
from tests._prepared import write_fake_prepared

SR = 12800


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """The tiny prepared dataset with its dances' audio: one synthetic song, each dance a clip of it."""
    import soundfile as sf

    from dancekit.audio.synth import ode_to_joy

    root = tmp_path_factory.mktemp("online")
    data = write_fake_prepared(root / "data", np.random.default_rng(0))
    song = root / "song.wav"
    sf.write(song, ode_to_joy(sr=SR, bpm=120)[: 8 * SR], SR)
    meta = json.loads((data / "meta.json").read_text())
    for k, (_name, d) in enumerate(sorted(meta["dances"].items())):
        d["audio"] = [str(song), 0.4 * k, 0.4 * k + d["frames"] / 25]
    (data / "meta.json").write_text(json.dumps(meta))
    return data


def test_online_copy_holds_the_rows_of_a_live_session_and_the_source_motion(dataset, tmp_path):
    """Each dance's rows are those of OnlineFeatures fed the dance's clip in 0.04-s blocks (fed here by hand), as
    many as the source's frames; the motion and splits are the source's; meta.json says how they were made."""
    from dancekit.audio import load
    from dancekit.data import PreparedData
    from dancekit.data.online import prepare_online
    from dancekit.features.online import OnlineFeatures

    out = prepare_online(dataset, tmp_path / "live", progress=False)
    src, live = PreparedData(dataset), PreparedData(out)
    assert live.names("train") == src.names("train") and live.names("val") == src.names("val")
    assert live.meta["online_features"]["lookahead_s"] == 0.08 and live.meta["online_features"]["block_s"] == 0.04
    for name in src.names():
        ref = src.audio(name)
        y, _ = load(ref.path, sr=SR, start=ref.start, end=ref.end)
        f = OnlineFeatures(preset="revolution", fps=25, lookahead_s=0.08)
        rows = np.concatenate([f.feed(y[a : a + 512]) for a in range(0, len(y), 512)] + [f.finish()])
        got = live.features(name, "revolution")["features"]
        assert got.shape == src.features(name, "revolution")["features"].shape
        np.testing.assert_array_equal(got, rows[: len(got)])
        np.testing.assert_array_equal(live.motion(name).positions, src.motion(name).positions)


def test_online_settings_are_the_live_sessions_defaults():
    from dancekit.data.online import ONLINE_DEFAULTS
    from dancekit.live import LiveConfig

    c = LiveConfig()
    assert ONLINE_DEFAULTS == {k: getattr(c, k) for k in ONLINE_DEFAULTS}


def test_online_copy_refuses_what_it_cannot_make(dataset, tmp_path, monkeypatch):
    from dancekit.data import online
    from dancekit.data.online import prepare_online

    copied = []
    monkeypatch.setattr(online.shutil, "copy2", lambda *a, **k: copied.append(a))

    with pytest.raises(ParameterError, match="presets revolution and music2dance"):
        prepare_online(dataset, tmp_path / "a", presets=("dual",), progress=False)
    with pytest.raises(DatasetError, match="no 'music2dance' features"):
        prepare_online(dataset, tmp_path / "b", presets=("music2dance",), progress=False)
    with pytest.raises(ParameterError, match="another folder"):
        prepare_online(dataset, dataset, progress=False)
    with pytest.raises(ParameterError, match="unknown online feature setting"):
        prepare_online(dataset, tmp_path / "c", progress=False, hop=3)
    # bad values are refused before anything is written or any worker starts, each naming its setting
    for setting, match in ((dict(tempogram_future="later"), "tempogram_future must be one of"),
                           (dict(lookahead_s="soon"), "lookahead_s must be a number of seconds"),
                           (dict(block_s=0), "block_s must be in"),
                           (dict(context_s=1.0), r"context_s must be a number of seconds in \[5, 60\]"),
                           (dict(beat_window_s=-3), "beat_window_s must be")):
        with pytest.raises(ParameterError, match=match):
            prepare_online(dataset, tmp_path / "d", progress=False, **setting)
    assert not any((tmp_path / n).exists() for n in "abcd") and copied == []
