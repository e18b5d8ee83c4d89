//! Line endings of text tables written on any system, read as `\n`.
//!
//! The `csv` crate ends a CRLF (Windows) record at its `\r` and counts the
//! line only when it meets the `\n`, at the start of the next record: every
//! record after the header was placed on the line before its own, so an
//! error named "line 4" for a bad value on line 5 (rust-csv issue 395). A
//! lone `\r` (classic Mac, Excel's "CSV (Macintosh)") is a record end it
//! never counts. Rewriting `\r\n` and `\r` to `\n` before the parser, and
//! ending the last line, gives every record a `\n` at its end: the reader
//! takes a record's line from where it ends (where it starts, csv counts
//! the blank lines it skipped before it), the editor's line for all three
//! conventions. A number never holds a carriage return: no value changes.

use std::io::{self, Read};

/// A reader that turns `\r\n` and a lone `\r` into `\n` and ends a last
/// line left open with one.
pub struct UnixLineEnds<R> {
    inner: R,
    /// The last byte read was a `\r` (already given out as `\n`): a `\n`
    /// first in the next read belongs to it and is dropped.
    after_cr: bool,
    /// The last byte given out was a `\n` (or none was given out yet).
    line_ended: bool,
}

impl<R: Read> UnixLineEnds<R> {
    pub fn new(inner: R) -> Self {
        UnixLineEnds {
            inner,
            after_cr: false,
            line_ended: true,
        }
    }
}

impl<R: Read> Read for UnixLineEnds<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            let n = self.inner.read(buf)?;
            if n == 0 {
                return Ok(self.end_last_line(buf));
            }
            // Files written on Unix pass through untouched.
            let kept = if !self.after_cr && !buf[..n].contains(&b'\r') {
                n
            } else {
                self.rewrite(&mut buf[..n])
            };
            // A read that held only the `\n` of a split `\r\n` is not the
            // end of the file: read on.
            if kept > 0 {
                self.line_ended = buf[kept - 1] == b'\n';
                return Ok(kept);
            }
        }
    }
}

impl<R> UnixLineEnds<R> {
    /// At the end of the input: a `\n` if the last line had none.
    fn end_last_line(&mut self, buf: &mut [u8]) -> usize {
        if self.line_ended || buf.is_empty() {
            return 0;
        }
        buf[0] = b'\n';
        self.line_ended = true;
        1
    }

    /// Rewrites `bytes` in place (never longer), returning the bytes kept.
    fn rewrite(&mut self, bytes: &mut [u8]) -> usize {
        let mut kept = 0;
        for i in 0..bytes.len() {
            let b = bytes[i];
            let after_cr = std::mem::replace(&mut self.after_cr, b == b'\r');
            if b == b'\n' && after_cr {
                continue;
            }
            bytes[kept] = if b == b'\r' { b'\n' } else { b };
            kept += 1;
        }
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A reader handing out `chunk` bytes at a time, to split `\r\n`.
    struct Chunked<'a>(&'a [u8], usize);

    impl Read for Chunked<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = self.0.len().min(self.1).min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    fn unix(text: &[u8], chunk: usize) -> Vec<u8> {
        let mut out = Vec::new();
        UnixLineEnds::new(Chunked(text, chunk))
            .read_to_end(&mut out)
            .unwrap();
        out
    }

    #[test]
    fn rewrites_each_convention() {
        assert_eq!(unix(b"a,b\r\n1,2\r\n", 64), b"a,b\n1,2\n");
        assert_eq!(unix(b"a,b\r1,2\r", 64), b"a,b\n1,2\n");
        assert_eq!(unix(b"a,b\n1,2\n", 64), b"a,b\n1,2\n");
        // A blank CRLF line stays a blank line; `\n\r` is two line ends.
        assert_eq!(unix(b"a\r\n\r\nb", 64), b"a\n\nb\n");
        assert_eq!(unix(b"a\n\rb", 64), b"a\n\nb\n");
    }

    #[test]
    fn ends_the_last_line_once() {
        assert_eq!(unix(b"a,b\r\n1,2", 64), b"a,b\n1,2\n");
        assert_eq!(unix(b"1,2\r", 1), b"1,2\n");
        assert_eq!(unix(b"", 64), b"");
    }

    proptest! {
        /// Any text, any line ending, any read size: the same lines, the
        /// last one ended.
        #[test]
        fn same_lines_whatever_the_ending_or_read_size(
            lines in proptest::collection::vec("[0-9a-z,. ]{0,12}", 0..20),
            ending in prop::sample::select(vec!["\n", "\r\n", "\r"]),
            chunk in 1usize..9,
            open_end: bool,
        ) {
            let mut text: String = lines.iter().map(|l| format!("{l}{ending}")).collect();
            // An open last line (no ending after it) needs text to exist.
            if open_end && lines.last().is_some_and(|l| !l.is_empty()) {
                text.truncate(text.len() - ending.len());
            }
            let expected: String = lines.iter().map(|l| format!("{l}\n")).collect();
            prop_assert_eq!(unix(text.as_bytes(), chunk), expected.into_bytes());
        }
    }
}
