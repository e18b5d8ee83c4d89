//! Ranges of the command-line numbers, checked while parsing: each bound
//! keeps the work finite (memory, time, files) and the message says how to
//! go past it. The bounds are listed in docs/cli.md.

/// Parses an integer in `min..=max`; `beyond` says what to do past `max`.
pub fn integer(
    min: u64,
    max: u64,
    beyond: &'static str,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let value: u64 = text
            .trim()
            .parse()
            .map_err(|_| format!("expected a whole number from {min} to {max}, got `{text}`"))?;
        if value < min {
            return Err(format!("must be at least {min}, got {value}"));
        }
        if value > max {
            return Err(format!("at most {max} is accepted, got {value}; {beyond}"));
        }
        usize::try_from(value).map_err(|_| format!("{value} does not fit this machine"))
    }
}

/// Parses a finite number in `(min, max]` (`min` excluded when
/// `exclusive`, for quantities that must be positive).
pub fn real(
    min: f64,
    max: f64,
    exclusive: bool,
    beyond: &'static str,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let value: f64 = text
            .trim()
            .parse()
            .map_err(|_| format!("expected a number, got `{text}`"))?;
        let low = if exclusive { value <= min } else { value < min };
        if !value.is_finite() || low {
            let bound = if exclusive { "above" } else { "at least" };
            return Err(format!("must be a finite number {bound} {min}, got {text}"));
        }
        if value > max {
            return Err(format!("at most {max} is accepted, got {value}; {beyond}"));
        }
        Ok(value)
    }
}

/// Seeds: any 64-bit number.
pub fn seed(text: &str) -> Result<u64, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("expected a seed from 0 to {}, got `{text}`", u64::MAX))
}

/// Hidden layer widths of an MLP: 1 to 8 layers of 1 to 4096 neurons.
pub fn width(text: &str) -> Result<usize, String> {
    integer(
        1,
        MAX_WIDTH as u64,
        "wider layers do not fit the trainer's memory bound",
    )(text)
}

/// Widest hidden layer accepted.
pub const MAX_WIDTH: usize = 4096;
/// Most hidden layers accepted.
pub const MAX_LAYERS: usize = 8;

/// Most weights between hidden layers (160 MB of f64 per copy; the trainer
/// keeps four copies: weights, gradient, two Adam moments).
pub const MAX_WEIGHTS: usize = 20_000_000;

/// Checks a list of hidden widths as a whole.
pub fn check_layers(hidden: &[usize]) -> Result<(), String> {
    if hidden.is_empty() || hidden.len() > MAX_LAYERS {
        return Err(format!(
            "--hidden takes 1 to {MAX_LAYERS} comma-separated widths, got {}",
            hidden.len()
        ));
    }
    let weights: usize = hidden.windows(2).map(|w| w[0] * w[1]).sum();
    if weights > MAX_WEIGHTS {
        return Err(format!(
            "--hidden {hidden:?} has {weights} weights between hidden layers; at most \
             {MAX_WEIGHTS} fit the trainer's memory bound (use narrower layers)"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_outside_the_range_say_the_bound() {
        let count = integer(1, 1000, "run several times");
        assert_eq!(count("14"), Ok(14));
        assert!(count("0").unwrap_err().contains("at least 1"));
        let huge = count("18446744073709551615").unwrap_err();
        assert!(
            huge.contains("at most 1000") && huge.contains("several"),
            "{huge}"
        );
        assert!(count("-3").unwrap_err().contains("whole number"));
        assert!(count("1e3").is_err());
    }

    #[test]
    fn reals_must_be_finite_and_inside() {
        let duration = real(0.0, 3600.0, true, "split the run");
        assert_eq!(duration("20"), Ok(20.0));
        for bad in ["0", "-1", "nan", "inf", "1e200", "x"] {
            assert!(duration(bad).is_err(), "{bad}");
        }
        let from = real(0.0, 1e9, false, "");
        assert_eq!(from("0"), Ok(0.0));
    }

    #[test]
    fn seeds_take_every_u64_and_widths_are_bounded() {
        assert_eq!(seed("18446744073709551615"), Ok(u64::MAX));
        assert!(seed("-1").is_err());
        assert!(width("100000000").is_err());
        assert!(check_layers(&[64; 9]).is_err());
        assert!(check_layers(&[64, 64]).is_ok());
        assert!(check_layers(&[4096, 4096, 4096]).is_err());
    }
}
