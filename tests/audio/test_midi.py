"""audio/midi.py: chroma + beats → chords, bass and drums on the beats → MIDI → audio."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pretty_midi")

from dancekit.audio.midi import arrange, best_triad, pick_beats, render, synthesize  # noqa: E402
from dancekit.errors import ParameterError  # noqa: E402

FPS = 25.0


def _known_piece():
    """8 s: a beat every 12 frames (125 BPM) from frame 6; C major for 4 s, then A minor."""
    T = 200
    chroma = np.full((T, 12), 0.05)
    chroma[:100, [0, 4, 7]] = 1.0  # C E G
    chroma[100:, [9, 0, 4]] = 1.0  # A C E
    beat = np.zeros(T)
    frames = np.arange(6, T, 12)
    beat[frames] = 0.9
    beat[frames + 1] = 0.6  # a shoulder: not a second beat
    return chroma, beat, frames / FPS


def test_best_triad():
    c = np.zeros(12)
    c[[7, 11, 2]] = 1.0
    assert best_triad(c) == (7, False)  # G major
    c = np.zeros(12)
    c[[2, 5, 9]] = 1.0
    assert best_triad(c) == (2, True)  # D minor


def test_pick_beats_finds_the_peaks():
    _, beat, times = _known_piece()
    np.testing.assert_allclose(pick_beats(beat, fps=FPS), times)


def test_known_chroma_and_beats_give_the_expected_chords_and_onsets():
    chroma, beat, times = _known_piece()
    arr = arrange(chroma, beat, fps=FPS)
    np.testing.assert_allclose(arr.beat_times, times)
    assert arr.tempo == pytest.approx(125.0)
    names = arr.chord_names()
    assert len(names) == len(times)
    for name, t in zip(names, times):
        if t + 12 / FPS <= 4.0:  # beat interval entirely in the C major half
            assert name == "C"
        elif t >= 4.0:
            assert name == "Am"
    assert names[0] == "C" and names[-1] == "Am"
    chords, bass, drums = arr.midi.instruments
    onsets = sorted({round(n.start, 6) for n in chords.notes})
    np.testing.assert_allclose(onsets, times)
    first = sorted(n.pitch for n in chords.notes if abs(n.start - times[0]) < 1e-9)
    assert first == [60, 64, 67]  # C4 E4 G4
    last = sorted(n.pitch for n in chords.notes if abs(n.start - times[-1]) < 1e-9)
    assert last == [69, 72, 76]  # A4 C5 E5
    assert [n.pitch % 12 for n in bass.notes] == [r for r, _ in arr.chords]
    assert drums.is_drum
    kick_snare = [n for n in drums.notes if n.pitch in (36, 38)]
    np.testing.assert_allclose([n.start for n in kick_snare], times)
    assert [n.pitch for n in kick_snare[:4]] == [36, 38, 36, 38]


def test_fixed_tempo_is_a_grid_phased_on_the_first_beat():
    chroma, beat, times = _known_piece()
    arr = arrange(chroma, beat, fps=FPS, tempo=100)
    assert arr.tempo == pytest.approx(100.0)
    np.testing.assert_allclose(np.diff(arr.beat_times), 0.6)
    assert times[0] in arr.beat_times


def test_no_beats_fall_back_to_a_grid():
    chroma, _, _ = _known_piece()
    arr = arrange(chroma, np.zeros(len(chroma)), fps=FPS)
    assert arr.tempo == pytest.approx(120.0) and len(arr.beat_times) == 16


def test_builtin_synthesiser_is_audible_not_clipped_and_not_a_sine():
    chroma, beat, times = _known_piece()
    arr = arrange(chroma, beat, fps=FPS)
    y, backend = render(arr.midi, sr=16000, backend="builtin")
    assert backend == "builtin" and y.dtype == np.float32
    assert len(y) >= int(8.0 * 16000)
    assert 0.5 < np.abs(y).max() <= 0.9 and np.sqrt(np.mean(y**2)) > 0.03
    # onsets: the energy right after each beat exceeds the energy just before it
    for t in times[1:-1]:
        a = int(t * 16000)
        assert np.abs(y[a: a + 400]).mean() > np.abs(y[a - 1200: a - 800]).mean()
    # not a sine: a piano note has energy in several harmonics
    import pretty_midi

    pm = pretty_midi.PrettyMIDI()
    inst = pretty_midi.Instrument(program=0)
    inst.notes.append(pretty_midi.Note(velocity=100, pitch=57, start=0.0, end=1.0))  # A3, 220 Hz
    pm.instruments.append(inst)
    spec = np.abs(np.fft.rfft(synthesize(pm, sr=16000)[:16000]))
    hz = np.fft.rfftfreq(16000, 1 / 16000)
    band = [spec[(hz > k * 220 * 0.97) & (hz < k * 220 * 1.03)].max() for k in (1, 2, 3, 4)]
    assert min(band[1:]) > 0.05 * band[0]


def test_bad_input_is_a_named_error():
    from dancekit.errors import ParameterError

    with pytest.raises(ParameterError, match="chroma"):
        arrange(np.zeros((10, 11)), np.zeros(10), fps=FPS)
    with pytest.raises(ParameterError, match="tempo"):
        arrange(np.zeros((10, 12)), np.zeros(10), fps=FPS, tempo="fast")


@pytest.mark.parametrize("bpm", [100.0, 125.0])
@pytest.mark.slow
def test_wav_is_audible_unclipped_and_its_tracked_beats_are_the_midi_beats(bpm):
    """Listen-free check of a composed WAV: librosa's beat tracker on the rendered audio finds the MIDI's beats
    (beat F1 ≥ 0.9 within ±0.1 s, mir_eval) and the tempo (±5 %); the audio is neither silent nor clipped."""
    import librosa

    from dancekit.metrics.music_beats import beat_f1

    T = int(20 * FPS)
    chroma = np.full((T, 12), 0.05)
    chroma[:, [0, 4, 7]] = 1.0
    beat = np.zeros(T)
    period = 60.0 / bpm
    beat[np.round(np.arange(0.3, T / FPS - 0.1, period) * FPS).astype(int)] = 1.0
    arr = arrange(chroma, beat, fps=FPS)
    sr = 22050
    y, _ = render(arr.midi, sr=sr, backend="builtin")
    assert np.sqrt(np.mean(y**2)) > 0.03  # not silent
    assert np.mean(np.abs(y) >= 0.999) < 1e-4  # not clipped
    tempo, frames = librosa.beat.beat_track(y=y.astype(np.float64), sr=sr, units="frames")
    tracked = librosa.frames_to_time(frames, sr=sr)
    assert beat_f1(tracked, arr.beat_times, min_beat_time=2.0) >= 0.9
    assert float(np.atleast_1d(tempo)[0]) == pytest.approx(arr.tempo, rel=0.05)


def _saturated_activation(period_s, seconds=30.0, seed=0):
    """A beat activation like the shipped G_D→M's: above 0.5 on most frames, with a rise to a peak every
    ``period_s`` seconds (not a whole number of frames) and noise; returns (activation, true beat times)."""
    rng = np.random.default_rng(seed)
    T = int(seconds * FPS)
    t = np.arange(T) / FPS
    beats = np.arange(0.37, seconds, period_s)
    dist = np.min(np.abs(t[:, None] - beats[None]), axis=1)
    act = 0.55 + 0.35 * np.exp(-0.5 * (dist / 0.04) ** 2) + rng.normal(0, 0.03, T)
    return np.clip(act, 0, 1), beats


@pytest.mark.parametrize("bpm", [72.0, 103.0, 141.0])
def test_periodic_beats_find_the_period_of_a_saturated_activation(bpm):
    from dancekit.audio.midi import periodic_beats
    from dancekit.metrics.music_beats import beat_f1, tempo_from_beats

    act, truth = _saturated_activation(60.0 / bpm)
    beats, tempo = periodic_beats(act, fps=FPS)
    assert tempo == pytest.approx(bpm, rel=0.02)
    assert tempo_from_beats(beats) == pytest.approx(bpm, rel=0.05)
    assert beat_f1(beats, truth, tolerance=0.05) > 0.95


def test_periodic_tempo_in_arrange_and_its_fallback():
    from dancekit.audio.midi import periodic_beats

    act, _ = _saturated_activation(0.6)
    chroma = np.ones((len(act), 12))
    arr = arrange(chroma, act, fps=FPS, tempo="periodic")
    assert arr.tempo == pytest.approx(100.0, rel=0.05)
    flat = np.full(200, 0.7)  # no periodicity: the default grid, as with no picked beats
    assert len(periodic_beats(flat, fps=FPS)[0]) == 0
    assert arrange(np.ones((200, 12)), flat, fps=FPS, tempo="periodic").tempo == pytest.approx(120.0)


def test_a_very_slow_composition_writes_a_midi_file_with_its_beats_in_place(tmp_path):
    # two beats 25 s apart: 2.4 BPM, whose 25 s per beat do not fit a MIDI header's 24-bit microseconds
    import pretty_midi

    from dancekit.audio.midi import midi_file_tempo

    T = 40 * int(FPS)
    chroma = np.full((T, 12), 0.05)
    chroma[:, [0, 4, 7]] = 1.0
    beat = np.zeros(T)
    beat[[50, 50 + 25 * int(FPS)]] = 0.9
    arr = arrange(chroma, beat, fps=FPS)
    assert arr.tempo == pytest.approx(2.4)
    arr.midi.write(str(tmp_path / "slow.mid"))
    back = pretty_midi.PrettyMIDI(str(tmp_path / "slow.mid"))
    kicks = [n.start for n in back.instruments[2].notes if n.pitch in (36, 38)]
    np.testing.assert_allclose(kicks, [2.0, 27.0], atol=0.01)
    assert back.get_tempo_changes()[1][0] == pytest.approx(38.4)  # 2.4 doubled four times
    assert midi_file_tempo(125.0) == 125.0 and midi_file_tempo(19.2) == pytest.approx(38.4)
    assert midi_file_tempo(500.0) == 250.0
    with pytest.raises(ParameterError):
        midi_file_tempo(0.0)


def test_synthesis_cache_gives_the_same_samples():
    """The per-piece cache of the voices' partials (one computation per pitch) writes the same samples as
    computing every note on its own."""
    import pretty_midi

    from dancekit.audio import midi

    pm = pretty_midi.PrettyMIDI()
    inst, bass = pretty_midi.Instrument(program=0), pretty_midi.Instrument(program=33)
    for k, t in enumerate(np.arange(0.0, 6.0, 0.45)):
        inst.notes.append(pretty_midi.Note(velocity=60 + k, pitch=60 + (k % 3) * 4, start=t, end=t + 0.3 + 0.2 * (k % 4)))
        bass.notes.append(pretty_midi.Note(velocity=90, pitch=36 + (k % 2) * 7, start=t, end=t + 0.4))
    pm.instruments.extend([inst, bass])
    y = synthesize(pm, sr=16000)
    out = np.zeros_like(y, dtype=np.float64)
    for ins, is_bass in ((inst, False), (bass, True)):
        for n in ins.notes:
            tone = midi._tone(n.pitch, n.velocity, n.end - n.start, 16000, bass=is_bass) * (1.4 if is_bass else 0.5)
            a = int(n.start * 16000)
            m = min(len(tone), len(out) - a)
            out[a: a + m] += tone[:m]
    np.testing.assert_array_equal(y, (out * (0.89 / np.abs(out).max())).astype(np.float32))
