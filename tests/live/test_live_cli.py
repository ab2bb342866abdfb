"""``dancekit live`` on the command line: bad input is one line and exit 2; a file or stdin PCM danced and
recorded (the performance and the audio it heard, read back by dancekit)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dancekit.audio import load, save_wav
from dancekit.audio.synth import ode_to_joy
from dancekit.cli.main import main

SRC = Path(__file__).resolve().parents[2] / "src"


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    path = tmp_path_factory.mktemp("live") / "song.wav"
    save_wav(path, ode_to_joy(sr=22050, bpm=120)[: 22050 * 5], sr=22050)
    return path


@pytest.mark.parametrize("argv, message", [
    (["live", "--input", "nowhere.wav", "--no-serve"], "no such audio file: nowhere.wav"),
    (["live", "--input", "{song}", "--record", "out.txt", "--no-serve"], "--record out.txt: the file must end in"),
    (["live", "--stdin", "--realtime"], "--realtime paces a file"),
    (["live", "--input", "{song}", "--duration", "-1"], "--duration must be > 0 s"),
    (["live", "--input", "{song}", "--osc", "localhost"], "--osc needs HOST:PORT"),
])
def test_live_bad_input_is_one_line(argv, message, song, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([a.format(song=song) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not (tmp_path / "out.txt").exists()


@pytest.mark.slow
def test_live_records_the_performance_with_its_audio(song, tmp_path, capsys):
    from dancekit.motion.formats.npz import read_npz

    out = tmp_path / "take.npz"
    log = tmp_path / "frames.jsonl"
    assert main(["live", "--input", str(song), "--no-serve", "--record", str(out), "--log", str(log)]) == 0
    motion = read_npz(out)
    n = 1 + int(5 * 12800) // 512  # every frame of the 5 s song at 25 fps
    assert motion.num_frames == n and np.isfinite(motion.positions).all()
    y, sr = load(out.with_suffix(".wav"))
    assert abs(len(y) / sr - 5.0) < 0.05  # the audio it heard
    assert len(log.read_text().splitlines()) == n
    assert "latency median" in capsys.readouterr().err


@pytest.mark.slow
def test_live_reads_pcm_on_stdin(tmp_path):
    pcm = (ode_to_joy(sr=16000, bpm=120)[: 16000 * 4] * 32767).astype("<i2").tobytes()
    out = tmp_path / "stdin.npz"
    env = dict(os.environ, PYTHONPATH=str(SRC))
    run = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "live", "--stdin", "--rate", "16000",
                          "--no-serve", "--record", str(out)], input=pcm, capture_output=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr.decode()
    from dancekit.motion.formats.npz import read_npz

    assert abs(read_npz(out).num_frames - 100) <= 2  # 4 s at 25 fps


@pytest.fixture
def made(monkeypatch):
    """The LiveSessions that ``dancekit live`` makes in a test, in order."""
    import dancekit.live.session as live_session

    sessions = []
    real = live_session.LiveSession

    def spy(*args, **kwargs):
        sessions.append(real(*args, **kwargs))
        return sessions[-1]

    monkeypatch.setattr(live_session, "LiveSession", spy)
    return sessions


@pytest.mark.slow
def test_live_jitter_cap_reaches_the_session(song, tmp_path, capsys, made):
    """``--jitter-cap`` turns the cap on: music2dance reads the genre of the 5-s song (its first reading at 4 s)
    and caps its smoothing; revolution says in one line that it has no cap to apply."""
    assert main(["live", "--input", str(song), "--no-serve", "--model", "music2dance", "--jitter-cap"]) == 0
    s = made[-1]
    assert s.config.jitter_cap and s.genre_reader is not None and s.genre_reader.probs
    assert s.stages.max_jitter in set(s.pipe.settings.stages.genre_stats.table("jitter").values())
    assert main(["live", "--input", str(song), "--no-serve", "--jitter-cap"]) == 0
    assert made[-1].stages.bank is None and "no jitter cap" in capsys.readouterr().err


def test_live_foot_lock_flag_reaches_the_session(song, made):
    """``--foot-lock on|off`` decides whether the session holds the feet; on without it."""
    for flag, held in ((["--foot-lock", "off"], False), (["--foot-lock", "on"], True), ([], True)):
        assert main(["live", "--input", str(song), "--no-serve", "--duration", "1", *flag]) == 0
        assert (made[-1].stages.lock is not None) is held
