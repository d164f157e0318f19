//! The `--data` specification of `funcorr match`: which corresponding functions F on X and G on
//! Y to use, parsed from a short string before any work is done (so that a typo fails at once,
//! and so that the parser can be fuzzed on its own).

use std::path::PathBuf;
use std::str::FromStr;

use crate::error::{Error, Result};

/// Most signature functions a spec may ask for (`wks:N`, `hks:N`): the same bound as
/// [`super::signatures::wks`].
pub const MAX_COUNT: usize = 100_000;

/// What `--data` asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PairDataSpec {
    /// `wks`: the default WKS recipe ([`super::signatures::WksRecipe`]).
    WksRecipe,
    /// `wks:N`, `hks`, `hks:N`, `wks+hks`, `wks+hks:N`: N (default
    /// [`super::signatures::DEFAULT_COUNT`]) wave and/or heat kernel signatures.
    Signatures {
        /// Include the WKS.
        wks: bool,
        /// Include the HKS.
        hks: bool,
        /// Functions of each kind, 1..=[`MAX_COUNT`].
        count: usize,
    },
    /// `segments:A,B`: indicator functions of the segments in label files A (on X) and B (on Y),
    /// matched by label.
    Segments(PathBuf, PathBuf),
    /// `persistence`: persistence segments of both shapes, matched by their signatures.
    Persistence,
    /// `rich` or `rich:A,B`: 100 WKS + 100 HKM localized on segments (persistence, or the
    /// label files A and B).
    Rich(Option<(PathBuf, PathBuf)>),
    /// `mser`: matched maximally stable extremal regions (meshes only).
    Mser,
    /// `landmarks:F`: delta functions at the vertex pairs `i j` of file F (0-based).
    Landmarks(PathBuf),
    /// `matrix:F,G`: user matrices F (n × q) and G (m × q), `.npy`/`.csv`/`.txt`.
    Matrix(PathBuf, PathBuf),
}

impl PairDataSpec {
    /// Whether the spec gives many functions (the paper's rich setting, which changes the
    /// defaults of the completion method): signatures, `rich`, `matrix`.
    pub fn is_rich(&self) -> bool {
        matches!(
            self,
            PairDataSpec::WksRecipe
                | PairDataSpec::Signatures { .. }
                | PairDataSpec::Rich(_)
                | PairDataSpec::Matrix(..)
        )
    }
}

/// The forms a spec can take, for error messages.
const FORMS: &str = "wks, wks:N, hks, hks:N, wks+hks, wks+hks:N, segments:A,B, persistence, mser, landmarks:F, rich, \
                     rich:A,B, matrix:F,G";

impl FromStr for PairDataSpec {
    type Err = Error;

    /// Parses a spec (see [`PairDataSpec`]'s variants). Errors ([`Error::Invalid`] naming
    /// `--data`): an unknown kind, a count that is not an integer in 1..=[`MAX_COUNT`], a
    /// missing or empty file name.
    fn from_str(spec: &str) -> Result<Self> {
        let bad = |msg: String| Error::invalid("--data", format!("'{spec}': {msg}"));
        let (kind, arg) = match spec.split_once(':') {
            Some((k, a)) => (k, Some(a)),
            None => (spec, None),
        };
        let count = || match arg {
            None => Ok(super::signatures::DEFAULT_COUNT),
            Some(a) => a.parse::<usize>().ok().filter(|n| (1..=MAX_COUNT).contains(n)).ok_or_else(|| {
                bad(format!("expected a count in 1..={MAX_COUNT} after the colon, e.g. {kind}:100, or none"))
            }),
        };
        let file = |a: &str| -> Result<PathBuf> {
            if a.is_empty() {
                Err(bad("expected a file name, found none".into()))
            } else {
                Ok(PathBuf::from(a))
            }
        };
        let two_files = || -> Result<(PathBuf, PathBuf)> {
            let (a, b) = arg
                .and_then(|a| a.split_once(','))
                .ok_or_else(|| bad("expected two files separated by a comma".into()))?;
            Ok((file(a)?, file(b)?))
        };
        let no_arg = |v: PairDataSpec| match arg {
            None => Ok(v),
            Some(_) => Err(bad(format!("'{kind}' takes no argument after a colon"))),
        };
        match kind {
            "wks" if arg.is_none() => Ok(PairDataSpec::WksRecipe),
            "wks" => Ok(PairDataSpec::Signatures { wks: true, hks: false, count: count()? }),
            "hks" => Ok(PairDataSpec::Signatures { wks: false, hks: true, count: count()? }),
            "wks+hks" => Ok(PairDataSpec::Signatures { wks: true, hks: true, count: count()? }),
            "segments" => two_files().map(|(a, b)| PairDataSpec::Segments(a, b)),
            "persistence" => no_arg(PairDataSpec::Persistence),
            "rich" if arg.is_none() => Ok(PairDataSpec::Rich(None)),
            "rich" => Ok(PairDataSpec::Rich(Some(two_files()?))),
            "mser" => no_arg(PairDataSpec::Mser),
            "landmarks" => Ok(PairDataSpec::Landmarks(file(arg.unwrap_or(""))?)),
            "matrix" => two_files().map(|(a, b)| PairDataSpec::Matrix(a, b)),
            _ => Err(bad(format!("unknown kind (expected one of {FORMS})"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_parses_and_mistakes_name_the_option() {
        use PairDataSpec as P;
        let p = |s: &str| s.parse::<PairDataSpec>();
        assert_eq!(p("wks").unwrap(), P::WksRecipe);
        assert_eq!(p("wks:7").unwrap(), P::Signatures { wks: true, hks: false, count: 7 });
        assert_eq!(p("hks").unwrap(), P::Signatures { wks: false, hks: true, count: 100 });
        assert_eq!(p("wks+hks:3").unwrap(), P::Signatures { wks: true, hks: true, count: 3 });
        assert_eq!(p("segments:a.txt,b.txt").unwrap(), P::Segments("a.txt".into(), "b.txt".into()));
        assert_eq!(p("rich").unwrap(), P::Rich(None));
        assert_eq!(p("rich:a,b").unwrap(), P::Rich(Some(("a".into(), "b".into()))));
        assert_eq!(p("landmarks:l.txt").unwrap(), P::Landmarks("l.txt".into()));
        assert_eq!(p("matrix:f.npy,g.npy").unwrap(), P::Matrix("f.npy".into(), "g.npy".into()));
        assert_eq!(p("persistence").unwrap(), P::Persistence);
        assert!(p("wks").unwrap().is_rich() && !p("persistence").unwrap().is_rich());
        for (s, needle) in [
            ("wks:0", "1..=100000"),
            ("wks:100001", "1..=100000"),
            ("hks:-1", "count"),
            ("wks:", "count"),
            ("segments:a", "two files"),
            ("segments:,b", "file name"),
            ("landmarks:", "file name"),
            ("mser:x", "no argument"),
            ("sift", "unknown kind"),
            ("", "unknown kind"),
        ] {
            let e = p(s).unwrap_err().to_string();
            assert!(e.contains("--data") && e.contains(needle), "{s}: {e}");
        }
    }
}
