"""What a browser sends: file kinds read from the bytes, client names made safe, uploads copied under a cap.

Nothing here trusts the client: the kind of an upload comes from its first bytes (not its name or its
``Content-Type``), and the client's file name only ever gives a sanitised output *stem* (letters, digits,
``-``, ``_``, ``.``), never a path.
"""

from __future__ import annotations

import re
from typing import BinaryIO

from dancekit.errors import ParameterError

#: Audio kinds the dance page takes, by content: kind -> the suffix the upload is stored under.
AUDIO_KINDS = {"wav": ".wav", "flac": ".flac", "ogg": ".ogg", "mp3": ".mp3", "mp4": ".m4a", "aiff": ".aiff"}
#: Dance kinds the compose page takes, by content: kind -> the suffix the motion readers go by.
DANCE_KINDS = {"npz": ".npz", "bvh": ".bvh", "pkl": ".pkl", "glb": ".glb"}

_NAME_OK = re.compile(r"[^A-Za-z0-9._-]+")


def sniff(head: bytes) -> str | None:
    """The kind of a file from its first bytes (at least 16 for a sure answer), or None when unknown.

    Audio: ``wav``, ``flac``, ``ogg``, ``mp3``, ``mp4`` (m4a / mp4 / mov: an ISO-BMFF ``ftyp`` box),
    ``aiff``; dances: ``npz`` (a zip), ``bvh``, ``pkl`` (a pickle, protocol 2-5), ``glb`` (glTF binary);
    ``midi``, ``html``, ``png``, ``jpeg`` and ``pdf`` are named so that an error can say what was sent.
    """
    h = bytes(head)
    if h[:4] == b"RIFF" and h[8:12] == b"WAVE":
        return "wav"
    if h[:4] == b"fLaC":
        return "flac"
    if h[:4] == b"OggS":
        return "ogg"
    if h[:4] == b"FORM" and h[8:12] in (b"AIFF", b"AIFC"):
        return "aiff"
    if h[4:8] == b"ftyp":
        return "mp4"
    if h[:3] == b"ID3" or (len(h) >= 2 and h[0] == 0xFF and (h[1] & 0xE0) == 0xE0 and (h[1] & 0x06) != 0):
        return "mp3"
    if h[:4] == b"PK\x03\x04":
        return "npz"
    if h[:4] == b"glTF":
        return "glb"
    if len(h) >= 2 and h[0] == 0x80 and 2 <= h[1] <= 5:
        return "pkl"
    if h[:4] == b"MThd":
        return "midi"
    if h[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    if h[:3] == b"\xff\xd8\xff":
        return "jpeg"
    if h[:5] == b"%PDF-":
        return "pdf"
    text = h.lstrip(b"\xef\xbb\xbf \t\r\n")
    if text[:9].upper() == b"HIERARCHY":
        return "bvh"
    if text[:1] == b"<":
        return "html"
    return None


def safe_stem(client_name: str | None, default: str) -> str:
    """A file-name stem from the client's file name: its last component without the suffix, reduced to
    ``[A-Za-z0-9._-]``, no leading dot, at most 60 characters; ``default`` when nothing is left.

    ``"../../x.mp3"`` -> ``"x"``, ``"C:\\\\songs\\\\my song.ogg"`` -> ``"my_song"``, ``".."`` -> ``default``.
    """
    name = re.split(r"[/\\]", str(client_name or ""))[-1]
    stem = name.rsplit(".", 1)[0] if "." in name.lstrip(".") else name
    stem = _NAME_OK.sub("_", stem).strip("._-")[:60].strip("._-")
    return stem or default


def copy_capped(src: BinaryIO, dst: BinaryIO, *, limit: int, what: str, chunk: int = 1 << 20) -> int:
    """Copy ``src`` to ``dst``; returns the bytes copied.

    Raises
    ------
    ParameterError
        When ``src`` holds more than ``limit`` bytes (the copy stops there; the caller removes ``dst``).
    """
    total = 0
    while True:
        block = src.read(chunk)
        if not block:
            return total
        total += len(block)
        if total > limit:
            raise ParameterError(f"{what} is larger than the upload limit of {limit / 1e6:g} MB")
        dst.write(block)
