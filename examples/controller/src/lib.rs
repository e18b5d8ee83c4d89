//! A joint controller for the Franka Panda on a microcontroller: computed
//! torque with the generated dynamics, in a `#![no_std]` crate with no
//! dependency. The generated file is plain Rust that needs only `core`;
//! include it (or copy it) and call its functions.
#![no_std]

/// The Panda's generated dynamics: `tau`, `mass_matrix`, `gravity`, ...
pub mod panda {
    include!("../../../models/generated/panda.rs");
}

/// Feedback gains of the computed-torque law.
#[derive(Debug, Clone, Copy)]
pub struct Gains {
    /// Position gain, 1/s^2.
    pub kp: f64,
    /// Velocity gain, 1/s.
    pub kd: f64,
}

/// Computed torque: tau = M(q) a + c(q, qd) + g(q) + effects(qd) with
/// a = qdd_ref + kp (q_ref - q) + kd (qd_ref - qd), N m.
#[must_use]
pub fn computed_torque(
    q: &[f64; panda::DOF],
    qd: &[f64; panda::DOF],
    reference: [&[f64; panda::DOF]; 3],
    gains: Gains,
) -> [f64; panda::DOF] {
    let [q_ref, qd_ref, qdd_ref] = reference;
    let mut a = [0.0; panda::DOF];
    for i in 0..panda::DOF {
        a[i] = qdd_ref[i] + gains.kp * (q_ref[i] - q[i]) + gains.kd * (qd_ref[i] - qd[i]);
    }
    panda::tau(q, qd, &a)
}

/// Gravity compensation alone: the torque that holds the arm still at q.
#[must_use]
pub fn hold(q: &[f64; panda::DOF]) -> [f64; panda::DOF] {
    panda::gravity(q)
}
