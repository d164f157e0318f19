//! The data specification (`--data` of `funcorr match`, `descriptors` and `bench`): which
//! corresponding functions F on X and G on Y to use, parsed from a short string before any work
//! is done (so that a typo fails at once, and so that the parser can be fuzzed on its own).
//!
//! One grammar for every command: most forms name functions of the two shapes alone
//! ([`PairDataSpec::functions`]); two forms name the data of a benchmark data set (its
//! segmentation of the pair, its ground-truth correspondence) and are resolved by
//! [`crate::benchmark::pair_data`]. [`PairDataSpec::standalone`] rejects those two where no
//! data set is given.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use super::persistence::SegmentationOptions;
use super::Descriptors;
use crate::error::{Error, Result};
use crate::laplacian::Laplacian;
use crate::shape::Shape;
use crate::spectral::Basis;

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
    /// `segments` (= `segments:sym`) or `segments:nonsym`, without files: one indicator per
    /// segment of the benchmark data set's segmentation of the pair (the paper's scarce data);
    /// `symmetric` selects its `.seg.sym` labels, else `.seg.nonsym`. Data sets only.
    DatasetSegments {
        /// Use the `.sym` label files.
        symmetric: bool,
    },
    /// `landmarks:N` (N written in digits only; a file named by digits is written `./N`): delta
    /// functions at N ground-truth landmarks of a benchmark data set (farthest-point samples of
    /// X's template points and their counterparts on Y). Data sets only.
    GroundTruthLandmarks(usize),
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

    /// Whether the spec names data of a benchmark data set (its segmentation or its ground
    /// truth), which only [`crate::benchmark::pair_data`] can resolve.
    pub fn needs_dataset(&self) -> bool {
        matches!(self, PairDataSpec::DatasetSegments { .. } | PairDataSpec::GroundTruthLandmarks(_))
    }

    /// The spec if it can be computed from two shapes alone ([`PairDataSpec::functions`]); an
    /// error naming `data` (the CLI's `--data`) for the data-set forms (`segments` without files, `landmarks:N`).
    pub fn standalone(self) -> Result<Self> {
        if !self.needs_dataset() {
            return Ok(self);
        }
        let hint = match self {
            PairDataSpec::DatasetSegments { .. } => "give the label files of both shapes, segments:A,B",
            _ => "give a file of vertex pairs, landmarks:F (a file named by digits is written ./N)",
        };
        Err(Error::invalid("data", format!("'{self}' names the data of a benchmark data set (funcorr bench); {hint}")))
    }

    /// The spec if it can be used on every pair of a data set; an error naming `data` for the
    /// forms that name files of one pair (`segments:A,B`, `rich:A,B`, `landmarks:F`,
    /// `matrix:F,G`).
    pub fn for_dataset(self) -> Result<Self> {
        match self {
            PairDataSpec::Segments(..)
            | PairDataSpec::Rich(Some(_))
            | PairDataSpec::Landmarks(_)
            | PairDataSpec::Matrix(..) => Err(Error::invalid(
                "data",
                format!(
                    "'{self}' names files of one pair; a data set needs data for every pair: segments, \
                     segments:nonsym, rich, landmarks:N, wks, wks:N, hks:N, wks+hks:N, persistence or mser"
                ),
            )),
            s => Ok(s),
        }
    }
}

/// The forms a spec can take, for error messages.
const FORMS: &str = "wks, wks:N, hks, hks:N, wks+hks, wks+hks:N, segments:A,B, persistence, mser, landmarks:F, rich, \
                     rich:A,B, matrix:F,G; in a data set also segments, segments:nonsym, landmarks:N";

impl FromStr for PairDataSpec {
    type Err = Error;

    /// Parses a spec (see [`PairDataSpec`]'s variants). Errors ([`Error::Invalid`] naming
    /// `data`): an unknown kind, a count that is not an integer in 1..=[`MAX_COUNT`], a
    /// missing or empty file name.
    fn from_str(spec: &str) -> Result<Self> {
        let bad = |msg: String| Error::invalid("data", format!("'{spec}': {msg}"));
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
            "segments" if matches!(arg, None | Some("sym")) => Ok(PairDataSpec::DatasetSegments { symmetric: true }),
            "segments" if arg == Some("nonsym") => Ok(PairDataSpec::DatasetSegments { symmetric: false }),
            "segments" => two_files().map(|(a, b)| PairDataSpec::Segments(a, b)),
            "persistence" => no_arg(PairDataSpec::Persistence),
            "rich" if arg.is_none() => Ok(PairDataSpec::Rich(None)),
            "rich" => Ok(PairDataSpec::Rich(Some(two_files()?))),
            "mser" => no_arg(PairDataSpec::Mser),
            "landmarks" if arg.is_some_and(|a| !a.is_empty() && a.bytes().all(|b| b.is_ascii_digit())) => {
                Ok(PairDataSpec::GroundTruthLandmarks(count()?))
            }
            "landmarks" => Ok(PairDataSpec::Landmarks(file(arg.unwrap_or(""))?)),
            "matrix" => two_files().map(|(a, b)| PairDataSpec::Matrix(a, b)),
            _ => Err(bad(format!("unknown kind (expected one of {FORMS})"))),
        }
    }
}

impl std::fmt::Display for PairDataSpec {
    /// The canonical spec string (what [`FromStr`] reads back).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PairDataSpec::WksRecipe => write!(f, "wks"),
            PairDataSpec::Signatures { wks, hks, count } => {
                let kind = match (wks, hks) {
                    (true, true) => "wks+hks",
                    (true, false) => "wks",
                    _ => "hks",
                };
                write!(f, "{kind}:{count}")
            }
            PairDataSpec::Segments(a, b) => write!(f, "segments:{},{}", a.display(), b.display()),
            PairDataSpec::Persistence => write!(f, "persistence"),
            PairDataSpec::Rich(None) => write!(f, "rich"),
            PairDataSpec::Rich(Some((a, b))) => write!(f, "rich:{},{}", a.display(), b.display()),
            PairDataSpec::Mser => write!(f, "mser"),
            PairDataSpec::Landmarks(p) => write!(f, "landmarks:{}", p.display()),
            PairDataSpec::Matrix(a, b) => write!(f, "matrix:{},{}", a.display(), b.display()),
            PairDataSpec::DatasetSegments { symmetric: true } => write!(f, "segments"),
            PairDataSpec::DatasetSegments { symmetric: false } => write!(f, "segments:nonsym"),
            PairDataSpec::GroundTruthLandmarks(n) => write!(f, "landmarks:{n}"),
        }
    }
}

/// One side of a pair for [`PairDataSpec::functions`]: the shape (n vertices), its Laplacian
/// and its basis (n × k).
pub type Side<'a> = (&'a Shape, &'a Laplacian, &'a Basis);

impl PairDataSpec {
    /// The corresponding functions F (n × q) on X and G (m × q) on Y this spec asks for, the
    /// same q columns in the same order on both shapes. `seg` configures the persistence
    /// segments of `persistence` and `rich`. Errors name the spec (parameter `data`) or the
    /// file at fault; the data-set forms ([`PairDataSpec::needs_dataset`]) are an error here.
    pub fn functions(
        &self,
        (x, lx, bx): Side,
        (y, ly, by): Side,
        seg: &SegmentationOptions,
    ) -> Result<(Descriptors, Descriptors)> {
        use super::{persistence as pers, signatures as sig};
        let bad = |msg: String| Error::invalid("data", format!("'{self}': {msg}"));
        let sigs = |b: &Basis, wks: bool, hks: bool, n: usize| -> Result<Descriptors> {
            let w = if wks { Some(sig::wks(b, n, true)?) } else { None };
            let h = if hks { Some(sig::hks(b, &sig::hks_times(b, n)?, true)?) } else { None };
            match (w, h) {
                (Some(w), Some(h)) => w.concat(&h),
                (Some(w), None) => Ok(w),
                (None, Some(h)) => Ok(h),
                (None, None) => Err(bad("no signature asked for".into())),
            }
        };
        let segments = |a: &Path, b: &Path| {
            let la = crate::io::indices::read_labels_file(a, x.n_vertices())?;
            let lb = crate::io::indices::read_labels_file(b, y.n_vertices())?;
            // Labels agree between the files: keep the labels present on both, in order.
            super::matched_segments(&la, &lb).map_err(|e| bad(e.to_string()))
        };
        let persistence = || -> Result<_> {
            let a = pers::segment_labels(x, lx, bx, seg)?;
            let b = pers::segment_labels(y, ly, by, seg)?;
            let (f, g, _) = pers::matched_segment_indicators(&a, bx, &b, by)?;
            Ok((f, g))
        };
        match self {
            PairDataSpec::WksRecipe => {
                let r = sig::WksRecipe::default();
                Ok((sig::wks_recipe(bx, &r)?, sig::wks_recipe(by, &r)?))
            }
            &PairDataSpec::Signatures { wks, hks, count } => {
                Ok((sigs(bx, wks, hks, count)?, sigs(by, wks, hks, count)?))
            }
            PairDataSpec::Segments(a, b) => segments(a, b),
            PairDataSpec::Persistence => persistence(),
            PairDataSpec::Rich(files) => {
                // Segments: given label files (matched by label) or persistence segments
                // (matched by signature); then 100 WKS + 100 HKM localized on them.
                let (fs, gs) = match files {
                    None => persistence()?,
                    Some((a, b)) => segments(a, b)?,
                };
                super::rich(bx, by, &fs, &gs, 100, 100)
            }
            PairDataSpec::Mser => match (x, y) {
                (Shape::Mesh(mx), Shape::Mesh(my)) => {
                    let (f, g, _) =
                        super::mser::matched_mser_indicators((mx, bx), (my, by), &super::mser::MserOptions::default())?;
                    Ok((f, g))
                }
                _ => Err(bad("mser needs two triangle meshes".into())),
            },
            PairDataSpec::Landmarks(file) => {
                let pairs = crate::io::indices::read_index_pairs_file(file, false, x.n_vertices(), y.n_vertices())?;
                let (a, b): (Vec<usize>, Vec<usize>) = pairs.into_iter().unzip();
                Ok((super::landmarks(x.n_vertices(), &a)?, super::landmarks(y.n_vertices(), &b)?))
            }
            PairDataSpec::Matrix(a, b) => {
                // Errors about a matrix name its file.
                let read = |p: &std::path::Path, n: usize| {
                    Descriptors::from_matrix(&crate::io::read_matrix(p)?, n).map_err(|e| match e {
                        Error::Invalid { what, msg } => Error::parse(p, None, format!("invalid {what}: {msg}")),
                        e => e,
                    })
                };
                let (f, g) = (read(a, x.n_vertices())?, read(b, y.n_vertices())?);
                Ok((f, g))
            }
            PairDataSpec::DatasetSegments { .. } | PairDataSpec::GroundTruthLandmarks(_) => {
                Err(self.clone().standalone().expect_err("a data-set form"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_print_as_they_parse_and_give_functions_on_both_shapes() {
        for text in [
            "wks",
            "wks:7",
            "hks:100",
            "wks+hks:3",
            "segments:a,b",
            "persistence",
            "rich",
            "rich:a,b",
            "mser",
            "landmarks:l.txt",
            "matrix:f.npy,g.npy",
            "segments",
            "segments:nonsym",
            "landmarks:12",
        ] {
            let spec: PairDataSpec = text.parse().unwrap();
            assert_eq!(spec.to_string(), text);
            assert_eq!(spec.to_string().parse::<PairDataSpec>().unwrap(), spec);
        }
        let m = crate::primitives::bumpy_sphere(2);
        let lap = crate::laplacian::cotangent(&m).unwrap();
        let basis = crate::spectral::eigen_basis(&lap, &crate::spectral::SpectralOptions::new(20), None).unwrap().0;
        let shape = Shape::Mesh(m);
        let side = (&shape, &lap, &basis);
        let seg = SegmentationOptions::default();
        let (f, g) = "wks+hks:5".parse::<PairDataSpec>().unwrap().functions(side, side, &seg).unwrap();
        assert_eq!((f.q(), g.q(), f.n()), (10, 10, shape.n_vertices()));
        let (f, g) = "persistence".parse::<PairDataSpec>().unwrap().functions(side, side, &seg).unwrap();
        assert!(f.q() >= 1 && f.q() == g.q());
        let e = "segments".parse::<PairDataSpec>().unwrap().functions(side, side, &seg).unwrap_err();
        assert!(e.to_string().contains("segments:A,B"), "{e}");
        let e =
            "landmarks:/nonexistent/l.txt".parse::<PairDataSpec>().unwrap().functions(side, side, &seg).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/l.txt"), "{e}");
    }

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
        assert_eq!(p("segments").unwrap(), P::DatasetSegments { symmetric: true });
        assert_eq!(p("segments:sym").unwrap(), P::DatasetSegments { symmetric: true });
        assert_eq!(p("segments:nonsym").unwrap(), P::DatasetSegments { symmetric: false });
        assert_eq!(p("landmarks:12").unwrap(), P::GroundTruthLandmarks(12));
        assert_eq!(p("landmarks:./12").unwrap(), P::Landmarks("./12".into()));
        for s in ["segments", "landmarks:3"] {
            assert!(p(s).unwrap().needs_dataset());
            let e = p(s).unwrap().standalone().unwrap_err().to_string();
            assert!(e.contains("data") && e.contains("data set"), "{s}: {e}");
        }
        assert_eq!(p("wks").unwrap().standalone().unwrap(), P::WksRecipe);
        for s in ["segments:a,b", "rich:a,b", "landmarks:l.txt", "landmarks:-3", "matrix:f,g"] {
            let e = p(s).unwrap().for_dataset().unwrap_err().to_string();
            assert!(e.contains("data") && e.contains("one pair"), "{s}: {e}");
        }
        for s in ["segments", "rich", "landmarks:3", "wks", "persistence"] {
            assert_eq!(p(s).unwrap().for_dataset().unwrap(), p(s).unwrap());
        }
        assert!(p("wks").unwrap().is_rich() && !p("persistence").unwrap().is_rich());
        for (s, needle) in [
            ("wks:0", "1..=100000"),
            ("wks:100001", "1..=100000"),
            ("hks:-1", "count"),
            ("wks:", "count"),
            ("segments:a", "two files"),
            ("segments:,b", "file name"),
            ("landmarks:", "file name"),
            ("landmarks:0", "1..=100000"),
            ("landmarks:100001", "1..=100000"),
            ("mser:x", "no argument"),
            ("sift", "unknown kind"),
            ("", "unknown kind"),
        ] {
            let e = p(s).unwrap_err().to_string();
            assert!(e.contains("data") && e.contains(needle), "{s}: {e}");
        }
    }
}
