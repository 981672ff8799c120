//! `troupe.json`: the manifest of a model bundle (contract documented in `onnx/README.md`).
//!
//! The manifest states everything the runtime needs; nothing is inferred from file names. It is
//! checked twice at load: against itself (dimensions that must agree) and, in
//! [`crate::graph`], against the ONNX graphs it names.

use std::fmt;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::bundle::BundleFiles;
use crate::error::{Error, Result};

/// Value of the manifest's `format` field.
pub const FORMAT: &str = "troupe-bundle";
/// The manifest format version this runtime reads.
pub const FORMAT_VERSION: u32 = 1;

/// A parsed and validated `troupe.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`FORMAT_VERSION`] for bundles this runtime can run.
    pub format_version: u32,
    /// Model family; `armflow` for the online reaction model.
    pub family: String,
    /// Human-readable bundle name.
    pub name: String,
    /// Free-form provenance (exporter, preset, seed); not interpreted.
    #[serde(default)]
    pub producer: serde_json::Value,
    /// Per-frame motion features.
    pub motion: MotionSpec,
    /// Latent tokens of the VAE.
    pub latent: LatentSpec,
    /// Conditioning vector (e.g. a text embedding).
    pub condition: ConditionSpec,
    /// Causal context encoder.
    pub context: ContextSpec,
    /// Streaming properties of the VAE.
    pub vae: VaeSpec,
    /// Default sampler settings (sessions may override them).
    pub sampler: SamplerSpec,
    /// The ONNX graphs of the bundle.
    pub graphs: Graphs,
}

/// Per-frame motion features.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MotionSpec {
    /// Feature layout name, e.g. `interhuman262`.
    pub layout: String,
    /// Floats per frame.
    pub frame_dim: usize,
    /// Frames per second of the motion.
    pub fps: u32,
}

/// Latent tokens.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LatentSpec {
    /// Floats per token (per person).
    pub dim: usize,
    /// Multiplied into encoder outputs, divided out before decoding.
    pub scale: f32,
    /// Motion frames per latent token.
    pub frames_per_token: usize,
}

/// Conditioning vector.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ConditionSpec {
    /// Floats in the conditioning vector.
    pub dim: usize,
}

/// Causal context encoder.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ContextSpec {
    /// Model width: `2 * latent.dim` (actor || reactor).
    pub width: usize,
    /// Transformer layers (each has its own key/value cache).
    pub layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Width of one head; `heads * head_dim == width`.
    pub head_dim: usize,
    /// Default number of tokens (`<sos>` included) kept in the key/value cache.
    pub capacity_tokens: usize,
}

/// Streaming properties of the VAE.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VaeSpec {
    /// True when the VAE is causal, so that windowed calls equal one pass over the stream.
    pub streaming: bool,
    /// Encoder window.
    pub encoder: EncoderWindow,
    /// Decoder window.
    pub decoder: DecoderWindow,
}

/// Frames the encoder reads around the frames of one token.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EncoderWindow {
    /// Frames before the token's first frame (a multiple of `frames_per_token`).
    pub context_frames: usize,
    /// Frames after the token's last frame.
    pub lookahead_frames: usize,
}

/// Tokens the decoder reads around one token.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DecoderWindow {
    /// Tokens before the decoded token.
    pub context_tokens: usize,
    /// Tokens after the decoded token.
    pub lookahead_tokens: usize,
}

/// How the actor's latent token is taken from the encoder's posterior.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActorLatent {
    /// `(mean + sqrt(exp(logvar)) * xi) * scale`, as the official sampler does.
    Sample,
    /// `mean * scale`: deterministic, no noise drawn.
    Mean,
}

/// Default sampler settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SamplerSpec {
    /// MeanFlow steps per token (1: one network call).
    pub steps: u32,
    /// Classifier-free guidance scale (1: off).
    pub cfg_scale: f32,
    /// Posterior sample or mean for actor tokens.
    pub actor_latent: ActorLatent,
}

/// The graphs of an `armflow` bundle, by role.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Graphs {
    /// condition -> AdaLN modulation of every layer, and `<sos>`; run when the condition changes.
    pub conditioning: GraphSpec,
    /// One context-encoder step over new tokens with a per-layer key/value cache.
    pub context_step: GraphSpec,
    /// Average-velocity MLP.
    pub velocity: GraphSpec,
    /// VAE encoder over a window of frames.
    pub vae_encoder: GraphSpec,
    /// VAE decoder over a window of tokens.
    pub vae_decoder: GraphSpec,
}

/// One ONNX graph and its interface.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GraphSpec {
    /// File name, relative to the bundle directory.
    pub file: String,
    /// Inputs, by name.
    pub inputs: Vec<TensorSpec>,
    /// Outputs, by name.
    pub outputs: Vec<TensorSpec>,
}

/// Element type of a graph tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DType {
    /// 32-bit float.
    Float32,
    /// 64-bit signed integer.
    Int64,
}

/// One dimension: a fixed size or a symbol (`T`, `P`, `P+S`, ...) resolved per call.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Dim {
    /// A size fixed by the bundle.
    Fixed(usize),
    /// A size that varies from call to call.
    Symbol(String),
}

/// Name, element type and shape of one graph input or output.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TensorSpec {
    /// Tensor name in the ONNX graph.
    pub name: String,
    /// Element type.
    pub dtype: DType,
    /// Shape.
    pub shape: Vec<Dim>,
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Dim::Fixed(n) => write!(f, "{n}"),
            Dim::Symbol(s) => write!(f, "{s}"),
        }
    }
}

impl fmt::Display for TensorSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dims: Vec<String> = self.shape.iter().map(Dim::to_string).collect();
        let dtype = match self.dtype {
            DType::Float32 => "float32",
            DType::Int64 => "int64",
        };
        write!(f, "`{}` {dtype} [{}]", self.name, dims.join(", "))
    }
}

impl Manifest {
    /// Reads and validates `troupe.json` from a bundle.
    pub(crate) fn load(files: &BundleFiles) -> Result<Self> {
        let path = files.path_of("troupe.json");
        let bytes = files.read("troupe.json")?;
        let text = std::str::from_utf8(&bytes).map_err(|_| Error::Manifest {
            path: path.clone(),
            message: "not UTF-8 text".into(),
        })?;
        Self::parse(text, &path)
    }

    /// Parses and validates manifest text; `path` is only used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let bad = |message: String| Error::Manifest {
            path: path.to_path_buf(),
            message,
        };
        let manifest: Manifest = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        manifest.validate().map_err(bad)?;
        Ok(manifest)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        let check = |ok: bool, msg: &dyn Fn() -> String| if ok { Ok(()) } else { Err(msg()) };
        check(self.format == FORMAT, &|| {
            format!("format is `{}`, expected `{FORMAT}`", self.format)
        })?;
        check(self.format_version == FORMAT_VERSION, &|| {
            format!(
                "format_version {} is not supported (this runtime reads version {FORMAT_VERSION})",
                self.format_version
            )
        })?;
        check(self.family == "armflow", &|| {
            format!(
                "family `{}` is not supported (expected `armflow`)",
                self.family
            )
        })?;
        let (m, l, c) = (&self.motion, &self.latent, &self.context);
        check(m.frame_dim > 0 && m.fps > 0, &|| {
            "motion.frame_dim and motion.fps must be positive".into()
        })?;
        check(l.dim > 0 && l.frames_per_token > 0, &|| {
            "latent.dim and latent.frames_per_token must be positive".into()
        })?;
        check(l.scale.is_finite() && l.scale > 0.0, &|| {
            format!("latent.scale must be finite and positive, got {}", l.scale)
        })?;
        check(c.width == 2 * l.dim, &|| {
            format!(
                "context.width {} must be 2 * latent.dim = {}",
                c.width,
                2 * l.dim
            )
        })?;
        check(c.heads > 0 && c.heads * c.head_dim == c.width, &|| {
            format!(
                "context.heads {} * context.head_dim {} must equal context.width {}",
                c.heads, c.head_dim, c.width
            )
        })?;
        check(c.layers % 2 == 1, &|| {
            format!(
                "context.layers {} must be odd (in, mid, out layers)",
                c.layers
            )
        })?;
        check(c.capacity_tokens >= 2, &|| {
            "context.capacity_tokens must be at least 2 (<sos> and one token)".into()
        })?;
        check(
            self.vae
                .encoder
                .context_frames
                .is_multiple_of(l.frames_per_token),
            &|| {
                format!(
                    "vae.encoder.context_frames {} must be a multiple of latent.frames_per_token {}",
                    self.vae.encoder.context_frames, l.frames_per_token
                )
            },
        )?;
        check(self.sampler.steps >= 1, &|| {
            "sampler.steps must be >= 1".into()
        })?;
        check(self.sampler.cfg_scale.is_finite(), &|| {
            "sampler.cfg_scale must be finite".into()
        })?;
        for (role, declared, expected) in self.graph_contract() {
            for (kind, got, want) in [
                ("inputs", &declared.inputs, &expected.inputs),
                ("outputs", &declared.outputs, &expected.outputs),
            ] {
                compare_tensor_lists(got, want)
                    .map_err(|e| format!("graphs.{role}.{kind}: {e}"))?;
            }
        }
        Ok(())
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract(&self) -> [(&'static str, &GraphSpec, GraphSpec); 5] {
        let (c, lat, d) = (self.context.width, self.latent.dim, self.motion.frame_dim);
        let (h, dh) = (self.context.heads, self.context.head_dim);
        let f = |name: &str, shape: Vec<Dim>| TensorSpec {
            name: name.into(),
            dtype: DType::Float32,
            shape,
        };
        let n = Dim::Fixed;
        let s = |x: &str| Dim::Symbol(x.into());
        let kv = |prefix: &str, len: &str| -> Vec<TensorSpec> {
            (0..self.context.layers)
                .flat_map(|i| {
                    ["key", "value"].map(|kv| {
                        f(
                            &format!("{prefix}_{kv}_{i}"),
                            vec![n(1), n(h), s(len), n(dh)],
                        )
                    })
                })
                .collect()
        };
        let spec = |g: &GraphSpec, inputs: Vec<TensorSpec>, outputs: Vec<TensorSpec>| GraphSpec {
            file: g.file.clone(),
            inputs,
            outputs,
        };
        let g = &self.graphs;
        let mut step_inputs = vec![
            f("tokens", vec![n(1), s("S"), n(c)]),
            TensorSpec {
                name: "positions".into(),
                dtype: DType::Int64,
                shape: vec![n(1), s("S")],
            },
            f("modulation", vec![n(1), n(self.context.layers), n(6), n(c)]),
        ];
        step_inputs.extend(kv("past", "P"));
        let mut step_outputs = vec![f("context", vec![n(1), n(c)])];
        step_outputs.extend(kv("present", "P+S"));
        [
            (
                "conditioning",
                &g.conditioning,
                spec(
                    &g.conditioning,
                    vec![f("condition", vec![n(1), n(self.condition.dim)])],
                    vec![
                        f("modulation", vec![n(1), n(self.context.layers), n(6), n(c)]),
                        f("start_token", vec![n(1), n(1), n(c)]),
                    ],
                ),
            ),
            (
                "context_step",
                &g.context_step,
                spec(&g.context_step, step_inputs, step_outputs),
            ),
            (
                "velocity",
                &g.velocity,
                spec(
                    &g.velocity,
                    vec![
                        f("actor", vec![s("B"), n(lat)]),
                        f("noisy", vec![s("B"), n(lat)]),
                        f("context", vec![s("B"), n(c)]),
                        f("r", vec![s("B")]),
                        f("t", vec![s("B")]),
                    ],
                    vec![f("velocity", vec![s("B"), n(lat)])],
                ),
            ),
            (
                "vae_encoder",
                &g.vae_encoder,
                spec(
                    &g.vae_encoder,
                    vec![f("motion", vec![n(1), s("T"), n(d)])],
                    vec![
                        f("mean", vec![n(1), s("N"), n(lat)]),
                        f("logvar", vec![n(1), s("N"), n(lat)]),
                    ],
                ),
            ),
            (
                "vae_decoder",
                &g.vae_decoder,
                spec(
                    &g.vae_decoder,
                    vec![f("latents", vec![n(1), s("N"), n(lat)])],
                    vec![f("motion", vec![n(1), s("T"), n(d)])],
                ),
            ),
        ]
    }
}

/// Same names (in any order), dtypes, ranks and fixed dims; symbols may be named freely.
fn compare_tensor_lists(
    got: &[TensorSpec],
    want: &[TensorSpec],
) -> std::result::Result<(), String> {
    for w in want {
        let g = got
            .iter()
            .find(|g| g.name == w.name)
            .ok_or_else(|| format!("missing tensor {w}"))?;
        let same_dims = g.shape.len() == w.shape.len()
            && g.shape.iter().zip(&w.shape).all(|(a, b)| match (a, b) {
                (Dim::Fixed(x), Dim::Fixed(y)) => x == y,
                (Dim::Symbol(_), Dim::Symbol(_)) => true,
                _ => false,
            });
        if g.dtype != w.dtype || !same_dims {
            return Err(format!("tensor declared as {g}, the runtime requires {w}"));
        }
    }
    if let Some(extra) = got.iter().find(|g| !want.iter().any(|w| w.name == g.name)) {
        return Err(format!("unexpected tensor {extra}"));
    }
    Ok(())
}
