"""Synthetic test signals that are not music: speech-like babble and white noise (seeded, float32)."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter


def white_noise(*, seconds: float, sr: int = 22050, seed: int = 0, level: float = 0.3) -> np.ndarray:
    """Gaussian white noise ``(n,)`` float32 at RMS ``level``."""
    return (level * np.random.default_rng(seed).standard_normal(int(seconds * sr))).astype(np.float32)


def _resonator(x: np.ndarray, *, freq: float, bandwidth: float, sr: int) -> np.ndarray:
    r = np.exp(-np.pi * bandwidth / sr)
    a = [1.0, -2 * r * np.cos(2 * np.pi * freq / sr), r * r]
    return lfilter([1 - r], a, x)


def speech_like(*, seconds: float, sr: int = 22050, seed: int = 0) -> np.ndarray:
    """Speech-like babble ``(n,)`` float32, peak 0.5: syllables of 80–350 ms at irregular intervals (pauses
    of 30–450 ms), each a glottal pulse train with a gliding pitch (90–230 Hz) through three formant
    resonators that move from syllable to syllable, often led by a short fricative noise burst."""
    rng = np.random.default_rng(seed)
    n = int(seconds * sr)
    y = np.zeros(n)
    t = int(rng.uniform(0.02, 0.2) * sr)
    while t < n:
        length = int(rng.uniform(0.08, 0.35) * sr)
        seg = np.zeros(length)
        if rng.random() < 0.5:  # fricative onset
            k = int(rng.uniform(0.02, 0.08) * sr)
            noise = rng.standard_normal(min(k, length)) * 0.3
            seg[: noise.size] += _resonator(noise, freq=rng.uniform(3000, 6000), bandwidth=2000, sr=sr)
        f0 = np.linspace(rng.uniform(110, 230), rng.uniform(90, 200), length)
        phase = np.cumsum(f0 / sr)
        pulses = np.diff(np.floor(phase), prepend=0.0)  # one impulse per glottal period
        voiced = pulses * np.hanning(length)
        for freq, bw in ((rng.uniform(300, 900), 80), (rng.uniform(900, 2500), 120), (rng.uniform(2300, 3200), 200)):
            seg += _resonator(voiced, freq=freq, bandwidth=bw, sr=sr)
        end = min(n, t + length)
        y[t:end] += seg[: end - t]
        t = end + int(rng.uniform(0.03, 0.45) * sr)
    return (0.5 * y / max(np.abs(y).max(), 1e-9)).astype(np.float32)
