"""Render a dance to ONE self-contained html file: a 3D player with the song embedded.

The page needs no network: the player (``assets/player.js``, a small hand-written
Canvas-2D perspective renderer) and its style (``assets/player.css``) are inlined, the
motion is embedded as base64 little-endian uint16 (quantised per axis to 1/65535 of
the motion's extent, well under a millimetre for a dance on a stage) and the song
slice as a base64 MP3 ``data:`` URI. The dance follows the audio clock
(frame = floor(currentTime x fps)); without audio it plays on a wall clock.
"""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import os
from importlib import resources

import numpy as np

from dancekit._io import atomic_path
from dancekit.render._ffmpeg import audio_span, encode_audio_slice
from dancekit.render._motion import _CHUNK
from dancekit.render._scene import Scene, camera_basis, default_azimuth, fit_distance, prepare_scene
from dancekit.render.options import AudioClip, RenderOptions, resolve

_FOV = 40.0  # degrees, vertical; must match FOV in player.js
_ELEVATION = 12.0
_ASPECT = 4.0 / 3.0  # the initial distance frames the dance in a 4:3 (or wider) window
_HTML_KEYWORDS = ("title",)  # deprecated keywords (release 0.1), besides audio_path / _start / _end


def asset_text(name: str) -> str:
    text = resources.files("dancekit.render").joinpath("assets", name).read_text(encoding="utf-8")
    assert "</script" not in text.lower() and "</style" not in text.lower(), name
    return text


def _quantise(p: np.ndarray) -> tuple[bytes, list[float], list[float]]:
    """``p (T, J, 3)`` -> (uint16 LE bytes, offset (3,), scale (3,)); ``p ~ offset + v * scale``."""
    lo = p.reshape(-1, 3).min(axis=0).astype(np.float64)
    hi = p.reshape(-1, 3).max(axis=0).astype(np.float64)
    scale = np.maximum(hi - lo, 1e-6) / 65535.0
    v = np.empty(p.shape, "<u2")
    for a in range(0, len(p), _CHUNK):  # per frame: the float64 temporaries stay a chunk's size
        v[a: a + _CHUNK] = np.clip(np.rint((p[a: a + _CHUNK] - lo) / scale), 0, 65535)
    return v.tobytes(), lo.tolist(), scale.tolist()


def page_html(
    scene: Scene,
    *,
    audio: tuple[bytes, str] | None = None,
    duration: float | None = None,
    title: str = "dancekit",
    azimuth: float | None = None,
    elevation: float = _ELEVATION,
    figure: str = "stick",
) -> str:
    """The html text of a player page for ``scene`` (``audio``: encoded bytes and MIME type): the text that
    :func:`write_page` writes, as one string. Arguments as :func:`write_page`."""
    import io

    buf = io.StringIO()
    write_page(buf.write, scene, audio=audio, duration=duration, title=title, azimuth=azimuth,
               elevation=elevation, figure=figure)
    return buf.getvalue()


def write_page(
    write,
    scene: Scene,
    *,
    audio: tuple[bytes, str] | None = None,
    duration: float | None = None,
    title: str = "dancekit",
    azimuth: float | None = None,
    elevation: float = _ELEVATION,
    figure: str = "stick",
) -> None:
    """Write the html of a player page for ``scene`` piece by piece with ``write(text)`` (e.g. an open
    file's ``write``): the song and the motion go out as base64 in pieces, so a one-hour song's page is
    never one string in memory (``audio``: encoded bytes and MIME type).

    ``azimuth`` / ``elevation`` (degrees) set the initial camera; azimuth None is a
    three-quarter view of the dancer's front. ``figure``: ``"stick"`` or ``"body"`` (shaded
    capsules, a rounded torso and a head with a face that turn with the body; the same
    parts as the mp4's body figure).
    """
    az = default_azimuth(scene) if azimuth is None else float(azimuth)
    tan_y = math.tan(math.radians(_FOV) / 2)
    basis = camera_basis(math.radians(az), math.radians(elevation))
    dist = fit_distance(scene, basis, tan_half_x=tan_y * _ASPECT, tan_half_y=tan_y)
    qbytes, offset, scale = _quantise(scene.positions)
    data = {
        "version": 1,
        "title": title,
        "fps": scene.fps,
        "frames": scene.num_frames,
        "joints": int(scene.positions.shape[1]),
        "duration": float(duration if duration is not None else scene.num_frames / scene.fps),
        "bones": scene.bones.tolist(),
        "sides": scene.sides.astype(int).tolist(),
        "head": scene.head,
        "height": scene.height,
        "azimuth": az,
        "elevation": elevation,
        "distance": dist,
        "offset": offset,
        "scale": scale,
        "positions": _B64_SLOT,  # written in pieces below
        "target": base64.b64encode(scene.target.astype("<f4").tobytes()).decode("ascii"),
    }
    if figure == "body" and len(scene.bones):
        from dancekit.render.video import body_parts

        torso, limb_r, limb = body_parts(scene)
        data["figure"] = "body"
        data["torso"] = torso.tolist()
        data["limbRadius"] = [round(float(r), 4) for r in limb_r]
        data["limb"] = limb.astype(int).tolist()
    else:
        data["figure"] = "stick"
    blob = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    before, after = blob.split(_B64_SLOT, 1)
    head, tail = _shell_parts(title)
    write(head)
    if audio is not None:
        write(f'<audio id="dk-audio" preload="auto" src="data:{audio[1]};base64,')
        _write_base64(write, audio[0])
        write('"></audio>\n')
    write('<script id="dk-data" type="application/json">')
    write(before)
    _write_base64(write, qbytes)
    write(after)
    write(f"</script>\n<script>\n{asset_text('player.js')}</script>\n")
    write(tail)


_B64_SLOT = "@@dancekit-positions@@"
#: Bytes per base64 piece written (a multiple of 3, so the pieces join into the one base64 text).
_B64_PIECE = 3 << 18


def _write_base64(write, data: bytes) -> None:
    """``write(base64(data))`` in pieces: the same text as one encode, without a full-size copy."""
    view = memoryview(data)
    for a in range(0, len(view), _B64_PIECE):
        write(base64.b64encode(view[a: a + _B64_PIECE]).decode("ascii"))


def render_html(
    path: str | os.PathLike,
    positions: np.ndarray,
    *,
    parents,
    fps: float,
    up_axis: str = "y",
    unit_scale: float = 0.01,
    sides=None,
    head: int | None = None,
    audio: AudioClip | str | os.PathLike | None = None,
    options: RenderOptions | None = None,
    **deprecated,
) -> None:
    """Write a self-contained html player for a dance (and its song).

    The file opens in any browser without network access: play/pause, a scrubbing
    slider, the time, and an orbit camera (drag to rotate, wheel to zoom, double-click
    to reset). With audio the dance follows the audio clock.

    Parameters
    ----------
    path : path-like
        Output ``.html`` (written to a temporary file and renamed; nothing is left on failure).
    positions : np.ndarray, (T, J, 3)
        Joint positions in the skeleton's units at ``fps`` frames per second.
    parents : array-like, (J,) int
        Parent of each joint (``-1`` for the root).
    fps : float
        Frames per second.
    up_axis : {"y", "z", "x", "-y"}
        Which axis of ``positions`` points up.
    unit_scale : float
        Metres per unit of ``positions`` (0.01 for centimetres).
    sides : array-like, (J,) or None
        ``+1`` left (blue) / ``-1`` right (orange) / ``0`` centre per joint.
    head : int or None
        Joint drawn as a head disc.
    audio : AudioClip, path-like or None
        Song slice, embedded as MP3 (``start`` / ``end`` default to 0 and
        ``start + T / fps``, clipped to the song; a plain path: the song from 0 s).
    options : RenderOptions or None
        ``title`` (default: the output file's stem), the initial camera
        (``azimuth``, ``elevation``) and ``figure`` (``"stick"`` or ``"body"``, the
        volumetric mannequin); the size and ``crf`` apply to mp4 only.
    **deprecated
        The keywords of release 0.1 (``audio_path``, ``audio_start``, ``audio_end``,
        ``title``) still work, with a ``DeprecationWarning``.

    Raises
    ------
    ParameterError
        On bad arrays or times.
    AudioError
        If the song is missing or unreadable.
    ExternalToolError
        If ffmpeg fails to encode the slice.
    DancekitError
        If the output folder does not exist or is not writable.

    Examples
    --------
    >>> render_html("dance.html", motion.positions, parents=skeleton.parents, fps=25,
    ...             audio=AudioClip("song.mp3", start=12.0))  # doctest: +SKIP
    """
    options, audio = resolve("render_html", options, audio, deprecated, accepted=_HTML_KEYWORDS)
    scene = prepare_scene(
        positions, parents=parents, fps=fps, up_axis=up_axis, unit_scale=unit_scale, sides=sides, head=head
    )
    encoded = None
    duration = None
    if audio is not None:
        span = audio_span(
            audio.path, start=audio.start, end=audio.end, motion_duration=scene.num_frames / scene.fps
        )
        encoded = encode_audio_slice(span)
        duration = span.duration
    title = options.title
    if title is None:
        title = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        write_page(fh.write, scene, audio=encoded, duration=duration, title=title, azimuth=options.azimuth,
                   elevation=options.elevation, figure=options.figure)


def render_motion_html(
    path: str | os.PathLike,
    motion,
    *,
    audio: AudioClip | str | os.PathLike | None = None,
    options: RenderOptions | None = None,
    **deprecated,
) -> None:
    """:func:`render_html` for a :class:`dancekit.motion.Motion` (skeleton, fps and sides taken from it).

    Examples
    --------
    >>> render_motion_html("dance.html", motion, audio="song.mp3",
    ...                    options=RenderOptions(title="my dance"))  # doctest: +SKIP
    """
    from dancekit.render._motion import motion_arrays

    options, audio = resolve("render_motion_html", options, audio, deprecated, accepted=_HTML_KEYWORDS)
    render_html(path, **motion_arrays(motion), audio=audio, options=options)


def page_shell(title: str, body: str) -> str:
    """The html page of the players: a head (error recorder, styles), the canvas, title, help line and
    play/scrub controls, then ``body`` (the page's data and script tags). ``title`` is escaped here."""
    head, tail = _shell_parts(title)
    return f"{head}{body}{tail}"


def _shell_parts(title: str) -> tuple[str, str]:
    """The page of :func:`page_shell` before and after its body."""
    esc = html_lib.escape(title)
    # the first script records errors (even a syntax error in the player) on <html data-dk-error>
    return (
        "<!doctype html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{esc}</title>\n"
        "<script>\n"
        "(function () {\n"
        "  function note(msg) { var d = document.documentElement;\n"
        "    d.dataset.dkError = (d.dataset.dkError ? d.dataset.dkError + ' | ' : '') + msg; }\n"
        "  window.addEventListener('error', function (e) { note(e.message || 'error'); });\n"
        "  window.addEventListener('unhandledrejection', function (e) { note(String(e.reason)); });\n"
        "  var err = console.error; console.error = function () {\n"
        "    note(Array.prototype.join.call(arguments, ' ')); err.apply(console, arguments); };\n"
        "})();\n"
        "</script>\n"
        f"<style>\n{asset_text('player.css')}</style>\n"
        "</head>\n<body>\n"
        '<div id="dk-player">\n'
        '<canvas id="dk-canvas"></canvas>\n'
        f'<div id="dk-title">{esc}</div>\n'
        '<div id="dk-help">drag: rotate &middot; wheel: zoom &middot; double-click: reset &middot; space: play</div>\n'
        '<div id="dk-controls">\n'
        '<button id="dk-play" type="button" aria-label="play">&#9654;</button>\n'
        '<input id="dk-scrub" type="range" min="0" max="0" step="1" value="0" aria-label="time">\n'
        '<span id="dk-time">0:00.0</span>\n'
        "</div>\n</div>\n"
    ), "</body>\n</html>\n"
