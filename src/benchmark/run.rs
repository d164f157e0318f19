//! Running the methods on the pairs: one pair ([`run_pair`]) and the whole data set ([`run`]).

#[allow(unused_imports)]
use super::*;

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
    pub data: PairDataSpec,
    /// The methods, run one after the other on each pair.
    pub methods: Vec<BenchMethod>,
    /// Allow symmetric flips (needs `corres/NAME.sym.vts`).
    pub symmetric: bool,
    /// Geodesic distances on Y for the errors.
    pub geodesics: GeodesicMethod,
    /// Cache of eigenbases (None: compute every time).
    pub cache: Option<BasisCache>,
    /// Eigenpairs computed per shape: at least what every method needs (its
    /// [`MatchOptions::basis_size`]); a front end gives the number its `match` command computes
    /// for the same options (e.g. `MatchSettings::basis_demand`) so that the bench runs exactly
    /// the maps `match` makes (e.g. 200 where X may be a part or the data read the whole basis,
    /// more than the axiomatic method's own 128). None: what the methods need.
    pub eigenpairs: Option<usize>,
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
    /// The solver's report (iterations, objective history, terms) of the methods that iterate.
    pub solver: Option<crate::matching::SolverReport>,
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
    let (f, g) = match pair_data(ds, x, y, &gt, &opts.data) {
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
                // As `funcorr match`: a part of Y (detected, or the method's partial option)
                // with the default WKS gets them at the same energies on both shapes.
                let mut options = method.options.clone();
                let pair = matching::partial::partial_pair_data(&x.prepared, &y.prepared, &opts.data, &mut options)?;
                let (f, g) = match &pair {
                    Some((fp, gp)) => (fp, gp),
                    None => (&f, &g),
                };
                let r = matching::run(&x.prepared, &y.prepared, f, g, &options)?;
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
                    solver: r.solver,
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
        return Err(Error::invalid("methods", "no method given"));
    }
    let mut seen = BTreeSet::new();
    for m in &opts.methods {
        let ok = !m.name.is_empty() && m.name.chars().all(|c| c.is_ascii_alphanumeric() || "-_+.=".contains(c));
        if !ok || !seen.insert(m.name.clone()) {
            return Err(Error::invalid(
                "methods",
                format!("method name {:?} is empty, repeated or unfit for a file name", m.name),
            ));
        }
    }
    if pairs.is_empty() {
        return Err(Error::invalid("pairs", "no pairs to run"));
    }
    let k = opts.methods.iter().map(|m| m.options.basis_size()).max().unwrap_or(1).max(opts.eigenpairs.unwrap_or(0));
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
        data: opts.data.clone(),
        symmetric: opts.symmetric,
        geodesics: opts.geodesics,
        methods: opts.methods.iter().map(|m| m.name.clone()).collect(),
        runs: runs.into_iter().flatten().collect(),
        shape_seconds: shapes.iter().map(|(n, s)| (n.clone(), s.seconds)).collect(),
        k,
        wall_seconds: wall.elapsed().as_secs_f64(),
    })
}
