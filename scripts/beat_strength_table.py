"""Beat strength of the real songs and the non-music inputs (the table in docs/FEATURES.md).

    PYTHONPATH=src python scripts/beat_strength_table.py
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from _signals import speech_like, white_noise  # noqa: E402
from conftest import NON_MUSIC, SONGS  # noqa: E402

from dancekit.audio.io import load  # noqa: E402
from dancekit.audio.synth import click_track  # noqa: E402
from dancekit.features import MUSIC_BEAT_STRENGTH, beat_strength, rhythm  # noqa: E402


def strength(y, sr) -> float:
    env = rhythm.fine_onset(rhythm.fine_log_mel(rhythm.to_beat_sr(y, sr)))
    return beat_strength(onset_envelope=env, rate=rhythm.BEAT_SR / rhythm.BEAT_HOP)


def main() -> int:
    rows = [(p.name, *load(p)) for p in [*SONGS, *NON_MUSIC] if p.exists()]
    rows += [(f"speech-like 30 s seed {s}", speech_like(seconds=30, seed=s), 22050) for s in range(3)]
    rows += [(f"white noise 30 s seed {s}", white_noise(seconds=30, seed=s), 22050) for s in range(3)]
    rows += [("120-BPM click track 20 s", click_track(bpm=120, duration=20, sr=22050), 22050)]
    print(f"threshold MUSIC_BEAT_STRENGTH = {MUSIC_BEAT_STRENGTH}")
    for name, y, sr in rows:
        b = strength(y, sr)
        print(f"{name:70s} {b:6.3f}  {'music' if b >= MUSIC_BEAT_STRENGTH else 'not music'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
