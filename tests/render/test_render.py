"""Rendering: mp4 streams and durations, atomic writes, the html player (headless Chromium), the CLI."""

from __future__ import annotations

import base64
import json
import re
import subprocess

import numpy as np
import pytest
import soundfile as sf
from _media import chromium as _chromium
from _media import run_chromium as _run_chromium
from _media import stream_info

from dancekit.errors import AudioError, DancekitError, ExternalToolError, ParameterError
from dancekit.render import (
    AudioClip,
    RenderOptions,
    render_html,
    render_motion_html,
    render_motion_mp4,
    render_mp4,
)
from dancekit.render._ffmpeg import audio_duration, ffmpeg_exe
from dancekit.render._motion import motion_arrays
from dancekit.render._scene import ground_level, prepare_scene
from dancekit.render.video import FrameRenderer

FPS = 25.0
# a 13-joint stick figure in metres, y up, facing +z (left = +x)
_REST = np.array([
    [0.0, 1.0, 0.0],     # 0 pelvis (root)
    [0.0, 1.5, 0.0],     # 1 neck
    [0.0, 1.7, 0.0],     # 2 head
    [0.2, 1.45, 0.0],    # 3 left shoulder
    [0.45, 1.1, 0.0],    # 4 left hand
    [-0.2, 1.45, 0.0],   # 5 right shoulder
    [-0.45, 1.1, 0.0],   # 6 right hand
    [0.1, 0.95, 0.0],    # 7 left hip
    [0.12, 0.5, 0.05],   # 8 left knee
    [0.12, 0.02, 0.0],   # 9 left foot
    [-0.1, 0.95, 0.0],   # 10 right hip
    [-0.12, 0.5, 0.05],  # 11 right knee
    [-0.12, 0.02, 0.0],  # 12 right foot
])  # fmt: skip
PARENTS = np.array([-1, 0, 1, 1, 3, 1, 5, 0, 7, 8, 0, 10, 11])
SIDES = np.array([0, 0, 0, 1, 1, -1, -1, 1, 1, 1, -1, -1, -1])
BLUE, ORANGE = np.array([52, 120, 220]), np.array([236, 112, 40])


def figure(seconds: float, *, speed: float = 0.0) -> np.ndarray:
    """(T, 13, 3) metres: the stick figure walking along +x at ``speed`` m/s, arms swinging."""
    t = np.arange(int(round(seconds * FPS))) / FPS
    pos = np.repeat(_REST[None], len(t), axis=0)
    pos[:, [4, 6], 2] += 0.2 * np.sin(2 * np.pi * t)[:, None]
    pos[:, :, 0] += speed * t[:, None]
    return pos


def write_song(path, segments: list[tuple[float, float]], sr: int = 22050) -> None:
    """A wav of consecutive (seconds, amplitude) 440 Hz segments (amplitude 0 is silence)."""
    y = np.concatenate([a * np.sin(2 * np.pi * 440 * np.arange(int(s * sr)) / sr) for s, a in segments])
    sf.write(path, y.astype(np.float32), sr)


def decode_audio(path, sr: int = 22050) -> np.ndarray:
    r = subprocess.run(
        [
            ffmpeg_exe(),
            "-v",
            "error",
            "-i",
            str(path),
            "-map",
            "0:a:0",
            "-ac",
            "1",
            "-ar",
            str(sr),
            "-f",
            "f32le",
            "pipe:1",
        ],
        capture_output=True,
        check=True, timeout=120,
    )
    return np.frombuffer(r.stdout, dtype="<f4")


def video_frame(path, t: float, size: tuple[int, int]) -> np.ndarray:
    r = subprocess.run(
        [
            ffmpeg_exe(),
            "-v",
            "error",
            "-ss",
            str(t),
            "-i",
            str(path),
            "-frames:v",
            "1",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "pipe:1",
        ],
        capture_output=True,
        check=True, timeout=120,
    )
    return np.frombuffer(r.stdout, np.uint8).reshape(size[1], size[0], 3)


def colour_pixels(img: np.ndarray, rgb: np.ndarray, tol: float = 40) -> int:
    return int((np.abs(img.astype(int) - rgb).max(axis=-1) < tol).sum())


@pytest.fixture
def song(tmp_path):
    """3 s: 1.5 s of silence then 1.5 s of a loud tone."""
    path = tmp_path / "song.wav"
    write_song(path, [(1.5, 0.0), (1.5, 0.5)])
    return path


# ---------------------------------------------------------------------- scene
def test_scene_up_axis_and_units_agree():
    p = figure(1.0, speed=0.5)
    ref = prepare_scene(p, parents=PARENTS, fps=FPS, up_axis="y", unit_scale=1.0)
    z_up = np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1) * 100  # centimetres, z up
    other = prepare_scene(z_up, parents=PARENTS, fps=FPS, up_axis="z", unit_scale=0.01)
    np.testing.assert_allclose(other.positions, ref.positions, atol=1e-5)
    np.testing.assert_allclose(other.target, ref.target, atol=1e-5)
    assert ref.positions[:, :, 1].min() == pytest.approx(0.0, abs=1e-6)  # feet on the floor
    assert ref.height == pytest.approx(1.68, abs=1e-3)


def test_scene_facing_from_sides():
    p = figure(0.5)
    assert prepare_scene(p, parents=PARENTS, fps=FPS, unit_scale=1.0).facing_azimuth is None
    sc = prepare_scene(p, parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES)
    assert sc.facing_azimuth == pytest.approx(0.0, abs=1e-6)  # facing +z
    turned = p[..., [2, 1, 0]] * [1, 1, -1]  # rotate -90 deg about y: +z -> +x
    sc = prepare_scene(turned, parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES)
    assert sc.facing_azimuth == pytest.approx(np.pi / 2, abs=1e-6)


def test_ground_level_removes_drift_but_not_jumps():
    t = np.arange(500) / FPS
    drift = 0.02 * t  # 0.4 m over 20 s
    lowest = drift.copy()
    lowest[200:210] += 0.4  # a 0.4 s jump
    level = ground_level(lowest, fps=FPS)
    assert np.abs(level - drift)[40:-40].max() < 0.03
    fixed = ground_level(lowest, fps=FPS, follow=False)
    assert np.all(fixed == np.percentile(lowest, 5))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"positions": np.zeros((4, 13, 2))}, "shape"),
        ({"positions": np.full((4, 13, 3), np.nan)}, "NaN"),
        ({"parents": PARENTS[:-1]}, "parents"),
        ({"parents": np.where(PARENTS == 5, 13, PARENTS)}, "parents"),
        ({"parents": np.zeros(13, int)}, "parents"),
        ({"fps": 0}, "fps"),
        ({"up_axis": "w"}, "up_axis"),
        ({"unit_scale": -1.0}, "unit_scale"),
        ({"sides": [1, -1]}, "sides"),
        ({"head": 13}, "head"),
    ],
)
def test_scene_rejects_bad_input(kwargs, match):
    args = {"positions": figure(0.2), "parents": PARENTS, "fps": FPS, "unit_scale": 1.0} | kwargs
    with pytest.raises(ParameterError, match=match):
        prepare_scene(args.pop("positions"), **args)


def test_camera_follows_and_keeps_the_figure_in_frame():
    sc = prepare_scene(figure(4.0, speed=1.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    r = FrameRenderer(sc, width=320, height=240)
    for t in range(0, sc.num_frames, 5):
        uv, z = r.project(t, sc.positions[t])
        assert np.all(z > 0)
        assert np.all((uv >= 0) & (uv < [320, 240])), t
        assert abs(uv[0, 0] - 160) < 40  # the root stays near the middle while walking 6 m
    img = np.asarray(r.render(50))
    assert img.shape == (240, 320, 3)
    assert colour_pixels(img, BLUE) > 30 and colour_pixels(img, ORANGE) > 30


# ---------------------------------------------------------------------- mp4
def test_mp4_streams_match_the_song_slice(tmp_path, song):
    out = tmp_path / "dance.mp4"
    # 1.0 s of dance, song slice [1.5, 2.6]: the dance is padded to 1.1 s, the audio is the loud part
    render_mp4(
        out,
        figure(1.0) * 100,
        parents=PARENTS,
        fps=FPS,
        sides=SIDES,
        head=2,
        audio=AudioClip(song, 1.5, 2.6),
        options=RenderOptions(width=160, height=120),
        progress=False,
    )
    info = stream_info(out)
    assert info["video"] == "h264" and info["audio"] == "aac" and info["size"] == (160, 120)
    assert info["video_s"] == pytest.approx(1.1, abs=0.1)
    assert info["audio_s"] == pytest.approx(1.1, abs=0.1)
    y = decode_audio(out)
    assert np.sqrt(np.mean(y[2000:-2000] ** 2)) > 0.25  # the tone (RMS 0.35), not the silence
    img = video_frame(out, 0.5, (160, 120))
    assert colour_pixels(img, BLUE) > 10 and colour_pixels(img, ORANGE) > 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dance.mp4", "song.wav"]


def test_mp4_default_slice_follows_the_motion_and_song_end(tmp_path, song):
    out = tmp_path / "a.mp4"
    render_mp4(
        out, figure(1.0) * 100, parents=PARENTS, fps=FPS, audio=song, options=RenderOptions(width=64, height=48),
        progress=False,
    )
    info = stream_info(out)
    assert info["video_s"] == pytest.approx(1.0, abs=0.1) and info["audio_s"] == pytest.approx(1.0, abs=0.1)
    assert np.sqrt(np.mean(decode_audio(out) ** 2)) < 0.01  # the silent first second
    # 3 s of dance from 1 s into a 3 s song: cut to the 2 s that the song has left
    render_mp4(
        out,
        figure(3.0) * 100,
        parents=PARENTS,
        fps=FPS,
        audio=AudioClip(song, start=1.0),
        options=RenderOptions(width=64, height=48),
        progress=False,
    )
    info = stream_info(out)
    assert info["video_s"] == pytest.approx(2.0, abs=0.1) and info["audio_s"] == pytest.approx(2.0, abs=0.1)
    y = decode_audio(out)
    assert np.flatnonzero(np.abs(y) > 0.1)[0] / 22050 == pytest.approx(
        0.5, abs=0.005
    )  # tone at 1.5 s of the song


def test_audio_duration_probes_each_file_version_once(tmp_path, song, monkeypatch):
    """The command line and the render both ask a song's length: one ffmpeg run answers both; a file written
    again (another length) is probed again, and a missing one is still an error."""
    import dancekit.render._ffmpeg as ff

    runs = []
    real = ff.subprocess.run
    monkeypatch.setattr(ff.subprocess, "run", lambda *a, **k: (runs.append(a[0]), real(*a, **k))[1])
    assert audio_duration(song) == pytest.approx(3.0, abs=0.05)
    assert audio_duration(str(song)) == pytest.approx(3.0, abs=0.05)
    assert len(runs) == 1
    write_song(song, [(2.0, 0.5)])
    assert audio_duration(song) == pytest.approx(2.0, abs=0.05)
    assert len(runs) == 2
    song.unlink()
    with pytest.raises(AudioError, match="not found"):
        audio_duration(song)


def test_mp4_without_audio(tmp_path):
    out = tmp_path / "silent.mp4"
    render_mp4(
        out, figure(0.8), parents=PARENTS, fps=FPS, unit_scale=1.0, options=RenderOptions(width=64, height=48),
        progress=False,
    )
    info = stream_info(out)
    assert info["video"] == "h264" and info["audio"] is None
    assert info["video_s"] == pytest.approx(0.8, abs=0.05)


def test_mp4_is_the_same_whatever_the_drawing_processes(tmp_path, song):
    """Frames drawn by 3 processes (every third by the caller) or by the caller alone: the same file, byte for
    byte (a moving figure, so that a frame put in the wrong place would show)."""
    kw = {"parents": PARENTS, "fps": FPS, "unit_scale": 1.0, "audio": song, "progress": False}
    moving = figure(1.2, speed=0.5)
    render_mp4(tmp_path / "one.mp4", moving, options=RenderOptions(width=64, height=48, workers=1), **kw)
    render_mp4(tmp_path / "three.mp4", moving, options=RenderOptions(width=64, height=48, workers=3), **kw)
    assert (tmp_path / "one.mp4").read_bytes() == (tmp_path / "three.mp4").read_bytes()
    with pytest.raises(ParameterError, match="workers"):
        RenderOptions(workers=0)


def test_a_drawing_process_that_fails_is_a_named_error():
    from dancekit.render.video import _FrameWorkers

    scene = prepare_scene(figure(0.4), parents=PARENTS, fps=FPS, unit_scale=1.0)
    with _FrameWorkers(scene, {"width": 64, "height": 48, "no_such_option": 1}, 10, 2) as helpers:
        assert helpers.draws(1) and not helpers.draws(2)
        with pytest.raises(DancekitError, match="drawing frame 1 failed: TypeError"):
            helpers.frame(1)
    assert all(not p.is_alive() for p in helpers.procs)


@pytest.mark.parametrize("width, height", [(161, 120), (160, 8), (True, 120)])
def test_mp4_rejects_bad_sizes(tmp_path, width, height):
    with pytest.raises(ParameterError, match="width|height"):
        render_mp4(tmp_path / "x.mp4", figure(0.2), parents=PARENTS, fps=FPS,
                   options=RenderOptions(width=width, height=height))
    assert list(tmp_path.iterdir()) == []


def test_mp4_failures_leave_no_file(tmp_path, song, monkeypatch):
    kw = {"parents": PARENTS, "fps": FPS, "options": RenderOptions(width=64, height=48), "progress": False}
    with pytest.raises(DancekitError, match="does not exist"):
        render_mp4(tmp_path / "missing" / "x.mp4", figure(0.4), **kw)
    corrupt = tmp_path / "corrupt.mp3"
    corrupt.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(AudioError, match="corrupt.mp3"):
        render_mp4(tmp_path / "x.mp4", figure(0.4), audio=corrupt, **kw)
    with pytest.raises(AudioError, match="not found"):
        render_mp4(tmp_path / "x.mp4", figure(0.4), audio=tmp_path / "nope.wav", **kw)
    with pytest.raises(ParameterError, match="past the end"):
        render_mp4(tmp_path / "x.mp4", figure(0.4), audio=AudioClip(song, start=5.0), **kw)
    # an error while frames stream to ffmpeg: ffmpeg is stopped, the partial file removed
    calls = []

    def broken(self, t):
        calls.append(t)
        if t == 5:
            raise RuntimeError("boom")
        return original(self, t)

    original = FrameRenderer.render
    monkeypatch.setattr(FrameRenderer, "render", broken)
    with pytest.raises(RuntimeError, match="boom"):
        render_mp4(tmp_path / "x.mp4", figure(0.4), audio=song, **kw)
    assert calls[-1] == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corrupt.mp3", "song.wav"]


def test_mp4_ffmpeg_failure_is_reported(tmp_path, monkeypatch):
    fake = tmp_path / "fake-ffmpeg"
    fake.write_text(
        "#!/bin/sh\ncat > /dev/null\necho 'first line' >&2\necho 'Encoder exploded' >&2\nexit 1\n"
    )
    fake.chmod(0o755)
    monkeypatch.setattr("dancekit.render.video.ffmpeg_exe", lambda: str(fake))
    with pytest.raises(ExternalToolError, match="Encoder exploded"):
        render_mp4(
            tmp_path / "x.mp4", figure(0.4), parents=PARENTS, fps=FPS, options=RenderOptions(width=64, height=48),
            progress=False,
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fake-ffmpeg"]


# ---------------------------------------------------------------------- html
def _page_data(text: str) -> dict:
    m = re.search(r'<script id="dk-data" type="application/json">(.*?)</script>', text, re.S)
    return json.loads(m.group(1))


def test_html_is_self_contained_and_embeds_motion_and_song(tmp_path, song):
    out = tmp_path / "dance.html"
    pos = figure(1.0, speed=0.5) * 100
    render_html(
        out,
        pos,
        parents=PARENTS,
        fps=FPS,
        sides=SIDES,
        head=2,
        audio=AudioClip(song, 1.5, 2.7),
        options=RenderOptions(title="Test <dance>"),
    )
    text = out.read_text()
    assert not re.search(r"https?://", text)  # nothing to fetch
    assert not re.search(r"""(src|href)\s*=\s*["']?(?!data:)[a-z]+:""", text)
    assert "<title>Test &lt;dance&gt;</title>" in text
    data = _page_data(text)
    assert data["frames"] == 25 and data["fps"] == FPS and data["duration"] == pytest.approx(1.2)
    # the embedded positions decode to the scene's positions within the quantisation step
    v = np.frombuffer(base64.b64decode(data["positions"]), "<u2").reshape(25, 13, 3)
    decoded = np.asarray(data["offset"]) + v * np.asarray(data["scale"])
    scene = prepare_scene(pos, parents=PARENTS, fps=FPS, sides=SIDES, head=2)
    np.testing.assert_allclose(decoded, scene.positions, atol=1e-4)
    # the embedded song is an mp3 of the slice: 1.2 s of the loud tone
    m = re.search(r'<audio id="dk-audio" preload="auto" src="data:audio/mpeg;base64,([A-Za-z0-9+/=]+)"', text)
    mp3 = tmp_path / "slice.mp3"
    mp3.write_bytes(base64.b64decode(m.group(1)))
    assert audio_duration(mp3) == pytest.approx(1.2, abs=0.1)
    assert np.sqrt(np.mean(decode_audio(mp3)[3000:-3000] ** 2)) > 0.25


def test_html_song_slice_starts_on_time(tmp_path, song):
    """The embedded mp3 carries its encoder delay: the tone at 1.5 s of the song is at 0.5 s of the slice."""
    out = tmp_path / "dance.html"
    render_html(out, figure(2.0), parents=PARENTS, fps=FPS, audio=AudioClip(song, start=1.0))
    m = re.search(r'src="data:audio/mpeg;base64,([A-Za-z0-9+/=]+)"', out.read_text())
    mp3 = tmp_path / "slice.mp3"
    mp3.write_bytes(base64.b64decode(m.group(1)))
    y = decode_audio(mp3, sr=22050)
    onset = np.flatnonzero(np.abs(y) > 0.1)[0] / 22050
    assert onset == pytest.approx(0.5, abs=0.005)  # 50 ms late without the LAME header
    assert len(y) / 22050 == pytest.approx(2.0, abs=0.01)


def test_html_failures_leave_no_file(tmp_path):
    corrupt = tmp_path / "bad.ogg"
    corrupt.write_bytes(b"OggS" + b"\x00" * 100)
    with pytest.raises(AudioError, match="bad.ogg"):
        render_html(tmp_path / "x.html", figure(0.4), parents=PARENTS, fps=FPS, audio=corrupt)
    with pytest.raises(ParameterError, match="audio_path"):
        render_html(tmp_path / "x.html", figure(0.4), parents=PARENTS, fps=FPS, audio_start=1.0)
    assert [p.name for p in tmp_path.iterdir()] == ["bad.ogg"]


@pytest.mark.parametrize(("ci", "outcome"), [("true", pytest.fail.Exception), ("", pytest.skip.Exception)])
def test_missing_chromium_fails_on_ci_and_skips_elsewhere(monkeypatch, ci, outcome):
    import _media

    monkeypatch.setattr(_media.shutil, "which", lambda name: None)
    monkeypatch.setenv("CI", ci)
    with pytest.raises(BaseException) as info:  # pytest's skip / fail outcomes are BaseExceptions
        _chromium()
    assert info.type is outcome and "apt-get install -y chromium" in str(info.value)


@pytest.mark.parametrize("with_audio", [True, False])
def test_html_plays_in_headless_chromium(tmp_path, song, with_audio):
    exe = _chromium()
    out = tmp_path / "dance.html"
    audio = {"audio": AudioClip(song, start=1.5)} if with_audio else {}
    render_html(
        out, figure(1.0, speed=0.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2, **audio
    )
    dom = _run_chromium(exe, out.as_uri(), tmp_path / "p1", "--dump-dom").stdout
    html_tag = re.search(r"<html[^>]*>", dom).group(0)
    assert "data-dk-error" not in html_tag, html_tag  # no script error, no console.error
    assert 'data-dk-status="drawn"' in html_tag
    assert int(re.search(r'data-dk-drawn="(\d+)"', html_tag).group(1)) == 13  # 12 bones + the head
    assert "0:00.0 / 0:01.0" in dom
    shot = tmp_path / "shot.png"
    _run_chromium(exe, out.as_uri(), tmp_path / "p2", "--window-size=640,480", f"--screenshot={shot}")
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB"))
    assert colour_pixels(img, BLUE) > 200 and colour_pixels(img, ORANGE) > 200


_INTERACT = """<script>
(function () {
  var c = document.getElementById("dk-canvas");
  var before = document.documentElement.dataset.dkCamera;
  c.dispatchEvent(new PointerEvent("pointerdown", {clientX: 100, clientY: 100, pointerId: 1, bubbles: true}));
  c.dispatchEvent(new PointerEvent("pointermove", {clientX: 150, clientY: 120, pointerId: 1, bubbles: true}));
  c.dispatchEvent(new PointerEvent("pointerup", {clientX: 150, clientY: 120, pointerId: 1, bubbles: true}));
  c.dispatchEvent(new WheelEvent("wheel", {deltaY: 100, bubbles: true, cancelable: true}));
  document.documentElement.dataset.testBefore = before;
  document.getElementById("dk-play").click();
  // a redraw 0.6 s later (a resize draws at once): newer headless Chromium delivers almost no animation
  // frames under a virtual-time budget, so the check reads the clock without depending on their cadence
  setTimeout(function () { window.dispatchEvent(new Event("resize")); }, 600);
})();
</script>
</body>"""


def test_html_orbit_camera_and_clock_playback(tmp_path):
    exe = _chromium()
    out = tmp_path / "dance.html"
    render_html(out, figure(4.0), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES)
    page = tmp_path / "interact.html"
    page.write_text(out.read_text().replace("</body>", _INTERACT))
    # the clock runs on animation frames, which a loaded machine may not deliver within the
    # virtual-time budget: allow more runs with longer budgets (the camera checks are exact)
    for attempt, budget in enumerate((1500, 4000, 8000, 15000)):
        dom = _run_chromium(exe, page.as_uri(), tmp_path / f"p{attempt}", "--dump-dom", budget_ms=budget).stdout
        tag = re.search(r"<html[^>]*>", dom).group(0)
        if int(re.search(r'data-dk-frame="(\d+)"', tag).group(1)) > 0:
            break
    assert "data-dk-error" not in tag, tag
    az0, el0, d0 = map(float, re.search(r'data-test-before="([^"]+)"', tag).group(1).split(","))
    az1, el1, d1 = map(float, re.search(r'data-dk-camera="([^"]+)"', tag).group(1).split(","))
    assert az1 == pytest.approx(az0 - 50 * 0.4, abs=0.1)  # dragged 50 px to the right
    assert el1 == pytest.approx(el0 + 20 * 0.3, abs=0.1)  # and 20 px down
    assert d1 == pytest.approx(d0 * np.exp(0.12), abs=0.02)  # zoomed out
    assert int(re.search(r'data-dk-frame="(\d+)"', tag).group(1)) > 0  # the clock advanced


# ---------------------------------------------------------------------- Motion and CLI
def test_motion_arrays_tang2018_adds_neck_and_head_centre():
    from dancekit.motion import Motion, get_skeleton

    sk = get_skeleton("tang2018")
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(3, 23, 3)).astype(np.float32)
    a = motion_arrays(Motion(skeleton=sk, fps=25, positions=pos))
    # the two head markers (0, 1) are replaced by one head centre; a neck is added
    assert a["positions"].shape == (3, 23, 3) and a["unit_scale"] == 0.01 and a["up_axis"] == "y"
    new = {j: j - 2 for j in range(2, 23)}  # old index -> drawing index
    neck, centre = 21, 22
    np.testing.assert_allclose(a["positions"][:, new[5]], pos[:, 5])
    np.testing.assert_allclose(a["positions"][:, neck], 0.5 * (pos[:, 3] + pos[:, 12]), atol=1e-6)
    np.testing.assert_allclose(a["positions"][:, centre], 0.5 * (pos[:, 0] + pos[:, 1]), atol=1e-6)
    assert a["head"] == centre and a["parents"][centre] == neck
    assert a["parents"][new[3]] == a["parents"][new[12]] == neck and a["parents"][neck] == new[2]
    assert a["parents"][new[2]] == -1 and a["parents"][new[4]] == new[3]
    assert a["sides"][new[sk.index("left_knee")]] == 1 and a["sides"][new[sk.index("right_knee")]] == -1
    assert a["sides"][new[sk.index("pelvis")]] == 0


def test_render_motion_2d_body25(tmp_path):
    from dancekit.motion import Motion, get_skeleton

    sk = get_skeleton("body25")
    rest = np.zeros((25, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    pos = np.repeat(rest[None, :, :2] + [320, 300], 10, axis=0).astype(np.float32)  # image space, px
    out = tmp_path / "b25.mp4"
    render_motion_mp4(out, Motion(skeleton=sk, fps=25, positions=pos), options=RenderOptions(width=96, height=96),
                      progress=False)
    img = video_frame(out, 0.1, (96, 96))
    rows = np.flatnonzero((np.abs(img.astype(int) - BLUE).max(axis=-1) < 40).any(axis=1))
    head_row = np.flatnonzero((np.abs(img.astype(int) - [232, 196, 160]).max(axis=-1) < 30).any(axis=1))
    assert rows.size and head_row.size and head_row.mean() < rows.mean()  # upright: the head is on top
    render_motion_html(tmp_path / "b25.html", Motion(skeleton=sk, fps=25, positions=pos))
    assert _page_data((tmp_path / "b25.html").read_text())["joints"] == 25


def _cli(*argv: str) -> subprocess.CompletedProcess:
    """Run ``dancekit render ARGV`` in this process; returns (returncode, stdout, stderr) like subprocess."""
    import contextlib
    import io

    from dancekit.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["render", *argv])
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())


def test_cli_render_npz_with_audio(tmp_path, song):
    from dancekit.motion import Motion, get_skeleton, write_motion

    sk = get_skeleton("tang2018")
    rest = np.zeros((23, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    rest[:, 1] -= rest[:, 1].min()
    npz = tmp_path / "m.npz"
    write_motion(npz, Motion(skeleton=sk, fps=25, positions=np.repeat(rest[None], 30, 0).astype(np.float32)))
    out = tmp_path / "m.mp4"
    r = _cli(
        str(npz),
        "--audio",
        str(song),
        "--start",
        "1.5",
        "-o",
        str(out),
        "--width",
        "96",
        "--height",
        "72",
        "-q",
    )
    assert r.returncode == 0, r.stderr
    info = stream_info(out)
    assert info["size"] == (96, 72) and info["audio_s"] == pytest.approx(1.2, abs=0.1)
    r = _cli(str(npz), "-o", str(tmp_path / "m.html"), "-q")
    assert r.returncode == 0, r.stderr
    assert "dk-data" in (tmp_path / "m.html").read_text()


@pytest.mark.parametrize(
    "args, message",
    [
        (["{npz}", "-o", "{tmp}/x.avi"], "must end in .mp4 or .html"),
        (["{tmp}/none.npz", "-o", "{tmp}/x.mp4"], "not found"),
        (["{npz}", "-o", "{tmp}/x.mp4", "--audio", "{tmp}/bad.mp3"], "bad.mp3"),
        (["{npz}", "-o", "{tmp}/x.mp4", "--start", "1"], "--audio"),
        (["{npz}", "-o", "{tmp}/x.html", "--width", "100"], "mp4 output only"),
        (["{npz}", "-o", "{tmp}/x.mp4", "--width", "99"], "width"),
        (["{npz}", "-o", "{tmp}/nowhere/x.mp4"], "does not exist"),
    ],
)
def test_cli_render_errors(tmp_path, args, message):
    from dancekit.motion import Motion, get_skeleton, write_motion

    npz = tmp_path / "m.npz"
    write_motion(
        npz, Motion(skeleton=get_skeleton("smpl"), fps=25, positions=np.zeros((5, 24, 3), np.float32))
    )
    (tmp_path / "bad.mp3").write_bytes(b"\xff\xfb" + b"\x00" * 64)
    before = sorted(p.name for p in tmp_path.iterdir())
    r = _cli(*[a.format(npz=npz, tmp=tmp_path) for a in args])
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dancekit render: error:") and message in lines[0], (
        r.stderr
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.shared
def test_cli_render_tang2018_folder_uses_its_song(tmp_path, tang2018_dir):
    dance = tang2018_dir / "DANCE_C_2"
    cfg = json.loads((dance / "config.json").read_text())
    out = tmp_path / "c2.html"
    r = _cli(str(dance), "-o", str(out), "-q")
    assert r.returncode == 0, r.stderr
    data = _page_data(out.read_text())
    n = json.loads((dance / "skeletons.json").read_text())["length"]
    assert data["frames"] == n and data["duration"] == pytest.approx(n / 25, abs=0.05)
    assert abs(n - (cfg["end_position"] - cfg["start_position"])) < 25
    assert 'src="data:audio/mpeg;base64,' in out.read_text()
