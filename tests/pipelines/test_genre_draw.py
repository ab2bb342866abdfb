"""The seed draws the genre model for ``genre="auto"`` (issue 15, third attempt): :class:`GenreDraw`,
:func:`draw_genre` and :meth:`RevolutionPipeline.dances` with a draw (deterministic per seed, a batch equals
one call per seed, τ → 0 is the most likely genre bit-identically, a forced genre is not drawn); the fourth
attempt's ``genre_min_ratio`` ρ (only genres with p ≥ ρ · max p are drawn; ρ = 0 is the third attempt's draw)."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
import torch

from dancekit.audio import save_wav
from dancekit.audio.synth import ode_to_joy
from dancekit.checkpoints import declare_components, read_config, save_pretrained
from dancekit.errors import CheckpointError, ParameterError
from dancekit.models.revolution import RevolutionConfig, RevolutionModel
from dancekit.motion import get_skeleton
from dancekit.pipelines.config import (
    GenreStats,
    JitterCapConfig,
    RevolutionSampling,
    StageConfig,
    checkpoint_settings,
)
from dancekit.pipelines.revolution import (
    GenreDraw,
    RevolutionPipeline,
    draw_genre,
    genre_draw_from_sampling,
    genre_options,
)
from dancekit.pipelines.stages import jitter_cap_for


def genre_draw_from_meta(meta: dict, folder: str = "?") -> GenreDraw:
    """The genre draw a checkpoint's config.json gives (parsed as the pipeline parses it)."""
    settings = checkpoint_settings({"model": "revolution", **meta}, folder=folder, sampling=RevolutionSampling)
    return genre_draw_from_sampling(settings.sampling, settings.stages.genre_stats.table("jitter"), folder=folder)

PROBS = {"waltz": 0.6, "rumba": 0.3, "chacha": 0.1}


def frequencies(probs, draw, n=4000):
    counts: dict = {}
    for seed in range(1, n + 1):
        g, _ = draw_genre(probs, seed=seed, draw=draw)
        counts[g] = counts.get(g, 0) + 1
    return {g: c / n for g, c in counts.items()}


def test_the_draw_follows_the_tempered_posterior():
    # τ = 0.5 squares the posterior: 0.36, 0.09, 0.01 of 0.46 (worked by hand)
    f = frequencies(PROBS, GenreDraw(temperature=0.5))
    for g, q in {"waltz": 0.36 / 0.46, "rumba": 0.09 / 0.46, "chacha": 0.01 / 0.46}.items():
        assert f.get(g, 0.0) == pytest.approx(q, abs=0.025), (g, f)
    # τ = 1: the posterior itself; w = 0.25: the model alone a quarter of the time, the genres share 0.75
    f = frequencies(PROBS, GenreDraw(temperature=1.0, alone=0.25))
    for g, q in {"waltz": 0.45, "rumba": 0.225, "chacha": 0.075, None: 0.25}.items():
        assert f.get(g, 0.0) == pytest.approx(q, abs=0.025), (g, f)
    # the probability reported with the draw is the option's
    q = draw_genre(PROBS, seed=5, draw=GenreDraw(temperature=1.0, alone=0.25))[1]
    assert min(abs(q - v) for v in (0.45, 0.225, 0.075, 0.25)) < 1e-12


def test_the_draw_is_deterministic_per_seed_and_seed_0_keeps_the_most_likely_genre():
    draw = GenreDraw(temperature=2.0)
    assert [draw_genre(PROBS, seed=s, draw=draw) for s in range(50)] == \
        [draw_genre(PROBS, seed=s, draw=draw) for s in range(50)]
    assert len({draw_genre(PROBS, seed=s, draw=draw)[0] for s in range(1, 50)}) == 3
    assert draw_genre(PROBS, seed=0, draw=draw) == ("waltz", None)
    assert draw_genre(PROBS, seed=0, draw=GenreDraw(temperature=2.0, seed0=True))[1] is not None
    assert draw_genre({}, seed=3, draw=draw) == (None, None)
    assert draw_genre(PROBS, seed=-7, draw=draw) == draw_genre(PROBS, seed=-7, draw=draw)  # negative seeds too


def test_a_vanishing_temperature_is_the_most_likely_genre():
    for seed in range(1, 200):
        assert draw_genre(PROBS, seed=seed, draw=GenreDraw(temperature=1e-6))[0] == "waltz"
        assert draw_genre(PROBS, seed=seed, draw=GenreDraw())[0] == "waltz"


def test_bad_settings_are_named_errors():
    with pytest.raises(ParameterError, match="genre_temperature"):
        GenreDraw(temperature=-1.0)
    with pytest.raises(ParameterError, match="genre_alone"):
        GenreDraw(alone=1.0)
    assert genre_draw_from_meta({}) == GenreDraw()
    assert genre_draw_from_meta({"sampling": {"phrase_s": 3.0, "genre_temperature": 2, "genre_alone": 0.1,
                                              "genre_draw_seed0": True}}) == GenreDraw(2.0, 0.1, True)
    for bad in ({"genre_temperature": "hot"}, {"genre_temperature": float("nan")}, {"genre_alone": 1.5},
                {"genre_draw_seed0": "yes"}):
        with pytest.raises(CheckpointError, match="ckpt: config.json: sampling.genre_"):
            genre_draw_from_meta({"sampling": bad}, folder="ckpt")


# ---- the pipeline: tiny untrained models with two genre models ------------------------------------------------


def tiny(seed: int) -> RevolutionModel:
    torch.manual_seed(seed)
    return RevolutionModel(RevolutionConfig(d_model=16, n_heads=2, d_ff=32, decoder_hidden=16))


@pytest.fixture(scope="module")
def parent(tmp_path_factory):
    skel = get_skeleton("tang2018")
    rest = np.zeros((skel.num_joints, 3))
    for j in skel.topological_order:
        if skel.parents[j] >= 0:
            rest[j] = rest[skel.parents[j]] + skel.offsets[j]
    stats = {"music_mean": np.zeros(438, np.float32), "music_std": np.ones(438, np.float32),
             "dance_mean": np.concatenate([(rest - rest[skel.root]).ravel(), [0.0, 0.0, 95.0]]).astype(np.float32),
             "dance_std": np.full(72, 5.0, np.float32)}
    meta = {"fps": 25.0, "preset": "revolution", "representation": "positions3d", "hop_length": 512,
            "skeleton": skel.to_dict(), "genres": ["waltz", "rumba", "chacha", "tango"]}
    root = tmp_path_factory.mktemp("draw") / "parent"
    model = tiny(0)
    save_pretrained(root, model, model.config, stats=stats, extra=meta)
    for k, g in enumerate(("waltz", "rumba")):
        m = tiny(k + 1)
        save_pretrained(root / "genres" / g, m, m.config, stats=stats, extra=meta)
    declare_components(root, {"genres": {"waltz": "genres/waltz", "rumba": "genres/rumba"}})
    return root


@pytest.fixture(scope="module")
def song(tmp_path_factory):
    path = tmp_path_factory.mktemp("song") / "ode.wav"
    save_wav(path, ode_to_joy(sr=22050, bpm=120)[: 3 * 22050], sr=22050)
    return path


def pipeline(parent, monkeypatch, draw: GenreDraw, cap: JitterCapConfig | None = None) -> RevolutionPipeline:
    pipe = RevolutionPipeline.from_pretrained(parent)
    pipe.genre_draw = draw
    if cap is not None:  # the jitter cap of the stages, over the real jitters of TABLE
        stages = dataclasses.replace(pipe.settings.stages, jitter_cap=cap, genre_stats=GenreStats(jitter=TABLE))
        pipe.settings = dataclasses.replace(pipe.settings, stages=stages)
    # the classifier's reading (a tiny folder has none): a song between waltz and rumba
    monkeypatch.setattr(pipe, "read_genre", lambda *a, **k: {"waltz": 0.55, "rumba": 0.45})
    return pipe


SEEDS = [0, 1, 2, 3, 4, 5, 6, 7]


def test_a_batch_of_seeds_equals_one_call_per_seed_and_says_what_was_drawn(parent, song, monkeypatch):
    pipe = pipeline(parent, monkeypatch, GenreDraw(temperature=1.0, alone=0.2))
    batch = pipe.dances(song, seeds=SEEDS, end=2.0)
    danced = [r.genre for r in batch]
    assert len(set(danced)) >= 2, danced  # the seeds dance different genre models
    assert danced[0] == "waltz" and batch[0].genre_drawn_p is None  # seed 0: the most likely genre
    for seed, res in zip(SEEDS, batch):
        alone = pipe(song, seed=seed, end=2.0)
        assert (alone.genre, alone.genre_drawn_p, alone.danced_by) == (res.genre, res.genre_drawn_p, res.danced_by)
        np.testing.assert_allclose(res.motion.to_positions(), alone.motion.to_positions(), atol=1e-3)
        if seed:
            what = f"as {res.genre}" if res.genre else "by the model alone"
            assert res.summary().startswith(f"{what} (drawn by seed {seed}, p = {res.genre_drawn_p:.2f})")
        if res.genre is not None:  # the drawn genre's own model danced it
            forced = pipe(song, seed=seed, end=2.0, genre=res.genre)
            np.testing.assert_allclose(res.motion.to_positions(), forced.motion.to_positions(), atol=1e-3)


def test_seeds_shared_by_processes_are_the_same_dances_bit_for_bit(parent, song, monkeypatch, tmp_path):
    """``workers=3``: the seeds split over three processes (forked on Linux) give every dance, its genre draw and
    its notes exactly as one process does, in seed order."""
    import os
    import sys

    pipe = pipeline(parent, monkeypatch, GenreDraw(temperature=1.0, alone=0.2))
    one = pipe.dances(song, seeds=SEEDS, end=2.0, workers=1)
    pids = tmp_path / "pids"
    real = type(pipe).generate_batch

    def generate_batch(self, *a, **k):
        with open(pids, "a") as fh:
            fh.write(f"{os.getpid()}\n")
        return real(self, *a, **k)

    monkeypatch.setattr(type(pipe), "generate_batch", generate_batch)
    three = pipe.dances(song, seeds=SEEDS, end=2.0, workers=3)
    assert [r.seed for r in three] == SEEDS
    for a, b in zip(one, three):
        assert (a.genre, a.genre_drawn_p, a.danced_by, a.notes) == (b.genre, b.genre_drawn_p, b.danced_by, b.notes)
        np.testing.assert_array_equal(a.motion.to_positions(), b.motion.to_positions())
    if sys.platform.startswith("linux"):
        assert len(set(pids.read_text().split())) == 3  # three processes generated
    with pytest.raises(ParameterError, match="workers"):
        pipe.dances(song, seeds=SEEDS, end=2.0, workers=0)


def test_a_vanishing_temperature_is_todays_dance_bit_for_bit(parent, song, monkeypatch):
    today = pipeline(parent, monkeypatch, GenreDraw()).dances(song, seeds=SEEDS, end=2.0)
    cold = pipeline(parent, monkeypatch, GenreDraw(temperature=1e-6)).dances(song, seeds=SEEDS, end=2.0)
    for a, b in zip(today, cold):
        assert a.genre == b.genre == "waltz"
        np.testing.assert_array_equal(a.motion.to_positions(), b.motion.to_positions())


def test_a_forced_genre_is_not_drawn(parent, song, monkeypatch):
    pipe = pipeline(parent, monkeypatch, GenreDraw(temperature=5.0, alone=0.5))
    for res in pipe.dances(song, seeds=SEEDS, end=2.0, genre="rumba"):
        assert res.genre == "rumba" and res.genre_drawn_p is None
    assert all(r.genre is None for r in pipe.dances(song, seeds=SEEDS, end=2.0, genre="none"))


def test_the_checkpoint_entry_is_read_and_a_bad_one_refused(parent, tmp_path):
    folder = tmp_path / "p"
    shutil.copytree(parent, folder)
    meta = read_config(folder)
    meta["sampling"] = {"genre_temperature": 1.5, "genre_alone": 0.1}
    (folder / "config.json").write_text(json.dumps(meta))
    assert RevolutionPipeline.from_pretrained(folder).genre_draw == GenreDraw(1.5, 0.1)
    meta["sampling"] = {"genre_temperature": -2}
    (folder / "config.json").write_text(json.dumps(meta))
    with pytest.raises(CheckpointError, match="config.json.*genre_temperature"):
        RevolutionPipeline.from_pretrained(folder)


# ---- the fourth attempt: only the song's plausible genres are drawn (``genre_min_ratio`` ρ) --------------------

FOUR = {"waltz": 0.40, "rumba": 0.30, "chacha": 0.20, "tango": 0.10}


def variety3_draw(probs, *, seed, temperature, alone):
    """The third attempt's draw, written out again: q ∝ p^(1/τ) over every genre, times 1 − w, the model alone
    last with w; one uniform number from the (stream, seed) generator, inverted through the cumulative sum."""
    names = list(probs)
    weights = [probs[g] ** (1.0 / temperature) for g in names]
    q = [v / sum(weights) * (1.0 - alone) for v in weights] + ([alone] if alone > 0 else [])
    keys = names + ([None] if alone > 0 else [])
    u = np.random.default_rng([0x67656E72, seed]).random()
    acc = 0.0
    for key, v in zip(keys, q):
        acc += v
        if u * sum(q) < acc:
            return key
    return keys[-1]


def test_only_plausible_genres_are_candidates_worked_by_hand():
    # ρ = 0.7: the threshold is 0.7 · 0.40 = 0.28, so waltz and rumba; τ = 1: 0.40 / 0.70 and 0.30 / 0.70
    opts = genre_options(FOUR, GenreDraw(temperature=1.0, min_ratio=0.7))
    assert opts == pytest.approx({"waltz": 4 / 7, "rumba": 3 / 7, "chacha": 0.0, "tango": 0.0})
    # ρ = 0.45: threshold 0.18, so tango (0.10) drops; τ = 2: √0.4, √0.3, √0.2 over their sum, times 1 − w
    opts = genre_options(FOUR, GenreDraw(temperature=2.0, alone=0.25, min_ratio=0.45))
    root = {"waltz": 0.6324555, "rumba": 0.5477226, "chacha": 0.4472136}
    total = sum(root.values())
    want = {g: 0.75 * v / total for g, v in root.items()} | {"tango": 0.0, None: 0.25}
    assert opts == pytest.approx(want, abs=1e-6)
    f = frequencies(FOUR, GenreDraw(temperature=2.0, alone=0.25, min_ratio=0.45))
    assert "tango" not in f
    for g, q in want.items():
        assert f.get(g, 0.0) == pytest.approx(q, abs=0.025), (g, f)
    # ρ = 1: the most likely genre only (or the model alone)
    assert set(frequencies(FOUR, GenreDraw(temperature=2.0, alone=0.25, min_ratio=1.0))) == {"waltz", None}
    assert set(frequencies(FOUR, GenreDraw(temperature=2.0, min_ratio=1.0))) == {"waltz"}


def test_rho_0_is_the_third_attempts_draw():
    for tau, w in ((1.0, 0.0), (2.0, 0.25), (0.5, 0.1)):
        for seed in range(1, 400):
            got = draw_genre(FOUR, seed=seed, draw=GenreDraw(temperature=tau, alone=w, min_ratio=0.0))[0]
            assert got == variety3_draw(FOUR, seed=seed, temperature=tau, alone=w), (tau, w, seed)


def test_a_bad_min_ratio_is_a_named_error(parent, tmp_path):
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ParameterError, match="genre_min_ratio"):
            GenreDraw(temperature=1.0, min_ratio=bad)
    assert genre_draw_from_meta({"sampling": {"genre_temperature": 2, "genre_min_ratio": 0.7}}) == \
        GenreDraw(2.0, 0.0, False, 0.7)
    folder = tmp_path / "p"
    shutil.copytree(parent, folder)
    meta = read_config(folder)
    for bad, says in ((1.2, r"sampling.genre_min_ratio must be a number in \[0, 1\], got 1.2"),
                      ("most", "sampling.genre_min_ratio must be a number in .*, got 'most'")):
        meta["sampling"] = {"genre_temperature": 1.0, "genre_min_ratio": bad}
        (folder / "config.json").write_text(json.dumps(meta))
        with pytest.raises(CheckpointError, match=f"{folder}: config.json: {says}"):
            RevolutionPipeline.from_pretrained(folder)


def test_an_implausible_genre_is_never_danced(parent, song, monkeypatch):
    # the posterior is waltz 0.55, rumba 0.45: rumba is 0.82 of waltz, so ρ = 0.9 leaves waltz alone and every
    # seed dances today's dance bit for bit; ρ = 0.8 lets rumba back in
    today = pipeline(parent, monkeypatch, GenreDraw()).dances(song, seeds=SEEDS, end=2.0)
    strict = pipeline(parent, monkeypatch, GenreDraw(temperature=1.0, min_ratio=0.9)).dances(song, seeds=SEEDS, end=2.0)
    for a, b in zip(today, strict):
        assert b.genre == "waltz"
        np.testing.assert_array_equal(a.motion.to_positions(), b.motion.to_positions())
    loose = pipeline(parent, monkeypatch, GenreDraw(temperature=1.0, min_ratio=0.8)).dances(song, seeds=SEEDS, end=2.0)
    assert {r.genre for r in loose} == {"waltz", "rumba"}


# ---- the fifth attempt: a drawn genre keeps its steps, not its tremor (``genre_jitter``, ``jitter_cap``,
# ``genre_max_jitter``) -------------------------------------------------------------------------------------------

TABLE = (("waltz", 0.026), ("rumba", 0.05), ("chacha", 0.14), ("tango", 0.22))


def jitter_cap(probs, *, genre, cap: JitterCapConfig | None):
    """The stages' cap (m/s) of a dance of ``genre`` for a song read as ``probs``, over TABLE."""
    from dancekit.motion import Motion
    from dancekit.pipelines.base import DanceResult

    m = Motion(skeleton=get_skeleton("tang2018"), fps=25.0, positions=np.zeros((3, 23, 3), np.float32))
    res = DanceResult(motion=m, model="m", seed=1, genre=genre, genre_probs=probs)
    return jitter_cap_for(res, cap, GenreStats(jitter=TABLE))


def test_the_jitter_cap_is_the_smallest_real_jitter_of_the_plausible_genres_worked_by_hand():
    cap = JitterCapConfig(scale=0.8)
    # FOUR: max 0.40, plausible (≥ 0.20): waltz, rumba, chacha; the smallest real jitter is waltz's 0.026
    assert jitter_cap(FOUR, genre="tango", cap=cap) == pytest.approx(0.8 * 0.026)
    assert jitter_cap(FOUR, genre=None, cap=cap) == pytest.approx(0.8 * 0.026)  # the model alone too
    assert jitter_cap(FOUR, genre="waltz", cap=cap) is None  # the most likely genre is left as it is
    assert jitter_cap(FOUR, genre="waltz", cap=JitterCapConfig(scale=0.8, all=True)) == pytest.approx(0.8 * 0.026)
    # a song read as cha-cha / tango: waltz (0.10 < 0.5 · 0.45) is not plausible, the cap is cha-cha's 0.14
    chacha = {"waltz": 0.10, "rumba": 0.10, "chacha": 0.45, "tango": 0.35}
    assert jitter_cap(chacha, genre="tango", cap=cap) == pytest.approx(0.8 * 0.14)
    assert jitter_cap(chacha, genre="tango", cap=JitterCapConfig(scale=1.0, min_ratio=0.2)) == pytest.approx(0.026)
    assert jitter_cap({}, genre=None, cap=cap) is None
    assert jitter_cap({}, genre="tango", cap=cap) is None  # a genre asked for by name: only with "named"
    assert jitter_cap({}, genre="tango", cap=JitterCapConfig(scale=0.8, named=True)) == pytest.approx(0.8 * 0.22)
    assert jitter_cap(FOUR, genre="tango", cap=None) is None  # no cap


def test_a_genre_far_jerkier_than_the_most_likely_one_is_not_drawn_worked_by_hand():
    # most likely waltz (0.026): k = 2 keeps rumba (0.05 ≤ 0.052) and drops cha-cha and tango; τ = 1 over 0.7
    opts = genre_options(FOUR, GenreDraw(temperature=1.0, genre_jitter=TABLE, max_jitter=2.0))
    assert opts == pytest.approx({"waltz": 4 / 7, "rumba": 3 / 7, "chacha": 0.0, "tango": 0.0})
    # k = 1.9 drops rumba too; the model alone keeps its w
    opts = genre_options(FOUR, GenreDraw(temperature=1.0, alone=0.25, genre_jitter=TABLE, max_jitter=1.9))
    assert opts == pytest.approx({"waltz": 0.75, "rumba": 0.0, "chacha": 0.0, "tango": 0.0, None: 0.25})
    # most likely cha-cha (0.14): tango is 1.57×, kept with k = 2; waltz and rumba are calmer, always kept
    chacha = {"waltz": 0.10, "rumba": 0.10, "chacha": 0.45, "tango": 0.35}
    opts = genre_options(chacha, GenreDraw(temperature=1.0, genre_jitter=TABLE, max_jitter=2.0))
    assert opts == pytest.approx(chacha)
    assert "tango" not in frequencies(FOUR, GenreDraw(temperature=2.0, alone=0.25, genre_jitter=TABLE, max_jitter=2.0))


def test_bad_jitter_entries_are_named_errors():
    for kwargs, says in (({"max_jitter": 2.0}, "genre_max_jitter needs a genre_stats.jitter table"),
                         ({"genre_jitter": (("waltz", -0.1),)}, "genre_jitter must map")):
        with pytest.raises(ParameterError, match=says):
            GenreDraw(**kwargs)
    for kwargs, says in (({"scale": -1.0}, "stages.jitter_cap.scale must be"),
                         ({"min_ratio": 1.5}, "stages.jitter_cap.min_ratio"),
                         ({"all": "yes"}, "stages.jitter_cap.all")):
        with pytest.raises(ParameterError, match=says):
            JitterCapConfig(**kwargs)
    with pytest.raises(ParameterError, match="stages.jitter_cap needs a genre_stats.jitter table"):
        StageConfig(jitter_cap=JitterCapConfig())
    # the old layout (the cap inside "sampling") converted: the draw keeps its limit, the stages get the cap
    spec = {"genre_temperature": 2, "genre_jitter": dict(TABLE), "jitter_cap": 0.9, "genre_max_jitter": 2,
            "jitter_cap_min_ratio": 0.4, "jitter_cap_all": True}
    assert genre_draw_from_meta({"sampling": spec}) == GenreDraw(2.0, genre_jitter=TABLE, max_jitter=2.0)
    settings = checkpoint_settings({"model": "revolution", "sampling": spec}, sampling=RevolutionSampling)
    assert settings.stages.jitter_cap == JitterCapConfig(scale=0.9, min_ratio=0.4, all=True)
    for bad in ({"jitter_cap": 1.0}, {"genre_jitter": [0.1]}, {"genre_jitter": {"waltz": "calm"}},
                {"genre_jitter": dict(TABLE), "jitter_cap": "low"}):
        with pytest.raises(CheckpointError, match="ckpt: config.json: .*jitter"):
            genre_draw_from_meta({"sampling": bad}, folder="ckpt")


def jitter_m_s(motion) -> float:
    """The guard's jitter (m/s), from the metrics module (not the stage's own sums)."""
    from dancekit.metrics import stability

    return stability.jitter(motion.to_positions(), fps=motion.fps, skeleton=motion.skeleton)["speed_residual"]


def test_a_drawn_dance_is_capped_and_the_most_likely_one_left_alone(parent, song, monkeypatch):
    free = GenreDraw(temperature=1.0, alone=0.2, genre_jitter=TABLE)
    # a cap of 0.1 × 0.026 m/s is under every tiny model's dance (0.007-0.03 m/s after the smoothing stage)
    before = pipeline(parent, monkeypatch, free).dances(song, seeds=SEEDS, beat_sync=False)
    after = pipeline(parent, monkeypatch, free, JitterCapConfig(scale=0.1)).dances(song, seeds=SEEDS, beat_sync=False)
    drawn = 0
    for a, b in zip(before, after):
        assert a.genre == b.genre
        if b.genre == "waltz":  # the song's most likely genre: not capped, bit for bit
            np.testing.assert_array_equal(a.motion.to_positions(), b.motion.to_positions())
            assert not any("calmed" in n for n in b.notes)
            continue
        drawn += 1
        assert jitter_m_s(a.motion) > 0.1 * 0.026
        assert jitter_m_s(b.motion) < jitter_m_s(a.motion)
        assert any("calmed to the song's genres" in n for n in b.notes), b.notes
        # bones keep their lengths through the low-pass
        p = b.motion.to_positions()
        sk = b.motion.skeleton
        for j in range(sk.num_joints):
            if sk.parents[j] >= 0:
                length = np.linalg.norm(p[:, j] - p[:, sk.parents[j]], axis=-1)
                np.testing.assert_allclose(length, length[0], rtol=1e-4)
    assert drawn >= 2
    every = pipeline(parent, monkeypatch, free, JitterCapConfig(scale=0.1, all=True)).dances(song, seeds=[0],
                                                                                           beat_sync=False)
    assert jitter_m_s(every[0].motion) < jitter_m_s(before[0].motion)


def test_the_cutoff_brings_the_jitter_under_the_cap():
    from dancekit.motion.filters import fir_lowpass, lowpass_kernel
    from dancekit.motion.jitter import CAP_CUTOFFS_HZ, jitter_cutoff

    skel = get_skeleton("tang2018")
    rng = np.random.default_rng(0)
    t = np.arange(500) / 25.0
    rest = np.zeros((skel.num_joints, 3))
    for j in skel.topological_order:
        if skel.parents[j] >= 0:
            rest[j] = rest[skel.parents[j]] + skel.offsets[j]
    sway = 10.0 * np.sin(2 * np.pi * 0.7 * t)[:, None, None] * rng.normal(size=(1, skel.num_joints, 3))
    tremor = 1.5 * rng.normal(size=(len(t), skel.num_joints, 3))
    p = rest[None] + sway + tremor
    p[:, skel.root] = rest[skel.root]

    def metric(x):
        from dancekit.metrics import stability

        return stability.jitter(x, fps=25.0, skeleton=skel)["speed_residual"]

    base = metric(p)
    for cap in (0.8 * base, 0.3 * base, 0.1 * base):
        c = jitter_cutoff(p, skeleton=skel, fps=25.0, max_jitter=cap)
        assert c in CAP_CUTOFFS_HZ
        q = fir_lowpass(p, lowpass_kernel(c, fps=25.0))
        assert metric(q) <= cap + 1e-12  # the stage measures as the metrics module does
        higher = [h for h in CAP_CUTOFFS_HZ if h > c]
        if higher:  # the highest cut-off that does: the next one up does not
            assert metric(fir_lowpass(p, lowpass_kernel(higher[-1], fps=25.0))) > cap
    assert jitter_cutoff(p, skeleton=skel, fps=25.0, max_jitter=2 * base) == 0.0
    assert jitter_cutoff(p, skeleton=skel, fps=25.0, max_jitter=1e-9) == CAP_CUTOFFS_HZ[-1]
    with pytest.raises(ParameterError, match="max_jitter"):
        jitter_cutoff(p, skeleton=skel, fps=25.0, max_jitter=0.0)


def test_the_draw_and_the_genre_stats_judge_a_genre_jitter_table_alike():
    from dancekit.pipelines.stages import genre_jitter_table

    assert genre_jitter_table({"waltz": 0.026, "tango": 1}) == {"waltz": 0.026, "tango": 1.0}
    assert genre_jitter_table((("rumba", 0.05),)) == {"rumba": 0.05}
    bad = ({"waltz": 0.0}, {"waltz": -0.1}, {"waltz": True}, {"waltz": float("inf")}, {"waltz": float("nan")},
           {"waltz": "calm"}, {3: 0.1}, {})
    for table in bad:
        with pytest.raises(ParameterError, match="genre_jitter must map genres to positive m/s"):
            genre_jitter_table(table)
        if table:  # an empty table is "no table" for the draw (its caps then say they need one)
            with pytest.raises(ParameterError, match="genre_jitter must map"):
                GenreDraw(genre_jitter=tuple(table.items()))
        if table:  # the genre statistics refuse it too (an empty table is no table)
            with pytest.raises(ParameterError, match="genre_stats.jitter"):
                GenreStats(jitter=table)
    assert GenreStats(jitter={"waltz": 0.026, "rumba": 0.05}).table("jitter") == {"waltz": 0.026, "rumba": 0.05}


def test_a_spread_draw_is_the_golden_ratio_sequence_worked_independently():
    from decimal import Decimal, getcontext

    from dancekit.pipelines.revolution import draw_uniform

    getcontext().prec = 60
    g = (Decimal(5).sqrt() - 1) / 2  # 0.6180339887…, to 60 digits
    for seed in (0, 1, 2, 3, 4, 17, 10**6, 2**40 + 3):
        exact = (seed * g) % 1
        # the 64-bit step is g within 2^-65, so seed k may differ from the exact fraction by k · 2^-65 (+ rounding)
        assert draw_uniform(seed, spread=True) == pytest.approx(float(exact), abs=(seed + 2) * 2.0**-64), seed
    # seeds 1-4 by hand: 0.618, 0.236, 0.854, 0.472
    assert [round(draw_uniform(s, spread=True), 3) for s in range(1, 5)] == [0.618, 0.236, 0.854, 0.472]
    # without spread: the generator's draw, as before
    from dancekit.pipelines.revolution import GENRE_DRAW_STREAM
    assert draw_uniform(5) == np.random.default_rng([GENRE_DRAW_STREAM, 5]).random()


def test_a_spread_draw_gives_every_option_its_share_over_a_few_consecutive_seeds():
    probs = {"waltz": 0.5, "rumba": 0.3, "chacha": 0.15, "tango": 0.05}
    spread = GenreDraw(temperature=1.0, alone=0.2, spread=True)
    plain = GenreDraw(temperature=1.0, alone=0.2)
    options = genre_options(probs, spread)
    worst = {"spread": 0.0, "plain": 0.0}
    for name, draw in (("spread", spread), ("plain", plain)):
        drawn = [draw_genre(probs, seed=s, draw=draw)[0] for s in range(1, 400)]
        for n in (5, 10, 30, 100):
            for start in range(0, len(drawn) - n, 7):
                window = drawn[start:start + n]
                for g, q in options.items():
                    worst[name] = max(worst[name], abs(window.count(g) - n * q))
    assert worst["spread"] <= 3.0, worst
    assert worst["plain"] > 4.0, worst  # independent draws stray much further over the same windows
    # seed 0 still keeps the most likely genre; the draw still follows the options in the long run
    assert draw_genre(probs, seed=0, draw=spread) == ("waltz", None)
    f = frequencies(probs, spread)
    for g, q in options.items():
        assert f.get(g, 0.0) == pytest.approx(q, abs=0.002), (g, f)


def test_the_spread_key_is_read_from_the_checkpoint_and_checked():
    assert genre_draw_from_meta({"sampling": {"genre_temperature": 2, "genre_draw_spread": True}}) == \
        GenreDraw(temperature=2.0, spread=True)
    assert genre_draw_from_meta({"sampling": {"genre_temperature": 2}}).spread is False
    with pytest.raises(CheckpointError, match="ckpt: config.json: sampling.genre_draw_spread must be true or false"):
        genre_draw_from_meta({"sampling": {"genre_temperature": 2, "genre_draw_spread": "yes"}}, folder="ckpt")
