"""``dancekit serve``'s live route: the ``/live`` page and the WebSocket ``/api/live`` that dances the browser's
microphone (dancekit.serve.live), through the framework's test client: a song sent as float32 PCM at 48 kHz in
40-ms messages comes back as the pose stream's messages; bad starts, bad audio, a busy server and a missing token
are one line each."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _serve import SR, need, ode_wav

need("fastapi")
need("httpx")
from fastapi.testclient import TestClient  # noqa: E402
from starlette.websockets import WebSocketDisconnect  # noqa: E402

from dancekit.serve import ServeConfig, create_app  # noqa: E402

BASE = "http://127.0.0.1"
WS = "ws://127.0.0.1/api/live"


@pytest.fixture(scope="module")
def pcm48k(tmp_path_factory) -> np.ndarray:
    """6 s of Ode to Joy at 48 kHz, float32: what a browser's AudioContext records."""
    import soxr

    from dancekit.audio import load

    path = ode_wav(tmp_path_factory.mktemp("song") / "ode.wav", 6.0)
    y, _ = load(path, sr=SR)
    return soxr.resample(y, SR, 48000).astype(np.float32)


def client(tmp_path, **kw) -> TestClient:
    return TestClient(create_app(ServeConfig(cache=tmp_path / "cache", workers=0, **kw)), base_url=BASE)


def test_the_live_page_is_the_live_page_in_microphone_mode(tmp_path):
    with client(tmp_path) as c:
        r = c.get("/live")
        assert r.status_code == 200 and '<body data-source="mic">' in r.text and 'id="start"' in r.text
        models = c.get("/api/options").json()["dance_models"]
        assert {n for n, m in models.items() if m["live"]} == {"revolution", "music2dance"}


def test_the_microphone_sent_as_pcm_comes_back_as_pose_frames(tmp_path, pcm48k):
    block = 48000 // 25  # 40 ms
    with client(tmp_path) as c, c.websocket_connect(WS) as ws:
        ws.send_text(json.dumps({"type": "start", "sample_rate": 48000, "model": "revolution", "seed": 0}))
        hello = json.loads(ws.receive_text())
        assert hello["type"] == "hello" and hello["model"] == "revolution" and hello["fps"] == 25.0
        poses = []
        for a in range(0, len(pcm48k), block):
            ws.send_bytes(pcm48k[a : a + block].tobytes())
        ws.send_text(json.dumps({"type": "stop"}))
        while True:
            m = json.loads(ws.receive_text())
            if m["type"] == "end":
                break
            assert m["type"] == "pose"
            poses.append(m)
    frames = [m["frame"] for m in poses]
    # 6 s at 25 fps, every frame: those still waiting for their lookahead when the client stopped are danced then
    # (1 + 76800 // 512 = 151 at the model's 12.8 kHz; one sample fewer after the two resamplings gives 150)
    assert frames == list(range(len(frames))) and 150 <= len(frames) <= 151
    assert np.allclose([m["t"] for m in poses], np.array(frames) / 25.0)
    joints = np.array([m["joints"] for m in poses])
    assert joints.shape[1:] == (len(hello["joint_names"]), 3) and np.isfinite(joints).all()
    travel = np.abs(np.diff(joints, axis=0)).sum(axis=(1, 2))
    assert np.mean(travel[50:] > 0.5) > 0.8  # it dances: the joints move from frame to frame


def test_samples_that_are_not_finite_are_silence_and_the_dance_goes_on(tmp_path, pcm48k):
    """A browser's buffer can hold NaN or infinity: those samples count as silence, every pose stays finite, and
    the song is danced to its last frame."""
    block = 48000 // 25
    y = pcm48k.copy()
    y[20 * block + 7], y[40 * block + 3], y[41 * block] = np.nan, np.inf, -np.inf
    with client(tmp_path) as c, c.websocket_connect(WS) as ws:
        ws.send_text(json.dumps({"type": "start", "sample_rate": 48000}))
        assert json.loads(ws.receive_text())["type"] == "hello"
        for a in range(0, len(y), block):
            ws.send_bytes(y[a : a + block].tobytes())
        ws.send_text(json.dumps({"type": "stop"}))
        poses = []
        while (m := json.loads(ws.receive_text()))["type"] != "end":
            poses.append(m)
    assert [m["frame"] for m in poses] == list(range(len(poses))) and 150 <= len(poses) <= 151
    assert np.isfinite(np.array([m["joints"] for m in poses])).all()


@pytest.mark.parametrize("start, match", [
    ("hello", "must be JSON"),
    (b"\x00\x00\x80?", "must be JSON"),  # audio before the start message
    ({"type": "begin"}, "must be"),
    ({"type": "start"}, "sample_rate must be"),
    ({"type": "start", "sample_rate": 1000}, "sample_rate must be"),
    ({"type": "start", "sample_rate": 44100.5}, "sample_rate must be"),
    ({"type": "start", "sample_rate": 48000, "model": "nope"}, "unknown model 'nope'"),
    ({"type": "start", "sample_rate": 48000, "model": "dual"}, "cannot dance live"),
    ({"type": "start", "sample_rate": 48000, "seed": -1}, "seed must be"),
])
def test_a_bad_start_is_one_line_and_the_socket_closes(tmp_path, start, match):
    with client(tmp_path) as c, c.websocket_connect(WS) as ws:
        if isinstance(start, bytes):
            ws.send_bytes(start)
        else:
            ws.send_text(start if isinstance(start, str) else json.dumps(start))
        m = json.loads(ws.receive_text())
        assert m["type"] == "error" and match in m["detail"] and "\n" not in m["detail"]
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_text()
        assert closed.value.code == 1008


def test_audio_that_is_not_whole_float32_samples_is_refused(tmp_path, monkeypatch):
    """The refusal ends the session: the audio queued before it is not danced, the session not finished."""
    from dancekit.live.session import LiveSession

    calls = []
    real_feed, real_finish = LiveSession.feed, LiveSession.finish
    monkeypatch.setattr(LiveSession, "feed", lambda self, blocks, **kw: calls.append("feed") or real_feed(self, blocks, **kw))
    monkeypatch.setattr(LiveSession, "finish", lambda self, **kw: calls.append("finish") or real_finish(self, **kw))
    with client(tmp_path) as c, c.websocket_connect(WS) as ws:
        ws.send_text(json.dumps({"type": "start", "sample_rate": 16000}))
        assert json.loads(ws.receive_text())["type"] == "hello"
        ws.send_bytes(b"\x00" * 6)
        m = json.loads(ws.receive_text())
        assert m["type"] == "error" and "whole float32 samples" in m["detail"]
        with pytest.raises(WebSocketDisconnect):
            ws.receive_text()
    assert "finish" not in calls


def test_a_second_session_beyond_the_limit_is_told_to_come_back_later(tmp_path):
    with client(tmp_path, max_live=1) as c, c.websocket_connect(WS) as first:
        first.send_text(json.dumps({"type": "start", "sample_rate": 16000}))
        assert json.loads(first.receive_text())["type"] == "hello"
        with c.websocket_connect(WS) as second:
            second.send_text(json.dumps({"type": "start", "sample_rate": 16000}))
            m = json.loads(second.receive_text())
            assert m["type"] == "error" and "try again later" in m["detail"]
            with pytest.raises(WebSocketDisconnect) as closed:
                second.receive_text()
            assert closed.value.code == 1013
    with client(tmp_path, max_live=0) as c, c.websocket_connect(WS) as ws:  # --live 0: no live sessions
        ws.send_text(json.dumps({"type": "start", "sample_rate": 16000}))
        assert "try again later" in json.loads(ws.receive_text())["detail"]


def test_a_server_with_a_token_needs_it_on_the_socket_too(tmp_path):
    with client(tmp_path, token="s3cret") as c:
        with pytest.raises(WebSocketDisconnect) as closed, c.websocket_connect(WS) as ws:
            ws.receive_text()
        assert closed.value.code == 1008
        with c.websocket_connect(WS + "?token=s3cret") as ws:
            ws.send_text(json.dumps({"type": "start", "sample_rate": 16000}))
            assert json.loads(ws.receive_text())["type"] == "hello"


def test_the_server_feeds_blocks_of_the_sessions_length_whatever_the_pieces():
    """Rebuffer: pieces of 1, 7, 64 and 300 samples give the same blocks of 64 samples, in order, each arriving
    when the piece that completed it did; what is left is one last shorter block."""
    from dancekit.serve.live import Rebuffer

    y = np.arange(1000, dtype=np.float32)
    for piece in (1, 7, 64, 300):
        r, blocks = Rebuffer(64), []
        for a in range(0, len(y), piece):
            blocks += [(b, a) for b in r.push(y[a : a + piece], arrival=float(a))]
        assert [len(b.samples) for b, _ in blocks] == [64] * 15
        assert np.array_equal(np.concatenate([b.samples for b, _ in blocks]), y[:960])
        for k, (b, _) in enumerate(blocks):  # the piece that brought sample 64·k + 63
            assert b.arrival == float((64 * k + 63) // piece * piece)
        last = r.rest(arrival=9.0)
        assert np.array_equal(last.samples, y[960:]) and last.arrival == 9.0 and r.rest(arrival=10.0) is None
