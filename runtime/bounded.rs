//! Reading that cannot be made to hold unbounded data: a text line longer
//! than any recording's or a file larger than any description's (a binary
//! file, `/dev/zero`) is an error, not an allocation that grows until the
//! machine runs out of memory.

use std::io::{self, Read};
use std::path::Path;

/// Longest line of a recording, a state file or a per-channel log.
pub const MAX_LINE_BYTES: usize = 1 << 20;
/// Largest file read whole (a URDF, a per-channel log).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// A reader that fails once a line exceeds [`MAX_LINE_BYTES`].
pub struct LineLimited<R> {
    inner: R,
    since_newline: usize,
}

impl<R: Read> LineLimited<R> {
    pub fn new(inner: R) -> Self {
        LineLimited {
            inner,
            since_newline: 0,
        }
    }
}

impl<R: Read> Read for LineLimited<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        let read = &buf[..n];
        self.since_newline = match read.iter().rposition(|&b| b == b'\n') {
            Some(at) => n - at - 1,
            None => self.since_newline + n,
        };
        if self.since_newline > MAX_LINE_BYTES {
            return Err(too_long());
        }
        Ok(n)
    }
}

fn too_long() -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "a line longer than {} MiB: not a text table (a binary file or a device?)",
            MAX_LINE_BYTES >> 20
        ),
    )
}

/// The bytes of `path`, refused beyond [`MAX_FILE_BYTES`].
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    read_at_most(path, MAX_FILE_BYTES)
}

/// The bytes of `path`, refused beyond `limit` bytes (read no further).
pub fn read_at_most(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "larger than {}: not a file this command reads (a device?)",
                size(limit)
            ),
        ));
    }
    Ok(bytes)
}

/// `bytes` in MiB or GiB.
fn size(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{} GiB", bytes >> 30)
    } else {
        format!("{} MiB", bytes >> 20)
    }
}

/// The text of `path` (UTF-8), refused beyond [`MAX_FILE_BYTES`].
pub fn read_to_string(path: &Path) -> io::Result<String> {
    read_to_string_at_most(path, MAX_FILE_BYTES)
}

/// The text of `path` (UTF-8), refused beyond `limit` bytes.
pub fn read_to_string_at_most(path: &Path, limit: u64) -> io::Result<String> {
    String::from_utf8(read_at_most(path, limit)?)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("not UTF-8 text: {e}")))
}

/// The text of a robot description, refused beyond
/// [`codegen::description::MAX_DESCRIPTION_BYTES`].
pub fn read_description(path: &Path) -> io::Result<String> {
    read_to_string_at_most(path, codegen::description::MAX_DESCRIPTION_BYTES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_its_limit_is_refused_before_it_is_read_whole() {
        let e = read_at_most(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert!(e.to_string().contains("larger than 1 MiB"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.toml");
        std::fs::write(&path, "x = 1\n").unwrap();
        assert_eq!(read_description(&path).unwrap(), "x = 1\n");
    }

    #[test]
    fn an_endless_line_is_refused_and_ordinary_lines_pass() {
        let endless = io::repeat(b'0').take(4 * MAX_LINE_BYTES as u64);
        let mut sink = Vec::new();
        let e = LineLimited::new(endless)
            .read_to_end(&mut sink)
            .unwrap_err();
        assert!(e.to_string().contains("longer than 1 MiB"), "{e}");
        let lines = "1.0,2.0\n".repeat(400_000);
        let mut out = String::new();
        LineLimited::new(lines.as_bytes())
            .read_to_string(&mut out)
            .unwrap();
        assert_eq!(out.len(), lines.len());
    }
}
