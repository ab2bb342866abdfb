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
