//! `sdnn-models`: the generated dynamics of every `models/*.toml`, one
//! module per model (`sdnn_models::panda::tau(&q, &qd, &qdd)`), and
//! [`MODELS`], each behind the `Dynamics` trait. The build script
//! regenerates stale models (Symbolica runs only then) and writes the
//! registry included here.

include!(concat!(env!("OUT_DIR"), "/models.rs"));
