"""troupe's live partner: `motion_control_live` (`docs/spec/magnet.md` §5.4) as a stream. The
user's frames come in as they happen; the partner's frames go out chunk by chunk. Mirrored by
`src/magnet/live.rs`, which is tested against this.

The official loop is an offline loop over a whole clip: the user (person 0) is ground truth over
every window, the partner (person 1) is generated in rolling chunks of `Tm` tokens that keep the
previous chunk's last `Tc` tokens as context and generate the next `Tm - Tc`. A stream differs
where the offline loop reads what a stream cannot have, each a documented choice:

1. **The user's tokens** are encoded from the frames received so far: chunk `c` encodes the
   user's frames `[4 (w0 - E), 4 (w0 + Tm))` (`w0 = c (Tm - Tc)` the window's first token, `E`
   tokens of left context, enough for the encoder's receptive field) on their own, and takes the
   last `Tm` tokens. The offline loop encodes the whole clip at once, so its last tokens of a
   window also see frames after it.
2. **The user's partner-relative transforms** (`T_self_canonical_partner_canonical`, part of each
   token) need the partner, who is being generated. They are taken from the partner's own
   relative transforms, inverted, where the partner is context (given or generated), and held at
   the last such frame over the tokens being generated. The offline loop reads the real partner.
3. **Draws.** Each chunk draws its window's starting noise `[1, Tm, P, D]`, then one DDIM `z`
   per network call (§3.5 draws the starting noise of the whole clip once).
4. **Guidance progress** counts the calls of one chunk (the released `{0, 1}` ratios guide every
   call either way).
5. **Emission.** `final` (the default) emits a token once no later chunk changes it: the window's
   first `Tm - Tc` tokens, decoded with the rest of the window as right context. `early` emits
   each chunk's generated tokens at once, 4 Tc frames sooner; the next chunk's smoothing still
   changes them, and the change is not sent.
6. **Decoding** runs over the last `L` emitted tokens (left context), the tokens emitted and the
   window's later tokens (right context), not the whole clip at once.
7. **Roots.** The partner's opening frames are given (its first `Tc` tokens); later roots chain the
   predicted canonical transitions from the last given canonical frame (§11 A2's online default).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from troupe_onnx.magnet.layout import FRAMES_PER_TOKEN, TOKEN_TRANSFORMS, TRANSFORM
from troupe_onnx.magnet.motion import Decoded, Stats, clip_from_frames, frames_from_decoded
from troupe_onnx.magnet.tasks import Run, Sampling, live_matrix, rolling_chunk
from troupe_onnx.magnet.transforms import compose, from_9d, inverse, to_9d

ENCODER_CONTEXT_TOKENS = 24  # the VQ encoder reaches about 21 tokens back
DECODER_CONTEXT_TOKENS = 24  # the VQ decoder reaches about 22 tokens back


@dataclass(frozen=True)
class LiveSettings:
    sampling: Sampling  # a motion_control_live configuration (samples forced to 1)
    early: bool = False
    encoder_context: int = ENCODER_CONTEXT_TOKENS
    decoder_context: int = DECODER_CONTEXT_TOKENS


class LiveStream:
    """One user/partner stream. `encode(clip) -> tokens [T, P', D']` and `decode(x, betas) ->
    Decoded` run the VQ-VAE; `make_run(sampling, draws, betas) -> Run` builds the sampler with
    the model's denoiser and guidance. `partner` [4 Tc, 145] are the partner's opening frames."""

    def __init__(self, settings: LiveSettings, stats: Stats, encode, decode, make_run, draws, partner: np.ndarray):
        self.cfg = replace(settings.sampling, samples=1)
        self.settings, self.stats = settings, stats
        self.encode, self.decode, self.make_run, self.draws = encode, decode, make_run, draws
        self.partner = partner.astype(np.float32)
        self.user = np.zeros((0, partner.shape[-1]), np.float32)  # every user frame received
        self.chunks = 0
        self.window: np.ndarray | None = None  # [1, Tm, P, D] after the last chunk
        self.seed_tokens: np.ndarray | None = None  # [Tc, D]: the partner's given tokens
        self.emitted: list[np.ndarray] = []  # partner tokens sent, [D] each
        self.frames_out = 0
        self.world = None  # the partner's canonical frame in the world at the last frame sent
        self.tokens_out: list[np.ndarray] = []  # every token sent, for tests

    # ---- geometry --------------------------------------------------------------------------

    @property
    def tc(self) -> int:
        return self.cfg.context_tokens

    def stride(self, tm: int) -> int:
        return tm - self.tc

    # ---- the stream ------------------------------------------------------------------------

    def push(self, frames: np.ndarray, tm: int, persons: int, latent: int) -> np.ndarray:
        """Feeds user frames [n, 145]; returns the partner frames that became ready [m, 145]."""
        self.user = np.concatenate([self.user, frames.astype(np.float32)])
        out = []
        while len(self.user) >= FRAMES_PER_TOKEN * (self.chunks * self.stride(tm) + tm):
            out.append(self.chunk(tm, persons, latent))
        return np.concatenate(out) if out else np.zeros((0, self.user.shape[-1]), np.float32)

    def user_tokens(self, w0: int, tm: int) -> np.ndarray:
        """The user's tokens [Tm, D1] of window(w0), encoded from its received frames alone."""
        b = FRAMES_PER_TOKEN * (w0 + tm)
        a = FRAMES_PER_TOKEN * max(0, w0 - self.settings.encoder_context)
        first = max(0, a - 1)  # one frame more, for the true transition into frame a
        clip = clip_from_frames(self.user[first:b, None])
        if first < a:
            clip = clip.slice(1, clip.frames)
        tokens = self.encode(clip)  # [T, 1, D1]
        return tokens[-tm:, 0]

    def user_partner_slots(self, window: np.ndarray, context: int, latent: int) -> np.ndarray:
        """The user's partner-relative transforms, normalised [Tm, 36]: the partner's own slot
        inverted over its context tokens, the last such frame held after them."""
        mean, std = self.stats.field("T_self_canonical_partner_canonical")
        at = latent + TOKEN_TRANSFORMS
        theirs = window[0, :context, 1, at : at + TOKEN_TRANSFORMS].reshape(-1, TRANSFORM) * std + mean
        mine = to_9d(inverse(from_9d(theirs.astype(np.float32))))
        tm = window.shape[1]
        held = np.concatenate([mine, np.repeat(mine[-1:], FRAMES_PER_TOKEN * (tm - context), axis=0)])
        return ((held - mean) / std).astype(np.float32).reshape(tm, TOKEN_TRANSFORMS)

    def chunk(self, tm: int, persons: int, latent: int) -> np.ndarray:
        c, tc = self.chunks, self.tc
        st = self.stride(tm)
        w0 = c * st
        if c == 0:
            seed_clip = clip_from_frames(np.stack([self.user[: FRAMES_PER_TOKEN * tc], self.partner], axis=1))
            self.seed_tokens = self.encode(seed_clip)[:, 1]  # [Tc, D]
        user = self.user_tokens(w0, tm)
        d = self.seed_tokens.shape[-1]
        x = self.draws.normal((1, tm, persons, d)).astype(np.float32)
        if c > 0:
            x[0, :tc, 1] = self.window[0, st:, 1]
        given = max(0, tc - w0)  # the partner's given tokens in this window
        x[0, :given, 1] = self.seed_tokens[w0 : w0 + given]
        gt = x.copy()
        gt[0, :, 0, : user.shape[-1]] = user
        gt[0, :, 0, latent + TOKEN_TRANSFORMS :] = self.user_partner_slots(x, tc, latent)
        ctx = np.zeros((1, tm, persons), bool)
        ctx[:, :, 0] = True
        ctx[:, :tc, 1:] = True
        inject = np.zeros((1, tm, persons), bool)
        inject[:, :, 0] = True
        inject[:, :given, 1:] = True  # the partner's given tokens stay given
        user_betas = self.stats.normalize("betas", self.user[0, :10])
        partner_betas = self.stats.normalize("betas", self.partner[0, :10])
        run = self.make_run(self.cfg, self.draws, np.stack([user_betas, partner_betas]))
        m = live_matrix(run, "motion_control_live")
        run.start(m.shape[0] - 1)
        rolling_chunk(run, x, 0, m, gt, inject, ctx, c)
        self.window = x
        self.chunks += 1
        sent = np.where(inject[..., None], gt, x)[0, :, 1]  # the given tokens as given
        if self.settings.early:
            first, last = (0 if c == 0 else tc), tm
        else:
            first, last = 0, st
        return self.emit(sent[first:last], sent[last:], partner_betas, latent)

    def emit(self, new: np.ndarray, ahead: np.ndarray, betas: np.ndarray, latent: int) -> np.ndarray:
        """Decodes `new` tokens [n, D] with the sent history and `ahead` as context; returns
        their frames [4n, 145] with roots in the world."""
        history = self.emitted[-self.settings.decoder_context :] if self.settings.decoder_context else []
        seq = np.concatenate([np.array(history, np.float32).reshape(-1, new.shape[-1]), new, ahead])
        decoded = self.decode(seq[None, :, None], betas[None])
        a = FRAMES_PER_TOKEN * len(history)
        b = a + FRAMES_PER_TOKEN * len(new)
        part = Decoded(decoded.body[:, a:b], decoded.canonical_root[:, a:b], decoded.tm1_t[:, a:b])
        roots = np.zeros((1, b - a, 1, 4, 4), np.float32)
        given = FRAMES_PER_TOKEN * self.tc
        seed_roots = from_9d(self.partner[:, 136:145])
        seed_canon = from_9d(clip_from_frames(self.partner[:, None]).world_canonical[:, 0])
        for i in range(b - a):
            f = self.frames_out + i
            if f < given:
                roots[0, i, 0] = seed_roots[f]
                continue
            if self.world is None:
                self.world = seed_canon[given - 1]
            self.world = compose(self.world, from_9d(part.tm1_t[0, i, 0]))
            roots[0, i, 0] = compose(self.world, from_9d(part.canonical_root[0, i, 0]))
        out = frames_from_decoded(part, roots, self.partner[:1, :10])[0, :, 0]
        self.frames_out += b - a
        self.emitted.extend(new)
        self.emitted = self.emitted[-max(self.settings.decoder_context, 1) :]
        self.tokens_out.extend(new)
        return out

    def latency_frames(self, tm: int) -> int:
        """User frames after frame t that arrive before the partner's frame t is out, at worst
        (the first frame of a chunk's emitted tokens, past the opening frames)."""
        return FRAMES_PER_TOKEN * (self.stride(tm) if self.settings.early else tm) - 1


def make_live_run(model_parts, sampling: Sampling, draws, betas: np.ndarray) -> Run:
    """A sampler for one chunk: `model_parts` = (schedule, denoise, transform stats, window,
    persons, latent, decoder_grad)."""
    sched, denoise, tstats, window, persons, latent, decoder_grad = model_parts
    return Run(sampling, sched, denoise, draws, tstats, window, persons, latent, betas, decoder_grad)
