//! [`FamilySection`]: what the manifest and [`crate::Model`] ask of a family's section of
//! `troupe.json`: its checks, its graphs' interfaces, its text graphs, and how its model loads.
//! Each family implements it once (`<family>/family.rs`), and `manifest.rs`'s one registration
//! table dispatches to it, so that nothing above a family lists the families again.

use std::fmt::Debug;

use crate::family::Family;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::{BundleIo, ConditionFeedback, ConditionSpec, MotionSpec};
use crate::shared::error::Result;
use crate::shared::graph_spec::GraphSpec;

/// A family's section of the manifest.
pub(crate) trait FamilySection: Debug + Send + Sync {
    /// The family's name in `troupe.json` (`"armflow"`).
    fn name(&self) -> &'static str;
    /// Checks the section against itself and the common `motion` and `condition` sections.
    fn validate(&self, motion: &MotionSpec, condition: &ConditionSpec) -> Result<(), String>;
    /// Checks `condition.feedback`, which only a family that reads it back accepts.
    fn validate_feedback(
        &self,
        feedback: &ConditionFeedback,
        motion: &MotionSpec,
    ) -> Result<(), String> {
        let _ = motion;
        Err(format!(
            "condition.feedback `{}` is not read by {} bundles",
            feedback.kind,
            self.name()
        ))
    }
    /// Each graph as declared, next to the interface the runtime requires of it.
    fn graph_contract<'a>(
        &'a self,
        motion: &MotionSpec,
        condition: &ConditionSpec,
    ) -> Vec<(&'static str, &'a GraphSpec, GraphSpec)>;
    /// The `text_encoder` and `text_branch` the section declares.
    fn text_graphs(&self) -> (Option<&GraphSpec>, Option<&GraphSpec>) {
        (None, None)
    }
    /// Floats per CLIP token feature the text encoder gives: the condition's width unless the
    /// family's text branch reads another.
    fn text_token_dim(&self, condition: &ConditionSpec) -> usize {
        condition.dim
    }
    /// Loads the family's model from the bundle's files.
    fn load(&self, files: &BundleFiles, io: BundleIo) -> Result<Box<dyn Family>>;
}
