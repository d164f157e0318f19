//! The Princeton benchmark protocol over a whole data set (paper §4.1, Figure 7): for every pair
//! (X, Y) of a data set, data functions F, G, one functional map per method, its point-to-point
//! map X → Y, and the hard error (12) at the template points, symmetric flips allowed or not;
//! then per-method summaries pooled over all pairs and their cumulative curves.
//!
//! A data set is a directory in the layout of the benchmark shapes (`../shared/data`):
//! shapes `NAME.off` (or `.obj`, `.ply`), ground truth `corres/NAME.vts` and
//! `corres/NAME.sym.vts` (1-based template vertices: line i of X's file corresponds to line i of
//! Y's), the pairs `pairs.txt` (two names per line, tab- or space-separated) and, for segment
//! data, `segmentation/A_B.S.seg.sym` (one 1-based label per vertex of shape S of the pair
//! (A, B)). Files directly in the directory (`NAME.vts`, `A_B.S.seg.sym`) are accepted too.
//!
//! Split by concern: the data set (this file), the data of a pair (`data`), the run
//! ([`run()`], module `run`), the report (`report`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::descriptors::persistence::SegmentationOptions;
use crate::descriptors::spec::PairDataSpec;
use crate::descriptors::{self as desc, Descriptors};
use crate::error::{Error, Result};
use crate::eval::{self, GroundTruth, Summary};
use crate::geodesic::GeodesicMethod;
use crate::io::indices::{read_labels_file, read_template_list_file};

use crate::matching::{self, MatchOptions};
use crate::shape::{Shape, TriMesh};
use crate::spectral::{Basis, BasisCache};

mod data;
mod report;
mod run;
pub use data::*;
pub use report::*;
pub use run::*;

/// Shape file extensions a data set may use, in order of preference.
const MESH_EXTENSIONS: [&str; 3] = ["off", "obj", "ply"];

/// A data set directory (see the module docs for its layout).
#[derive(Debug, Clone)]
pub struct Dataset {
    dir: PathBuf,
    shapes: BTreeMap<String, PathBuf>,
}

impl Dataset {
    /// Opens `dir` and lists its shapes. Errors when `dir` cannot be read or holds no mesh.
    pub fn open(dir: &Path) -> Result<Dataset> {
        let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
        let mut shapes = BTreeMap::new();
        for entry in entries {
            let path = entry.map_err(|e| Error::io(dir, e))?.path();
            let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            let (Some(ext), Some(stem)) = (ext, path.file_stem().and_then(|s| s.to_str())) else { continue };
            let Some(rank) = MESH_EXTENSIONS.iter().position(|e| *e == ext) else { continue };
            // One file per name: the preferred extension wins (a.off over a.ply).
            let better = shapes.get(stem).is_none_or(|p: &PathBuf| {
                let old = p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
                MESH_EXTENSIONS.iter().position(|e| *e == old).unwrap_or(usize::MAX) > rank
            });
            if better && path.is_file() {
                shapes.insert(stem.to_string(), path);
            }
        }
        if shapes.is_empty() {
            return Err(Error::invalid("dataset", format!("{} holds no .off, .obj or .ply shape", dir.display())));
        }
        Ok(Dataset { dir: dir.to_path_buf(), shapes })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Names of the shapes, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.shapes.keys().map(String::as_str)
    }

    /// The file of shape `name`; errors when the data set has no such shape.
    pub fn shape_path(&self, name: &str) -> Result<&Path> {
        self.shapes
            .get(name)
            .map(PathBuf::as_path)
            .ok_or_else(|| Error::invalid("shape", format!("{} has no shape named {name:?}", self.dir.display())))
    }

    /// The pairs to evaluate: from `file` or else `DIR/pairs.txt`; two shape names per line
    /// separated by tabs or spaces, `#` comments and blank lines skipped. Errors name the file
    /// and line of a malformed line or an unknown shape.
    pub fn pairs(&self, file: Option<&Path>) -> Result<Vec<(String, String)>> {
        let path = file.map(Path::to_path_buf).unwrap_or_else(|| self.dir.join("pairs.txt"));
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let mut pairs = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let words: Vec<&str> = line.split_whitespace().collect();
            if words.len() != 2 {
                return Err(Error::parse(&path, Some(i + 1), format!("expected two shape names, found {line:?}")));
            }
            for w in &words {
                if !self.shapes.contains_key(*w) {
                    return Err(Error::parse(
                        &path,
                        Some(i + 1),
                        format!("no shape named {w:?} in {}", self.dir.display()),
                    ));
                }
            }
            pairs.push((words[0].to_string(), words[1].to_string()));
        }
        if pairs.is_empty() {
            return Err(Error::parse(&path, None, "no pairs"));
        }
        Ok(pairs)
    }

    /// The first of `candidates` (relative to the data set) that exists.
    fn find(&self, candidates: &[String]) -> Result<PathBuf> {
        candidates.iter().map(|c| self.dir.join(c)).find(|p| p.is_file()).ok_or_else(|| {
            Error::invalid("dataset", format!("{} has none of {}", self.dir.display(), candidates.join(", ")))
        })
    }

    /// Template vertices of shape `name` with `n` vertices (0-based; None where a part lacks the
    /// template point, 0 in the file): `corres/NAME.vts`, or `corres/NAME.sym.vts` when
    /// `mirrored`.
    pub fn template(&self, name: &str, n: usize, mirrored: bool) -> Result<Vec<Option<usize>>> {
        let file = if mirrored { format!("{name}.sym.vts") } else { format!("{name}.vts") };
        read_template_list_file(&self.find(&[format!("corres/{file}"), file])?, n)
    }

    /// Ground truth of the pair (X, Y) with n and m vertices; the mirrored template of Y too
    /// when `symmetric`. Template points a part lacks (0 in its `.vts`) are left out
    /// ([`GroundTruth::from_templates`]).
    pub fn ground_truth(&self, x: &str, y: &str, n: usize, m: usize, symmetric: bool) -> Result<GroundTruth> {
        let (tx, ty) = (self.template(x, n, false)?, self.template(y, m, false)?);
        let ts = if symmetric { Some(self.template(y, m, true)?) } else { None };
        if tx.len() != ty.len() || ts.as_ref().is_some_and(|s| s.len() != ty.len()) {
            return Err(Error::invalid(
                "ground truth",
                format!("the template files of {x} and {y} have different lengths ({} and {})", tx.len(), ty.len()),
            ));
        }
        GroundTruth::from_templates(&tx, &ty, ts.as_deref())
    }

    /// Segment labels of `shape` (n vertices) for the pair (a, b):
    /// `segmentation/A_B.SHAPE.seg.SUFFIX` (or B_A), SUFFIX `sym` or `nonsym`.
    pub fn segmentation(&self, a: &str, b: &str, shape: &str, n: usize, suffix: &str) -> Result<Vec<u32>> {
        let names = [format!("{a}_{b}.{shape}.seg.{suffix}"), format!("{b}_{a}.{shape}.seg.{suffix}")];
        let candidates: Vec<String> = names.iter().flat_map(|f| [format!("segmentation/{f}"), f.clone()]).collect();
        read_labels_file(&self.find(&candidates)?, n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::signatures as sig;

    #[test]
    fn data_specs_parse_and_print() {
        // The data set's forms in the one `--data` grammar ([`PairDataSpec`]).
        let p = |s: &str| s.parse::<PairDataSpec>().and_then(PairDataSpec::for_dataset);
        for s in ["segments", "segments:nonsym", "wks:100", "rich", "landmarks:12"] {
            assert_eq!(p(s).unwrap().to_string(), s);
        }
        assert_eq!(p("segments:sym").unwrap(), PairDataSpec::DatasetSegments { symmetric: true });
        // A count is optional for wks: 100 WKS, as in `funcorr match --data wks`.
        assert_eq!(p("wks").unwrap(), PairDataSpec::WksRecipe);
        assert_eq!(sig::DEFAULT_COUNT, 100);
        for bad in ["", "wks:", "wks:0", "wks:x", "landmarks:-3", "rich:3", "segments:odd", "mser:x"] {
            let e = p(bad).unwrap_err().to_string();
            assert!(e.contains("invalid data"), "{bad}: {e}");
        }
        assert!(p("rich").unwrap().is_rich() && !p("landmarks:3").unwrap().is_rich());
    }

    #[test]
    fn data_sets_are_read_in_both_layouts() {
        let dir = std::env::temp_dir().join(format!("funcorr_dataset_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("corres")).unwrap();
        let mesh = crate::primitives::icosphere(1);
        let data =
            crate::io::MeshData { vertices: mesh.vertices().to_vec(), faces: mesh.faces().to_vec(), colors: None };
        for name in ["a.off", "b.off", "b.ply"] {
            crate::io::write_mesh(&dir.join(name), &data).unwrap();
        }
        std::fs::write(dir.join("notes.txt"), "not a shape").unwrap();
        let ds = Dataset::open(&dir).unwrap();
        assert_eq!(ds.names().collect::<Vec<_>>(), ["a", "b"]);
        // .off is preferred over .ply for the same name.
        assert!(ds.shape_path("b").unwrap().ends_with("b.off"));
        assert!(ds.shape_path("c").unwrap_err().to_string().contains("\"c\""));
        std::fs::write(dir.join("pairs.txt"), "# source target\na\tb\n\nb a  # reversed\n").unwrap();
        assert_eq!(ds.pairs(None).unwrap(), [("a".into(), "b".into()), ("b".into(), "a".into())]);
        std::fs::write(dir.join("pairs.txt"), "a b\na c\n").unwrap();
        let e = ds.pairs(None).unwrap_err().to_string();
        assert!(e.contains("pairs.txt:2") && e.contains("\"c\""), "{e}");
        // Ground truth from corres/ (preferred) or the directory itself, 1-based.
        std::fs::write(dir.join("corres/a.vts"), "1\n2\n3\n").unwrap();
        std::fs::write(dir.join("b.vts"), "3\n2\n1\n").unwrap();
        std::fs::write(dir.join("corres/b.sym.vts"), "1\n2\n").unwrap();
        let n = mesh.n_vertices();
        let gt = ds.ground_truth("a", "b", n, n, false).unwrap();
        assert_eq!((gt.x, gt.y), (vec![0, 1, 2], vec![2, 1, 0]));
        let e = ds.ground_truth("a", "b", n, n, true).unwrap_err().to_string();
        assert!(e.contains("different lengths"), "{e}");
        let e = ds.template("a", n, true).unwrap_err().to_string();
        assert!(e.contains("a.sym.vts"), "{e}");
        // Segmentations of the pair in either order.
        std::fs::create_dir_all(dir.join("segmentation")).unwrap();
        let labels: String = (0..n).map(|i| format!("{}\n", 1 + i % 3)).collect();
        std::fs::write(dir.join("segmentation/b_a.a.seg.sym"), &labels).unwrap();
        assert_eq!(ds.segmentation("a", "b", "a", n, "sym").unwrap().len(), n);
        assert!(ds.segmentation("a", "b", "b", n, "sym").is_err());
        // No shapes: an error naming the directory.
        let empty = dir.join("corres");
        assert!(Dataset::open(&empty).unwrap_err().to_string().contains("corres"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
