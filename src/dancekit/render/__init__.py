"""dancekit.render: a dance (and its song) to an mp4 video or a self-contained html player.

``render_mp4`` / ``render_html`` take plain arrays (positions ``(T, J, 3)``, parents, fps,
up axis, units); ``render_motion_mp4`` / ``render_motion_html`` take a
:class:`dancekit.motion.Motion`. All four take ``audio=AudioClip(path, start, end)`` (the
song slice that plays with the dance) and ``options=RenderOptions(...)`` (size, camera,
quality, title), both validated when they are made. To write a dance to every format at
once, see :func:`dancekit.export.export_motion`.
"""

from __future__ import annotations

import importlib
from typing import Any

from dancekit.render.options import AudioClip, RenderOptions

# the renderers import PIL: loaded on first use, so that a dance written as npz or bvh
# (and ``dancekit dance``'s start-up) does not pay for them
_LAZY = {
    "audio_duration": "dancekit.render._ffmpeg",
    "render_html": "dancekit.render.html",
    "render_motion_html": "dancekit.render.html",
    "render_mp4": "dancekit.render.video",
    "render_motion_mp4": "dancekit.render.video",
}

__all__ = [
    "AudioClip",
    "RenderOptions",
    "audio_duration",
    "render_html",
    "render_motion_html",
    "render_motion_mp4",
    "render_mp4",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dancekit.render' has no attribute {name!r}")
