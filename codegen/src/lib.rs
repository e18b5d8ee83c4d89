//! Robot descriptions to flat Rust dynamics.
//!
//! Three steps, like prost-build: [`Description::load`] parses, validates and
//! lumps fixed and locked joints; `generate` (pure) derives the Lagrangian
//! with Symbolica and returns the Rust source as a string; [`Config`] writes
//! it, only when stale, plus a registry for the runtime. Without the
//! `symbolic` feature only the description side and the fingerprints are
//! available, so the runtime can parse descriptions without Symbolica.

pub mod description;
pub mod error;
pub mod fingerprint;
pub mod names;
pub mod reduce;
mod schema;
#[cfg(any(feature = "symbolic", test))]
mod states;
pub mod tool;
mod validate;

#[cfg(feature = "symbolic")]
mod composed;
#[cfg(feature = "symbolic")]
mod config;
#[cfg(feature = "symbolic")]
mod crosscheck;
pub mod derivative;
#[cfg(feature = "symbolic")]
mod emit;
#[cfg(feature = "symbolic")]
mod emit_lanes;
#[cfg(feature = "symbolic")]
mod generate;
#[cfg(feature = "symbolic")]
mod lagrangian;
pub mod lanes;
#[cfg(feature = "symbolic")]
mod listing;
#[cfg(feature = "symbolic")]
mod printer;
pub mod program;
pub mod recursive;
#[cfg(feature = "symbolic")]
pub mod session;
#[cfg(feature = "symbolic")]
mod support;

#[cfg(feature = "symbolic")]
pub use config::{Config, Outcome, Report, registry};
pub use description::{Description, Inertia, Joint, JointEffects, JointKind, Limits, Link, Origin};
pub use error::DescriptionError;
#[cfg(feature = "symbolic")]
pub use generate::{Cost, Generated, generate};
pub use reduce::{Body, Chain, Coupling, Inertial};
pub use schema::{EFFECT_CONSTANTS, EFFECT_NAMES, EFFECTS_PER_JOINT, PARAMETERS_PER_JOINT};

/// The generated file of a model, relative to the models directory.
pub fn generated_file_name(model: &str) -> String {
    format!("generated/{model}.rs")
}
