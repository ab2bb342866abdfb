"""Render a dance to an mp4 with its song: frames drawn with Pillow, piped to one ffmpeg.

The figure stands on a checkerboard floor seen in perspective by a camera that follows
the dancer (the root's horizontal path smoothed without lag, fixed elevation, one
distance for the whole clip that keeps every joint of every frame in the image).
Bones are thick lines drawn at twice the resolution and box-filtered down (so their
edges are anti-aliased), left joints blue, right joints orange; a soft shadow lies
under the figure.

The video lasts exactly as long as the song slice: the dance is padded with its last
frame (or cut) to ``round(duration * fps)`` frames.

Speed (a minute of dance in a few seconds on two cores): the mp4's frames are drawn in
Y'CbCr (BT.601, limited range: the values ffmpeg's own rgb24 -> yuv420p conversion gives)
and piped as yuv420p, half the bytes of RGB and no conversion in ffmpeg; the sky, the floor
and the soft shadow are made at half resolution, where they are the chroma planes, and the
Y plane is their Y pixel-doubled: only the figure's region is drawn at full resolution (2x
supersampled) and has its chroma averaged; the figures are drawn with Pillow's drawing core
(a private API, checked at import, with the public one as fallback); a writer thread feeds
ffmpeg while the next frame is drawn; x264 runs ``ultrafast`` on one thread, beside the
drawing. :meth:`FrameRenderer.render` gives RGB frames by default (tests, stills).
"""

from __future__ import annotations

import functools
import math
import os
import queue
import statistics
import subprocess
import tempfile
import threading
from fractions import Fraction

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

from dancekit._io import atomic_path
from dancekit.errors import DancekitError, ExternalToolError, ParameterError
from dancekit.render._ffmpeg import AudioSpan, audio_span, ffmpeg_exe, last_line
from dancekit.render._scene import Scene, camera_basis, default_azimuth, fit_distance, prepare_scene
from dancekit.render.options import AudioClip, RenderOptions, resolve

# colours (RGB)
_SKY_TOP = np.array([236, 240, 246], np.float32)
_SKY_LOW = np.array([206, 213, 224], np.float32)
_TILE_A = np.array([226, 229, 234], np.float32)
_TILE_B = np.array([168, 176, 190], np.float32)
_SHADOW = (52, 58, 72)
_BONE = {1: (52, 120, 220), -1: (236, 112, 40), 0: (70, 78, 96)}

_TILE = 0.5  # metres per floor tile
_FOG = 14.0  # metres at which the floor has faded into the sky
_BONE_RADIUS = 0.032  # metres, for a 1.75 m figure
_JOINT_RADIUS = 0.04
_HEAD_RADIUS = 0.11
_SS = 2  # supersampling factor of the figure
_MP4_KEYWORDS = ("width", "height", "azimuth", "elevation", "crf")  # deprecated keywords (release 0.1)


def _shade(rgb: tuple[int, int, int], k: float) -> tuple[int, int, int]:
    return tuple(int(min(255, max(0, round(c * k)))) for c in rgb)


_LEVELS = 17  # brightness levels, from far (0.78) to near (1.22)
_K = np.linspace(0.78, 1.22, _LEVELS)
_PALETTE = {sd: [_shade(rgb, k) for k in _K] for sd, rgb in _BONE.items()}
_JOINT_PALETTE = {sd: [_shade(rgb, 0.82 * k) for k in _K] for sd, rgb in _BONE.items()}
_HEAD_PAL = [_shade((232, 196, 160), k) for k in _K]
_HEAD_EDGE_PAL = [_shade((150, 112, 84), k) for k in _K]

# the "body" figure: a mannequin with a slight blue / orange tint for the left / right limbs
_SKIN = {1: (196, 200, 222), -1: (226, 196, 178), 0: (214, 200, 194)}
_BODY_PAL = {sd: [_shade(rgb, 0.9 * k) for k in _K] for sd, rgb in _SKIN.items()}
_BODY_DARK = {sd: [_shade(rgb, 0.62 * k) for k in _K] for sd, rgb in _SKIN.items()}
_BODY_LIGHT = {sd: [_shade(rgb, 1.08 * k) for k in _K] for sd, rgb in _SKIN.items()}
_LIMB_RADIUS = (0.03, 0.07)  # metres, limb radius = 22 % of the bone length within these bounds
_TORSO_RADIUS = 0.075  # rounding of the torso outline



# BT.601 limited-range R'G'B' -> Y'CbCr: the conversion ffmpeg applies by default to rgb24 frames encoded as
# yuv420p, so frames drawn in YCbCr (the mp4's) look as the RGB ones did after ffmpeg converted them
_YCC = np.array([[65.481, 128.553, 24.966], [-37.797, -74.203, 112.0], [112.0, -93.786, -18.214]]) / 255.0
_YCC_OFFSET = np.array([16.0, 128.0, 128.0])
MODES = ("RGB", "YCbCr")


def _to_mode(rgb: np.ndarray, mode: str) -> np.ndarray:
    """RGB values (..., 3) in 0..255 as uint8 values of ``mode`` (rounded)."""
    rgb = np.asarray(rgb, np.float64)
    out = rgb if mode == "RGB" else rgb @ _YCC.T + _YCC_OFFSET
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _image(values: np.ndarray, mode: str) -> Image.Image:
    """An image of ``mode`` from uint8 values ``(h, w, 3)`` already in that mode."""
    h, w = values.shape[:2]
    return Image.frombytes(mode, (w, h), np.ascontiguousarray(values, np.uint8).tobytes())


@functools.cache
def _palettes(mode: str) -> dict:
    """Every colour of the figures and the shadow, as tuples of ``mode`` (RGB or YCbCr)."""

    def conv(c):
        if isinstance(c, dict):
            return {k: conv(v) for k, v in c.items()}
        if isinstance(c, list):
            return [conv(v) for v in c]
        return tuple(int(v) for v in _to_mode(c, mode))

    return {
        "shadow": conv(_SHADOW), "bone": conv(_PALETTE), "joint": conv(_JOINT_PALETTE), "head": conv(_HEAD_PAL),
        "head_edge": conv(_HEAD_EDGE_PAL), "centre": conv(_BONE[0]),
        "body_dark": conv(_BODY_DARK), "body": conv(_BODY_PAL), "body_light": conv(_BODY_LIGHT),
    }  # fmt: skip


def _inks() -> dict | None:
    """The figures' palettes as Pillow's ink values, ``{mode: {name: {side: [ink per level]}}}``, or None where
    Pillow's drawing core differs from Pillow 10-13's."""
    try:
        out = {}
        for mode in MODES:
            pal = _palettes(mode)
            core = ImageDraw.Draw(Image.new(mode, (4, 4))).draw
            inks = {k: {sd: [core.draw_ink(c) for c in cols] for sd, cols in pal[k].items()}
                    for k in ("body_dark", "body", "body_light", "bone", "joint")}
            core.draw_lines([(0.0, 0.0), (3.0, 3.0)], inks["bone"][0][0], 2)
            core.draw_ellipse([0.0, 0.0, 2.0, 2.0], inks["bone"][0][0], 1)
            out[mode] = inks
        if ImageDraw.Draw(Image.new("L", (4, 4))).draw.draw_ink(110) != 110:  # the shadow's ink
            return None
        return out
    except Exception:  # noqa: BLE001 - any change of the private API: use the public one
        return None


_INKS = _inks()


def _median(values: np.ndarray) -> float:
    """``float(np.median(values))`` of a 1-D float64 array, the same value in a microsecond rather than 40:
    :func:`statistics.median` of its finite values (the middle value, or the mean of the two middle ones as numpy
    takes it: (a + b) / 2)."""
    v = values.tolist()
    if values.dtype != np.float64 or not v or not math.isfinite(sum(v)):
        return float(np.median(values))  # numpy's answer (and warnings) for other types, empty or non-finite
    return statistics.median(v)


def _square_wave(half_off: np.ndarray, c: float, gain2: np.ndarray) -> np.ndarray:
    """The floor's box-filtered square wave of period 2 tiles, +1 on even tiles (float32, a new array of
    ``half_off``'s shape): clip(a h(x), -1, 1) with the triangle wave h(x) = |((x + 1.5) mod 2) - 1| - 0.5, the
    signed distance to the nearest tile edge, of x = off + c tiles (off float32 per pixel, c a scalar) and the
    filter gain a (per pixel, 1 / the pixel's footprint in tiles), from ``half_off`` = off / 2 and ``gain2`` = 2 a.

    With u = x / 2 (exact: half_off + (c + 1.5) / 2 rounds as off + (c + 1.5) does, halved) and f = u - floor(u)
    (exact), (x + 1.5) mod 2 is 2 f and a h(x) = 2 a (|f - 1/2| - 1/4): each step is the plain formula's halved or
    doubled, so the float32 results are the same, in 8 passes instead of 11."""
    u = half_off + np.float32(c + 1.5) * np.float32(0.5)  # in place from here: fewer arrays
    u -= np.floor(u)
    u -= 0.5
    np.abs(u, out=u)
    u -= 0.25
    u *= gain2
    return np.clip(u, -1.0, 1.0, out=u)


class FrameRenderer:
    """Draws the frames of one :class:`~dancekit.render._scene.Scene` (RGB, ``height x width``).

    Parameters
    ----------
    scene : Scene
    width, height : int
        Image size in pixels.
    azimuth, elevation : float or None
        Camera angles in degrees; azimuth None faces the figure's average front at a
        three-quarter angle (or 30 degrees when the front is unknown).
    fov : float
        Vertical field of view in degrees.
    figure : {"stick", "body"}
        How the dancer is drawn.
    mode : {"RGB", "YCbCr"}
        Pillow mode of the frames: RGB, or YCbCr with BT.601 limited-range values (the mp4's; see
        :func:`yuv420`).
    """

    def __init__(
        self,
        scene: Scene,
        *,
        width: int,
        height: int,
        azimuth: float | None = None,
        elevation: float = 12.0,
        fov: float = 40.0,
        figure: str = "stick",
        mode: str = "RGB",
    ):
        if mode not in MODES:
            raise ParameterError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        self.scene = scene
        self.figure = figure
        self.mode = mode
        self._pal = _palettes(mode)
        self.W, self.H = int(width), int(height)
        az = default_azimuth(scene) if azimuth is None else float(azimuth)
        self.basis = camera_basis(math.radians(az), math.radians(elevation))
        right, up, fwd = self.basis
        self.f = 0.5 * self.H / math.tan(math.radians(fov) / 2)
        tan_y = 0.5 * self.H / self.f
        tan_x = 0.5 * self.W / self.f
        self.distance = fit_distance(scene, self.basis, tan_half_x=tan_x, tan_half_y=tan_y)
        # camera positions (T, 3); the height is the same in every frame
        self.cam = scene.target - self.distance * fwd[None, :].astype(np.float32)
        self.cam_h = float(self.cam[0, 1])
        self.k = scene.height / 1.75  # thickness scale
        self._build_background()
        self._build_floor()
        bones = scene.bones
        self._bc, self._bp = bones[:, 0], bones[:, 1]
        self._bc_all, self._bp_all = self._bc.tolist(), self._bp.tolist()
        sides = scene.sides
        bone_side = [int(sides[c]) if sides[c] == sides[p] or sides[p] == 0 else 0 for c, p in bones]
        self._bone_pal = [self._pal["bone"][sd] for sd in bone_side]
        self._joint_pal = [self._pal["joint"][int(sd)] for sd in sides]
        # bones that end at the head are drawn behind the head disc
        self._head_bones = np.array(
            [i for i, (c, p) in enumerate(bones) if scene.head in (c, p)], dtype=np.int64
        )
        self._bone_side = bone_side
        self._build_body()

    def _build_body(self) -> None:
        """The body figure's parts: the torso's joints and a radius per limb bone (metres)."""
        if self.figure != "body" or not len(self.scene.bones):
            self._torso = np.zeros(0, np.int64)
            return
        self._torso, self._limb_r, self._limb = body_parts(self.scene)
        self._bc_list, self._bp_list = self._bc.tolist(), self._bp.tolist()
        self._limb_list = np.flatnonzero(self._limb).tolist()
        self._limb_r_list = self._limb_r.tolist()

    def _head_depth(self, z: np.ndarray) -> float:
        """Sort depth of the head disc: just in front of the bones that end at the head."""
        if self.scene.head is None:
            return -np.inf
        hb = self._head_bones
        near = min(z[self._bc[hb]].min(), z[self._bp[hb]].min()) if len(hb) else np.inf
        return float(min(z[self.scene.head], near)) - 1e-3

    # ---------------------------------------------------------------- static parts
    def _build_background(self) -> None:
        v = np.linspace(0.0, 1.0, self.H, dtype=np.float32)[:, None]
        sky = _SKY_TOP * (1 - v) + _SKY_LOW * v  # (H, 3)
        self.background = np.repeat(sky[:, None, :], self.W, axis=1)  # (H, W, 3) float32
        # a frame's sky and floor are made at half resolution and pixel-doubled (the sky changes by one level in
        # about 16 rows, the floor's checker is box-filtered at half resolution)
        self._half = ((self.W + 1) // 2, (self.H + 1) // 2)
        self._bg_half = _image(_to_mode(self.background[::2, ::2].astype(np.uint8), self.mode), self.mode)
        self._bg_image = self._double(self._bg_half)

    def _double(self, half: Image.Image) -> Image.Image:
        """A half-resolution image pixel-doubled to the frame's size."""
        return half.resize((self.W, self.H), Image.NEAREST, box=(0, 0, 0.5 * self.W, 0.5 * self.H))

    def _build_floor(self) -> None:
        """Per-pixel floor geometry at half resolution (the checker is box-filtered there, then pixel-doubled)."""
        right, up, fwd = self.basis
        # horizon: rows whose ray points down; the camera never rolls, so it is a row index
        el = math.asin(-fwd[1])
        v_h = 0.5 * self.H - self.f * math.tan(el)
        self.row0 = int(max(0, min(self.H, math.floor(v_h) + 1)))
        self.row0 -= self.row0 % 2
        w2, h2 = self._half[0], (self.H - self.row0 + 1) // 2
        if h2 <= 0 or self.cam_h <= 0:
            self.has_floor = False
            return
        self.has_floor = True
        u = 2.0 * np.arange(w2, dtype=np.float64) + 1.0
        v = self.row0 + 2.0 * np.arange(h2, dtype=np.float64) + 1.0
        uu, vv = np.meshgrid(u, v)  # (h2, w2), full-resolution pixel centres
        dx = (uu - 0.5 * self.W) / self.f
        dy = -(vv - 0.5 * self.H) / self.f
        d = dx[..., None] * right + dy[..., None] * up + fwd  # (h2, w2, 3)
        down = np.minimum(d[..., 1], -1e-6)
        t = self.cam_h / -down
        offx, offz = t * d[..., 0], t * d[..., 2]
        dist = t * np.linalg.norm(d, axis=-1)
        # footprint of a half-resolution pixel on the floor, in tiles (box-filter width)
        gx = np.abs(np.gradient(offx, axis=1)) + np.abs(np.gradient(offx, axis=0))
        gz = np.abs(np.gradient(offz, axis=1)) + np.abs(np.gradient(offz, axis=0))
        # the floor's offsets in tiles and the box filter's gains (1 / footprint in tiles), float32, as
        # _square_wave takes them: offsets halved, gains doubled (h2, w2)
        self._half_offx = (offx / _TILE).astype(np.float32) * np.float32(0.5)
        self._half_offz = (offz / _TILE).astype(np.float32) * np.float32(0.5)
        self._gain2x = (2.0 * _TILE / np.maximum(gx, 1e-9)).astype(np.float32) * np.float32(2.0)
        self._gain2z = (2.0 * _TILE / np.maximum(gz, 1e-9)).astype(np.float32) * np.float32(2.0)
        fog = np.clip(dist / _FOG, 0.0, 1.0)[..., None] ** 1.5
        sky = self.background[self.row0 : self.row0 + 2 * h2 : 2, ::2][:h2, :w2]
        # the sky above the floor of the dark tile colour faded into the sky, and the floor's rows alone in the
        # light colour; a frame blends them by the filtered checker (its blending weights, 0..255, in self._blend)
        self._floor_dark = self._bg_half.copy()
        dark = _image(_to_mode(_TILE_B * (1 - fog) + sky * fog, self.mode), self.mode)
        self._floor_dark.paste(dark, (0, self.row0 // 2))
        self._floor_light = _image(_to_mode(_TILE_A * (1 - fog) + sky * fog, self.mode), self.mode)  # (w2, h2)
        self._blend = np.zeros((h2, w2), np.uint8)

    def _base(self, t: int) -> Image.Image:
        """The sky and the floor of frame ``t`` at half resolution (a new image)."""
        if not self.has_floor:
            return self._bg_half.copy()
        cx, cz = self.cam[t, 0] / _TILE, self.cam[t, 2] / _TILE
        checker = _square_wave(self._half_offx, cx, self._gain2x)
        checker *= _square_wave(self._half_offz, cz, self._gain2z)  # -1 (dark tile) .. 1 (light tile)
        checker *= 127.5
        checker += 128.0  # rounded by the cast below: 0 (dark) .. 255 (light)
        np.copyto(self._blend, checker, casting="unsafe")
        blend = Image.frombuffer("L", self._blend.shape[::-1], self._blend, "raw", "L", 0, 1)
        out = self._floor_dark.copy()  # Image.composite over the floor's rows only (0 on the sky: the dark image)
        out.paste(self._floor_light, (0, self.row0 // 2), blend)
        return out

    def _floor(self, t: int) -> Image.Image:
        """The floor of frame ``t``: rows ``row0`` and below, at full resolution."""
        return self._double(self._base(t)).crop((0, self.row0, self.W, self.H))

    # ---------------------------------------------------------------- per frame
    def project(self, t: int, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates ``(N, 2)`` and camera depths ``(N,)`` of world points ``(N, 3)``."""
        right, up, fwd = self.basis
        rel = points - self.cam[t]
        z = np.maximum(rel @ fwd, 1e-3)
        uv = np.stack(
            [0.5 * self.W + self.f * (rel @ right) / z, 0.5 * self.H - self.f * (rel @ up) / z], axis=1
        )
        return uv, z

    def render(self, t: int) -> Image.Image:
        """Frame ``t`` as an image of the renderer's mode, RGB by default (``t`` is clipped to the motion's frames)."""
        half, fig, x0, y0 = self._layers(t)
        # NEAREST: the checker is already box-filtered, the shadow soft (BILINEAR would cost 2 ms a frame)
        frame = self._double(half)
        if fig is not None:
            frame.paste(fig, (x0, y0))
        return frame

    def render_yuv420(self, t: int) -> bytes:
        """Frame ``t`` as raw yuv420p bytes, equal to ``yuv420(self.render(t))`` (a renderer in YCbCr mode, even
        width and height), without the full-resolution frame: outside the figure's region the frame is the
        pixel-doubled ``half``, whose chroma is already the 2 x 2 mean, so the Y plane is ``half``'s Y doubled
        with the figure's Y pasted in, and the chroma planes are ``half``'s with the figure's region averaged."""
        if self.mode != "YCbCr" or self.W % 2 or self.H % 2 or getattr(self.render, "__func__", None) is not _RENDER:
            return yuv420(self.render(t))  # a render replaced (a subclass's, a test's): its frames
        half, fig, x0, y0 = self._layers(t)
        w2, h2 = half.size
        out = np.empty(self.W * self.H + 2 * w2 * h2, np.uint8)  # the yuv420p frame: Y (H, W), Cb, Cr (H/2, W/2)
        y_plane = out[: self.W * self.H].reshape(self.H, self.W)
        # pixel doubling of Y: each half-resolution byte times 257 is the 16-bit word of two equal bytes, and
        # each row of words is written to two rows
        y_half = np.frombuffer(half.getchannel("Y").tobytes(), np.uint8).reshape(h2, w2)
        np.multiply(y_half[:, None, :], np.uint16(257), out=y_plane.view(np.uint16).reshape(h2, 2, w2))
        if fig is not None:
            fw, fh = fig.size
            y_plane[y0 : y0 + fh, x0 : x0 + fw] = np.frombuffer(fig.tobytes("raw", "Y"), np.uint8).reshape(fh, fw)
            half.paste(fig.reduce(2), (x0 // 2, y0 // 2))
        n = w2 * h2
        out[self.W * self.H : self.W * self.H + n] = np.frombuffer(half.tobytes("raw", "Cb"), np.uint8)
        out[self.W * self.H + n :] = np.frombuffer(half.tobytes("raw", "Cr"), np.uint8)
        return out.tobytes()

    def _layers(self, t: int) -> tuple[Image.Image, Image.Image | None, int, int]:
        """The parts of frame ``t`` (clipped to the motion's frames): the sky, floor and shadow at half resolution
        (W/2, H/2, rounded up), and the figure's region at full resolution with its top-left corner ``(x0, y0)``
        (even), which covers the pixel-doubled ``half`` there (None, 0, 0 when the figure is off screen)."""
        t = int(min(max(t, 0), self.scene.num_frames - 1))
        pos = self.scene.positions[t]
        half = self._base(t)
        self._shadow(half, t, pos)
        if self.figure == "body" and len(self.scene.bones):
            region = self._body(half, t, pos)
        else:
            region = self._figure(half, t, pos)
        return (half, None, 0, 0) if region is None else (half, *region)

    def _shadow(self, half: Image.Image, t: int, pos: np.ndarray) -> None:
        """Bones projected straight down, drawn at quarter resolution, blurred and upsampled to ``half``: the frame's
        sky and floor at half resolution (soft edges)."""
        if not self.has_floor or len(self.scene.bones) == 0:
            return
        ground = pos.copy()
        ground[:, 1] = 0.0
        uv, z = self.project(t, ground)
        if np.any(z <= 1e-3):
            return
        uv = uv * 0.5  # half-resolution pixels
        q = 2  # half-resolution pixels per pixel of the mask
        pad = 20
        x0, y0 = np.floor(uv.min(axis=0)).astype(int) - pad
        x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + pad
        x0, y0 = max(x0, 0), max(y0, self.row0 // 2)
        x1, y1 = min(x1, half.width), min(y1, half.height)
        if x1 - x0 < q or y1 - y0 < q:
            return
        size = ((x1 - x0 + q - 1) // q, (y1 - y0 + q - 1) // q)
        mask = Image.new("L", size, 0)
        draw = ImageDraw.Draw(mask)
        loc = [tuple(v) for v in ((uv - [x0, y0]) / q).tolist()]  # plain floats: numpy scalars are slow here
        width = max(1, int(round(2.6 * _BONE_RADIUS * self.k * self.f / _median(z) / (2 * q))))
        r = 0.5 * width
        if _INKS is not None:  # Pillow's core, as in _body: the same pixels as the public calls below
            seg, disc = draw.draw.draw_lines, draw.draw.draw_ellipse
            for c, p in zip(self._bc_all, self._bp_all):
                seg([loc[c], loc[p]], 110, width)
            for x, y in loc:
                disc([x - r, y - r, x + r, y + r], 110, 1)
        else:
            for c, p in zip(self._bc_all, self._bp_all):
                draw.line([loc[c], loc[p]], fill=110, width=width)
            for x, y in loc:
                draw.ellipse([x - r, y - r, x + r, y + r], fill=110)
        mask = mask.filter(ImageFilter.GaussianBlur(1.2))
        mask = mask.resize((x1 - x0, y1 - y0), Image.BILINEAR, box=(0, 0, (x1 - x0) / q, (y1 - y0) / q))
        half.paste(self._pal["shadow"], (x0, y0, x1, y1), mask)

    def _figure(self, half: Image.Image, t: int, pos: np.ndarray) -> tuple[Image.Image, int, int] | None:
        """Bones (far to near) and joints drawn at ``_SS`` x resolution on a crop of the pixel-doubled ``half``,
        then reduced: the figure's region at full resolution and its top-left corner (see :meth:`_layers`)."""
        sc = self.scene
        uv, z = self.project(t, pos)
        zr = _median(z)
        rb = _BONE_RADIUS * self.k * self.f / z  # pixel radii per joint
        rj = _JOINT_RADIUS * self.k * self.f / z
        rh = _HEAD_RADIUS * self.k * self.f / z
        reach = float(max(rj.max(), rh.max() if sc.head is not None else 0.0)) + 3
        region = self._figure_region(half, uv, reach)
        if region is None:
            return None
        crop, x0, y0 = region
        draw = ImageDraw.Draw(crop)
        loc = (uv - [x0, y0]) * _SS

        # nearer is brighter: brightness level 0.._LEVELS-1 from the depth relative to the body
        depth = np.concatenate([0.5 * (z[self._bc] + z[self._bp]), [self._head_depth(z)]])
        level = np.clip(
            np.rint((np.clip((zr - depth) / 0.6, -1.0, 1.0) + 1) * 0.5 * (_LEVELS - 1)), 0, _LEVELS - 1
        )
        level = level.astype(np.int64).tolist()
        order = np.argsort(-depth, kind="stable").tolist()
        nb = len(self._bc)
        # per-bone widths and per-joint boxes computed at once, as plain floats (numpy scalars are slow)
        widths = [max(1, int(round(float(w) * _SS))) for w in (rb[self._bc] + rb[self._bp]).tolist()]
        pts = [tuple(q) for q in loc.tolist()]
        rs = rj * _SS
        boxes = np.stack([loc[:, 0] - rs, loc[:, 1] - rs, loc[:, 0] + rs, loc[:, 1] + rs], axis=1).tolist()
        bc, bp = self._bc_all, self._bp_all
        if _INKS is not None:  # Pillow's drawing core with precomputed inks, as in _body
            seg, disc = draw.draw.draw_lines, draw.draw.draw_ellipse
            ink = _INKS[self.mode]
            bone_pal = [ink["bone"][sd] for sd in self._bone_side]
            joint_pal = [ink["joint"][sd] for sd in sc.sides.tolist()]
        else:
            def seg(xy, fill, width):
                draw.line(xy, fill=fill, width=width)

            def disc(box, fill, _):
                draw.ellipse(box, fill=fill)

            bone_pal, joint_pal = self._bone_pal, self._joint_pal
        for i in order:
            if i < nb:
                c, p = bc[i], bp[i]
                lv = level[i]
                seg([pts[c], pts[p]], bone_pal[i][lv], widths[i])
                disc(boxes[c], joint_pal[c][lv], 1)
                disc(boxes[p], joint_pal[p][lv], 1)
            elif sc.head is not None:
                j = sc.head
                r = rh[j] * _SS
                draw.ellipse(
                    [loc[j, 0] - r, loc[j, 1] - r, loc[j, 0] + r, loc[j, 1] + r],
                    fill=self._pal["head"][level[i]],
                    outline=self._pal["head_edge"][level[i]],
                    width=max(1, int(round(0.12 * r))),
                )
        if not len(sc.bones):
            for j in range(len(pos)):
                r = rj[j] * _SS
                draw.ellipse([loc[j, 0] - r, loc[j, 1] - r, loc[j, 0] + r, loc[j, 1] + r], fill=self._pal["centre"])
        return crop.reduce(_SS), x0, y0

    def _figure_region(self, half: Image.Image, uv: np.ndarray,
                       reach: float) -> tuple[Image.Image, int, int] | None:
        """The part of the frame around the projected joints ``uv`` (J, 2) plus ``reach`` pixels, clipped to the
        frame, with even corners, as a crop of the pixel-doubled ``half`` upscaled ``_SS`` times for supersampled
        drawing, and its top-left corner ``(x0, y0)`` in frame pixels; None when less than 2 pixels of it are on
        screen."""
        x0 = int(max(math.floor(uv[:, 0].min() - reach), 0))
        y0 = int(max(math.floor(uv[:, 1].min() - reach), 0))
        x1 = int(min(math.ceil(uv[:, 0].max() + reach), self.W))
        y1 = int(min(math.ceil(uv[:, 1].max() + reach), self.H))
        if x1 - x0 < 2 or y1 - y0 < 2:
            return None
        # even corners: the region is whole 2 x 2 blocks of the half-resolution sky and floor (render_yuv420)
        x0, y0 = x0 - x0 % 2, y0 - y0 % 2
        x1, y1 = min(x1 + x1 % 2, self.W), min(y1 + y1 % 2, self.H)
        # NEAREST by 2 * _SS from half: pixel (i, j) of the crop is half's (x0/2 + i // (2 _SS), ...), as the
        # doubled frame's (x0 + i // _SS, ...) is (the sampling positions are exact binary fractions)
        box = (0.5 * x0, 0.5 * y0, 0.5 * x1, 0.5 * y1)
        crop = half.resize(((x1 - x0) * _SS, (y1 - y0) * _SS), Image.NEAREST, box=box)
        return crop, x0, y0

    def _body(self, half: Image.Image, t: int, pos: np.ndarray) -> tuple[Image.Image, int, int] | None:
        """The mannequin: shaded capsules, a rounded torso outline and a head, far to near, supersampled, as
        :meth:`_figure` draws the stick figure.

        The per-item work is on plain Python floats (numpy scalars cost more than the drawing).
        """
        sc = self.scene
        uv, z = self.project(t, pos)
        zr = _median(z)
        pix = self.f / z  # pixels per metre at each joint
        rh = 1.15 * _HEAD_RADIUS * self.k * pix
        reach = float(max((_LIMB_RADIUS[1] * self.k * pix).max(), rh.max() if sc.head is not None else 0.0)) + 3
        region = self._figure_region(half, uv, reach)
        if region is None:
            return None
        crop, x0, y0 = region
        draw = ImageDraw.Draw(crop)
        loc_np = (uv - [x0, y0]) * _SS
        loc = [tuple(q) for q in loc_np.tolist()]
        zl, pl = z.tolist(), pix.tolist()
        top = _LEVELS - 1

        def level(d: float) -> int:
            return int(round((min(max((zr - d) / 0.6, -1.0), 1.0) + 1) * 0.5 * top))

        bc, bp = self._bc_list, self._bp_list
        items = [(0.5 * (zl[bc[i]] + zl[bp[i]]), 0, i) for i in self._limb_list]  # (depth, kind, index)
        if len(self._torso) >= 3:
            items.append((float(z[self._torso].mean()), 1, 0))
        if sc.head is not None:
            items.append((self._head_depth(z), 2, sc.head))
        items.sort(key=lambda it: -it[0])
        if _INKS is not None:  # Pillow's drawing core with precomputed inks: the same pixels, less overhead
            seg, disc, poly = draw.draw.draw_lines, draw.draw.draw_ellipse, draw.draw.draw_polygon
            dark, pal, light = (_INKS[self.mode][k] for k in ("body_dark", "body", "body_light"))
        else:
            def seg(xy, fill, width):
                draw.line(xy, fill=fill, width=width)

            def disc(box, fill, _):
                draw.ellipse(box, fill=fill)

            def poly(xy, fill, _):
                draw.polygon(xy, fill=fill)

            dark, pal, light = self._pal["body_dark"], self._pal["body"], self._pal["body_light"]

        for d, kind, i in items:
            lv = level(d)
            if kind == 0:  # a limb: dark rim, body colour, a highlight towards the light (up left)
                c, p = bc[i], bp[i]
                sd = self._bone_side[i]
                (ax, ay), (bx, by) = loc[c], loc[p]
                r = self._limb_r_list[i] * 0.5 * (pl[c] + pl[p]) * _SS
                for fill, rr in ((dark[sd][lv], r), (pal[sd][lv], 0.82 * r)):
                    seg([(ax, ay), (bx, by)], fill, max(1, int(round(2 * rr))))
                    disc([ax - rr, ay - rr, ax + rr, ay + rr], fill, 1)
                    disc([bx - rr, by - rr, bx + rr, by + rr], fill, 1)
                o = -0.3 * r
                seg([(ax + o, ay + o), (bx + o, by + o)], light[sd][lv], max(1, int(round(2 * 0.32 * r))))
            elif kind == 1:  # the torso: the outline of its joints, rounded, shaded the same way
                hull = _convex_hull(loc_np[self._torso])
                r = _TORSO_RADIUS * self.k * float(pix[self._torso].mean()) * _SS
                ring = [tuple(q) for q in hull.tolist()]
                for fill, grow in ((dark[0][lv], 1.0), (pal[0][lv], 0.82)):
                    # the hull grown by r: its polygon, a wide line along its edges and a disc on each corner
                    w = max(1, int(round(2 * grow * r)))
                    seg(ring + ring[:1], fill, w)
                    rr = 0.5 * w
                    for qx, qy in ring:
                        disc([qx - rr, qy - rr, qx + rr, qy + rr], fill, 1)
                    if len(ring) >= 3:
                        poly(ring, fill, 1)
            else:  # the head
                r = float(rh[i]) * _SS
                qx, qy = loc[i]
                disc([qx - r, qy - r, qx + r, qy + r], dark[0][lv], 1)
                r2 = 0.86 * r
                disc([qx - r2, qy - r2, qx + r2, qy + r2], pal[0][lv], 1)
                r3, o = 0.35 * r, 0.3 * r
                disc([qx - o - r3, qy - o - r3, qx - o + r3, qy - o + r3], light[0][lv], 1)
        return crop.reduce(_SS), x0, y0


_RENDER = FrameRenderer.render  # render_yuv420 draws the same frames itself, unless render is replaced


def yuv420(frame: Image.Image) -> bytes:
    """A YCbCr frame (H, W) as raw yuv420p bytes: the Y plane (H, W), then Cb and Cr averaged over 2 x 2 pixels
    (H/2, W/2 each); H and W even."""
    half = frame.reduce(2)  # box filter: each pixel the mean of 2 x 2 (rounded)
    return b"".join((frame.tobytes("raw", "Y"), half.tobytes("raw", "Cb"), half.tobytes("raw", "Cr")))


class _PipeWriter(threading.Thread):
    """Writes byte strings to a pipe from its own thread, so that the next frame is drawn while ffmpeg reads.

    After a write fails (ffmpeg died) the rest is read and dropped, so :meth:`put` never blocks for good;
    ``error`` holds the failure (an ``OSError`` such as ``BrokenPipeError``, or anything else for the caller to
    raise).
    """

    def __init__(self, pipe, depth: int = 8):
        super().__init__(name="dancekit-mp4-writer", daemon=True)
        self.pipe = pipe
        self.queue: queue.Queue = queue.Queue(depth)
        self.error: OSError | None = None
        try:  # a larger pipe (Linux): fewer waits on each side
            import fcntl

            fcntl.fcntl(pipe.fileno(), fcntl.F_SETPIPE_SZ, 1 << 20)
        except (ImportError, AttributeError, OSError):
            pass

    def run(self) -> None:
        while (data := self.queue.get()) is not None:
            if self.error is None:
                try:
                    self.pipe.write(data)
                except Exception as exc:  # noqa: BLE001 - BrokenPipeError: ffmpeg died; others are raised by the caller
                    self.error = exc

    def put(self, data: bytes) -> None:
        self.queue.put(data)

    def finish(self) -> None:
        """Write what is queued, then stop the thread."""
        self.queue.put(None)
        self.join()

    def abort(self, timeout: float = 5.0) -> None:
        """Stop after an error or a signal (ffmpeg already killed: the writes fail and the queue drains) without
        ever blocking for long: a join that a signal interrupted (e.g. inside :meth:`finish`) may not be
        waited on again, and the thread is a daemon, so it cannot hold the process open either way."""
        try:
            self.queue.put_nowait(None)
        except queue.Full:
            pass  # the thread drains the queue (its writes fail) and then waits on a daemon's get
        self.join(timeout)


def body_parts(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body figure's parts, shared by the mp4 and the html player.

    Returns ``(torso, limb_radius, limb)``: the torso's joints (K,), a radius per bone
    (B,) in metres (scaled with the figure's height) and which bones are drawn as limbs
    (B,) bool (bones inside the torso are covered by it).
    """
    sc = scene
    k = sc.height / 1.75
    mean = sc.positions.mean(axis=0)  # (J, 3)
    parent = {int(c): int(p) for c, p in sc.bones}
    root_h = float(np.median(mean[[j for j in range(len(mean)) if j not in parent], 1]))
    side = sc.sides
    trunk = {j for j in range(len(mean)) if side[j] == 0 and j != sc.head}
    # the first joint of each limb (hips, shoulders or collars); above the hips, also the next one
    first = [c for c, p in parent.items() if side[c] != 0 and side[p] == 0]
    trunk.update(first)
    for c, p in parent.items():
        if p in first and mean[p, 1] > root_h and np.linalg.norm(mean[c] - mean[p]) < 0.16 * sc.height / 1.75:
            trunk.add(c)
    if sc.head is not None and sc.head in parent:  # the neck bone is drawn, the head is not torso
        trunk.discard(sc.head)
    torso = np.array(sorted(trunk), dtype=np.int64)
    bc, bp = sc.bones[:, 0], sc.bones[:, 1]
    length = np.linalg.norm(mean[bc] - mean[bp], axis=1)
    limb_r = np.clip(0.22 * length, *_LIMB_RADIUS) * k
    limb = np.array([not (c in trunk and p in trunk) for c, p in sc.bones], dtype=bool)
    return torso, limb_r, limb


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (K, 2) of 2D points (N, 2), counter-clockwise (Andrew's monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) <= 2:
        return np.asarray(pts)

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    upper: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.asarray(lower[:-1] + upper[:-1])


def render_mp4(
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
    progress: bool = True,
    **deprecated,
) -> None:
    """Render a dance to an H.264 mp4, with the song slice muxed in as AAC.

    Parameters
    ----------
    path : path-like
        Output ``.mp4``; written to a temporary file beside it and renamed at the end, so
        a failure leaves nothing behind.
    positions : np.ndarray, (T, J, 3)
        Joint positions in the skeleton's units; frame ``i`` is shown at ``i / fps`` s.
    parents : array-like, (J,) int
        Parent of each joint (``-1`` for the root); one bone is drawn per non-root joint.
    fps : float
        Frames per second of ``positions`` and of the video.
    up_axis : {"y", "z", "x"}
        Which axis of ``positions`` points up.
    unit_scale : float
        Metres per unit of ``positions`` (0.01 for centimetres, as in tang2018).
    sides : array-like, (J,) or None
        ``+1`` left (drawn blue) / ``-1`` right (orange) / ``0`` centre (grey) per joint.
    head : int or None
        Joint to draw as a head disc.
    audio : AudioClip, path-like or None
        Song slice to mux in (a plain path: the song from 0 s). Frame 0 plays at
        ``audio.start``; ``audio.end`` defaults to ``start + T / fps``; both are clipped to
        the song. The video lasts exactly as long as the slice (the dance is padded with
        its last frame or cut to ``round(duration * fps)`` frames). None renders a silent
        video of ``T / fps`` seconds.
    options : RenderOptions or None
        Video size, camera and x264 quality (None: the defaults, 640x480).
    progress : bool
        Show a tqdm progress bar on stderr.
    **deprecated
        The keywords of release 0.1 (``audio_path``, ``audio_start``, ``audio_end``, ``width``,
        ``height``, ``azimuth``, ``elevation``, ``crf``) still work, with a ``DeprecationWarning``.

    Raises
    ------
    ParameterError
        On bad arrays or times.
    AudioError
        If the song is missing or unreadable.
    ExternalToolError
        If ffmpeg fails (its last stderr line is in the message).
    DancekitError
        If the output folder does not exist or is not writable.

    Examples
    --------
    >>> render_mp4("dance.mp4", motion.positions, parents=skeleton.parents, fps=25,
    ...            audio=AudioClip("song.mp3", start=0.0))  # doctest: +SKIP
    """
    options, audio = resolve("render_mp4", options, audio, deprecated, accepted=_MP4_KEYWORDS)
    width, height = options.width, options.height
    scene = prepare_scene(
        positions, parents=parents, fps=fps, up_axis=up_axis, unit_scale=unit_scale, sides=sides, head=head
    )
    span: AudioSpan | None = None
    if audio is not None:
        span = audio_span(
            audio.path, start=audio.start, end=audio.end, motion_duration=scene.num_frames / scene.fps
        )
        n_frames = max(1, int(round(span.duration * scene.fps)))
    else:
        n_frames = scene.num_frames
    rate = Fraction(scene.fps).limit_denominator(1001)

    cmd = [
        ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "error", "-y",
        "-f", "rawvideo", "-pix_fmt", "yuv420p", "-s", f"{width}x{height}", "-r", f"{rate.numerator}/{rate.denominator}",
        "-i", "pipe:0",
    ]  # fmt: skip
    if span is not None:
        cmd += ["-ss", f"{span.start:.6f}", "-t", f"{span.duration:.6f}", "-i", str(span.path)]
        cmd += ["-map", "0:v:0", "-map", "1:a:0", "-c:a", "aac", "-aac_coder", "fast", "-b:a", "160k"]
    cmd += [
        "-c:v", "libx264", "-preset", "ultrafast", "-tune", "animation", "-crf", str(options.crf), "-threads", "1",
        "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4",
    ]  # fmt: skip

    frames = range(n_frames)
    if progress:
        from tqdm import tqdm

        frames = tqdm(frames, desc=f"render {os.path.basename(os.fspath(path))}", unit="frame", leave=False)
    workers = options.workers
    if workers is None:  # a core is left to ffmpeg; on 2 cores drawing and encoding already fill both (measured)
        workers = max(1, min(4, (os.cpu_count() or 1) - 1)) if n_frames > 10 * scene.fps else 1
    draw = dict(width=width, height=height, azimuth=options.azimuth, elevation=options.elevation,
                figure=options.figure, mode="YCbCr")
    with atomic_path(path) as tmp, tempfile.TemporaryFile() as err, _FrameWorkers(scene, draw, n_frames,
                                                                                   workers) as helpers:
        # Popen rather than run: the frames stream to ffmpeg's stdin while they are drawn.
        try:
            proc = subprocess.Popen(  # own process group: a terminal's Ctrl-C reaches dancekit, which stops it
                [*cmd, str(tmp)], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=err, process_group=0
            )
        except OSError as exc:
            raise ExternalToolError(f"cannot start ffmpeg ({cmd[0]}): {exc}") from exc
        writer = _PipeWriter(proc.stdin)
        try:
            # made while ffmpeg starts (about 0.1 s each); frames are drawn in YCbCr and sent as yuv420p, so
            # ffmpeg has no colour conversion to do
            renderer = FrameRenderer(scene, **draw)
            writer.start()
            for t in frames:
                if writer.error is not None:
                    break  # ffmpeg died; its message is read below
                writer.put(helpers.frame(t) if helpers.draws(t) else renderer.render_yuv420(t))
            writer.finish()
            if writer.error is not None and not isinstance(writer.error, OSError):
                raise writer.error
            try:
                proc.stdin.close()
            except BrokenPipeError:
                pass
            rc = proc.wait()
        except BaseException:
            proc.kill()  # first: a write blocked on ffmpeg's pipe fails, and the writer thread ends
            if writer.ident is not None:
                writer.abort()
            proc.wait()
            raise
        if rc != 0:
            err.seek(0)
            raise ExternalToolError(f"ffmpeg failed writing {path} (exit {rc}): {last_line(err.read())}")


def _draw_frames(scene: Scene, draw: dict, first: int, step: int, stop: int, out) -> None:
    """A worker process of :class:`_FrameWorkers`: frames ``first, first + step, … < stop`` as yuv420 bytes into
    the queue ``out`` (an exception as ``("error", message)``)."""
    try:
        renderer = FrameRenderer(scene, **draw)
        for t in range(first, stop, step):
            out.put(renderer.render_yuv420(t))
    except BaseException as exc:  # handed to the parent, which raises it
        out.put(("error", f"{type(exc).__name__}: {exc}"))


class _FrameWorkers:
    """Processes that draw every frame ``t`` with ``t % n != 0`` of an mp4 (``n`` = ``workers``; the caller draws
    the others): each frame is a pure function of the scene and its index, so the video is the same whatever
    ``n``. Spawned (not forked: the caller may hold threads), ahead of the caller by at most 8 frames each;
    stopped when the context ends, whatever happened."""

    def __init__(self, scene: Scene, draw: dict, n_frames: int, workers: int):
        self.n = max(1, min(int(workers), n_frames))
        self.scene, self.draw, self.n_frames = scene, draw, n_frames
        self.procs, self.queues = [], []

    def __enter__(self) -> _FrameWorkers:
        if self.n > 1:
            import multiprocessing as mp

            ctx = mp.get_context("spawn")
            for k in range(1, self.n):
                q = ctx.Queue(maxsize=8)
                p = ctx.Process(target=_draw_frames, args=(self.scene, self.draw, k, self.n, self.n_frames, q),
                                daemon=True, name=f"dancekit-render-{k}")
                p.start()
                self.procs.append(p)
                self.queues.append(q)
        return self

    def draws(self, t: int) -> bool:
        """Whether a worker draws frame ``t``."""
        return self.n > 1 and t % self.n != 0

    def frame(self, t: int) -> bytes:
        """Frame ``t`` from its worker (frames are asked for in order)."""
        k = t % self.n
        while True:
            try:
                item = self.queues[k - 1].get(timeout=1.0)
                break
            except queue.Empty:
                if not self.procs[k - 1].is_alive():
                    raise DancekitError(f"the process drawing frame {t} stopped (exit {self.procs[k - 1].exitcode})") \
                        from None
        if isinstance(item, tuple):
            raise DancekitError(f"drawing frame {t} failed: {item[1]}")
        return item

    def __exit__(self, *exc) -> None:
        for p in self.procs:
            if p.is_alive():
                p.terminate()
        for p in self.procs:
            p.join()
        for q in self.queues:
            q.cancel_join_thread()
            q.close()


def render_motion_mp4(
    path: str | os.PathLike,
    motion,
    *,
    audio: AudioClip | str | os.PathLike | None = None,
    options: RenderOptions | None = None,
    progress: bool = True,
    **deprecated,
) -> None:
    """:func:`render_mp4` for a :class:`dancekit.motion.Motion` (skeleton, fps and sides taken from it).

    Examples
    --------
    >>> render_motion_mp4("dance.mp4", motion, audio=AudioClip("song.mp3", start=12.0),
    ...                   options=RenderOptions(width=320, height=240))  # doctest: +SKIP
    """
    from dancekit.render._motion import motion_arrays

    options, audio = resolve("render_motion_mp4", options, audio, deprecated, accepted=_MP4_KEYWORDS)
    render_mp4(path, **motion_arrays(motion), audio=audio, options=options, progress=progress)
