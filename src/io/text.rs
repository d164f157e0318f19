//! Line reader and token parsing shared by the text formats.

use std::io::{BufRead, ErrorKind, Read};
use std::path::Path;
use std::str::FromStr;

use crate::error::{Error, Result};

/// Longest text line accepted (bytes): far above any mesh, point or matrix row.
pub(crate) const MAX_LINE: usize = 16 << 20;

/// Reads a text input line by line, strips `#` comments and surrounding whitespace, skips blank
/// lines, and keeps the 1-based number of the last line read for error messages.
pub(crate) struct LineReader<'p, R> {
    r: R,
    path: &'p Path,
    text: String,
    /// Number of lines read so far (= the 1-based number of the last line returned).
    pub line: usize,
}

impl<'p, R: BufRead> LineReader<'p, R> {
    /// Starts reading `r`; `first_line - 1` lines are taken as already read (for bodies that
    /// follow a header parsed elsewhere).
    pub fn new(r: R, path: &'p Path, first_line: usize) -> Self {
        LineReader { r, path, text: String::new(), line: first_line.saturating_sub(1) }
    }

    /// The next line with content, as `(line number, trimmed text without comment)`, or
    /// `None` at the end of the input. Invalid UTF-8 is a parse error.
    pub fn next_content(&mut self) -> Result<Option<(usize, &str)>> {
        let range = loop {
            self.text.clear();
            // At most MAX_LINE + 1 bytes per line: a file without newlines (or /dev/zero) is an
            // error after MAX_LINE bytes, not an allocation as large as the input.
            let n = match (&mut self.r).take(MAX_LINE as u64 + 1).read_line(&mut self.text) {
                Ok(n) if n > MAX_LINE => {
                    let msg = format!("expected lines of at most {} MiB, found a longer one", MAX_LINE >> 20);
                    return Err(Error::parse(self.path, Some(self.line + 1), msg));
                }
                Ok(n) => n,
                Err(e) if e.kind() == ErrorKind::InvalidData => {
                    let msg = "expected UTF-8 text, found invalid bytes (binary data?)";
                    return Err(Error::parse(self.path, Some(self.line + 1), msg));
                }
                Err(e) => return Err(Error::io(self.path, e)),
            };
            if n == 0 {
                return Ok(None);
            }
            self.line += 1;
            // A UTF-8 byte-order mark (as some Windows editors write) is not content.
            let bom = if self.line == 1 && self.text.starts_with('\u{feff}') { '\u{feff}'.len_utf8() } else { 0 };
            let body = &self.text[bom..self.text.find('#').unwrap_or(self.text.len())];
            let start = bom + body.len() - body.trim_start().len();
            let end = bom + body.trim_end().len();
            if start < end {
                break start..end;
            }
        };
        Ok(Some((self.line, &self.text[range])))
    }

    /// The unread rest of the input.
    pub fn inner(&self) -> &R {
        &self.r
    }

    /// Like [`Self::next_content`], but the end of the input is a "truncated" error saying
    /// what was `expected`.
    pub fn expect_content(&mut self, expected: &str) -> Result<(usize, &str)> {
        let (path, line) = (self.path, self.line);
        match self.next_content()? {
            Some(x) => Ok(x),
            None => Err(Error::parse(
                path,
                Some(line + 1),
                format!("truncated file: expected {expected}, found end of file"),
            )),
        }
    }
}

/// A token shortened for error messages.
pub(crate) fn clip(tok: &str) -> String {
    match tok.char_indices().nth(40) {
        Some((i, _)) => format!("{}…", &tok[..i]),
        None => tok.to_string(),
    }
}

/// Parses `tok` as a `T`; on failure the message says `expected {what}, found '{tok}'`.
pub(crate) fn parse_tok<T: FromStr>(tok: &str, what: &str, path: &Path, line: usize) -> Result<T> {
    tok.parse().map_err(|_| Error::parse(path, Some(line), format!("expected {what}, found '{}'", clip(tok))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_line_is_an_error_not_an_allocation() {
        let path = Path::new("zeros.off");
        // MAX_LINE + 2 zero bytes and no newline: what `ln -s /dev/zero z.off` reads.
        let endless = std::io::BufReader::new(std::io::repeat(0).take(MAX_LINE as u64 + 2));
        let err = LineReader::new(endless, path, 1).next_content().unwrap_err().to_string();
        assert!(err.contains("zeros.off") && err.contains("at most 16 MiB"), "{err}");
        // Lines below the cap read as before.
        let text = b"OFF\n 3 1 0 # comment\n\n1 2 3\n";
        let mut r = LineReader::new(&text[..], path, 1);
        assert_eq!(r.next_content().unwrap(), Some((1, "OFF")));
        assert_eq!(r.next_content().unwrap(), Some((2, "3 1 0")));
        assert_eq!(r.next_content().unwrap(), Some((4, "1 2 3")));
        assert_eq!(r.next_content().unwrap(), None);
        // A byte-order mark before the first line is skipped.
        let text = "\u{feff}OFF\n1 2 3\n".as_bytes();
        let mut r = LineReader::new(text, path, 1);
        assert_eq!(r.next_content().unwrap(), Some((1, "OFF")));
        assert_eq!(r.next_content().unwrap(), Some((2, "1 2 3")));
    }
}
