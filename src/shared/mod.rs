//! The machinery every family stands on, one concept per module. Nothing here knows a family or
//! the [`crate::Model`] handle: a module of this layer imports only from this layer.

pub(crate) mod attention;
pub mod bundle;
pub(crate) mod bundle_io;
pub(crate) mod checks;
pub(crate) mod clock;
pub mod error;
pub(crate) mod files;
pub mod graph;
pub mod graph_spec;
pub(crate) mod half_products;
pub(crate) mod isa;
pub mod limits;
pub(crate) mod logging;
pub mod noise;
pub(crate) mod onnx_guard;
pub(crate) mod panics;
pub(crate) mod paths;
pub mod progress;
pub(crate) mod sealed;
pub(crate) mod snapshot;
pub mod solver;
pub(crate) mod text;
pub(crate) mod threads;
pub(crate) mod unit_axes;
pub(crate) mod vector_state;
