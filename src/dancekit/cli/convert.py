"""``dancekit convert IN -o OUT``: any motion file the toolkit reads to another format.

IN is anything :func:`dancekit.motion.formats.read_motion` reads (npz, BVH, AIST++ pkl, OpenPose
folder, tang2018 dance folder). OUT's suffix picks the format (:func:`~dancekit.motion.formats.write_motion`):
``.npz``, ``.bvh``, ``.glb``, ``.pkl`` (AIST++ SMPL) or a suffix-less folder (keypoint JSON, one file per
frame). OUT is the path written: ``-o a.json`` is refused (keypoints are a folder of files), not turned into
a folder ``a/``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from dancekit.cli._options import output_fps
from dancekit.errors import ParameterError

_SUFFIXES = (".npz", ".bvh", ".glb", ".pkl", "")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "convert",
        help="convert a motion file: npz, bvh, glb, pkl (AIST++ SMPL), json keypoints",
        description="Read any motion file or folder the toolkit reads and write it in the format of OUT's "
        "suffix: .npz, .bvh, .glb (glTF with a skinned body), .pkl (AIST++ SMPL), or a folder without a "
        "suffix (keypoint JSON, one file per frame).",
    )
    p.add_argument("motion", metavar="IN",
                   help="motion file or folder (npz, bvh, glb, pkl, OpenPose or tang2018 folder)")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output .npz, .bvh, .glb, .pkl, or a folder (keypoint JSON files)")
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate first (slerp; at most 240)")
    p.add_argument("--bvh-rig", choices=("exact", "humanoid"), default="exact",
                   help="BVH rig: the skeleton's own joints (default) or a standard humanoid (Mixamo-like names)")
    p.add_argument("--keypoints", choices=("body25", "coco17", "coco18"), default="body25",
                   help="keypoint layout of .json output (default body25, OpenPose)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    args.fps = output_fps(args.fps)
    if out.suffix.lower() == ".json":
        raise ParameterError(f"keypoint JSON is one file per frame: give a folder without a suffix (e.g. "
                             f"{str(out.with_suffix(''))!r}), got {str(out)!r}")
    if out.suffix.lower() not in _SUFFIXES:
        raise ParameterError(f"output must end in .npz, .bvh, .glb or .pkl (or be a folder), got {str(out)!r}")
    if out.is_dir() and out.suffix:
        raise ParameterError(f"output {str(out)!r} is a folder; give a file name")
    if str(out.parent) and not out.parent.is_dir():
        raise ParameterError(f"output folder does not exist: {out.parent}")

    from dancekit.motion.formats import read_motion, write_motion

    motion = read_motion(args.motion)
    if args.fps is not None:
        motion = motion.resample(args.fps)
    target = out
    kwargs = {}
    if target.suffix.lower() == ".bvh":
        kwargs["rig"] = args.bvh_rig
    elif target.suffix == "":
        kwargs["keypoints"] = args.keypoints
    write_motion(target, motion, **kwargs)
    if not args.quiet:
        print(f"{args.motion} → {target} ({motion.num_frames} frames at {motion.fps:g} fps)")
    return 0
