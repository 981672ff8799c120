//! A prompt to a condition: the bundle's tokenizer (the manifest's `tokenizer` section and its
//! merges file), its text tower and its text branch, with a small cache of the prompts encoded
//! last, so that a game asking for the same sentence again pays nothing.

use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use super::branch::TextBranch;
use super::encoder::TextTower;
use super::tokenizer::ClipTokenizer;
use crate::shared::bundle::BundleFiles;
use crate::shared::error::{Error, Result};
use crate::shared::limits::LIMITS;

/// The manifest's `tokenizer` section: how a prompt becomes the text encoder's token ids.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Eq)]
pub struct TokenizerSpec {
    /// The tokenizer: `clip-bpe` (OpenAI CLIP's byte-pair encoding), the only one so far.
    pub kind: String,
    /// The bundle file holding the byte-pair merges (a `#version` line, then one per line).
    pub merges_file: String,
    /// How many merges the file holds (48,894 for CLIP's own vocabulary).
    pub merges: usize,
    /// Token ids per prompt, padded with 0 and truncated (CLIP's 77).
    pub context: usize,
}

impl TokenizerSpec {
    /// Checks the section against itself.
    pub(crate) fn validate(&self) -> std::result::Result<(), String> {
        if self.kind != "clip-bpe" {
            return Err(format!(
                "tokenizer.kind `{}` is unknown (this runtime reads `clip-bpe`)",
                self.kind
            ));
        }
        if self.context < 2 || self.context as u64 > LIMITS.max_text_tokens {
            return Err(format!(
                "tokenizer.context {} must be in 2..={} (CLIP's context)",
                self.context, LIMITS.max_text_tokens
            ));
        }
        Ok(())
    }
}

/// Prompts encoded last, most recent first.
const CACHED_PROMPTS: usize = 64;

/// A bundle's tokenizer and its cache of encoded prompts; owned by the family's networks.
#[derive(Debug)]
pub(crate) struct Prompts {
    tokenizer: ClipTokenizer,
    context: usize,
    cache: Mutex<Vec<(String, Vec<f32>)>>,
}

impl Prompts {
    /// Reads the merges file `spec` names and builds the tokenizer; the file must hold the
    /// number of merges the manifest states.
    pub(crate) fn load(files: &BundleFiles, spec: &TokenizerSpec) -> Result<Self> {
        let path = files.path_of(&spec.merges_file);
        let bad = |message: String| Error::Manifest {
            path: path.clone(),
            message,
        };
        let bytes = files.read(&spec.merges_file, LIMITS.max_manifest_bytes)?;
        let text = std::str::from_utf8(&bytes).map_err(|_| bad("not UTF-8 text".into()))?;
        let tokenizer = ClipTokenizer::from_merges(text).map_err(|e| bad(e.to_string()))?;
        if tokenizer.merges() != spec.merges {
            return Err(bad(format!(
                "holds {} merges, the manifest's tokenizer.merges says {}",
                tokenizer.merges(),
                spec.merges
            )));
        }
        Ok(Self {
            tokenizer,
            context: spec.context,
            cache: Mutex::new(Vec::new()),
        })
    }

    /// The token ids the text tower reads for `prompt`: `context` ids, truncated and padded as
    /// CLIP's `tokenize(..., truncate=True)`.
    pub(crate) fn token_ids(&self, prompt: &str) -> Result<Vec<i64>> {
        self.tokenizer.tokenize(prompt, self.context)
    }

    fn cached(&self, prompt: &str) -> Option<Vec<f32>> {
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        let i = cache.iter().position(|(p, _)| p == prompt)?;
        let entry = cache.remove(i);
        let condition = entry.1.clone();
        cache.insert(0, entry);
        Some(condition)
    }

    fn remember(&self, prompt: &str, condition: &[f32]) {
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|(p, _)| p != prompt);
        cache.insert(0, (prompt.to_owned(), condition.to_vec()));
        cache.truncate(CACHED_PROMPTS);
    }
}

/// Everything a prompt goes through, borrowed from the family's networks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PromptEncoder<'g> {
    /// The tokenizer and cache.
    pub prompts: &'g Prompts,
    /// CLIP's text tower.
    pub tower: TextTower<'g>,
    /// The family's text branch.
    pub branch: TextBranch<'g>,
}

impl<'g> PromptEncoder<'g> {
    /// The encoder of a family's loaded text parts, when it has all three.
    pub(crate) fn assemble(
        prompts: Option<&'g Prompts>,
        tower: Option<&'g crate::shared::graph::Graph>,
        branch: Option<TextBranch<'g>>,
    ) -> Option<Self> {
        let (prompts, graph, branch) = (prompts?, tower?, branch?);
        Some(Self {
            prompts,
            tower: TextTower {
                graph,
                context: prompts.context,
                token_dim: branch.token_dim,
            },
            branch,
        })
    }

    /// The condition for `prompt`: tokens, CLIP's features, the text branch at the end-of-text
    /// token. Served from the cache when the prompt was encoded recently.
    pub(crate) fn encode(&self, prompt: &str) -> Result<Vec<f32>> {
        if let Some(condition) = self.prompts.cached(prompt) {
            return Ok(condition);
        }
        let ids = self.prompts.token_ids(prompt)?;
        let eot = ClipTokenizer::end_of_text_index(&ids).unwrap_or(0);
        let features = self.tower.features(&ids)?;
        let features =
            ndarray::ArrayView2::from_shape((ids.len(), self.tower.token_dim), &features)
                .expect("the tower returned [context, token_dim]");
        let condition = self.branch.encode(features, eot)?;
        self.prompts.remember(prompt, &condition);
        Ok(condition)
    }
}

/// The error of a prompt given to a bundle that takes none.
pub(crate) fn no_prompts(bundle: &str) -> Error {
    Error::InvalidInput(format!(
        "bundle `{bundle}` takes no text prompts (it has no text_encoder graph and tokenizer; \
         re-export it from a checkpoint that carries CLIP's text tower)"
    ))
}
