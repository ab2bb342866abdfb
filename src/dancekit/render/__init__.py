"""dancekit.render: a dance (and its song) to an mp4 video or a self-contained html player.

``render_mp4`` / ``render_html`` take plain arrays (positions ``(T, J, 3)``, parents, fps,
up axis, units); ``render_motion_mp4`` / ``render_motion_html`` take a
:class:`dancekit.motion.Motion`. All four take ``audio=AudioClip(path, start, end)`` (the
song slice that plays with the dance) and ``options=RenderOptions(...)`` (size, camera,
quality, title), both validated when they are made. To write a dance to every format at
once, see :func:`dancekit.export.export_motion`.
"""

from dancekit.render.html import render_html, render_motion_html
from dancekit.render.options import AudioClip, RenderOptions
from dancekit.render.video import render_motion_mp4, render_mp4

__all__ = [
    "AudioClip",
    "RenderOptions",
    "render_html",
    "render_motion_html",
    "render_motion_mp4",
    "render_mp4",
]
