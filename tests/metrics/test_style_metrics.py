"""Style classifier: tiny training on synthetic genres, save → load, the Dance Revolution metrics."""

from __future__ import annotations

import numpy as np
import pytest
from _style import fit_tiny_style_classifier

from dancekit.checkpoints import MODELS_DIR
from dancekit.errors import CheckpointError, ParameterError
from dancekit.evaluation import style_classifier_scores
from dancekit.metrics.style import balanced_accuracy, multimodality, style_diversity, style_fid
from dancekit.models.style import style_input
from dancekit.motion import get_skeleton
from dancekit.pipelines import StylePipeline

DEFAULT_CLASSIFIER = MODELS_DIR / "style"

SK = get_skeleton("tang2018")


def rest_pose() -> np.ndarray:
    rest = np.zeros((SK.num_joints, 3))
    for j in SK.topological_order:
        p = SK.parents[j]
        rest[j] = SK.offsets[j] + (rest[p] if p >= 0 else 0.0)
    return rest


def synthetic_dance(genre: int, seed: int, seconds: float = 12.0, fps: float = 25.0) -> np.ndarray:
    """Genre 0 swings the arms sideways at ~1 Hz; genre 1 bobs the whole body up and down at ~3 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fps))[:, None] / fps
    p = np.repeat(rest_pose()[None], len(t), axis=0) + rng.normal(scale=0.3, size=(len(t), SK.num_joints, 3))
    f = rng.uniform(0.8, 1.2) * (1.0 if genre == 0 else 3.0)
    wave = np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    if genre == 0:
        for j in ("left_elbow", "left_wrist", "right_elbow", "right_wrist"):
            p[:, SK.index(j), 0] += 25.0 * wave[:, 0]
    else:
        p[..., 1] += 8.0 * wave
    heading = rng.uniform(0, 2 * np.pi)  # the classifier must not care which way the dancer faces
    c, s = np.cos(heading), np.sin(heading)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return p @ rot.T + rng.uniform(-100, 100, size=3)


@pytest.fixture(scope="module")
def tiny_classifier(tmp_path_factory):
    train = [(synthetic_dance(g, seed), g) for seed in range(4) for g in (0, 1)]
    val = [(synthetic_dance(g, 100 + g), g) for g in (0, 1)]
    out = tmp_path_factory.mktemp("style_run")
    model = fit_tiny_style_classifier(
        train, val, skeleton=SK, fps=25.0, genres=["swing", "bob"], out_dir=out, window=50, stride=25,
        epochs=4, batch_size=16, channels=16, feature_dim=8,
    )
    return model, out


def test_style_input_is_heading_and_position_invariant():
    p = synthetic_dance(0, 1)
    c, s = np.cos(1.0), np.sin(1.0)
    turned = p @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T + [500.0, 0.0, -300.0]
    x, y = style_input(p, fps=25, skeleton=SK), style_input(turned, fps=25, skeleton=SK)
    assert x.shape == (len(p), 6 * SK.num_joints + 4)
    np.testing.assert_allclose(x, y, atol=1e-3)


def test_tiny_classifier_learns_synthetic_genres(tiny_classifier):
    model, _ = tiny_classifier
    test = [(synthetic_dance(g, 200 + seed), g) for seed in range(3) for g in (0, 1)]
    scores = style_classifier_scores(model, test, fps=25.0)
    assert scores["dance_accuracy"] == 1.0
    assert scores["window_balanced_accuracy"] >= 0.9
    feats, logp = model.embed(test[0][0], fps=25.0)
    assert feats.shape == (6, 8) and logp.shape == (6, 2)  # 12 s in 2-s windows
    np.testing.assert_allclose(np.exp(logp).sum(axis=1), 1.0, rtol=1e-6)


def test_classifier_save_load_round_trip(tiny_classifier):
    model, out = tiny_classifier
    again = StylePipeline.from_pretrained(out / "best")
    p = synthetic_dance(1, 7)
    np.testing.assert_allclose(again.embed(p, fps=25.0)[0], model.embed(p, fps=25.0)[0], rtol=1e-5, atol=1e-6)
    assert again.genres == ["swing", "bob"]
    # another frame rate is resampled to the classifier's
    assert again.predict(p[::2], fps=12.5) == 1


def test_classifier_rejects_other_skeletons_and_bad_folders(tiny_classifier, tmp_path):
    model, _ = tiny_classifier
    with pytest.raises(ParameterError, match="skeleton"):
        model.embed(np.zeros((100, 24, 3)), fps=25.0, skeleton=get_skeleton("smpl"))
    with pytest.raises(CheckpointError):
        StylePipeline.from_pretrained(tmp_path / "missing")


def test_style_fid_diversity_multimodality_known_answers(rng):
    x = rng.normal(size=(40, 4))
    assert style_fid(x, x) == pytest.approx(0.0, abs=1e-6)
    feats = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 0.0], [6.0, 8.0]])
    music = ["a", "b", "a", "b"]
    # pairs with different music: (0,1)=5, (0,3)=10, (1,2)=5, (2,3)=10
    assert style_diversity(feats, music) == pytest.approx(7.5)
    assert style_diversity(feats, music, pairs=2, seed=0) in (5.0, 7.5, 10.0)
    # same music: a → 0, b → 5
    assert multimodality(feats, music) == pytest.approx(2.5)
    assert np.isnan(multimodality(feats, ["a", "b", "c", "d"]))


def test_balanced_accuracy():
    assert balanced_accuracy([0, 0, 0, 1], [0, 0, 0, 0]) == pytest.approx(0.5)


def test_the_style_classifier_is_packaged():
    """The evaluation's default classifier ships with the package: its absence is a failure, not a skip."""
    for name in ("config.json", "model.safetensors", "stats.npz"):
        assert (DEFAULT_CLASSIFIER / name).is_file(), f"the packaged style classifier lacks {DEFAULT_CLASSIFIER / name}"
    assert sum(f.stat().st_size for f in DEFAULT_CLASSIFIER.iterdir()) < 2_000_000
    model = StylePipeline.from_pretrained(DEFAULT_CLASSIFIER)
    assert list(model.genres) == ["waltz", "rumba", "chacha", "tango"]


def test_shipped_classifier(tang2018_dir):
    assert (DEFAULT_CLASSIFIER / "config.json").is_file(), f"no packaged style classifier in {DEFAULT_CLASSIFIER}"
    from dancekit.motion.formats import read_tang2018

    model = StylePipeline.from_pretrained()
    for name, genre in (("DANCE_C_6", "chacha"), ("DANCE_W_1", "waltz"), ("DANCE_R_2", "rumba")):  # test split
        motion = read_tang2018(tang2018_dir / name)[0]
        assert model.genres[model.predict(motion.to_positions(), fps=motion.fps)] == genre
