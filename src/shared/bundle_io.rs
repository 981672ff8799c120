//! What a bundle takes in and gives out whatever its family: per-frame motion features and the
//! conditioning vector (the manifest's `motion` and `condition` sections), and [`BundleIo`], the
//! copy of them, with the bundle's name, that a family keeps beside its graphs.

use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use crate::shared::text::prompt::TokenizerSpec;

/// Per-frame motion features.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MotionSpec {
    /// Feature layout name, e.g. `interhuman262`.
    pub layout: String,
    /// Floats per frame.
    pub frame_dim: usize,
    /// Frames per second of the motion.
    pub fps: u32,
    /// The skeleton the features are defined on; when absent, the layout's own (see
    /// [`MotionSpec::skeleton`]).
    #[serde(default, skip_serializing_if = "Option::is_none", rename = "skeleton")]
    pub declared_skeleton: Option<String>,
}

impl MotionSpec {
    /// The skeleton the features are defined on: the declared one, else the layout's own
    /// (`t2m22` for `interhuman262`, `smplx55` for `interx336`, `unknown` otherwise).
    pub fn skeleton(&self) -> &str {
        match (&self.declared_skeleton, self.layout.as_str()) {
            (Some(s), _) => s,
            (None, "interhuman262") => "t2m22",
            (None, "interx336") => "smplx55",
            (None, _) => "unknown",
        }
    }
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
    /// What `null` is: `empty_prompt` (the prompt "" through the checkpoint's CLIP and text
    /// branch, computed at export: the official meaning of "no text"), `zeros` (no `null`, or
    /// all zeros), `label:NAME` (the vector of that label) or `vector` (a vector the producer
    /// chose). Absent in older bundles: `zeros` without `null`, `vector` with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub null_source: Option<String>,
    /// Named conditions a bundle was trained on (the demo model's partner rules), in the order
    /// the bundle lists them. Empty for bundles conditioned on free vectors (text features).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub labels: Vec<ConditionLabel>,
    /// Floats the runtime appends to the caller's `dim` before every token, when the model
    /// was trained to see its own state in its condition (ARMFlow only). The conditioning graph
    /// then reads `dim + feedback.dim` floats; callers still pass `dim`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feedback: Option<ConditionFeedback>,
}

/// What the runtime feeds back into the condition (the manifest's `condition.feedback`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ConditionFeedback {
    /// `partner_placement`: `[valid, dx, dz, fx, fz]`, where the reactor stood at the last
    /// frame of the previous token relative to the actor (root offset on the floor, metres)
    /// and its unit facing on the floor; all zeros before the first token.
    pub kind: String,
    /// Floats fed back (5 for `partner_placement`).
    pub dim: usize,
}

impl ConditionFeedback {
    /// The only kind there is.
    pub const PARTNER_PLACEMENT: &'static str = "partner_placement";
}

/// A named condition: what to pass for a behaviour the bundle knows by name.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ConditionLabel {
    /// The name a caller asks for (`mirror`).
    pub name: String,
    /// The conditioning vector, `condition.dim` floats.
    pub vector: Vec<f32>,
    /// One line on what the condition makes the model do.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub about: String,
}

impl ConditionSpec {
    /// Floats the runtime feeds back after the caller's (0 without `feedback`).
    pub fn feedback_dim(&self) -> usize {
        self.feedback.as_ref().map_or(0, |f| f.dim)
    }

    /// Floats the conditioning graph reads: the caller's and the fed-back ones.
    pub fn graph_dim(&self) -> usize {
        self.dim + self.feedback_dim()
    }

    /// The condition that stands for "none": `null`, or zeros.
    pub fn null_or_zeros(&self) -> Vec<f32> {
        self.null.clone().unwrap_or_else(|| vec![0f32; self.dim])
    }

    /// What the null condition is ([`ConditionSpec::null_source`], defaulted for older
    /// bundles).
    pub fn null_source(&self) -> &str {
        match (&self.null_source, &self.null) {
            (Some(source), _) => source,
            (None, None) => "zeros",
            (None, Some(_)) => "vector",
        }
    }

    /// The vector of the label called `name`, if the bundle has one.
    pub fn labelled(&self, name: &str) -> Option<&[f32]> {
        self.labels
            .iter()
            .find(|l| l.name == name)
            .map(|l| l.vector.as_slice())
    }

    /// `null` and every label: the right length, finite; label names non-empty and unique.
    pub(crate) fn validate(&self) -> Result<(), String> {
        let check = |what: &str, v: &[f32]| -> Result<(), String> {
            if v.len() != self.dim {
                return Err(format!(
                    "{what} holds {} floats, condition.dim is {}",
                    v.len(),
                    self.dim
                ));
            }
            if !v.iter().all(|x| x.is_finite()) {
                return Err(format!("{what} holds a non-finite value"));
            }
            Ok(())
        };
        if let Some(null) = &self.null {
            check("condition.null", null)?;
        }
        let null = self.null_or_zeros();
        match self.null_source() {
            "zeros" if null.iter().any(|&v| v != 0.0) => {
                return Err("condition.null_source is `zeros` but condition.null is not".into())
            }
            "empty_prompt" | "vector" if self.null.is_none() => {
                return Err(format!(
                    "condition.null_source `{}` needs condition.null",
                    self.null_source()
                ))
            }
            "zeros" | "empty_prompt" | "vector" => {}
            source => match source.strip_prefix("label:") {
                Some(name) if self.labelled(name) == Some(&null[..]) => {}
                Some(name) => {
                    return Err(format!(
                        "condition.null_source names label `{name}`, whose vector is not \
                         condition.null"
                    ))
                }
                None => {
                    return Err(format!(
                        "condition.null_source `{source}` is unknown (empty_prompt, zeros, \
                         label:NAME or vector)"
                    ))
                }
            },
        }
        if let Some(feedback) = &self.feedback {
            if (feedback.kind.as_str(), feedback.dim) != (ConditionFeedback::PARTNER_PLACEMENT, 5) {
                return Err(format!(
                    "condition.feedback `{}` of {} floats is unknown (partner_placement, 5)",
                    feedback.kind, feedback.dim
                ));
            }
        }
        for (i, label) in self.labels.iter().enumerate() {
            if label.name.is_empty() || label.name.contains('\0') {
                return Err(format!(
                    "condition.labels[{i}] has an empty or NUL-holding name"
                ));
            }
            if self.labels[..i].iter().any(|l| l.name == label.name) {
                return Err(format!("condition.labels: `{}` is named twice", label.name));
            }
            check(
                &format!("condition.labels[{i}] (`{}`)", label.name),
                &label.vector,
            )?;
        }
        Ok(())
    }
}

/// The family-neutral facts of a bundle a family's networks need at run time: its name (for
/// messages), its motion features and its condition. Copied from the manifest at load, so that a
/// family never reads the manifest (which sits above the families).
#[derive(Debug, Clone)]
pub(crate) struct BundleIo {
    /// The bundle's `name`.
    pub name: String,
    /// The manifest's `motion` section.
    pub motion: MotionSpec,
    /// The manifest's `condition` section.
    pub condition: ConditionSpec,
    /// The manifest's `tokenizer` section, for bundles with a text encoder.
    pub tokenizer: Option<TokenizerSpec>,
    /// The model's identity (`BundleFiles::identity`), known once the load has read every file:
    /// shared by every clone, set by `Model` when the family has loaded.
    pub identity: Arc<OnceLock<[u8; 32]>>,
}

impl BundleIo {
    /// The model's identity, which snapshots of its streams carry.
    pub fn identity(&self) -> [u8; 32] {
        // Networks are reachable only through a loaded model, which set it.
        self.identity.get().copied().unwrap_or_default()
    }

    /// Floats per motion frame.
    pub fn frame_dim(&self) -> usize {
        self.motion.frame_dim
    }
}
