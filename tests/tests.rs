//! Integration tests of the product, one binary (see `util` for helpers).

mod bags;
mod beyond_tau;
mod cli;
mod data_effects;
mod descriptions;
mod diagnose;
mod dynamics;
mod excite;
mod freshness;
mod generated_code;
mod held_joints;
mod hidden_effects;
mod hostile;
mod hostile2;
mod inertial;
mod lumping;
mod module_graph;
mod pointwise;
mod prismatic;
mod readers_fuzz;
mod sanity_gate;
mod springs;
mod stribeck;
mod study;
mod urdf_chains;
mod util;
