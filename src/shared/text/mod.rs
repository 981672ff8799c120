//! Text to a family's condition vector, as the official ARMFlow and UMF code computes it: a
//! prompt is tokenized as CLIP tokenizes it (`tokenizer`), CLIP's text tower gives per-token
//! features (`encoder`), and the family's trainable text branch turns the features at the
//! end-of-text token into the condition (`branch`). `prompt` puts the three together.

pub(crate) mod branch;
pub(crate) mod encoder;
pub(crate) mod prompt;
pub(crate) mod tokenizer;

/// The text graphs, which troupe runs one prompt at a time (`encoder`, `branch`), so they are
/// planned for one row.
pub(crate) const ONE_ROW_ROLES: [&str; 2] = ["text_encoder", "text_branch"];
