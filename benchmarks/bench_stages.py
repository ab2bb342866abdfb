"""The pipeline stages (issue 15) measured: beat sync and clean-up on the test songs and on songs outside
the dataset, with the embedded default model.

    PYTHONPATH=src python benchmarks/bench_stages.py --data data/tang2018 --music ../shared/music \
        --seeds 5 -o runs/stages

For every song (the test split's song excerpts and the three songs of ``--music``) and seed, three dances:
``raw`` (the model's own output, stages off), ``cleanup`` (clean-up only: ``--beat-sync off``) and ``on``
(clean-up and beat sync, the default). Per dance: beat metrics against the song's tracked beats (BAS,
hit rate), jerk and jitter, foot skating, the floor metrics against the *local floor* (the lowest point
of the lowest joint within ±1 s): the lowest joint's median height and its share within 2 cm, the
planted-foot share (per foot and frame: its lowest joint of ankle, heel and toe within 3 cm of the local floor and moving slower than 0.15 m/s), the farthest
distance of the root from its start, the knee angles (180° = straight), and FID_k / FID_g of each
variant's dances against the training dances (10-s segments). The real test dances are measured the same
way. Also a 20-minute song (the three songs repeated), danced raw and with the stages.

Writes ``OUT/stages.json``, ``OUT/table.md`` and ``docs/stages.png`` (``--plot``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from dancekit.audio import load, save_wav
from dancekit.data import PreparedData
from dancekit.metrics import beat_metrics, foot_skating, jitter
from dancekit.metrics import fid as fid_mod
from dancekit.motion.analysis import mean_joint_speed
from dancekit.motion.floor import floor_gap_cm, planted_share
from dancekit.pipelines import load_pipeline, stages

SONGS = ("Kevin_MacLeod_-_Vibe_Ace.ogg", "brahms_hungarian_dance_5.ogg",
         "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg")
VARIANTS = ("raw", "cleanup", "on")


def knee_angles(p: np.ndarray, sk) -> np.ndarray:
    """(T, 2) knee angles in degrees (180 = straight leg), left and right."""
    out = []
    for side in ("left", "right"):
        hip, knee, ankle = (p[:, sk.index(f"{side}_{j}")] for j in ("hip", "knee", "ankle"))
        a, b = hip - knee, ankle - knee
        cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1) + 1e-12)
        out.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return np.stack(out, axis=1)


def physical(p: np.ndarray, sk, fps: float) -> dict[str, float]:
    """Floor, planted ankles, travel and knee metrics of one dance ``(T, J, 3)`` in skeleton units."""
    above = floor_gap_cm(p, skeleton=sk, fps=fps)  # (T,) cm over the lowest point within ±1 s
    root = p[:, sk.root][:, [0, 2]]
    dist = np.hypot(*(root - root[0]).T) * sk.unit_scale
    knees = knee_angles(p, sk)
    return {
        "floor_median_cm": float(np.median(above)),
        "floor_within_2cm": float(np.mean(above <= 2.0)),
        "planted_foot_share": planted_share(p, skeleton=sk, fps=fps),  # within 3 cm of the local floor, < 0.15 m/s
        "max_distance_m": float(dist.max()),
        "knee_min_deg": float(knees.min()),
        "knee_p5_deg": float(np.percentile(knees, 5)),
        "knee_median_deg": float(np.median(knees)),
    }


def dance_row(motion, beats: np.ndarray | None) -> dict[str, float]:
    p = np.asarray(motion.to_positions(), np.float64)
    sk, fps = motion.skeleton, motion.fps
    row = physical(p, sk, fps)
    j = jitter(p, fps=fps, skeleton=sk)
    row.update({"jerk": j["jerk"], "jitter": j["speed_residual"],
                "foot_skating": foot_skating(p, fps=fps, skeleton=sk)["ratio"]})
    if beats is not None:
        b = beat_metrics(p, beats, fps=fps, skeleton=sk)
        row.update({"bas": b["bas_bailando"], "hit_rate": b["beat_hit_rate"]})
    return row


def fids(dances: list[np.ndarray], reference: list[np.ndarray], fps: float, sk,
         cache: dict[str, np.ndarray] | None = None) -> dict[str, float]:
    """FID_k and FID_g of ``dances`` against ``reference``; ``cache``: a dict that keeps the reference's
    feature sets between calls (the same reference, fps and skeleton each time)."""
    out = {}
    cache = {} if cache is None else cache
    for kind, short in (("kinetic", "k"), ("geometric", "g")):
        if kind not in cache:
            cache[kind] = fid_mod.feature_sets(reference, fps=fps, skeleton=sk, kind=kind, segment_seconds=10.0)
        fr = cache[kind]
        fp = fid_mod.feature_sets(dances, fps=fps, skeleton=sk, kind=kind, segment_seconds=10.0)
        fr_z, fp_z, _ = fid_mod.normalize_features(fr, fp)
        out[f"fid_{short}"] = float(fid_mod.frechet_distance(fp_z, fr_z))
    return out


def energy_gain(res) -> float:
    """The energy stage's gain from a :class:`~dancekit.pipelines.base.DanceResult`'s notes (1.0 when it did
    not lift the dance)."""
    return next((float(n.split("gain ")[1].split()[0]) for n in res.notes if n.startswith("energy lifted")), 1.0)


def mean_rows(rows: list[dict]) -> dict[str, float]:
    return {k: float(np.nanmean([r[k] for r in rows])) for k in rows[0]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--music", required=True)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--long-minutes", type=float, default=20.0)
    ap.add_argument("--plot", default="docs/stages.png")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = PreparedData(args.data)
    pipe = load_pipeline()
    sk = pipe.skeleton
    fps = pipe.fps
    reference = [np.asarray(data.motion(n).to_positions(), np.float64) for n in data.names("train")]

    songs: list[tuple[str, str, float | None, float | None]] = []
    for name in data.names("test"):
        ref = data.audio(name)
        songs.append((f"test:{name}", str(ref.path), ref.start, ref.end))
    for s in SONGS:
        songs.append((f"song:{s[:24]}", str(Path(args.music) / s), None, None))

    per: dict[str, dict[str, list[dict]]] = {}
    positions: dict[str, dict[str, list[np.ndarray]]] = {"test": {v: [] for v in VARIANTS},
                                                         "song": {v: [] for v in VARIANTS}}
    timing = {"stages_s": 0.0, "cleanup_s": 0.0, "seconds": 0.0}
    plot_case = None
    for label, path, start, end in songs:
        beats = stages.song_beats_for(path, start=start, end=end)
        per[label] = {v: [] for v in VARIANTS}
        per[label]["clarity"] = beats.clarity
        for k in range(args.seeds):
            raw = pipe(path, seed=k, start=start, end=end, beat_sync=False, cleanup=False)
            t0 = time.perf_counter()
            cleaned = stages.clean_up(raw)
            t1 = time.perf_counter()
            on = stages.beat_sync(cleaned, path, start=start, end=end, beats=beats)
            t2 = time.perf_counter()
            timing["cleanup_s"] += t1 - t0
            timing["stages_s"] += t2 - t0
            timing["seconds"] += raw.motion.duration
            for v, res in zip(VARIANTS, (raw, cleaned, on), strict=True):
                per[label][v].append({**dance_row(res.motion, beats.times), "note": "; ".join(res.notes)})
                positions[label.split(":")[0]][v].append(np.asarray(res.motion.to_positions(), np.float64))
            if plot_case is None and label.startswith("song:Kevin_MacLeod_-_Vibe"):
                plot_case = (cleaned.motion, on.motion, beats.times)
        print(label, {v: {m: round(x, 3) for m, x in mean_rows([{a: b for a, b in r.items() if a != "note"}
                                                               for r in per[label][v]]).items()}
                      for v in ("raw", "on")}, flush=True)

    real = {}
    for name in data.names("test"):
        m = data.motion(name)
        beats_real = np.asarray(data.features(name, "revolution")["beat_times"], np.float64)
        real[name] = dance_row(m, beats_real)

    summary: dict[str, dict] = {}
    for group in ("test", "song"):
        summary[group] = {}
        for v in VARIANTS:
            rows = [{a: b for a, b in r.items() if a != "note"} for lab in per if lab.startswith(group)
                    for r in per[lab][v]]
            summary[group][v] = {**mean_rows(rows), **fids(positions[group][v], reference, fps, sk)}
            summary[group][v]["knee_min_deg_range"] = [float(min(r["knee_min_deg"] for r in rows)),
                                                       float(max(r["knee_min_deg"] for r in rows))]
    real_rows = list(real.values())
    summary["real_test"] = {**mean_rows(real_rows), **fids([np.asarray(data.motion(n).to_positions(), np.float64)
                                                            for n in data.names("test")], reference, fps, sk)}
    summary["real_test"]["knee_min_deg_range"] = [float(min(r["knee_min_deg"] for r in real_rows)),
                                                  float(max(r["knee_min_deg"] for r in real_rows))]

    # a 20-minute song: the three songs, repeated
    pieces = []
    sr = 22050
    total = 0
    while total < args.long_minutes * 60 * sr:
        for s in SONGS:
            y, _ = load(Path(args.music) / s, sr=sr)
            pieces.append(y)
            total += len(y)
    long_path = out / "long_song.wav"
    save_wav(long_path, np.concatenate(pieces)[: int(args.long_minutes * 60 * sr)], sr=sr)
    t0 = time.perf_counter()
    long_raw = pipe(str(long_path), seed=0, beat_sync=False, cleanup=False)
    t1 = time.perf_counter()
    long_on = stages.beat_sync(stages.clean_up(long_raw), long_path)
    t2 = time.perf_counter()
    long = {v: physical(np.asarray(r.motion.to_positions(), np.float64), sk, fps)
            for v, r in (("raw", long_raw), ("on", long_on))}
    long["minutes"] = long_raw.motion.duration / 60
    long["generation_s"] = t1 - t0
    long["stages_s"] = t2 - t1
    long["note"] = "; ".join(long_on.notes)
    summary["long_song"] = long
    summary["timing"] = timing
    (out / "stages.json").write_text(json.dumps({"summary": summary, "per_song": per, "real": real}, indent=1))
    print(json.dumps(summary, indent=1))
    if args.plot and plot_case is not None:
        plot(Path(args.plot), plot_case, long_raw.motion, long_on.motion, per, real)


# ---------------------------------------------------------------------------------------------- the plot


def plot(path: Path, case, long_raw, long_on, per, real) -> None:
    """Three panels, drawn with Pillow: speed and beats before / after the warp (10 s of Vibe Ace), the
    root path of the 20-minute song raw / cleaned up, the knee-angle distribution real / generated."""
    from PIL import Image, ImageDraw

    W, H = 1500, 460
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)

    def frame(x0, y0, w, h, title):
        d.rectangle([x0, y0, x0 + w, y0 + h], outline="black")
        d.text((x0 + 4, y0 - 16), title, fill="black")

    # panel 1: mean joint speed, 10 s, before / after, music beats
    cleaned, warped, beats = case
    fps = cleaned.fps
    s0 = mean_joint_speed(cleaned.to_positions(), fps=fps)
    s1 = mean_joint_speed(warped.to_positions(), fps=fps)
    a, b = int(20 * fps), int(30 * fps)
    x0, y0, w, h = 40, 40, 560, 170
    top = max(s0[a:b].max(), s1[a:b].max())
    for row, (sp, col, name) in enumerate(((s0, (200, 60, 60), "before the warp"), (s1, (40, 90, 200), "after"))):
        oy = y0 + row * (h + 40)
        frame(x0, oy, w, h, f"mean joint speed, Vibe Ace 20-30 s, {name}; grey: the song's beats")
        for t in beats[(beats >= a / fps) & (beats <= b / fps)]:
            x = x0 + (t * fps - a) / (b - a) * w
            d.line([x, oy, x, oy + h], fill=(170, 170, 170))
        pts = [(x0 + i / (b - a) * w, oy + h - sp[a + i] / top * (h - 6)) for i in range(b - a)]
        d.line(pts, fill=col, width=2)
        mins = [i for i in range(1, b - a - 1) if sp[a + i] < sp[a + i - 1] and sp[a + i] < sp[a + i + 1]]
        for i in mins:
            x, y = pts[i]
            d.ellipse([x - 4, y - 4, x + 4, y + 4], outline=col, width=2)

    # panel 2: root paths of the 20-minute song (top view, metres)
    x0, y0, w, h = 650, 40, 380, 380
    minutes = long_raw.duration / 60
    frame(x0, y0, w, h, f"root path, {minutes:.0f}-min song (red raw, blue cleaned up); circles 4 m, 15 m")
    sk = long_raw.skeleton
    r0 = long_raw.to_positions()[:, sk.root][:, [0, 2]] * sk.unit_scale
    r1 = long_on.to_positions()[:, sk.root][:, [0, 2]] * sk.unit_scale
    r0, r1 = r0 - r0[0], r1 - r1[0]
    span = 16.0
    cx, cy = x0 + w / 2, y0 + h / 2

    def to_px(q):
        return [(cx + u / span * w / 2, cy - v / span * h / 2) for u, v in q]

    for rad, col in ((4.0, (150, 200, 150)), (15.0, (230, 150, 150))):
        rr = rad / span * w / 2
        d.ellipse([cx - rr, cy - rr, cx + rr, cy + rr], outline=col)
    inside = np.abs(r0).max(axis=1) < span
    d.line(to_px(r0[inside][::5]), fill=(200, 60, 60), width=1)
    d.line(to_px(r1[::5]), fill=(40, 90, 200), width=1)
    far = float(np.hypot(*r0[-1]))
    d.text((x0 + 6, y0 + h - 16), f"raw: ends {far:.0f} m from its start (drawn within 16 m)", fill=(200, 60, 60))

    # panel 3: knee angle at the 5th percentile per dance, real test dances vs generated (test songs)
    x0, y0, w, h = 1080, 40, 390, 380
    frame(x0, y0, w, h, "knee angle (deg), 5th percentile per dance")
    groups = [("real", [r["knee_p5_deg"] for r in real.values()], (60, 140, 60))]
    for v, col in (("raw", (200, 60, 60)), ("on", (40, 90, 200))):
        groups.append((f"model {v}", [r["knee_p5_deg"] for lab in per if lab.startswith("test") for r in per[lab][v]], col))
    lo, hi = 40.0, 180.0
    for i, (name, vals, col) in enumerate(groups):
        gx = x0 + 60 + i * 110
        d.text((gx - 20, y0 + h - 16), name, fill=col)
        for v in vals:
            y = y0 + h - 24 - (v - lo) / (hi - lo) * (h - 40)
            d.ellipse([gx - 4, y - 4, gx + 4, y + 4], outline=col, width=2)
    for tick in range(40, 181, 20):
        y = y0 + h - 24 - (tick - lo) / (hi - lo) * (h - 40)
        d.text((x0 + 4, y - 6), str(tick), fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)


if __name__ == "__main__":
    main()
