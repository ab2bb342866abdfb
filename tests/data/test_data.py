"""dancekit.data: splits, representations, normalisation, and the prepared tang2018 dataset."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from dancekit.checkpoints import NormStats
from dancekit.data import (
    GENRES,
    PreparedData,
    WindowDataset,
    split_by_genre,
    tang2018_genre,
)
from dancekit.errors import DatasetError, ParameterError
from dancekit.motion import Motion, get_skeleton
from dancekit.motion.representations import decode_motion, encode_motion, pose_dim


def _names(code, n):
    return [f"DANCE_{code}_{i}" for i in range(n)]


def test_split_is_by_whole_dance_stratified_and_seeded():
    by_genre = {"waltz": _names("W", 26), "rumba": _names("R", 6), "chacha": _names("C", 4), "tango": _names("T", 1)}
    a = split_by_genre(by_genre, seed=0)
    b = split_by_genre(by_genre, seed=0)
    c = split_by_genre(by_genre, seed=1)
    assert a == b and a != c
    every = a["train"] + a["val"] + a["test"]
    assert sorted(every) == sorted(sum(by_genre.values(), []))  # each dance exactly once
    assert len(set(every)) == len(every)
    for genre, names in by_genre.items():
        n_test = sum(n in a["test"] for n in names)
        assert (n_test >= 1) == (len(names) >= 3), genre  # every genre with >= 3 dances is tested
    assert "DANCE_T_0" in a["train"]  # a single-dance genre is only trained on


def test_genre_from_folder_name():
    assert tang2018_genre("DANCE_W_12") == "waltz"
    assert tang2018_genre("/x/DANCE_C_2") == "chacha"
    with pytest.raises(DatasetError, match="DANCE_X_1"):
        tang2018_genre("DANCE_X_1")


def _random_motion(rng, T=50):
    skel = get_skeleton("tang2018")
    rest = np.zeros((skel.num_joints, 3))
    for j, p in enumerate(skel.parents):
        if p >= 0:
            rest[j] = rest[p] + skel.offsets[j]
    pos = rest[None] + rng.normal(0, 2.0, (T, skel.num_joints, 3))
    pos += np.cumsum(rng.normal(0, 1.0, (T, 1, 3)), axis=0)  # wandering root
    return Motion(skeleton=skel, fps=25.0, positions=pos.astype(np.float32))


def test_positions3d_round_trip_keeps_pose_and_trajectory(rng):
    m = _random_motion(rng)
    x = encode_motion(m, "positions3d")
    assert x.shape == (50, pose_dim(m.skeleton, "positions3d")) == (50, 72)
    back = decode_motion(x, m.skeleton, m.fps, "positions3d").to_positions()
    orig = m.to_positions().astype(np.float64)
    # decoding starts the root at the horizontal origin: compare after removing that offset
    shift = orig[0, m.skeleton.root] - back[0, m.skeleton.root]
    np.testing.assert_allclose(back + shift, orig, atol=1e-3)
    assert abs(shift[1]) < 1e-4  # the height is kept, only the horizontal start moves


def test_positions3d_bad_shape_names_the_shape():
    skel = get_skeleton("tang2018")
    with pytest.raises(ParameterError, match=r"\(T, 72\)"):
        decode_motion(np.zeros((10, 71)), skel, 25, "positions3d")
    with pytest.raises(ParameterError, match="representation"):
        encode_motion(Motion(skeleton=skel, fps=25, positions=np.zeros((3, 23, 3), np.float32)), "nope")


def test_norm_stats_normalise_and_save_round_trip(tmp_path, rng):
    music = [rng.normal(3, 2, (100, 4)), rng.normal(3, 2, (50, 4))]
    dance = [rng.normal(-1, 5, (100, 6)), rng.normal(-1, 5, (50, 6))]
    music[0][:, 2] = 7.0  # a constant column
    music[1][:, 2] = 7.0
    s = NormStats.compute(music, dance)
    z = s.normalize_music(np.concatenate(music))
    np.testing.assert_allclose(z[:, [0, 1, 3]].mean(0), 0, atol=1e-5)
    np.testing.assert_allclose(z[:, [0, 1, 3]].std(0), 1, atol=1e-4)
    assert np.all(np.isfinite(z)) and np.allclose(z[:, 2], 0)
    d = np.concatenate(dance).astype(np.float32)
    np.testing.assert_allclose(s.denormalize_dance(s.normalize_dance(d)), d, atol=1e-4)
    s.save(tmp_path / "stats.npz")
    s2 = NormStats.load(tmp_path / "stats.npz")
    for k, v in s.as_arrays().items():
        np.testing.assert_array_equal(v, s2.as_arrays()[k])


def test_prepared_data_missing_folder_is_a_named_error(tmp_path):
    with pytest.raises(DatasetError, match="meta.json"):
        PreparedData(tmp_path)


# ---- the real tang2018 data, prepared once per test session (one preset, to stay fast) ----


@pytest.mark.slow
def test_prepared_tang2018_alignment_every_dance(prepared_tang2018):
    data = prepared_tang2018
    names = data.names()
    assert len(names) == 37
    for name in names:
        T = data.frames(name)
        motion = data.motion(name)
        feats = data.features(name, "music2dance")
        assert motion.num_frames == T == len(feats["features"]), name
        # the features were computed on exactly T / fps seconds of the song: 1 + T frames before
        # dropping the last, i.e. feature frame i is motion frame i.
        assert data.meta["dances"][name]["feature_frames_raw"] == T + 1, name
        ref = data.audio(name)
        assert abs((ref.end - ref.start) - T / data.fps) < 1e-9
        assert np.all(feats["beat_times"] < T / data.fps)
        assert data.genre(name) in GENRES


@pytest.mark.slow
def test_prepared_tang2018_floor_and_splits(prepared_tang2018):
    data = prepared_tang2018
    split = data.splits
    assert set(split["train"]).isdisjoint(split["test"]) and set(split["train"]).isdisjoint(split["val"])
    assert {data.genre(n) for n in split["test"]} == {"waltz", "rumba", "chacha"}
    from scipy.ndimage import percentile_filter

    up = 1
    feet = [data.skeleton.index(f) for f in data.skeleton.feet]
    for name in data.names("test"):
        pos = data.motion(name).to_positions()
        lowest = pos[:, feet, up].min(axis=1)
        # the floor is at 0 all along the dance, not just on average (the capture drifts up to 50 cm)
        running_floor = percentile_filter(lowest, 5, size=75, mode="nearest")
        assert np.abs(running_floor).max() < 3.0, name
        lo, hi = data.meta["dances"][name]["floor_offset"]
        assert hi - lo > 5.0, name  # a drifting floor was removed
        assert pos[:, data.skeleton.index("head"), up].mean() > 100  # a standing adult, in cm
        assert data.motion(name).rotations is not None


def test_mirror_and_heading_augmentations_are_the_moved_dance_re_encoded(rng):
    """Derived independently: the window of the mirrored / turned world positions, encoded again."""
    from dancekit.data.windows import augment_positions3d

    m = _random_motion(rng)
    x = encode_motion(m, "positions3d")
    np.testing.assert_allclose(augment_positions3d(x, skeleton=m.skeleton, mirror=True),
                               encode_motion(m.mirror(), "positions3d"), atol=1e-4)
    theta = 0.7
    pos = m.to_positions().astype(np.float64)
    c, s = np.cos(theta), np.sin(theta)  # y up: turn x, z about the y axis (the code's h0 = x, h1 = z)
    turned = pos.copy()
    turned[..., 0], turned[..., 2] = c * pos[..., 0] - s * pos[..., 2], s * pos[..., 0] + c * pos[..., 2]
    np.testing.assert_allclose(augment_positions3d(x, skeleton=m.skeleton, heading=theta),
                               encode_motion(Motion(m.skeleton, m.fps, turned.astype(np.float32)), "positions3d"),
                               atol=1e-4)


def test_rot6d_heading_turns_the_decoded_dance_about_the_up_axis(rng):
    """Derived independently: the rot6d window turned by the augmentation, decoded by forward kinematics, is the
    original dance's world positions turned about the y axis through the origin."""
    from dancekit.data.windows import augment_rot6d

    m = _random_motion(rng, T=12)
    x = encode_motion(m, "rot6d")
    pos = decode_motion(x, m.skeleton, m.fps, "rot6d").to_positions().astype(np.float64)
    theta = -1.1
    c, s = np.cos(theta), np.sin(theta)
    turned = pos.copy()
    turned[..., 0], turned[..., 2] = c * pos[..., 0] - s * pos[..., 2], s * pos[..., 0] + c * pos[..., 2]
    out = decode_motion(augment_rot6d(x, skeleton=m.skeleton, heading=theta), m.skeleton, m.fps, "rot6d")
    np.testing.assert_allclose(out.to_positions(), turned, atol=1e-3)
    np.testing.assert_array_equal(augment_rot6d(x, skeleton=m.skeleton), x)  # no turn: the window as it was


@pytest.mark.slow
def test_window_dataset_augmentations_are_seeded_and_keep_the_window(prepared_tang2018):
    data = prepared_tang2018
    plain = WindowDataset(data, "train", preset="music2dance", window=100, stride=200)
    aug = WindowDataset(data, "train", preset="music2dance", window=100, stride=200, stats=plain.stats,
                        mirror=0.5, heading=True, tempo=0.05)
    again = WindowDataset(data, "train", preset="music2dance", window=100, stride=200, stats=plain.stats,
                          mirror=0.5, heading=True, tempo=0.05)
    for k in (0, 5):
        a, b, p = aug[k], again[k], plain[k]
        assert a["dance"].shape == (100, 72) and a["music"].shape == (100, 15)
        torch.testing.assert_close(a["dance"], b["dance"])  # a pure function of (seed, epoch, item)
        assert not torch.allclose(a["dance"], p["dance"])
        # the music is only resampled in time (within ±5 %): it stays close to the plain window's
        assert float((a["music"] - p["music"]).abs().mean()) < float((a["music"] - plain[k + 1]["music"]).abs().mean())
    aug.set_epoch(1)
    assert not torch.allclose(aug[0]["dance"], again[0]["dance"])
    with pytest.raises(ParameterError, match="mirror augmentation needs positions3d"):
        WindowDataset(data, "train", preset="music2dance", window=100, representation="rot6d", mirror=0.5)
    with pytest.raises(ParameterError, match="positions3d or rot6d"):
        WindowDataset(data, "train", preset="music2dance", window=100, representation="rotations_rootdelta",
                      heading=True)
    # rot6d: turned and tempo-changed windows, seeded; the turn moves the root's columns alone
    plain6 = WindowDataset(data, "train", preset="music2dance", window=100, stride=200, representation="rot6d")
    turn6 = WindowDataset(data, "train", preset="music2dance", window=100, stride=200, representation="rot6d",
                          stats=plain6.stats, heading=True)
    a, p = turn6[3]["dance"], plain6[3]["dance"]
    torch.testing.assert_close(a, WindowDataset(data, "train", preset="music2dance", window=100, stride=200,
                                                representation="rot6d", stats=plain6.stats, heading=True)[3]["dance"])
    root = 3 + 6 * data.skeleton.rig().root
    changed = (a - p).abs().amax(0) > 1e-5
    assert changed[:3].any() and changed[root : root + 6].any()
    assert not changed[3:root].any() and not changed[root + 6 :].any()
    slow6 = WindowDataset(data, "train", preset="music2dance", window=100, stride=200, representation="rot6d",
                          stats=plain6.stats, tempo=0.1)
    assert slow6[3]["dance"].shape == p.shape and not torch.allclose(slow6[3]["dance"], p)


@pytest.mark.slow
def test_window_dataset_shapes_and_train_only_stats(prepared_tang2018):
    data = prepared_tang2018
    train = WindowDataset(data, "train", preset="music2dance", window=100, stride=200)
    val = WindowDataset(data, "val", preset="music2dance", window=100, stride=200, stats=train.stats)
    item = train[0]
    assert item["music"].shape == (100, 15) and item["dance"].shape == (100, 72)
    assert item["music"].dtype == torch.float32 and item["genre"].dtype == torch.int64
    assert val.stats is train.stats
    # statistics come from the training split only: normalised training frames are centred
    all_train = np.concatenate(train.dance)
    np.testing.assert_allclose(all_train.mean(0), 0, atol=1e-3)
    assert abs(np.concatenate(val.dance).mean()) > 1e-4  # held-out data is not centred by construction
    assert len(train) > len(val) > 0


def test_prepare_cli_bad_source_exits_nonzero(tmp_path, capsys):
    from dancekit.cli.main import main

    code = main(["prepare", "tang2018", str(tmp_path / "nowhere"), "-o", str(tmp_path / "out")])
    assert code != 0
    err = capsys.readouterr().err
    assert "nowhere" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_meta_json_is_plain_json(prepared_tang2018):
    meta = json.loads((prepared_tang2018.root / "meta.json").read_text())
    assert meta["source"] == "tang2018" and meta["fps"] == 25.0


@pytest.mark.slow
def test_window_dataset_balances_genres(prepared_tang2018):
    data = prepared_tang2018
    plain = WindowDataset(data, "train", preset="music2dance", window=100, stride=100)
    bal = WindowDataset(data, "train", preset="music2dance", window=100, stride=100, stats=plain.stats,
                        balance_genres=True, max_repeat=8)

    def share(ds):
        g = np.array([ds.genres[i] for i, _ in ds.index])
        return np.bincount(g, minlength=4) / len(g)

    waltz = data.genres.index("waltz")
    assert share(plain)[waltz] > 0.6  # tang2018 is mostly waltz
    assert share(bal)[waltz] < 0.45 and share(bal).min() > 0.1
    assert bal.repeats[waltz] == 1 and max(bal.repeats.values()) <= 8
    assert set(bal.index) == set(plain.index)  # the same windows, repeated


@pytest.mark.slow
def test_window_dataset_keeps_only_the_asked_genres(prepared_tang2018):
    data = prepared_tang2018
    plain = WindowDataset(data, "train", preset="music2dance", window=100, stride=100)
    latin = WindowDataset(data, "train", preset="music2dance", window=100, stride=100, stats=plain.stats,
                          genres=["rumba", "chacha"])
    assert sorted(latin.names) == sorted(n for n in data.names("train") if data.genre(n) in ("rumba", "chacha"))
    assert len(latin.names) == 6 and 0 < len(latin) < len(plain)  # 4 rumba + 2 cha-cha training dances
    assert {data.genres[latin.genres[i]] for i, _ in latin.index} == {"rumba", "chacha"}
    with pytest.raises(ParameterError, match="salsa"):
        WindowDataset(data, "train", preset="music2dance", window=100, stats=plain.stats, genres=["salsa"])


def test_norm_stats_from_checkpoint_arrays_names_what_is_missing():
    from dancekit.errors import CheckpointError

    arrays = {k: np.arange(3, dtype=np.float64) for k in ("music_mean", "music_std", "dance_mean", "dance_std")}
    s = NormStats.from_arrays(arrays, source="ckpt")
    assert s.music_std.dtype == np.float32 and s.dance_mean.tolist() == [0.0, 1.0, 2.0]
    s.music_mean[0] = 9.0  # a copy: the checkpoint's arrays are untouched
    assert arrays["music_mean"][0] == 0.0
    del arrays["dance_std"]
    with pytest.raises(CheckpointError, match=r"checkpoint ckpt: stats.npz lacks \['dance_std'\]"):
        NormStats.from_arrays(arrays, source="ckpt")
