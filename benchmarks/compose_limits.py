"""What limits `dancekit compose` on tang2018: the music's beat phase in the dance, and the notes accuracy a composer
that does not hear the music can reach (issue 41; docs/research/dual.md, "Music that follows the dance, second
round").

    python benchmarks/compose_limits.py [--data data/tang2018] [--splits train val] [--model dual]
                                        [--studies phase notes]

Never reads the test split unless it is asked for. Per dance of the splits: the real music's beats (tracked on its
audio as `dancekit evaluate --compose` tracks them), its notes (its `dual` target arranged, the reference of the
notes accuracy) and the dance's kinematic beats. Then:

* **phase**: a metronome at the real music's tempo (the oracle tempo) phased on a curve of the dance, where its
  mean over the metronome's clicks is highest, then moved by a share of a beat (−0.5 … +0.45); its beat F1 against
  the real beats (±0.1 s), the mean over the dances per offset, beside the mean over every phase (a random phase);
  the best offset chosen on one half of the dances (even / odd positions) scored on the other half. Two curves:
  the body's speed dips relative to their 1-s mean (``dancekit.pipelines.compose.metre_pulse_of``) and the
  negative mean joint speed itself (``dancekit.motion.analysis.mean_joint_speed``, whose minima are the
  kinematic beats);
* **notes**: the notes accuracy of music arranged by ``dancekit.audio.arrange.follow_dance`` (one triad of the key
  per bar) from (a) the real music's chroma in its own key (estimated from that chroma), (b) the tonic of that key
  alone, (c) G_D→M's chroma (seed 0) in each of the 24 keys, and (d) the tonic alone in each of the 24 keys (the
  mean over the keys: what a composer that does not know the key can expect); and where each real piece's tonic
  lands once transposed to C major / A minor (the metric's transposition).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def chroma_key(chroma: np.ndarray) -> tuple[int, bool]:
    """Krumhansl–Schmuckler key (tonic, minor) of a chroma sequence (its summed profile)."""
    from dancekit.metrics.music import KK_MAJOR, KK_MINOR

    h = np.asarray(chroma, np.float64).sum(0)
    best = (-2.0, 0, False)
    for minor, profile in ((False, KK_MAJOR), (True, KK_MINOR)):
        for t in range(12):
            r = float(np.corrcoef(h, np.roll(profile, t))[0, 1])
            if r > best[0]:
                best = (r, t, minor)
    return best[1], best[2]


def tonic_place(notes: np.ndarray) -> str:
    """Where a piece's tonic triad's top note lands after the metric's transposition (G4 / G5 major, E4 / E5 minor)."""
    from dancekit.metrics.music import estimate_key, transpose_to_c

    tonic, mode, _ = estimate_key(notes)
    _, shift = transpose_to_c(notes)
    top = 60 + tonic + shift + 7  # the fifth of the tonic triad voiced from middle C (dancekit.audio.midi.arrange)
    return ["C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B"][top % 12] + str(top // 12 - 1) \
        + (" minor" if mode == "minor" else " major")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=str(ROOT / "data" / "tang2018"))
    p.add_argument("--splits", nargs="+", default=["train", "val"])
    p.add_argument("--model", default="dual", help="the dual model whose G_D→M composes (default: dual)")
    p.add_argument("--studies", nargs="+", default=["phase", "notes"], choices=("phase", "notes"))
    args = p.parse_args()

    from dancekit.audio.arrange import follow_dance
    from dancekit.audio.io import load
    from dancekit.data import PreparedData
    from dancekit.evaluation.music import audio_piece
    from dancekit.metrics import music_beats as mb
    from dancekit.metrics.music import note_array, notes_accuracy
    from dancekit.motion.analysis import mean_joint_speed
    from dancekit.pipelines.compose import metre_pulse_of, phase_pulse_of, pulse_of
    from dancekit.pipelines.dual import ComposePipeline

    data = PreparedData(args.data)
    pipe = ComposePipeline.from_pretrained(args.model)
    offsets = np.arange(-0.5, 0.5, 0.05)
    curves = {"speed dips (metre_pulse_of)": lambda m: metre_pulse_of(m),
              "-mean joint speed": lambda m: -mean_joint_speed(m.to_positions(), fps=m.fps)}
    phase_rows: dict[str, list] = {k: [] for k in curves}
    random_phase, notes_rows, places = [], [], {}
    for split in args.splits:
        for name in data.names(split):
            motion = data.motion(name)
            fps, T = motion.fps, motion.num_frames
            duration = T / fps
            a = data.audio(name)
            y, _ = load(a.path, sr=mb.DETECTOR_SR, start=a.start, end=a.end)
            real = audio_piece(np.asarray(y, np.float32), sr=mb.DETECTOR_SR)
            rb = real.beats[real.beats < duration]
            ref = real.notes[real.notes[:, 0] < duration].copy()
            ref[:, 1] = np.minimum(ref[:, 1], duration)
            places[name] = tonic_place(ref)
            # phase: the oracle tempo, phased on a curve of the dance, moved by a share of a beat
            period = 60.0 / mb.tempo_from_beats(rb)
            t = np.arange(T) / fps
            phases = np.arange(0.0, period, 0.5 / fps)
            if "phase" in args.studies:
                for label, curve in curves.items():
                    c = curve(motion)
                    best = phases[int(np.argmax([np.interp(np.arange(ph, duration, period), t, c).mean()
                                                 for ph in phases]))]
                    phase_rows[label].append([mb.beat_f1(np.arange(best + (o - 1) * period, duration, period), rb)
                                              for o in offsets])
                random_phase.append(np.mean([mb.beat_f1(np.arange(ph, duration, period), rb) for ph in phases]))
                print(f"{split} {name}: phase done", flush=True)
            if "notes" not in args.studies:
                continue
            # notes: arranged from the real chroma / tonic in the real key, G_D→M's chroma / tonic in every key
            feats = data.features(name, "dual")
            names = [str(n).split(":")[0] for n in feats["names"]]
            col = sum(int(str(n).split(":")[1]) for n in feats["names"][: names.index("chroma_harmonic")])
            chroma = feats["features"][:T, col: col + 12]
            n = min(T, len(chroma))
            key = chroma_key(chroma[:n])
            common = {"fps": fps, "phase_pulse": phase_pulse_of(motion)[:n], "metre_pulse": metre_pulse_of(motion)[:n]}
            pulse = pulse_of(motion)[:n]

            def acc(arr, ref=ref) -> float:
                return notes_accuracy(note_array(arr.midi), ref, fps=25.0)

            composed = pipe(motion, seed=0)
            row = {"real chroma, real key": acc(follow_dance(pulse, key=key, chroma=chroma[:n], **common)),
                   "tonic, real key": acc(follow_dance(pulse, key=key, **common))}
            common = {"fps": fps, "phase_pulse": phase_pulse_of(motion), "metre_pulse": metre_pulse_of(motion)}
            keys = [(k, m) for k in range(12) for m in (False, True)]
            row["G_D→M chroma, mean over 24 keys"] = float(np.mean(
                [acc(follow_dance(pulse_of(motion), key=k, chroma=composed.chroma, **common)) for k in keys]))
            row["tonic, mean over 24 keys"] = float(np.mean([acc(follow_dance(pulse_of(motion), key=k, **common))
                                                            for k in keys]))
            notes_rows.append((split, name, row))
            print(f"{split} {name}: tonic at {places[name]}; " + ", ".join(f"{k} {v:.3f}" for k, v in row.items()),
                  flush=True)
    for label, rows in phase_rows.items():
        if not rows:
            continue
        a = np.asarray(rows)
        half = np.arange(len(a)) % 2 == 0
        print(f"\nphase on {label} ({len(a)} dances, oracle tempo): random phase {np.mean(random_phase):.3f}")
        for o, v in zip(offsets, a.mean(0)):
            print(f"  offset {o:+.2f} beat: beat F1 vs real beats {v:.3f}")
        for pick, score in ((half, ~half), (~half, half)):
            k = int(np.argmax(a[pick].mean(0)))
            print(f"  chosen on one half: {offsets[k]:+.2f} beat -> {a[score][:, k].mean():.3f} on the other half "
                  f"(random phase there {np.mean(np.asarray(random_phase)[score]):.3f})")
    if not notes_rows:
        return 0
    print("\nnotes accuracy (mean over dances):")
    for split in args.splits:
        rows = [r for s, _, r in notes_rows if s == split]
        print(f"  {split}: " + ", ".join(f"{k} {np.mean([r[k] for r in rows]):.3f}" for k in rows[0]))
    counts: dict[str, int] = {}
    for v in places.values():
        counts[v] = counts.get(v, 0) + 1
    print("where the real pieces' tonic lands after the transposition:", counts)
    return 0


if __name__ == "__main__":
    sys.exit(main())
