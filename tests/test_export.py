"""RenderOptions / AudioClip validation, the deprecated keywords, layering."""

from __future__ import annotations

import ast
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancekit.errors import ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.render import AudioClip, RenderOptions, render_motion_html, render_motion_mp4

SRC = Path(__file__).resolve().parents[1] / "src" / "dancekit"
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
