//! "Did you mean": the known names closest to a mistyped one, and the
//! files beside a mistyped path.

use std::fs::File;
use std::io;
use std::path::Path;

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

/// Opens an input file; when that fails, the error says what the path is
/// instead: a folder (pass its files), a pattern the shell left unexpanded
/// (no file matched it), or a near name of a file beside it.
pub fn open_input(path: &Path) -> io::Result<File> {
    if path.is_dir() {
        let pattern = path.join("*.csv");
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "a folder, not a file: pass its files (for example {})",
                pattern.display()
            ),
        ));
    }
    File::open(path).map_err(|e| match e.kind() {
        io::ErrorKind::NotFound => io::Error::new(e.kind(), not_found(path)),
        _ => e,
    })
}

/// Why `path`, which does not exist, was not found.
fn not_found(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_default();
    if name.contains(['*', '?', '[']) {
        return "no such file: a pattern that matched no file (the shell passes it as \
                written)"
            .to_owned();
    }
    let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
    let folder = folder.unwrap_or(Path::new("."));
    let Ok(entries) = std::fs::read_dir(folder) else {
        return format!("no such file (nor the folder {})", folder.display());
    };
    let beside: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .collect();
    let beside: Vec<&str> = beside.iter().map(String::as_str).collect();
    match did_you_mean(&name, &beside) {
        Some(hint) => format!("no such file; {hint}"),
        None => "no such file".to_owned(),
    }
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

    #[test]
    fn a_path_that_opens_no_file_says_what_it_is() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("trajectory_01.csv"), "t\n").unwrap();
        let said = |name: &str| open_input(&dir.path().join(name)).unwrap_err().to_string();
        assert!(open_input(&dir.path().join("trajectory_01.csv")).is_ok());
        assert!(said("trajectory_1.csv").ends_with("did you mean `trajectory_01.csv`?"));
        assert!(said("*.cvs").contains("a pattern that matched no file"));
        assert_eq!(said("elsewhere.txt"), "no such file");
        assert!(said("gone/a.csv").contains("nor the folder"));
        let folder = open_input(dir.path()).unwrap_err().to_string();
        assert!(folder.starts_with("a folder, not a file") && folder.ends_with("*.csv)"));
    }
}
