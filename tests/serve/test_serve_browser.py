"""``dancekit serve`` in a real browser: Debian's Chromium driven by Playwright (its Python package only: the
browser is the system's, never downloaded) through the dance page: upload → progress → the 3D player
playing → downloads that are valid files. Without Chromium it skips, on CI (``CI=true``) it fails."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
from _media import chromium, stream_info
from _serve import Server, need, ode_wav

need("fastapi")
sync_api = need("playwright.sync_api")

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--autoplay-policy=no-user-gesture-required"]


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float32)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    srv = Server(tmp_path_factory.mktemp("serve") / "cache", "--workers", "1")
    yield srv
    srv.stop()


@pytest.mark.slow
def test_upload_progress_playing_player_and_downloads(server, tmp_path):
    exe = chromium()
    song = ode_wav(tmp_path / "ode.wav", 8.0)
    with sync_api.sync_playwright() as p:
        # Playwright gives every launch a fresh temporary profile (--user-data-dir)
        browser = p.chromium.launch(executable_path=exe, headless=True, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1100, "height": 1000}, accept_downloads=True)
            page.goto(server.url + "/")
            page.wait_for_selector("#model option", state="attached")
            assert page.locator("#genre option").first.inner_text().startswith("auto")
            # a bad upload: the page shows the server's one-line reason
            fake = tmp_path / "notes.mp3"
            fake.write_text("my notes, not a song\n" * 10)
            page.set_input_files("#file", str(fake))
            page.click("#go")
            page.wait_for_function("document.getElementById('error').textContent.length > 0")
            assert "notes.mp3 is not audio" in page.inner_text("#error")
            page.set_input_files("#file", str(song))
            assert "ode.wav" in page.inner_text("#song-name")
            page.click("#go")
            # progress: the bar and its message while the job runs
            page.wait_for_selector("#progress", state="visible")
            messages = set()
            deadline = time.monotonic() + 120
            while not page.locator("#frame").get_attribute("src") and time.monotonic() < deadline:
                messages.add(page.inner_text("#msg"))
                time.sleep(0.1)
            assert page.locator("#frame").get_attribute("src"), f"no player; messages: {messages}; " \
                f"error: {page.inner_text('#error')}"
            assert messages - {""}, "no progress message was shown"
            # the player: play, two screenshots of its canvas that differ, the time display advancing
            frame = page.frame_locator("#frame")
            frame.locator("#dk-canvas").wait_for()
            frame.locator("#dk-play").click()
            time.sleep(1.0)
            t1, shot1 = frame.locator("#dk-time").inner_text(), frame.locator("#dk-canvas").screenshot()
            time.sleep(1.5)
            t2, shot2 = frame.locator("#dk-time").inner_text(), frame.locator("#dk-canvas").screenshot()
            a, b = _pixels(shot1), _pixels(shot2)
            assert a.std() > 10, "the canvas is blank"
            assert np.abs(a - b).mean() > 0.5, "the canvas did not change while playing"
            seconds = [float(t.split("/")[0].split(":")[0]) * 60 + float(t.split("/")[0].split(":")[1]) for t in (t1, t2)]
            assert seconds[1] > seconds[0], (t1, t2)
            # the downloads, once the job is done
            page.wait_for_selector("#downloads a[data-name='ode.glb']", timeout=180_000)
            assert "0:08" in page.inner_text("#summary") or "8.0 s" in page.inner_text("#summary")
            got = {}
            for name in ("ode.glb", "ode.mp4"):
                with page.expect_download() as info:
                    page.click(f"#downloads a[data-name='{name}']")
                got[name] = tmp_path / name
                info.value.save_as(got[name])
            names = set(page.locator("#downloads a").evaluate_all("els => els.map(e => e.dataset.name)"))
            assert names == {"ode.html", "ode.mp4", "ode.glb", "ode.bvh", "ode_humanoid.bvh", "ode.pkl", "ode.npz",
                             "ode_openpose.zip", "ode_coco17.zip"}
        finally:
            browser.close()
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(got["ode.glb"]))
    assert gltf.animations and gltf.skins and gltf.meshes
    info = stream_info(got["ode.mp4"])
    assert info["video"] and info["audio"], info
    assert abs(info["video_s"] - 8.0) < 0.2 and abs(info["audio_s"] - 8.0) < 0.2, info


@pytest.mark.slow
def test_the_live_page_dances_to_the_browsers_microphone(server, tmp_path):
    """/live in Chromium, its microphone a song (Chromium's fake capture device plays a wav): the button starts
    it, the poses come back over /api/live in order, and the figure moves."""
    exe = chromium()
    song = ode_wav(tmp_path / "mic.wav", 30.0)
    args = [*FLAGS, "--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream",
            f"--use-file-for-fake-audio-capture={song}"]
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=args)
        try:
            context = browser.new_context(viewport={"width": 640, "height": 480})
            context.grant_permissions(["microphone"], origin=server.url)
            page = context.new_page()
            page.goto(server.url + "/live")
            page.wait_for_selector("#model option", state="attached")
            assert page.locator("#model").input_value() == "revolution"
            page.click("#start")
            page.wait_for_function("window.live.frames > 25 || window.live.error", timeout=90000)
            assert not page.evaluate("window.live.error"), page.evaluate("window.live.error")
            first = page.evaluate("({frame: window.live.lastFrame, t: window.live.lastT})")
            shot1 = page.screenshot()
            page.wait_for_function(f"window.live.lastFrame > {first['frame']} + 25", timeout=60000)
            shot2 = page.screenshot()
            later = page.evaluate("({frame: window.live.lastFrame, t: window.live.lastT, sent: window.live.sentBlocks,"
                                  " joints: window.live.hello.joint_names.length, latency: window.live.latency,"
                                  " music: window.live.musicFrames})")
            page.click("#stop")
            page.wait_for_function("window.live.ended || window.live.closed", timeout=30000)
        finally:
            browser.close()
    assert later["frame"] > first["frame"] + 25 and later["t"] > first["t"]
    assert later["sent"] > 50 and later["joints"] == 23 and 0 <= later["latency"] < 2.0
    assert later["music"] > 25  # danced to the song the microphone heard, not calmed as in silence
    a, b = _pixels(shot1), _pixels(shot2)
    figure = np.abs(a - np.array([0x15, 0x17, 0x1C])).sum(-1) > 60  # not the page's background
    assert figure.sum() > 500, "no figure drawn"
    assert (np.abs(a - b).sum(-1) > 60).sum() > 200, "the figure did not move"


@pytest.mark.slow
def test_the_live_page_dances_to_a_file_played_in_the_browser(server, tmp_path):
    """/live with a song picked instead of the microphone: it plays in the page once the model is ready, is sent as
    the microphone would be, and the poses come back danced to music; the song's end stops the session."""
    exe = chromium()
    song = ode_wav(tmp_path / "pick.wav", 6.0)
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 640, "height": 480})
            page.goto(server.url + "/live")
            page.wait_for_selector("#model option", state="attached")
            page.set_input_files("#file", str(song))
            page.wait_for_function("window.live.frames > 50 || window.live.error", timeout=90000)
            assert not page.evaluate("window.live.error"), page.evaluate("window.live.error")
            page.wait_for_function("window.live.ended", timeout=60000)  # the song ended: stop sent, end received
            done = page.evaluate("({frames: window.live.frames, music: window.live.musicFrames, t: window.live.lastT,"
                                 " disabled: document.getElementById('start').disabled})")
        finally:
            browser.close()
    # 6 s is 151 frames; the page may send a few 40-ms blocks of silence before the song starts playing (it plays
    # once the model is ready) or before its end is signalled, more on a loaded machine: up to 6.4 s
    assert 100 <= done["frames"] <= 161 and 4.0 <= done["t"] <= 6.4 and done["disabled"] is False
    assert done["music"] > 50  # danced to the song, not calmed as in silence
