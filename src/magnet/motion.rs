//! troupe's frames <-> MAGNet's motion tokens (`docs/spec/magnet.md` §1.2-§1.5, §7): the
//! features derived from each person's root as the official preprocessing derives them, the
//! encoding of a clip, the decoding of tokens and each person's root rebuilt in the world.
//! Mirrors `onnx/troupe_onnx/magnet/motion.py`.

use ndarray::{s, Array2, Array3, Array4, ArrayView2, ArrayView3, ArrayView4};

use super::layout::{
    stats, BETAS, BODY_JOINTS, ENCODER_COND_DIM, FRAMES_PER_TOKEN, FRAME_BETAS, FRAME_BODY,
    FRAME_DIM, FRAME_ROOT, POSE_DIM, TOKEN_TRANSFORMS, TRANSFORM,
};
use super::networks::Networks;
use super::transforms::{canonical_frame, compose, from_9d, inverse, to_9d, Mat4, IDENTITY};
use crate::motion::rotation::{matrix_from_6d, matrix_to_6d, SixD};
use crate::shared::error::Result;

/// Every per-frame feature MAGNet reads, derived from troupe frames `[F, P, 145]`.
pub(crate) struct Clip {
    /// `[F, P, 126]` body 6-D rotations.
    pub body: Array3<f32>,
    /// `[F, P, 9]` the root in the canonical frame.
    pub canonical_root: Array3<f32>,
    /// `[F, P, 9]` the canonical frame's transition from the previous frame (identity at 0).
    pub tm1_t: Array3<f32>,
    /// `[F, P, P - 1, 9]` each partner's canonical frame in one's own.
    pub partner: Array4<f32>,
    /// `[P, 10]` betas (from the first frame).
    pub betas: Array2<f32>,
    /// `[F, P]` whether the person is present.
    pub mask: Array2<bool>,
    /// `[F, P]` canonical frames in the world.
    pub world_canonical: Vec<Mat4>,
    /// `[F, P]` roots in the world.
    pub world_root: Vec<Mat4>,
    pub frames: usize,
    pub persons: usize,
}

/// §1.2 steps 4 and 6 from troupe frames `[F, P, 145]` and presence `[F, P]`.
pub(crate) fn clip_from_frames(frames: ArrayView3<f32>, mask: ArrayView2<bool>) -> Clip {
    let (f, p, _) = frames.dim();
    let root: Vec<Mat4> = frames
        .outer_iter()
        .flat_map(|frame| {
            frame
                .outer_iter()
                .map(|person| from_9d(&person.as_slice().expect("contiguous")[FRAME_ROOT]))
                .collect::<Vec<_>>()
        })
        .collect();
    let canon: Vec<Mat4> = root.iter().map(canonical_frame).collect();
    let inv: Vec<Mat4> = canon.iter().map(inverse).collect();
    let mut tm1_t = Array3::zeros((f, p, TRANSFORM));
    let mut canonical_root = Array3::zeros((f, p, TRANSFORM));
    let mut partner = Array4::zeros((f, p, p.saturating_sub(1), TRANSFORM));
    let mut nine = [0f32; 9];
    for t in 0..f {
        for i in 0..p {
            let at = t * p + i;
            let step = if t == 0 {
                IDENTITY
            } else {
                compose(&inv[at - p], &canon[at])
            };
            to_9d(&step, &mut nine);
            tm1_t
                .slice_mut(s![t, i, ..])
                .assign(&ndarray::ArrayView1::from(&nine));
            to_9d(&compose(&inv[at], &root[at]), &mut nine);
            canonical_root
                .slice_mut(s![t, i, ..])
                .assign(&ndarray::ArrayView1::from(&nine));
            for j in (0..p).filter(|&j| j != i) {
                let slot = if j < i { j } else { j - 1 };
                to_9d(&compose(&inv[at], &canon[t * p + j]), &mut nine);
                partner
                    .slice_mut(s![t, i, slot, ..])
                    .assign(&ndarray::ArrayView1::from(&nine));
            }
        }
    }
    Clip {
        body: frames.slice(s![.., .., FRAME_BODY]).to_owned(),
        canonical_root,
        tm1_t,
        partner,
        betas: frames.slice(s![0, .., FRAME_BETAS]).to_owned(),
        mask: mask.to_owned(),
        world_canonical: canon,
        world_root: root,
        frames: f,
        persons: p,
    }
}

/// Normalises `x`'s last axis with the statistics' `range`.
fn normalise(nets: &Networks, range: std::ops::Range<usize>, x: &mut [f32]) {
    let st = &nets.spec.statistics;
    let (mean, std) = (&st.mean[range.clone()], &st.std[range]);
    for chunk in x.chunks_exact_mut(mean.len()) {
        for ((v, m), s) in chunk.iter_mut().zip(mean).zip(std) {
            *v = (*v - m) / s;
        }
    }
}

fn denormalise(nets: &Networks, range: std::ops::Range<usize>, x: &mut [f32]) {
    let st = &nets.spec.statistics;
    let (mean, std) = (&st.mean[range.clone()], &st.std[range]);
    for chunk in x.chunks_exact_mut(mean.len()) {
        for ((v, m), s) in chunk.iter_mut().zip(mean).zip(std) {
            *v = *v * s + m;
        }
    }
}

/// The clip's normalised betas, `[P, 10]`.
pub(crate) fn normalised_betas(nets: &Networks, clip: &Clip) -> Array2<f32> {
    let mut b = clip.betas.clone();
    normalise(nets, stats::BETAS, b.as_slice_mut().expect("contiguous"));
    b
}

/// Raw betas (10 floats) normalised.
pub(crate) fn normalise_betas(nets: &Networks, raw: &[f32]) -> Vec<f32> {
    let mut b = raw.to_vec();
    normalise(nets, stats::BETAS, &mut b);
    b
}

/// Tokens `[F/4, P, D]` of frames `first..first + n` of the clip (§5.0 step 3, §1.5): latents
/// are snapped codebook rows (zero where the person is absent), transforms normalised.
pub(crate) fn encode(nets: &Networks, clip: &Clip, first: usize, n: usize) -> Result<Array3<f32>> {
    let (p, lat) = (clip.persons, nets.spec.model.vq.d_latent);
    let t = n / FRAMES_PER_TOKEN;
    let span = s![first..first + n, .., ..];
    let mut body = clip.body.slice(span).to_owned();
    normalise(nets, stats::BODY, body.as_slice_mut().expect("contiguous"));
    let mut root = clip.canonical_root.slice(span).to_owned();
    normalise(
        nets,
        stats::CANONICAL_ROOT,
        root.as_slice_mut().expect("contiguous"),
    );
    let mut tm1 = clip.tm1_t.slice(span).to_owned();
    normalise(nets, stats::TM1_T, tm1.as_slice_mut().expect("contiguous"));
    let betas = normalised_betas(nets, clip);
    // Persons into the batch: [P, n, 135] and [P, n, 19].
    let mut pose = Array3::zeros((p, n, POSE_DIM));
    let mut cond = Array3::zeros((p, n, ENCODER_COND_DIM));
    for person in 0..p {
        for f in 0..n {
            pose.slice_mut(s![person, f, ..BODY_JOINTS * 6])
                .assign(&body.slice(s![f, person, ..]));
            pose.slice_mut(s![person, f, BODY_JOINTS * 6..])
                .assign(&root.slice(s![f, person, ..]));
            cond.slice_mut(s![person, f, ..BETAS])
                .assign(&betas.slice(s![person, ..]));
            cond.slice_mut(s![person, f, BETAS..])
                .assign(&tm1.slice(s![f, person, ..]));
        }
    }
    let z = nets.encode(pose.view(), cond.view())?;
    let d = nets.spec.model.token_dim;
    let mut tokens = Array3::zeros((t, p, d));
    let mut partner = clip
        .partner
        .slice(s![first..first + n, .., .., ..])
        .to_owned();
    normalise(
        nets,
        stats::PARTNER,
        partner.as_slice_mut().expect("contiguous"),
    );
    let mut snapped = vec![0f32; lat];
    for tau in 0..t {
        for person in 0..p {
            // Nearest-neighbour downsample of the presence mask: the token's first frame.
            if clip.mask[[first + tau * FRAMES_PER_TOKEN, person]] {
                let zv = z.slice(s![person, tau, ..]);
                nets.snap(zv.as_slice().expect("contiguous"), &mut snapped);
                tokens
                    .slice_mut(s![tau, person, ..lat])
                    .assign(&ndarray::ArrayView1::from(&snapped[..]));
            }
            for fr in 0..FRAMES_PER_TOKEN {
                let at = lat + fr * TRANSFORM;
                tokens
                    .slice_mut(s![tau, person, at..at + TRANSFORM])
                    .assign(&tm1.slice(s![tau * FRAMES_PER_TOKEN + fr, person, ..]));
                for slot in 0..p.saturating_sub(1) {
                    let at = lat + TOKEN_TRANSFORMS * (1 + slot) + fr * TRANSFORM;
                    tokens
                        .slice_mut(s![tau, person, at..at + TRANSFORM])
                        .assign(&partner.slice(s![tau * FRAMES_PER_TOKEN + fr, person, slot, ..]));
                }
            }
        }
    }
    Ok(tokens)
}

/// Decoded tokens per frame, de-normalised: body `[S, F, P, 126]`, canonical root and tm1_t
/// `[S, F, P, 9]`.
pub(crate) struct Decoded {
    pub body: Array4<f32>,
    pub canonical_root: Array4<f32>,
    pub tm1_t: Array4<f32>,
}

/// §7.1: snap the latents, decode each person's whole sequence with `[betas, tm1_t]`.
/// `x` `[S, T, P, D]`, `betas` `[P, 10]` normalised.
pub(crate) fn decode(
    nets: &Networks,
    x: ArrayView4<f32>,
    betas: ArrayView2<f32>,
) -> Result<Decoded> {
    let (s, _, p, _) = x.dim();
    let (mut z, cond) = fold_for_decoder(nets, x, betas);
    let mut snapped = vec![0f32; z.dim().2];
    for mut latent in z.rows_mut() {
        nets.snap(latent.as_slice().expect("contiguous"), &mut snapped);
        latent.assign(&ndarray::ArrayView1::from(&snapped[..]));
    }
    decode_folded(nets, z.view(), cond.view(), s, p)
}

/// §7.4: after the whole sequence is decoded, each key frame `kf` whose 4 frames the output
/// holds gets frames `kf..kf + 4` from its original key latent decoded on its own (one token,
/// not snapped), with the sampled token `kf / 4`'s transitions as the condition: body,
/// canonical root and transitions replaced. `x` `[S, T, P, D]` sampled, `keys` `[Tm, P, D]`
/// as [`key_tokens`] made them.
pub(crate) fn overwrite_key_frames(
    nets: &Networks,
    decoded: &mut Decoded,
    x: ArrayView4<f32>,
    keys: ArrayView3<f32>,
    keyframes: &[usize],
    betas: ArrayView2<f32>,
) -> Result<()> {
    let (s, t, p, _) = x.dim();
    let lat = nets.spec.model.vq.d_latent;
    for &kf in keyframes {
        if t * FRAMES_PER_TOKEN < kf + FRAMES_PER_TOKEN {
            continue;
        }
        let tau = kf / FRAMES_PER_TOKEN;
        let (mut z, cond) = fold_for_decoder(nets, x.slice(s![.., tau..=tau, .., ..]), betas);
        for sample in 0..s {
            for person in 0..p {
                z.slice_mut(s![sample * p + person, 0, ..])
                    .assign(&keys.slice(s![tau, person, ..lat]));
            }
        }
        let one = decode_folded(nets, z.view(), cond.view(), s, p)?;
        let frames = s![.., kf..kf + FRAMES_PER_TOKEN, .., ..];
        decoded.body.slice_mut(frames).assign(&one.body);
        decoded
            .canonical_root
            .slice_mut(frames)
            .assign(&one.canonical_root);
        decoded.tm1_t.slice_mut(frames).assign(&one.tm1_t);
    }
    Ok(())
}

/// The decoder's inputs from tokens `[S, T, P, D]`: latents as they are `[S*P, T, d_latent]` and
/// the condition `[betas, tm1_t]` `[S*P, T, 46]`, one person of one sample a row.
fn fold_for_decoder(
    nets: &Networks,
    x: ArrayView4<f32>,
    betas: ArrayView2<f32>,
) -> (Array3<f32>, Array3<f32>) {
    let (s, t, p, _) = x.dim();
    let lat = nets.spec.model.vq.d_latent;
    let mut z = Array3::zeros((s * p, t, lat));
    let mut cond = Array3::zeros((s * p, t, BETAS + TOKEN_TRANSFORMS));
    for sample in 0..s {
        for person in 0..p {
            let n = sample * p + person;
            for tau in 0..t {
                let token = x.slice(s![sample, tau, person, ..]);
                z.slice_mut(s![n, tau, ..]).assign(&token.slice(s![..lat]));
                cond.slice_mut(s![n, tau, ..BETAS])
                    .assign(&betas.slice(s![person, ..]));
                cond.slice_mut(s![n, tau, BETAS..])
                    .assign(&token.slice(s![lat..lat + TOKEN_TRANSFORMS]));
            }
        }
    }
    (z, cond)
}

/// Decodes folded latents and condition (as [`fold_for_decoder`] lays them out, `S` samples of
/// `P` people) to frames, de-normalised; the transitions are the condition's.
fn decode_folded(
    nets: &Networks,
    z: ArrayView3<f32>,
    cond: ArrayView3<f32>,
    s: usize,
    p: usize,
) -> Result<Decoded> {
    let pose = nets.decode(z, cond)?; // [S*P, 4T, 135]
    let frames = z.dim().1 * FRAMES_PER_TOKEN;
    let mut body = Array4::zeros((s, frames, p, BODY_JOINTS * 6));
    let mut root = Array4::zeros((s, frames, p, TRANSFORM));
    let mut tm1 = Array4::zeros((s, frames, p, TRANSFORM));
    for sample in 0..s {
        for person in 0..p {
            let n = sample * p + person;
            for f in 0..frames {
                body.slice_mut(s![sample, f, person, ..])
                    .assign(&pose.slice(s![n, f, ..BODY_JOINTS * 6]));
                root.slice_mut(s![sample, f, person, ..])
                    .assign(&pose.slice(s![n, f, BODY_JOINTS * 6..]));
                let (tau, fr) = (f / FRAMES_PER_TOKEN, f % FRAMES_PER_TOKEN);
                let at = BETAS + fr * TRANSFORM;
                tm1.slice_mut(s![sample, f, person, ..])
                    .assign(&cond.slice(s![n, tau, at..at + TRANSFORM]));
            }
        }
    }
    denormalise(nets, stats::BODY, body.as_slice_mut().expect("contiguous"));
    denormalise(
        nets,
        stats::CANONICAL_ROOT,
        root.as_slice_mut().expect("contiguous"),
    );
    denormalise(nets, stats::TM1_T, tm1.as_slice_mut().expect("contiguous"));
    Ok(Decoded {
        body,
        canonical_root: root,
        tm1_t: tm1,
    })
}

/// §5.0 step 2 for in-betweening: the window's key tokens `[Tm, P, D]` and which are keys.
/// Key frame `kf` sets token `kf / 4`: its latent from frames `kf..kf + 4` encoded on their own,
/// its transforms from the token's own frames (the official code fills every token's transform
/// slices from the ground truth), so a key frame off the token grid (63) takes its latent from
/// frames 63-66 and its transforms from 60-63.
pub(crate) fn key_tokens(
    nets: &Networks,
    clip: &Clip,
    keyframes: &[usize],
) -> Result<(Array3<f32>, Vec<bool>)> {
    let m = &nets.spec.model;
    let mut keys = Array3::zeros((m.window, clip.persons, m.token_dim));
    let mut is_key = vec![false; m.window];
    for &kf in keyframes {
        let tau = kf / FRAMES_PER_TOKEN;
        let own = encode(nets, clip, tau * FRAMES_PER_TOKEN, FRAMES_PER_TOKEN)?;
        keys.slice_mut(s![tau, .., ..])
            .assign(&own.slice(s![0, .., ..]));
        if kf % FRAMES_PER_TOKEN != 0 {
            let at_key = encode(nets, clip, kf, FRAMES_PER_TOKEN)?;
            let lat = m.vq.d_latent;
            keys.slice_mut(s![tau, .., ..lat])
                .assign(&at_key.slice(s![0, .., ..lat]));
        }
        is_key[tau] = true;
    }
    Ok((keys, is_key))
}

/// §7.2: the frame every task's roots are anchored at, `context_seq_len` (4 when that is 0), as
/// the official inference passes it; the frames before it are the input's.
pub(crate) fn anchor_frame(context_len: usize) -> usize {
    if context_len == 0 {
        FRAMES_PER_TOKEN
    } else {
        context_len
    }
}

/// §7.2 (mode `temporal`): each person's root in the world `[S, F, P]` from the first generated
/// frame `c` on, chaining the predicted transitions; the clip's roots before it (its last one
/// repeated past its end, as the reference pads the ground truth). When the clip
/// covers frame `c`, its canonical frame there is the anchor, as the reference's (§11 A2);
/// otherwise the online default: the clip's last canonical frame chained with the predicted
/// transition into frame `c`.
pub(crate) fn world_roots(decoded: &Decoded, context_frames: usize, clip: &Clip) -> Vec<Mat4> {
    let (s, f, p, _) = decoded.canonical_root.dim();
    let c = context_frames.min(f - 1);
    let at = |sample: usize, frame: usize, person: usize| (sample * f + frame) * p + person;
    let mut roots = vec![IDENTITY; s * f * p];
    for sample in 0..s {
        for person in 0..p {
            for frame in 0..c {
                let known = frame.min(clip.frames - 1);
                roots[at(sample, frame, person)] = clip.world_root[known * p + person];
            }
            // The last axis of a standard-layout array is contiguous.
            let nine = |a: &Array4<f32>, frame: usize| {
                from_9d(
                    a.slice(s![sample, frame, person, ..])
                        .as_slice()
                        .expect("contiguous"),
                )
            };
            let mut world = if clip.frames > c {
                clip.world_canonical[c * p + person]
            } else {
                let last = clip.world_canonical[(clip.frames - 1) * p + person];
                compose(&last, &nine(&decoded.tm1_t, c))
            };
            let local = |frame: usize| nine(&decoded.canonical_root, frame);
            roots[at(sample, c, person)] = compose(&world, &local(c));
            for frame in c + 1..f {
                world = compose(&world, &nine(&decoded.tm1_t, frame));
                roots[at(sample, frame, person)] = compose(&world, &local(frame));
            }
        }
    }
    roots
}

/// troupe frames `[S, F, P, 145]`: betas as given, body rotations orthonormalised (as the
/// reference saves them), roots in the world.
pub(crate) fn frames_out(decoded: &Decoded, roots: &[Mat4], betas: ArrayView2<f32>) -> Array4<f32> {
    let (s, f, p, _) = decoded.body.dim();
    let mut out = Array4::zeros((s, f, p, FRAME_DIM));
    let mut nine = [0f32; 9];
    for sample in 0..s {
        for frame in 0..f {
            for person in 0..p {
                let mut row = out.slice_mut(s![sample, frame, person, ..]);
                row.slice_mut(s![FRAME_BETAS])
                    .assign(&betas.slice(s![person, ..]));
                let body = decoded.body.slice(s![sample, frame, person, ..]);
                for j in 0..BODY_JOINTS {
                    let d6 = body.slice(s![j * 6..j * 6 + 6]);
                    let layout = SixD::ConcatenatedColumns;
                    let clean = matrix_to_6d(
                        &matrix_from_6d(d6.as_slice().expect("contiguous"), layout),
                        layout,
                    );
                    let at = FRAME_BODY.start + j * 6;
                    row.slice_mut(s![at..at + 6])
                        .assign(&ndarray::ArrayView1::from(&clean));
                }
                to_9d(&roots[(sample * f + frame) * p + person], &mut nine);
                row.slice_mut(s![FRAME_ROOT])
                    .assign(&ndarray::ArrayView1::from(&nine));
            }
        }
    }
    out
}
