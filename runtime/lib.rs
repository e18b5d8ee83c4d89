//! `sdnn-runtime`: the virtual robot, analytical data synthesis, the MLP
//! trainer (the SDNN method), model diagnosis and the command line, over
//! models behind the [`Dynamics`] trait. The compiled models are another
//! crate (`sdnn-models`) that the `sdnn` binary installs at start
//! ([`dynamics::install`]); [`oracle`] is an independent numeric recursive
//! Newton-Euler built from the descriptions, used to verify them.

pub mod args;
pub mod bounded;
pub mod cli;
pub mod commands;
pub mod corrections;
pub mod described;
pub mod diagnose;
pub mod digits;
pub mod dynamics;
pub mod errors;
pub mod excite;
pub mod identified;
pub mod import_log;
pub mod import_urdf;
pub mod imports;
pub mod inputs;
pub mod kernels;
pub mod limits;
pub mod line_ends;
pub mod mlp;
pub mod oracle;
pub mod output;
pub mod parallel;
pub mod preprocess;
pub mod ranges;
pub mod report;
pub mod rosbag;
pub mod seeds;
pub mod shell;
pub mod sim;
pub mod study;
pub mod suggest;
pub mod trajectory;

pub use dynamics::{Dynamics, model, model_names};
