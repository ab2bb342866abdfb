"""Every door a user tries opens (issue 45): special and odd inputs and outputs get one error line, every motion
file the toolkit writes reads back (glb included) as the same dance, every verb's flags mean one thing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancekit.audio.io import save_wav
from dancekit.audio.synth import click_track
from dancekit.cli.main import main
from dancekit.errors import AudioError, MotionFormatError
from dancekit.motion import Motion
from dancekit.motion.formats import read_motion, write_motion
from dancekit.motion.skeleton import get_skeleton

ROOT = Path(__file__).resolve().parents[2]
SR = 22050


def _wav(path: Path, seconds: float) -> Path:
    save_wav(path, click_track(bpm=120, duration=seconds, sr=SR), sr=SR)
    return path


def _one_error_line(err: str, verb: str, *needles: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"dancekit {verb}: error:"), err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def _tang_walk(T: int = 60, fps: float = 25.0) -> Motion:
    """A tang2018 dance with rotations: the rest pose swaying and walking forward (cm, y up)."""
    sk = get_skeleton("tang2018")
    t = np.arange(T) / fps
    J = sk.rig().num_joints
    ang = 0.3 * np.sin(2 * np.pi * 1.5 * t)[:, None] * np.linspace(0.2, 1.0, J)[None]  # (T, J) about z
    c, s = np.cos(ang), np.sin(ang)
    R = np.zeros((T, J, 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    root = np.stack([np.zeros(T), 95 + 3 * np.sin(2 * np.pi * 2 * t), 40 * t], axis=-1)
    return Motion(sk, fps, rotations=R, root_translation=root).with_positions()


# ------------------------------------------------------------------- special files, odd outputs
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this system")
def test_info_and_dance_on_a_named_pipe_answer_at_once(tmp_path):
    """A FIFO is refused by name (reading it would wait for a writer forever), for audio and motion alike."""
    for name in ("song.ogg", "dance.bvh"):
        fifo = tmp_path / name
        os.mkfifo(fifo)
        r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "info", str(fifo)], capture_output=True,
                           text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
        assert r.returncode == 2
        _one_error_line(r.stderr, "info", "named pipe", name)
    with pytest.raises(AudioError, match="named pipe"):
        from dancekit.audio import check_audio_path

        check_audio_path(tmp_path / "song.ogg")
    with pytest.raises(MotionFormatError, match="dance.bvh"):
        read_motion(tmp_path / "dance.bvh")


def test_render_onto_a_folder_is_refused_before_rendering(tmp_path, capsys):
    m = _tang_walk(T=10)
    write_motion(tmp_path / "d.npz", m)
    (tmp_path / "adir.mp4").mkdir()
    assert main(["render", str(tmp_path / "d.npz"), "-o", str(tmp_path / "adir.mp4")]) == 2
    _one_error_line(capsys.readouterr().err, "render", "adir.mp4", "is a folder")
    assert list((tmp_path / "adir.mp4").iterdir()) == []


def test_info_on_random_bytes_named_mp3_is_one_line(tmp_path, capfd):
    """No libmpg123 note ("[src/libmpg123/parse.c...]" / "Note: Illegal Audio-MPEG-Header") on file descriptor 2."""
    bad = tmp_path / "noise.mp3"
    bad.write_bytes(np.random.default_rng(0).integers(0, 256, 50_000, dtype=np.uint8).tobytes())
    assert main(["info", str(bad)]) == 2
    _one_error_line(capfd.readouterr().err, "info", "noise.mp3")


class _Decoded:
    """What :func:`dancekit.audio.io._check_decoded` reads of an open SoundFile."""

    def __init__(self, frames: int):
        self.format, self.frames = "OGG", frames


def test_a_cut_ogg_may_end_one_block_short_but_a_truncated_one_is_refused(tmp_path):
    """An Ogg stream whose last granule position lies up to one long Vorbis block (from its header) past the
    decoded end is whole (``ffmpeg -t 60`` leaves 128 samples); more is refused; so is a cut-off file."""
    from dancekit.audio.io import _check_decoded, _ogg_block

    y = click_track(bpm=120, duration=3.0, sr=SR)
    path = tmp_path / "cut.ogg"
    sf.write(path, y, SR, format="OGG", subtype="VORBIS")
    block = _ogg_block(path)
    assert block in (256, 512, 1024, 2048, 4096, 8192)  # a Vorbis long block
    n = sf.info(path).frames
    _check_decoded(_Decoded(n + 128), path, got=n, want=n + 128)  # accepted
    _check_decoded(_Decoded(n + block), path, got=n, want=n + block)  # accepted: one block
    with pytest.raises(AudioError, match="declares"):
        _check_decoded(_Decoded(n + block + 1), path, got=n, want=n + block + 1)
    cut = tmp_path / "truncated.ogg"
    cut.write_bytes(path.read_bytes()[:-200])  # the last page cut off: real truncation
    with pytest.raises(AudioError, match="truncated"):
        _check_decoded(_Decoded(n + 128), cut, got=n, want=n + 128)


def test_empty_output_and_unbounded_fps_are_one_line_each(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    song = _wav(tmp_path / "song.wav", 3.0)
    write_motion(tmp_path / "d.npz", _tang_walk(T=10))
    assert main(["dance", str(song), "-o", "", "--format", "npz", "--quiet"]) == 2
    _one_error_line(capsys.readouterr().err, "dance", "-o")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npz", "song.wav"]  # nothing in the current folder
    for argv in (["dance", str(song), "-o", "x", "--fps", "1000"], ["render", "d.npz", "-o", "x.html", "--fps", "1000"],
                 ["convert", "d.npz", "-o", "x.npz", "--fps", "1000"]):
        assert main(argv) == 2
        _one_error_line(capsys.readouterr().err, argv[0], "--fps 1000", "240")
    assert main(["convert", "d.npz", "-o", "x.npz", "--fps", "240", "-q"]) == 0  # the bound itself is allowed
    assert main(["dance", str(song), "-o", "x", "--seeds", "0-1", "--workers", "0"]) == 2
    _one_error_line(capsys.readouterr().err, "dance", "--workers", "at least 1")


def test_convert_writes_the_path_it_is_given(tmp_path, capsys):
    write_motion(tmp_path / "d.npz", _tang_walk(T=10))
    assert main(["convert", str(tmp_path / "d.npz"), "-o", str(tmp_path / "a.json")]) == 2
    _one_error_line(capsys.readouterr().err, "convert", "a.json", "one file per frame")
    assert not (tmp_path / "a").exists() and not (tmp_path / "a.json").exists()
    assert main(["convert", str(tmp_path / "d.npz"), "-o", str(tmp_path / "kp"), "-q"]) == 0
    assert len(list((tmp_path / "kp").glob("*.json"))) == 10


def test_compose_refuses_a_dance_too_short_and_a_song(tmp_path, capsys):
    write_motion(tmp_path / "two.npz", _tang_walk(T=2))
    assert main(["compose", str(tmp_path / "two.npz"), "-o", str(tmp_path / "c")]) == 2
    _one_error_line(capsys.readouterr().err, "compose", "two.npz", "0.08 s", "at least 1 s")
    song = _wav(tmp_path / "song.ogg", 2.0)
    assert main(["compose", str(song), "-o", str(tmp_path / "c")]) == 2
    _one_error_line(capsys.readouterr().err, "compose", "dancekit dance")
    assert not (tmp_path / "c").exists()


# ------------------------------------------------------------------- glb, mp4 and MIDI read back
def test_glb_reads_back_as_the_dance_it_was_written_from(tmp_path):
    m = _tang_walk()
    write_motion(tmp_path / "d.glb", m)
    back = read_motion(tmp_path / "d.glb")
    assert back.skeleton.same_as(m.skeleton) and dict(back.skeleton.roles) == dict(m.skeleton.roles)
    assert back.fps == 25 and back.num_frames == m.num_frames and back.skeleton.units == "cm"
    np.testing.assert_allclose(back.to_positions(), m.to_positions(), atol=1e-3)  # float32 metres in the file
    np.testing.assert_allclose(back.rotations, m.rotations, atol=1e-5)


def test_glb_of_another_rig_keeps_its_joints_in_metres(tmp_path):
    """A rig that is not a built-in one: the file's joint names, metres, roles guessed from the names."""
    from dancekit.motion.formats.bvh import guess_roles
    from dancekit.motion.skeleton import Skeleton

    names = ("Hips", "Spine", "Head", "LeftUpLeg", "LeftLeg", "RightUpLeg", "RightLeg")
    parents = (-1, 0, 1, 0, 3, 0, 5)
    off = np.array([[0, 0, 0], [0, 20, 0], [0, 30, 0], [10, -5, 0], [0, -45, 0], [-10, -5, 0], [0, -45, 0]], float)
    roles, pairs = guess_roles(names, parents)
    sk = Skeleton(name="mini", joint_names=names, parents=parents, offsets=off, units="cm", roles=roles,
                  left_right=pairs)
    T = 12
    R = np.tile(np.eye(3), (T, 7, 1, 1))
    a = np.linspace(0, 1, T)
    R[:, 4, 1, 1], R[:, 4, 1, 2], R[:, 4, 2, 1], R[:, 4, 2, 2] = np.cos(a), -np.sin(a), np.sin(a), np.cos(a)
    m = Motion(sk, 30, rotations=R, root_translation=np.tile([0.0, 90.0, 0.0], (T, 1))).with_positions()
    write_motion(tmp_path / "mini.glb", m)
    back = read_motion(tmp_path / "mini.glb")
    assert back.skeleton.joint_names == names and back.skeleton.units == "m" and back.fps == 30
    assert back.skeleton.roles["head"] == "Head"
    np.testing.assert_allclose(back.to_positions(), m.to_positions() * 0.01, atol=1e-6)


def test_info_and_convert_read_the_glb_that_dance_writes(tmp_path, capsys):
    m = _tang_walk()
    write_motion(tmp_path / "d.glb", m)
    assert main(["info", "--json", str(tmp_path / "d.glb")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["format"], info["skeleton"], info["frames"], info["fps"]) == ("glb", "tang2018", 60, 25)
    assert main(["convert", str(tmp_path / "d.glb"), "-o", str(tmp_path / "d.npz"), "-q"]) == 0
    np.testing.assert_allclose(read_motion(tmp_path / "d.npz").positions, m.positions, atol=1e-3)


def test_info_lists_an_mp4s_video_and_audio(tmp_path, capsys):
    from dancekit.render import AudioClip, RenderOptions, render_motion_mp4

    song = _wav(tmp_path / "song.wav", 2.0)
    render_motion_mp4(tmp_path / "d.mp4", _tang_walk(T=40), audio=AudioClip(song, None, None),
                      options=RenderOptions(width=160, height=120), progress=False)
    assert main(["info", str(tmp_path / "d.mp4")]) == 0
    out = capsys.readouterr().out
    assert "video" in out and "160x120" in out and "25 fps" in out and "22050 Hz" in out, out


def test_info_reads_the_midi_compose_writes(tmp_path, capsys):
    import pretty_midi

    pm = pretty_midi.PrettyMIDI(initial_tempo=120.0)
    drums = pretty_midi.Instrument(program=0, is_drum=True, name="drums")
    drums.notes = [pretty_midi.Note(velocity=90, pitch=36, start=0.5 * k, end=0.5 * k + 0.1) for k in range(8)]
    pm.instruments.append(drums)
    pm.write(str(tmp_path / "song.mid"))
    assert main(["info", "--json", str(tmp_path / "song.mid")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["kind"] == "midi" and abs(info["tempo_bpm"] - 120) < 1e-6 and info["tracks"][0]["notes"] == 8
    with pytest.raises(MotionFormatError, match="MIDI"):
        read_motion(tmp_path / "song.mid")


def test_info_models_and_convert_of_rotations_import_no_torch(tmp_path):
    """``info`` of any motion, ``models``, and ``convert`` between files that hold rotations (BVH, glb, npz
    with rotations) to npz or BVH do no model work: torch (seconds to import) stays out."""
    m = _tang_walk(T=10)
    for name in ("d.npz", "d.bvh", "d.glb"):
        write_motion(tmp_path / name, m)
    d = str(tmp_path)
    code = ("import sys; from dancekit.cli.main import main\n"
            f"for f in ('d.npz', 'd.bvh', 'd.glb'): assert main(['info', {d!r} + '/' + f]) == 0\n"
            "assert main(['models']) == 0\n"
            f"assert main(['convert', {d!r} + '/d.glb', '-o', {d!r} + '/e.bvh']) == 0\n"
            f"assert main(['convert', {d!r} + '/d.bvh', '-o', {d!r} + '/e.npz']) == 0\n"
            f"assert main(['convert', {d!r} + '/d.npz', '-o', {d!r} + '/f.bvh']) == 0\n"
            "print('torch' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "False"


# ------------------------------------------------------------------- the same dance from every file
@pytest.mark.shared
def test_the_same_dance_from_npz_bvh_and_glb_composes_the_same_music(tang2018_dir, tmp_path):
    """A dance read from the npz, the exact-rig BVH and the glb the toolkit writes is the same dance (same
    skeleton, positions to 1e-3 cm, the same ``info``) and composes the same music (tempo within 1 %, the same
    beats)."""
    from dancekit.cli.info import motion_info
    from dancekit.motion.formats import read_tang2018
    from dancekit.pipelines.dual import ComposePipeline

    raw, _ = read_tang2018(sorted(p for p in tang2018_dir.iterdir() if p.is_dir())[0])
    rig = raw.slice(0, 250).with_rotations()  # 10 s, on the rest bone lengths as a generated dance is
    dance = Motion(rig.skeleton, rig.fps, positions=Motion(rig.skeleton, rig.fps, rotations=rig.rotations,
                                                             root_translation=rig.root_translation).to_positions())
    pipe = ComposePipeline.from_pretrained("dual")
    music, infos = {}, {}
    for name in ("d.npz", "d.bvh", "d.glb"):
        write_motion(tmp_path / name, dance)
        m = read_motion(tmp_path / name)
        assert m.skeleton.same_as(dance.skeleton) and m.fps == dance.fps, name
        np.testing.assert_allclose(m.to_positions(), dance.to_positions(), atol=1e-3)
        arr = pipe(m, seed=0).arrangement
        music[name] = (arr.tempo, np.asarray(arr.beat_times))
        info = motion_info(tmp_path / name)
        infos[name] = {k: v for k, v in info.items() if k not in ("format", "stored")}
    assert infos["d.bvh"] == infos["d.npz"] == infos["d.glb"], infos
    tempo, beats = music["d.npz"]
    for name, (t, b) in music.items():
        assert abs(t - tempo) <= 0.01 * tempo, (name, t, tempo)
        assert len(b) == len(beats) and np.abs(b - beats).max() < 1.5 / dance.fps, name


@pytest.mark.shared
def test_the_humanoid_bvh_and_the_smpl_pkl_of_a_dance_compose_its_tempo(tang2018_dir, tmp_path):
    """The humanoid-rig BVH and the AIST++ pkl are the dance retargeted onto other proportions (they read back as
    other skeletons, mapped onto tang2018 by joint role, :func:`dancekit.motion.retarget.map_by_role`: the rig's
    bone directions on tang2018's lengths, at tang2018's size): the music composed from them keeps the tempo of
    the npz's within 1 % (the composer's tempo follows the steps of the ankles, which the rig's other thigh-to-shin
    proportions would turn into sliding feet were its joints' positions copied: 5 % off on this dance)."""
    from dancekit.export.writer import export_motion
    from dancekit.motion.formats import read_tang2018
    from dancekit.pipelines.dual import ComposePipeline

    raw, _ = read_tang2018(sorted(p for p in tang2018_dir.iterdir() if p.is_dir())[0])
    rig = raw.slice(0, 500).with_rotations()  # 20 s
    dance = Motion(rig.skeleton, rig.fps, positions=Motion(rig.skeleton, rig.fps, rotations=rig.rotations,
                                                             root_translation=rig.root_translation).to_positions())
    write_motion(tmp_path / "d.npz", dance)
    export_motion(dance, tmp_path / "h", stem="d", formats=["bvh", "pkl"], bvh_rig="humanoid")
    pipe = ComposePipeline.from_pretrained("dual")
    tempo = pipe(read_motion(tmp_path / "d.npz"), seed=0).arrangement.tempo
    for path in (tmp_path / "h" / "d.bvh", tmp_path / "h" / "d.pkl"):
        m = read_motion(path)
        assert not m.skeleton.same_as(dance.skeleton), path.name  # another skeleton, mapped by role
        t = pipe(m, seed=0).arrangement.tempo
        assert abs(t - tempo) <= 0.01 * tempo, (path.name, t, tempo)


# ------------------------------------------------------------------- one flag per idea
#: Verbs that write files or folders (the rest only print).
WRITING_VERBS = {"features", "prepare", "train", "evaluate", "baselines", "compare", "select-checkpoint", "steering",
                 "score-classifier", "dance", "render", "convert", "compose"}


def _verbs():
    import argparse

    from dancekit.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_verb_that_writes_takes_o_out_and_output():
    verbs = _verbs()
    assert WRITING_VERBS <= set(verbs)
    for verb, p in verbs.items():
        outs = [a for a in p._actions if {"-o", "--out", "--output"} & set(a.option_strings)]
        if verb in WRITING_VERBS:
            assert len(outs) == 1 and {"-o", "--out", "--output"} <= set(outs[0].option_strings), verb
            for flag in ("-o", "--out", "--output"):  # every spelling is the same option
                assert p._option_string_actions[flag] is outs[0], (verb, flag)
        else:
            assert outs == [], verb


def test_seeds_is_a_list_of_seeds_in_every_verb(capsys):
    """``--seeds`` is a seed LIST wherever it appears (``dance`` and the evaluation verbs alike), parsed by one
    function at run time (so a bad list is one error line); ``--seed`` is one integer."""
    from dancekit.cli._options import seed_list, seed_run

    with_seeds = {verb: p for verb, p in _verbs().items() if "--seeds" in p._option_string_actions}
    assert {"dance", "evaluate", "select-checkpoint", "steering"} <= set(with_seeds)
    for verb, p in with_seeds.items():
        action = p._option_string_actions["--seeds"]
        assert action.type is None and action.metavar == "LIST" and action.nargs is None, verb
    assert seed_list("0-2,7") == [0, 1, 2, 7]
    assert seed_run("3-5", verb="evaluate", default=5) == (3, 3)
    assert seed_run(None, verb="evaluate", default=5) == (0, 5)
    assert seed_run("4-4", verb="evaluate", default=5) == (4, 1)
    assert seed_run("2", verb="evaluate", default=5) == (0, 2)  # the old count, deprecated (with a note)
    err = capsys.readouterr().err
    assert "deprecated" in err and "write --seeds 0-1" in err, err
    for verb in ("evaluate", "select-checkpoint", "steering"):
        assert main([verb, "--seeds", "3-1", *_required(verb)]) == 2
        _one_error_line(capsys.readouterr().err, verb, "--seeds 3-1")


def _required(verb: str) -> list[str]:
    return {"evaluate": ["--checkpoint", "x", "--data", "y", "-o", "z"],
            "select-checkpoint": ["--run", "x", "--data", "y"],
            "steering": ["--checkpoint", "x", "--data", "y"]}[verb]


def test_argparse_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["dance", "song.wav", "-o", "x", "--beat-sync", "maybe"])
    assert exc.value.code == 2
    line = _one_error_line(capsys.readouterr().err, "dance", "--beat-sync")
    assert "--help" in line


# ------------------------------------------------------------------- progress into a pipe
def test_dance_into_a_pipe_writes_a_few_progress_lines(tmp_path):
    """stderr a pipe (a log, CI): no carriage-return redraws, at most a progress line every few seconds."""
    song = _wav(tmp_path / "song.wav", 4.0)
    r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "dance", str(song), "-o", str(tmp_path / "o"),
                        "--format", "npz,mp4", "--width", "160", "--height", "120"],
                       capture_output=True, timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 0, r.stderr.decode()
    err = r.stderr.decode()
    assert "\r" not in err
    bars = [ln for ln in err.splitlines() if "%|" in ln]
    assert 1 <= len(bars) <= 4, err
    assert len(err) < 1000, len(err)


def test_train_help_lists_the_set_keys(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    assert "--set keys" in out and "steps=" in out and "batch_size=" in out
    assert "model (revolution):" in out and "d_model=" in out and "model (music2dance):" in out


def test_models_says_what_every_model_is_and_its_genres(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    heads = [ln for ln in out.splitlines() if ln and not ln.startswith(" ")]
    assert heads and all(ln.split(":", 1)[1].strip() for ln in heads), heads  # never "style:" and nothing
    blocks, name = {}, None
    for ln in out.splitlines():
        if ln and not ln.startswith(" "):
            name = ln.split(":", 1)[0].split()[0]
        blocks.setdefault(name, []).append(ln)
    for model in ("music2dance", "revolution"):  # a dance-type condition, genre models
        assert any(ln.startswith("  --genre: auto") and "waltz" in ln for ln in blocks[model]), blocks[model]


def test_render_takes_the_song_a_dance_was_made_for(tmp_path, capsys):
    """A dance of a whole song has 1 + n // hop frames (its last frame at the song's end, so ``duration`` is one
    frame period longer than the song): render plays it with that song; a dance a frame longer is refused."""
    song = _wav(tmp_path / "song.wav", 2.0)
    write_motion(tmp_path / "d.npz", _tang_walk(T=51))  # 2 s at 25 fps: frames 0 .. 50, the last at 2.00 s
    assert main(["render", str(tmp_path / "d.npz"), "--audio", str(song), "-o", str(tmp_path / "d.html"), "-q"]) == 0
    write_motion(tmp_path / "e.npz", _tang_walk(T=53))  # the last frame 0.08 s after the song
    assert main(["render", str(tmp_path / "e.npz"), "--audio", str(song), "-o", str(tmp_path / "e.html")]) == 2
    _one_error_line(capsys.readouterr().err, "render", "shorter than the dance")
