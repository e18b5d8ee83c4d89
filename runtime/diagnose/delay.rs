//! A torque delay to second order. A torque logged `d` late reads
//! tau(t - d), so the model's torque tau(t) is the logged torque `d` ahead:
//! the residual is -d tau' - d^2/2 tau'' of the logged torque. The
//! candidate's column is the first-order term alone (-tau', linear in d);
//! the second-order term is about -(omega d)^2 / 2 of the torque at the
//! motion's frequency omega, which on a joint without gravity load a
//! torque scale takes up (a UR10e's 25 ms at 0.88 Hz: a 1% scale named on
//! joint 1 beside the delay), and `evaluate --torque-delay` shifts the
//! torque exactly. Once a delay is named, its column becomes
//! -tau' - (d/2) tau'' at the fitted `d`, still linear in d, and the
//! selection runs again.

use super::candidate::{Candidate, width};
use super::fit::fit;
use super::kind::Kind;
use super::moments::Moments;
use super::stacked::Stacked;

/// Gives the named delay of `selected` its second-order term at the
/// fitted delay; the note to give when it did.
pub(super) fn second_order(
    data: &Stacked,
    m: &Moments,
    candidates: &mut [Candidate],
    selected: &[usize],
) -> Option<String> {
    let at = selected
        .iter()
        .position(|&c| candidates[c].kind == Kind::TorqueDelay)?;
    let fitted = fit(m, candidates, selected, |_| true)?;
    let offset: usize = selected[..at].iter().map(|&c| width(&candidates[c])).sum();
    let delay = fitted.theta[offset];
    let column = &mut candidates[selected[at]].columns[0];
    *column -= &data.measured_curvature * (0.5 * delay);
    Some(format!(
        "torque_delay: fitted again with its second-order term (half the delay times the \
         torque's second rate) at the first fit's {:.2} ms, and the effects chosen again",
        1e3 * delay
    ))
}

#[cfg(test)]
mod tests {
    use nalgebra::DVector;

    use super::*;
    use crate::diagnose::candidate::{Shape, linear};

    /// One joint whose torque, sin(omega t) at 1 Hz, is logged 50 ms late
    /// (omega d = 0.31), fitted with a delay and a torque scale: to first
    /// order a scale error of 5% takes up the second-order term (about
    /// (omega d)^2 / 2 of the torque); with the term in the delay's column
    /// the scale error is under a tenth of that, and the delay within 2%
    /// (what is left is of third order: sin(omega d) / omega).
    #[test]
    fn the_second_order_term_is_the_delay_not_a_scale() {
        let (samples, dt, delay) = (4000, 0.005, 0.05);
        let omega = std::f64::consts::TAU;
        let t = |s: usize| s as f64 * dt;
        let logged = |s: usize| (omega * (t(s) - delay)).sin();
        let model = DVector::from_fn(samples, |s, _| (omega * t(s)).sin());
        let residual = DVector::from_fn(samples, |s, _| logged(s)) - &model;
        let rate = DVector::from_fn(samples, |s, _| omega * (omega * (t(s) - delay)).cos());
        let curvature = DVector::from_fn(samples, |s, _| -omega * omega * logged(s));
        let data = Stacked {
            measured_curvature: curvature,
            ..Stacked::of_residual(residual, 1)
        };
        let mut candidates = vec![
            Candidate {
                joint: None,
                shape: Shape::Delay { sample_period: dt },
                ..linear(Kind::TorqueDelay, -rate)
            },
            linear(Kind::TorqueScale, model),
        ];
        let fitted = |candidates: &[Candidate]| {
            let m = Moments::new(&data, candidates);
            let theta = fit(&m, candidates, &[0, 1], |_| true).unwrap().theta;
            (theta[0], theta[1])
        };
        let (_, first_scale) = fitted(&candidates);
        assert!(first_scale.abs() > 0.04, "{first_scale}");
        let m = Moments::new(&data, &candidates);
        assert!(second_order(&data, &m, &mut candidates, &[0, 1]).is_some());
        let (second, second_scale) = fitted(&candidates);
        assert!(
            second_scale.abs() < 0.1 * first_scale.abs(),
            "{second_scale}"
        );
        assert!((second / delay - 1.0).abs() < 0.02, "{second}");
    }
}
