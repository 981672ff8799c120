//! The loaded graphs of a `umf` bundle, with the manifest sections they are run by.

use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::error::Result;
use crate::shared::graph::{load_graphs, Graph, PlanPolicy};
use crate::shared::text::branch::TextBranch;
use crate::shared::text::prompt::{PromptEncoder, Prompts};
use crate::shared::text::ONE_ROW_ROLES;

use super::spec::UmfSpec;

/// A `umf` bundle's graphs, loaded and optimised, with its own manifest section and the common
/// facts it needs. Shared (`Arc`) by the [`crate::Model`] handles that loaded it.
#[derive(Debug)]
pub(crate) struct Networks {
    pub io: BundleIo,
    pub spec: UmfSpec,
    pub prior: Graph,
    pub reaction: Graph,
    pub context: Graph,
    pub decoder: Graph,
    pub text_branch: Option<Graph>,
    /// CLIP's text tower and the tokenizer, when the bundle takes prompts.
    text_encoder: Option<Graph>,
    prompts: Option<Prompts>,
}

impl Networks {
    /// Loads every graph `spec` names from `files`.
    pub(crate) fn load(files: &BundleFiles, io: BundleIo, spec: UmfSpec) -> Result<Self> {
        let g = &spec.graphs;
        let mut wanted = vec![
            ("prior", &g.prior),
            ("reaction", &g.reaction),
            ("context", &g.context),
            ("decoder", &g.decoder),
        ];
        wanted.extend(g.text_branch.as_ref().map(|t| ("text_branch", t)));
        wanted.extend(g.text_encoder.as_ref().map(|t| ("text_encoder", t)));
        let mut graphs = load_graphs(files, &wanted, |role| PlanPolicy {
            one_row: ONE_ROW_ROLES.contains(&role),
            ..PlanPolicy::default()
        })?
        .into_iter();
        let mut next = || graphs.next().expect("one graph per wanted entry");
        Ok(Self {
            prior: next(),
            reaction: next(),
            context: next(),
            decoder: next(),
            text_branch: g.text_branch.as_ref().map(|_| next()),
            text_encoder: g.text_encoder.as_ref().map(|_| next()),
            prompts: io
                .tokenizer
                .as_ref()
                .map(|t| Prompts::load(files, t))
                .transpose()?,
            io,
            spec,
        })
    }

    /// The text branch, when the bundle has one: it reads CLIP features as wide as the prior's
    /// text and writes the whole `[prior text ; reaction text]` condition.
    pub(crate) fn text_branch(&self) -> Option<TextBranch<'_>> {
        self.text_branch.as_ref().map(|graph| TextBranch {
            graph,
            token_dim: self.spec.text.prior_dim,
            condition_dim: self.io.condition.dim,
        })
    }

    /// The prompt encoder, when the bundle takes prompts.
    pub(crate) fn prompt_encoder(&self) -> Option<PromptEncoder<'_>> {
        PromptEncoder::assemble(
            self.prompts.as_ref(),
            self.text_encoder.as_ref(),
            self.text_branch(),
        )
    }
}
