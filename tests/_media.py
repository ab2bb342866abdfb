"""Media helpers shared by the tests: stream probing with the bundled ffmpeg, headless Chromium."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from dancekit.render._ffmpeg import ffmpeg_exe


def stream_info(path) -> dict:
    """``{"video": codec or None, "audio": codec or None, "size": (w, h), "video_s", "audio_s"}`` by decoding."""
    exe = ffmpeg_exe()
    head = subprocess.run([exe, "-hide_banner", "-i", str(path)], capture_output=True, text=True, timeout=120).stderr
    info = {"video": None, "audio": None, "size": None, "video_s": None, "audio_s": None}
    if m := re.search(r"Stream #0:\d.*?: Video: (\w+).*?, (\d+)x(\d+)", head):
        info["video"], info["size"] = m.group(1), (int(m.group(2)), int(m.group(3)))
    if m := re.search(r"Stream #0:\d.*?: Audio: (\w+)", head):
        info["audio"] = m.group(1)
    for kind in ("video", "audio"):
        if info[kind] is None:
            continue
        r = subprocess.run(
            [exe, "-hide_banner", "-i", str(path), "-map", f"0:{kind[0]}:0", "-f", "null", "-"],
            capture_output=True,
            text=True,
            check=True, timeout=120,
        )
        h, mi, s = re.findall(r"time=\s*(\d+):(\d\d):(\d\d\.\d+)", r.stderr)[-1]
        info[f"{kind}_s"] = int(h) * 3600 + int(mi) * 60 + float(s)
    return info


def chromium() -> str:
    """Path of a headless Chromium; without one, fail on CI (``CI=true``) and skip elsewhere.

    The html player is only checked in a real browser here, so CI must not skip these tests silently.
    """
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if exe := shutil.which(name):
            return exe
    hint = "install it with `apt-get install -y chromium` (Debian) or put chromium / google-chrome on PATH"
    if os.environ.get("CI", "").strip().lower() == "true":
        pytest.fail(f"headless Chromium not found on PATH but CI=true: the html player cannot be checked; {hint}",
                    pytrace=False)
    pytest.skip(f"headless Chromium not installed (the html player tests need it; {hint})")


def run_chromium(exe: str, url: str, profile, *extra: str, budget_ms: int = 1500) -> subprocess.CompletedProcess:
    cmd = [
        exe,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--mute-audio",
        f"--user-data-dir={profile}",
        f"--virtual-time-budget={int(budget_ms)}",
        *extra,
        url,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True)
