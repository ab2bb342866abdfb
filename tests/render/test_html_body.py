"""The html player's volumetric "body" figure: the option reaches the page and draws in headless Chromium."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from _media import chromium as _chromium
from _media import run_chromium as _run_chromium
from test_render import FPS, PARENTS, SIDES, _cli, figure

from dancekit.render import RenderOptions, render_html


def page_data(path) -> dict:
    text = path.read_text()
    return json.loads(re.search(r'<script id="dk-data" type="application/json">(.*?)</script>', text, re.S).group(1))


def skin_pixels(img: np.ndarray) -> int:
    """Pixels of the mannequin's warm skin tints (the floor and sky are grey-blue, the stick figure saturated)."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return int(((r - b >= 10) & (r - b <= 70) & (g >= 0.8 * r) & (r >= 120)).sum())


def test_body_option_reaches_the_page(tmp_path):
    body, stick = tmp_path / "body.html", tmp_path / "stick.html"
    kw = dict(parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    render_html(body, figure(1.0), options=RenderOptions(figure="body"), **kw)
    render_html(stick, figure(1.0), **kw)
    b, s = page_data(body), page_data(stick)
    assert b["figure"] == "body" and s["figure"] == "stick"
    assert len(b["torso"]) >= 4 and len(b["limbRadius"]) == len(b["bones"]) == len(b["limb"])
    assert "torso" not in s


def test_cli_render_html_figure_body(tmp_path):
    from dancekit.motion import Motion, get_skeleton, write_motion

    sk = get_skeleton("tang2018")
    rest = np.zeros((23, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    npz = tmp_path / "m.npz"
    write_motion(npz, Motion(skeleton=sk, fps=25, positions=np.repeat(rest[None], 10, 0).astype(np.float32)))
    out = tmp_path / "m.html"
    r = _cli(str(npz), "-o", str(out), "--figure", "body", "-q")
    assert r.returncode == 0, r.stderr
    assert page_data(out)["figure"] == "body"


def test_export_passes_the_figure_to_the_html(tmp_path):
    """``dancekit dance --figure body`` reaches the html player through export_motion's options."""
    from test_glb_viewer import swaying

    from dancekit.export import export_motion

    written = export_motion(swaying(10), tmp_path / "out", stem="song", formats="html",
                            options=RenderOptions(figure="body"))
    assert page_data(written[0])["figure"] == "body"


@pytest.mark.slow
def test_body_figure_draws_in_headless_chromium(tmp_path):
    exe = _chromium()
    kw = dict(parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    counts = {}
    for name in ("body", "stick"):
        out = tmp_path / f"{name}.html"
        render_html(out, figure(2.0, speed=0.5), options=RenderOptions(figure=name), **kw)
        url = out.as_uri() + "#t=1.2"  # paused mid-dance
        dom = _run_chromium(exe, url, tmp_path / f"d{name}", "--dump-dom").stdout
        tag = re.search(r"<html[^>]*>", dom).group(0)
        assert "data-dk-error" not in tag, tag
        assert f'data-dk-figure="{name}"' in tag
        assert re.search(r'data-dk-frame="(\d+)"', tag).group(1) == "30"
        data = page_data(out)
        if name == "body":  # the limbs outside the torso, the torso and the head
            assert int(re.search(r'data-dk-drawn="(\d+)"', tag).group(1)) == sum(data["limb"]) + 2
        shot = tmp_path / f"{name}.png"
        _run_chromium(exe, url, tmp_path / f"s{name}", "--window-size=640,480", f"--screenshot={shot}")
        from PIL import Image

        counts[name] = skin_pixels(np.asarray(Image.open(shot).convert("RGB")))
    print("skin-tinted pixels", counts)
    assert counts["body"] > 3000 and counts["body"] > 4 * counts["stick"]


@pytest.mark.parametrize("mode", ["RGB", "YCbCr"])
@pytest.mark.parametrize("fig", ["body", "stick"])
def test_mp4_fast_drawing_equals_the_public_api(monkeypatch, fig, mode):
    """The mp4 figures and shadow draw with Pillow's core and precomputed inks; the public API gives the same pixels."""
    from test_render import figure as stick_dance

    import dancekit.render.video as video
    from dancekit.render._scene import prepare_scene

    assert video._INKS is not None  # the fast path is in use with this Pillow
    scene = prepare_scene(stick_dance(1.0, speed=0.5), parents=PARENTS, fps=FPS, unit_scale=1.0, sides=SIDES, head=2)
    r = video.FrameRenderer(scene, width=160, height=120, figure=fig, mode=mode)
    fast = [np.asarray(r.render(t)) for t in (0, 12, 24)]
    monkeypatch.setattr(video, "_INKS", None)
    slow = [np.asarray(r.render(t)) for t in (0, 12, 24)]
    for a, b in zip(fast, slow, strict=True):
        assert np.array_equal(a, b)
