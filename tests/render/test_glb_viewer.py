"""The bundled glTF viewer: a self-contained html page that plays a .glb's skinned body (WebGL)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from _media import chromium as _chromium
from _media import run_chromium as _run_chromium
from test_render import _cli

from dancekit.errors import ParameterError
from dancekit.motion import Motion, get_skeleton, write_motion
from dancekit.render.glb_html import glb_page_html, render_glb_html

pytest.importorskip("pygltflib")


def swaying(frames: int = 50) -> Motion:
    """The tang2018 rest pose standing on the floor, arms swinging and the body stepping sideways."""
    sk = get_skeleton("tang2018")
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    rest[:, 1] -= rest[:, 1].min()
    pos = np.repeat(rest[None], frames, axis=0)
    t = np.arange(frames) / 25.0
    pos[:, :, 0] += 30 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    return Motion(sk, 25.0, positions=pos.astype(np.float32))


def mannequin_pixels(img: np.ndarray) -> int:
    """Pixels of the glb's warm mannequin colour (the floor and the sky are grey-blue)."""
    r, b = img[..., 0].astype(int), img[..., 2].astype(int)
    return int((r - b > 40).sum())


@pytest.fixture
def glb(tmp_path):
    path = tmp_path / "dance.glb"
    write_motion(path, swaying())
    return path


def test_page_is_self_contained_and_embeds_the_glb(tmp_path, glb):
    out = tmp_path / "view.html"
    render_glb_html(out, glb)
    text = out.read_text()
    assert "<title>view</title>" in text
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", text)  # nothing fetched
    b64 = re.search(r'<script id="dk-glb" type="application/octet-stream">([^<]*)</script>', text).group(1)
    import base64

    assert base64.b64decode(b64) == glb.read_bytes()
    with pytest.raises(ParameterError, match="glTF"):
        glb_page_html(b"not a glb")


def test_cli_glb_to_viewer_and_errors(tmp_path, glb):
    out = tmp_path / "v.html"
    r = _cli(str(glb), "-o", str(out), "-q")
    assert r.returncode == 0, r.stderr
    assert 'id="dk-glb"' in out.read_text()
    npz = tmp_path / "m.npz"
    write_motion(npz, swaying(10))
    out2 = tmp_path / "v2.html"
    r = _cli(str(npz), "-o", str(out2), "--format", "glb-html", "-q")
    assert r.returncode == 0, r.stderr
    assert 'id="dk-glb"' in out2.read_text() and 'id="dk-data"' not in out2.read_text()
    r = _cli(str(glb), "-o", str(tmp_path / "x.html"), "--figure", "body")
    assert r.returncode != 0 and "glTF viewer" in r.stderr
    r = _cli(str(npz), "-o", str(tmp_path / "x.mp4"), "--format", "glb-html")
    assert r.returncode != 0 and "does not match" in r.stderr


def test_viewer_shows_the_body_mid_dance_in_headless_chromium(tmp_path, glb):
    exe = _chromium()
    out = tmp_path / "view.html"
    render_glb_html(out, glb)
    url = out.as_uri() + "#t=1.1"  # paused mid-dance
    dom = _run_chromium(exe, url, tmp_path / "p1", "--dump-dom").stdout
    tag = re.search(r"<html[^>]*>", dom).group(0)
    assert "data-dk-error" not in tag, tag
    assert 'data-dk-status="drawn"' in tag and 'data-dk-time="1.100"' in tag
    assert int(re.search(r'data-dk-triangles="(\d+)"', tag).group(1)) > 500
    shot = tmp_path / "view.png"
    _run_chromium(exe, url, tmp_path / "p2", "--window-size=640,480", f"--screenshot={shot}")
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB"))
    h, w = img.shape[:2]
    centre = img[h // 8: 7 * h // 8, w // 4: 3 * w // 4]
    n_centre, n_all = mannequin_pixels(centre), mannequin_pixels(img)
    print(f"mannequin pixels: {n_centre} in the centre, {n_all} in all")
    assert n_centre > 2000  # the body, not a blank page or an empty floor
    assert n_centre > 0.9 * n_all  # framed by the camera
