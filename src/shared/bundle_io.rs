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
}

impl ConditionSpec {
    /// The condition that stands for "none": `null`, or zeros.
    pub fn null_or_zeros(&self) -> Vec<f32> {
        self.null.clone().unwrap_or_else(|| vec![0f32; self.dim])
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
