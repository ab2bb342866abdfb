"""A bundled glTF viewer: ONE self-contained html page that plays a ``.glb`` (embedded as base64).

The page needs no network: the viewer (``assets/glb_viewer.js``, a small hand-written
WebGL 1 renderer that parses the glb, plays its first animation and skins its meshes on
the GPU) and the player's style (``assets/player.css``) are inlined. Drag to rotate, wheel
to zoom, double-click to reset, space to play; ``view.html#t=12.5`` opens it paused at
12.5 s. Any glTF 2.0 binary with triangle meshes works; the dancekit glb (a skinned
capsule mannequin, see :mod:`dancekit.motion.formats.gltf`) is what it is made for.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import os
import tempfile
from pathlib import Path

from dancekit._io import atomic_path
from dancekit.errors import ParameterError
from dancekit.render.html import asset_text, page_shell
from dancekit.render.options import RenderOptions

_ELEVATION = 12.0


def glb_page_html(glb: bytes, *, title: str = "dancekit", azimuth: float = 30.0,
                  elevation: float = _ELEVATION) -> str:
    """The html text of a viewer page for the glb bytes ``glb``."""
    if glb[:4] != b"glTF":
        raise ParameterError("not a glTF binary (.glb): the file does not start with 'glTF'")
    conf = json.dumps({"title": title, "azimuth": float(azimuth), "elevation": float(elevation)})
    conf = conf.replace("</", "<\\/")
    b64 = base64.b64encode(glb).decode("ascii")
    return page_shell(title, (
        f'<script id="dk-conf" type="application/json">{conf}</script>\n'
        f'<script id="dk-glb" type="application/octet-stream">{b64}</script>\n'
        f"<script>\n{asset_text('glb_viewer.js')}</script>\n"
    ))


def render_glb_html(path: str | os.PathLike, glb: str | os.PathLike | bytes, *,
                    options: RenderOptions | None = None) -> None:
    """Write a self-contained html page that plays the glTF binary ``glb`` (a path or the bytes).

    ``options``: ``title`` (default: the output file's stem) and the initial camera
    (``azimuth``, default 30 degrees, and ``elevation``); the other fields do not apply.

    Examples
    --------
    >>> render_glb_html("view.html", "dance.glb")  # doctest: +SKIP
    """
    options = RenderOptions() if options is None else options
    data = glb if isinstance(glb, bytes | bytearray) else Path(glb).read_bytes()
    title = options.title
    if title is None:
        title = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    text = glb_page_html(bytes(data), title=title, azimuth=30.0 if options.azimuth is None else options.azimuth,
                         elevation=options.elevation)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def render_motion_glb_html(path: str | os.PathLike, motion, *, options: RenderOptions | None = None) -> None:
    """:func:`render_glb_html` for a :class:`dancekit.motion.Motion` (written as a glb first)."""
    from dancekit.motion.formats.gltf import write_glb
    from dancekit.render._motion import motion_arrays
    from dancekit.render._scene import default_azimuth, prepare_scene

    options = RenderOptions() if options is None else options
    if options.azimuth is None and motion.skeleton.dims == 3:  # a three-quarter view of the dancer's front
        a = motion_arrays(motion)
        scene = prepare_scene(a.pop("positions"), **a)
        options = dataclasses.replace(options, azimuth=default_azimuth(scene))
    with tempfile.TemporaryDirectory() as d:
        glb = Path(d) / "dance.glb"
        write_glb(glb, motion)
        render_glb_html(path, glb, options=options)
