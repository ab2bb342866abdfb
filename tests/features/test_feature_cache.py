"""The feature cache has a size bound and prunes its least recently used entries."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from dancekit.audio.io import save_wav
from dancekit.audio.synth import click_track
from dancekit.errors import ParameterError
from dancekit.features import CACHE_MAX_BYTES, cache_max_bytes, extract_file, prune_cache


def _songs(tmp_path, n):
    paths = []
    for i in range(n):
        p = tmp_path / f"song{i}.wav"
        save_wav(p, click_track(bpm=90 + 10 * i, duration=2.0, sr=22050), sr=22050)
        paths.append(p)
    return paths


def test_cache_stays_under_its_bound_and_keeps_the_recently_used(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    songs = _songs(tmp_path, 4)
    first = extract_file(songs[0], fps=25, preset="music2dance", cache_dir=cache)
    entry_size = next(cache.glob("*[0-9a-f].npz")).stat().st_size
    (cache / "notes.txt").write_text("not an entry")  # a stranger in the folder is never touched
    monkeypatch.setenv("DANCEKIT_CACHE_MAX_MB", str(2.5 * entry_size / (1 << 20)))  # room for two entries
    t = time.time() - 100
    for i, song in enumerate(songs[1:3], start=1):
        extract_file(song, fps=25, preset="music2dance", cache_dir=cache)
        for k, p in enumerate(sorted(cache.glob("*[0-9a-f].npz"), key=os.path.getmtime)):
            os.utime(p, (t + 10 * i + k, t + 10 * i + k))  # distinct mtimes, oldest first
    assert len(list(cache.glob("*[0-9a-f].npz"))) == 2  # song0 (least recently used) went when song2 came
    again = extract_file(songs[1], fps=25, preset="music2dance", cache_dir=cache)  # a hit touches song1
    assert again.from_cache
    extract_file(songs[3], fps=25, preset="music2dance", cache_dir=cache)  # evicts song2, not song1
    assert extract_file(songs[1], fps=25, preset="music2dance", cache_dir=cache).from_cache
    assert not extract_file(songs[0], fps=25, preset="music2dance", cache_dir=cache).from_cache
    assert sum(p.stat().st_size for p in cache.glob("*[0-9a-f].npz")) <= 2.5 * entry_size
    assert (cache / "notes.txt").read_text() == "not an entry"
    np.testing.assert_array_equal(first.features, extract_file(songs[0], fps=25, preset="music2dance",
                                                               cache_dir=cache).features)


def test_prune_keeps_the_entry_just_written_even_over_the_bound(tmp_path):
    names = [f"{i:064x}.npz" for i in range(3)]
    for i, name in enumerate(names):
        (tmp_path / name).write_bytes(b"x" * 100)
        os.utime(tmp_path / name, (1000 + i, 1000 + i))
    removed = prune_cache(tmp_path, max_bytes=0, keep=tmp_path / names[0])
    assert [p.name for p in removed] == names[1:] and [p.name for p in tmp_path.iterdir()] == [names[0]]


def test_cache_bound_setting(monkeypatch):
    monkeypatch.delenv("DANCEKIT_CACHE_MAX_MB", raising=False)
    assert cache_max_bytes() == CACHE_MAX_BYTES == 1 << 30
    monkeypatch.setenv("DANCEKIT_CACHE_MAX_MB", "2")
    assert cache_max_bytes() == 2 << 20
    for bad in ("-1", "lots", "inf", "nan"):
        monkeypatch.setenv("DANCEKIT_CACHE_MAX_MB", bad)
        with pytest.raises(ParameterError, match="DANCEKIT_CACHE_MAX_MB"):
            cache_max_bytes()
