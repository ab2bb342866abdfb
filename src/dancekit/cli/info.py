"""``dancekit info FILE``: what a motion file or an audio file holds."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dancekit.errors import AudioError, DancekitError

AUDIO_SUFFIXES = {".wav", ".mp3", ".ogg", ".flac", ".m4a", ".aac", ".opus", ".aiff", ".aif", ".wma"}
#: Video containers: ``info`` reports their (first) audio track, the song ``dancekit dance`` would dance.
VIDEO_SUFFIXES = {".mp4", ".mkv", ".mov", ".webm", ".avi", ".m4v"}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="show what a motion or audio file holds",
        description="Print frames, fps, joints and duration of a motion (npz, bvh, AIST++ pkl, tang2018 "
        "folder, OpenPose folder), or duration, sample rate and channels of an audio file.",
    )
    p.add_argument("path", help="motion file/folder or audio file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=run)


def audio_info(path: Path) -> dict:
    """Duration, sample rate and channels of an audio file (soundfile, else dancekit.audio.load)."""
    import soundfile as sf

    try:
        i = sf.info(str(path))
        return {"kind": "audio", "format": i.format, "duration_s": float(i.duration),
                "sample_rate": int(i.samplerate), "channels": int(i.channels)}
    except (RuntimeError, sf.LibsndfileError):
        pass
    try:
        from dancekit.audio import load
    except ImportError as exc:  # audio layer not available
        raise AudioError(f"cannot read audio file {path}: {exc}") from exc
    y, sr = load(path, mono=False)
    channels = 1 if y.ndim == 1 else int(min(y.shape))
    n = y.shape[-1] if y.ndim > 1 and y.shape[0] == channels else y.shape[0]
    return {"kind": "audio", "format": path.suffix.lstrip(".").upper(), "duration_s": n / sr,
            "sample_rate": int(sr), "channels": channels}


def motion_info(path: Path) -> dict:
    """Format, skeleton, joints, frames, fps and duration of a motion file or folder."""
    from dancekit.motion.formats import detect_format, read_motion, read_tang2018

    fmt = detect_format(path)
    extra = {}
    if fmt == "tang2018":
        motion, audio = read_tang2018(path)
        extra["audio"] = {"path": str(audio.path), "start_s": round(audio.start, 3), "end_s": round(audio.end, 3)}
    else:
        motion = read_motion(path)
    sk = motion.skeleton
    stored = [k for k in ("positions", "rotations", "root_translation") if getattr(motion, k) is not None]
    return {
        "kind": "motion", "format": fmt, "skeleton": sk.name, "joints": sk.num_joints, "dims": sk.dims,
        "units": sk.units, "up_axis": sk.up_axis, "frames": motion.num_frames, "fps": motion.fps,
        "duration_s": motion.duration, "stored": stored, "roles": len(sk.roles), **extra,
    }


def run(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if not path.exists():
        raise DancekitError(f"no such file or folder: {path}")
    suffix = path.suffix.lower()
    info = audio_info(path) if suffix in AUDIO_SUFFIXES | VIDEO_SUFFIXES else motion_info(path)
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{path}")
    if info["kind"] == "audio":
        print(f"  audio     {info['format']}, {info['duration_s']:.2f} s, {info['sample_rate']} Hz, "
              f"{info['channels']} channel{'s' if info['channels'] != 1 else ''}")
        return 0
    print(f"  motion    {info['format']}, skeleton {info['skeleton']} ({info['joints']} joints, {info['dims']}D, "
          f"{info['units']}, {info['up_axis']} up)")
    print(f"  frames    {info['frames']} at {info['fps']:g} fps = {info['duration_s']:.2f} s")
    print(f"  stored    {', '.join(info['stored'])}; {info['roles']} roles")
    if "audio" in info:
        a = info["audio"]
        print(f"  audio     {a['path']} from {a['start_s']:.2f} s to {a['end_s']:.2f} s")
    return 0
