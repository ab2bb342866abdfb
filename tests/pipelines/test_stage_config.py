"""The typed stage configuration (dancekit.pipelines.config): one checked dataclass per stage, parsed once per
pipeline load; bad or unknown keys in an embedded model's config.json are one named error of `dancekit dance`;
the layout of the previous release is converted on reading; finish runs the configured list of stages."""

from __future__ import annotations

import copy
import dataclasses
import importlib
import inspect
import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from dancekit.cli.main import main
from dancekit.errors import CheckpointError, ParameterError
from dancekit.pipelines import config as cfgmod
from dancekit.pipelines import stages
from dancekit.pipelines.config import (
    STAGE_NAMES,
    EnergyConfig,
    JitterCapConfig,
    SettleConfig,
    StageConfig,
    checkpoint_settings,
    convert_old_layout,
    read_checkpoint_settings,
)

ASSETS = Path(stages.__file__).resolve().parent.parent / "assets" / "models"
MODELS = ("revolution", "music2dance", "dual")


def _leaves(entry: dict, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """The paths to every value under ``entry`` (a nested dict), tables of genres included."""
    out = []
    for k, v in entry.items():
        if isinstance(v, dict):
            out += _leaves(v, prefix + (k,))
        else:
            out.append(prefix + (k,))
    return out


def _meta(name: str) -> dict:
    return json.loads((ASSETS / name / "config.json").read_text())


# every stage and sampling value of every embedded model, and an unknown key in every entry
VALUE_CASES = [(name, path) for name in MODELS for entry in ("stages", "sampling", "genre_stats")
               for path in _leaves(_meta(name).get(entry, {}), (entry,))]
KEY_CASES = [(name, where) for name in MODELS for where in
             [(), ("config",), ("stages",), ("sampling",), ("genre_stats",)]
             + [("stages", s) for s in _meta(name)["stages"]]
             + ([("sampling", "genres", "chacha")] if name == "music2dance" else [])]


def test_every_embedded_stage_and_sampling_value_is_covered():
    """The cases below reach the embedded entries: every stage entry of each model and its sampling."""
    names = {p[1] for n, p in VALUE_CASES if p[0] == "stages"}
    assert names == {"smooth", "lift_energy", "jitter_cap", "foot_lock", "settle", "reground", "beat_sync"}
    assert len(VALUE_CASES) > 60


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A copy of each embedded model (its config.json is rewritten per case, and restored)."""
    root = tmp_path_factory.mktemp("models")
    for name in MODELS:
        shutil.copytree(ASSETS / name, root / name)
    return root


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    from dancekit.audio import save_wav
    from dancekit.audio.synth import ode_to_joy

    path = tmp_path_factory.mktemp("song") / "ode.wav"
    save_wav(path, ode_to_joy(sr=22050, bpm=120)[: 3 * 22050], sr=22050)
    return path


def _dance_fails(capsys, folder: Path, meta: dict, song: Path, out: Path) -> str:
    """``dancekit dance --model FOLDER`` with ``meta`` as its config.json: the error line (asserted: non-zero exit,
    one line, nothing written)."""
    original = (folder / "config.json").read_text()
    (folder / "config.json").write_text(json.dumps(meta))
    try:
        code = main(["dance", str(song), "-o", str(out), "--model", str(folder), "--quiet", "--format", "npz"])
    finally:
        (folder / "config.json").write_text(original)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.strip().count("\n") == 0 and err.startswith("dancekit dance: error:"), err
    assert not out.exists() or list(out.iterdir()) == []
    return err


def _set(meta: dict, path: tuple[str, ...], value) -> dict:
    meta = copy.deepcopy(meta)
    d = meta
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value
    return meta


@pytest.mark.slow
@pytest.mark.parametrize(("name", "path"), VALUE_CASES, ids=[f"{n}:{'.'.join(p)}" for n, p in VALUE_CASES])
@pytest.mark.parametrize("bad", ["a string", -1])
def test_a_bad_value_anywhere_is_one_line_naming_the_key_and_the_folder(capsys, folders, song, tmp_path, name,
                                                                        path, bad):
    folder = folders / name
    err = _dance_fails(capsys, folder, _set(_meta(name), path, bad), song, tmp_path / "out")
    key = ".".join(path)
    assert key in err and str(folder) in err, err


@pytest.mark.slow
@pytest.mark.parametrize(("name", "where"), KEY_CASES, ids=[f"{n}:{'.'.join(w) or 'top'}" for n, w in KEY_CASES])
def test_an_unknown_key_anywhere_is_one_line_naming_it_and_the_folder(capsys, folders, song, tmp_path, name, where):
    meta = _meta(name)
    d = meta
    for k in where:
        d = d[k]
    d["bogus_key"] = 1
    err = _dance_fails(capsys, folders / name, meta, song, tmp_path / "out")
    assert "bogus_key" in err and str(folders / name) in err, err


def test_the_dataclasses_name_the_key_the_value_and_the_range():
    with pytest.raises(ParameterError, match=r"stages.settle.cutoff_hz must be a number in \[0, inf\) \(Hz\), got -1"):
        SettleConfig(cutoff_hz=-1)
    with pytest.raises(ParameterError, match=r"stages.lift_energy.damp must be a number in \[0, 1\], got 2"):
        EnergyConfig(floor=0.3, damp=2)
    with pytest.raises(ParameterError, match=r"stages.jitter_cap.min_ratio must be a number in \[0, 1\], got 'x'"):
        JitterCapConfig(min_ratio="x")
    with pytest.raises(ParameterError, match="unknown stages"):
        StageConfig(enabled={"warp"})
    assert StageConfig().order() == ("clean_up", "smooth", "lift_energy", "foot_lock", "settle", "beat_sync")


def test_the_stage_configuration_is_parsed_once_per_pipeline_load_and_never_read_while_dancing(song, monkeypatch):
    """Each family parses its checkpoint's settings once when it loads; its dances read no config.json at all
    (the stages take the parsed configuration; before, each dance re-read it about 7 times)."""
    from dancekit.pipelines import load_pipeline

    parsed: list[str] = []
    real = cfgmod.checkpoint_settings

    def counting(meta, *, folder="?", sampling=cfgmod.NoSampling):
        parsed.append(str(folder))
        return real(meta, folder=folder, sampling=sampling)

    for module in ("dance", "revolution", "music2dance", "dual"):  # the base and each family's own loading
        if hasattr(importlib.import_module(f"dancekit.pipelines.{module}"), "checkpoint_settings"):
            monkeypatch.setattr(f"dancekit.pipelines.{module}.checkpoint_settings", counting)
    reads: list[str] = []
    real_read = Path.read_text

    def read_text(self, *args, **kwargs):
        if self.name == "config.json":
            reads.append(str(self))
        return real_read(self, *args, **kwargs)

    monkeypatch.setattr(Path, "read_text", read_text)
    for name in ("music2dance", "dual", "revolution"):
        parsed.clear()
        pipe = load_pipeline(name)
        assert parsed == [str(ASSETS / name)], parsed
        genre = {"revolution": "waltz", "music2dance": "chacha", "dual": None}[name]
        pipe.dances(song, seeds=[0], genre=genre, end=2.0)  # a revolution genre model loads on first use
        reads.clear()
        parsed.clear()
        pipe.dances(song, seeds=[0, 1], genre=genre, end=2.0)
        pipe.dances(song, seeds=[1], end=2.0)
        assert reads == [] and parsed == [], (reads, parsed)


def test_finish_takes_the_result_the_audio_the_configuration_and_a_trace_and_holds_no_closure():
    assert list(inspect.signature(stages.finish).parameters) == ["result", "audio", "config", "trace"]
    comprehensions = {"<listcomp>", "<genexpr>", "<setcomp>", "<dictcomp>"}
    nested = [c.co_name for c in stages.finish.__code__.co_consts
              if inspect.iscode(c) and c.co_name not in comprehensions]
    assert nested == []  # no closures: the stages are the named functions of stages.STAGES
    assert set(stages.STAGES) == set(STAGE_NAMES)


def test_switching_a_stage_off_removes_it_and_what_belongs_to_it():
    config = read_checkpoint_settings(ASSETS / "revolution").stages
    assert config.order() == ("clean_up", "smooth", "lift_energy", "jitter_cap", "foot_lock", "settle", "reground",
                              "beat_sync")
    assert config.switched(foot_lock=False).order() == ("clean_up", "smooth", "lift_energy", "beat_sync")
    assert config.switched(cleanup=False).order() == ("beat_sync",)
    assert config.switched(cleanup=False, smooth=True, beat_sync=False).order() == ("smooth",)


# the stage entries of the previous release (as the embedded music2dance and dual carried them), which a user's
# checkpoint written by it still has
OLD_MUSIC2DANCE = {
    "sampling": {"temperature": 0.8, "noise_correlation": 0.95, "smooth_sigma": 2.0},
    "genre_sampling": {"chacha": {"genre_scale": 12.0, "temperature": 1.0, "noise_correlation": 0.9,
                                  "smooth_sigma": 0.0},
                       "tango": {"genre_scale": 12.0, "temperature": 1.0, "noise_correlation": 0.9,
                                 "smooth_sigma": 0.0}},
    "smoothing": {"genre_targets": {"chacha": 0.197, "tango": 0.284}},
    "beat_sync": {"max_rate_change": 0.4, "pair_rate_change": 0.38, "between_tolerance": 0.08, "max_shift": 1.0},
    "jitter_cap": {"genre_jitter": {"waltz": 0.026, "rumba": 0.05, "chacha": 0.14, "tango": 0.22}, "jitter_cap": 1.0,
                   "jitter_cap_min_ratio": 0.7, "to_end": True}}
OLD_DUAL = {
    "smooth_frames": 13, "root_6d_decode": "procrustes",
    "jitter_cap": {"genre_jitter": {"waltz": 0.026, "rumba": 0.05, "chacha": 0.14, "tango": 0.22}, "jitter_cap": 1.0,
                   "jitter_cap_min_ratio": 0.7, "to_end": True},
    "beat_min_gap": 0.35, "beat_threshold": 0.5,
    "foot_lock": {"speed_on": 1.0, "speed_off": 1.4, "height_on": 0.08, "height_off": 0.11, "max_drift_m": 0.6,
                  "blend_s": 0.48, "min_hold_s": 0.32},
    "beat_sync": {"max_rate_change": 0.3, "pair_rate_change": 0.28, "step_pairing": False},
    "energy": {"fraction": 0.8, "band_hz": 1.0, "damp": 1.0,
               "genre_energy": {"waltz": 0.444, "rumba": 0.586, "chacha": 0.787, "tango": 0.911}}}


@pytest.mark.parametrize(("name", "old"), [("music2dance", OLD_MUSIC2DANCE), ("dual", OLD_DUAL)])
def test_the_old_layout_is_converted_to_the_embedded_settings_with_one_warning(tmp_path, caplog, name, old):
    """A checkpoint of the previous release (the settings the embedded model carried then) reads as the migrated
    embedded model: the same settings, said once per folder in one warning line."""
    meta = {k: v for k, v in _meta(name).items() if k not in ("stages", "sampling", "genre_stats")}
    folder = tmp_path / name
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({**meta, **old}))
    sampling = cfgmod.SAMPLING_CONFIGS[name]
    with caplog.at_level(logging.WARNING, logger="dancekit.checkpoints"):
        got = read_checkpoint_settings(folder)
        read_checkpoint_settings(folder)
    lines = [r.getMessage() for r in caplog.records if str(folder) in r.getMessage()]
    assert len(lines) == 1 and "converting" in lines[0] and "\n" not in lines[0]
    want = checkpoint_settings(_meta(name), folder=ASSETS / name, sampling=sampling)
    assert got.sampling == want.sampling
    # the same stages; the embedded tables hold all four genres where the old entries held those they used; the
    # embedded music2dance's foot lock got its "plant" entry after that release (issue 44): the old one has none
    for stage in STAGE_NAMES:
        if name == "music2dance" and stage == "foot_lock":
            assert got.stages.foot_lock == dataclasses.replace(want.stages.foot_lock, plant=False)
            assert want.stages.foot_lock.plant
            continue
        assert getattr(got.stages, stage) == getattr(want.stages, stage), stage
    for table in ("jitter", "energy", "planted_share", "smoothing"):
        old_table, new_table = got.stages.genre_stats.table(table), want.stages.genre_stats.table(table)
        assert old_table.items() <= new_table.items(), table


def test_an_old_entry_mixed_with_the_new_layout_is_refused(tmp_path):
    with pytest.raises(CheckpointError, match="mixes the old stage entries"):
        convert_old_layout({"model": "dual", "stages": {}, "smooth_frames": 3}, folder="m")


def test_each_embedded_model_dances_with_its_own_switches_bit_for_bit_through_the_cli(tmp_path, song):
    """The CLI's own stage run (``--smooth on``: the stages after the pipeline, with its configuration) equals
    the pipeline's dance, so both paths read one configuration. (Not dual: with ``cleanup=False`` its pipeline
    reads no genre from the music, so the CLI's own run has no genre posterior for the energy floor and the jitter
    cap; kept as it was.)"""
    from dancekit.motion import read_motion

    for name in ("revolution", "music2dance"):
        outs = []
        for flags in ((), ("--smooth", "on")):
            out = tmp_path / f"{name}{len(flags)}"
            assert main(["dance", str(song), "-o", str(out), "--model", name, "--quiet", "--format", "npz",
                         *flags]) == 0
            outs.append(read_motion(out / "ode.npz").positions)
        np.testing.assert_array_equal(*outs)
