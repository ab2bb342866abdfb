"""Reading, validating, resampling and writing audio.

All audio inside dancekit is a float32 NumPy array: ``(n,)`` for mono, or
``(channels, n)`` when ``mono=False`` (the librosa convention), with its
sample rate ``sr`` in Hz carried beside it.

Decoding goes through libsndfile (``soundfile``: wav, flac, ogg/vorbis,
ogg/opus, mp3, aiff, ...) and falls back to the ffmpeg binary bundled with
the ``imageio-ffmpeg`` wheel for everything else (m4a/aac, wma, video
containers, ...). :func:`validate_audio` is the one place decoded samples are
checked.
"""

from __future__ import annotations

import contextlib
import os
import re
import struct
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import soundfile as sf

from dancekit._io import atomic_path
from dancekit.errors import AudioError, ExternalToolError, ParameterError

__all__ = ["MIN_DURATION", "check_audio_path", "load", "resample", "save_wav", "stream", "validate_audio"]

#: Shortest audio accepted by :func:`validate_audio`, in seconds.
MIN_DURATION = 1.0

# frames read (or written) per block, so long files never need a second full-size copy
_BLOCK = 1 << 18


def _describe(path: str | os.PathLike | None) -> str:
    return f"audio file {str(path)!r}" if path is not None else "audio"


def special_file_kind(path: str | os.PathLike) -> str:
    """What a path that exists but is neither a regular file nor a folder is, in words ("a named pipe (FIFO)")."""
    import stat

    mode = os.stat(path).st_mode
    for test, what in ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device")):
        if test(mode):
            return what
    return "a special file"


def check_audio_path(path: str | os.PathLike) -> None:
    """Raise :class:`AudioError` (naming the file) if ``path`` is missing, a folder, unreadable or 0 bytes."""
    path = Path(path)
    if not path.exists():
        raise AudioError(f"audio file not found: {str(path)!r}")
    if path.is_dir():
        raise AudioError(f"expected an audio file but got a folder: {str(path)!r}")
    if not path.is_file():  # a named pipe, socket or device: reading it could block, and it cannot be seeked
        raise AudioError(f"expected an audio file but got {special_file_kind(path)}: {str(path)!r}")
    if not os.access(path, os.R_OK):
        raise AudioError(f"audio file is not readable (permissions): {str(path)!r}")
    if path.stat().st_size == 0:
        raise AudioError(f"audio file is empty (0 bytes): {str(path)!r}")


def validate_audio(y: np.ndarray, *, sr: int, path: str | os.PathLike | None = None) -> None:
    """Check decoded samples; the one place audio is validated.

    Parameters
    ----------
    y : np.ndarray, shape (n,) or (channels, n)
        Floating-point samples.
    sr : int
        Sample rate in Hz (> 0).
    path : str or PathLike, optional
        File the samples came from; named in every error message.

    Raises
    ------
    ParameterError
        ``sr`` is not a positive integer.
    AudioError
        ``y`` is not a floating-point array of 1 or 2 dimensions, is empty,
        is shorter than :data:`MIN_DURATION` (1 s), or holds NaN/inf.
        Silent (all-zero) audio is valid.
    """
    if isinstance(sr, bool) or not isinstance(sr, int | np.integer) or sr <= 0:
        raise ParameterError(f"sr must be a positive integer sample rate in Hz, got {sr!r}")
    what = _describe(path)
    if not isinstance(y, np.ndarray):
        raise AudioError(f"{what}: samples must be a NumPy array, got {type(y).__name__}")
    if not np.issubdtype(y.dtype, np.floating):
        raise AudioError(f"{what}: samples must be floating point, got dtype {y.dtype}")
    if y.ndim not in (1, 2):
        raise AudioError(f"{what}: samples must have shape (n,) or (channels, n), got {y.shape}")
    n = y.shape[-1]
    if y.size == 0:
        raise AudioError(f"{what} holds no samples (zero-length audio)")
    if n < MIN_DURATION * sr:
        raise AudioError(
            f"{what} is too short: {n / sr:.3f} s ({n} samples at {sr} Hz); need at least {MIN_DURATION:g} s"
        )
    finite = np.isfinite(y)
    if not finite.all():
        bad = int(y.size - np.count_nonzero(finite))
        first = int(np.argmin(finite.reshape(-1, n).all(axis=0)))
        raise AudioError(
            f"{what} holds {bad} non-finite samples (NaN or inf), the first at {first / sr:.3f} s"
        )


def resample(y: np.ndarray, *, orig_sr: int, target_sr: int, stream=None) -> np.ndarray:
    """Resample along the last axis with soxr (high quality); float32 out.

    The same samples as ``librosa.resample(y, orig_sr=..., target_sr=..., res_type="soxr_hq")``: soxr's HQ
    resampler on each channel, cut or zero-padded to ``ceil(n * target_sr / orig_sr)`` samples (soxr is
    called directly: importing librosa costs seconds in a fresh process).
    Returns ``y`` itself (as float32) when the rates are equal.

    ``stream``: a ``soxr.ResampleStream(orig_sr, target_sr, 1, dtype="float32", quality="soxr_hq")`` to use for
    each channel, cleared before each (the same samples, without building a resampler per call: for many short
    calls, as a live feature extractor makes).
    """
    import soxr

    y = np.asarray(y, dtype=np.float32)
    if int(orig_sr) == int(target_sr):
        return y
    n_out = int(np.ceil(y.shape[-1] * (float(target_sr) / int(orig_sr))))
    if y.shape[-1] == 0:  # nothing to resample (e.g. an empty tail chunk)
        return np.zeros(y.shape, dtype=np.float32)
    rows = y.reshape(-1, y.shape[-1])
    out = np.zeros((rows.shape[0], n_out), dtype=np.float32)
    for i, row in enumerate(rows):
        if stream is None:
            r = soxr.resample(row, int(orig_sr), int(target_sr), quality="soxr_hq")
        else:
            stream.clear()
            r = stream.resample_chunk(np.ascontiguousarray(row), last=True)
        out[i, : min(n_out, len(r))] = r[:n_out]
    return out.reshape(y.shape[:-1] + (n_out,))


# ---------------------------------------------------------------------------------------------
# truncation checks (libsndfile silently returns fewer samples for a cut-off wav or ogg)


def _wav_truncated(path: Path) -> bool:
    """True if the RIFF header declares more bytes than the file holds."""
    with open(path, "rb") as f:
        head = f.read(12)
    if len(head) < 12 or head[:4] != b"RIFF" or head[8:12] != b"WAVE":
        return False
    (riff_size,) = struct.unpack("<I", head[4:8])
    if riff_size in (0, 0xFFFFFFFF):  # streamed (size unknown): nothing to compare
        return False
    # 1 byte of slack: some writers omit the pad byte after an odd-sized last chunk
    return riff_size + 8 > path.stat().st_size + 1


def _ogg_truncated(path: Path) -> bool:
    """True if the last Ogg page is incomplete or lacks the end-of-stream flag."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        f.seek(max(0, size - (1 << 16)))
        tail = f.read()
    at = tail.rfind(b"OggS")
    if at < 0:
        return True
    page = tail[at:]
    if len(page) < 27:
        return True
    header_type = page[5]
    n_segments = page[26]
    if len(page) < 27 + n_segments:
        return True
    body = sum(page[27 : 27 + n_segments])
    if len(page) < 27 + n_segments + body:
        return True
    return not header_type & 0x04


_MP3_KBPS = {  # (MPEG-1?, layer) → bitrate (kbit/s) by index 1..14
    (True, 1): (32, 64, 96, 128, 160, 192, 224, 256, 288, 320, 352, 384, 416, 448),
    (True, 2): (32, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320, 384),
    (True, 3): (32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320),
    (False, 1): (32, 48, 56, 64, 80, 96, 112, 128, 144, 160, 176, 192, 224, 256),
    (False, 2): (8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 144, 160),
    (False, 3): (8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 144, 160),
}
_MP3_RATES = {3: (44100, 48000, 32000), 2: (22050, 24000, 16000), 0: (11025, 12000, 8000)}


def _mp3_frame_length(head: bytes) -> int:
    """Bytes of the MPEG audio frame whose 4-byte header is ``head`` (0: not a valid header)."""
    if len(head) < 4 or head[0] != 0xFF or head[1] & 0xE0 != 0xE0:
        return 0
    version, layer_bits = (head[1] >> 3) & 3, (head[1] >> 1) & 3
    bitrate_i, rate_i, pad = head[2] >> 4, (head[2] >> 2) & 3, (head[2] >> 1) & 1
    if version == 1 or layer_bits == 0 or bitrate_i in (0, 15) or rate_i == 3:
        return 0
    layer = 4 - layer_bits
    kbps = _MP3_KBPS[(version == 3, layer)][bitrate_i - 1]
    rate = _MP3_RATES[version][rate_i]
    if layer == 1:
        return (12 * kbps * 1000 // rate + pad) * 4
    per = 144 if (version == 3 or layer == 2) else 72
    return per * kbps * 1000 // rate + pad


def _mp3_truncated(path: Path) -> bool:
    """True if the last MPEG audio frame of an mp3 runs past the end of the file (a cut-off download).

    libsndfile *estimates* an mp3's length (from its Xing header or its bitrate and size: cover art or a
    stale header make it wrong), so decoding fewer frames than declared is no proof of truncation; a frame
    cut in the middle is. Walks the frame headers from the first two consecutive valid ones; when the chain
    is lost (trailing tags, junk) the file is not called truncated."""
    data = path.read_bytes()
    pos = 0
    if data[:3] == b"ID3" and len(data) >= 10:  # ID3v2 tag: syncsafe size, optional footer
        size = (data[6] & 0x7F) << 21 | (data[7] & 0x7F) << 14 | (data[8] & 0x7F) << 7 | (data[9] & 0x7F)
        pos = 10 + size + (10 if data[5] & 0x10 else 0)
    n = len(data)
    while pos + 4 <= n:  # first frame: a valid header followed by another valid header (or the end)
        length = _mp3_frame_length(data[pos:pos + 4])
        if length and (pos + length + 4 > n or _mp3_frame_length(data[pos + length:pos + length + 4])):
            break
        pos = data.find(b"\xff", pos + 1)
        if pos < 0:
            return False
    else:
        return False
    while pos + 4 <= n:
        length = _mp3_frame_length(data[pos:pos + 4])
        if not length:
            return False  # a tag or junk after the frames: the chain ended inside the file
        if pos + length > n:
            return True
        pos += length
    return 0 < n - pos < 4  # a few bytes of a header left


def _check_truncated(path: Path, fmt: str) -> None:
    if (fmt in ("WAV", "WAVEX") and _wav_truncated(path)) or (fmt == "OGG" and _ogg_truncated(path)) \
            or (fmt in ("MP3", "MPEG") and _mp3_truncated(path)):
        raise AudioError(f"audio file is truncated (the file ends before its declared length): {str(path)!r}")


# ---------------------------------------------------------------------------------------------
# decoders


@contextlib.contextmanager
def quiet_c_stderr() -> Iterator[None]:
    """Silence what C libraries write to file descriptor 2 (libsndfile's mpg123 prints "Note: Illegal
    Audio-MPEG-Header ..." for a corrupt mp3 before we raise our own one-line error)."""
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _seek_range(f: sf.SoundFile, path: Path, start: float | None, end: float | None) -> int:
    """Check ``[start, end)`` s against an open SoundFile's length, seek to ``start``; the frames to read."""
    sr, total = f.samplerate, f.frames
    a = 0 if start is None else int(round(start * sr))
    b = total if end is None else min(total, int(round(end * sr)))
    _check_range(path, start, end, total / sr)
    if a > 0:
        f.seek(a)
    return max(0, b - a)


#: Largest Vorbis block (samples): a stream's last granule position may declare up to one block more than
#: its decoder returns (the end trim of an encoder that rounds to blocks); Opus frames are shorter (5760).
OGG_BLOCK_MAX = 8192


def _ogg_block(path: Path) -> int:
    """The long block size (samples) of an Ogg Vorbis stream from its identification header (byte 28 of the
    packet: two 4-bit exponents), or :data:`OGG_BLOCK_MAX` when the header is not Vorbis (Opus) or unreadable."""
    with open(path, "rb") as f:
        head = f.read(1 << 12)
    at = head.find(b"\x01vorbis")
    if at < 0 or len(head) < at + 29:
        return OGG_BLOCK_MAX
    exp = head[at + 28] >> 4
    return 1 << exp if 6 <= exp <= 13 else OGG_BLOCK_MAX


def ogg_rounding(path: Path, shortfall: int) -> bool:
    """Whether ``shortfall`` samples missing at the end of a complete Ogg stream (its last page whole, with
    the end-of-stream flag) are explained by the container's rounding: at most one long block of the stream
    (an encoder or a cut such as ``ffmpeg -t`` sets the last granule position past the decoded end)."""
    return 0 < shortfall <= _ogg_block(path) and not _ogg_truncated(path)


def _check_decoded(f: sf.SoundFile, path: Path, *, got: int, want: int) -> None:
    """Refuse a file that decoded to fewer frames than its header declares (an mp3's length is only an
    estimate: a short mp3 that decoded at all is accepted; an Ogg stream may end up to one block short of
    its last granule position, :func:`ogg_rounding`)."""
    if got < want and f.format == "OGG" and ogg_rounding(path, want - got):
        return
    if got < want and not (f.format in ("MP3", "MPEG") and got > 0):
        raise AudioError(
            f"audio file is truncated or corrupt: {str(path)!r} declares {f.frames} frames but only "
            f"{f.frames - (want - got)} could be decoded"
        )


def _read_soundfile(
    f: sf.SoundFile, path: Path, start: float | None, end: float | None, mono: bool
) -> np.ndarray:
    """Read [start, end) of an open SoundFile in blocks; (n,) if mono else (channels, n)."""
    want = _seek_range(f, path, start, end)
    out = np.empty((want,) if mono else (f.channels, want), dtype=np.float32)  # filled in place: no 2nd copy
    got = 0
    while got < want:
        block = f.read(min(_BLOCK, want - got), dtype="float32", always_2d=True)
        if block.shape[0] == 0:
            break
        k = block.shape[0]
        if mono:
            np.mean(block, axis=1, out=out[got:got + k])
        else:
            out[:, got:got + k] = block.T
        got += k
    _check_decoded(f, path, got=got, want=want)
    return out[..., :got] if got < want else out


def _ffmpeg_exe() -> str:
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except Exception as exc:  # the wheel raises RuntimeError when its binary is missing
        raise ExternalToolError(f"ffmpeg is not available (imageio-ffmpeg): {exc}") from exc


def _read_ffmpeg(path: Path, mono: bool) -> tuple[np.ndarray, int]:
    """Decode a whole file to float32 through ffmpeg; (n,) if mono else (channels, n)."""
    exe = _ffmpeg_exe()
    cmd = [exe, "-nostdin", "-hide_banner", "-v", "info", "-i", str(path), "-vn", "-map", "0:a:0"]
    if mono:
        cmd += ["-ac", "1"]
    cmd += ["-f", "f32le", "-c:a", "pcm_f32le", "pipe:1"]
    try:
        # own process group: a terminal's Ctrl-C interrupts dancekit (which then ends ffmpeg), not ffmpeg first
        proc = subprocess.run(cmd, check=True, capture_output=True, process_group=0)
    except subprocess.CalledProcessError as exc:
        lines = [ln for ln in exc.stderr.decode("utf-8", "replace").splitlines() if ln.strip()]
        reason = lines[-1].strip() if lines else f"ffmpeg exit status {exc.returncode}"
        raise AudioError(
            f"cannot decode audio file {str(path)!r}: not a readable audio file ({reason})"
        ) from None
    except OSError as exc:
        raise ExternalToolError(f"cannot run ffmpeg ({exe}): {exc}") from exc
    err = proc.stderr.decode("utf-8", "replace")
    # the output stream line ("Stream #0:0...: Audio: pcm_f32le, 44100 Hz, stereo, ...") gives rate and layout
    out_part = err.split("Output #0", 1)[-1]
    m = re.search(r"Audio: pcm_f32le[^,]*, (\d+) Hz, ([^,]+),", out_part)
    if m is None:
        raise AudioError(f"cannot decode audio file {str(path)!r}: ffmpeg found no audio stream")
    sr = int(m.group(1))
    layout = m.group(2).strip()
    channels = 1 if mono else _channels_from_layout(layout)
    data = np.frombuffer(proc.stdout, dtype="<f4")
    n = data.size // channels
    y = data[: n * channels].reshape(n, channels).T
    y = y[0] if mono else y
    return np.ascontiguousarray(y, dtype=np.float32), sr


def _channels_from_layout(layout: str) -> int:
    named = {"mono": 1, "stereo": 2, "2.1": 3, "quad": 4, "4.0": 4, "5.0": 5, "5.1": 6, "6.1": 7, "7.1": 8}
    if layout in named:
        return named[layout]
    m = re.match(r"(\d+) channels", layout)
    if m:
        return int(m.group(1))
    base = layout.split("(")[0]
    if base in named:
        return named[base]
    raise AudioError(f"unsupported channel layout {layout!r} reported by ffmpeg")


def _check_range(path: Path, start: float | None, end: float | None, duration: float) -> None:
    if start is not None and not start < duration:
        raise ParameterError(f"start={start:g} s is beyond the end of {str(path)!r} ({duration:.3f} s long)")


def _validate_range(start: float | None, end: float | None) -> None:
    for name, value in (("start", start), ("end", end)):
        if value is not None and (not np.isfinite(value) or value < 0):
            raise ParameterError(f"{name} must be a finite number of seconds >= 0, got {value!r}")
    if start is not None and end is not None and not start < end:
        raise ParameterError(f"start must be before end, got start={start:g} s, end={end:g} s")


def _open_soundfile(path: Path) -> sf.SoundFile | None:
    """``path`` opened by libsndfile (its C library's notes kept off stderr), or None for a format it cannot
    read (decoded by ffmpeg instead)."""
    with quiet_c_stderr():
        try:
            return sf.SoundFile(path)
        except (sf.LibsndfileError, RuntimeError):
            return None


def duration(path: str | os.PathLike) -> float | None:
    """The length of the audio file ``path`` in seconds from its header (libsndfile), or None when libsndfile
    cannot read the format (ffmpeg decodes those) or the file cannot be opened. Reads no samples."""
    f = _open_soundfile(Path(path)) if Path(path).is_file() else None
    if f is None:
        return None
    with f:
        return f.frames / f.samplerate if f.samplerate > 0 else None


def load(
    path: str | os.PathLike,
    *,
    sr: int | None = None,
    mono: bool = True,
    start: float | None = None,
    end: float | None = None,
) -> tuple[np.ndarray, int]:
    """Decode an audio file to float32 samples.

    Parameters
    ----------
    path : str or PathLike
        wav / flac / ogg / mp3 (read through libsndfile, in blocks) or any
        format the bundled ffmpeg decodes (m4a, aac, wma, mp4, ...).
    sr : int, optional
        Target sample rate in Hz; ``None`` keeps the file's own rate.
        Resampling uses soxr (``soxr_hq``).
    mono : bool
        Mix all channels down to one (the mean). With ``False`` the result is
        ``(channels, n)``.
    start, end : float, optional
        Excerpt bounds in seconds from the start of the file. ``start`` must
        lie inside the file and be before ``end``; an ``end`` past the end of
        the file is clipped to it.

    Returns
    -------
    y : np.ndarray, float32, shape (n,) (or (channels, n) if ``mono=False``)
    sr : int
        Sample rate of ``y`` in Hz.

    Raises
    ------
    AudioError
        Missing file, a folder, an unreadable / corrupt / truncated file, or
        audio that fails :func:`validate_audio` (empty, shorter than 1 s,
        non-finite samples). The message names the file.
    ParameterError
        Bad ``sr``, ``start`` or ``end``.

    Examples
    --------
    >>> y, sr = load("song.ogg", sr=22050, start=10.0, end=40.0)  # doctest: +SKIP
    >>> y.shape, sr  # doctest: +SKIP
    ((661500,), 22050)
    """
    path = Path(path)
    if sr is not None and (isinstance(sr, bool) or not isinstance(sr, int | np.integer) or sr <= 0):
        raise ParameterError(f"sr must be a positive integer sample rate in Hz or None, got {sr!r}")
    _validate_range(start, end)
    check_audio_path(path)

    f = _open_soundfile(path)
    with quiet_c_stderr():
        if f is not None:
            with f:
                _check_truncated(path, f.format)
                try:
                    y = _read_soundfile(f, path, start, end, mono)
                except sf.LibsndfileError as exc:
                    raise AudioError(f"cannot decode audio file {str(path)!r}: corrupt data ({exc})") from None
                native_sr = f.samplerate
    if f is None:
        y, native_sr = _read_ffmpeg(path, mono)
        duration = y.shape[-1] / native_sr
        if duration == 0:
            raise AudioError(f"audio file {str(path)!r} holds no samples (zero-length audio)")
        _check_range(path, start, end, duration)
        a = 0 if start is None else int(round(start * native_sr))
        b = y.shape[-1] if end is None else min(y.shape[-1], int(round(end * native_sr)))
        y = np.ascontiguousarray(y[..., a:b])

    if y.shape[-1] == 0:
        raise AudioError(f"audio file {str(path)!r} holds no samples (zero-length audio)")
    validate_audio(y, sr=int(native_sr), path=path)
    if sr is not None and int(sr) != native_sr:
        y = resample(y, orig_sr=native_sr, target_sr=int(sr))
        return y, int(sr)
    return y, int(native_sr)


def stream(
    path: str | os.PathLike,
    *,
    rates: Sequence[int],
    start: float | None = None,
    end: float | None = None,
) -> Iterator[list[np.ndarray]]:
    """Decode an audio file to mono in blocks, resampled on the fly to each of ``rates``: memory is a block,
    not the song.

    Yields one list per decoded block: the block's samples at each of ``rates`` (float32, (n_k,) each; soxr
    ``HQ`` resampling streams, so a block may yield fewer or more samples than its share). Concatenated, the
    samples at rate ``r`` equal ``load(path, sr=r, start=start, end=end)[0]`` exactly (the same blocks are
    read and mixed down, soxr's stream gives the same samples as its one-shot resampler, and the tail is
    zero-padded to ``ceil(n * r / native_sr)`` samples as librosa pads it). The same checks as :func:`load`
    (range, truncation, finite samples, at least :data:`MIN_DURATION` s) raise the same errors, a
    non-finite or too-short song only once its blocks have been read. Formats libsndfile cannot read (m4a,
    aac, ...) are decoded whole by ffmpeg first (one block).

    Raises
    ------
    AudioError, ParameterError
        As :func:`load`.
    """
    import soxr

    path = Path(path)
    rates = [int(r) for r in rates]
    if not rates or any(r <= 0 for r in rates):
        raise ParameterError(f"rates must be positive sample rates in Hz, got {rates!r}")
    _validate_range(start, end)
    check_audio_path(path)
    f = _open_soundfile(path)
    if f is None:
        y, native = load(path, start=start, end=end)
        yield [resample(y, orig_sr=native, target_sr=r) for r in rates]
        return
    with f:
        with quiet_c_stderr():
            _check_truncated(path, f.format)
        native = f.samplerate
        want = _seek_range(f, path, start, end)
        streams = {r: soxr.ResampleStream(native, r, 1, dtype="float32", quality="HQ") for r in rates if r != native}
        counts = dict.fromkeys(rates, 0)
        got, flushed = 0, False
        while got < want:
            try:
                with quiet_c_stderr():
                    raw = f.read(min(_BLOCK, want - got), dtype="float32", always_2d=True)
            except sf.LibsndfileError as exc:
                raise AudioError(f"cannot decode audio file {str(path)!r}: corrupt data ({exc})") from None
            k = raw.shape[0]
            if k == 0:
                break
            block = np.mean(raw, axis=1, dtype=np.float32) if raw.shape[1] > 1 else np.ascontiguousarray(raw[:, 0])
            del raw
            finite = np.isfinite(block)
            if not finite.all():
                bad_here = int(k - np.count_nonzero(finite))
                first = got + int(np.argmin(finite))
                raise AudioError(f"audio file {str(path)!r} holds non-finite samples (NaN or inf; {bad_here} in "
                                 f"one block), the first at {first / native:.3f} s")
            got += k
            flushed = got >= want
            out = [block if r == native else streams[r].resample_chunk(block, last=flushed) for r in rates]
            for r, o in zip(rates, out):
                counts[r] += len(o)
            yield out
        _check_decoded(f, path, got=got, want=want)
    if got == 0:
        raise AudioError(f"audio file {str(path)!r} holds no samples (zero-length audio)")
    if got < MIN_DURATION * native:
        raise AudioError(f"audio file {str(path)!r} is too short: {got / native:.3f} s ({got} samples at {native} "
                         f"Hz); need at least {MIN_DURATION:g} s")
    tail = []
    for r in rates:
        rest = streams[r].resample_chunk(np.zeros(0, np.float32), last=True) if r != native and not flushed \
            else np.zeros(0, np.float32)
        n_r = got if r == native else int(np.ceil(got * r / native))
        pad = max(0, n_r - counts[r] - len(rest))
        tail.append(np.concatenate([rest, np.zeros(pad, np.float32)])[: max(0, n_r - counts[r])])
    if any(len(t) for t in tail):
        yield tail


def save_wav(path: str | os.PathLike, y: np.ndarray, *, sr: int, subtype: str = "PCM_16") -> Path:
    """Write samples to a WAV file atomically (temporary file + rename), in blocks.

    Parameters
    ----------
    path : str or PathLike
        Output ``.wav`` path; its folder must exist.
    y : np.ndarray, shape (n,) or (channels, n)
        Samples in [-1, 1]; values outside are clipped for integer subtypes.
    sr : int
        Sample rate in Hz.
    subtype : str
        libsndfile subtype: ``"PCM_16"`` (default), ``"PCM_24"``, ``"FLOAT"``.

    Returns
    -------
    Path
        The written file.
    """
    if isinstance(sr, bool) or not isinstance(sr, int | np.integer) or sr <= 0:
        raise ParameterError(f"sr must be a positive integer sample rate in Hz, got {sr!r}")
    y = np.asarray(y)
    if y.ndim not in (1, 2):
        raise ParameterError(f"y must have shape (n,) or (channels, n), got {y.shape}")
    frames = y.reshape(1, -1) if y.ndim == 1 else y
    channels = frames.shape[0]
    clip = subtype.startswith("PCM")
    path = Path(path)
    with atomic_path(path, suffix=".wav") as tmp:
        with sf.SoundFile(
            tmp, "w", samplerate=int(sr), channels=channels, format="WAV", subtype=subtype
        ) as f:
            for a in range(0, frames.shape[1], _BLOCK):
                block = np.asarray(frames[:, a : a + _BLOCK].T, dtype=np.float32)
                if clip:
                    block = np.clip(block, -1.0, 1.0)
                f.write(block)
    return path


# ---------------------------------------------------------------------------------------------
# describing a media file (``dancekit info``)

_STREAM = re.compile(r"Stream #\d+:\d+[^:]*: (Audio|Video): (.*)")


def probe(path: str | os.PathLike) -> dict:
    """What an audio or video file holds, from its headers (no samples decoded, nothing on stderr).

    Returns ``{"format", "duration_s", "audio": {"sample_rate", "channels", "codec"} | None,
    "video": {"codec", "width", "height", "fps"} | None}`` (seconds, Hz, pixels, frames per second).
    libsndfile reads the header of wav / flac / ogg / mp3; anything else (mp4, m4a, mkv, ...) is described by
    the bundled ffmpeg (``ffmpeg -i``). A cover picture in a music file is not a video stream.

    Raises
    ------
    AudioError
        Missing, special (a pipe) or empty file, or one that neither libsndfile nor ffmpeg can read (names
        the file, without the libraries' own messages).
    """
    path = Path(path)
    check_audio_path(path)
    f = _open_soundfile(path)
    if f is not None:
        with f:
            if f.samplerate > 0 and f.frames > 0:
                return {"format": f.format, "duration_s": f.frames / f.samplerate, "video": None,
                        "audio": {"sample_rate": int(f.samplerate), "channels": int(f.channels),
                                  "codec": f.subtype}}
    cmd = [_ffmpeg_exe(), "-nostdin", "-hide_banner", "-i", str(path)]
    try:  # no output file: ffmpeg describes the input on stderr and exits 1
        err = subprocess.run(cmd, capture_output=True, process_group=0).stderr.decode("utf-8", "replace")
    except OSError as exc:
        raise ExternalToolError(f"cannot run ffmpeg: {exc}") from exc
    m = re.search(r"Input #0, ([^,\s]+)", err)
    if m is None:
        lines = [ln.strip() for ln in err.splitlines() if ln.strip()]
        reason = lines[-1] if lines else "unknown format"
        raise AudioError(f"cannot read media file {str(path)!r}: not an audio or video file ({reason})")
    fmt = m.group(1)
    d = re.search(r"Duration: (\d+):(\d+):(\d+(?:\.\d+)?)", err)
    duration = int(d.group(1)) * 3600 + int(d.group(2)) * 60 + float(d.group(3)) if d else None
    audio = video = None
    for kind, desc in _STREAM.findall(err):
        if kind == "Audio" and audio is None:
            rate = re.search(r"(\d+) Hz", desc)
            parts = [p.strip() for p in desc.split(",")]
            layout = parts[2] if len(parts) > 2 else "mono"
            try:
                channels = _channels_from_layout(layout)
            except AudioError:
                channels = 0
            audio = {"sample_rate": int(rate.group(1)) if rate else 0, "channels": channels,
                     "codec": desc.split()[0]}
        elif kind == "Video" and video is None and "attached pic" not in desc:
            size = re.search(r"(\d{2,})x(\d{2,})", desc)
            fps = re.search(r"([\d.]+) fps", desc)
            video = {"codec": desc.split()[0], "width": int(size.group(1)) if size else 0,
                     "height": int(size.group(2)) if size else 0, "fps": float(fps.group(1)) if fps else None}
    if audio is None and video is None:
        raise AudioError(f"cannot read media file {str(path)!r}: it holds no audio or video stream")
    return {"format": fmt.upper(), "duration_s": duration, "audio": audio, "video": video}
