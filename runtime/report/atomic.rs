//! Report files through the one writer (`crate::output`), with the
//! report's error type.

use std::path::Path;

use crate::report::error::ReportError;

/// Writes `bytes` to `path` atomically (see `crate::output`).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    crate::output::write(path, bytes).map_err(|source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    })
}
