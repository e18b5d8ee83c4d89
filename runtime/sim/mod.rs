//! A virtual robot: it tracks planned joint trajectories with a
//! computed-torque controller on a simulated plant and records joint angle,
//! velocity and torque the way the thesis recorded the Kinova Gen3 Lite
//! (thesis 2.1: random waypoints, 20 s at 1 kHz, current-based torque).

pub mod models;
pub mod plant;
pub mod reference;
pub mod replay;
pub mod simulate;
