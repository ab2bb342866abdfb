"""The features of a cold ``dancekit dance`` computed in a forked child while the parent imports torch
(:mod:`dancekit.features.prefetch`, issue 13's ≤ 5 s point). Each check runs in a fresh process: this test
process has torch loaded, where prefetching is off by design."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dancekit.audio import save_wav
from dancekit.audio.synth import ode_to_joy
from dancekit.features.prefetch import Prefetch, prefetch_features

SR = 22050
SRC = str(Path(__file__).resolve().parents[2] / "src")


@pytest.fixture(scope="module")
def song(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("song") / "ode.wav"
    save_wav(path, ode_to_joy(sr=SR, bpm=120)[: int(6.0 * SR)], sr=SR)
    return path


def _python(code: str, cache: Path, **env) -> subprocess.CompletedProcess:
    full = {**os.environ, "PYTHONPATH": SRC, "DANCEKIT_CACHE": str(cache), **env}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=full, timeout=300)


CHILD = """
import sys
from dancekit.pipelines.prefetch import prefetch_for_model
from dancekit.features import extract_file
pre = prefetch_for_model({song!r}, "music2dance")
print("started", pre.started, "torch", "torch" in sys.modules)
print("done", pre.wait())
fs = extract_file({song!r}, fps=25.0, preset="music2dance")
print("from_cache", fs.from_cache)
"""


def test_prefetch_fills_the_cache_the_parent_then_reads(song, tmp_path):
    r = _python(CHILD.format(song=str(song)), tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["started", "True", "torch", "False", "done", "True", "from_cache", "True"], r.stdout
    assert r.stderr == ""
    # the cached features are the ones the parent computes itself
    from dancekit.features import extract_file

    cached = np.load(next((tmp_path / "cache").rglob("*[0-9a-f].npz")))
    fresh = extract_file(song, fps=25.0, preset="music2dance", use_cache=False)
    np.testing.assert_array_equal(cached["features"], fresh.features)


def test_prefetch_is_off_when_torch_is_loaded_or_switched_off(song, tmp_path):
    import torch  # noqa: F401 - this process has it; prefetching would have nothing to overlap

    pre = prefetch_features(song, fps=25.0, preset="music2dance")
    assert not pre.started and pre.wait() is False
    pre.cancel()
    r = _python(CHILD.format(song=str(song)), tmp_path / "cache", DANCEKIT_PREFETCH="0")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[:6] == ["started", "False", "torch", "False", "done", "False"]


def test_a_failing_child_is_quiet_and_leaves_nothing(tmp_path):
    bad = tmp_path / "bad.wav"  # a header that promises 5 s of audio, then a few bytes: the read fails
    good = tmp_path / "good.wav"
    save_wav(good, np.zeros(5 * SR, np.float32), sr=SR)
    bad.write_bytes(good.read_bytes()[:200])
    code = f"""
from dancekit.features.prefetch import prefetch_features
pre = prefetch_features({str(bad)!r}, fps=25.0, preset="music2dance")
print(pre.started, pre.wait())
"""
    r = _python(code, tmp_path / "cache")
    assert r.returncode == 0 and r.stdout.split() == ["True", "False"] and r.stderr == "", (r.stdout, r.stderr)
    cache = tmp_path / "cache"
    assert not cache.exists() or not [p for p in cache.rglob("*") if p.is_file()]


def test_no_prefetch_for_a_long_clip(song, tmp_path):
    # a long song's features are computed by the parent alone (two processes would hold memory at once)
    code = f"""
import dancekit.features.prefetch as pf
pf.MAX_SECONDS = 4.0
whole = pf.prefetch_features({str(song)!r}, fps=25.0, preset="music2dance")      # 6 s > 4 s
part = pf.prefetch_features({str(song)!r}, fps=25.0, preset="music2dance", start=1.0, end=4.5)  # 3.5 s
tail = pf.prefetch_features({str(song)!r}, fps=25.0, preset="music2dance", start=1.5)           # 4.5 s
print(whole.started, part.started, tail.started, part.wait())
"""
    r = _python(code, tmp_path / "cache")
    assert r.returncode == 0 and r.stdout.split() == ["False", "True", "False", "True"], (r.stdout, r.stderr)


def test_cancel_stops_a_running_child(song, tmp_path):
    code = f"""
import time
from dancekit.features.prefetch import prefetch_features
pre = prefetch_features({str(song)!r}, fps=25.0, preset="music2dance")
pid = pre.pid
pre.cancel()
import os
try:
    os.kill(pid, 0)
    print("alive")
except ProcessLookupError:
    print("gone")
"""
    r = _python(code, tmp_path / "cache")
    assert r.returncode == 0 and r.stdout.split() == ["gone"], (r.stdout, r.stderr)
    assert not [p for p in (tmp_path / "cache").rglob(".*") if p.is_file()]  # no temporary file left


@pytest.mark.slow
def test_cli_dance_with_and_without_prefetch_is_the_same_dance(song, tmp_path):
    outs = {}
    for flag in ("1", "0"):
        out = tmp_path / f"out{flag}"
        r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "--model", "music2dance",
                            "--format", "npz", "--quiet", "-o", str(out)], capture_output=True, text=True, timeout=300,
                           env={**os.environ, "PYTHONPATH": SRC, "DANCEKIT_CACHE": str(tmp_path / f"c{flag}"),
                                "DANCEKIT_PREFETCH": flag})
        assert r.returncode == 0 and r.stderr == "", r.stderr
        with np.load(out / "ode.npz") as f:
            outs[flag] = f["positions"]
    np.testing.assert_array_equal(outs["1"], outs["0"])


def test_prefetch_handle_without_child():
    pre = Prefetch()
    assert not pre.started and pre.wait() is False
    pre.cancel()
