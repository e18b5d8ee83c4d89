//! sdnn: exact arm dynamics compiled from a description file, analytical
//! data synthesis, an MLP trainer (the SDNN method) and model diagnosis.
//!
//! This crate is the product as one library: the runtime (`sdnn-runtime`,
//! re-exported whole) with the compiled models of every `models/*.toml` as
//! [`models`] (crate `sdnn-models`). [`oracle`] is an independent numeric
//! recursive Newton-Euler built from the same descriptions, used to verify
//! them.

pub use sdnn_models as models;
pub use sdnn_runtime::*;

/// Makes the compiled models the ones the runtime finds by name (the
/// binary does this first; [`model`] does it too). Idempotent.
pub fn install_models() {
    sdnn_runtime::dynamics::install(models::MODELS);
}

/// The compiled model with this name.
pub fn model(name: &str) -> Option<&'static dyn Dynamics> {
    install_models();
    sdnn_runtime::dynamics::model(name)
}
