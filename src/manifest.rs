//! `troupe.json`: the manifest of a model bundle (contract documented in `onnx/README.md`).
//!
//! The manifest states everything the runtime needs; nothing is inferred from file names. It is
//! checked twice at load: against itself (dimensions that must agree) and, when each graph
//! loads, against the ONNX graphs it names.
//!
//! This module sits above the families, beside [`crate::Model`]: it reads the common header and
//! hands each family its own section (`crate::armflow::spec`, `crate::umf::spec`,
//! `crate::magnet::spec`, `crate::arflow::spec`). The types a manifest is made of are
//! re-exported here under the paths they have always had.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::family::section::FamilySection;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::ensure;
use crate::shared::error::{file_name_shown, json_error_shown, Error, Result};
use crate::shared::graph_spec::check_contract;
use crate::shared::limits::LIMITS;
use crate::shared::logging::{self, Level};
use crate::shared::text::encoder::text_encoder_contract;

pub use crate::arflow::spec::ArflowSpec;
pub use crate::armflow::spec::{
    ActorLatent, ArmFlowGraphs, ArmFlowSpec, ClipSpec, ContextSpec, DecoderWindow, EncoderWindow,
    LatentSpec, SamplerSpec, VaeSpec,
};
pub use crate::magnet::spec::MagnetSpec;
pub use crate::shared::bundle_io::{ConditionFeedback, ConditionLabel, ConditionSpec, MotionSpec};
pub use crate::shared::graph_spec::{DType, Dim, GraphSpec, TensorSpec, Weights};
pub use crate::shared::text::prompt::TokenizerSpec;
pub use crate::umf::spec::{
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
    /// How a prompt becomes token ids, for bundles with a text encoder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tokenizer: Option<TokenizerSpec>,
    /// What the family's sampler needs: its latents, graphs and defaults. Serialised as the
    /// `family` tag plus the family's own top-level fields.
    #[serde(flatten)]
    pub family: Family,
    /// The SHA-256 (64 lowercase hex digits) of each file the manifest names, by file name, as
    /// the exporter wrote them (`onnx/cli.py bundle digests` records them for an older
    /// bundle). Every file the load reads is checked against it, so a damaged or edited graph
    /// is refused at load, naming the file. A bundle without it loads, with a warning.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sha256: BTreeMap<String, String>,
}

/// Builds the registration table below: the [`Family`] enum the manifest is read into (tagged
/// by `family`), [`FAMILIES`], and [`Family::section`], the one dispatch to each family's
/// [`FamilySection`].
macro_rules! register_families {
    ($($(#[$doc:meta])* $variant:ident($section:ty) = $name:literal,)+) => {
        /// The model families troupe runs, each with the manifest fields of its own.
        #[derive(Debug, Clone, Serialize, Deserialize)]
        #[serde(tag = "family")]
        pub enum Family {
            $($(#[$doc])* #[serde(rename = $name)] $variant(Box<$section>),)+
        }

        /// The family names this runtime reads, as they appear in `troupe.json`.
        pub const FAMILIES: [&str; [$($name),+].len()] = [$($name),+];

        impl Family {
            /// The family's section, through what every family answers.
            pub(crate) fn section(&self) -> &dyn FamilySection {
                match self {
                    $(Self::$variant(section) => &**section,)+
                }
            }
        }
    };
}

// The families, one registration line each: a fifth family adds its line here, its folder under
// `src/` (whose section implements `FamilySection`), its `ffi/` module and its bindings.
register_families! {
    /// ARMFlow: online reaction, streamed token by token ([`crate::Session`]).
    Armflow(ArmFlowSpec) = "armflow",
    /// UMF: text-to-group generation ([`crate::Umf::generate_group`]).
    Umf(UmfSpec) = "umf",
    /// MAGNet: multi-agent diffusion forcing ([`crate::Magnet::generate`]).
    Magnet(MagnetSpec) = "magnet",
    /// ARFlow: action-to-reaction flow with penetration guidance
    /// ([`crate::Arflow::generate`]).
    Arflow(ArflowSpec) = "arflow",
}

impl Manifest {
    /// Reads and validates `troupe.json` from a bundle.
    pub(crate) fn load(files: &BundleFiles) -> Result<Self> {
        let path = files.path_of("troupe.json");
        let bytes = files.read("troupe.json", LIMITS.max_manifest_bytes)?;
        let text = std::str::from_utf8(&bytes).map_err(|_| Error::Manifest {
            path: path.clone(),
            message: "not UTF-8 text".into(),
        })?;
        let manifest = Self::parse(text, &path)?;
        if manifest.sha256.is_empty() {
            logging::log(Level::Warn, "troupe::load", || {
                format!(
                    "{}: records no SHA-256 of its files, so a damaged graph is found only when \
                     a step fails (`onnx/cli.py bundle digests` records them)",
                    path.display()
                )
            });
        } else {
            // Checked by `validate`: every value is 64 hex digits.
            let digests = manifest
                .sha256
                .iter()
                .filter_map(|(name, hex)| Some((name.clone(), sha256_from_hex(hex)?)))
                .collect();
            files.expect_digests(digests);
        }
        Ok(manifest)
    }

    /// Parses and validates manifest text; `path` is only used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let bad = |message: String| Error::Manifest {
            path: path.to_path_buf(),
            message,
        };
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(json_error_shown(&e)))?;
        check_header(&value).map_err(bad)?;
        check_integers(&value, "").map_err(bad)?;
        let manifest: Manifest =
            serde_json::from_value(value).map_err(|e| bad(json_error_shown(&e)))?;
        manifest.validate().map_err(bad)?;
        Ok(manifest)
    }

    /// The family name as written in the manifest.
    pub fn family_name(&self) -> &'static str {
        self.family.section().name()
    }

    fn validate(&self) -> std::result::Result<(), String> {
        for (name, hex) in &self.sha256 {
            ensure(sha256_from_hex(hex).is_some(), || {
                format!(
                    "sha256 of {}: not 64 hexadecimal digits",
                    file_name_shown(name)
                )
            })?;
        }
        let m = &self.motion;
        ensure(m.frame_dim > 0 && m.fps > 0, || {
            "motion.frame_dim and motion.fps must be positive".into()
        })?;
        crate::motion::check_layout(m)?;
        self.condition.validate()?;
        let section = self.family.section();
        section.validate(m, &self.condition)?;
        if let Some(feedback) = &self.condition.feedback {
            section.validate_feedback(feedback, m)?;
        }
        let (encoder, branch) = self.text_graphs();
        ensure(encoder.is_some() == self.tokenizer.is_some(), || {
            "graphs.text_encoder and the `tokenizer` section come together".into()
        })?;
        ensure(encoder.is_none() || branch.is_some(), || {
            "graphs.text_encoder needs graphs.text_branch (the features go through it)".into()
        })?;
        if let Some(tokenizer) = &self.tokenizer {
            tokenizer.validate()?;
        }
        for (role, declared, expected) in self.graph_contract() {
            check_contract(role, declared, &expected)?;
        }
        Ok(())
    }

    /// The family's `text_encoder` and `text_branch` declarations.
    fn text_graphs(&self) -> (Option<&GraphSpec>, Option<&GraphSpec>) {
        self.family.section().text_graphs()
    }

    /// The graphs whose weights are not float32 (by role, in manifest order), as each graph's
    /// `weights` declares and the load checked against its file. A role of several graphs
    /// (`context_layers`) is listed once, with its first reduced graph's weights. Empty for a
    /// float32 bundle.
    pub fn reduced_precision_graphs(&self) -> Vec<(&'static str, Weights)> {
        let mut graphs: Vec<(&'static str, Weights)> = Vec::new();
        for (role, declared, _) in self.graph_contract() {
            if !declared.weights.is_float32() && graphs.iter().all(|(r, _)| *r != role) {
                graphs.push((role, declared.weights));
            }
        }
        graphs
    }

    /// Each graph as declared, next to the interface the runtime requires of it.
    pub(crate) fn graph_contract(&self) -> Vec<(&'static str, &GraphSpec, GraphSpec)> {
        let (motion, condition) = (&self.motion, &self.condition);
        let section = self.family.section();
        let mut contracts = section.graph_contract(motion, condition);
        if let (Some(encoder), Some(tokenizer)) = (self.text_graphs().0, &self.tokenizer) {
            let token_dim = section.text_token_dim(condition);
            let expected = text_encoder_contract(encoder, tokenizer.context, token_dim);
            contracts.push(("text_encoder", encoder, expected));
        }
        contracts
    }

    /// The common facts every family keeps beside its graphs.
    pub(crate) fn bundle_io(&self) -> BundleIo {
        BundleIo {
            name: self.name.clone(),
            motion: self.motion.clone(),
            condition: self.condition.clone(),
            tokenizer: self.tokenizer.clone(),
            identity: Default::default(),
        }
    }
}

/// Every integer of the manifest outside `producer` (dimensions, counts, frames, steps) is at most
/// `LIMITS.max_manifest_dim`, so that no product of a few of them overflows and nothing sized by
/// one is allocated before the graphs are checked against it.
fn check_integers(value: &serde_json::Value, path: &str) -> std::result::Result<(), String> {
    use serde_json::Value;
    match value {
        Value::Object(map) => map
            .iter()
            .filter(|(key, _)| !(path.is_empty() && key.as_str() == "producer"))
            .try_for_each(|(key, v)| check_integers(v, &format!("{path}.{key}"))),
        Value::Array(items) => items
            .iter()
            .enumerate()
            .try_for_each(|(i, v)| check_integers(v, &format!("{path}[{i}]"))),
        Value::Number(n) if n.is_u64() || n.is_i64() => {
            let limit = LIMITS.max_manifest_dim;
            let ok = n.as_u64().is_some_and(|v| v <= limit)
                || n.as_i64().is_some_and(|v| v.unsigned_abs() <= limit);
            ensure(ok, || {
                format!(
                    "{} is {n}, above troupe's limit of {limit} for a manifest's counts and \
                     dimensions",
                    path.trim_start_matches('.')
                )
            })
        }
        _ => Ok(()),
    }
}

/// Format, version and family, checked before the family's fields are read so that an
/// unsupported bundle gets a message about what it is rather than about a missing field.
fn check_header(value: &serde_json::Value) -> std::result::Result<(), String> {
    let field = |name: &str| value.get(name);
    let format = field("format").and_then(|v| v.as_str()).unwrap_or("");
    ensure(format == FORMAT, || {
        format!("format is {}, expected `{FORMAT}`", file_name_shown(format))
    })?;
    let version = field("format_version").and_then(|v| v.as_u64());
    ensure(version == Some(u64::from(FORMAT_VERSION)), || {
        let found = match field("format_version") {
            None => "(missing)".to_owned(),
            Some(v) => v
                .as_u64()
                .map_or("not a whole number".into(), |v| v.to_string()),
        };
        format!(
            "format_version {found} is not supported (this runtime reads version {FORMAT_VERSION})"
        )
    })?;
    let family = field("family").and_then(|v| v.as_str()).unwrap_or("");
    ensure(FAMILIES.contains(&family), || {
        format!(
            "family {} is not supported (this runtime reads {})",
            file_name_shown(family),
            FAMILIES.join(", ")
        )
    })
}

/// The 32 bytes a SHA-256 written as 64 hexadecimal digits stands for.
fn sha256_from_hex(hex: &str) -> Option<[u8; 32]> {
    let digits = hex.as_bytes();
    if digits.len() != 64 {
        return None;
    }
    let mut out = [0u8; 32];
    for (byte, pair) in out.iter_mut().zip(digits.chunks_exact(2)) {
        let text = std::str::from_utf8(pair).ok()?;
        *byte = u8::from_str_radix(text, 16).ok()?;
    }
    Some(out)
}
