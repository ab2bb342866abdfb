"""dancekit.export: every format at once, all or nothing; RenderOptions / AudioClip validation; layering."""

from __future__ import annotations

import ast
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

import dancekit.render
from dancekit.errors import DancekitError, ExternalToolError, ParameterError
from dancekit.export import FORMATS, check_formats, check_output_folder, export_motion
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.formats import read_motion
from dancekit.render import AudioClip, RenderOptions, render_motion_html, render_motion_mp4

SRC = Path(__file__).resolve().parents[2] / "src" / "dancekit"
SMALL = RenderOptions(width=64, height=48)


@pytest.fixture(scope="module")
def motion() -> Motion:
    """Ten frames of the tang2018 rest pose, feet on the floor, the arms swinging a little."""
    sk = get_skeleton("tang2018")
    rest = np.zeros((sk.num_joints, 3))
    for j in sk.topological_order:
        if sk.parents[j] >= 0:
            rest[j] = rest[sk.parents[j]] + sk.offsets[j]
    rest[:, 1] -= rest[:, 1].min()
    pos = np.repeat(rest[None], 10, axis=0)
    pos[:, :, 0] += 2.0 * np.sin(np.arange(10) / 3.0)[:, None]
    return Motion(skeleton=sk, fps=25, positions=pos.astype(np.float32))


@pytest.fixture
def song(tmp_path):
    path = tmp_path / "song.wav"
    sr = 22050
    sf.write(path, (0.3 * np.sin(2 * np.pi * 440 * np.arange(2 * sr) / sr)).astype(np.float32), sr)
    return path


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ---------------------------------------------------------------------- what is written
@pytest.mark.parametrize(
    "formats, names",
    [
        (["npz"], ["s.npz"]),
        ("bvh, npz", ["s.bvh", "s.npz"]),
        (["openpose", "html", "npz", "html"], ["s.html", "s.npz", "s_openpose"]),
        # fbx needs Blender: tests/test_fbx.py
        ([f for f in FORMATS if f != "fbx"], ["s.bvh", "s.glb", "s.html", "s.mp4", "s.npz", "s.pkl", "s_coco17", "s_coco18",
                             "s_openpose"]),
    ],
)
def test_export_writes_exactly_the_requested_files(tmp_path, motion, formats, names):
    out = tmp_path / "out"
    written = export_motion(motion, out, stem="s", formats=formats, options=SMALL)
    assert listing(out) == names  # and no staging folder
    assert [p.parent for p in written] == [out] * len(names)
    assert [p.name for p in written] == [
        f"s_{f}" if f in ("openpose", "coco17", "coco18") else f"s.{f}" for f in check_formats(formats)
    ]
    if "s.npz" in names:
        np.testing.assert_allclose(read_motion(out / "s.npz").positions, motion.positions, atol=1e-5)


def test_export_writes_what_the_renderers_write(tmp_path, motion, song):
    clip = AudioClip(song, start=0.5)
    options = RenderOptions(width=64, height=48, elevation=20.0, title="t")
    export_motion(motion, tmp_path / "out", stem="s", formats=["mp4", "html"], audio=clip, options=options)
    render_motion_mp4(tmp_path / "s.mp4", motion, audio=clip, options=options, progress=False)
    render_motion_html(tmp_path / "s.html", motion, audio=clip, options=options)
    assert (tmp_path / "out" / "s.mp4").read_bytes() == (tmp_path / "s.mp4").read_bytes()
    assert (tmp_path / "out" / "s.html").read_bytes() == (tmp_path / "s.html").read_bytes()


def test_export_replaces_its_files_and_keeps_the_others(tmp_path, motion):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    (out / "s.npz").write_text("old")
    (out / "s_openpose").mkdir()
    (out / "s_openpose" / "stale.json").write_text("{}")
    export_motion(motion, out, stem="s", formats=["npz", "openpose"])
    assert listing(out) == ["keep.txt", "s.npz", "s_openpose"]
    assert (out / "keep.txt").read_text() == "mine"
    assert read_motion(out / "s.npz").num_frames == 10
    assert len(list((out / "s_openpose").glob("*_keypoints.json"))) == 10
    assert not (out / "s_openpose" / "stale.json").exists()


# ---------------------------------------------------------------------- all or nothing
@pytest.mark.parametrize("error", [ExternalToolError("ffmpeg died"), KeyboardInterrupt()])
@pytest.mark.parametrize("existing", [True, False])
def test_a_failure_half_way_leaves_the_folder_as_it_was(tmp_path, motion, monkeypatch, error, existing):
    """The mp4 writer dies after the npz and bvh were written: no file, no staging folder remains."""
    reached = []

    def boom(path, motion, **kwargs):
        reached.append(sorted(p.name for p in Path(path).parent.iterdir()))
        raise error

    monkeypatch.setattr(dancekit.render, "render_motion_mp4", boom)
    out = tmp_path / "a" / "b" / "out"
    if existing:
        out.mkdir(parents=True)
        (out / "keep.txt").write_text("mine")
        (out / "s.npz").write_text("old")
    with pytest.raises(type(error)):
        export_motion(motion, out, stem="s", formats=["npz", "bvh", "mp4", "html"])
    assert reached == [["s.bvh", "s.npz"]]  # the failure came after two complete files
    if existing:
        assert listing(out) == ["keep.txt", "s.npz"] and (out / "s.npz").read_text() == "old"
    else:
        assert listing(tmp_path) == []  # the folders it created are gone too


def test_a_failure_while_moving_into_place_is_rolled_back(tmp_path, motion, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "s.npz").write_text("old npz")
    replace = os.replace

    def interrupted(src, dst):
        if Path(dst) == out / "s.bvh":  # s.npz is already in place
            raise KeyboardInterrupt
        replace(src, dst)

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export_motion(motion, out, stem="s", formats=["npz", "bvh"])
    assert listing(out) == ["s.npz"] and (out / "s.npz").read_text() == "old npz"


def test_bad_arguments_fail_before_anything_is_written(tmp_path, motion):
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match="gif"):
        export_motion(motion, out, stem="s", formats="mp4,gif")
    with pytest.raises(ParameterError, match="choose from"):
        export_motion(motion, out, stem="s", formats=[])
    with pytest.raises(ParameterError, match="'a/b'"):
        export_motion(motion, out, stem="a/b", formats=["npz"])
    with pytest.raises(ParameterError, match="options"):
        export_motion(motion, out, stem="s", formats=["npz"], options={"width": 64})
    assert listing(tmp_path) == []
    (tmp_path / "file.txt").write_text("x")
    for check in (check_output_folder, lambda f: export_motion(motion, f, stem="s", formats=["npz"])):
        with pytest.raises(DancekitError, match="file.txt"):
            check(tmp_path / "file.txt")
        with pytest.raises(DancekitError, match="file.txt"):
            check(tmp_path / "file.txt" / "out")
    assert listing(tmp_path) == ["file.txt"] and (tmp_path / "file.txt").read_text() == "x"
    with pytest.raises(DancekitError, match="/proc/dancekit/out"):  # refused even to root
        check_output_folder("/proc/dancekit/out")
    assert check_output_folder(tmp_path / "new" / "out") == tmp_path / "new" / "out"
    assert listing(tmp_path) == ["file.txt"]  # the check leaves nothing behind


# ---------------------------------------------------------------------- options
@pytest.mark.parametrize(
    "kwargs, named",
    [
        ({"width": 161}, "width"),
        ({"width": 8}, "width"),
        ({"width": True}, "width"),
        ({"width": "640"}, "width"),
        ({"height": 5000}, "height"),
        ({"elevation": 90.0}, "elevation"),
        ({"elevation": math.nan}, "elevation"),
        ({"azimuth": math.inf}, "azimuth"),
        ({"crf": 52}, "crf"),
        ({"crf": 2.5}, "crf"),
        ({"title": 3}, "title"),
    ],
)
def test_render_options_errors_name_the_value(kwargs, named):
    with pytest.raises(ParameterError) as err:
        RenderOptions(**kwargs)
    message = str(err.value)
    assert "\n" not in message and message.startswith(named) and repr(kwargs[named]) in message


@pytest.mark.parametrize(
    "args, named",
    [
        ((None,), "path"),
        ((3,), "path"),
        (("s.wav", -1.0), "start"),
        (("s.wav", math.nan), "start"),
        (("s.wav", 2.0, 2.0), "end"),
        (("s.wav", None, math.inf), "end"),
    ],
)
def test_audio_clip_errors_name_the_value(args, named):
    with pytest.raises(ParameterError) as err:
        AudioClip(*args)
    message = str(err.value)
    assert "\n" not in message and named in message and repr(args[-1]) in message


def test_options_are_frozen_and_normalised():
    opts = RenderOptions(width=np.int64(320), height=240, elevation=np.float32(20), azimuth=10)
    assert (opts.width, opts.elevation, opts.azimuth) == (320, 20.0, 10.0) and type(opts.width) is int
    with pytest.raises(AttributeError):
        opts.width = 100
    clip = AudioClip("song.wav", start=1)
    assert clip.path == Path("song.wav") and clip.start == 1.0 and clip.end is None
    assert AudioClip.of("song.wav") == AudioClip("song.wav") and AudioClip.of(None) is None


def test_the_old_keywords_still_work_with_a_warning(tmp_path, motion, song):
    render_motion_html(
        tmp_path / "new.html", motion, audio=AudioClip(song, 0.5), options=RenderOptions(title="t")
    )
    with pytest.warns(DeprecationWarning, match="audio_path"):
        render_motion_html(tmp_path / "old.html", motion, audio_path=song, audio_start=0.5, title="t")
    assert (tmp_path / "old.html").read_bytes() == (tmp_path / "new.html").read_bytes()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        with pytest.raises(ParameterError, match="width"):
            render_motion_mp4(tmp_path / "x.mp4", motion, width=99)
        with pytest.raises(TypeError, match="width"):
            render_motion_html(tmp_path / "x.html", motion, width=64)  # never an html keyword
    assert listing(tmp_path) == ["new.html", "old.html", "song.wav"]


# ---------------------------------------------------------------------- layering
_ALLOWED = {
    "render": {"render", "motion", "audio", "errors", "_io", "_checks"},
    "export": {"export", "render", "motion", "audio", "errors", "_io"},
}


@pytest.mark.parametrize("package", sorted(_ALLOWED))
def test_package_imports_only_lower_layers(package):
    found = set()
    for path in (SRC / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [
                    f"{node.module}.{a.name}" for a in node.names if node.module == "dancekit"
                ]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                parts = name.split(".")
                if parts[0] == "dancekit" and len(parts) > 1:
                    found.add((parts[1], path.name))
    assert {layer for layer, _ in found} <= _ALLOWED[package], sorted(found)
