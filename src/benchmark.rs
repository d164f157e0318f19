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

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::descriptors::{self as desc, signatures as sig, Descriptors};
use crate::error::{Error, Result};
use crate::eval::{self, GroundTruth, Summary};
use crate::geodesic::GeodesicMethod;
use crate::io::indices::{read_index_list_file, read_labels_file};

use crate::matching::{self, MatchOptions};
use crate::shape::{Shape, TriMesh};
use crate::spectral::{Basis, BasisCache};

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
            return Err(Error::invalid("--dataset", format!("{} holds no .off, .obj or .ply shape", dir.display())));
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

    /// Template vertices of shape `name` with `n` vertices (0-based): `corres/NAME.vts`, or
    /// `corres/NAME.sym.vts` when `mirrored`.
    pub fn template(&self, name: &str, n: usize, mirrored: bool) -> Result<Vec<usize>> {
        let file = if mirrored { format!("{name}.sym.vts") } else { format!("{name}.vts") };
        read_index_list_file(&self.find(&[format!("corres/{file}"), file])?, true, n)
    }

    /// Ground truth of the pair (X, Y) with n and m vertices; the mirrored template of Y too
    /// when `symmetric`.
    pub fn ground_truth(&self, x: &str, y: &str, n: usize, m: usize, symmetric: bool) -> Result<GroundTruth> {
        let gt = GroundTruth {
            x: self.template(x, n, false)?,
            y: self.template(y, m, false)?,
            y_sym: if symmetric { Some(self.template(y, m, true)?) } else { None },
        };
        if gt.x.len() != gt.y.len() || gt.y_sym.as_ref().is_some_and(|s| s.len() != gt.y.len()) {
            return Err(Error::invalid(
                "ground truth",
                format!("the template files of {x} and {y} have different lengths ({} and {})", gt.x.len(), gt.y.len()),
            ));
        }
        Ok(gt)
    }

    /// Segment labels of `shape` (n vertices) for the pair (a, b):
    /// `segmentation/A_B.SHAPE.seg.SUFFIX` (or B_A), SUFFIX `sym` or `nonsym`.
    pub fn segmentation(&self, a: &str, b: &str, shape: &str, n: usize, suffix: &str) -> Result<Vec<u32>> {
        let names = [format!("{a}_{b}.{shape}.seg.{suffix}"), format!("{b}_{a}.{shape}.seg.{suffix}")];
        let candidates: Vec<String> = names.iter().flat_map(|f| [format!("segmentation/{f}"), f.clone()]).collect();
        read_labels_file(&self.find(&candidates)?, n)
    }
}

/// The data functions of a benchmark run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DataSpec {
    /// The data set's segmentation of each pair: one indicator per segment (the paper's scarce
    /// data); `symmetric` selects the `.seg.sym` labels, else `.seg.nonsym`.
    Segments {
        /// Use the `.sym` label files.
        symmetric: bool,
    },
    /// WKS descriptors (count energies from the whole basis, normalized) on each shape.
    Wks(usize),
    /// The default WKS recipe ([`sig::WksRecipe`]: 100 energies from the first 128 eigenpairs,
    /// every 2nd kept).
    WksDefault,
    /// The paper's rich data: 100 WKS + 100 heat kernel maps localized on the segments.
    Rich,
    /// Delta functions at `N` ground-truth landmarks (farthest-point samples of X's template
    /// points and their counterparts on Y).
    Landmarks(usize),
}

impl DataSpec {
    /// Whether this is the paper's rich setting (many functions) rather than scarce data.
    pub fn is_rich(self) -> bool {
        matches!(self, DataSpec::Wks(_) | DataSpec::WksDefault | DataSpec::Rich)
    }
}

impl std::fmt::Display for DataSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DataSpec::Segments { symmetric: true } => write!(f, "segments"),
            DataSpec::Segments { symmetric: false } => write!(f, "segments:nonsym"),
            DataSpec::Wks(n) => write!(f, "wks:{n}"),
            DataSpec::WksDefault => write!(f, "wks"),
            DataSpec::Rich => write!(f, "rich"),
            DataSpec::Landmarks(n) => write!(f, "landmarks:{n}"),
        }
    }
}

impl FromStr for DataSpec {
    type Err = Error;
    /// `segments`, `segments:nonsym`, `wks` (the default recipe, [`sig::WksRecipe`]), `wks:N`,
    /// `rich` or `landmarks:N` (N ≥ 1).
    fn from_str(s: &str) -> Result<Self> {
        let bad = |m: &str| Error::invalid("--data", format!("{s:?}: {m}"));
        let (kind, arg) = s.split_once(':').unwrap_or((s, ""));
        let count = || -> Result<usize> {
            arg.parse::<usize>()
                .ok()
                .filter(|&n| (1..=100_000).contains(&n))
                .ok_or_else(|| bad("expected a count in 1..=100000 after the colon, e.g. wks:100"))
        };
        match (kind, arg) {
            ("segments", "" | "sym") => Ok(DataSpec::Segments { symmetric: true }),
            ("segments", "nonsym") => Ok(DataSpec::Segments { symmetric: false }),
            ("wks", "") if !s.contains(':') => Ok(DataSpec::WksDefault),
            ("wks", _) => Ok(DataSpec::Wks(count()?)),
            ("rich", "") => Ok(DataSpec::Rich),
            ("landmarks", _) => Ok(DataSpec::Landmarks(count()?)),
            _ => Err(bad("expected segments, segments:nonsym, wks, wks:N, rich or landmarks:N")),
        }
    }
}

/// A shape of the data set ready for matching: its name, mesh, Laplacian, eigenbasis and surface
/// geometry ([`crate::prepared::PreparedShape`]).
#[derive(Debug)]
pub struct PreparedShape {
    /// Name in the data set.
    pub name: String,
    /// The mesh, its Laplacian, basis and geometry.
    pub prepared: crate::prepared::PreparedShape,
    /// Seconds to read, assemble and solve (or load from the cache).
    pub seconds: f64,
}

impl PreparedShape {
    /// The mesh.
    pub fn mesh(&self) -> &TriMesh {
        match &self.prepared.shape {
            Shape::Mesh(m) => m,
            Shape::Points(_) => unreachable!("data set shapes are meshes (checked by prepare_shape)"),
        }
    }
    /// The eigenbasis.
    pub fn basis(&self) -> &Basis {
        &self.prepared.basis
    }
}

/// Loads shape `name`, its cotangent Laplacian and `k` eigenpairs (through `cache` when given).
pub fn prepare_shape(ds: &Dataset, name: &str, k: usize, cache: Option<&BasisCache>) -> Result<PreparedShape> {
    let t = Instant::now();
    let path = ds.shape_path(name)?;
    let shape = Shape::load(path)?;
    if !matches!(shape, Shape::Mesh(_)) {
        return Err(Error::invalid("dataset", format!("{} is not a triangle mesh", path.display())));
    }
    let prepared = crate::prepared::PreparedShape::new(shape, crate::prepared::LaplacianChoice::Cotangent, k, cache)?;
    Ok(PreparedShape { name: name.to_string(), prepared, seconds: t.elapsed().as_secs_f64() })
}

/// Farthest-point sampling of `count` of the `candidates` (vertex ids of `mesh`) by Euclidean
/// distance, starting from the first candidate; returns positions into `candidates`.
/// Deterministic; fewer than `count` when there are fewer distinct candidates.
pub fn farthest_points(mesh: &TriMesh, candidates: &[usize], count: usize) -> Vec<usize> {
    let v = mesh.vertices();
    let d2 = |a: usize, b: usize| (0..3).map(|c| (v[a][c] - v[b][c]).powi(2)).sum::<f64>();
    let mut chosen = Vec::with_capacity(count);
    if candidates.is_empty() || count == 0 {
        return chosen;
    }
    let mut best = vec![f64::INFINITY; candidates.len()];
    let mut next = 0;
    while chosen.len() < count {
        chosen.push(next);
        let c = candidates[next];
        for (b, &p) in best.iter_mut().zip(candidates) {
            *b = b.min(d2(p, c));
        }
        let (i, far) = best.iter().enumerate().fold((0, -1.0), |acc, (i, &d)| if d > acc.1 { (i, d) } else { acc });
        if far <= 0.0 {
            break;
        }
        next = i;
    }
    chosen
}

/// The data F (n × q) on X and G (m × q) on Y of the pair (x, y) for `spec`.
pub fn pair_data(
    ds: &Dataset,
    x: &PreparedShape,
    y: &PreparedShape,
    gt: &GroundTruth,
    spec: DataSpec,
) -> Result<(Descriptors, Descriptors)> {
    let segments = |symmetric: bool| -> Result<(Descriptors, Descriptors)> {
        let suffix = if symmetric { "sym" } else { "nonsym" };
        let la = ds.segmentation(&x.name, &y.name, &x.name, x.mesh().n_vertices(), suffix)?;
        let lb = ds.segmentation(&x.name, &y.name, &y.name, y.mesh().n_vertices(), suffix)?;
        desc::matched_segments(&la, &lb)
    };
    match spec {
        DataSpec::Segments { symmetric } => segments(symmetric),
        DataSpec::Wks(count) => Ok((sig::wks(x.basis(), count, true)?, sig::wks(y.basis(), count, true)?)),
        DataSpec::WksDefault => {
            let r = sig::WksRecipe::default();
            Ok((sig::wks_recipe(x.basis(), &r)?, sig::wks_recipe(y.basis(), &r)?))
        }
        DataSpec::Rich => {
            let (fs, gs) = segments(true)?;
            desc::rich(x.basis(), y.basis(), &fs, &gs, 100, 100)
        }
        DataSpec::Landmarks(count) => {
            let picks = farthest_points(x.mesh(), &gt.x, count);
            let xs: Vec<usize> = picks.iter().map(|&i| gt.x[i]).collect();
            let ys: Vec<usize> = picks.iter().map(|&i| gt.y[i]).collect();
            Ok((desc::landmarks(x.mesh().n_vertices(), &xs)?, desc::landmarks(y.mesh().n_vertices(), &ys)?))
        }
    }
}

/// One method of a benchmark run: a name for tables and files, and its options.
#[derive(Debug, Clone)]
pub struct BenchMethod {
    /// Name (letters, digits, `-`, `_`, `+`, `.`: it names files).
    pub name: String,
    /// The matching pipeline.
    pub options: MatchOptions,
}

/// What to run on every pair.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// The data functions.
    pub data: DataSpec,
    /// The methods, run one after the other on each pair.
    pub methods: Vec<BenchMethod>,
    /// Allow symmetric flips (needs `corres/NAME.sym.vts`).
    pub symmetric: bool,
    /// Geodesic distances on Y for the errors.
    pub geodesics: GeodesicMethod,
    /// Cache of eigenbases (None: compute every time).
    pub cache: Option<BasisCache>,
}

/// The score of one method on one pair.
#[derive(Debug, Clone, Serialize)]
pub struct PairScore {
    /// Number of template points evaluated.
    pub points: usize,
    /// Hard error (12) per template point (normalized by √area(Y)).
    pub errors: Vec<f64>,
    /// Mean and fractions of the errors.
    pub summary: Summary,
    /// Cumulative curve at [`eval::standard_thresholds`].
    pub curve: Vec<f64>,
    /// Seconds of the method's stages (data, functional map, point-wise map; without the
    /// shared eigenbases and the evaluation).
    pub seconds: f64,
    /// (stage, seconds) in order, data functions first.
    pub stages: Vec<(String, f64)>,
    /// Number q of data functions.
    pub q: usize,
    /// The map X → Y (length n).
    #[serde(skip)]
    pub map_xy: Vec<usize>,
}

/// One method on one pair: its score, or why it failed.
#[derive(Debug, Clone)]
pub struct PairRun {
    /// Source shape X.
    pub source: String,
    /// Target shape Y.
    pub target: String,
    /// Method name.
    pub method: String,
    /// The score, or the error message.
    pub outcome: std::result::Result<PairScore, String>,
}

/// Runs every method of `opts` on the pair (x, y) and scores it. Failures of one method (or of
/// the pair's data) are recorded in the runs, not returned.
pub fn run_pair(ds: &Dataset, x: &PreparedShape, y: &PreparedShape, opts: &BenchOptions) -> Vec<PairRun> {
    let fail = |msg: String| -> Vec<PairRun> {
        opts.methods
            .iter()
            .map(|m| PairRun {
                source: x.name.clone(),
                target: y.name.clone(),
                method: m.name.clone(),
                outcome: Err(msg.clone()),
            })
            .collect()
    };
    let (n, m) = (x.mesh().n_vertices(), y.mesh().n_vertices());
    let gt = match ds.ground_truth(&x.name, &y.name, n, m, opts.symmetric) {
        Ok(gt) => gt,
        Err(e) => return fail(e.to_string()),
    };
    let t = Instant::now();
    let (f, g) = match pair_data(ds, x, y, &gt, opts.data) {
        Ok(d) => d,
        Err(e) => return fail(format!("data {}: {e}", opts.data)),
    };
    let data_seconds = t.elapsed().as_secs_f64();
    let geo = match opts.geodesics.build(y.mesh()) {
        Ok(g) => g,
        Err(e) => return fail(format!("geodesics on {}: {e}", y.name)),
    };
    let thresholds = eval::standard_thresholds();
    opts.methods
        .iter()
        .map(|method| {
            let score = || -> Result<PairScore> {
                let r = matching::run_prepared(&x.prepared, &y.prepared, &f, &g, &method.options)?;
                let errors = eval::hard_errors(&r.map_xy, &gt, &*geo, y.mesh().total_area())?;
                let mut stages = vec![("data".to_string(), data_seconds)];
                stages.extend(r.stages);
                Ok(PairScore {
                    points: errors.len(),
                    summary: eval::summarize(&errors),
                    curve: eval::cumulative_curve(&errors, &thresholds),
                    seconds: stages.iter().map(|s| s.1).sum(),
                    stages,
                    q: f.q(),
                    errors,
                    map_xy: r.map_xy,
                })
            };
            PairRun {
                source: x.name.clone(),
                target: y.name.clone(),
                method: method.name.clone(),
                outcome: score().map_err(|e| e.to_string()),
            }
        })
        .collect()
}

/// The plot colour of a method: fixed for the four methods of funcorr (so that every plot draws
/// `fmap` in the same colour), else by position.
pub fn method_color(name: &str, position: usize) -> usize {
    match name {
        "fmap" => 0,
        "pokrass" => 1,
        "coupled" => 2,
        "completion" => 3,
        _ => 4 + position,
    }
}

/// Per-method results pooled over the pairs of a run.
#[derive(Debug, Clone, Serialize)]
pub struct MethodSummary {
    /// Method name.
    pub method: String,
    /// Pairs scored.
    pub pairs: usize,
    /// Pairs where the method (or the pair's data) failed; they are not in the numbers.
    pub failed: usize,
    /// Template points scored, over all pairs.
    pub points: usize,
    /// Mean and fractions over all points of all scored pairs (the Princeton protocol pools the
    /// correspondences).
    pub summary: Summary,
    /// Pooled cumulative curve at [`eval::standard_thresholds`].
    pub curve: Vec<f64>,
    /// Mean seconds per scored pair (method stages, see [`PairScore::seconds`]).
    pub seconds_per_pair: f64,
}

/// A benchmark run: all pair runs and the shapes' preparation times.
#[derive(Debug, Clone)]
pub struct Report {
    /// Data spec of the run.
    pub data: DataSpec,
    /// Whether symmetric flips were allowed.
    pub symmetric: bool,
    /// The geodesic solver.
    pub geodesics: GeodesicMethod,
    /// Method names in order.
    pub methods: Vec<String>,
    /// Every (pair, method), pairs in input order.
    pub runs: Vec<PairRun>,
    /// Seconds to prepare each shape (read, Laplacian, eigenbasis or cache load).
    pub shape_seconds: BTreeMap<String, f64>,
    /// Eigenpairs per shape.
    pub k: usize,
    /// Wall-clock seconds of the whole run.
    pub wall_seconds: f64,
}

/// Progress of [`run`]: (stage `"shapes"` or `"pairs"`, done, total).
pub type Progress<'a> = &'a (dyn Fn(&str, usize, usize) + Sync);

/// Runs `opts` on `pairs` of `ds`: prepares every shape once (in parallel, eigenbases through
/// the cache), then runs the pairs in parallel. Errors: no methods, a method name unfit for a
/// file name, and failures to prepare a shape (a shape that cannot be matched at all is an
/// error of the data set, not of a method).
pub fn run(
    ds: &Dataset,
    pairs: &[(String, String)],
    opts: &BenchOptions,
    progress: Option<Progress>,
) -> Result<Report> {
    let wall = Instant::now();
    if opts.methods.is_empty() {
        return Err(Error::invalid("--methods", "no method given"));
    }
    let mut seen = BTreeSet::new();
    for m in &opts.methods {
        let ok = !m.name.is_empty() && m.name.chars().all(|c| c.is_ascii_alphanumeric() || "-_+.=".contains(c));
        if !ok || !seen.insert(m.name.clone()) {
            return Err(Error::invalid(
                "--methods",
                format!("method name {:?} is empty, repeated or unfit for a file name", m.name),
            ));
        }
    }
    if pairs.is_empty() {
        return Err(Error::invalid("pairs", "no pairs to run"));
    }
    let k = opts.methods.iter().map(|m| m.options.basis_size()).max().unwrap_or(1);
    let names: Vec<&str> =
        pairs.iter().flat_map(|(a, b)| [a.as_str(), b.as_str()]).collect::<BTreeSet<_>>().into_iter().collect();
    let done = AtomicUsize::new(0);
    let report = |stage: &str, total: usize| {
        let d = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(p) = progress {
            p(stage, d, total);
        }
    };
    if let Some(p) = progress {
        p("shapes", 0, names.len());
    }
    let shapes: BTreeMap<String, PreparedShape> = names
        .par_iter()
        .map(|name| {
            let s = prepare_shape(ds, name, k, opts.cache.as_ref());
            report("shapes", names.len());
            s.map(|s| (name.to_string(), s))
        })
        .collect::<Result<_>>()?;
    done.store(0, Ordering::Relaxed);
    if let Some(p) = progress {
        p("pairs", 0, pairs.len());
    }
    let runs: Vec<Vec<PairRun>> = pairs
        .par_iter()
        .map(|(a, b)| {
            let r = run_pair(ds, &shapes[a], &shapes[b], opts);
            report("pairs", pairs.len());
            r
        })
        .collect();
    Ok(Report {
        data: opts.data,
        symmetric: opts.symmetric,
        geodesics: opts.geodesics,
        methods: opts.methods.iter().map(|m| m.name.clone()).collect(),
        runs: runs.into_iter().flatten().collect(),
        shape_seconds: shapes.iter().map(|(n, s)| (n.clone(), s.seconds)).collect(),
        k,
        wall_seconds: wall.elapsed().as_secs_f64(),
    })
}

impl Report {
    /// Per-method summaries, in method order.
    pub fn summaries(&self) -> Vec<MethodSummary> {
        let thresholds = eval::standard_thresholds();
        self.methods
            .iter()
            .map(|name| {
                let runs: Vec<&PairRun> = self.runs.iter().filter(|r| &r.method == name).collect();
                let scores: Vec<&PairScore> = runs.iter().filter_map(|r| r.outcome.as_ref().ok()).collect();
                let all: Vec<f64> = scores.iter().flat_map(|s| s.errors.iter().copied()).collect();
                MethodSummary {
                    method: name.clone(),
                    pairs: scores.len(),
                    failed: runs.len() - scores.len(),
                    points: all.len(),
                    summary: eval::summarize(&all),
                    curve: eval::cumulative_curve(&all, &thresholds),
                    seconds_per_pair: scores.iter().map(|s| s.seconds).sum::<f64>() / scores.len().max(1) as f64,
                }
            })
            .collect()
    }

    /// The summary as a Markdown table: method, pairs (failed), mean error ×100, fractions at
    /// r = 0.05, 0.10, 0.25 (%), seconds per pair.
    pub fn table(&self) -> String {
        table_of(&self.summaries())
    }

    /// The plot of the pooled cumulative curves, one line per method (dashed for scarce data).
    pub fn plot(&self, title: &str) -> crate::viz::plot::LinePlot {
        plot_of(self.data, &self.summaries(), title)
    }

    /// Writes the run to `out` (created): `pairs.csv` (one row per pair and method),
    /// `pairs.json` (the same with curves and stage times), `maps/X__Y.METHOD.txt` (0-based
    /// maps X → Y, readable by `funcorr eval`), `summary.csv`, `summary.md`, `summary.json` and
    /// `curves.png` (one line per method). Returns the paths written.
    pub fn write(&self, out: &Path, title: &str) -> Result<Vec<PathBuf>> {
        let maps = out.join("maps");
        std::fs::create_dir_all(&maps).map_err(|e| Error::io(&maps, e))?;
        let write = |name: &str, text: String| -> Result<PathBuf> {
            let p = out.join(name);
            crate::io::write_atomic(&p, text)?;
            Ok(p)
        };
        let mut written = Vec::new();
        let mut csv = String::from("source,target,method,status,q,points,mean_x100,le_0.05,le_0.10,le_0.25,seconds\n");
        let mut json_pairs = Vec::new();
        for r in &self.runs {
            match &r.outcome {
                Ok(s) => {
                    csv += &format!(
                        "{},{},{},ok,{},{},{:.4},{:.4},{:.4},{:.4},{:.3}\n",
                        r.source,
                        r.target,
                        r.method,
                        s.q,
                        s.points,
                        100.0 * s.summary.mean,
                        s.summary.at_005,
                        s.summary.at_010,
                        s.summary.at_025,
                        s.seconds
                    );
                    let map: String = s.map_xy.iter().map(|j| format!("{j}\n")).collect();
                    let p = maps.join(format!("{}__{}.{}.txt", r.source, r.target, r.method));
                    crate::io::write_atomic(&p, map)?;
                    json_pairs.push(serde_json::json!({
                        "source": r.source, "target": r.target, "method": r.method, "status": "ok",
                        "q": s.q, "points": s.points, "summary": s.summary, "curve": s.curve,
                        "seconds": s.seconds, "stages": s.stages,
                    }));
                }
                Err(msg) => {
                    csv += &format!("{},{},{},failed,,,,,,,\n", r.source, r.target, r.method);
                    json_pairs.push(serde_json::json!({
                        "source": r.source, "target": r.target, "method": r.method, "status": "failed", "error": msg,
                    }));
                }
            }
        }
        written.push(write("pairs.csv", csv)?);
        written.push(write("pairs.json", serde_json::to_string_pretty(&json_pairs).expect("plain JSON"))?);
        let summaries = self.summaries();
        let mut csv = String::from("method,pairs,failed,points,mean_x100,le_0.05,le_0.10,le_0.25,seconds_per_pair\n");
        for m in &summaries {
            csv += &format!(
                "{},{},{},{},{:.4},{:.4},{:.4},{:.4},{:.3}\n",
                m.method,
                m.pairs,
                m.failed,
                m.points,
                100.0 * m.summary.mean,
                m.summary.at_005,
                m.summary.at_010,
                m.summary.at_025,
                m.seconds_per_pair
            );
        }
        written.push(write("summary.csv", csv)?);
        written.push(write("summary.md", format!("# {title}\n\n{}", table_of(&summaries)))?);
        let json = serde_json::json!({
            "title": title, "data": self.data.to_string(), "symmetric": self.symmetric,
            "geodesics": self.geodesics.name(), "k": self.k, "wall_seconds": self.wall_seconds,
            "shape_seconds": self.shape_seconds, "thresholds": eval::standard_thresholds(), "methods": summaries,
        });
        written.push(write("summary.json", serde_json::to_string_pretty(&json).expect("plain JSON"))?);
        if summaries.iter().any(|m| m.pairs > 0) {
            let p = out.join("curves.png");
            plot_of(self.data, &summaries, title).write_png(&p, 900, 640)?;
            written.push(p);
        }
        Ok(written)
    }
}

/// The Markdown table of [`Report::table`] from per-method summaries.
fn table_of(summaries: &[MethodSummary]) -> String {
    let mut s = String::from(
        "| method | pairs | mean error ×100 | ≤ 0.05 | ≤ 0.10 | ≤ 0.25 | s / pair |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for m in summaries {
        let failed = if m.failed > 0 { format!(" ({} failed)", m.failed) } else { String::new() };
        if m.pairs == 0 {
            s += &format!("| {} | 0{failed} | – | – | – | – | – |\n", m.method);
            continue;
        }
        s += &format!(
            "| {} | {}{failed} | {:.2} | {:.1}% | {:.1}% | {:.1}% | {:.2} |\n",
            m.method,
            m.pairs,
            100.0 * m.summary.mean,
            100.0 * m.summary.at_005,
            100.0 * m.summary.at_010,
            100.0 * m.summary.at_025,
            m.seconds_per_pair
        );
    }
    s
}

/// The plot of [`Report::plot`] from per-method summaries.
fn plot_of(data: DataSpec, summaries: &[MethodSummary], title: &str) -> crate::viz::plot::LinePlot {
    let dashed = !data.is_rich();
    let curves: Vec<(String, Vec<f64>, bool, usize)> = summaries
        .iter()
        .enumerate()
        .filter(|(_, m)| m.pairs > 0)
        .map(|(i, m)| (m.method.clone(), m.curve.clone(), dashed, method_color(&m.method, i)))
        .collect();
    crate::viz::plot::cumulative_curves(title, &eval::standard_thresholds(), &curves)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_specs_parse_and_print() {
        for s in ["segments", "segments:nonsym", "wks:100", "rich", "landmarks:12"] {
            assert_eq!(s.parse::<DataSpec>().unwrap().to_string(), s);
        }
        assert_eq!("segments:sym".parse::<DataSpec>().unwrap(), DataSpec::Segments { symmetric: true });
        // A count is optional for wks: 100 WKS, as in `funcorr match --data wks`.
        assert_eq!("wks".parse::<DataSpec>().unwrap(), DataSpec::WksDefault);
        assert_eq!(sig::DEFAULT_COUNT, 100);
        for bad in ["", "wks:", "wks:0", "wks:x", "landmarks:-3", "rich:3", "segments:odd", "mser"] {
            let e = bad.parse::<DataSpec>().unwrap_err().to_string();
            assert!(e.contains("--data"), "{bad}: {e}");
        }
        assert!(DataSpec::Rich.is_rich() && !DataSpec::Landmarks(3).is_rich());
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

    #[test]
    fn farthest_points_spread_out() {
        let mesh = crate::primitives::icosphere(2);
        let all: Vec<usize> = (0..mesh.n_vertices()).collect();
        let p = farthest_points(&mesh, &all, 2);
        // The second point is antipodal to the first on the unit sphere.
        let (a, b) = (mesh.vertices()[p[0]], mesh.vertices()[p[1]]);
        let d: f64 = (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt();
        assert!((d - 2.0).abs() < 1e-9, "{d}");
        // Duplicated candidates: never more distinct points than exist.
        assert_eq!(farthest_points(&mesh, &[3, 3, 3], 5), vec![0]);
        assert!(farthest_points(&mesh, &[], 5).is_empty());
    }
}
