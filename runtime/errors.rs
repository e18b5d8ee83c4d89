//! How errors read on the command line.

/// The error and its causes, each cause once: a cause whose text the
/// message already carries (a file error that prints its OS error) is not
/// repeated.
pub fn message(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if !text.contains(&part) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&part);
        }
    }
    text
}

/// Exit code of a failed command: bad input or arguments.
pub const BAD_INPUT: u8 = 2;

/// Exit code of `sdnn diagnose` and `sdnn evaluate` when the recordings
/// fail the sanity gate: nothing is named or evaluated, and the data (a
/// torque's sign, the angles' unit, the joint order), not the command
/// line, need checking.
pub const FAILED_SANITY_GATE: u8 = 3;

/// The exit code of `error`.
pub fn exit_code(error: &anyhow::Error) -> u8 {
    if error
        .chain()
        .any(|e| e.downcast_ref::<crate::diagnose::Refusal>().is_some())
    {
        FAILED_SANITY_GATE
    } else {
        BAD_INPUT
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn a_cause_already_in_the_message_is_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let error = Err::<(), _>(io)
            .context("a.csv: no such file")
            .context("reading inputs")
            .unwrap_err();
        assert_eq!(message(&error), "reading inputs: a.csv: no such file");
    }
}
