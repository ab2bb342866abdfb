"""The dance models stepped frame by frame with their state kept (inference only).

A stepper takes normalised-later feature rows as they come (:meth:`push`, the rows of
:class:`dancekit.live.OnlineFeatures`) and returns the poses ``(k, J, 3)`` (world positions, the model's
skeleton and units) of the frames it can dance now; :meth:`finish` dances the rest at the stream's end.

* :class:`RevolutionStepper` (Dance Revolution): the local self-attention encoder looks ``window // 2`` frames
  ahead in each of its layers (the embedded model: 2 × 50 frames, 4 s at 25 fps). Live, each latent is encoded
  from the music up to ``lookahead`` frames after it (the frames beyond are not there yet: the encoder sees the
  stream's end there, as it sees a song's end offline) and ``context`` frames before it. With ``lookahead`` and
  ``context`` at least the receptive field the latents are the offline ones (each block's new latents are
  computed on the frames they see alone: :meth:`~dancekit.models.revolution.MusicEncoder.forward_range`), and
  the dance — the LSTM decoder stepped with its state carried from block to block — equals one offline pass
  (``tests/live/test_live.py``); the default lookahead is the latency floor's 3 frames, an approximation whose
  cost the quality benchmark measures. A model whose encoder itself looks only ``lookahead`` frames ahead (a
  checkpoint's ``live`` component, ``RevolutionConfig.lookahead``) is stepped exactly: each latent is computed once,
  as its music comes (:class:`~dancekit.models.revolution.StreamingEncoder`), and equals the offline one whatever
  the blocks. The seed draws the initial state; the checkpoint's per-phrase state noise is drawn phrase by
  phrase as the phrases come.
* :class:`Music2DanceStepper` (Music2Dance): the WaveNet is causal; its F_map (convolutions and a BiLSTM) is
  run on the last ``context`` frames up to ``lookahead`` frames ahead, and each frame is stepped with the
  model's own :meth:`~dancekit.models.music2dance.Music2DanceModel.step` and its queues (state carried: one
  offline pass on the same conditions). The samples are smoothed as the checkpoint's ``smooth_sigma`` says
  (:class:`SampleSmoother`: the offline centred Gaussian with its radius held back, or its causal half), then
  the motion is decoded from ``rotations_rootdelta`` with the root's place and heading carried.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from dancekit.errors import ParameterError
from dancekit.live.config import SMOOTHING
from dancekit.motion.kinematics import normalize_bone_lengths
from dancekit.motion.root_delta import RootDeltaDecoder

__all__ = ["SMOOTHING", "Music2DanceStepper", "RevolutionStepper", "SampleSmoother", "make_stepper"]


class _Stepper:
    """What both steppers share: the feature history (normalised) and the frame counters."""

    def __init__(self, pipe, *, lookahead: int, context: int):
        if lookahead < 0 or context < 0:
            raise ParameterError(f"lookahead and context must be >= 0 frames, got {lookahead}, {context}")
        self.pipe = pipe
        self.skeleton = pipe.skeleton
        self.fps = pipe.fps
        self.lookahead, self.context = int(lookahead), int(context)
        self.music = np.zeros((0, pipe.model.config.music_dim), np.float32)  # the history kept
        self.music_start = 0  # frame index of music[0]
        self.n_music = 0  # rows received
        self.n_out = 0  # frames danced

    def _append(self, rows: np.ndarray) -> None:
        rows = self.pipe.stats.normalize_music(np.asarray(rows, np.float32)).astype(np.float32)
        self.music = np.concatenate([self.music, rows])
        self.n_music += len(rows)

    def _trim(self, keep_from: int) -> None:
        cut = keep_from - self.music_start
        if cut > 0:
            self.music = self.music[cut:]
            self.music_start += cut

    def _window(self, a: int, b: int) -> np.ndarray:
        return self.music[a - self.music_start : b - self.music_start]

    @torch.no_grad()
    def push(self, rows: np.ndarray) -> np.ndarray:
        """Feature rows ``(k, D)`` (unnormalised, the checkpoint's preset) in → poses ``(m, J, 3)`` float32 of the
        frames whose lookahead has arrived."""
        self._append(rows)
        return self._dance(max(self.n_out, self.n_music - self.lookahead))

    @torch.no_grad()
    def finish(self) -> np.ndarray:
        """The poses of the frames still waiting for their lookahead (the stream has ended)."""
        return self._dance(self.n_music)

    def _dance(self, upto: int) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


class RevolutionStepper(_Stepper):
    """Dance Revolution stepped frame by frame (see the module's description).

    Parameters
    ----------
    pipe : a :class:`~dancekit.pipelines.revolution.RevolutionPipeline` (``positions3d``)
    lookahead, context : frames of music after / before a frame that its latent sees
    seed : draws the initial decoder state (and the phrase noise)
    variety : the checkpoint's per-phrase state noise (False: the paper's decoding)
    """

    def __init__(self, pipe, *, lookahead: int, context: int, seed: int = 0, variety: bool = True):
        super().__init__(pipe, lookahead=lookahead, context=context)
        if pipe.representation != "positions3d":
            raise ParameterError(f"live dancing needs a positions3d model, {pipe.folder} is {pipe.representation}")
        model = self.model = pipe.model.eval()
        self.generator = torch.Generator().manual_seed(int(seed))
        self.state = model.initial_state(1, generator=self.generator, device="cpu")
        self.prev = model.bop.detach().expand(1, 1, -1)
        v = pipe.variety if variety else None
        self.phrase = v.phrase if v is not None and v.phrase > 0 and v.state_noise > 0 else 0
        self.state_noise = v.state_noise if self.phrase else 0.0
        self.root = np.zeros(2)  # the root's horizontal place (the integrated velocity)
        #: the local encoder's embedding of the music history (1, frames, d), embedded as the rows come
        self.embedded = model.encoder.config.encoder == "local"
        self.emb = torch.zeros(1, 0, model.config.d_model)
        #: with relative positions, the first layer's queries, keys and values of those rows (1, frames, 3d): a
        #: frame's own, computed once as it comes instead of again for every block that looks at it
        self.qkv0 = torch.zeros(1, 0, 3 * model.config.d_model) \
            if self.embedded and model.encoder.config.pos_encoding == "relative" else None
        #: an encoder whose lookahead is this stepper's: each latent computed once, as its music comes
        #: (:class:`~dancekit.models.revolution.StreamingEncoder`), kept from frame ``z_start`` on
        self.stream = None
        if model.encoder.config.pos_encoding == "relative" and self.lookahead == model.encoder.bounded_lookahead:
            from dancekit.models.revolution import StreamingEncoder

            self.stream = StreamingEncoder(model.encoder)
        #: the encoder's frames in NumPy (a live block's few dozen small products cost less there than torch's
        #: calls): then ``emb`` and ``qkv0`` are NumPy arrays of the same shapes
        self.np_encoder = None
        if self.qkv0 is not None and self.stream is None:
            from dancekit.models.revolution import NumpyLocalEncoder

            if NumpyLocalEncoder.usable(model.encoder):
                self.np_encoder = NumpyLocalEncoder.of(model.encoder)
                self.emb = np.zeros((1, 0, model.config.d_model), np.float32)
                self.qkv0 = np.zeros((1, 0, 3 * model.config.d_model), np.float32)
        self.z = torch.zeros(1, 0, model.config.d_model)
        self.z_start = 0
        #: True: the decoded positions as they are (the live stages set the bone lengths); False: rest bone
        #: lengths, as the offline pipeline's ``postprocess`` without its floor
        self.raw = False
        J = self.skeleton.num_joints
        self._vel = slice(3 * J, 3 * J + 2)

    def _append(self, rows: np.ndarray) -> None:
        n = len(self.music)
        super()._append(rows)
        if self.np_encoder is not None and len(self.music) > n:
            e = self.np_encoder.embed_rows(self.music[n:])[None]  # (1, k, d)
            self.emb = np.concatenate([self.emb, e], axis=1)
            self.qkv0 = np.concatenate([self.qkv0, self.np_encoder.projections(e[0])[None]], axis=1)
        elif self.embedded and len(self.music) > n:
            new = torch.from_numpy(np.ascontiguousarray(self.music[n:]))[None]  # (1, k, D)
            e = self.model.encoder.embed(new)
            self.emb = torch.cat([self.emb, e], dim=1)
            if self.qkv0 is not None:
                self.qkv0 = torch.cat([self.qkv0, self.model.encoder.layers[0].projections(e)], dim=1)
            if self.stream is not None:
                self.z = torch.cat([self.z, self.stream.push(e)], dim=1)

    def _trim(self, keep_from: int) -> None:
        start = self.music_start
        super()._trim(keep_from)
        self.emb = self.emb[:, self.music_start - start :]
        if self.qkv0 is not None:
            self.qkv0 = self.qkv0[:, self.music_start - start :]

    def _dance(self, upto: int) -> np.ndarray:
        from dancekit.motion.representations import decode_positions

        t0 = self.n_out
        if upto <= t0:
            return np.zeros((0, self.skeleton.num_joints, 3), np.float32)
        z_end = self.z_start + self.z.shape[1]
        if self.stream is not None and upto <= z_end:  # the streamed latents (every frame but a stream's last few)
            z = self.z[:, t0 - self.z_start : upto - self.z_start]
        else:
            a = max(self.music_start, t0 - self.context)
            b = min(self.n_music, upto + self.lookahead)
            qkv0 = None
            if self.embedded:
                x = self.emb[:, a - self.music_start : b - self.music_start]  # (1, b - a, d)
                if self.qkv0 is not None:
                    qkv0 = self.qkv0[:, a - self.music_start : b - self.music_start]
            else:
                x = torch.from_numpy(np.ascontiguousarray(self._window(a, b)))[None]  # (1, b - a, D)
            if self.np_encoder is not None:
                z = torch.from_numpy(self.np_encoder.forward_range(x[0], t0 - a, upto - a, qkv0=qkv0[0]))[None]
            else:
                z = self.model.encoder.forward_range(x, t0 - a, upto - a, embedded=self.embedded, qkv0=qkv0)
        self.z, self.z_start = self.z[:, max(0, upto - self.z_start) :], max(self.z_start, min(upto, z_end))
        z = self.model._condition(z, None)  # (1, upto - t0, d)
        ys = []
        for p0, p1 in self._pieces(t0, upto):
            if self.phrase and p0 > 0 and p0 % self.phrase == 0:  # a phrase starts: the state mixed with noise
                eps = torch.randn((2,) + tuple(self.state[0].shape), generator=self.generator)
                keep = math.sqrt(1.0 - self.state_noise**2)
                self.state = (keep * self.state[0] + self.state_noise * eps[0],
                              keep * self.state[1] + self.state_noise * eps[1])
            y, self.prev, self.state = self.model._autoregress(z[:, p0 - t0 : p1 - t0], self.prev, self.state)
            ys.append(y[0])
        y = torch.cat(ys).numpy()
        self.n_out = upto
        self._trim(upto - self.context)
        poses = self.pipe.stats.denormalize_dance(y).astype(np.float64)  # (k, P)
        vel = poses[:, self._vel]
        start = self.root.copy()
        self.root = self.root + vel.sum(axis=0)
        pos = decode_positions(poses, self.skeleton).astype(np.float64)  # root path from 0 in this piece
        _, (h0, h1) = _axes(self.skeleton)
        pos[..., h0] += start[0]
        pos[..., h1] += start[1]
        return np.asarray(pos if self.raw else normalize_bone_lengths(pos, self.skeleton), np.float32)

    def _pieces(self, a: int, b: int) -> list[tuple[int, int]]:
        if not self.phrase:
            return [(a, b)]
        cuts = [a, *range((a // self.phrase + 1) * self.phrase, b, self.phrase), b]
        return [(x, y) for x, y in zip(cuts[:-1], cuts[1:]) if y > x]


def _axes(skeleton):
    from dancekit.motion.representations import up_and_horizontal_axes as axes

    return axes(skeleton)


class SampleSmoother:
    """The Gaussian smoothing of sampled feature rows as they come (Music2Dance's ``smooth_sigma``, online).

    Offline, the pipeline smooths the whole dance's first ``columns`` columns along time with a centred
    Gaussian of ``sigma`` frames over ``±r`` frames, ``r = max(1, round(3 sigma))``, the edges replicated
    (:func:`dancekit.models.foot_constraint.gaussian_smooth`); the other columns (the contacts) are left as
    sampled. Online, row ``t`` out is ``Σ_k w_k x_{t+k}`` over ``k = -r … ahead`` with ``w_k ∝ exp(-k² / 2σ²)``
    normalised, the first row replicated before the stream's start and, at its end (``final``), the last one
    after it:

    * ``ahead=True`` (``LiveConfig.sample_smoothing = "delay"``): the centred kernel (``ahead = r``), each row
      given out ``r`` rows after it is sampled — the offline smoothing exactly, ``r / fps`` s more lookahead;
    * ``ahead=False`` (``"causal"``): the kernel's past half (``k = -r … 0``), renormalised — nothing held back,
      a weaker low-pass (at 25 fps and ``sigma = 2``: 36 % of a 5-Hz movement left against 4 %) that lags the
      movement by ``Σ_k |k| w_k`` ≈ 0.65 sigma frames;
    * ``ahead=a`` (an integer, ``0 ≤ a``): the kernel's lags ``-r … min(a, r)``, renormalised — each row held back
      ``min(a, r)`` rows (``0``: ``"causal"``; ``r`` or more: ``"delay"``).

    ``sigma = 0``: the rows as they come.
    """

    def __init__(self, sigma: float, *, ahead: bool | int, columns: int):
        if not sigma >= 0:
            raise ParameterError(f"smoothing sigma must be >= 0 frames, got {sigma!r}")
        self.sigma, self.columns = float(sigma), int(columns)
        self.radius = max(1, int(round(3 * self.sigma))) if self.sigma > 0 else 0
        if isinstance(ahead, bool):
            self.ahead = self.radius if ahead else 0
        elif isinstance(ahead, int) and ahead >= 0:
            self.ahead = min(self.radius, ahead)
        else:
            raise ParameterError(f"the smoothing's hold-back must be True, False or frames >= 0, got {ahead!r}")
        k = np.arange(-self.radius, self.ahead + 1, dtype=np.float64)
        w = np.exp(-0.5 * (k / self.sigma) ** 2) if self.sigma > 0 else np.ones(1)
        self.weights = w / w.sum()  # (radius + ahead + 1,) for the lags -radius … ahead
        self.hist: np.ndarray | None = None  # the rows from (next row out) - radius on

    def push(self, rows: np.ndarray, *, final: bool = False) -> np.ndarray:
        """Rows ``(k, P)`` sampled in → the smoothed rows ``(m, P)`` (float32) whose future rows have come (all of
        them when ``final``)."""
        rows = np.asarray(rows, np.float32)
        if self.radius == 0:
            return rows
        if self.hist is None:
            if not len(rows):
                return rows
            self.hist = np.repeat(rows[:1], self.radius, axis=0)  # the first row before the start
        buf = np.concatenate([self.hist, rows])
        if final:
            buf = np.concatenate([buf, np.repeat(buf[-1:], self.ahead, axis=0)])  # the last row after the end
        m = len(buf) - self.radius - self.ahead  # rows out
        if m <= 0:
            self.hist = None if final else buf
            return np.zeros((0, rows.shape[1]), np.float32)
        win = np.lib.stride_tricks.sliding_window_view(buf[:, : self.columns].astype(np.float64),
                                                       len(self.weights), axis=0)  # (m, columns, lags)
        out = buf[self.radius : self.radius + m].copy()
        out[:, : self.columns] = win @ self.weights
        self.hist = buf[m:] if not final else None
        return out


class Music2DanceStepper(_Stepper):
    """Music2Dance stepped frame by frame (see the module's description).

    Parameters
    ----------
    pipe : a :class:`~dancekit.pipelines.music2dance.Music2DancePipeline`
    lookahead, context : frames of music after / before a frame that its F_map condition sees
    seed : seeds the mixture sampling
    genre : a dance type of the model, or None / "none" (the model's "no type"); the sampling settings are the
        checkpoint's for that genre (temperature, noise correlation, guidance, smoothing), as offline
    smoothing : how the checkpoint's Gaussian smoothing of the samples runs online (:class:`SampleSmoother`):
        ``"delay"`` (centred, each frame held back its radius) or ``"causal"`` (the kernel's past half)
    hold_back : with ``"delay"``, hold each frame back at most this many frames (the kernel's lags beyond it
        dropped and the rest renormalised); None: the kernel's radius (the offline smoothing exactly)
    """

    def __init__(self, pipe, *, lookahead: int, context: int, seed: int = 0, genre: str | None = None,
                 smoothing: str = "delay", hold_back: int | None = None):
        super().__init__(pipe, lookahead=lookahead, context=context)
        if smoothing not in SMOOTHING:
            raise ParameterError(f"smoothing must be one of {', '.join(SMOOTHING)}, got {smoothing!r}")
        model = self.model = pipe.model.eval()
        if model.config.generator != "wavenet":
            raise ParameterError("live dancing runs the Music2Dance WaveNet, not its LSTM baseline")
        if genre in (None, "none", "auto"):
            index = -1
        elif genre in pipe.genres:
            index = pipe.genres.index(genre)
        else:
            raise ParameterError(f"unknown genre {genre!r}; choose from {', '.join(pipe.genres)} or none")
        steer = pipe.genre_sampling.get(genre, {}) if index >= 0 else {}
        self.temperature = float(steer.get("temperature", pipe.temperature))
        self.rho = float(steer.get("noise_correlation", pipe.noise_correlation))
        scale = float(steer.get("genre_scale", pipe.genre_scale))
        sigma = float(steer.get("smooth_sigma", pipe.smooth_sigma))
        ahead = (hold_back if hold_back is not None else True) if smoothing == "delay" else False
        self.smoother = SampleSmoother(sigma, ahead=ahead, columns=model.config.gmm_dim)
        #: frames each danced frame waits for after its own is sampled (the smoothing's lookahead)
        self.delay = self.smoother.ahead
        self.g = model.guided_genre_vector(torch.tensor([index]), 1, torch.device("cpu"), genre_scale=scale)
        self.global_term = model.global_proj(self.g)  # (1, L * 2C)
        self.generator = torch.Generator().manual_seed(int(seed))
        self.queues = model.init_state(1)
        self.weights = model._step_weights()
        self.x = torch.zeros(1, model.config.pose_dim)
        self.eps = None
        self.prev_row: np.ndarray | None = None  # the last decoded feature row and where it left the root
        self.decoder = RootDeltaDecoder(self.skeleton)  # decode_rootdelta's positions, in NumPy
        self.origin = (0.0, 0.0, 0.0)

    @torch.no_grad()
    def finish(self) -> np.ndarray:
        """The poses of the frames still waiting for their lookahead or their smoothing (the stream has ended)."""
        return self._dance(self.n_music, final=True)

    def _dance(self, upto: int, final: bool = False) -> np.ndarray:
        J = self.skeleton.num_joints
        sampled = self._sample(upto)  # (k, P) normalised
        rows = self.smoother.push(sampled, final=final)  # (m, P) normalised, smoothed
        if not len(rows):
            return np.zeros((0, J, 3), np.float32)
        return self._decode(self.pipe.stats.denormalize_dance(rows.astype(np.float64)))

    def _sample(self, upto: int) -> np.ndarray:
        """The model's samples ``(upto - n_out, P)`` (normalised, float32) of the frames up to ``upto``."""
        from dancekit.models.music2dance import standard_normal

        t0 = self.n_out
        if upto <= t0:
            return np.zeros((0, self.model.config.pose_dim), np.float32)
        model, c = self.model, self.model.config
        a = max(self.music_start, t0 - self.context)
        a -= a % 2  # F_map's stride 2: its windows start on even frames (the history is cut on even frames)
        b = min(self.n_music, upto + self.lookahead)
        x = torch.from_numpy(np.ascontiguousarray(self._window(a, b)))[None]
        h = model.music_condition(x)[:, t0 - a : upto - a]  # (1, k, H)
        cond = (model.local_proj(h) + self.global_term[:, None]).reshape(1, upto - t0, c.n_layers, 2 * c.channels)
        frames = []
        for k in range(upto - t0):
            if self.rho > 0 and self.temperature > 0:
                eta = standard_normal((1, c.gmm_dim), generator=self.generator, dtype=torch.float32)
                self.eps = eta if self.eps is None else self.rho * self.eps + math.sqrt(1 - self.rho**2) * eta
            params = model.step(cond[:, k], self.g, self.x, self.queues, self.weights)
            self.x = model.predict(params, temperature=self.temperature, generator=self.generator, noise=self.eps)
            frames.append(self.x[0])
        self.n_out = upto
        self._trim((upto - self.context - 2) // 2 * 2)
        return torch.stack(frames).numpy()

    def _decode(self, poses: np.ndarray) -> np.ndarray:
        """Denormalised feature rows ``(k, P)`` → positions ``(k, J, 3)`` float32, the root's place and heading
        carried on from the rows decoded before."""
        if self.prev_row is None:
            positions, tr = self.decoder(poses, origin=self.origin)
            new = slice(0, None)
        else:
            positions, tr = self.decoder(np.concatenate([self.prev_row[None], poses]), origin=self.origin)
            new = slice(1, None)
        heading = self.origin[2] + float(np.sum(poses[:, 3])) if self.prev_row is not None \
            else self.origin[2] + float(np.sum(poses[1:, 3]))
        up = self.skeleton.up_index
        horiz = [i for i in range(3) if i != up]
        self.origin = (float(tr[-1, horiz[0]]), float(tr[-1, horiz[1]]), heading)
        self.prev_row = poses[-1].copy()
        return np.asarray(positions[new], np.float32)


def make_stepper(pipe, *, lookahead: int, context: int, seed: int = 0, genre: str | None = None,
                 smoothing: str = "delay", hold_back: int | None = None):
    """The stepper of a loaded dance pipeline (Dance Revolution or Music2Dance; ``smoothing`` and ``hold_back``:
    Music2Dance's, :class:`SampleSmoother`)."""
    from dancekit.models.music2dance import Music2DanceModel
    from dancekit.models.revolution import RevolutionModel

    if isinstance(pipe.model, RevolutionModel) or isinstance(getattr(pipe, "_fp32_model", None), RevolutionModel):
        if genre not in (None, "none", "auto"):
            raise ParameterError("live Dance Revolution dances the model alone (its genre models need the whole song)")
        return RevolutionStepper(pipe, lookahead=lookahead, context=context, seed=seed)
    if isinstance(pipe.model, Music2DanceModel):
        return Music2DanceStepper(pipe, lookahead=lookahead, context=context, seed=seed, genre=genre,
                                  smoothing=smoothing, hold_back=hold_back)
    raise ParameterError(f"live dancing runs Dance Revolution and Music2Dance models, not {type(pipe.model).__name__}")
