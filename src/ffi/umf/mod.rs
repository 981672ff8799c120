//! The C entry points of the `umf` family: text-to-group generation.

pub mod group;
