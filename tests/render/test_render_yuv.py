"""The mp4's frames are drawn in Y'CbCr (BT.601, limited range) and piped to ffmpeg as yuv420p.

Known answers: the BT.601 values of the 100 % colour bars, and the yuv420p plane layout of a hand-made frame.
The frames must show what the RGB frames show: they are compared after converting back, and so is a decoded mp4.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from PIL import Image
from test_render import FPS, PARENTS, SIDES, figure

from dancekit.errors import ExternalToolError, ParameterError
from dancekit.render import RenderOptions, render_mp4
from dancekit.render._ffmpeg import ffmpeg_exe
from dancekit.render._scene import prepare_scene
from dancekit.render.video import FrameRenderer, _median, _square_wave, _to_mode, yuv420

# ITU-R BT.601 in 8 bits, limited range: the 100 % colour bars (Y', Cb, Cr), as published in the standard's tables
BARS = {
    (255, 255, 255): (235, 128, 128),
    (0, 0, 0): (16, 128, 128),
    (255, 0, 0): (81, 90, 240),
    (0, 255, 0): (145, 54, 34),
    (0, 0, 255): (41, 240, 110),
    (255, 255, 0): (210, 16, 146),
    (0, 255, 255): (170, 166, 16),
    (255, 0, 255): (106, 202, 222),
}


def to_rgb(ycc: np.ndarray) -> np.ndarray:
    """BT.601 limited-range Y'CbCr (..., 3) back to RGB floats, with the standard's inverse."""
    y, cb, cr = (ycc[..., i].astype(np.float64) for i in range(3))
    y = (y - 16.0) * 255.0 / 219.0
    cb = (cb - 128.0) * 255.0 / 224.0
    cr = (cr - 128.0) * 255.0 / 224.0
    r = y + 1.402 * cr
    g = y - 0.344136 * cb - 0.714136 * cr
    b = y + 1.772 * cb
    return np.stack([r, g, b], axis=-1)


@pytest.mark.parametrize("rgb, ycc", sorted(BARS.items()))
def test_bt601_colour_bars(rgb, ycc):
    assert tuple(int(v) for v in _to_mode(rgb, "YCbCr")) == ycc
    assert tuple(int(v) for v in _to_mode(rgb, "RGB")) == rgb


def test_yuv420_plane_layout():
    h, w = 4, 6
    y = np.arange(h * w, dtype=np.uint8).reshape(h, w) * 3
    # each 2 x 2 block of Cb holds 10, 20, 30, 40 plus a per-block offset: its mean is 25 + offset
    block = np.array([[10, 20], [30, 40]], np.uint8)
    off = np.array([[0, 50, 100], [150, 200, 1]], np.uint8)
    cb = np.kron(np.ones((2, 3), np.uint8), block) + np.kron(off, np.ones((2, 2), np.uint8))
    cr = 255 - cb
    img = Image.frombytes("YCbCr", (w, h), np.stack([y, cb, cr], axis=-1).tobytes())
    out = np.frombuffer(yuv420(img), np.uint8)
    assert out.size == h * w * 3 // 2
    assert np.array_equal(out[: h * w].reshape(h, w), y)
    assert np.array_equal(out[h * w : h * w * 5 // 4].reshape(2, 3), 25 + off)
    assert np.array_equal(out[h * w * 5 // 4 :].reshape(2, 3), 255 - 25 - off)


def test_renderer_mode_is_checked():
    sc = prepare_scene(figure(0.2), parents=PARENTS, fps=FPS, unit_scale=1.0)
    with pytest.raises(ParameterError, match="mode must be one of RGB, YCbCr, got 'RGBA'"):
        FrameRenderer(sc, width=64, height=48, mode="RGBA")


@pytest.mark.parametrize("fig", ["stick", "body"])
def test_ycbcr_frames_show_the_rgb_frames(fig):
    sc = prepare_scene(figure(1.0, speed=0.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    rgb = FrameRenderer(sc, width=160, height=120, figure=fig)
    ycc = FrameRenderer(sc, width=160, height=120, figure=fig, mode="YCbCr")
    for t in (0, 12, 24):
        a = np.asarray(rgb.render(t)).astype(np.float64)
        im = ycc.render(t)
        assert im.mode == "YCbCr" and im.size == (160, 120)
        err = np.abs(to_rgb(np.asarray(im)) - a).max(axis=-1)
        # 8-bit Y'CbCr has fewer levels than RGB (219 luma steps): the round trip alone costs about 1 level
        print(f"{fig} frame {t}: mean error {err.mean():.3f}, max {err.max():.2f} levels")
        assert err.mean() < 1.2 and err.max() < 6.0


@pytest.mark.parametrize("fig", ["stick", "body"])
def test_render_yuv420_is_yuv420_of_the_frame(fig):
    """The mp4 path averages the chroma of the figure's region only: the same bytes as the whole frame's average."""
    sc = prepare_scene(figure(2.0, speed=1.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    r = FrameRenderer(sc, width=160, height=120, figure=fig, mode="YCbCr", azimuth=90.0)
    for t in range(0, sc.num_frames, 7):
        assert r.render_yuv420(t) == yuv420(r.render(t)), t
    # a camera so close that the figure leaves the frame on some side
    r = FrameRenderer(sc, width=64, height=48, figure=fig, mode="YCbCr", fov=5.0)
    assert r.render_yuv420(20) == yuv420(r.render(20))


def _plain_square_wave(off: np.ndarray, c: float, a: np.ndarray) -> np.ndarray:
    """The floor's box-filtered square wave as first written (float32): clip(a (|((x + 1.5) mod 2) - 1| - 0.5), -1, 1)
    of x = off + c tiles."""
    x = off + np.float32(c + 1.5)
    x = x - 2.0 * np.floor(x * np.float32(0.5))
    return np.clip((np.abs(x - 1.0) - 0.5) * a, -1.0, 1.0)


def test_square_wave_is_the_plain_formula():
    """The floor's square wave, from halved offsets and doubled gains in fewer passes, is the plain formula's bit for
    bit: offsets across many tiles, on and near tile edges, gains from blurred to sharp, camera offsets of any sign."""
    rng = np.random.default_rng(0)
    edges = np.arange(-40, 41, dtype=np.float32) * np.float32(0.5)
    off = np.concatenate([rng.uniform(-300, 300, 20000), rng.uniform(-3, 3, 20000), edges,
                          np.nextafter(edges, np.float32(np.inf)), np.nextafter(edges, np.float32(-np.inf))])
    off = off.astype(np.float32)
    gain = np.exp(rng.uniform(-3, 6, off.size)).astype(np.float32)
    for c in [0.0, 0.25, -1.75, 3.1, -123.456, 2.0**-20, *rng.uniform(-500, 500, 30)]:
        c = np.float32(c)
        got = _square_wave(off * np.float32(0.5), c, gain * np.float32(2.0))
        assert np.array_equal(got, _plain_square_wave(off, c, gain)), c


def test_median_is_numpys():
    """The figure's reference depth: numpy's median, bit for bit, for odd and even counts, ties and one value."""
    rng = np.random.default_rng(1)
    for n in [1, 2, 3, 4, 13, 22, 23, 24, 55]:
        for _ in range(200):
            z = rng.uniform(0.5, 9.0, n) * 10.0 ** rng.integers(-3, 3)
            if n > 3:
                z[: n // 3] = z[n // 2]  # ties
            assert _median(z) == float(np.median(z)), z
    assert np.isnan(_median(np.array([1.0, np.nan, 3.0])))


@pytest.mark.parametrize("mode", ["RGB", "YCbCr"])
def test_floor_is_the_blend_of_the_plain_checker(mode):
    """A frame's floor: the plain checker's weights (from the renderer's offsets and gains) blending the two tile
    colours over the floor's rows, the sky above, as Image.composite of the whole image gives."""
    sc = prepare_scene(figure(2.0, speed=1.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    r = FrameRenderer(sc, width=160, height=120, mode=mode)
    off_x, off_z = r._half_offx * np.float32(2.0), r._half_offz * np.float32(2.0)  # exact
    a_x, a_z = r._gain2x * np.float32(0.5), r._gain2z * np.float32(0.5)
    r2 = r.row0 // 2
    for t in range(0, sc.num_frames, 5):
        half = r._base(t)
        cx, cz = r.cam[t, 0] / 0.5, r.cam[t, 2] / 0.5  # tiles of 0.5 m
        want = _plain_square_wave(off_x, cx, a_x) * _plain_square_wave(off_z, cz, a_z)
        want = (want * np.float32(127.5) + np.float32(128.0)).astype(np.uint8)
        light = Image.new(mode, half.size)
        light.paste(r._floor_light, (0, r2))
        blend = np.zeros(half.size[::-1], np.uint8)
        blend[r2:] = want
        assert half.tobytes() == Image.composite(light, r._floor_dark, Image.fromarray(blend)).tobytes(), t


def test_mp4_colours_are_the_rgb_frames(tmp_path):
    """A decoded frame of the mp4 (ffmpeg's own yuv420p -> RGB) against the RGB drawing of the same frame."""
    out = tmp_path / "c.mp4"
    pos = figure(1.0, speed=0.5)
    opts = RenderOptions(width=160, height=120, crf=12)
    render_mp4(out, pos, parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2, options=opts, progress=False)
    sc = prepare_scene(pos, parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    want = np.asarray(FrameRenderer(sc, width=160, height=120).render(12)).astype(np.float64)
    raw = subprocess.run([ffmpeg_exe(), "-v", "error", "-i", str(out), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, check=True, timeout=120).stdout
    got = np.frombuffer(raw, np.uint8).reshape(-1, 120, 160, 3)[12].astype(np.float64)
    err = np.abs(got - want).mean(axis=(0, 1))
    # x264 at crf 12 and the 4:2:0 chroma: about 2 levels per channel (the RGB pipe of release 0.2 gave the same)
    print(f"decoded frame 12: mean error per channel {err.round(2)} levels")
    assert np.all(err < 3.0)


def test_mp4_ffmpeg_dying_at_once_is_reported(tmp_path, monkeypatch):
    """ffmpeg exits before reading a frame: the writer thread stops, the message is ffmpeg's, nothing is left."""
    fake = tmp_path / "fake-ffmpeg"
    fake.write_text("#!/bin/sh\necho 'Unknown encoder libx264' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr("dancekit.render.video.ffmpeg_exe", lambda: str(fake))
    with pytest.raises(ExternalToolError, match="Unknown encoder libx264"):
        render_mp4(tmp_path / "x.mp4", figure(4.0), parents=PARENTS, fps=FPS, unit_scale=1.0,
                   options=RenderOptions(width=320, height=240), progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fake-ffmpeg"]


def test_mp4_writer_thread_failure_is_raised(tmp_path, monkeypatch):
    """A failure in the writer thread other than a broken pipe reaches the caller; no partial mp4 is left."""
    monkeypatch.setattr(FrameRenderer, "render_yuv420", lambda self, t: "not bytes")
    with pytest.raises(TypeError):
        render_mp4(tmp_path / "x.mp4", figure(0.4), parents=PARENTS, fps=FPS, unit_scale=1.0,
                   options=RenderOptions(width=64, height=48), progress=False)
    assert list(tmp_path.iterdir()) == []


def test_writer_abort_never_blocks_on_a_stuck_pipe():
    """After an error or a signal the mp4 writer thread is stopped without waiting for good, even when its
    pipe is stuck (nobody reads it) and its queue is full; ``finish`` would block forever here."""
    import os
    import threading
    import time

    from dancekit.render.video import _PipeWriter

    r, w = os.pipe()
    pipe = os.fdopen(w, "wb", buffering=0)
    writer = _PipeWriter(pipe, depth=2)
    writer.start()
    chunk = b"\0" * (4 << 20)  # larger than the pipe's buffer: the first write blocks
    for _ in range(3):  # one being written, two queued: full
        writer.put(chunk)
    time.sleep(0.2)
    assert writer.queue.full() and writer.is_alive()
    done = threading.Event()
    threading.Thread(target=lambda: (writer.abort(timeout=0.5), done.set()), daemon=True).start()
    assert done.wait(5.0), "abort() blocked on a stuck writer"
    assert writer.daemon  # a stuck writer cannot hold the process open
    os.close(r)  # the blocked write fails now; the thread drains the queue
    writer.join(1.0)
    pipe.close()
