//! What a bundle takes in and gives out whatever its family: per-frame motion features and the
//! conditioning vector (the manifest's `motion` and `condition` sections), and [`BundleIo`], the
//! copy of them, with the bundle's name, that a family keeps beside its graphs.

use serde::{Deserialize, Serialize};

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
    /// Named conditions a bundle was trained on (the demo model's partner rules), in the order
    /// the bundle lists them. Empty for bundles conditioned on free vectors (text features).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub labels: Vec<ConditionLabel>,
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
    /// The condition that stands for "none": `null`, or zeros.
    pub fn null_or_zeros(&self) -> Vec<f32> {
        self.null.clone().unwrap_or_else(|| vec![0f32; self.dim])
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
}

impl BundleIo {
    /// Floats per motion frame.
    pub fn frame_dim(&self) -> usize {
        self.motion.frame_dim
    }
}
