//! Names from a description are data: the rules they follow, so they can
//! never become code in a generated file (see docs/generated-code.md).

use std::path::Path;

/// Rust keywords (strict and reserved, all editions): a model is a module
/// named by its file stem, so these cannot be model names.
const KEYWORDS: [&str; 52] = [
    "abstract", "as", "async", "await", "become", "box", "break", "const", "continue", "crate",
    "do", "dyn", "else", "enum", "extern", "false", "final", "fn", "for", "gen", "if", "impl",
    "in", "let", "loop", "macro", "match", "mod", "move", "mut", "override", "priv", "pub", "ref",
    "return", "self", "static", "struct", "super", "trait", "true", "try", "type", "typeof",
    "union", "unsafe", "unsized", "use", "virtual", "where", "while", "yield",
];

/// A model is a module named by its description's file stem: a snake_case
/// Rust identifier that is not a keyword.
pub fn check_model_name(name: &str, toml: &Path) -> Result<(), String> {
    if KEYWORDS.contains(&name) || name == "_" {
        return Err(format!(
            "{}: the model is named by its file stem, which becomes a Rust module name;              `{name}` is a Rust keyword, rename the file (for example `{name}_arm.toml`)",
            toml.display()
        ));
    }
    let mut chars = name.chars();
    let valid = chars
        .next()
        .is_some_and(|c| c.is_ascii_lowercase() || c == '_')
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if valid {
        Ok(())
    } else {
        Err(format!(
            "{}: the model is named by its file stem, which must be a snake_case Rust identifier \
             (lowercase letters, digits, `_`); found `{name}`",
            toml.display()
        ))
    }
}

/// Longest robot, link or joint name accepted, in characters.
pub const MAX_NAME_CHARS: usize = 200;

/// Names are data shown in generated comments, reports and files: one line
/// of printable text. Control characters (a newline could end a comment in
/// generated code) are refused, not escaped, so every output shows the name
/// as written.
pub fn check_name(name: &str) -> Result<(), String> {
    if let Some(c) = name.chars().find(|c| c.is_control()) {
        return Err(format!(
            "name {name:?} contains the control character U+{:04X}; names must be one line of printable text",
            u32::from(c)
        ));
    }
    if name.chars().count() > MAX_NAME_CHARS {
        return Err(format!(
            "name is {} characters long; at most {MAX_NAME_CHARS} are accepted",
            name.chars().count()
        ));
    }
    Ok(())
}
