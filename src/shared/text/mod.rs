//! Text to a family's condition vector, as the official ARMFlow and UMF code computes it: a
//! prompt is tokenized as CLIP tokenizes it, CLIP's text tower gives per-token features, and the
//! family's trainable text branch turns the features at the end-of-text token into the
//! condition.

pub(crate) mod branch;
