"""The volumetric "body" figure of the mp4 renderer: a mannequin that covers a body's area, as an option."""

from __future__ import annotations

import numpy as np
import pytest

from dancekit.errors import ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.render import RenderOptions, render_motion_mp4
from dancekit.render._motion import motion_arrays
from dancekit.render._scene import prepare_scene
from dancekit.render.video import FrameRenderer, _convex_hull


def rest_motion(name: str = "tang2018", frames: int = 6) -> Motion:
    sk = get_skeleton(name)
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    pos = np.repeat(rest[None], frames, axis=0)
    return Motion(sk, 25.0, positions=pos.astype(np.float32))


def figure_pixels(motion: Motion, figure: str) -> tuple[int, FrameRenderer]:
    a = motion_arrays(motion)
    a.pop("fps")
    scene = prepare_scene(a.pop("positions"), fps=motion.fps, **a)
    r = FrameRenderer(scene, width=160, height=120, azimuth=0.0, figure=figure)
    img = np.asarray(r.render(0), dtype=np.int16)
    bg = np.asarray(r._bg_image, dtype=np.int16)
    floor = r._floor(0)
    bg[r.row0:] = np.asarray(floor, dtype=np.int16)
    changed = np.abs(img - bg).sum(axis=-1) > 30
    return int(changed.sum()), r


@pytest.mark.parametrize("name", ["tang2018", "smpl"])
def test_body_covers_more_than_the_stick_figure(name):
    stick, _ = figure_pixels(rest_motion(name), "stick")
    body, r = figure_pixels(rest_motion(name), "body")
    print(f"{name}: figure pixels stick {stick}, body {body}; torso joints {len(r._torso)}")
    assert body > 1.25 * stick  # volumetric limbs and a torso (both images also hold the shadow)
    assert len(r._torso) >= 4  # hips and shoulders at least


def test_convex_hull_known_answer():
    pts = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 1], [1, 0]], float)
    hull = _convex_hull(pts)
    assert sorted(map(tuple, hull)) == [(0, 0), (0, 2), (2, 0), (2, 2)]


def test_body_mp4_renders(tmp_path):
    out = tmp_path / "b.mp4"
    render_motion_mp4(out, rest_motion(), options=RenderOptions(width=64, height=48, figure="body"), progress=False)
    assert out.stat().st_size > 0


def test_figure_option_is_checked():
    with pytest.raises(ParameterError, match="figure"):
        RenderOptions(figure="mesh")
