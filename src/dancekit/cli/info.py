"""``dancekit info FILE``: what a motion, audio, video or MIDI file holds."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dancekit.errors import DancekitError

AUDIO_SUFFIXES = {".wav", ".mp3", ".ogg", ".flac", ".m4a", ".aac", ".opus", ".aiff", ".aif", ".wma"}
#: Video containers: ``info`` reports their video stream and their (first) audio track.
VIDEO_SUFFIXES = {".mp4", ".mkv", ".mov", ".webm", ".avi", ".m4v"}
#: MIDI files (``dancekit compose`` writes one).
MIDI_SUFFIXES = {".mid", ".midi"}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="show what a motion, audio, video or MIDI file holds",
        description="Print frames, fps, joints and duration of a motion (npz, bvh, glb, AIST++ pkl, tang2018 "
        "folder, OpenPose folder); duration, sample rate and channels of an audio file; the video and audio "
        "streams of a video (mp4, ...); tempo, tracks and notes of a MIDI file.",
    )
    p.add_argument("path", help="motion file/folder, audio, video or MIDI file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=run)


def audio_info(path: Path) -> dict:
    """Format, duration, sample rate and channels of an audio file, and the video stream of a video file
    (:func:`dancekit.audio.io.probe`: headers only, no library noise on stderr)."""
    from dancekit.audio.io import probe

    p = probe(path)
    a, v = p["audio"], p["video"]
    info = {"kind": "video" if v is not None else "audio", "format": p["format"], "duration_s": p["duration_s"],
            "sample_rate": a["sample_rate"] if a else None, "channels": a["channels"] if a else 0}
    if v is not None:
        info["video"] = v
    return info


def midi_info(path: Path) -> dict:
    """Duration, tempo, tracks and notes of a MIDI file (pretty_midi)."""
    import pretty_midi

    try:
        pm = pretty_midi.PrettyMIDI(str(path))
    except Exception as exc:  # mido / pretty_midi raise several kinds (OSError, EOFError, KeyError, ...)
        raise DancekitError(f"cannot read MIDI file {str(path)!r}: {exc}") from None
    _, tempi = pm.get_tempo_changes()
    return {"kind": "midi", "format": "MIDI", "duration_s": float(pm.get_end_time()),
            "tempo_bpm": float(tempi[0]) if len(tempi) else None,
            "tracks": [{"name": i.name, "drums": bool(i.is_drum), "notes": len(i.notes)} for i in pm.instruments]}


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
    if not (path.is_file() or path.is_dir()):  # reading a named pipe would wait for a writer forever
        from dancekit.audio.io import special_file_kind

        raise DancekitError(f"expected a file or a folder but got {special_file_kind(path)}: {path}")
    suffix = path.suffix.lower()
    if suffix in MIDI_SUFFIXES:
        info = midi_info(path)
    elif suffix in AUDIO_SUFFIXES | VIDEO_SUFFIXES:
        info = audio_info(path)
    else:
        info = motion_info(path)
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{path}")
    if info["kind"] == "midi":
        tempo = f", {info['tempo_bpm']:.1f} BPM" if info["tempo_bpm"] else ""
        print(f"  midi      {info['duration_s']:.2f} s{tempo}")
        for t in info["tracks"]:
            print(f"  track     {t['name'] or '(unnamed)'}{' (drums)' if t['drums'] else ''}: {t['notes']} notes")
        return 0
    if info["kind"] in ("audio", "video"):
        duration = "unknown length" if info["duration_s"] is None else f"{info['duration_s']:.2f} s"
        if "video" in info:
            v = info["video"]
            fps = f", {v['fps']:g} fps" if v["fps"] else ""
            print(f"  video     {info['format']}, {duration}, {v['codec']} {v['width']}x{v['height']}{fps}")
        if info["channels"]:
            print(f"  audio     {info['format']}, {duration}, {info['sample_rate']} Hz, "
                  f"{info['channels']} channel{'s' if info['channels'] != 1 else ''}")
        elif "video" in info:
            print("  audio     none")
        return 0
    print(f"  motion    {info['format']}, skeleton {info['skeleton']} ({info['joints']} joints, {info['dims']}D, "
          f"{info['units']}, {info['up_axis']} up)")
    print(f"  frames    {info['frames']} at {info['fps']:g} fps = {info['duration_s']:.2f} s")
    print(f"  stored    {', '.join(info['stored'])}; {info['roles']} roles")
    if "audio" in info:
        a = info["audio"]
        print(f"  audio     {a['path']} from {a['start_s']:.2f} s to {a['end_s']:.2f} s")
    return 0
