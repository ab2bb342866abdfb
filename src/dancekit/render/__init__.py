"""dancekit.render: a dance (and its song) to an mp4 video or a self-contained html player.

``render_mp4`` / ``render_html`` take plain arrays (positions ``(T, J, 3)``, parents, fps,
up axis, units); ``render_motion_mp4`` / ``render_motion_html`` take a
:class:`dancekit.motion.Motion`.
"""

from dancekit.render.html import render_html, render_motion_html
from dancekit.render.video import render_motion_mp4, render_mp4

__all__ = ["render_html", "render_motion_html", "render_motion_mp4", "render_mp4"]
