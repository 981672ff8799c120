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

mod armflow;
mod umf;

pub use armflow::{
    ActorLatent, ArmFlowGraphs, ArmFlowSpec, ClipSpec, ContextSpec, DecoderWindow, EncoderWindow,
    LatentSpec, SamplerSpec, VaeSpec,
};
pub use umf::{
    PyramidSpec, StageSpec, TextSpec, UmfGraphs, UmfLatentSpec, UmfSamplerSpec, UmfSpec,
};

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
    /// Human-readable bundle name.
    pub name: String,
    /// Free-form provenance (exporter, preset, seed); not interpreted.
    #[serde(default)]
    pub producer: serde_json::Value,
    /// Per-frame motion features.
    pub motion: MotionSpec,
    /// Conditioning vector (e.g. a text embedding).
    pub condition: ConditionSpec,
    /// What the family's sampler needs: its latents, graphs and defaults. Serialised as the
    /// `family` tag plus the family's own top-level fields.
    #[serde(flatten)]
    pub family: Family,
}

/// The model families troupe runs, each with the manifest fields of its own.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "family", rename_all = "lowercase")]
pub enum Family {
    /// ARMFlow: online reaction, streamed token by token ([`crate::Session`]).
    Armflow(Box<ArmFlowSpec>),
    /// UMF: text-to-group generation ([`crate::Model::generate_group`]).
    Umf(Box<UmfSpec>),
}

/// The family names this runtime reads, as they appear in `troupe.json`.
pub const FAMILIES: [&str; 2] = ["armflow", "umf"];

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

/// Conditioning vector.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ConditionSpec {
    /// Floats in the conditioning vector.
    pub dim: usize,
    /// The condition standing for "no condition" (classifier-free guidance's unconditional
    /// branch, and what `None` means). Zeros when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub null: Option<Vec<f32>>,
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
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        check_header(&value).map_err(bad)?;
        let manifest: Manifest = serde_json::from_value(value).map_err(|e| bad(e.to_string()))?;
        manifest.validate().map_err(bad)?;
        Ok(manifest)
    }

    /// The family name as written in the manifest.
    pub fn family_name(&self) -> &'static str {
        match self.family {
            Family::Armflow(_) => "armflow",
            Family::Umf(_) => "umf",
        }
    }

    fn validate(&self) -> std::result::Result<(), String> {
        let m = &self.motion;
        ensure(m.frame_dim > 0 && m.fps > 0, || {
            "motion.frame_dim and motion.fps must be positive".into()
        })?;
        if let Some(null) = &self.condition.null {
            ensure(null.len() == self.condition.dim, || {
                format!(
                    "condition.null holds {} floats, condition.dim is {}",
                    null.len(),
                    self.condition.dim
                )
            })?;
            ensure(null.iter().all(|v| v.is_finite()), || {
                "condition.null holds a non-finite value".into()
            })?;
        }
        match &self.family {
            Family::Armflow(spec) => spec.validate(self)?,
            Family::Umf(spec) => spec.validate(self)?,
        }
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
    pub(crate) fn graph_contract(&self) -> Vec<(&'static str, &GraphSpec, GraphSpec)> {
        match &self.family {
            Family::Armflow(spec) => spec.graph_contract(self),
            Family::Umf(spec) => spec.graph_contract(self),
        }
    }
}

/// Format, version and family, checked before the family's fields are read so that an
/// unsupported bundle gets a message about what it is rather than about a missing field.
fn check_header(value: &serde_json::Value) -> std::result::Result<(), String> {
    let field = |name: &str| value.get(name);
    let format = field("format").and_then(|v| v.as_str()).unwrap_or("");
    ensure(format == FORMAT, || {
        format!("format is `{format}`, expected `{FORMAT}`")
    })?;
    let version = field("format_version").and_then(|v| v.as_u64());
    ensure(version == Some(u64::from(FORMAT_VERSION)), || {
        format!(
            "format_version {} is not supported (this runtime reads version {FORMAT_VERSION})",
            field("format_version").map_or("(missing)".into(), |v| v.to_string())
        )
    })?;
    let family = field("family").and_then(|v| v.as_str()).unwrap_or("");
    ensure(FAMILIES.contains(&family), || {
        format!(
            "family `{family}` is not supported (this runtime reads {})",
            FAMILIES.join(", ")
        )
    })
}

/// `Ok` when `ok`, else the message.
pub(crate) fn ensure(
    ok: bool,
    message: impl FnOnce() -> String,
) -> std::result::Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(message())
    }
}

/// Shorthands for writing graph contracts.
pub(crate) fn float(name: &str, shape: Vec<Dim>) -> TensorSpec {
    TensorSpec {
        name: name.into(),
        dtype: DType::Float32,
        shape,
    }
}

/// A symbolic dimension.
pub(crate) fn sym(name: &str) -> Dim {
    Dim::Symbol(name.into())
}

/// The declared graph's file with the required interface.
pub(crate) fn contract(
    g: &GraphSpec,
    inputs: Vec<TensorSpec>,
    outputs: Vec<TensorSpec>,
) -> GraphSpec {
    GraphSpec {
        file: g.file.clone(),
        inputs,
        outputs,
    }
}

/// The official text branch: CLIP's token features `[B, T, token_dim]` and the end-of-text
/// index `[B]` give the condition `[B, condition_dim]`.
pub(crate) fn text_branch_contract(
    g: &GraphSpec,
    token_dim: usize,
    condition_dim: usize,
) -> GraphSpec {
    contract(
        g,
        vec![
            float(
                "clip_tokens",
                vec![sym("B"), sym("T"), Dim::Fixed(token_dim)],
            ),
            TensorSpec {
                name: "eot_index".into(),
                dtype: DType::Int64,
                shape: vec![sym("B")],
            },
        ],
        vec![float(
            "condition",
            vec![sym("B"), Dim::Fixed(condition_dim)],
        )],
    )
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
