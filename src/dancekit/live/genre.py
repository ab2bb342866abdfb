"""The genre of the music heard so far (:class:`OnlineGenreReader`), and the jitter cap it gives live.

Offline, a checkpoint's music attribute classifier (its ``genre_reader`` component) reads the whole song
(:meth:`~dancekit.models.music_attributes.MusicAttributeClassifier.predict_song`: windows of ``config.window``
frames, hop ``window // 2``, the last flush with the end; the softmax of their mean log-probability), and the
jitter cap (:func:`dancekit.pipelines.stages.genre_jitter_cap`) follows from that posterior. Live, the same
reading is made of the prefix heard so far, every ``every_s`` seconds of music from ``after_s`` on: the
windows that are complete are read once and kept, the one flush with the end again at each reading, so that a
reading equals ``predict_song`` of the prefix.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from dancekit.errors import ParameterError

__all__ = ["OnlineGenreReader"]


class OnlineGenreReader:
    """The genre posterior of a live session's music (see the module's description).

    Parameters
    ----------
    reader : the checkpoint's music attribute classifier (a ``MusicAttributePipeline``: its model, class names
        and normalisation statistics)
    genres : the genres the dance model knows; the posterior is renormalised over those the reader has
    after_s : the first reading is made once this much music has come (s, ≥ 0)
    every_s : later readings every this much music (s, > 0)
    """

    def __init__(self, reader, *, genres: tuple[str, ...], after_s: float = 4.0, every_s: float = 1.0):
        if not after_s >= 0 or not every_s > 0:
            raise ParameterError(f"the genre reader needs after_s >= 0 and every_s > 0 s, got {after_s!r}, {every_s!r}")
        self.model = reader.model.eval()
        self.mean = np.asarray(reader.music_mean, np.float32)
        self.std = np.asarray(reader.music_std, np.float32)
        self.classes = tuple(reader.genres)
        self.keep = [i for i, g in enumerate(self.classes) if g in genres]
        self.fps = float(reader.fps)
        self.window = int(self.model.config.window)
        self.hop = max(1, self.window // 2)
        self.first = max(int(np.ceil(after_s * self.fps - 1e-9)), self.model.min_frames())
        self.every = max(1, int(round(every_s * self.fps)))
        self.rows = np.zeros((0, len(self.mean)), np.float32)  # normalised rows from frame ``start`` on
        self.start = 0
        self.n = 0  # rows received
        self.done: list[torch.Tensor] = []  # log-probabilities of the complete windows, in order
        self.next_read = self.first
        #: the newest posterior (genre → p over the dance model's genres), empty before the first reading
        self.probs: dict[str, float] = {}
        #: the rows heard at the newest reading
        self.heard = 0

    def push(self, rows: np.ndarray) -> bool:
        """Raw feature rows ``(k, D)`` (the reader's preset, unnormalised) in; True when a new reading was made
        (:attr:`probs`)."""
        rows = np.asarray(rows, np.float32)
        if not len(rows):
            return False
        norm = ((rows - self.mean) / self.std).astype(np.float32)
        self.rows = np.concatenate([self.rows, norm])
        self.n += len(rows)
        if self.n < self.next_read:
            return False
        while self.n >= self.next_read:
            self.next_read += self.every
        self._complete_windows()
        self.probs = self._read()
        self.heard = self.n
        return True

    @torch.no_grad()
    def _logp(self, windows: list[np.ndarray]) -> torch.Tensor:
        x = torch.from_numpy(np.stack(windows))
        return F.log_softmax(self.model(x), dim=-1)  # (W, n_classes)

    def _complete_windows(self) -> None:
        """Read each window ``[s, s + window)`` (s a multiple of the hop) that is complete and not read yet; drop
        the rows no later window needs."""
        w, h = self.window, self.hop
        s = len(self.done) * h
        new = []
        while s + w <= self.n:
            new.append(self.rows[s - self.start: s - self.start + w])
            s += h
        if new:
            self.done.extend(self._logp(new))
        # the rows kept: from the next complete window's start, or the window flush with the end
        keep = min(len(self.done) * h, max(0, self.n - w))
        if keep > self.start:
            self.rows = self.rows[keep - self.start:]
            self.start = keep

    def _read(self) -> dict[str, float]:
        w, n = self.window, self.n
        if n <= w:  # one window: the whole prefix
            logp = self._logp([self.rows[:n - self.start]])
        else:
            parts = list(self.done)
            if (n - w) % self.hop:  # the window flush with the end (else it is the last complete one)
                parts.append(self._logp([self.rows[n - w - self.start:]])[0])
            logp = torch.stack(parts)
        p = torch.softmax(logp.mean(0), dim=0).numpy().astype(np.float64)
        probs = {self.classes[i]: float(p[i]) for i in self.keep}
        total = sum(probs.values())
        return {g: v / total for g, v in probs.items()} if total > 0 else {}
