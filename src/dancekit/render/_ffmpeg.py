"""The bundled ffmpeg (``imageio_ffmpeg``): probing a song, cutting the dance's slice of it.

Every call goes through ``subprocess.run([...], check=True)``; a failure becomes an
:class:`~dancekit.errors.AudioError` (the song is unreadable) or an
:class:`~dancekit.errors.ExternalToolError` (ffmpeg itself failed) whose message ends
with ffmpeg's last stderr line.
"""

from __future__ import annotations

import functools
import math
import os
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from dancekit.errors import AudioError, ExternalToolError, ParameterError

_DURATION = re.compile(r"Duration:\s*(\d+):(\d\d):(\d\d(?:\.\d+)?)")
_TIME = re.compile(r"time=\s*(\d+):(\d\d):(\d\d(?:\.\d+)?)")


def ffmpeg_exe() -> str:
    """Path of the ffmpeg executable bundled with ``imageio_ffmpeg``."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:  # no bundled binary for this platform
        raise ExternalToolError(f"ffmpeg is not available: {exc}") from exc


def last_line(stderr: bytes | str | None) -> str:
    """The last non-empty line of a program's stderr (``"no message"`` when empty)."""
    if isinstance(stderr, bytes):
        stderr = stderr.decode("utf-8", "replace")
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    return lines[-1] if lines else "no message"


def _hms(match: re.Match) -> float:
    h, m, s = match.groups()
    return int(h) * 3600 + int(m) * 60 + float(s)


def audio_duration(path: str | os.PathLike) -> float:
    """Duration in seconds of the first audio stream of ``path``.

    Read from the container header; when the header has none, the stream is decoded. Remembered per file
    version (path, inode, size and change times) for the process: rendering a song asks twice (the command
    line's check, then the slice), and each ask is an ffmpeg run.

    Raises
    ------
    AudioError
        If the file is missing, unreadable or has no audio stream.
    """
    path = Path(path)
    if not path.is_file():
        raise AudioError(f"audio file not found: {path}")
    try:
        st = path.stat()
    except OSError as exc:
        raise AudioError(f"cannot read audio file {path}: {exc}") from exc
    return _probed_duration(path, path.resolve(), (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns))


@functools.lru_cache(maxsize=64)
def _probed_duration(path: Path, resolved: Path, version: tuple) -> float:
    """:func:`audio_duration` of one version of a file (``resolved`` and ``version`` only key the cache; messages
    name ``path``)."""
    cmd = [
        ffmpeg_exe(),
        "-hide_banner",
        "-nostdin",
        "-i",
        str(path),
        "-map",
        "0:a:0",
        "-t",
        "0",
        "-f",
        "null",
        "-",
    ]
    try:
        r = subprocess.run(cmd, capture_output=True, check=True)
    except subprocess.CalledProcessError as exc:
        raise AudioError(f"cannot read audio file {path}: {last_line(exc.stderr)}") from exc
    text = r.stderr.decode("utf-8", "replace")
    m = _DURATION.search(text)
    if m is not None:
        return _hms(m)
    # no duration in the header (e.g. a raw stream): decode it all
    cmd = [ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", str(path), "-map", "0:a:0", "-f", "null", "-"]
    try:
        r = subprocess.run(cmd, capture_output=True, check=True)
    except subprocess.CalledProcessError as exc:
        raise AudioError(f"cannot decode audio file {path}: {last_line(exc.stderr)}") from exc
    times = _TIME.findall(r.stderr.decode("utf-8", "replace"))
    if not times:
        raise AudioError(f"cannot find the duration of audio file {path}")
    h, m_, s = times[-1]
    return int(h) * 3600 + int(m_) * 60 + float(s)


@dataclass(frozen=True)
class AudioSpan:
    """The part of a song that plays with the dance: ``start`` and ``duration`` in seconds."""

    path: Path
    start: float
    duration: float


def audio_span(
    audio_path: str | os.PathLike,
    *,
    start: float | None,
    end: float | None,
    motion_duration: float,
) -> AudioSpan:
    """Resolve the song slice that accompanies a dance.

    ``start`` defaults to 0 s; ``end`` defaults to ``start + motion_duration``; both are
    clipped to the song's length. Frame ``i`` of the dance plays at ``start + i / fps``.

    Raises
    ------
    AudioError
        If the song is missing or unreadable.
    ParameterError
        If ``start`` / ``end`` are negative, not finite, or leave an empty slice.
    """
    song = audio_duration(audio_path)
    s = 0.0 if start is None else float(start)
    if not math.isfinite(s) or s < 0:
        raise ParameterError(f"audio start must be a finite time >= 0 s, got {start!r}")
    if s >= song:
        raise ParameterError(f"audio start {s:.3f} s is past the end of {audio_path} ({song:.3f} s)")
    e = s + motion_duration if end is None else float(end)
    if not math.isfinite(e) or e <= s:
        raise ParameterError(f"audio end must be a finite time after the start ({s:.3f} s), got {end!r}")
    e = min(e, song)
    return AudioSpan(Path(audio_path), s, e - s)


def encode_audio_slice(span: AudioSpan, *, bitrate: str = "128k") -> tuple[bytes, str]:
    """Cut ``span`` out of its song and encode it as MP3 (every browser plays it).

    Returns
    -------
    data : bytes
        The MP3 bytes, with a LAME header giving the encoder delay, so the decoded
        audio starts exactly at ``span.start``.
    mime : str
        ``"audio/mpeg"``, for a ``data:`` URI.

    Raises
    ------
    ExternalToolError
        If ffmpeg fails (its last stderr line is in the message).
    """
    args, mime = ["-c:a", "libmp3lame", "-f", "mp3"], "audio/mpeg"
    # Encode to a seekable scratch file, not a pipe: only then can ffmpeg go back and write
    # the LAME/Xing header that tells decoders to drop the encoder's priming samples
    # (1105 samples, 50 ms at 22.05 kHz, by which the dance would otherwise lead the music).
    with tempfile.TemporaryDirectory(prefix="dancekit-audio-") as scratch:
        out = Path(scratch) / "slice.mp3"
        cmd = [
            ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-y",
            "-ss", f"{span.start:.6f}", "-t", f"{span.duration:.6f}", "-i", str(span.path),
            "-vn", "-map", "0:a:0", "-b:a", bitrate, *args, str(out),
        ]  # fmt: skip
        try:
            subprocess.run(cmd, capture_output=True, check=True)
        except subprocess.CalledProcessError as exc:
            raise ExternalToolError(
                f"ffmpeg could not encode the audio of {span.path}: {last_line(exc.stderr)}"
            ) from exc
        data = out.read_bytes() if out.is_file() else b""
    if not data:
        raise ExternalToolError(f"ffmpeg produced no audio for {span.path}")
    return data, mime
