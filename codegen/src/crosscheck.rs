//! The structured programs against Symbolica's expanded Lagrangian: both
//! derive the same torques by different routes (Newton-Euler over named
//! constants with regrouped parameters, Euler-Lagrange over the description's
//! standard parameters), so agreement on random states checks kinematics,
//! regrouping and emission inputs at once.

use crate::lagrangian::RigidBodyTorque;
use crate::program::NodeId;
use crate::recursive::Traced;
use crate::recursive::program_inputs;
use crate::reduce::Chain;
use crate::states::uniform;

/// States compared; each is a full evaluation of both forms.
const STATES: usize = 24;
/// Relative tolerance (both forms are exact up to rounding).
const TOLERANCE: f64 = 1e-9;

/// Compares tau (rigid part) and the regressor's inertial columns.
pub fn against_lagrangian(
    traced: &Traced,
    rigid: &RigidBodyTorque,
    chain: &Chain,
) -> Result<(), String> {
    let n = chain.bodies.len();
    let parameters: Vec<f64> = chain
        .bodies
        .iter()
        .flat_map(|b| b.inertial.standard_parameters())
        .collect();
    let effects: Vec<_> = chain.bodies.iter().map(|b| b.effects).collect();
    let mut seed = 0x5eed_u64;
    for _ in 0..STATES {
        let mut draw =
            |scale: f64| -> Vec<f64> { (0..n).map(|_| scale * uniform(&mut seed)).collect() };
        let (q, qd, qdd) = (draw(std::f64::consts::PI), draw(2.0), draw(5.0));
        let x = program_inputs(chain, &q, &qd, &qdd);
        let eval = |roots: &[NodeId]| traced.dag.evaluate(roots, &x);
        let y = eval(&traced.regressor);
        let tau = eval(&traced.tau);
        let width = crate::schema::PARAMETERS_PER_JOINT * n;
        for i in 0..n {
            let expected: Vec<f64> = rigid.regressor[i].iter().map(|p| p.evaluate(&x)).collect();
            let got = &y[i * width..i * width + 10 * n];
            compare(&format!("regressor row {}", i + 1), got, &expected)?;
            let e = &effects[i];
            let effect = e.motion_torque(qd[i], qdd[i]) + e.position_torque(q[i]);
            let lagrange: f64 = expected.iter().zip(&parameters).map(|(c, p)| c * p).sum();
            compare(&format!("tau[{}]", i + 1), &[tau[i]], &[lagrange + effect])?;
        }
    }
    Ok(())
}

fn compare(what: &str, got: &[f64], want: &[f64]) -> Result<(), String> {
    let scale = want.iter().fold(1.0_f64, |s, w| s.max(w.abs()));
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        if (g - w).abs() > TOLERANCE * scale || !g.is_finite() {
            return Err(format!(
                "the generated {what} (entry {k}) is {g} where the Lagrangian gives {w}: \
                 a generator bug, please report it with the TOML"
            ));
        }
    }
    Ok(())
}
