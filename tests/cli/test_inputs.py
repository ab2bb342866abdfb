"""Inputs users really send to `dancekit dance` / `render`: each gives a dance or exactly one clear error line
on stderr (no traceback, no decoder or librosa noise), and an output folder with nothing partial in it."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from _signals import speech_like, white_noise
from conftest import NON_MUSIC

from dancekit._checks import reduce_seed
from dancekit.audio.io import save_wav
from dancekit.audio.synth import click_track
from dancekit.cli.main import main
from dancekit.render._ffmpeg import ffmpeg_exe

ROOT = Path(__file__).resolve().parents[2]
SR = 22050


def _wav(path: Path, seconds: float) -> Path:
    save_wav(path, click_track(bpm=120, duration=seconds, sr=SR), sr=SR)
    return path


def _write(path: Path, y: np.ndarray, sr: int, subtype: str = "PCM_16") -> Path:
    save_wav(path, y, sr=sr, subtype=subtype)
    return path


def _ffmpeg(src: Path, dst: Path, *args: str) -> Path:
    subprocess.run([ffmpeg_exe(), "-nostdin", "-y", "-v", "error", "-i", str(src), *args, str(dst)],
                   check=True, capture_output=True, timeout=120)
    return dst


def _video(d: Path, ext: str, acodec: str) -> Path:
    song = _wav(d / "track.wav", 3.0)
    dst = d / f"clip.{ext}"
    subprocess.run([ffmpeg_exe(), "-nostdin", "-y", "-v", "error", "-f", "lavfi", "-i", "color=c=blue:s=64x48:d=3:r=10",
                    "-i", str(song), "-shortest", "-c:v", "mpeg4", "-c:a", acodec, str(dst)], check=True,
                   capture_output=True, timeout=120)
    song.unlink()
    return dst


def _truncated_mp3(d: Path) -> Path:
    whole = _ffmpeg(_wav(d / "whole.wav", 4.0), d / "whole.mp3", "-c:a", "libmp3lame")
    data = whole.read_bytes()
    (d / "cut.mp3").write_bytes(data[: len(data) // 2])  # a download that stopped half-way
    whole.unlink()
    (d / "whole.wav").unlink()
    return d / "cut.mp3"


def _mp3_with_cover_art(d: Path) -> Path:
    """An mp3 with a cover picture in its ID3 tag and no Xing header: libsndfile estimates its length from
    the file size, cover included, so it declares more samples than the file holds."""
    song, cover, dst = _wav(d / "a.wav", 3.0), d / "cover.png", d / "covered.mp3"
    exe = ffmpeg_exe()
    subprocess.run([exe, "-nostdin", "-v", "error", "-f", "lavfi", "-i", "testsrc=s=320x320:d=1", "-frames:v", "1",
                    str(cover)], check=True, capture_output=True, timeout=120)
    subprocess.run([exe, "-nostdin", "-v", "error", "-i", str(song), "-i", str(cover), "-map", "0:a", "-map", "1:v",
                    "-c:a", "libmp3lame", "-c:v", "png", "-disposition:v", "attached_pic", "-write_xing", "0",
                    "-id3v2_version", "3", str(dst)], check=True, capture_output=True, timeout=120)
    song.unlink()
    cover.unlink()
    return dst


def _shared(path: Path):
    def make(d: Path) -> Path:
        if not path.exists():
            pytest.skip(f"{path} not available")
        return path

    return make


def _random_mp3(d: Path) -> Path:
    (d / "noise.mp3").write_bytes(np.random.default_rng(0).bytes(20000))
    return d / "noise.mp3"


def _empty(d: Path) -> Path:
    (d / "empty.wav").touch()
    return d / "empty.wav"


def _folder(d: Path) -> Path:
    (d / "album").mkdir()
    return d / "album"


# (id, make the input, extra args, expected: "dance", "calm" (danced, and said not to look like music) or a piece
# of the one error line)
CASES = [
    ("random_bytes_mp3", _random_mp3, [], "cannot decode audio file"),
    ("clip_1_5s", lambda d: _wav(d / "short.wav", 1.5), [], "dance"),
    ("clip_0_5s", lambda d: _wav(d / "tiny.wav", 0.5), [], "too short"),
    ("empty_file", _empty, [], "empty (0 bytes)"),
    ("directory", _folder, [], "got a folder"),
    ("spaces_non_ascii_path", lambda d: _wav(d / "mi canción ü 舞.wav", 4.0), [], "dance"),
    ("huge_seed", lambda d: _wav(d / "seed.wav", 3.0), ["--seed", "18446744073709551616"], "dance"),
    ("negative_seed", lambda d: _wav(d / "neg.wav", 3.0), ["--seed", "-5"], "dance"),
    ("start_beyond_end", lambda d: _wav(d / "s.wav", 3.0), ["--start", "100"], "beyond the end"),
    ("wav_named_mp3", lambda d: _wav(d / "really_a_wav.mp3", 3.0), [], "dance"),
    ("start_after_end", lambda d: _wav(d / "s.wav", 3.0), ["--start", "2", "--end", "1"], "start"),
    ("silence", lambda d: _write(d / "silence.wav", np.zeros(3 * SR, np.float32), SR), [], "calm"),
    ("white_noise", lambda d: _write(d / "noise.wav", white_noise(seconds=3.0), SR), [], "calm"),
    ("speech_like", lambda d: _write(d / "speech.wav", speech_like(seconds=5.0), SR), [], "calm"),
    ("bird_robin", _shared(NON_MUSIC[0]), [], "calm"),
    ("humpback_whale", _shared(NON_MUSIC[1]), ["--end", "12"], "calm"),
    ("clip_0_2s", lambda d: _wav(d / "blip.wav", 0.2), [], "too short"),
    ("clip_2s", lambda d: _wav(d / "two.wav", 2.0), [], "dance"),
    ("mono_8khz", lambda d: _write(d / "phone.wav", click_track(bpm=120, duration=3.0, sr=8000), 8000), [], "dance"),
    ("stereo_96khz_24bit", lambda d: _write(d / "studio.wav", np.stack([click_track(bpm=120, duration=3.0, sr=96000)] * 2)
                                            * np.array([[1.0], [0.5]], np.float32), 96000, "PCM_24"), [], "dance"),
    ("stereo_one_silent_channel", lambda d: _write(d / "left.wav", np.stack(
        [click_track(bpm=120, duration=3.0, sr=SR), np.zeros(3 * SR, np.float32)]), SR), [], "dance"),
    ("mp4_video", lambda d: _video(d, "mp4", "aac"), [], "dance"),
    ("mkv_video", lambda d: _video(d, "mkv", "libvorbis"), [], "dance"),
    ("m4a", lambda d: _ffmpeg(_wav(d / "m.wav", 3.0), d / "song.m4a", "-c:a", "aac"), [], "dance"),
    ("truncated_mp3", _truncated_mp3, [], "truncated"),
    ("mp3_with_cover_art", _mp3_with_cover_art, [], "dance"),
]


@pytest.mark.parametrize("make,extra,expect", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_dance_input(tmp_path, capfd, make, extra, expect):
    src = make(tmp_path)
    before = sorted(p.name for p in src.parent.iterdir()) if src.parent == tmp_path else None
    out = tmp_path / "out dir"
    with warnings.catch_warnings(record=True) as caught:  # what a user's terminal would show
        warnings.simplefilter("always")
        code = main(["dance", str(src), "-o", str(out), "--format", "npz", "--quiet", *extra])
    stdout, stderr = capfd.readouterr()  # file-descriptor level: C libraries' output too
    assert [str(w.message) for w in caught] == []
    if expect in ("dance", "calm"):
        assert code == 0, stderr
        said = "does not look like music" in stdout
        assert said == (expect == "calm"), stdout
        assert stderr == "", stderr  # no warnings, no decoder notes
        assert [p.name for p in out.iterdir()] == [f"{src.stem}.npz"]
        assert np.isfinite(np.load(out / f"{src.stem}.npz")["positions"]).all()
    else:
        assert code == 2
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("dancekit dance: error:") and expect in lines[0], stderr
        assert not out.exists() or not any(out.iterdir())  # nothing partial
    if before is not None:  # nothing hidden beside the input either (no temp folders or files)
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, *(["out dir"] if out.exists() else [])])


def test_output_path_that_is_a_file(tmp_path, capfd):
    song = _wav(tmp_path / "song.wav", 3.0)
    (tmp_path / "taken").write_text("mine")
    code = main(["dance", str(song), "-o", str(tmp_path / "taken"), "--format", "npz", "--quiet"])
    lines = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "taken" in lines[0]
    assert (tmp_path / "taken").read_text() == "mine"


def test_output_named_like_a_file_is_a_folder_and_says_so(tmp_path, capfd):
    """``-o d.npz``: -o is a folder, so the dance goes inside it, and one line on stderr says so (a newcomer may
    have meant a file); a plain folder name gets no such line."""
    song = _wav(tmp_path / "song.wav", 3.0)
    code = main(["dance", str(song), "-o", str(tmp_path / "d.npz"), "--format", "npz", "--quiet"])
    lines = capfd.readouterr().err.strip().splitlines()
    assert code == 0 and len(lines) == 1 and "is an output folder" in lines[0] and "d.npz" in lines[0]
    assert (tmp_path / "d.npz" / "song.npz").is_file()
    code = main(["dance", str(song), "-o", str(tmp_path / "plain"), "--format", "npz", "--quiet"])
    assert code == 0 and capfd.readouterr().err == ""


def test_huge_seeds_reduce_to_64_bits_and_keep_small_ones():
    assert reduce_seed(0) == 0 and reduce_seed(2**63 - 1) == 2**63 - 1
    big = [reduce_seed(2**64), reduce_seed(2**64 + 1), reduce_seed(-1), reduce_seed(10**40)]
    assert all(0 <= s < 2**63 for s in big) and len(set(big)) == 4 and reduce_seed(2**64) == big[0]


def test_render_refuses_audio_shorter_than_the_dance(tmp_path, capfd):
    from dancekit.motion import Motion, get_skeleton
    from dancekit.motion.formats import write_motion

    skel = get_skeleton("tang2018")
    pos = np.random.default_rng(0).normal(0, 10, (150, skel.num_joints, 3)).astype(np.float32)  # 6 s
    write_motion(tmp_path / "dance.npz", Motion(skeleton=skel, fps=25.0, positions=pos))
    song = _wav(tmp_path / "song.wav", 2.0)
    out = tmp_path / "out"
    out.mkdir()
    code = main(["render", str(tmp_path / "dance.npz"), "--audio", str(song), "-o", str(out / "v.mp4"), "-q"])
    stderr = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(stderr) == 1 and "shorter than the dance" in stderr[0]
    assert not any(out.iterdir())


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"])
@pytest.mark.slow
def test_signal_during_render_leaves_nothing(tmp_path, sig):
    """Ctrl-C reaches the whole foreground process group (dancekit and its ffmpeg), as in a terminal; a plain
    ``kill`` / ``timeout`` (SIGTERM) or a closed terminal (SIGHUP) reaches dancekit alone."""
    song = _wav(tmp_path / "song.wav", 30.0)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o", str(out),
                             "--format", "mp4", "--quiet"], env=env, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            # Ctrl-C and a closed terminal's SIGHUP as a user's shell delivers them, even when the
                            # tests themselves run in the background or under nohup (a non-interactive shell's
                            # background job ignores SIGINT, nohup SIGHUP; SIG_IGN is inherited, and Python and
                            # dancekit leave an ignored signal alone)
                            preexec_fn=lambda: [signal.signal(s, signal.SIG_DFL) for s in (signal.SIGINT,
                                                                                          signal.SIGHUP)])
    deadline = time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline:
        if out.is_dir() and any(p.name.startswith(".dancekit-") for p in out.iterdir()):
            break  # the staging folder exists: rendering has begun
        time.sleep(0.02)
    time.sleep(0.5)  # a few frames into the mp4
    assert proc.poll() is None, "the render ended before the signal"
    if sig == signal.SIGINT:
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, stderr
    assert stderr.strip().splitlines() == [f"dancekit dance: stopped by {sig.name}; nothing partial was left"]
    assert not out.exists() or list(out.iterdir()) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "song.wav"] or not out.exists()


def _as_unprivileged(cmd: list[str]) -> list[str]:
    """``cmd`` run without the power to write where permissions forbid it (root ignores a read-only mode bit:
    run as root, drop the DAC-override capabilities with util-linux ``setpriv``)."""
    if os.geteuid() != 0:
        return cmd
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: a read-only folder cannot be made")
    caps = "-dac_override,-dac_read_search"
    return [setpriv, f"--inh-caps={caps}", f"--bounding-set={caps}", *cmd]


@pytest.mark.parametrize("where", ["readonly", "readonly/new"], ids=["readonly_folder", "inside_readonly_folder"])
def test_read_only_output_folder(tmp_path, where):
    song = _wav(tmp_path / "song.wav", 3.0)
    ro = tmp_path / "readonly"
    ro.mkdir()
    ro.chmod(0o555)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    try:
        r = subprocess.run(_as_unprivileged([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o",
                                             str(tmp_path / where), "--format", "npz", "--quiet"]),
                           env=env, capture_output=True, text=True, timeout=300)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1, r.stderr
        assert lines[0].startswith("dancekit dance: error:") and "readonly" in lines[0] and "writ" in lines[0]
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def _parsers(parser, path=()):
    """(verb path, parser) for every (sub-)command of ``parser``."""
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield (*path, name), child
                yield from _parsers(child, (*path, name))


def test_output_flag_has_both_spellings_on_every_verb():
    from dancekit.cli.main import build_parser

    with_output = {}
    for verb, parser in _parsers(build_parser()):
        spellings = {f for a in parser._actions for f in a.option_strings if f in ("--out", "--output")}
        if spellings:
            with_output[verb] = spellings
    assert {("dance",), ("render",), ("train",), ("convert",), ("features",)} <= set(with_output)
    assert all(s == {"--out", "--output"} for s in with_output.values()), with_output
    dance_out = build_parser().parse_args(["dance", "song.wav", "--output", "x"]).out
    render_out = build_parser().parse_args(["render", "d.npz", "--out", "y.mp4"]).output
    assert (dance_out, render_out) == ("x", "y.mp4")


def test_info_reads_the_audio_track_of_a_video_dance_accepts(tmp_path, capfd):
    video = _video(tmp_path, "mp4", "aac")
    assert main(["info", str(video), "--json"]) == 0
    import json

    info = json.loads(capfd.readouterr().out)
    assert info["kind"] == "video" and abs(info["duration_s"] - 3.0) < 0.1, info
    assert info["channels"] == 1 and info["video"]["width"] == 64 and info["video"]["height"] == 48, info


def test_readme_says_what_the_dance_npz_holds(tmp_path):
    """The README's sentence on rotations in ``song.npz`` matches the file ``dancekit dance`` writes."""
    song = _wav(tmp_path / "song.wav", 3.0)
    assert main(["dance", str(song), "-o", str(tmp_path / "o"), "--format", "npz", "--quiet"]) == 0
    has_rotations = "rotations" in np.load(tmp_path / "o" / "song.npz").files
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert ("so the file has no rotations" in readme) == (not has_rotations)


def test_a_verb_alone_gets_the_parser_every_verb_gets():
    """main() builds only the parser of the verb on the command line: for every verb, the same options as in the
    whole parser (``dancekit --help`` and a misspelt verb still build them all)."""
    from dancekit.cli.main import VERBS, build_parser

    whole = dict(_parsers(build_parser()))
    for verb in VERBS:
        alone = dict(_parsers(build_parser([verb])))
        assert {p[0] for p in alone} == {verb}
        for path, parser in alone.items():
            want = sorted(f for a in whole[path]._actions for f in a.option_strings)
            assert sorted(f for a in parser._actions for f in a.option_strings) == want, (verb, path)


def test_a_verb_imports_no_other_verbs_module():
    import subprocess
    import sys

    code = ("import sys; from dancekit.cli.main import main; main(['models']); "
            "print(sorted(m for m in sys.modules if m.startswith('dancekit.cli.') and m not in "
            "('dancekit.cli.main', 'dancekit.cli.models', 'dancekit.cli._options')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"
