"""Render a dance to an mp4 with its song: frames drawn with Pillow, piped to one ffmpeg.

The figure stands on a checkerboard floor seen in perspective by a camera that follows
the dancer (the root's horizontal path smoothed without lag, fixed elevation, one
distance for the whole clip that keeps every joint of every frame in the image).
Bones are thick lines drawn at twice the resolution and box-filtered down (so their
edges are anti-aliased), left joints blue, right joints orange; a soft shadow lies
under the figure.

The video lasts exactly as long as the song slice: the dance is padded with its last
frame (or cut) to ``round(duration * fps)`` frames.
"""

from __future__ import annotations

import math
import os
import subprocess
import tempfile
from fractions import Fraction

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

from dancekit._io import atomic_path
from dancekit.errors import ExternalToolError
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



def _inks() -> tuple[dict, dict, dict] | None:
    """The body palettes as Pillow's RGB ink values, or None where its drawing core differs from Pillow 10-13's."""
    try:
        core = ImageDraw.Draw(Image.new("RGB", (4, 4))).draw
        inks = tuple({sd: [core.draw_ink(c) for c in cols] for sd, cols in pal.items()}
                     for pal in (_BODY_DARK, _BODY_PAL, _BODY_LIGHT))
        core.draw_lines([(0.0, 0.0), (3.0, 3.0)], inks[0][0][0], 2)
        core.draw_ellipse([0.0, 0.0, 2.0, 2.0], inks[0][0][0], 1)
        return inks
    except Exception:  # noqa: BLE001 - any change of the private API: use the public one
        return None


_INKS = _inks()


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
    ):
        self.scene = scene
        self.figure = figure
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
        self._bone_pal = [_PALETTE[sd] for sd in bone_side]
        self._joint_pal = [_JOINT_PALETTE[int(sd)] for sd in sides]
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
        self._bg_image = Image.fromarray(self.background.astype(np.uint8), "RGB")

    def _build_floor(self) -> None:
        """Per-pixel floor geometry at half resolution (the checker is box-filtered there, then pixel-doubled)."""
        right, up, fwd = self.basis
        # horizon: rows whose ray points down; the camera never rolls, so it is a row index
        el = math.asin(-fwd[1])
        v_h = 0.5 * self.H - self.f * math.tan(el)
        self.row0 = int(max(0, min(self.H, math.floor(v_h) + 1)))
        self.row0 -= self.row0 % 2
        w2, h2 = self.W // 2, (self.H - self.row0) // 2
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
        self._offx = (offx / _TILE).astype(np.float32)
        self._offz = (offz / _TILE).astype(np.float32)
        self._ax = (2.0 * _TILE / np.maximum(gx, 1e-9)).astype(np.float32)
        self._az = (2.0 * _TILE / np.maximum(gz, 1e-9)).astype(np.float32)
        fog = np.clip(dist / _FOG, 0.0, 1.0)[..., None] ** 1.5
        sky = self.background[self.row0 : self.row0 + 2 * h2 : 2, ::2][:h2, :w2]
        mid, amp = 0.5 * (_TILE_A + _TILE_B), 0.5 * (_TILE_A - _TILE_B)
        self._floor_base = (mid * (1 - fog) + sky * fog).astype(np.float32)
        self._floor_amp = (amp * (1 - fog)).astype(np.float32)

    def _floor(self, t: int) -> Image.Image:
        cx, cz = self.cam[t, 0] / _TILE, self.cam[t, 2] / _TILE

        def square(off: np.ndarray, c: float, a: np.ndarray) -> np.ndarray:
            # in place, with the arithmetic of the plain expressions in the comments (same pixels, fewer arrays)
            x = off + np.float32(c)
            fl = np.floor(x)
            x -= fl  # fr = x - fl
            x -= 0.5
            np.abs(x, out=x)
            np.subtract(0.5, x, out=x)  # edge = 0.5 - |fr - 0.5|: distance to the nearest tile edge (tiles)
            x *= a
            np.minimum(x, 1.0, out=x)  # min(edge * a, 1)
            sign = np.multiply(fl, 0.5)  # sign = 1 - 2 (fl - 2 floor(fl / 2)): +1 on even tiles, -1 on odd
            np.floor(sign, out=sign)
            sign *= 2.0
            np.subtract(fl, sign, out=sign)
            sign *= 2.0
            np.subtract(1.0, sign, out=sign)
            sign *= x
            return sign  # the box-filtered square wave

        checker = square(self._offx, cx, self._ax)
        checker *= square(self._offz, cz, self._az)
        rgb = checker[..., None] * self._floor_amp
        rgb += self._floor_base
        img = Image.fromarray(rgb.astype(np.uint8), "RGB")
        # NEAREST: the checker is already box-filtered, and BILINEAR costs 2 ms a frame
        return img.resize((self.W, self.H - self.row0), Image.NEAREST)

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
        """Frame ``t`` as an RGB image (``t`` is clipped to the motion's frames)."""
        t = int(min(max(t, 0), self.scene.num_frames - 1))
        frame = self._bg_image.copy()
        if self.has_floor:
            frame.paste(self._floor(t), (0, self.row0))
        pos = self.scene.positions[t]
        self._shadow(frame, t, pos)
        if self.figure == "body" and len(self.scene.bones):
            self._body(frame, t, pos)
        else:
            self._figure(frame, t, pos)
        return frame

    def _shadow(self, frame: Image.Image, t: int, pos: np.ndarray) -> None:
        """Bones projected straight down, drawn at quarter resolution and upsampled (soft edges)."""
        if not self.has_floor or len(self.scene.bones) == 0:
            return
        ground = pos.copy()
        ground[:, 1] = 0.0
        uv, z = self.project(t, ground)
        if np.any(z <= 1e-3):
            return
        q = 4
        pad = 40
        x0, y0 = np.floor(uv.min(axis=0)).astype(int) - pad
        x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + pad
        x0, y0 = max(x0, 0), max(y0, self.row0)
        x1, y1 = min(x1, self.W), min(y1, self.H)
        if x1 - x0 < q or y1 - y0 < q:
            return
        size = ((x1 - x0 + q - 1) // q, (y1 - y0 + q - 1) // q)
        mask = Image.new("L", size, 0)
        draw = ImageDraw.Draw(mask)
        loc = [tuple(v) for v in ((uv - [x0, y0]) / q).tolist()]  # plain floats: numpy scalars are slow here
        width = max(1, int(round(2.6 * _BONE_RADIUS * self.k * self.f / float(np.median(z)) / q)))
        for c, p in zip(self._bc_all, self._bp_all):
            draw.line([loc[c], loc[p]], fill=110, width=width)
        r = 0.5 * width
        for x, y in loc:
            draw.ellipse([x - r, y - r, x + r, y + r], fill=110)
        mask = mask.filter(ImageFilter.GaussianBlur(1.2))
        mask = mask.resize((size[0] * q, size[1] * q), Image.BILINEAR).crop((0, 0, x1 - x0, y1 - y0))
        frame.paste(_SHADOW, (x0, y0, x1, y1), mask)

    def _figure(self, frame: Image.Image, t: int, pos: np.ndarray) -> None:
        """Bones (far to near) and joints drawn at ``_SS`` x resolution on a crop, then reduced."""
        sc = self.scene
        uv, z = self.project(t, pos)
        zr = float(np.median(z))
        rb = _BONE_RADIUS * self.k * self.f / z  # pixel radii per joint
        rj = _JOINT_RADIUS * self.k * self.f / z
        rh = _HEAD_RADIUS * self.k * self.f / z
        reach = float(max(rj.max(), rh.max() if sc.head is not None else 0.0)) + 3
        region = self._figure_region(frame, uv, reach)
        if region is None:
            return
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
        for i in order:
            if i < nb:
                c, p = bc[i], bp[i]
                lv = level[i]
                draw.line([pts[c], pts[p]], fill=self._bone_pal[i][lv], width=widths[i])
                draw.ellipse(boxes[c], fill=self._joint_pal[c][lv])
                draw.ellipse(boxes[p], fill=self._joint_pal[p][lv])
            elif sc.head is not None:
                j = sc.head
                r = rh[j] * _SS
                draw.ellipse(
                    [loc[j, 0] - r, loc[j, 1] - r, loc[j, 0] + r, loc[j, 1] + r],
                    fill=_HEAD_PAL[level[i]],
                    outline=_HEAD_EDGE_PAL[level[i]],
                    width=max(1, int(round(0.12 * r))),
                )
        if not len(sc.bones):
            for j in range(len(pos)):
                r = rj[j] * _SS
                draw.ellipse([loc[j, 0] - r, loc[j, 1] - r, loc[j, 0] + r, loc[j, 1] + r], fill=_BONE[0])
        frame.paste(crop.reduce(_SS), (x0, y0))

    def _figure_region(self, frame: Image.Image, uv: np.ndarray,
                       reach: float) -> tuple[Image.Image, int, int] | None:
        """The part of ``frame`` around the projected joints ``uv`` (J, 2) plus ``reach`` pixels, clipped to the
        frame and upscaled ``_SS`` times for supersampled drawing, with its top-left corner ``(x0, y0)``;
        None when less than 2 pixels of it are on screen."""
        x0 = int(max(math.floor(uv[:, 0].min() - reach), 0))
        y0 = int(max(math.floor(uv[:, 1].min() - reach), 0))
        x1 = int(min(math.ceil(uv[:, 0].max() + reach), self.W))
        y1 = int(min(math.ceil(uv[:, 1].max() + reach), self.H))
        if x1 - x0 < 2 or y1 - y0 < 2:
            return None
        crop = frame.crop((x0, y0, x1, y1)).resize(((x1 - x0) * _SS, (y1 - y0) * _SS), Image.NEAREST)
        return crop, x0, y0

    def _body(self, frame: Image.Image, t: int, pos: np.ndarray) -> None:
        """The mannequin: shaded capsules, a rounded torso outline and a head, far to near, supersampled.

        The per-item work is on plain Python floats (numpy scalars cost more than the drawing).
        """
        sc = self.scene
        uv, z = self.project(t, pos)
        zr = float(np.median(z))
        pix = self.f / z  # pixels per metre at each joint
        rh = 1.15 * _HEAD_RADIUS * self.k * pix
        reach = float(max((_LIMB_RADIUS[1] * self.k * pix).max(), rh.max() if sc.head is not None else 0.0)) + 3
        region = self._figure_region(frame, uv, reach)
        if region is None:
            return
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
        line, ellipse = draw.line, draw.ellipse
        if _INKS is not None:  # Pillow's drawing core with precomputed inks: the same pixels, less overhead
            seg, disc = draw.draw.draw_lines, draw.draw.draw_ellipse
            dark, pal, light = _INKS
        else:
            def seg(xy, fill, width):
                line(xy, fill=fill, width=width)

            def disc(box, fill, _):
                ellipse(box, fill=fill)

            dark, pal, light = _BODY_DARK, _BODY_PAL, _BODY_LIGHT

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
                ring = [tuple(q) for q in hull] + [tuple(hull[0]), tuple(hull[1 % len(hull)])]
                for fill, grow in ((_BODY_DARK[0][lv], 1.0), (_BODY_PAL[0][lv], 0.82)):
                    # the outline as one wide line with round joints: the hull grown by r, rounded
                    line(ring, fill=fill, width=max(1, int(round(2 * grow * r))), joint="curve")
                    draw.polygon(ring[:-2], fill=fill)
            else:  # the head
                r = float(rh[i]) * _SS
                qx, qy = loc[i]
                ellipse([qx - r, qy - r, qx + r, qy + r], fill=_BODY_DARK[0][lv])
                r2 = 0.86 * r
                ellipse([qx - r2, qy - r2, qx + r2, qy + r2], fill=_BODY_PAL[0][lv])
                r3, o = 0.35 * r, 0.3 * r
                ellipse([qx - o - r3, qy - o - r3, qx - o + r3, qy - o + r3], fill=_BODY_LIGHT[0][lv])
        frame.paste(crop.reduce(_SS), (x0, y0))


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
    renderer = FrameRenderer(
        scene, width=width, height=height, azimuth=options.azimuth, elevation=options.elevation,
        figure=options.figure,
    )
    rate = Fraction(scene.fps).limit_denominator(1001)

    cmd = [
        ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "error", "-y",
        "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", f"{rate.numerator}/{rate.denominator}",
        "-i", "pipe:0",
    ]  # fmt: skip
    if span is not None:
        cmd += ["-ss", f"{span.start:.6f}", "-t", f"{span.duration:.6f}", "-i", str(span.path)]
        cmd += ["-map", "0:v:0", "-map", "1:a:0", "-c:a", "aac", "-b:a", "160k"]
    cmd += [
        "-c:v", "libx264", "-preset", "ultrafast", "-tune", "animation", "-crf", str(options.crf),
        "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4",
    ]  # fmt: skip

    frames = range(n_frames)
    if progress:
        from tqdm import tqdm

        frames = tqdm(frames, desc=f"render {os.path.basename(os.fspath(path))}", unit="frame", leave=False)
    with atomic_path(path) as tmp, tempfile.TemporaryFile() as err:
        # Popen rather than run: the frames stream to ffmpeg's stdin while they are drawn.
        try:
            proc = subprocess.Popen(  # own process group: a terminal's Ctrl-C reaches dancekit, which stops it
                [*cmd, str(tmp)], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=err, process_group=0
            )
        except OSError as exc:
            raise ExternalToolError(f"cannot start ffmpeg ({cmd[0]}): {exc}") from exc
        try:
            try:
                for t in frames:
                    proc.stdin.write(renderer.render(t).tobytes())
                proc.stdin.close()
            except BrokenPipeError:
                pass  # ffmpeg died; its message is read below
            rc = proc.wait()
        except BaseException:
            proc.kill()
            proc.wait()
            raise
        if rc != 0:
            err.seek(0)
            raise ExternalToolError(f"ffmpeg failed writing {path} (exit {rc}): {last_line(err.read())}")


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
