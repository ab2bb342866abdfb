"""An mp3 is called truncated when its last MPEG frame runs past the end of the file, not when libsndfile's
length estimate is more than it decodes."""

from __future__ import annotations

import subprocess

from dancekit.audio.io import _mp3_frame_length, _mp3_truncated, save_wav
from dancekit.audio.synth import click_track
from dancekit.render._ffmpeg import ffmpeg_exe


def test_mp3_frame_length_known_answers():
    # MPEG-1 layer III, 128 kbit/s, 44.1 kHz, no padding: 144 * 128000 / 44100 = 417 bytes; padded: 418
    assert _mp3_frame_length(bytes([0xFF, 0xFB, 0x90, 0x00])) == 417
    assert _mp3_frame_length(bytes([0xFF, 0xFB, 0x92, 0x00])) == 418
    # MPEG-2 layer III, 64 kbit/s, 22.05 kHz: 72 * 64000 / 22050 = 208
    assert _mp3_frame_length(bytes([0xFF, 0xF3, 0x80, 0x00])) == 208
    assert _mp3_frame_length(b"RIFF") == 0 and _mp3_frame_length(bytes([0xFF, 0xFB, 0xF0, 0x00])) == 0


def test_every_cut_inside_a_frame_is_truncated_and_the_whole_file_is_not(tmp_path):
    save_wav(tmp_path / "a.wav", click_track(bpm=120, duration=2.0, sr=22050), sr=22050)
    subprocess.run([ffmpeg_exe(), "-nostdin", "-v", "error", "-i", str(tmp_path / "a.wav"), "-c:a", "libmp3lame",
                    str(tmp_path / "a.mp3")], check=True, capture_output=True, timeout=120)
    data = (tmp_path / "a.mp3").read_bytes()
    assert not _mp3_truncated(tmp_path / "a.mp3")
    cut = tmp_path / "cut.mp3"
    results = []
    for k in range(len(data) // 4, len(data) - 1, 53):
        cut.write_bytes(data[:k])
        results.append(_mp3_truncated(cut))
    assert sum(results) >= len(results) - 1  # at most one cut falls exactly on a frame boundary
