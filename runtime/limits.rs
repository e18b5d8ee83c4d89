//! Joint positions against the description's limits, for every command
//! that reads positions: the sanity gate refuses recordings that leave
//! them (`diagnose`, `evaluate`), and `tau`, `qdd` and `pose` warn. One
//! reading of an excursion serves them all: degrees read as radians,
//! angles a turn off the description's zero, or another joint's column.

use std::f64::consts::TAU;

use nalgebra::DMatrix;

use crate::digits::sig;
use crate::dynamics::Dynamics;
use crate::trajectory::AngleUnit;

/// Room past a limit, as a share of the joint's range: encoders read a
/// little past a limit (a description's limits are often the controller's
/// soft limits, inside the mechanical stops; an overshoot; a zero offset).
/// A tenth of the range is well beyond those and well short of what
/// degrees read as radians make of any motion of a few degrees or more
/// (57 times the value).
pub const LIMIT_MARGIN: f64 = 0.1;

/// One moving joint's limits as the description states them.
#[derive(Debug, Clone, Copy)]
pub struct Limit {
    pub lower: f64,
    pub upper: f64,
    pub revolute: bool,
}

impl Limit {
    /// Whether `low..=high` stays within the limits and the margin.
    fn holds(&self, low: f64, high: f64) -> bool {
        let margin = LIMIT_MARGIN * (self.upper - self.lower);
        low >= self.lower - margin && high <= self.upper + margin
    }
}

/// The smallest and largest position of a joint.
pub type Range = (f64, f64);

/// What positions beyond the limits read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reading {
    /// Beyond the limits, in no unit that fits them (`value`: the
    /// farthest excursion past a limit, rad or m).
    BeyondLimits,
    /// Inside the limits one turn lower or higher: angles kept in
    /// [0, 2 pi) (`value`: as for `BeyondLimits`).
    Turned,
    /// Inside the limits once read as degrees (`value`: the largest |q|).
    Degrees,
}

/// One joint beyond its limits.
#[derive(Debug, Clone)]
pub struct Excursion {
    /// 1-based.
    pub joint: usize,
    pub reading: Reading,
    pub value: f64,
    /// What was seen and what to check, as printed.
    pub message: String,
}

/// The model's moving joints with position limits (`None` for a joint
/// without), or nothing when the model has no description.
pub fn of(model: &dyn Dynamics) -> Vec<Option<Limit>> {
    let Ok(description) = crate::dynamics::parsed_description(model) else {
        return Vec::new();
    };
    description
        .chain()
        .free_bodies()
        .map(|b| {
            let (lower, upper) = b.limits.and_then(|l| l.position())?;
            Some(Limit {
                lower,
                upper,
                revolute: b.kind != codegen::JointKind::Prismatic,
            })
        })
        .collect()
}

/// Per column, the range of the positions over every matrix that has it
/// (`None` for a column without rows).
pub fn ranges(positions: &[&DMatrix<f64>]) -> Vec<Option<Range>> {
    let columns = positions.iter().map(|q| q.ncols()).max().unwrap_or(0);
    (0..columns)
        .map(|j| {
            let values = positions
                .iter()
                .filter(|q| j < q.ncols())
                .flat_map(|q| q.column(j).iter().copied().collect::<Vec<_>>());
            values.fold(None, |range, q| match range {
                None => Some((q, q)),
                Some((low, high)) => Some((low.min(q), high.max(q))),
            })
        })
        .collect()
}

/// The joints whose positions leave their limits by more than
/// [`LIMIT_MARGIN`]. `read_as`: the unit the positions were read in;
/// angles already converted from degrees are not read as degrees again.
pub fn excursions(
    model: &dyn Dynamics,
    ranges: &[Option<Range>],
    read_as: AngleUnit,
) -> Vec<Excursion> {
    let limits = of(model);
    let all_revolute = limits.iter().flatten().all(|l| l.revolute);
    let degrees_possible = read_as == AngleUnit::Radians;
    limits
        .iter()
        .zip(ranges)
        .enumerate()
        .filter_map(|(j, (limit, range))| {
            let fix = degrees_possible.then_some(degrees_fix(all_revolute));
            excursion(limit.as_ref()?, (*range)?, j, fix)
        })
        .collect()
}

/// A hint when positions in radians read as degrees as a whole though
/// no joint's `excursions` alone tells (a few degrees overshoot by less
/// than the joint's range): some joint leaves its limits in no unit and
/// turn that fits, and two or more revolute joints are past a turn, or
/// every joint with limits is inside them once read as degrees.
pub fn degrees_as_a_whole(
    model: &dyn Dynamics,
    ranges: &[Option<Range>],
    excursions: &[Excursion],
) -> Option<String> {
    let told = excursions.iter().any(|e| e.reading == Reading::Degrees);
    let unexplained = excursions
        .iter()
        .any(|e| e.reading == Reading::BeyondLimits);
    if told || !unexplained {
        return None;
    }
    let limits = of(model);
    let limited: Vec<(&Limit, Range)> = limits
        .iter()
        .zip(ranges)
        .filter_map(|(l, r)| Some((l.as_ref()?, (*r)?)))
        .collect();
    let levers = crate::dynamics::joint_levers(model);
    let past_a_turn = ranges
        .iter()
        .zip(&levers)
        .filter(|(r, lever)| **lever == 1.0 && r.is_some_and(|(l, h)| l.abs().max(h.abs()) > TAU))
        .count();
    let as_degrees = limited
        .iter()
        .all(|(l, (low, high))| l.holds(low.to_radians(), high.to_radians()));
    let why = if past_a_turn >= 2 {
        format!("{past_a_turn} joints are past a turn")
    } else if as_degrees {
        "every joint is inside its limits once they are read as degrees".to_string()
    } else {
        return None;
    };
    let all_revolute = levers.iter().all(|&l| l == 1.0);
    Some(format!(
        "the positions look like degrees ({why}): {}",
        degrees_fix(all_revolute)
    ))
}

/// What to do with angles in degrees: `--angles deg` converts every
/// joint, so a model with prismatic joints needs its columns converted.
fn degrees_fix(all_revolute: bool) -> &'static str {
    if all_revolute {
        "pass `--angles deg`"
    } else {
        "convert them to radians (`--angles deg` converts every joint, and this model has \
         prismatic ones)"
    }
}

/// Joint `j`'s excursion past `limit`, if any; `degrees_fix`: what to do
/// when the positions read as degrees (`None`: they cannot be degrees).
fn excursion(
    limit: &Limit,
    (low, high): Range,
    j: usize,
    degrees_fix: Option<&str>,
) -> Option<Excursion> {
    if limit.holds(low, high) {
        return None;
    }
    let beyond = (limit.lower - low).max(high - limit.upper);
    let unit = if limit.revolute { "rad" } else { "m" };
    let seen = format!(
        "joint {}: {} the description's limits [{}, {}] {unit}",
        j + 1,
        positions(low, high, unit),
        sig(limit.lower),
        sig(limit.upper)
    );
    let turns = (0.5 * (low + high) / TAU).round();
    let unwrapped = limit.revolute
        && turns != 0.0
        && low.abs().max(high.abs()) <= TAU
        && limit.holds(low - turns * TAU, high - turns * TAU);
    let (radians_low, radians_high) = (low.to_radians(), high.to_radians());
    // Within one turn, angles kept in [0, 2 pi) (a logger's convention)
    // explain an excursion as well as degrees of a small motion do; beyond a
    // turn only degrees (or a multi-turn zero) do. Degrees read as radians
    // overshoot by 57 times the motion: an overshoot within the joint's
    // range is a motion in radians (a poorly tracked one) or a wrong zero,
    // not a few degrees of motion.
    let far = beyond > limit.upper - limit.lower;
    if let Some(fix) = degrees_fix.filter(|_| limit.revolute && !unwrapped && far)
        && limit.holds(radians_low, radians_high)
    {
        return Some(Excursion {
            joint: j + 1,
            reading: Reading::Degrees,
            value: low.abs().max(high.abs()),
            message: format!(
                "{seen}; read as degrees they are {}, inside them: the angles look like \
                 degrees: {fix}",
                span(radians_low, radians_high, "rad")
            ),
        });
    }
    let hint = if unwrapped {
        format!(
            "they fit them {turns:.0} turn(s) lower: unwrap the angles to the description's zero"
        )
    } else {
        "check the joint order (the CSV's q columns, `--joints` for a bag), the joint's zero \
         and its units"
            .to_string()
    };
    Some(Excursion {
        joint: j + 1,
        reading: if unwrapped {
            Reading::Turned
        } else {
            Reading::BeyondLimits
        },
        value: beyond,
        message: format!(
            "{seen} by {} {unit} (more than a tenth of its range): {hint}",
            sig(beyond)
        ),
    })
}

/// "positions from a to b rad leave", or "position a rad leaves" for one
/// value (a single sample of `pose`).
fn positions(low: f64, high: f64, unit: &str) -> String {
    if low == high {
        format!("position {} leaves", span(low, high, unit))
    } else {
        format!("positions {} leave", span(low, high, unit))
    }
}

/// "from a to b rad", or "a rad" for one value.
fn span(low: f64, high: f64, unit: &str) -> String {
    if low == high {
        format!("{} {unit}", sig(low))
    } else {
        format!("from {} to {} {unit}", sig(low), sig(high))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const REVOLUTE: Limit = Limit {
        lower: -2.69,
        upper: 2.69,
        revolute: true,
    };
    const DEG: Option<&str> = Some("pass `--angles deg`");

    #[test]
    fn positions_within_the_limits_and_the_margin_pass() {
        assert!(excursion(&REVOLUTE, (-2.69, 2.69), 0, DEG).is_none());
        assert!(excursion(&REVOLUTE, (-3.2, 3.2), 0, DEG).is_none());
    }

    #[test]
    fn degrees_are_told_from_other_excursions() {
        let degrees = excursion(&REVOLUTE, (-150.0, 120.0), 1, DEG).unwrap();
        assert_eq!(degrees.reading, Reading::Degrees);
        assert_eq!(degrees.joint, 2);
        assert!(
            degrees.message.contains("--angles deg"),
            "{}",
            degrees.message
        );
        let wrapped = excursion(&REVOLUTE, (4.0, 6.0), 0, DEG).unwrap();
        assert_eq!(wrapped.reading, Reading::Turned);
        assert!(
            wrapped.message.contains("1 turn(s) lower"),
            "{}",
            wrapped.message
        );
        // 0.39 to 4.17 rad against [-0.0175, 3.75]: a motion in radians
        // that overshoots, not 3.8 degrees of motion.
        let panda6 = Limit {
            lower: -0.0175,
            upper: 3.75,
            revolute: true,
        };
        let overshoot = excursion(&panda6, (0.387, 4.17), 5, DEG).unwrap();
        assert_eq!(overshoot.reading, Reading::BeyondLimits);
        let prismatic = Limit {
            lower: 0.0,
            upper: 0.5,
            revolute: false,
        };
        let far = excursion(&prismatic, (0.0, 20.0), 0, DEG).unwrap();
        assert_eq!(far.reading, Reading::BeyondLimits);
        assert!(far.message.contains("joint order"), "{}", far.message);
    }

    #[test]
    fn angles_read_in_degrees_are_not_read_as_degrees_again() {
        let twice = excursion(&REVOLUTE, (100.0, 100.0), 0, None).unwrap();
        assert_eq!(twice.reading, Reading::BeyondLimits);
        assert!(
            twice
                .message
                .starts_with("joint 1: position 100 rad leaves"),
            "{}",
            twice.message
        );
    }

    /// A few degrees on each joint: joint 3's 7 "rad" overshoots by less
    /// than its range and no turn fits it, but every joint fits its limits
    /// read as degrees; a wrapped angle or a motion in radians gets no hint.
    #[test]
    fn degrees_are_told_from_the_whole_input() {
        let model = crate::dynamics::model("kinova_gen3_lite_3dof").unwrap();
        let hint = |row: [f64; 3]| {
            let q = DMatrix::from_row_slice(1, 3, &row);
            let ranges = ranges(&[&q]);
            let found = excursions(model, &ranges, AngleUnit::Radians);
            degrees_as_a_whole(model, &ranges, &found)
        };
        let few = hint([0.0, 2.0, 7.0]).expect("a hint");
        assert!(few.contains("--angles deg"), "{few}");
        assert!(hint([0.0, 0.1, 4.5]).is_none(), "a turn off");
        assert!(hint([0.0, 0.1, 0.2]).is_none(), "inside");
        let turns = hint([7.0, -7.0, 0.0]).expect("a hint");
        assert!(turns.contains("2 joints are past a turn"), "{turns}");
    }

    #[test]
    fn ranges_span_every_matrix() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, -1.0, 3.0, 0.5]);
        let b = DMatrix::from_row_slice(1, 1, &[-2.0]);
        assert_eq!(ranges(&[&a, &b]), [Some((-2.0, 3.0)), Some((-1.0, 0.5))]);
    }
}
