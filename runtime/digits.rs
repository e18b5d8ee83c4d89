//! Numbers as the report prints them.

/// Three significant digits, without exponent for everyday magnitudes.
pub fn sig(x: f64) -> String {
    significant(x, 3)
}

/// `digits` significant digits, without exponent for everyday magnitudes.
pub fn significant(x: f64, digits: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        let decimals = (digits - 1) as usize;
        return format!("{x:.decimals$e}");
    }
    let decimals = (digits - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The significant digits, three or as many more (up to six) as it takes
/// to print `a` and `b` as different numbers: an interval narrower than
/// the third digit does not read as a point.
pub fn needed(a: f64, b: f64) -> i32 {
    let differ = |d: i32| {
        let read = |x: f64| significant(x, d).parse::<f64>().ok();
        read(a) != read(b)
    };
    (3..=6).find(|&d| a == b || differ(d)).unwrap_or(6)
}

/// Two numbers (an interval's ends, a before and an after) with the
/// digits [`needed`] to print them apart.
pub fn apart(a: f64, b: f64) -> (String, String) {
    let d = needed(a, b);
    (significant(a, d), significant(b, d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_significant_digits() {
        assert_eq!(sig(0.302_449), "0.302");
        assert_eq!(sig(12.345), "12.3");
        assert_eq!(sig(1234.5), "1234");
        assert_eq!(sig(-0.000_123_4), "-0.000123");
        assert_eq!(sig(2.5e-9), "2.50e-9");
    }

    #[test]
    fn two_numbers_are_printed_apart() {
        let own = |a: &str, b: &str| (a.to_string(), b.to_string());
        assert_eq!(apart(0.398, 0.437), own("0.398", "0.437"));
        assert_eq!(apart(0.14987, 0.14994), own("0.14987", "0.14994"));
        assert_eq!(apart(0.15, 0.15), own("0.150", "0.150"));
        assert_eq!(apart(-2.5e-9, 2.5e-9), own("-2.50e-9", "2.50e-9"));
        assert_eq!(apart(1.0, 1.0 + 1e-12), own("1.00000", "1.00000"));
        // Apart as numbers, not only as strings ("10.00" and "10.0").
        assert_eq!(apart(9.996, 10.004), own("9.996", "10.00"));
        assert_eq!(apart(-0.5, -0.5004), own("-0.5000", "-0.5004"));
    }
}
