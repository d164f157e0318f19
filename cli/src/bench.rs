//! `funcorr bench` (a data set through the Princeton protocol) and `funcorr reproduce` (the
//! paper's Figures 5, 6 and 7): argument parsing, progress and printing over
//! [`funcorr::benchmark`] and [`funcorr::experiments`].
//!
//! One file for both commands (≈ 610 lines): `reproduce benchmark` is `bench` run twice with the
//! paper's settings, and both share the pair selection, thread pool, progress bar and staged
//! output of this file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use funcorr::benchmark::{self, BenchMethod, BenchOptions, Dataset, Report};
use funcorr::completion::Form;
use funcorr::descriptors::spec::PairDataSpec;
use funcorr::experiments::{run_sweep, Sterile, Sweep, SweepRow, SweepSettings};
use funcorr::io::staged::StagedDir;
use funcorr::{Error, Result};

use crate::args::{CacheArgs, GeodesicsChoice, MethodChoice, PipelineArgs, ScalingChoice};
use crate::options::{settings, Flags};

/// Arguments of `funcorr bench`.
#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Data set directory: shapes NAME.off (.obj, .ply), corres/NAME.vts and NAME.sym.vts,
    /// pairs.txt, segmentation/A_B.S.seg.sym (the layout of ../shared/data).
    #[arg(long)]
    dataset: PathBuf,
    /// Pairs to run (two shape names per line; default DATASET/pairs.txt).
    #[arg(long)]
    pairs: Option<PathBuf>,
    /// Run only the first N pairs.
    #[arg(long)]
    limit: Option<usize>,
    /// Methods, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "fmap,pokrass,coupled,completion")]
    methods: Vec<MethodChoice>,
    /// Data functions: `segments` (the data set's segmentation, .seg.sym; `segments:nonsym` for
    /// .seg.nonsym), `wks:N` (`wks` alone: 100 energies from the first 128 eigenpairs, every 2nd
    /// kept), `rich` (100 WKS + 100 heat kernel maps
    /// localized on the segments),
    /// or `landmarks:N` (delta functions at N ground-truth landmarks); also the per-shape forms
    /// of `funcorr match --data` that name no file (`hks:N`, `wks+hks:N`, `persistence`, `mser`).
    #[arg(long, default_value = "segments")]
    data: String,
    /// Do not allow symmetric flips (default: allowed, with corres/NAME.sym.vts, as the paper).
    #[arg(long)]
    no_symmetric: bool,
    /// Geodesic distances on Y for the errors.
    #[arg(long, value_enum, default_value = "exact")]
    geodesics: GeodesicsChoice,
    /// Pairs run at once (default: one per core).
    #[arg(long)]
    jobs: Option<usize>,
    /// Title of the plot and the table.
    #[arg(long)]
    title: Option<String>,
    #[command(flatten)]
    pipe: PipelineArgs,
    #[command(flatten)]
    cache: CacheArgs,
    #[command(flatten)]
    html: HtmlArgs,
    /// Output directory: pairs.csv, pairs.json, maps/, summary.csv, summary.md, summary.json,
    /// curves.png, index.html (with pairs/ and viewer/).
    #[arg(short, long)]
    output: PathBuf,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

/// The HTML report of a run: index.html and viewer pages.
#[derive(clap::Args)]
pub(crate) struct HtmlArgs {
    /// Viewer pages linked from index.html: `N` for the N runs of each method with the largest
    /// mean error, or `all` (every pair and method).
    #[arg(long, default_value = "10", value_name = "N|all")]
    html: String,
    /// Do not write index.html and its viewer pages.
    #[arg(long)]
    no_html: bool,
}

impl HtmlArgs {
    /// Which pages to write (None: no HTML report); errors name `--html`.
    fn pages(&self) -> Result<Option<funcorr::viz::report::Pages>> {
        if self.no_html {
            return Ok(None);
        }
        self.html.parse().map(Some).map_err(|e| match e {
            Error::Invalid { msg, .. } => Error::invalid("--html", msg),
            e => e,
        })
    }
}

fn method_name(m: MethodChoice) -> &'static str {
    match m {
        MethodChoice::Axiomatic => "axiomatic",
        MethodChoice::Fmap => "fmap",
        MethodChoice::Pokrass => "pokrass",
        MethodChoice::Coupled => "coupled",
        MethodChoice::Completion => "completion",
    }
}

/// A progress bar for [`benchmark::run`] (hidden when quiet).
fn stage_bar(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} {pos}/{len} [{bar:30}] {elapsed} (eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb
}

/// Runs `methods` with `data` on the pairs and returns the report (with a progress bar).
#[allow(clippy::too_many_arguments)]
fn run_benchmark(
    ds: &Dataset,
    pairs: &[(String, String)],
    methods: &[MethodChoice],
    data: PairDataSpec,
    options: &dyn Fn(MethodChoice, bool) -> Result<funcorr::matching::MatchOptions>,
    eigenpairs: Option<&dyn Fn(MethodChoice, bool) -> Result<usize>>,
    symmetric: bool,
    geodesics: GeodesicsChoice,
    cache: &CacheArgs,
    quiet: bool,
) -> Result<Report> {
    let is_rich = data.is_rich();
    let eigenpairs = match eigenpairs {
        Some(f) => {
            Some(methods.iter().map(|&m| f(m, is_rich)).collect::<Result<Vec<_>>>()?.into_iter().max().unwrap_or(0))
        }
        None => None,
    };
    let methods = methods
        .iter()
        .map(|&m| Ok(BenchMethod { name: method_name(m).to_string(), options: options(m, is_rich)? }))
        .collect::<Result<Vec<_>>>()?;
    let opts = BenchOptions { data, methods, symmetric, geodesics: geodesics.into(), cache: cache.cache(), eigenpairs };
    let pb = stage_bar(quiet);
    let progress = |stage: &str, done: usize, total: usize| {
        if done == 0 {
            pb.set_message(if stage == "shapes" { "shapes (eigenbases)" } else { "pairs" });
            pb.set_length(total as u64);
            pb.reset();
        }
        pb.set_position(done as u64);
    };
    let report = benchmark::run(ds, pairs, &opts, Some(&progress));
    pb.finish_and_clear();
    report
}

fn thread_pool(jobs: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(j) = jobs {
        if j == 0 || j > 1024 {
            return Err(Error::invalid("--jobs", format!("{j}: expected 1..=1024")));
        }
        b = b.num_threads(j);
    }
    b.build().map_err(|e| Error::invalid("--jobs", e.to_string()))
}

fn select_pairs(ds: &Dataset, file: Option<&Path>, limit: Option<usize>) -> Result<Vec<(String, String)>> {
    let mut pairs = ds.pairs(file)?;
    if let Some(l) = limit {
        if l == 0 {
            return Err(Error::invalid("--limit", "must be at least 1"));
        }
        pairs.truncate(l);
    }
    Ok(pairs)
}

/// The run's tables, JSON and maps ([`Report::write`]), its curves
/// ([`funcorr::viz::plot::write_benchmark_curves`]) and, unless `pages` is None, its HTML report
/// with viewer pages ([`funcorr::viz::report::write_html_report`]) in `dir`; the paths written.
fn write_report(
    report: &Report,
    ds: &Dataset,
    dir: &Path,
    title: &str,
    pages: Option<funcorr::viz::report::Pages>,
) -> Result<Vec<PathBuf>> {
    let mut written = report.write(dir, title)?;
    written.extend(funcorr::viz::plot::write_benchmark_curves(report, dir, title)?);
    if let Some(pages) = pages {
        written.extend(funcorr::viz::report::write_html_report(report, ds, dir, title, pages)?);
    }
    Ok(written)
}

fn publish(staged: StagedDir, paths: &[PathBuf]) -> Result<()> {
    let finals: Vec<PathBuf> = paths.iter().map(|p| staged.published_path(p)).collect();
    staged.publish()?;
    for p in finals {
        outln!("wrote {}", p.display());
    }
    Ok(())
}

pub(crate) fn bench(args: &BenchArgs) -> Result<()> {
    let data = args.data.parse::<PairDataSpec>()?.for_dataset()?;
    let pages = args.html.pages()?;
    let ds = Dataset::open(&args.dataset)?;
    let pairs = select_pairs(&ds, args.pairs.as_deref(), args.limit)?;
    let pool = thread_pool(args.jobs)?;
    // Checked writable before any work (published at the end, removed on failure).
    let staged = StagedDir::create(&args.output)?;
    let report = pool.install(|| {
        run_benchmark(
            &ds,
            &pairs,
            &args.methods,
            data.clone(),
            &|m, rich| settings(&args.pipe, m)?.resolve_as(rich, &Flags),
            // The eigenpairs `funcorr match` computes for the same options, so that the maps are
            // the ones `match` makes.
            Some(&|m, rich| {
                let s = settings(&args.pipe, m)?;
                Ok(s.basis_demand(&s.resolve_as(rich, &Flags)?, &Flags)?.size)
            }),
            !args.no_symmetric,
            args.geodesics,
            &args.cache,
            args.quiet,
        )
    })?;
    let title = args.title.clone().unwrap_or_else(|| {
        format!(
            "{}: {} pairs, data {data}{}",
            ds.dir().file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default(),
            pairs.len(),
            if report.symmetric { ", symmetric" } else { "" }
        )
    });
    let written = write_report(&report, &ds, staged.path(), &title, pages).map_err(|e| staged.attribute(e))?;
    outln!("{title} (hard error, {} geodesics; {:.1} s)\n", report.geodesics.name(), report.wall_seconds);
    outln!("{}", report.table());
    for r in report.runs.iter().filter(|r| r.outcome.is_err()) {
        eprintln!("funcorr: {} → {} ({}): {}", r.source, r.target, r.method, r.outcome.as_ref().unwrap_err());
    }
    publish(staged, &written)
}

/// What `funcorr reproduce` runs.
#[derive(clap::Subcommand)]
pub(crate) enum ReproduceWhat {
    /// Figure 5: soft error (13) vs the rank k for the completion method (11) in the fixed-rank
    /// regime (μ4 = 0), Ovsjanikov et al. (5) and Pokrass et al. (6), with q ideal corresponding
    /// functions on a near-isometric pair. Writes rank.csv, rank.json and rank.png.
    Rank(RankArgs),
    /// Figure 6: soft error (13) vs the L1 weight μ3 at fixed k. Writes l1.csv, l1.json, l1.png.
    L1(L1Args),
    /// Figure 7: the Princeton protocol (hard error, symmetric flips) on data set pairs in the
    /// scarce (segments) and rich (localized WKS + HKM) settings, ICP refinement as in the
    /// paper. Writes scarce/ and rich/ (as `funcorr bench`), benchmark.md and benchmark.png
    /// (solid: rich, dashed: scarce).
    Benchmark(ReproBenchArgs),
}

/// The sterile setting of Figures 5 and 6.
#[derive(clap::Args)]
pub(crate) struct SterileArgs {
    /// Data set directory.
    #[arg(long, default_value = "../shared/data/faust_r")]
    dataset: PathBuf,
    /// The near-isometric pair X,Y (same subject, different poses).
    #[arg(long, default_value = "tr_reg_000,tr_reg_001")]
    pair: String,
    /// Number q of ideal corresponding functions.
    #[arg(long, default_value_t = 50)]
    q: usize,
    /// Subspace size k' of the completion method (and the eigenpairs per shape).
    #[arg(long, default_value_t = 350)]
    kprime: usize,
    /// Template points at which the soft error is evaluated (evenly spaced).
    #[arg(long, default_value_t = 250)]
    samples: usize,
    /// Weight normalization of the completion method: `unit` (default) reads the paper's weights
    /// in scale-free units, `paper` takes them literally on the mass-orthonormal bases (where the
    /// L1 term dominates; EXPERIMENTS.md has both).
    #[arg(long, value_enum, default_value = "unit")]
    scaling: ScalingChoice,
    /// μ1 (default: the paper's value for the figure).
    #[arg(long)]
    mu1: Option<f64>,
    /// μ2 (default: the paper's value for the figure).
    #[arg(long)]
    mu2: Option<f64>,
    /// ξ of the smoothed absolute value.
    #[arg(long, default_value_t = 1e-3)]
    xi: f64,
    /// Isometry prior added to (11) (0: the paper's pure form).
    #[arg(long, default_value_t = 0.0)]
    completion_commutativity: f64,
    /// Iteration cap of the completion optimizer (L-BFGS).
    #[arg(long, default_value_t = 300)]
    max_iterations: usize,
    /// Size of the eq. (5) map starting the completion method (capped at q).
    #[arg(long, default_value_t = 50)]
    init_k: usize,
    /// Weight μ of the off-diagonal L1 prior of Pokrass et al.
    #[arg(long, default_value_t = 1e-3)]
    pokrass_mu: f64,
    /// Geodesic distances on Y.
    #[arg(long, value_enum, default_value = "exact")]
    geodesics: GeodesicsChoice,
    #[command(flatten)]
    cache: CacheArgs,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
}

#[derive(clap::Args)]
pub(crate) struct RankArgs {
    #[command(flatten)]
    common: SterileArgs,
    /// The ranks k.
    #[arg(long, value_delimiter = ',', default_value = "10,20,30,40,50,60,80,100,150")]
    ks: Vec<usize>,
    /// L1 weight μ3 (the paper's 1e-1).
    #[arg(long, default_value_t = 1e-1)]
    mu3: f64,
}

#[derive(clap::Args)]
pub(crate) struct L1Args {
    #[command(flatten)]
    common: SterileArgs,
    /// The L1 weights μ3 (0 is drawn at the left end of the log axis).
    #[arg(long, value_delimiter = ',', default_value = "0,1e-4,1e-3,1e-2,1e-1,1")]
    mu3s: Vec<f64>,
    /// The rank k (the paper's 45).
    #[arg(short, default_value_t = 45)]
    k: usize,
}

#[derive(clap::Args)]
pub(crate) struct ReproBenchArgs {
    /// Data set directory.
    #[arg(long, default_value = "../shared/data/faust_r")]
    dataset: PathBuf,
    /// Pairs (default DATASET/pairs.txt).
    #[arg(long)]
    pairs: Option<PathBuf>,
    /// Run only the first N pairs.
    #[arg(long)]
    limit: Option<usize>,
    /// Methods, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "fmap,pokrass,completion")]
    methods: Vec<MethodChoice>,
    /// Iteration cap of the completion optimizer.
    #[arg(long, default_value_t = crate::args::defaults().completion.optimize.max_iterations)]
    max_iterations: usize,
    /// The paper's weights taken literally (`paper`) or scale-free (`unit`, funcorr's default).
    #[arg(long, value_enum, default_value = "unit")]
    scaling: ScalingChoice,
    /// Isometry prior of the completion method (funcorr's default 1e-2; 0: the paper's (11)).
    #[arg(long, default_value_t = 1e-2)]
    completion_commutativity: f64,
    /// Evaluate the completion method's L1 term on this many farthest-point samples of each
    /// shape (0: on every pair of vertices, as the paper). Default: 1000 with the unit scaling,
    /// 0 with `--scaling paper`.
    #[arg(long)]
    l1_samples: Option<usize>,
    /// Arithmetic of the products of the completion method's L1 term (f64: as the paper).
    /// Default: f32.
    #[arg(long, value_enum)]
    l1_precision: Option<crate::args::PrecisionChoice>,
    /// The same as --l1-precision f32 (kept for scripts written before f32 became the default).
    #[arg(long, hide = true, conflicts_with = "l1_precision")]
    l1_f32: bool,
    /// Preconditioner of the completion method's L-BFGS (subspace form).
    #[arg(long, value_enum, default_value = "off")]
    precondition: crate::args::PreconditionChoice,
    /// Continuation in ξ of the completion method: this many stages ξ·10^(N−1), …, ξ, sharing the
    /// iteration cap (0 or 1: off).
    #[arg(long, default_value_t = 0)]
    xi_stages: usize,
    /// Multiscale schedule of the completion method: this many stages of growing k' and k,
    /// sharing the iteration cap (0 or 1: off, as the paper). Default: 2.
    #[arg(long)]
    multiscale: Option<usize>,
    /// Also stop the completion optimizer when its point map has settled: check every this many
    /// iterations (0: off).
    #[arg(long, default_value_t = 0)]
    map_check_every: usize,
    /// Fraction of the checked vertices whose image may change between two checks.
    #[arg(long, default_value_t = 0.005)]
    map_tolerance: f64,
    /// Pairs run at once (default: one per core).
    #[arg(long)]
    jobs: Option<usize>,
    #[command(flatten)]
    cache: CacheArgs,
    #[command(flatten)]
    html: HtmlArgs,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

pub(crate) fn reproduce(what: &ReproduceWhat) -> Result<()> {
    match what {
        ReproduceWhat::Rank(a) => sweep(&a.common, Sweep::Rank { ks: a.ks.clone(), mu3: a.mu3 }),
        ReproduceWhat::L1(a) => sweep(&a.common, Sweep::L1 { mu3s: a.mu3s.clone(), k: a.k }),
        ReproduceWhat::Benchmark(a) => figure7(a),
    }
}

impl SterileArgs {
    fn settings(&self) -> SweepSettings {
        SweepSettings {
            kprime: self.kprime,
            scaling: self.scaling.into(),
            mu1: self.mu1,
            mu2: self.mu2,
            xi: self.xi,
            completion_commutativity: self.completion_commutativity,
            max_iterations: self.max_iterations,
            init_k: self.init_k,
            pokrass_mu: self.pokrass_mu,
        }
    }
}

fn sweep(a: &SterileArgs, what: Sweep) -> Result<()> {
    let (xname, yname) =
        a.pair.split_once(',').ok_or_else(|| Error::invalid("--pair", format!("{:?}: expected X,Y", a.pair)))?;
    let settings = a.settings();
    // Check the sweep before the (slow) setup.
    funcorr::experiments::sweep::sweep_jobs(&what, a.kprime).map_err(|e| flag_error(e, &what))?;
    let ds = Dataset::open(&a.dataset)?;
    // Checked writable before the setup (published at the end, removed on failure).
    let staged = StagedDir::create(&a.output)?;
    let prepare = |name: &str| {
        let t = Instant::now();
        let s = benchmark::prepare_shape(&ds, name, a.kprime, a.cache.cache().as_ref());
        if !a.quiet {
            eprintln!("funcorr: {name}: mesh and {} eigenpairs in {:.1} s", a.kprime, t.elapsed().as_secs_f64());
        }
        s
    };
    let (x, y) = (prepare(xname)?, prepare(yname)?);
    let gt = ds.ground_truth(xname, yname, x.mesh().n_vertices(), y.mesh().n_vertices(), false)?;
    let t = Instant::now();
    let setup = Sterile::new(x.mesh(), x.basis(), y.mesh(), y.basis(), &gt, a.q, a.samples, a.geodesics.into())?;
    if !a.quiet {
        eprintln!(
            "funcorr: ideal data q = {} and distances from {} template points in {:.1} s",
            a.q,
            setup.sample.x.len(),
            t.elapsed().as_secs_f64()
        );
    }
    let mut progress = |r: &SweepRow| {
        if !a.quiet {
            let extra =
                r.permutation_correct.map(|p| format!(", permutation {:.0}% right", 100.0 * p)).unwrap_or_default();
            eprintln!(
                "funcorr: {:<12} k {:>4} μ3 {:<8.1e} soft error ×100 {:>7.3}  ({:.1} s{extra})",
                r.method.as_str(),
                r.k,
                r.mu3.unwrap_or(0.0),
                100.0 * r.mean_soft_error,
                r.seconds
            );
        }
    };
    let rows = run_sweep(&setup, &what, &settings, &mut progress)?;
    write_sweep(a, staged, &what, &rows)
}

/// A library error about the sweep's parameters, named by its flag.
fn flag_error(e: Error, what: &Sweep) -> Error {
    match e {
        Error::Invalid { what: parameter, msg } => {
            let flag = match (parameter.as_str(), what) {
                ("ks", _) => "--ks",
                ("mu3s", _) => "--mu3s",
                ("k", Sweep::L1 { .. }) => "-k",
                _ => return Error::Invalid { what: parameter, msg },
            };
            Error::invalid(flag, msg)
        }
        e => e,
    }
}

fn write_sweep(a: &SterileArgs, staged: StagedDir, what: &Sweep, rows: &[SweepRow]) -> Result<()> {
    let written = write_sweep_into(a, &staged, what, rows).map_err(|e| staged.attribute(e))?;
    publish(staged, &written)
}

/// The sweep's table, JSON and plot, written into the staging directory; the paths written.
fn write_sweep_into(a: &SterileArgs, staged: &StagedDir, what: &Sweep, rows: &[SweepRow]) -> Result<Vec<PathBuf>> {
    let name = what.name();
    let write = |file: String, text: String| -> Result<PathBuf> {
        let p = staged.join(file);
        funcorr::io::write_atomic(&p, text)?;
        Ok(p)
    };
    let mut csv = String::from("method,k,mu3,mean_soft_error_x100,seconds,iterations\n");
    for r in rows {
        csv += &format!(
            "{},{},{},{:.4},{:.2},{}\n",
            r.method,
            r.k,
            r.mu3.map(|m| format!("{m:e}")).unwrap_or_default(),
            100.0 * r.mean_soft_error,
            r.seconds,
            r.iterations.map(|i| i.to_string()).unwrap_or_default()
        );
    }
    #[derive(serde::Serialize)]
    struct Settings<'a> {
        dataset: &'a Path,
        pair: &'a str,
        q: usize,
        samples: usize,
        #[serde(flatten)]
        sweep: SweepSettings,
    }
    #[derive(serde::Serialize)]
    struct SweepFile<'a> {
        settings: Settings<'a>,
        rows: &'a [SweepRow],
    }
    let file = SweepFile {
        settings: Settings { dataset: &a.dataset, pair: &a.pair, q: a.q, samples: a.samples, sweep: a.settings() },
        rows,
    };
    let mut written =
        vec![write(format!("{name}.csv"), csv)?, write(format!("{name}.json"), funcorr::io::to_json_sorted(&file)?)?];
    let png = staged.join(format!("{name}.png"));
    funcorr::viz::plot::sweep_plot(what, rows, &a.pair.replace(',', " → "), a.q).write_png(&png, 900, 600)?;
    written.push(png);
    outln!("{:<12} {:>5} {:>9} {:>16} {:>9}", "method", "k", "μ3", "soft error ×100", "seconds");
    for r in rows {
        let mu3 = r.mu3.map(|m| format!("{m:.0e}")).unwrap_or_else(|| "–".into());
        outln!(
            "{:<12} {:>5} {:>9} {:>16.3} {:>9.1}",
            r.method.as_str(),
            r.k,
            mu3,
            100.0 * r.mean_soft_error,
            r.seconds
        );
    }
    Ok(written)
}

fn figure7(a: &ReproBenchArgs) -> Result<()> {
    let pages = a.html.pages()?;
    let ds = Dataset::open(&a.dataset)?;
    let pairs = select_pairs(&ds, a.pairs.as_deref(), a.limit)?;
    let pool = thread_pool(a.jobs)?;
    let mut all = Vec::new();
    let mut table = String::new();
    let mut written = Vec::new();
    let staged = StagedDir::create(&a.output)?;
    for (setting, data) in
        [("scarce", PairDataSpec::DatasetSegments { symmetric: true }), ("rich", PairDataSpec::Rich(None))]
    {
        // The paper's settings: k' = 350, k = 250 (scarce) and k' = 50, k = 30 (rich) for the
        // completion method, k for the baselines the same, ICP refinement.
        let options = |m: MethodChoice, rich: bool| -> Result<funcorr::matching::MatchOptions> {
            let mut o = funcorr::matching::MatchOptions::for_method(m.into(), rich);
            o.refine = funcorr::matching::Refine::Icp;
            o.completion = funcorr::matching::completion_defaults(rich, a.scaling.into(), Form::Subspace);
            o.completion.params.mu_comm = a.completion_commutativity;
            o.completion.optimize.max_iterations = a.max_iterations;
            if let Some(samples) = a.l1_samples {
                o.completion.l1_sampling = funcorr::completion::L1Sampling::farthest(samples);
            }
            o.completion.params.l1_precision =
                crate::args::l1_precision(a.l1_precision, a.l1_f32, o.completion.params.l1_precision);
            o.completion.precondition = a.precondition.into();
            o.completion.xi_stages = a.xi_stages;
            if let Some(stages) = a.multiscale {
                o.completion.multiscale = stages;
            }
            // The map the refinement starts from: the leading refine_k block of C.
            o.completion.settled =
                funcorr::matching::options::settled_map(a.map_check_every, a.map_tolerance, o.refine_k, &Flags)?;
            Ok(o)
        };
        let report = pool.install(|| {
            run_benchmark(
                &ds,
                &pairs,
                &a.methods,
                data.clone(),
                &options,
                None,
                true,
                GeodesicsChoice::Exact,
                &a.cache,
                a.quiet,
            )
        })?;
        let title = format!("{setting} data ({data}), {} pairs", pairs.len());
        written
            .extend(write_report(&report, &ds, &staged.join(setting), &title, pages).map_err(|e| staged.attribute(e))?);
        table += &format!("## {title}\n\n{}\n", report.table());
        all.push((setting, setting == "scarce", report.summaries()));
    }
    let title = format!("Figure 7: {} pairs of {}, symmetric, ICP", pairs.len(), a.dataset.display());
    let png = staged.join("benchmark.png");
    let settings: Vec<(&str, bool, &[benchmark::MethodSummary])> =
        all.iter().map(|(s, dashed, m)| (*s, *dashed, m.as_slice())).collect();
    funcorr::viz::plot::figure7_curves(&title, &settings).write_png(&png, 900, 640).map_err(|e| staged.attribute(e))?;
    let md = staged.join("benchmark.md");
    funcorr::io::write_atomic(&md, format!("# {title}\n\n{table}")).map_err(|e| staged.attribute(e))?;
    written.extend([png, md]);
    if pages.is_some() {
        let index = staged.join("index.html");
        let html = funcorr::viz::report::settings_index_html(&title, &settings, "benchmark.png");
        funcorr::io::write_atomic(&index, html).map_err(|e| staged.attribute(e))?;
        written.push(index);
    }
    outln!("{title}\n\n{table}");
    publish(staged, &written)
}
