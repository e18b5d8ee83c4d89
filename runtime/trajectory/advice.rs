//! What to do with a header cell outside the trajectory contract: the
//! advice of the "unexpected column" error.

/// The advice for `cell`: a cell holding semicolons or tabs is a whole
/// header the comma reader did not split; any other cell is mapped to the
/// contract column it most likely means, or skipped.
pub(super) fn unexpected(cell: &str) -> String {
    match [';', '\t'].into_iter().find(|d| cell.contains(*d)) {
        Some(d) => format!(
            "the header is separated by {}: write the file with commas (for example \
             `tr '{}' ','`, if no value holds a decimal comma)",
            if d == ';' { "semicolons" } else { "tabs" },
            if d == ';' { ";" } else { "\\t" },
        ),
        None => format!(
            "map it to a contract column with `--column {}={}`, or skip it with \
             `--ignore-column {}`",
            crate::shell::shell_word(cell),
            contract_guess(cell).unwrap_or_else(|| "NAME".to_string()),
            crate::shell::shell_word(cell)
        ),
    }
}

/// The contract column a header cell names in words (`torque2`,
/// `joint_effort_2` -> `tau2`, `time_s` -> `t`, `Q1` -> `q1`): every word of
/// the cell known, one quantity among them, and a 1-based joint number
/// ending it (a time without one). A cell with any other word (a TCP pose,
/// a temperature, a motor current in amperes) or joint 0 (a 0-based log:
/// which joint is meant is not for a guess) gets none.
fn contract_guess(cell: &str) -> Option<String> {
    let lower = cell.to_lowercase();
    let named = lower.trim_end_matches(|c: char| c.is_ascii_digit());
    let number = &lower[named.len()..];
    let words = named
        .split(|c: char| !c.is_ascii_alphabetic())
        .filter(|w| !w.is_empty());
    let mut quantity = None;
    for word in words {
        let this = match word {
            "q" | "pos" | "position" | "angle" => "q",
            "qd" | "vel" | "velocity" | "speed" => "qd",
            "qdd" | "acc" | "accel" | "acceleration" => "qdd",
            "tau" | "torque" | "effort" => "tau",
            "t" | "time" | "timestamp" | "stamp" | "s" | "sec" | "secs" => "t",
            "joint" | "j" | "actual" | "measured" | "meas" => continue,
            _ => return None,
        };
        if quantity.is_some_and(|q| q != this) {
            return None;
        }
        quantity = Some(this);
    }
    match (quantity?, number.parse::<usize>().ok()) {
        ("t", None) => Some("t".to_string()),
        ("t", Some(_)) | (_, None) | (_, Some(0)) => None,
        (q, Some(joint)) => Some(format!("{q}{joint}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_is_guessed_only_from_known_words() {
        let guess = |cell: &str| contract_guess(cell);
        let some = |s: &str| Some(s.to_string());
        assert_eq!(guess("torque2"), some("tau2"));
        assert_eq!(guess("joint_effort_3"), some("tau3"));
        assert_eq!(guess("position_1"), some("q1"));
        assert_eq!(guess("Q1"), some("q1"));
        assert_eq!(guess("QD12"), some("qd12"));
        assert_eq!(guess("actual_velocity_4"), some("qd4"));
        assert_eq!(guess("time_s"), some("t"));
        assert_eq!(guess("timestamp"), some("t"));
        // Unknown words, joint 0, a time with a number, two quantities.
        for cell in [
            "temp",
            "joint_temperatures_1",
            "actual_TCP_pose_1",
            "actual_current_2",
            "tau_ext_hat_filtered_1",
            "cycle_time",
            "panda_joint1_effort",
            "position_0",
            "time2",
            "position_velocity_1",
        ] {
            assert_eq!(guess(cell), None, "{cell}");
        }
    }
}
