//! "Did you mean": the known names closest to a mistyped one.

/// The names of `known` nearest to `typed` in edit distance (case
/// ignored), when they are near enough to be a typo of it: at most one
/// edit in four characters (at least one, at most three). Several when
/// they tie; none when nothing is that near.
pub fn closest<'a>(typed: &str, known: &[&'a str]) -> Vec<&'a str> {
    let typed = typed.to_lowercase();
    let allowed = (typed.chars().count() / 4).clamp(1, 3);
    let distances: Vec<(usize, &str)> = known
        .iter()
        .map(|&k| (strsim::damerau_levenshtein(&typed, &k.to_lowercase()), k))
        .collect();
    let best = distances.iter().map(|&(d, _)| d).min().unwrap_or(0);
    if best > allowed {
        return Vec::new();
    }
    distances
        .into_iter()
        .filter(|&(d, _)| d == best)
        .map(|(_, k)| k)
        .collect()
}

/// `did you mean `a`?` (or `a` or `b`), none without a near name.
pub fn did_you_mean(typed: &str, known: &[&str]) -> Option<String> {
    let near = closest(typed, known);
    let quoted: Vec<String> = near.iter().map(|n| format!("`{n}`")).collect();
    (!near.is_empty()).then(|| format!("did you mean {}?", quoted.join(" or ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODELS: [&str; 4] = [
        "kinova_gen3_lite",
        "kinova_gen3_lite_3dof",
        "panda",
        "planar_2link",
    ];

    #[test]
    fn names_a_typo_and_only_a_typo() {
        assert_eq!(closest("pand", &MODELS), ["panda"]);
        assert_eq!(closest("Panda", &MODELS), ["panda"]);
        assert_eq!(closest("pnada", &MODELS), ["panda"]);
        assert_eq!(
            closest("kinova_gen3_lite_3do", &MODELS),
            ["kinova_gen3_lite_3dof"]
        );
        assert_eq!(
            closest("kinova_gen3_lite3dof", &MODELS),
            ["kinova_gen3_lite_3dof"]
        );
        assert!(closest("ur10e", &MODELS).is_empty());
        assert!(closest("kinova", &MODELS).is_empty());
        assert!(closest("", &MODELS).is_empty());
    }

    #[test]
    fn says_nothing_without_a_near_name() {
        let said = |typed| did_you_mean(typed, &MODELS);
        assert_eq!(said("pand").as_deref(), Some("did you mean `panda`?"));
        assert_eq!(said("xyz"), None);
        let tie = did_you_mean("ab", &["aa", "bb"]);
        assert_eq!(tie.as_deref(), Some("did you mean `aa` or `bb`?"));
    }
}
