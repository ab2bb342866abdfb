"""dancekit.export: one dance to every output format at once, all or nothing.

:func:`export_motion` writes a :class:`~dancekit.motion.Motion` as an mp4 with its song, a
self-contained html player, the npz motion file, a BVH (exact or humanoid rig), a glTF binary
with a skinned body, an AIST++ SMPL pkl and OpenPose / COCO keypoint JSON, through a staging
folder: an error or Ctrl-C half-way leaves the output folder as it was.

This module imports the renderers and the motion writers only when it writes, so importing
it (for :data:`FORMATS`) is cheap.
"""

from dancekit.export.writer import DEFAULT_FORMATS, FORMATS, check_formats, check_output_folder, export_motion

__all__ = ["DEFAULT_FORMATS", "FORMATS", "check_formats", "check_output_folder", "export_motion"]
