//! What a model family plugs into, and the neutral machinery every family shares: the layer
//! between `shared`/`motion` beneath and the family folders above.
//!
//! - [`Family`] (here): a family's loaded model (`armflow::Armflow`, `umf::Umf`,
//!   `magnet::Magnet`, `arflow::Arflow`) answers the questions every caller asks whatever the
//!   family, gives its text encoder if it has one, and opens its default stream if it streams.
//!   [`crate::Model`] holds one behind this trait and hands out the family's own type for
//!   everything else (`model.armflow()?`), so no layer above a family grows with its operations.
//! - `stream.rs`: the [`stream::Stream`] trait a streaming family implements, and the
//!   capabilities a stream reports.
//! - `session.rs`: the [`session::Session`] that boxes any stream, the one way to step one.
//! - `motion/`: the motion stages a session runs around its stream by the stream's frame
//!   layout (joints in, poses out, guard, smoothing, foot lock).

pub(crate) mod motion;
pub(crate) mod section;
pub(crate) mod session;
pub(crate) mod stream;

use std::any::Any;
use std::fmt::Debug;

use crate::family::session::Session;
use crate::shared::error::{a_or_an, Error, Result};
use crate::shared::snapshot::{cannot_snapshot, SnapshotReader};
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::PromptEncoder;

/// A loaded model of one family.
pub(crate) trait Family: Send + Sync + Debug + Any {
    /// The family's manifest name (`"armflow"`).
    fn name(&self) -> &'static str;
    /// Motion frames per latent token; 0 when tokens are not spans of frames (UMF) or there are
    /// none (ARFlow).
    fn frames_per_token(&self) -> usize;
    /// Floats per latent token of one person.
    fn latent_dim(&self) -> usize;
    /// Algorithmic latency of the family's default stream, in frames (0 without one).
    fn latency_frames(&self) -> usize;
    /// The most frames one step with `n` new frames can return (0 without a stream).
    fn max_output_frames(&self, n: usize) -> usize;
    /// Frames per generated clip (0 for a family without clips).
    fn clip_frames(&self) -> usize {
        0
    }
    /// The text encoder, for a bundle that turns prompts into conditions.
    fn prompt_encoder(&self) -> Option<PromptEncoder<'_>> {
        None
    }
    /// The official text branch (CLIP features to a condition), when the bundle has one.
    fn text_branch(&self) -> Option<TextBranch<'_>> {
        None
    }
    /// The family's stream with its defaults and the common `options`.
    fn session(&self, options: &SessionOptions) -> Result<Session> {
        let _ = options;
        Err(does_not_stream(self.name()))
    }
    /// The common options the family's default stream starts with (the bundle's steps and
    /// context, seed 0), for callers that show or edit them before opening it.
    fn session_defaults(&self) -> Result<SessionOptions> {
        Err(does_not_stream(self.name()))
    }
    /// The stream whose snapshot payload `payload` holds (its frame already checked by
    /// [`crate::Model::restore`]).
    fn restore(&self, payload: &mut SnapshotReader) -> Result<Session> {
        let _ = payload;
        Err(match self.session_defaults() {
            Err(does_not_stream) => does_not_stream,
            Ok(_) => cannot_snapshot(self.name()),
        })
    }
    /// For the typed access of [`crate::Model`].
    fn as_any(&self) -> &dyn Any;
}

/// The options every stream takes, whatever its family; the rest take the bundle's defaults.
/// Each family's own options type ([`crate::armflow::ReactorOptions`],
/// [`crate::magnet::PartnerOptions`], [`crate::arflow::ArflowOptions`]) holds everything it
/// offers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SessionOptions {
    /// Seed of the portable noise generator ([`crate::noise`]).
    pub seed: u64,
    /// Sampler steps: MeanFlow steps per token (ARMFlow), DDIM steps per chunk (MAGNet), flow
    /// steps per frame (ARFlow).
    pub steps: Option<u32>,
    /// Context the stream keeps: ARMFlow's cache capacity in tokens (`<sos>` included, >= 2),
    /// MAGNet's context tokens per window; ARFlow keeps its whole history and takes `None`.
    pub context_capacity: Option<usize>,
}

/// Options that open a stream: [`SessionOptions`] for any family's default stream, or one
/// family's own options type for that family's. `Model::session` takes any of them; a family's
/// options given to another family's model are refused with [`Error::Unsupported`].
pub trait StreamOptions: sealed::Sealed {
    /// Opens the stream on `family`.
    #[doc(hidden)]
    #[allow(private_interfaces)]
    fn open(self, family: &dyn Family) -> Result<Session>;
}

pub(crate) mod sealed {
    /// Only troupe's option types open streams.
    pub trait Sealed {}
}

impl sealed::Sealed for SessionOptions {}

impl StreamOptions for SessionOptions {
    #[allow(private_interfaces)]
    fn open(self, family: &dyn Family) -> Result<Session> {
        family.session(&self)
    }
}

/// The error for a session of a family that does not stream.
fn does_not_stream(family: &str) -> Error {
    Error::Unsupported(format!(
        "a `{family}` model does not stream; a session needs an `armflow`, a `magnet` or an \
         online `arflow` bundle"
    ))
}

/// `family` as the family type `F`, or [`Error::Unsupported`] saying that `what` needs a
/// `needed` bundle and which family this one is.
pub(crate) fn family_as<'a, F: 'static>(
    family: &'a dyn Family,
    needed: &str,
    what: &str,
) -> Result<&'a F> {
    family
        .as_any()
        .downcast_ref::<F>()
        .ok_or_else(|| wrong_family(None, family.name(), needed, what))
}

/// The error for using a `family` bundle (named `bundle` when known) where a `needed` one is:
/// `what` needs it.
pub(crate) fn wrong_family(bundle: Option<&str>, family: &str, needed: &str, what: &str) -> Error {
    let this = match bundle {
        Some(name) => format!("bundle `{name}` is"),
        None => "this is".to_owned(),
    };
    Error::Unsupported(format!(
        "{this} {} `{family}` model; {what} needs {} `{needed}` bundle",
        a_or_an(family),
        a_or_an(needed)
    ))
}
