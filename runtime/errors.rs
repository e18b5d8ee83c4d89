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
