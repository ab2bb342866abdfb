"""The edit stage (issue 44) on test-song excerpts, for each model: keys, a path, kept arms, a prefix.

    PYTHONPATH=src python benchmarks/bench_edit.py --data data/tang2018 --seeds 0-1 \
        --out docs/results/edit.json --figure docs/edit.png

Per model, song (the three test songs of tests/conftest.py, excerpt ``--start``-``--end`` s) and seed, the
finished dance (``pipe.dances``, the model's stages) is edited four ways by ``stages.edit_dance``:

* keys every 2 s (whole poses but the root, from the real test dances of ``--data`` 30 s in (or earlier), turned to the
  dance's heading and placed on its root at the key's frame): the largest key error (cm) over keyed joints;
* an L-shaped path (1.5 m then 1.5 m, constant speed), danced as ``dancekit dance --path`` dances it
  (``pipe.dances(..., edit=EditConfig(path=...))``: the dance moved onto the path before the model's foot lock):
  the root's RMS distance to it (m) and the foot-skating ratio (``dancekit.metrics.foot_skating``) of the edited
  and of the unedited dance (real: the mean over the real test dances);
* the upper body kept from a real test dance: the largest error (cm) of the kept joints relative to the root, and
  the generated legs' floor and contacts against issue 15's bounds (means over the dances: the lowest joint's
  median height over the local floor ≤ 2 cm and its share within 2 cm ≥ 0.6; planted-foot share and foot skating
  within ±25 % of the real test dances');
* a 2-s prefix from the middle of a real test dance, danced as ``dancekit dance --prefix`` dances it
  (``pipe.dances(..., edit=EditConfig(prefix=...))``: Dance Revolution's decoder is fed the prefix): the largest
  prefix error (cm), the largest per-frame joint acceleration (m/s^2) from 2 frames before the seam to the end of
  the fade, against the 99th percentile of the real test dances' per-frame largest joint acceleration, and the
  pose gap the fade has to bridge (the dance before the edit stage at the prefix's last frame, root-relative and
  turned to its heading, against the prefix's last pose; cm, median) for the dance as danced and for the same
  seed's dance without the prefix (what the stage alone would have to bridge).

Writes the JSON table (docs/results/<topic>.json shape) and, with ``--figure``, a PNG: a keyed wrist's height
through its keys (edited, unedited) and a path with the root's trace seen from above.

``--fid OUT`` instead dances every song of the tang2018 test split of ``--data`` (the dance's slice of its song,
seeds ``--seeds``, ``--genre auto``: what ``dancekit evaluate --checkpoint`` dances) and keys each dance every 2 s
with the poses of the song's real dance at the same frames (turned to the dance's heading, placed on its root);
the unedited and the keyed dances go to ``OUT/MODEL/unedited`` and ``OUT/MODEL/keyed``, to be scored with
``dancekit evaluate --pred OUT/MODEL/keyed --ref DATA --data DATA`` (and the same for ``unedited``): issue 44's
"edited dances' FID within +10 % of the unedited dances". Each dance is also danced with its upper body kept from
the song's real dance (``OUT/MODEL/kept``), and ``OUT/physical.json`` holds the floor and contact figures of
issue 15 (the means over the dances: floor median, share within 2 cm, planted-foot share, foot skating) for the
unedited, the kept and the real test dances.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SONGS = ["Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg", "Kevin_MacLeod_-_Vibe_Ace.ogg",
         "brahms_hungarian_dance_5.ogg"]


def _real_dances(data: Path):
    from dancekit.motion.formats import read_motion

    test = json.loads((data / "splits.json").read_text())["test"]
    return [read_motion(data / "dances" / n / "motion.npz") for n in test]


def _turned(pose: np.ndarray, sk, yaw: float) -> np.ndarray:
    """``pose`` (J, 3) relative to its root, turned by ``yaw`` rad about the up axis."""
    from dancekit.motion.analysis import horizontal_axes

    a, b = horizontal_axes(sk)
    rel = pose - pose[sk.root]
    c, s = math.cos(yaw), math.sin(yaw)
    out = rel.copy()
    out[:, a] = c * rel[:, a] - s * rel[:, b]
    out[:, b] = s * rel[:, a] + c * rel[:, b]
    return out


def _keys_file(path: Path, p: np.ndarray, real: np.ndarray, sk, fps: float, offset: int | None = None) -> list[int]:
    """Keys every 2 s of ``p``'s frames: the poses of ``real`` from frame ``offset`` on (default: 30 s in, or
    as far in as ``real`` allows), turned to ``p``'s heading at each key and placed on its root."""
    from dancekit.motion.edit import _yaw

    frames = [int(round(t * fps)) for t in np.arange(2.0, min(len(p), len(real)) / fps - 0.5, 2.0)]
    keys = []
    off = max(min(int(30 * fps), len(real) - len(p) - 1), 0) if offset is None else offset
    for f in frames:
        yaw = _yaw(p, sk, f) - _yaw(real, sk, off + f)
        pose = _turned(real[off + f], sk, yaw) + p[f, sk.root]
        keys.append({"frame": f, "pose": {n: pose[j].tolist() for j, n in enumerate(sk.joint_names) if j != sk.root}})
    path.write_text(json.dumps(keys))
    return frames


def _rel(x, joints: list[int], sk) -> np.ndarray:
    """Positions of ``joints`` relative to the root, ``(T, n, 3)`` float64."""
    x = np.asarray(x, np.float64)
    return x[:, joints] - x[:, sk.root:sk.root + 1]


def _acc(p: np.ndarray, sk, fps: float) -> np.ndarray:
    """Per frame, the largest joint acceleration (m/s^2), ``(T - 2,)``."""
    return np.linalg.norm(np.diff(p, 2, axis=0), axis=-1).max(axis=1) * fps * fps * sk.unit_scale


def _seam_gap(dance: np.ndarray, prefix: np.ndarray, sk) -> float:
    """The pose the prefix's fade has to bridge (cm, mean over joints): the dance's frame ``N - 1`` (N = the
    prefix's length) relative to its root and turned to the prefix's heading, against the prefix's last pose."""
    from dancekit.motion.edit import _yaw

    n = len(prefix)
    a = _turned(dance[n - 1], sk, _yaw(prefix, sk, n - 1) - _yaw(dance, sk, n - 1))
    b = prefix[n - 1] - prefix[n - 1, sk.root]
    return float(np.linalg.norm(a - b, axis=-1).mean())


def keyed_split(data_dir: Path, out: Path, models: list[str], seeds: list[int]) -> None:
    """The ``--fid`` mode: unedited and keyed dances of the test split per model (see the module's description)."""
    import torch
    from bench_stages import physical

    from dancekit.data import PreparedData
    from dancekit.evaluation.generate import SAMPLE_SEP, requested_genre
    from dancekit.metrics import foot_skating
    from dancekit.motion import Motion, edit
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.config import EditConfig
    from dancekit.pipelines.stages import Song, edit_dance

    torch.set_num_threads(1)
    data = PreparedData(data_dir)
    t0 = time.time()

    def contacts(dances: list[np.ndarray], sk, fps: float) -> dict[str, float]:
        rows = [{**physical(p, sk, fps), "foot_skating": foot_skating(p, fps=fps, skeleton=sk)["ratio"]}
                for p in dances]
        keys = ("floor_median_cm", "floor_within_2cm", "planted_foot_share", "foot_skating")
        return {k: round(float(np.nanmean([r[k] for r in rows])), 3) for k in keys} | {"dances": len(rows)}

    reals = {n: data.motion(n).to_positions().astype(np.float64) for n in data.names("test")}
    first = data.motion(data.names("test")[0])
    summary = {"real test": contacts(list(reals.values()), first.skeleton, first.fps)}
    for model in models:
        pipe = load_pipeline(model)
        config = pipe.stage_options()
        dirs = {k: out / model / k for k in ("unedited", "keyed", "keys", "kept")}
        got: dict[str, list[np.ndarray]] = {"unedited": [], "kept": []}
        for d in dirs.values():
            d.mkdir(parents=True, exist_ok=True)
        for name in data.names("test"):
            ref = data.audio(name)
            real = reals[name]
            sk, fps = data.motion(name).skeleton, data.motion(name).fps
            song = Song(ref.path, ref.start, ref.end)
            results = pipe.dances(ref.path, seeds=seeds, start=ref.start, end=ref.end,
                                  genre=requested_genre("auto", data.genre(name)))
            for k, r in enumerate(results):
                stem = f"{name}{SAMPLE_SEP}{k}"
                p0 = r.motion.to_positions().astype(np.float64)
                kf = dirs["keys"] / f"{stem}.json"
                _keys_file(kf, p0, real, sk, fps, offset=0)
                keyed = edit_dance(r, EditConfig(keyframes=str(kf)), song, config).motion
                write_motion(dirs["unedited"] / f"{stem}.npz", r.motion)
                write_motion(dirs["keyed"] / f"{stem}.npz", keyed)
                take = dirs["keys"] / f"{name}_take.npz"
                if not take.exists():  # the real dance, its last pose held 1 s (a song slice can be a frame longer)
                    held = np.concatenate([real, np.repeat(real[-1:], int(fps), axis=0)]).astype(np.float32)
                    write_motion(take, Motion(skeleton=sk, fps=fps, positions=held))
                kept = edit_dance(r, EditConfig(keep="upper", take=str(take)), song, config).motion
                write_motion(dirs["kept"] / f"{stem}.npz", kept)
                got["unedited"].append(p0)
                got["kept"].append(np.asarray(kept.to_positions(), np.float64))
                assert np.array_equal(got["kept"][-1][:, list(edit.body_part_joints(sk, "lower"))],
                                      p0[:, list(edit.body_part_joints(sk, "lower"))].astype(np.float32))
            print(f"{model} {name}: {len(results)} dances, {time.time() - t0:.0f} s", flush=True)
        summary[model] = {k: contacts(v, sk, fps) for k, v in got.items()}
        print(model, json.dumps(summary[model]), flush=True)
    (out / "physical.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary, indent=1))


def contacts_table(physical: Path, out: str | None, argv) -> int:
    """The floor and contact figures of a ``--fid`` run (``OUT/physical.json``) as a docs/results table: per model,
    the unedited dances and the same dances with the upper body kept from the song's real dance, against the real
    test dances and issue 15's bounds."""
    summary = json.loads(physical.read_text())
    real = summary.pop("real test")
    keys = ("floor_median_cm", "floor_within_2cm", "planted_foot_share", "foot_skating")
    rows = [["real test dances", "-", real["dances"], *(real[k] for k in keys)]]
    for model, parts in summary.items():
        for part in ("unedited", "kept"):
            rows.append([model, "upper body kept from the real dance" if part == "kept" else "unedited",
                         parts[part]["dances"], *(parts[part][k] for k in keys)])
    lo, hi = 0.75 * real["planted_foot_share"], 1.25 * real["planted_foot_share"]
    slo, shi = 0.75 * real["foot_skating"], 1.25 * real["foot_skating"]
    doc = {"title": "Editing: the generated legs' floor and foot contacts with the upper body kept, tang2018 test split "
                    "(issue 44)",
           "command": f"PYTHONPATH=src python benchmarks/bench_edit.py --fid {physical.parent} --data data/tang2018 "
                      "--seeds 0-4; PYTHONPATH=src python " + " ".join(["benchmarks/bench_edit.py",
                                                                          *(argv or sys.argv[1:])]),
           "machine": "any (the figures do not depend on the machine)",
           "date": time.strftime("%Y-%m-%d", time.gmtime()),
           "columns": ["dances of", "edit", "dances", "floor median (cm)", "within 2 cm of the floor",
                       "planted-foot share", "foot skating ratio"],
           "rows": rows,
           "note": ("Every song of the test split, seeds 0-4, genre auto; kept: `--keep upper --from` the song's real "
                    "dance (the legs and the root stay the model's own: equal to the unedited dance's, checked by the "
                    "benchmark). Issue 15's bounds: floor median <= 2 cm, within 2 cm >= 0.6, planted-foot share "
                    f"{lo:.3f}-{hi:.3f} and foot skating {slo:.3f}-{shi:.3f} (+-25 % of the real test dances').")}
    print(json.dumps(doc, indent=1))
    if out:
        from dancekit._io import atomic_path

        with atomic_path(out) as tmp:
            Path(tmp).write_text(json.dumps(doc, indent=1) + "\n")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fid", default=None, metavar="OUT",
                    help="write the unedited and keyed dances of the test split (seeds --seeds) under OUT/MODEL/")
    ap.add_argument("--contacts-table", default=None, metavar="PHYSICAL_JSON",
                    help="the --fid run's OUT/physical.json as a docs/results table, written to --out")
    ap.add_argument("--data", default=str(ROOT / "data" / "tang2018"))
    ap.add_argument("--music", default=str(ROOT.parent / "shared" / "music"))
    ap.add_argument("--models", default="revolution,music2dance,dual")
    ap.add_argument("--seeds", default="0-1")
    ap.add_argument("--start", type=float, default=10.0)
    ap.add_argument("--end", type=float, default=20.0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--figure", default=None)
    ap.add_argument("--work", default="/tmp/bench_edit")
    args = ap.parse_args(argv)
    if args.contacts_table:
        return contacts_table(Path(args.contacts_table), args.out, argv)
    if args.fid:
        from dancekit.pipelines.base import parse_seeds

        keyed_split(Path(args.data), Path(args.fid), args.models.split(","), parse_seeds(args.seeds))
        return 0

    import torch
    from bench_stages import physical

    from dancekit.metrics import foot_skating
    from dancekit.motion import Motion, edit
    from dancekit.motion.formats import write_motion
    from dancekit.pipelines import load_pipeline
    from dancekit.pipelines.base import parse_seeds
    from dancekit.pipelines.config import EditConfig
    from dancekit.pipelines.stages import Song, edit_dance

    torch.set_num_threads(1)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    seeds = parse_seeds(args.seeds)
    reals = _real_dances(Path(args.data))
    sk, fps = reals[0].skeleton, reals[0].fps
    real_pos = [r.to_positions().astype(np.float64) for r in reals]
    real_acc99 = float(np.percentile(np.concatenate([_acc(p, sk, fps) for p in real_pos]), 99))
    real_skate = float(np.nanmean([foot_skating(p, fps=fps, skeleton=sk)["ratio"] for p in real_pos]))
    real_planted = float(np.mean([physical(p, sk, fps)["planted_foot_share"] for p in real_pos]))
    path_file = work / "path.json"
    path_file.write_text(json.dumps({"points": [[0, 0], [1.5, 0], [1.5, 1.5]]}))
    pts, _ = edit.read_path(path_file)
    rows, fig = [], None
    t0 = time.time()
    for model in args.models.split(","):
        pipe = load_pipeline(model)
        per = {k: [] for k in ("key", "path", "skate", "skate0", "keep", "prefix", "seam", "refused", "keep_floor",
                               "keep_within", "keep_planted", "keep_skate", "gap_model", "gap_stage")}
        n = 0
        for si, name in enumerate(SONGS):
            song = Song(str(Path(args.music) / name), args.start, args.end)
            results = pipe.dances(song.path, seeds=seeds, start=args.start, end=args.end)
            on_path = pipe.dances(song.path, seeds=seeds, start=args.start, end=args.end,
                                  edit=EditConfig(path=str(path_file)))
            config = pipe.stage_options()
            for k, r in enumerate(results):
                n += 1
                p0 = r.motion.to_positions().astype(np.float64)
                real = real_pos[(si + k) % len(real_pos)]
                kf = work / f"keys_{model}_{si}_{k}.json"
                frames = _keys_file(kf, p0, real, sk, fps)
                try:
                    out = edit_dance(r, EditConfig(keyframes=str(kf)), song, config).motion.to_positions()
                    keys = edit.read_keyframes(kf, skeleton=sk, fps=fps, num_frames=len(p0))
                    per["key"].append(max(float(np.abs(out[q.frame, list(q.joints)] - q.positions).max())
                                          for q in keys))
                    if fig is None and model == "revolution":
                        fig = (p0, np.asarray(out, np.float64), frames)
                except Exception as exc:  # noqa: BLE001 (a refusal is counted and said)
                    per["refused"].append(str(exc))
                pe = on_path[k].motion.to_positions()
                target = edit.path_positions(pts, None, num_frames=len(pe), fps=fps)
                root = np.asarray(pe[:, sk.root][:, [0, 2]], np.float64) * sk.unit_scale
                per["path"].append(float(np.sqrt(np.mean(np.sum((root - target) ** 2, axis=1)))))
                per["skate"].append(foot_skating(pe, fps=fps, skeleton=sk)["ratio"])
                per["skate0"].append(foot_skating(p0, fps=fps, skeleton=sk)["ratio"])
                if model == "revolution" and k == 0 and si == 0:
                    fig = (*fig, root, target) if fig is not None and len(fig) == 3 else fig
                take = work / f"take_{si}_{k}.npz"
                write_motion(take, Motion(skeleton=sk, fps=fps, positions=real[: len(p0)].astype(np.float32)))
                pk = edit_dance(r, EditConfig(keep="upper", take=str(take)), song, config).motion.to_positions()
                j = list(edit.body_part_joints(sk, "upper"))
                per["keep"].append(float(np.abs(_rel(pk, j, sk) - _rel(real[: len(p0)], j, sk)).max()))
                ph = physical(np.asarray(pk, np.float64), sk, fps)
                per["keep_floor"].append(ph["floor_median_cm"])
                per["keep_within"].append(ph["floor_within_2cm"])
                per["keep_planted"].append(ph["planted_foot_share"])
                per["keep_skate"].append(foot_skating(pk, fps=fps, skeleton=sk)["ratio"])
                pre_n = int(2 * fps)
                pre = real[len(real) // 2: len(real) // 2 + pre_n]
                pf = work / f"prefix_{si}_{k}.npz"
                write_motion(pf, Motion(skeleton=sk, fps=fps, positions=pre.astype(np.float32)))
                steps = {}
                pp = pipe.dances(song.path, seeds=[seeds[k]], start=args.start, end=args.end,
                                 edit=EditConfig(prefix=str(pf)),
                                 stage_trace=lambda i, name, res, steps=steps: steps.__setitem__(name, res))[0]
                pp = np.asarray(pp.motion.to_positions(), np.float64)
                per["prefix"].append(float(np.abs(pp[:pre_n] - pre.astype(np.float32)).max()))
                w = int(round(edit.CROSSFADE_S * fps))
                per["seam"].append(float(_acc(pp, sk, fps)[pre_n - 3: pre_n + w].max()))
                before = [res for name, res in steps.items() if name != "edit"][-1]
                per["gap_model"].append(_seam_gap(np.asarray(before.motion.to_positions(), np.float64), pre, sk))
                per["gap_stage"].append(_seam_gap(p0, pre, sk))
        rows.append([model, n, round(max(per["key"], default=float("nan")), 5), len(per["refused"]),
                     round(max(per["path"]), 4), round(float(np.nanmean(per["skate"])), 3),
                     round(float(np.nanmean(per["skate0"])), 3), round(real_skate, 3),
                     round(max(per["keep"]), 5), round(max(per["prefix"]), 5), round(max(per["seam"]), 1),
                     round(real_acc99, 1), round(float(np.mean(per["keep_floor"])), 2),
                     round(float(np.mean(per["keep_within"])), 3), round(float(np.mean(per["keep_planted"])), 3),
                     round(real_planted, 3), round(float(np.nanmean(per["keep_skate"])), 3),
                     round(float(np.median(per["gap_model"])), 2), round(float(np.median(per["gap_stage"])), 2)])
        print(rows[-1], per["refused"][:2], f"{time.time() - t0:.0f} s", flush=True)
    columns = ["model", "dances", "key error max (cm)", "key sets refused", "path RMS max (m)",
               "skating ratio, path (mean)", "skating ratio, unedited (mean)", "skating ratio, real test (mean)",
               "kept joints error max (cm)", "prefix error max (cm)", "seam acceleration max (m/s^2)",
               "real acceleration p99 (m/s^2)", "kept upper: floor median (cm)", "kept upper: within 2 cm",
               "kept upper: planted-foot share", "planted-foot share, real test (mean)", "kept upper: skating ratio",
               "prefix: pose gap left to the fade, as danced (cm, median)",
               "prefix: pose gap left to the fade, the dance without the prefix (cm, median)"]
    doc = {"title": "Editing: keys, path, kept upper body, prefix (issue 44)",
           "command": "PYTHONPATH=src python " + " ".join(["benchmarks/bench_edit.py", *(argv or sys.argv[1:])]),
           "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}, 1 torch thread (shared 2-core box)",
           "date": time.strftime("%Y-%m-%d", time.gmtime()), "columns": columns, "rows": rows,
           "note": (f"test songs {', '.join(SONGS)}, excerpt {args.start:g}-{args.end:g} s, seeds {args.seeds}; "
                    "keys every 2 s = real test poses (tang2018 test split, 30 s in) turned to the dance's heading "
                    "on its root; path an L of 1.5 m + 1.5 m at constant speed, danced with the path (moved before the foot lock, as "
                    "dancekit dance --path); prefix 2 s of a real test dance "
                    "(from its middle); keys, kept parts and prefix: the edit stage on the model's finished dance "
                    "(pipelines.stages.edit_dance). "
                    "FID of keyed dances: docs/results/edit_fid.json.")}
    print(json.dumps(doc, indent=1))
    if args.out:
        from dancekit._io import atomic_path

        with atomic_path(args.out) as tmp:
            Path(tmp).write_text(json.dumps(doc, indent=1) + "\n")
    if args.figure and fig is not None and len(fig) == 5:
        _plot(Path(args.figure), *fig, sk=sk, fps=fps)
    return 0


def _plot(path: Path, p0, p1, frames, root, target, *, sk, fps: float) -> None:
    """Left: the left wrist's height (cm) over time, unedited (grey) and keyed (blue), keys as red dots.
    Right: the path (red) and the root's trace (blue) seen from above (m)."""
    from PIL import Image, ImageDraw

    W, H, M = 1000, 420, 40
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    j = sk.joint_names.index("left_wrist")
    up = sk.up_index
    y0, y1 = p0[:, j, up], p1[:, j, up]
    lo, hi = min(y0.min(), y1.min()) - 5, max(y0.max(), y1.max()) + 5
    pw = 560

    def xy(i, v):
        return M + i / (len(p0) - 1) * (pw - 2 * M), H - M - (v - lo) / (hi - lo) * (H - 2 * M)

    d.rectangle([M, M, pw - M, H - M], outline="black")
    d.line([xy(i, v) for i, v in enumerate(y0)], fill=(160, 160, 160), width=2)
    d.line([xy(i, v) for i, v in enumerate(y1)], fill=(30, 80, 200), width=2)
    for f in frames:
        x, y = xy(f, y1[f])
        d.ellipse([x - 5, y - 5, x + 5, y + 5], outline=(220, 30, 30), width=2)
    d.text((M, 10), f"left wrist height (cm {lo:.0f}-{hi:.0f}) over {len(p0) / fps:.0f} s: unedited grey, "
                    "keyed blue, keys red", fill="black")
    allp = np.concatenate([root, target])
    c, span = (allp.min(0) + allp.max(0)) / 2, float(np.ptp(allp, axis=0).max()) + 0.4
    x0 = pw + M

    def top(q):  # one scale on both axes
        s = min(W - x0 - M, H - 2 * M) / span
        return x0 + (q[0] - c[0] + span / 2) * s, H - M - (q[1] - c[1] + span / 2) * s

    d.rectangle([x0, M, W - M, H - M], outline="black")
    d.line([top(q) for q in target], fill=(220, 30, 30), width=3)
    d.line([top(q) for q in root], fill=(30, 80, 200), width=2)
    d.text((x0, 10), f"path (red) and root (blue) from above, {span:.1f} m across", fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)


if __name__ == "__main__":
    raise SystemExit(main())
