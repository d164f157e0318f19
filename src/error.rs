//! Library errors. Every error names what was wrong (file, line, parameter) and why.
//!
//! Messages quote untrusted text (tokens of a file, paths): control characters in it (a NUL
//! byte, an escape sequence that would recolour or rewrite the terminal, a newline that would
//! forge another line) are escaped when an error is displayed ([`escape`]), never printed raw.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// The error type of every fallible funcorr function.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a file.
    #[error("{}: {}", escape_path(path), escape(&source.to_string()))]
    Io {
        /// The file that could not be read or written.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A file's content is malformed.
    #[error("{}{}: {}", escape_path(path), line.map(|l| format!(":{l}")).unwrap_or_default(), escape(msg))]
    Parse {
        /// The file being read.
        path: PathBuf,
        /// 1-based line number, for text formats, when known.
        line: Option<usize>,
        /// What is wrong.
        msg: String,
    },
    /// A parameter or an in-memory input is invalid (wrong size, out of range, NaN, ...).
    #[error("invalid {}: {}", escape(what), escape(msg))]
    Invalid {
        /// The parameter or input concerned (e.g. `k`, `mesh`, `landmarks`).
        what: String,
        /// Why it is invalid.
        msg: String,
    },
    /// A numerical method failed (factorization, non-convergence, residual check).
    #[error("numerical failure in {}: {}", escape(stage), escape(msg))]
    Numerical {
        /// The computation that failed (e.g. `eigensolver`).
        stage: String,
        /// What happened.
        msg: String,
    },
    /// The computation was cancelled ([`crate::progress`]: Ctrl-C in the CLI or in Python, or
    /// a [`crate::progress::Monitor`] cancelled by its owner) before it finished.
    #[error("cancelled{}", if stage.is_empty() { String::new() } else { format!(" during {}", escape(stage)) })]
    Cancelled {
        /// The stage the computation was in (empty when it had not named one).
        stage: String,
    },
}

/// Result alias with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Builds an [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, line: Option<usize>, msg: impl Into<String>) -> Self {
        Error::Parse { path: path.into(), line, msg: msg.into() }
    }
    /// Builds an [`Error::Invalid`].
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Invalid { what: what.into(), msg: msg.into() }
    }
    /// Builds an [`Error::Numerical`].
    pub fn numerical(stage: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Numerical { stage: stage.into(), msg: msg.into() }
    }
    /// Builds an [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

/// `text` with every control character escaped: `\0`, `\t`, `\n`, `\r` and `\u{1b}`-style
/// escapes for the others (C0, DEL, C1), so that quoted input cannot inject bytes into a
/// terminal or a log. Text without control characters is returned as is.
pub fn escape(text: &str) -> Cow<'_, str> {
    if !text.chars().any(char::is_control) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        match c {
            '\0' => out.push_str("\\0"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{{{:x}}}", u32::from(c))),
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// A path for a message: lossy UTF-8 with control characters escaped (see [`escape`]).
pub fn escape_path(path: &Path) -> String {
    escape(&path.to_string_lossy()).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displayed_errors_never_carry_control_characters() {
        assert_eq!(escape("plain ünïcode"), "plain ünïcode");
        assert_eq!(escape("a\0b\x1b[31mc\nd\u{9b}"), "a\\0b\\u{1b}[31mc\\nd\\u{9b}");
        let e = Error::parse("f\x07.off", Some(3), "found 'x\0y'");
        assert_eq!(e.to_string(), "f\\u{7}.off:3: found 'x\\0y'");
        let e = Error::invalid("data", "'\x1b]0;title\x07'");
        assert!(!e.to_string().chars().any(char::is_control), "{e}");
        let e = Error::io("dir\n/x", std::io::Error::other("disk\rfull"));
        assert_eq!(e.to_string(), "dir\\n/x: disk\\rfull");
    }
}
