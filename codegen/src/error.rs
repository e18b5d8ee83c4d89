//! Errors of the description and the generator, with file, line and key.

use std::fmt;
use std::path::PathBuf;

/// An error in a robot description file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DescriptionError {
    #[error("{path}: cannot read: {message}")]
    Io { path: PathBuf, message: String },
    /// TOML syntax, a missing or unknown key, or a value of the wrong type.
    #[error("{path}:{line}:{column}: {message}")]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// A value or the topology is invalid; `key` is the dotted path.
    #[error("{path}:{line}:{column}: `{key}`: {message}")]
    Invalid {
        path: PathBuf,
        line: usize,
        column: usize,
        key: String,
        message: String,
    },
}

/// A path of keys and array indices into the TOML document.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KeyPath(Vec<Segment>);

#[derive(Debug, Clone, PartialEq)]
enum Segment {
    Key(String),
    Index(usize),
}

impl KeyPath {
    pub fn root() -> KeyPath {
        KeyPath::default()
    }

    pub fn key(&self, key: &str) -> KeyPath {
        let mut path = self.clone();
        path.0.push(Segment::Key(key.to_string()));
        path
    }

    pub fn index(&self, index: usize) -> KeyPath {
        let mut path = self.clone();
        path.0.push(Segment::Index(index));
        path
    }

    /// Byte span of the deepest part of this path that exists in `source`.
    fn span_in(&self, source: &str) -> Option<std::ops::Range<usize>> {
        let document = toml_edit::Document::parse(source).ok()?;
        let mut item: &toml_edit::Item = document.as_item();
        let mut span = None;
        for segment in &self.0 {
            let next = match segment {
                Segment::Key(k) => item.get(k.as_str()),
                Segment::Index(i) => item.get(*i),
            };
            match next {
                Some(next) => {
                    item = next;
                    span = item_span(item).or(span);
                }
                None => break,
            }
        }
        span
    }
}

fn item_span(item: &toml_edit::Item) -> Option<std::ops::Range<usize>> {
    match item {
        toml_edit::Item::Value(v) => v.span(),
        toml_edit::Item::Table(t) => t.span(),
        toml_edit::Item::ArrayOfTables(a) => a.span(),
        toml_edit::Item::None => None,
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, segment) in self.0.iter().enumerate() {
            match segment {
                Segment::Key(k) if n == 0 => write!(f, "{k}")?,
                Segment::Key(k) => write!(f, ".{k}")?,
                Segment::Index(i) => write!(f, "[{i}]")?,
            }
        }
        Ok(())
    }
}

/// A validation error before it is tied to a file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Located {
    pub key: KeyPath,
    pub message: String,
}

impl Located {
    pub fn new(key: KeyPath, message: impl Into<String>) -> Located {
        Located {
            key,
            message: message.into(),
        }
    }

    /// Resolves the key path to a line and column of the source file.
    pub fn locate(self, source: &str, path: PathBuf) -> DescriptionError {
        let (line, column) = self
            .key
            .span_in(source)
            .map(|s| line_column(source, s.start))
            .unwrap_or((1, 1));
        DescriptionError::Invalid {
            path,
            line,
            column,
            key: self.key.to_string(),
            message: self.message,
        }
    }
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_column(source: &str, offset: usize) -> (usize, usize) {
    let before = &source[..offset.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
