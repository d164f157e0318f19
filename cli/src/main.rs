//! The `funcorr` command-line tool: a thin layer over the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};

use funcorr::io::npy::{write_npz, NpzArray};
use funcorr::laplacian::{self, Bandwidth, KnnOptions, Laplacian, VertexWeights};
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{self, Basis, BasisCache, SpectralOptions};
use funcorr::{Error, Result};

/// Dense shape correspondence with functional maps (Kovnatsky et al., CVPR 2015).
#[derive(Parser)]
#[command(name = "funcorr", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print facts about a shape: vertices, faces, area, components, boundary loops,
    /// degenerate faces.
    Info {
        /// Shape file: OFF, OBJ, PLY, XYZ/CSV/TXT/PTS point list, or NPY (n×3 points, n×d features).
        shape: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compute the first k Laplacian eigenpairs W φ = λ A φ and write them as .npz
    /// (arrays eigenvalues [k], eigenvectors [n×k], mass [n], residuals [k]).
    Spectrum(SpectrumArgs),
    /// Compute data functions F (n × q) on a shape and write them as .npy: landmark deltas,
    /// HKS, WKS, heat kernel maps, segment indicators, localized descriptors, or a given matrix.
    Descriptors(DescriptorArgs),
    /// Corresponding region indicators F (n × s) and G (m × s) for two shapes: segments from
    /// label files, persistence segments or ShapeMSER regions, matched by their signatures.
    /// Writes OUTDIR/F.npy, OUTDIR/G.npy and OUTDIR/matches.json.
    Regions(RegionArgs),
    /// Match X to Y: data functions on both shapes, a functional map, a point-to-point map.
    /// Writes OUTDIR/map.txt (for every vertex of X its vertex on Y), map.npy, C.npy and
    /// report.json.
    Match(MatchArgs),
    /// Evaluate a point-to-point map X → Y against ground-truth template correspondences
    /// (.vts files) with the Princeton protocol: geodesic errors on Y / √area(Y).
    Eval(EvalArgs),
    /// Run methods on the pairs of a data set (the Princeton protocol: hard error (12), symmetric
    /// flips allowed) and write per-pair CSV/JSON, maps, a summary table and a plot of the
    /// cumulative error curves (one line per method).
    Bench(bench_cli::BenchArgs),
    /// Reproduce the paper's experiments: `rank` (Figure 5), `l1` (Figure 6), `benchmark`
    /// (Figure 7); each writes its table, JSON and plot.
    Reproduce {
        #[command(subcommand)]
        what: bench_cli::ReproduceWhat,
    },
    /// Run the default pipeline on a pair of bundled FAUST shapes and write results to
    /// ./funcorr-demo/.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "funcorr-demo")]
        out: PathBuf,
        /// Number of eigenpairs.
        #[arg(short, default_value_t = 100)]
        k: usize,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum LaplacianChoice {
    /// Cotangent weights with barycentric lumped mass (paper eq. (2)); meshes only. Default for meshes.
    Cotan,
    /// The point-cloud Laplacian of local Delaunay triangulations of --cloud-neighbours nearest
    /// neighbours (Sharp & Crane 2020): spectrum and mass agree with the cotangent Laplacian of
    /// the sampled surface. 3-D points (a mesh is used as its vertices). Default for 3-D point sets.
    Cloud,
    /// Symmetric K-nearest-neighbour graph with Gaussian weights (paper eq. (1)); any shape
    /// (a mesh is used as its point cloud). Default for point sets of other dimensions.
    Knn,
}

#[derive(Clone, Copy, ValueEnum)]
enum WeightsChoice {
    /// A = I: unnormalized graph Laplacian.
    Identity,
    /// A = D: random-walk Laplacian.
    Degree,
}

/// How to build the Laplacian of a shape.
#[derive(clap::Args)]
struct LaplacianArgs {
    /// Laplacian discretization (default: cotan for meshes, cloud for 3-D point sets, knn for
    /// other point sets).
    #[arg(long, value_enum)]
    laplacian: Option<LaplacianChoice>,
    /// Neighbours of the point-cloud Laplacian's local triangulations.
    #[arg(long, default_value_t = funcorr::cloud::DEFAULT_NEIGHBOURS)]
    cloud_neighbours: usize,
    /// Number of neighbours K of the kNN graph.
    #[arg(long = "knn", default_value_t = 10)]
    knn_k: usize,
    /// Vertex weights of the kNN graph Laplacian.
    #[arg(long, value_enum, default_value = "identity")]
    vertex_weights: WeightsChoice,
    /// Fixed Gaussian bandwidth σ of the kNN weights, in coordinate units
    /// (default: self-tuning, σᵢ = distance to the K-th neighbour).
    #[arg(long)]
    sigma: Option<f64>,
}

/// Where eigenbases are cached.
#[derive(clap::Args)]
struct CacheArgs {
    /// Do not read or write the basis cache.
    #[arg(long)]
    no_cache: bool,
    /// Cache directory (default: $FUNCORR_CACHE_DIR, $XDG_CACHE_HOME/funcorr or ~/.cache/funcorr).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
}

impl CacheArgs {
    fn cache(&self) -> Option<BasisCache> {
        if self.no_cache {
            None
        } else {
            self.cache_dir.clone().or_else(BasisCache::default_dir).map(BasisCache::new)
        }
    }
}

#[derive(clap::Args)]
struct SpectrumArgs {
    /// Shape file (see `funcorr info --help` for formats).
    shape: PathBuf,
    /// Number of eigenpairs k (1 ≤ k < n; the paper uses up to k' = 350).
    #[arg(short)]
    k: usize,
    /// Output .npz file. Without it, the eigenvalues are printed to stdout, one per line.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    lap: LaplacianArgs,
    /// Convergence tolerance on the relative residual ‖Wφ − λAφ‖_{A⁻¹} / λ_k of every pair.
    #[arg(long, default_value_t = 1e-8)]
    tol: f64,
    /// Lanczos block size (default: 4 for k ≤ 120, 8 for k ≤ 250, else 16).
    #[arg(long)]
    block_size: Option<usize>,
    /// Seed of the random start block.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[command(flatten)]
    cache: CacheArgs,
    /// Also write W (CSC arrays W_data, W_indices, W_indptr, W_shape) and the mass to this .npz,
    /// e.g. to compare with scipy.
    #[arg(long)]
    save_laplacian: Option<PathBuf>,
    /// No progress bar or timings on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum DescriptorKind {
    /// Delta functions at landmark vertices (--landmarks, one column per pair).
    Landmarks,
    /// Heat kernel signature (Sun et al. 2009), --count log-spaced times.
    Hks,
    /// Wave kernel signature (Aubry et al. 2011), --count log-energies.
    Wks,
    /// Heat kernel maps (Ovsjanikov et al. 2010) from the --seeds vertices at --times times.
    Hkm,
    /// Indicator functions of the segments in --labels (one column per label).
    Segments,
    /// Indicators of the segments of a persistence-based segmentation (Skraba et al. 2010) of
    /// --function (default: HKS at t = --hks-time/λ₁) with persistence threshold --threshold.
    Persistence,
    /// Indicators of the maximally stable regions of the heat kernel diagonal (ShapeMSER,
    /// Litman et al. 2011); meshes only.
    Mser,
    /// WKS (and HKM when --seeds is given) multiplied by the indicators of the --labels segments
    /// (or, without --labels, of the persistence segments).
    Localized,
    /// A given n × q matrix (--matrix .npy or .csv), checked and passed through.
    Matrix,
}

#[derive(Clone, Copy, ValueEnum)]
enum Side2 {
    /// First column of the landmark file (the source shape X).
    Source,
    /// Second column (the target shape Y).
    Target,
}

#[derive(clap::Args)]
struct DescriptorArgs {
    /// Shape file (see `funcorr info --help` for formats).
    shape: PathBuf,
    /// Which functions to compute.
    #[arg(long, value_enum)]
    kind: DescriptorKind,
    /// Output .npy file (n × q, f64).
    #[arg(short, long)]
    output: PathBuf,
    /// Also write the q column names, one per line, to this file.
    #[arg(long)]
    names: Option<PathBuf>,
    /// Number of HKS times or WKS energies.
    #[arg(long, default_value_t = 100)]
    count: usize,
    /// Keep the raw signatures (default: scale-normalized, area-weighted mean 1 per column).
    #[arg(long)]
    no_normalize: bool,
    /// Landmark pairs file: two vertex indices per line, `i j` (X vertex, Y vertex).
    #[arg(long)]
    landmarks: Option<PathBuf>,
    /// Which column of the landmark file belongs to this shape.
    #[arg(long, value_enum, default_value = "source")]
    side: Side2,
    /// Vertex indices in --landmarks / --seeds files are 1-based (MATLAB).
    #[arg(long)]
    one_based: bool,
    /// Seed vertices of heat kernel maps: one vertex index per line.
    #[arg(long)]
    seeds: Option<PathBuf>,
    /// Number of heat kernel map times (log-spaced over the HKS range).
    #[arg(long, default_value_t = 5)]
    times: usize,
    /// Per-vertex segment labels: one integer per line, one line per vertex.
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Data matrix (.npy or .csv), n rows.
    #[arg(long)]
    matrix: Option<PathBuf>,
    #[command(flatten)]
    seg: SegmentationArgs,
    /// Also write the per-vertex segment labels (1-based, one per line) of --kind persistence.
    #[arg(long)]
    write_labels: Option<PathBuf>,
    /// Number of eigenpairs of the basis the signatures are computed from.
    #[arg(short, default_value_t = 100)]
    k: usize,
    /// Use this basis file (from `funcorr spectrum`) instead of computing one.
    #[arg(long)]
    basis: Option<PathBuf>,
    #[command(flatten)]
    lap: LaplacianArgs,
    #[command(flatten)]
    cache: CacheArgs,
    /// No progress bar or timings on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Refine {
    /// The method's own point map (nearest neighbours in the spectral embedding).
    None,
    /// The ICP refinement of Ovsjanikov et al. 2012 (orthonormal C).
    Icp,
    /// ZoomOut (Melzi et al. 2019) up to --zoomout-to eigenpairs.
    Zoomout,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum MethodChoice {
    /// The orientation-aware axiomatic functional map (descriptor preservation, resolvent
    /// Laplacian commutativity, descriptor commutativity, orientation; signed descriptors),
    /// the best of several sizes after ZoomOut, refined by ZoomOut. The default.
    Axiomatic,
    /// Ovsjanikov et al. 2012, eq. (5) (least squares, optional Laplacian commutativity).
    Fmap,
    /// Pokrass et al. 2013, eq. (6) (permuted sparse coding).
    Pokrass,
    /// Kovnatsky et al. 2013, eq. (7) (coupled quasi-harmonic bases).
    Coupled,
    /// Kovnatsky et al. 2015, eqs. (8)–(11) (matrix completion; see --form).
    Completion,
}

impl From<MethodChoice> for funcorr::matching::Method {
    fn from(m: MethodChoice) -> Self {
        use funcorr::matching::Method;
        match m {
            MethodChoice::Axiomatic => Method::Axiomatic,
            MethodChoice::Fmap => Method::Fmap,
            MethodChoice::Pokrass => Method::Pokrass,
            MethodChoice::Coupled => Method::Coupled,
            MethodChoice::Completion => Method::Completion,
        }
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum OrientationChoice {
    /// Orientation-preserving maps (two scans of the same kind of object).
    Preserve,
    /// Orientation-reversing maps (a shape and a mirror image).
    Reverse,
    /// No orientation term and no signed descriptors.
    Ignore,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum MaskChoice {
    /// The resolvent mask of Ren et al. 2019 (γ = 0.5).
    Resolvent,
    /// The standard (λᵢ − λⱼ)² mask.
    Standard,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum FormChoice {
    /// (11): T = Ψ_k' A Bᵀ Φ_k'ᵀ, A and B k' × k.
    Subspace,
    /// (8): T = U Vᵀ of rank k on the vertices (Riemannian CG).
    FixedRank,
    /// (9): convex, nuclear norm on the dense m × n T (small shapes: m·n ≤ 4·10⁶).
    LowRank,
    /// (10): T = U Vᵀ with ½(‖U‖² + ‖V‖²) on the vertices.
    LowNorm,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum ScalingChoice {
    /// Scale-free weights: unit-area shapes, relative data term (see the library docs).
    Unit,
    /// The paper's (11) literally (its weights depend on the meshes' size and sampling).
    Paper,
}

impl From<ScalingChoice> for funcorr::completion::Scaling {
    fn from(s: ScalingChoice) -> Self {
        match s {
            ScalingChoice::Unit => funcorr::completion::Scaling::Unit,
            ScalingChoice::Paper => funcorr::completion::Scaling::Paper,
        }
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum ExtractChoice {
    /// Nearest neighbours of the rows of Φ_k' B among the rows of Ψ_k' A.
    Nn,
    /// The largest entry of every column of T (never formed).
    Argmax,
    /// Nearest neighbours of the rows of Φ_k' among the rows of Ψ_k' C.
    Fmap,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum InitChoice {
    /// A = C₀ zero-padded, B = I.
    Pad,
    /// A, B from the SVD of C₀.
    Svd,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum OptimizerChoice {
    /// L-BFGS on the factors.
    Lbfgs,
    /// Riemannian conjugate gradients on the fixed-rank manifold (needs --mu4 0).
    Rcg,
}

/// Settings of the matching pipeline shared by `match` and `bench`: the method's parameters,
/// the point-map extraction and the refinement.
/// `funcorr match`'s default data, camera and image size (also the demo's).
const DEFAULT_DATA: &str = "wks";
const DEFAULT_VIEW: &str = "0,0";
const DEFAULT_SIZE: &str = "1600x900";

/// The library's defaults (what `funcorr match X Y` runs): the single source of the option
/// defaults below.
fn defaults() -> funcorr::matching::MatchOptions {
    funcorr::matching::MatchOptions::default()
}

#[derive(clap::Args, Clone)]
struct PipelineArgs {
    /// Form of the completion method.
    #[arg(long, value_enum, default_value = "subspace")]
    form: FormChoice,
    /// Size k of the functional map (baselines; default 50; for the axiomatic method a single
    /// candidate size) or the rank k of the completion method (default 250 for scarce data, 30
    /// for rich data: wks, hks, rich, matrix).
    #[arg(short)]
    k: Option<usize>,
    /// Eigenpairs per shape k': the basis size of the baselines (default 200) or the subspace
    /// size of the completion method (default 350 for scarce data, 50 for rich data).
    #[arg(long)]
    kprime: Option<usize>,
    /// Weight μ_c of the Laplacian-commutativity term of eq. (5) relative to its normalized data
    /// term (0: the paper's plain eq. (5)); also used for the completion method's start.
    /// Default: 1e-3 for rich data, 0 for scarce data (measured best, EXPERIMENTS.md).
    #[arg(long)]
    commutativity: Option<f64>,
    /// Normalization of the completion method's weights.
    #[arg(long, value_enum, default_value = "unit")]
    scaling: ScalingChoice,
    /// μ1, weight of the Dirichlet energy on X (default: per --scaling and --form; with
    /// --scaling unit 0.01 for the subspace form, 0.3 for fixed-rank, low-rank and low-norm).
    #[arg(long)]
    mu1: Option<f64>,
    /// μ2, weight of the Dirichlet energy on Y (default: as μ1).
    #[arg(long)]
    mu2: Option<f64>,
    /// μ3, weight of the L1 term.
    #[arg(long)]
    mu3: Option<f64>,
    /// μ4, weight of the low-norm term.
    #[arg(long)]
    mu4: Option<f64>,
    /// ξ of the smoothed absolute value √(t² + ξ).
    #[arg(long)]
    xi: Option<f64>,
    /// Weight of the Laplacian-commutativity term (isometry prior) added to the completion
    /// objective; on by default because it won on the faust_r dev pairs (EXPERIMENTS.md);
    /// 0 gives the paper's pure form (11).
    #[arg(long, default_value_t = funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY)]
    completion_commutativity: f64,
    /// Size of the leading block of C the completion's commutativity term acts on (0: all k');
    /// also the block of the axiomatic prior (--completion-prior).
    #[arg(long, default_value_t = funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY_K)]
    completion_commutativity_k: usize,
    /// Weight of the axiomatic prior added to the completion objective (0: off): the energy of
    /// the axiomatic method without its descriptor term — Laplacian commutativity with --mask,
    /// descriptor commutativity and orientation with --w-laplacian, --w-commutativity,
    /// --w-orientation and --orientation — on the leading block of C (subspace form (11) only).
    #[arg(long, default_value_t = 0.0)]
    completion_prior: f64,
    /// Initialization of the completion method from the eq. (5) map.
    #[arg(long, value_enum, default_value = "pad")]
    init: InitChoice,
    /// Size of the eq. (5) map that starts the completion method.
    #[arg(long, default_value_t = defaults().init_k)]
    init_k: usize,
    /// Optimizer of the completion method (default: L-BFGS, RCG for --form fixed-rank).
    #[arg(long, value_enum)]
    optimizer: Option<OptimizerChoice>,
    /// Iteration cap of the completion optimizer.
    #[arg(long, default_value_t = defaults().completion.optimize.max_iterations)]
    max_iterations: usize,
    /// Stop when the objective's relative decrease in one iteration is at most this.
    #[arg(long, default_value_t = defaults().completion.optimize.rel_tol)]
    rel_tol: f64,
    /// Point-map extraction of the completion method.
    #[arg(long, value_enum, default_value = "nn")]
    extract: ExtractChoice,
    /// Point-wise refinement (default: zoomout for rich data, icp for scarce data, as measured
    /// best on faust_r, see EXPERIMENTS.md).
    #[arg(long, value_enum)]
    refine: Option<Refine>,
    /// Size of the map the refinement of the completion method starts from.
    #[arg(long, default_value_t = defaults().refine_k)]
    refine_k: usize,
    /// Maximum number of ICP iterations.
    #[arg(long, default_value_t = defaults().icp.max_iterations)]
    icp_iterations: usize,
    /// Final size of ZoomOut (default: 110 for axiomatic, 150 for the other methods).
    #[arg(long)]
    zoomout_to: Option<usize>,
    /// Size increment per ZoomOut iteration (default: 5 for axiomatic, 1 for the others, as in
    /// Melzi et al.).
    #[arg(long)]
    zoomout_step: Option<usize>,
    /// Farthest-point samples of X the axiomatic method's ZoomOut maps are computed on (0: every
    /// vertex).
    #[arg(long, default_value_t = defaults().axiomatic.refine.samples)]
    zoomout_samples: usize,
    /// Rounds of the axiomatic method's bijective polish after ZoomOut (both point maps and both
    /// functional maps with the coupling and bijectivity terms of Ren et al. 2021; 0: none).
    #[arg(long, default_value_t = defaults().axiomatic.polish)]
    polish: usize,
    /// Which maps the axiomatic method looks for (orientation term and signed descriptors).
    #[arg(long, value_enum, default_value = "preserve")]
    orientation: OrientationChoice,
    /// Signed (orientation) descriptors the axiomatic method adds to the data.
    #[arg(long, default_value_t = defaults().axiomatic.signed)]
    signed: usize,
    /// Sizes k of the axiomatic method's candidate functional maps (the one with the least
    /// metric distortion after a short ZoomOut is kept; default 20,30,40,50, or -k alone).
    #[arg(long, value_delimiter = ',')]
    candidates: Option<Vec<usize>>,
    /// Weight of descriptor preservation in the axiomatic energy.
    #[arg(long, default_value_t = defaults().axiomatic.fit.weights.descriptors)]
    w_descriptors: f64,
    /// Weight of Laplacian commutativity in the axiomatic energy.
    #[arg(long, default_value_t = defaults().axiomatic.fit.weights.laplacian)]
    w_laplacian: f64,
    /// Weight of descriptor commutativity in the axiomatic energy.
    #[arg(long, default_value_t = defaults().axiomatic.fit.weights.commutativity)]
    w_commutativity: f64,
    /// Weight of the orientation term in the axiomatic energy.
    #[arg(long, default_value_t = defaults().axiomatic.fit.weights.orientation)]
    w_orientation: f64,
    /// Laplacian-commutativity mask of the axiomatic energy.
    #[arg(long, value_enum, default_value = "resolvent")]
    mask: MaskChoice,
}

#[derive(clap::Args)]
struct MatchArgs {
    /// Source shape X.
    x: PathBuf,
    /// Target shape Y.
    y: PathBuf,
    /// Corresponding data: `wks` (the default: 100 WKS energies from the first 128 eigenpairs,
    /// every 2nd kept), `wks:N` (N WKS from the whole basis), `hks:N`, `wks+hks:N` (`hks` and
    /// `wks+hks` without a count mean N = 100), `segments:X.seg,Y.seg` (labels that
    /// agree between the files), `persistence`, `mser`, `landmarks:pairs.txt` (0-based `i j`
    /// per line), `rich` (100 WKS + 100 heat kernel maps localized on the persistence segments,
    /// the paper's rich data) or `rich:X.seg,Y.seg` (on given segments), or `matrix:F.npy,G.npy`.
    #[arg(long, default_value = DEFAULT_DATA)]
    data: String,
    /// Functional-map method.
    #[arg(long, value_enum, default_value = "axiomatic")]
    method: MethodChoice,
    #[command(flatten)]
    pipe: PipelineArgs,
    /// Write map.txt with 1-based vertex ids (MATLAB).
    #[arg(long)]
    one_based: bool,
    /// Also write the soft map T δ_i (a function on Y) of these vertices of X (comma-separated,
    /// 0-based) as soft_<i>.npy and soft_<i>.ply.
    #[arg(long, value_delimiter = ',')]
    soft: Vec<usize>,
    /// Camera of render.png: azimuth,elevation in degrees (0,0: looking along −Z, Y up).
    #[arg(long, default_value = DEFAULT_VIEW)]
    view: String,
    /// Size of render.png, WIDTHxHEIGHT pixels (each side ≤ 16384, at most 67,108,864 pixels in
    /// all, e.g. 8192x8192).
    #[arg(long, default_value = DEFAULT_SIZE)]
    size: String,
    /// Do not write render.png.
    #[arg(long)]
    no_render: bool,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    seg: SegmentationArgs,
    #[command(flatten)]
    lap: LaplacianArgs,
    #[command(flatten)]
    cache: CacheArgs,
    /// No timings on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct EvalArgs {
    /// Source shape X.
    #[arg(long)]
    source: PathBuf,
    /// Target shape Y (a triangle mesh).
    #[arg(long)]
    target: PathBuf,
    /// The map: one vertex id of Y per line for every vertex of X (map.txt of `funcorr match`).
    #[arg(long)]
    map: PathBuf,
    /// The map file is 1-based.
    #[arg(long)]
    one_based: bool,
    /// Template points on X (1-based .vts).
    #[arg(long)]
    gt_source: PathBuf,
    /// Corresponding template points on Y (1-based .vts).
    #[arg(long)]
    gt_target: PathBuf,
    /// Left–right mirrored template points on Y (1-based .sym.vts): allow symmetric flips.
    #[arg(long)]
    gt_target_sym: Option<PathBuf>,
    /// Geodesic distances on Y.
    #[arg(long, value_enum, default_value_t = GeodesicsChoice::Exact)]
    geodesics: GeodesicsChoice,
    /// Print JSON (summary, cumulative curve, per-point errors) instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum GeodesicsChoice {
    /// Exact polyhedral distances (MMP window propagation), each template point's propagation
    /// stopped at its predicted point: fast for good maps, up to a full solve per badly mapped
    /// point for poor ones (≈ 0.05 s each on 5,000 vertices, ≈ 1 s on 28,000).
    Exact,
    /// The heat method (approximate, ~2–4% mean relative error).
    Heat,
    /// Dijkstra on the mesh edges (upper bound, ~5% mean relative error).
    Dijkstra,
}

impl From<GeodesicsChoice> for funcorr::geodesic::GeodesicMethod {
    fn from(c: GeodesicsChoice) -> Self {
        match c {
            GeodesicsChoice::Exact => Self::Exact,
            GeodesicsChoice::Heat => Self::Heat,
            GeodesicsChoice::Dijkstra => Self::Dijkstra,
        }
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum RegionKind {
    /// Segments given by --labels-x and --labels-y (e.g. the data set's segmentations).
    Labels,
    /// Persistence-based segments of both shapes.
    Persistence,
    /// ShapeMSER regions of both shapes (meshes only).
    Mser,
}

#[derive(clap::Args)]
struct RegionArgs {
    /// Source shape X.
    x: PathBuf,
    /// Target shape Y.
    y: PathBuf,
    /// Where the regions come from.
    #[arg(long, value_enum, default_value = "persistence")]
    kind: RegionKind,
    /// Per-vertex labels of X (--kind labels).
    #[arg(long)]
    labels_x: Option<PathBuf>,
    /// Per-vertex labels of Y (--kind labels).
    #[arg(long)]
    labels_y: Option<PathBuf>,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    /// Number of eigenpairs of the bases the signatures are computed from.
    #[arg(short, default_value_t = 100)]
    k: usize,
    #[command(flatten)]
    seg: SegmentationArgs,
    #[command(flatten)]
    lap: LaplacianArgs,
    #[command(flatten)]
    cache: CacheArgs,
    /// No timings on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Clone, Copy, ValueEnum)]
enum SegFunction {
    /// Scale-normalized heat kernel signature at t = --hks-time / λ₁ (maxima at protrusions).
    Hks,
    /// Average geodesic distance from 32 farthest-point sources (heat-method geodesics on meshes,
    /// kNN-graph distances on point clouds).
    Agd,
}

impl SegmentationArgs {
    fn options(&self) -> funcorr::descriptors::persistence::SegmentationOptions {
        use funcorr::descriptors::persistence::{SegmentFunction, SegmentationOptions};
        SegmentationOptions {
            function: match self.function {
                SegFunction::Hks => SegmentFunction::Hks,
                SegFunction::Agd => SegmentFunction::Agd,
            },
            threshold: self.threshold,
            hks_time: self.hks_time,
        }
    }
}

/// Options of the persistence-based segmentation.
#[derive(clap::Args)]
struct SegmentationArgs {
    /// Function whose maxima seed the persistence segments.
    #[arg(long, value_enum, default_value = "hks")]
    function: SegFunction,
    /// Persistence threshold τ as a fraction of the function's range (0–1).
    #[arg(long, default_value_t = funcorr::descriptors::persistence::DEFAULT_THRESHOLD)]
    threshold: f64,
    /// HKS time of the segmentation function, in units of 1/λ₁.
    #[arg(long, default_value_t = funcorr::descriptors::persistence::DEFAULT_HKS_TIME)]
    hks_time: f64,
}

/// Persistence segmentation of a shape (labels 1..=s, one per vertex).
fn persistence_labels(shape: &Shape, lap: &Laplacian, basis: &Basis, args: &SegmentationArgs) -> Result<Vec<u32>> {
    funcorr::descriptors::persistence::segment_labels(shape, lap, basis, &args.options())
}

/// The Laplacian and basis of a shape: read from --basis, or computed (and cached).
fn shape_basis(
    shape: &Shape,
    path: &Path,
    lap_args: &LaplacianArgs,
    cache: &CacheArgs,
    k: usize,
    basis_file: Option<&Path>,
    st: &mut Stages,
) -> Result<(Laplacian, Basis)> {
    let lap = st.run("laplacian", || build_laplacian(shape, path, lap_args))?;
    let basis = match basis_file {
        Some(p) => {
            let b = st.run("read basis", || spectral::load_basis(p))?;
            if b.n() != shape.n_vertices() {
                return Err(Error::invalid(
                    "--basis",
                    format!("{} has {} rows but the shape has {} vertices", p.display(), b.n(), shape.n_vertices()),
                ));
            }
            b
        }
        None => {
            let c = cache.cache();
            st.run("eigenbasis", || spectral::eigen_basis_cached(&lap, &SpectralOptions::new(k), c.as_ref(), None))?.0
        }
    };
    Ok((lap, basis))
}

/// A shape prepared for matching: its Laplacian (and surface: the mesh or the point cloud's
/// triangulation), and its basis through the cache.
fn prepared_shape(
    shape: Shape,
    path: &Path,
    lap_args: &LaplacianArgs,
    cache: &CacheArgs,
    k: usize,
    st: &mut Stages,
) -> Result<funcorr::PreparedShape> {
    let (lap, surface) = st.run("laplacian", || {
        funcorr::prepared::build_laplacian(&shape, laplacian_choice(lap_args)).map_err(laplacian_error(path))
    })?;
    let c = cache.cache();
    let basis =
        st.run("eigenbasis", || spectral::eigen_basis_cached(&lap, &SpectralOptions::new(k), c.as_ref(), None))?.0;
    Ok(funcorr::PreparedShape::from_parts(shape, lap, basis, surface))
}

/// `println!` that ends the program quietly when stdout is closed early (`funcorr … | head`),
/// as a well-behaved Unix filter does, instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(Error::io("<stdout>", e));
        }
    }};
}

mod bench_cli;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info { shape, json } => info(&shape, json),
        Command::Spectrum(args) => spectrum(&args),
        Command::Descriptors(args) => descriptors(&args),
        Command::Regions(args) => regions(&args),
        Command::Match(args) => match_shapes(&args),
        Command::Eval(args) => eval(&args),
        Command::Demo { out, k } => demo(&out, k),
        Command::Bench(args) => bench_cli::bench(&args),
        Command::Reproduce { what } => bench_cli::reproduce(&what),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("funcorr: error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Stage timer printing `stage: seconds` to stderr unless quiet.
struct Stages {
    quiet: bool,
    parts: Vec<String>,
}

impl Stages {
    fn run<T>(&mut self, name: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let t = Instant::now();
        let r = f()?;
        self.parts.push(format!("{name} {:.3} s", t.elapsed().as_secs_f64()));
        Ok(r)
    }
    fn note(&mut self, s: String) {
        self.parts.push(s);
    }
    fn finish(&self) {
        if !self.quiet {
            eprintln!("funcorr: {}", self.parts.join(" | "));
        }
    }
}

fn info(path: &Path, json: bool) -> Result<()> {
    let shape = Shape::load(path)?;
    let mut facts = vec![("file", serde_json::json!(path.display().to_string()))];
    match &shape {
        Shape::Mesh(m) => facts.extend(mesh_facts(m)),
        Shape::Points(p) => facts.extend([
            ("kind", serde_json::json!(if p.dim() == 3 { "point cloud" } else { "feature matrix" })),
            ("vertices", serde_json::json!(p.len())),
            ("dimension", serde_json::json!(p.dim())),
        ]),
    };
    if json {
        let obj: serde_json::Map<String, serde_json::Value> =
            facts.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
        outln!("{}", serde_json::to_string_pretty(&obj).expect("JSON of plain values"));
    } else {
        for (key, value) in facts {
            let text = match value {
                serde_json::Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            outln!("{:<22} {text}", key.replace('_', " "));
        }
    }
    Ok(())
}

/// Facts about a mesh, in display order.
fn mesh_facts(m: &TriMesh) -> Vec<(&'static str, serde_json::Value)> {
    use serde_json::json;
    let (components, _) = m.components();
    let (lo, hi) = m.bounding_box();
    vec![
        ("kind", json!("triangle mesh")),
        ("vertices", json!(m.n_vertices())),
        ("faces", json!(m.n_faces())),
        ("edges", json!(m.edges().len())),
        ("area", json!(m.total_area())),
        ("components", json!(components)),
        ("boundary_loops", json!(m.boundary_loops().len())),
        ("degenerate_faces", json!(m.degenerate_faces().len())),
        ("unreferenced_vertices", json!(m.unreferenced_vertices().len())),
        ("mean_edge_length", json!(m.mean_edge_length())),
        ("bounding_box_min", json!(lo)),
        ("bounding_box_max", json!(hi)),
    ]
}

/// The library's Laplacian choice for the CLI's arguments.
fn laplacian_choice(args: &LaplacianArgs) -> funcorr::prepared::LaplacianChoice {
    use funcorr::prepared::LaplacianChoice as L;
    match args.laplacian {
        None => L::Auto,
        Some(LaplacianChoice::Cotan) => L::Cotangent,
        Some(LaplacianChoice::Cloud) => L::Cloud { k: args.cloud_neighbours },
        Some(LaplacianChoice::Knn) => L::Knn(KnnOptions {
            k: args.knn_k,
            vertex_weights: match args.vertex_weights {
                WeightsChoice::Identity => VertexWeights::Identity,
                WeightsChoice::Degree => VertexWeights::Degree,
            },
            bandwidth: args.sigma.map_or(Bandwidth::SelfTuning, Bandwidth::Fixed),
        }),
    }
}

fn build_laplacian(shape: &Shape, path: &Path, args: &LaplacianArgs) -> Result<Laplacian> {
    Ok(funcorr::prepared::build_laplacian(shape, laplacian_choice(args)).map_err(laplacian_error(path))?.0)
}

/// Names the option or the file in a Laplacian error: `--laplacian` for a bad choice, the shape's
/// file for a shape without a Laplacian (zero area, vertices in no triangle, ...).
fn laplacian_error(path: &Path) -> impl Fn(Error) -> Error + '_ {
    move |e| match e {
        Error::Invalid { what, msg } if what == "laplacian" => Error::invalid("--laplacian", msg),
        Error::Invalid { what, msg } if what == "mesh" || what == "point set" => {
            Error::parse(path, None, format!("invalid {what}: {msg}"))
        }
        e => e,
    }
}

fn progress_bar(k: usize, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(k as u64);
    pb.set_style(
        ProgressStyle::with_template("{spinner} eigenpairs converged {pos}/{len} [{bar:30}] {elapsed}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb
}

fn spectrum(args: &SpectrumArgs) -> Result<()> {
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    let shape = st.run("read", || Shape::load(&args.shape))?;
    let lap = st.run("laplacian", || build_laplacian(&shape, &args.shape, &args.lap))?;
    if let Some(p) = &args.save_laplacian {
        st.run("save laplacian", || save_laplacian(p, &lap))?;
    }
    let opts =
        SpectralOptions { tol: args.tol, block_size: args.block_size, seed: args.seed, ..SpectralOptions::new(args.k) };
    if args.block_size == Some(0) {
        return Err(Error::invalid("--block-size", "must be at least 1"));
    }
    let cache = args.cache.cache();
    let pb = progress_bar(args.k, args.quiet);
    let update = |done: usize, _k: usize| pb.set_position(done as u64);
    let t = Instant::now();
    let (basis, info) =
        spectral::eigen_basis_cached(&lap, &opts, cache.as_ref(), Some(&update)).map_err(|e| match e {
            Error::Invalid { what, msg } if what == "block_size" => Error::invalid("--block-size", msg),
            e => e,
        })?;
    pb.finish_and_clear();
    match info {
        Some(i) => st.note(format!(
            "factor {:.3} s | eigensolve {:.3} s ({}, {} restarts, {} solves)",
            i.factor_seconds, i.iterate_seconds, i.method, i.restarts, i.operator_applications
        )),
        None => st.note(format!("cached basis {:.3} s", t.elapsed().as_secs_f64())),
    }
    match &args.output {
        Some(out) => st.run("write", || spectral::save_basis(out, &basis))?,
        None => {
            for l in &basis.eigenvalues {
                outln!("{l:.17e}");
            }
        }
    }
    st.note(format!(
        "n {} k {} λ_k {:.6e} max residual {:.2e}",
        basis.n(),
        basis.k(),
        basis.eigenvalues[basis.k() - 1],
        basis.residuals.iter().copied().fold(0.0, f64::max)
    ));
    st.finish();
    Ok(())
}

fn save_laplacian(path: &Path, lap: &Laplacian) -> Result<()> {
    let w = lap.w.as_ref();
    let n = lap.n();
    let as_i64 = |v: &[usize]| v.iter().map(|&x| x as i64).collect::<Vec<i64>>();
    write_npz(
        path,
        &[
            ("W_data", NpzArray::F64 { shape: vec![w.val().len()], data: w.val().to_vec() }),
            ("W_indices", NpzArray::I64 { shape: vec![w.val().len()], data: as_i64(w.symbolic().row_idx()) }),
            ("W_indptr", NpzArray::I64 { shape: vec![n + 1], data: as_i64(w.symbolic().col_ptr()) }),
            ("W_shape", NpzArray::I64 { shape: vec![2], data: vec![n as i64, n as i64] }),
            ("mass", NpzArray::F64 { shape: vec![n], data: lap.mass.clone() }),
        ],
    )
}

/// `flag` must be given for this descriptor kind.
fn need<'a>(v: &'a Option<PathBuf>, flag: &str, kind: &str) -> Result<&'a PathBuf> {
    v.as_ref().ok_or_else(|| Error::invalid(flag, format!("--kind {kind} needs {flag} FILE")))
}

fn descriptors(args: &DescriptorArgs) -> Result<()> {
    use funcorr::descriptors::{self as desc, signatures};
    use funcorr::io::indices;
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    let shape = st.run("read", || Shape::load(&args.shape))?;
    let n = shape.n_vertices();
    let normalize = !args.no_normalize;
    let needs_basis =
        !matches!(args.kind, DescriptorKind::Landmarks | DescriptorKind::Segments | DescriptorKind::Matrix);
    let lb = if needs_basis {
        Some(shape_basis(&shape, &args.shape, &args.lap, &args.cache, args.k, args.basis.as_deref(), &mut st)?)
    } else {
        None
    };
    let basis = lb.as_ref().map(|(_, b)| b);
    let seeds = |path: &Path| indices::read_index_list_file(path, args.one_based, n);
    let mut computed_labels = None;
    let d = st.run("descriptors", || {
        let b = || basis.expect("basis computed for this kind");
        let lap = || &lb.as_ref().expect("Laplacian computed for this kind").0;
        match args.kind {
            DescriptorKind::Landmarks => {
                let p = need(&args.landmarks, "--landmarks", "landmarks")?;
                // Only the chosen side refers to this shape; the other is checked by its own run.
                let (nx, ny) = if matches!(args.side, Side2::Source) { (n, usize::MAX) } else { (usize::MAX, n) };
                let pairs = indices::read_index_pairs_file(p, args.one_based, nx, ny)?;
                let v: Vec<usize> =
                    pairs.iter().map(|&(i, j)| if matches!(args.side, Side2::Source) { i } else { j }).collect();
                desc::landmarks(n, &v).map_err(|e| Error::parse(p, None, e.to_string()))
            }
            DescriptorKind::Hks => signatures::hks(b(), &signatures::hks_times(b(), args.count)?, normalize),
            DescriptorKind::Wks => signatures::wks(b(), args.count, normalize),
            DescriptorKind::Hkm => {
                let s = seeds(need(&args.seeds, "--seeds", "hkm")?)?;
                signatures::hkm(b(), &s, &signatures::hks_times(b(), args.times)?, normalize)
            }
            DescriptorKind::Segments => {
                desc::segments(&indices::read_labels_file(need(&args.labels, "--labels", "segments")?, n)?)
            }
            DescriptorKind::Persistence => {
                let labels = persistence_labels(&shape, lap(), b(), &args.seg)?;
                let d = desc::segments(&labels);
                computed_labels = Some(labels);
                d
            }
            DescriptorKind::Mser => match &shape {
                Shape::Mesh(m) => Ok(desc::mser::shape_mser(m, b(), &desc::mser::MserOptions::default())?.1),
                Shape::Points(_) => Err(Error::invalid("--kind", "mser needs a triangle mesh; this file has no faces")),
            },
            DescriptorKind::Localized => {
                let labels = match &args.labels {
                    Some(p) => indices::read_labels_file(p, n)?,
                    None => persistence_labels(&shape, lap(), b(), &args.seg)?,
                };
                let segs = desc::segments(&labels)?;
                let mut base = signatures::wks(b(), args.count, normalize)?;
                if let Some(p) = &args.seeds {
                    base = base.concat(&signatures::hkm(
                        b(),
                        &seeds(p)?,
                        &signatures::hks_times(b(), args.times)?,
                        normalize,
                    )?)?;
                }
                desc::localized(&base, &segs)
            }
            DescriptorKind::Matrix => {
                desc::Descriptors::from_matrix(&funcorr::io::read_matrix(need(&args.matrix, "--matrix", "matrix")?)?, n)
            }
        }
    })?;
    st.run("write", || {
        // All outputs appear together or none does (io::staged).
        let mut staged = funcorr::io::staged::StagedFiles::new();
        staged.write_with(&args.output, |p| funcorr::io::npy::write_npy_matrix(p, &d.to_dense()))?;
        if let Some(p) = &args.names {
            staged.write_with(p, |p| funcorr::io::write_atomic(p, d.names.join("\n") + "\n"))?;
        }
        if let (Some(p), Some(labels)) = (&args.write_labels, &computed_labels) {
            let text: String = labels.iter().map(|l| format!("{l}\n")).collect();
            staged.write_with(p, |p| funcorr::io::write_atomic(p, text))?;
        }
        staged.publish()
    })?;
    st.note(format!("n {} q {}", d.n(), d.q()));
    st.finish();
    Ok(())
}

fn regions(args: &RegionArgs) -> Result<()> {
    use funcorr::descriptors::{mser, persistence as pers};
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    let x = st.run("read", || Shape::load(&args.x))?;
    let y = st.run("read", || Shape::load(&args.y))?;
    let (lx, bx) = shape_basis(&x, &args.x, &args.lap, &args.cache, args.k, None, &mut st)?;
    let (ly, by) = shape_basis(&y, &args.y, &args.lap, &args.cache, args.k, None, &mut st)?;
    let (f, g, matches) = st.run("regions", || match args.kind {
        RegionKind::Labels => {
            let read = |p: &Option<PathBuf>, flag: &str, n| {
                funcorr::io::indices::read_labels_file(need(p, flag, "labels")?, n)
            };
            let (a, b) = (
                read(&args.labels_x, "--labels-x", x.n_vertices())?,
                read(&args.labels_y, "--labels-y", y.n_vertices())?,
            );
            pers::matched_segment_indicators(&a, &bx, &b, &by)
        }
        RegionKind::Persistence => {
            let a = persistence_labels(&x, &lx, &bx, &args.seg)?;
            let b = persistence_labels(&y, &ly, &by, &args.seg)?;
            pers::matched_segment_indicators(&a, &bx, &b, &by)
        }
        RegionKind::Mser => match (&x, &y) {
            (Shape::Mesh(mx), Shape::Mesh(my)) => {
                mser::matched_mser_indicators((mx, &bx), (my, &by), &mser::MserOptions::default())
            }
            _ => Err(Error::invalid("--kind", "mser needs two triangle meshes")),
        },
    })?;
    st.run("write", || {
        funcorr::io::staged::StagedDir::create(&args.output)?.write_with(|out| {
            funcorr::io::npy::write_npy_matrix(&out.join("F.npy"), &f.to_dense())?;
            funcorr::io::npy::write_npy_matrix(&out.join("G.npy"), &g.to_dense())?;
            let list: Vec<serde_json::Value> = (0..f.q())
                .map(|j| serde_json::json!({"x": f.names[j], "y": g.names[j], "cost": matches.get(j).map(|m| m.cost)}))
                .collect();
            let path = out.join("matches.json");
            let text = serde_json::to_string_pretty(&serde_json::json!({ "pairs": list })).expect("plain JSON");
            funcorr::io::write_atomic(&path, text)
        })
    })?;
    st.note(format!("{} matched regions", f.q()));
    st.finish();
    Ok(())
}

/// Data functions F on X and G on Y from a `--data` spec (see `funcorr match --help`).
fn pair_data(
    spec: &str,
    x: (&Shape, &Laplacian, &Basis),
    y: (&Shape, &Laplacian, &Basis),
    seg: &SegmentationArgs,
) -> Result<(funcorr::descriptors::Descriptors, funcorr::descriptors::Descriptors)> {
    spec.parse::<funcorr::descriptors::spec::PairDataSpec>()?.functions(x, y, &seg.options())
}

/// Geometry of a shape for writing (None for feature matrices of dimension ≠ 3).
fn mesh_data(shape: &Shape) -> Option<funcorr::io::MeshData> {
    match shape {
        Shape::Mesh(m) => {
            Some(funcorr::io::MeshData { vertices: m.vertices().to_vec(), faces: m.faces().to_vec(), colors: None })
        }
        Shape::Points(p) if p.dim() == 3 => Some(funcorr::io::MeshData {
            vertices: p.coords().chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
            faces: vec![],
            colors: None,
        }),
        Shape::Points(_) => None,
    }
}

/// Whether a `--data` spec is the paper's rich setting (many functions) rather than scarce data.
fn is_rich(spec: &str) -> bool {
    spec.parse::<funcorr::descriptors::spec::PairDataSpec>().is_ok_and(|s| s.is_rich())
}

/// The library options of a pipeline (defaults per method and data, see `--help`).
fn pipeline_options(p: &PipelineArgs, method: MethodChoice, rich: bool) -> Result<funcorr::matching::MatchOptions> {
    use funcorr::completion::{self as comp, Form, Init, Optimizer, Scaling};
    use funcorr::matching::{Extraction, MatchOptions, Method};
    let scaling: Scaling = p.scaling.into();
    let form = match p.form {
        FormChoice::Subspace => Form::Subspace,
        FormChoice::FixedRank => Form::FixedRank,
        FormChoice::LowRank => Form::LowRank,
        FormChoice::LowNorm => Form::LowNorm,
    };
    let method: Method = method.into();
    // The library's defaults for this method and data; the options given override them.
    let base = MatchOptions::for_method(method, rich);
    // The form's own default weights; --mu1 … --xi override them below.
    let mut completion = funcorr::matching::completion_defaults(rich, scaling, form);
    if let Some(k) = p.k {
        completion.k = k;
    }
    if let Some(kp) = p.kprime {
        completion.k_prime = kp;
    }
    if method == Method::Completion && !(1..=completion.k_prime).contains(&completion.k) {
        let (k, kp) = (completion.k, completion.k_prime);
        let src = |given: bool, flag: &str, v: usize| {
            if given {
                format!("{flag} {v}")
            } else {
                format!("{flag} (default {v})")
            }
        };
        return Err(Error::invalid(
            if p.k.is_some() { "-k" } else { "--kprime" },
            format!(
                "the completion rank {} must be between 1 and the subspace size {}",
                src(p.k.is_some(), "-k", k),
                src(p.kprime.is_some(), "--kprime", kp)
            ),
        ));
    }
    completion.init = match p.init {
        InitChoice::Pad => Init::Pad,
        InitChoice::Svd => Init::Svd,
    };
    completion.optimizer = p.optimizer.map(|o| match o {
        OptimizerChoice::Lbfgs => Optimizer::Lbfgs,
        OptimizerChoice::Rcg => Optimizer::Rcg,
    });
    let w = &mut completion.params;
    for (slot, v) in
        [(&mut w.mu1, p.mu1), (&mut w.mu2, p.mu2), (&mut w.mu3, p.mu3), (&mut w.mu4, p.mu4), (&mut w.xi, p.xi)]
    {
        if let Some(v) = v {
            *slot = v;
        }
    }
    if completion.optimizer == Some(Optimizer::Rcg) || completion.form == Form::FixedRank {
        if p.mu4.is_some_and(|m| m != 0.0) {
            return Err(Error::invalid("--mu4", "the fixed-rank forms have no low-norm term"));
        }
        w.mu4 = 0.0;
    }
    w.mu_comm = p.completion_commutativity;
    w.k_comm = p.completion_commutativity_k;
    w.mu_prior = p.completion_prior;
    completion.optimize = comp::OptimizeOptions {
        max_iterations: p.max_iterations,
        rel_tol: p.rel_tol,
        ..comp::OptimizeOptions::default()
    };
    let commutativity = p.commutativity.unwrap_or(base.commutativity);
    if !(commutativity.is_finite() && commutativity >= 0.0) {
        return Err(Error::invalid("--commutativity", "must be finite and ≥ 0"));
    }
    let axiomatic = {
        use funcorr::fmap::energy::{EnergyWeights, Mask, Orientation};
        let mut a = base.axiomatic.clone();
        a.fit.weights = EnergyWeights {
            descriptors: p.w_descriptors,
            laplacian: p.w_laplacian,
            commutativity: p.w_commutativity,
            orientation: p.w_orientation,
        };
        a.fit.mask = match p.mask {
            MaskChoice::Resolvent => Mask::Resolvent { gamma: 0.5 },
            MaskChoice::Standard => Mask::Standard,
        };
        a.fit.orientation = match p.orientation {
            OrientationChoice::Preserve => Orientation::Preserve,
            OrientationChoice::Reverse => Orientation::Reverse,
            OrientationChoice::Ignore => Orientation::Ignore,
        };
        a.signed = p.signed;
        if let Some(c) = &p.candidates {
            a.candidates = c.clone();
        } else if let Some(k) = p.k {
            a.candidates = vec![k];
        }
        match p.refine {
            Some(Refine::None) => a.refine.k_final = 0,
            Some(Refine::Icp) if method == Method::Axiomatic => {
                return Err(Error::invalid(
                    "--refine",
                    "the axiomatic method refines with ZoomOut (or none); ICP is for the other methods",
                ))
            }
            _ => {}
        }
        if let Some(k) = p.zoomout_to {
            if p.refine != Some(Refine::None) {
                a.refine.k_final = k;
            }
        }
        if let Some(s) = p.zoomout_step {
            a.refine.step = s;
        }
        a.refine.samples = p.zoomout_samples;
        a.polish = p.polish;
        for (flag, v) in [
            ("--w-descriptors", p.w_descriptors),
            ("--w-laplacian", p.w_laplacian),
            ("--w-commutativity", p.w_commutativity),
            ("--w-orientation", p.w_orientation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(flag, format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if a.candidates.is_empty() || a.candidates.contains(&0) {
            return Err(Error::invalid("--candidates", "need one or more sizes ≥ 1"));
        }
        if a.refine.step == 0 {
            return Err(Error::invalid("--zoomout-step", "must be at least 1"));
        }
        a
    };
    Ok(MatchOptions {
        method,
        k: p.k.unwrap_or(base.k),
        commutativity,
        completion,
        init_k: p.init_k,
        extraction: match p.extract {
            ExtractChoice::Nn => Extraction::Nn,
            ExtractChoice::Argmax => Extraction::Argmax,
            ExtractChoice::Fmap => Extraction::Fmap,
        },
        refine: match p.refine {
            None => base.refine,
            Some(Refine::None) => funcorr::matching::Refine::None,
            Some(Refine::Icp) => funcorr::matching::Refine::Icp,
            Some(Refine::Zoomout) => funcorr::matching::Refine::Zoomout,
        },
        refine_k: p.refine_k,
        icp: funcorr::pointwise::IcpOptions { max_iterations: p.icp_iterations },
        zoomout_to: p.zoomout_to.unwrap_or(base.zoomout_to),
        zoomout_step: p.zoomout_step.unwrap_or(base.zoomout_step),
        axiomatic,
        ..base
    })
}

/// The eigenpairs per shape that `funcorr match` computes, and the option that asks for the
/// most of them (e.g. "--zoomout-to (default 150)"), so that a shape with too few vertices gets
/// an error naming the option to change. Errors when --kprime is given but smaller than what
/// the other options need (the basis would silently be larger than asked).
fn basis_demand(p: &PipelineArgs, opts: &funcorr::matching::MatchOptions) -> Result<(usize, String)> {
    use funcorr::matching::{Method, Refine as R, DEFAULT_BASIS_SIZE};
    let named = |given: bool, flag: &str, v: usize| {
        if given {
            format!("{flag} {v}")
        } else {
            format!("{flag} (default {v})")
        }
    };
    let mut parts: Vec<(usize, String)> = Vec::new();
    match opts.method {
        Method::Completion => {
            parts.push((opts.completion.k_prime, named(p.kprime.is_some(), "--kprime", opts.completion.k_prime)));
        }
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            let kmax = a.candidates.iter().copied().max().unwrap_or(0);
            let flag = if p.candidates.is_some() { "--candidates" } else { "-k" };
            parts.push((kmax, named(p.candidates.is_some() || p.k.is_some(), flag, kmax)));
            parts.push((a.refine.k_final, named(p.zoomout_to.is_some(), "--zoomout-to", a.refine.k_final)));
            parts.push((a.probe.k_final, format!("the size selection (ZoomOut to {})", a.probe.k_final)));
        }
        _ => parts.push((opts.k, named(p.k.is_some(), "-k", opts.k))),
    }
    if opts.method != Method::Axiomatic && opts.refine == R::Zoomout {
        parts.push((opts.zoomout_to, named(p.zoomout_to.is_some(), "--zoomout-to", opts.zoomout_to)));
    }
    let (need, who) = parts.iter().max_by_key(|(k, _)| *k).cloned().unwrap_or((0, "-k".into()));
    if opts.method == Method::Completion {
        return Ok((need.max(opts.basis_size()), who));
    }
    // The other methods compute --kprime eigenpairs (default 200), at least what they need.
    match p.kprime {
        Some(kp) if kp < need => Err(Error::invalid(
            "--kprime",
            format!(
                "{kp} eigenpairs per shape are fewer than the {need} that {who} needs; raise --kprime or lower {who}"
            ),
        )),
        Some(kp) => Ok((kp, format!("--kprime {kp}"))),
        None if need >= DEFAULT_BASIS_SIZE => Ok((need, who)),
        None => Ok((DEFAULT_BASIS_SIZE, format!("--kprime (default {DEFAULT_BASIS_SIZE})"))),
    }
}

/// The library options of `funcorr match` (defaults per method and data, see `--help`).
fn match_options(args: &MatchArgs) -> Result<funcorr::matching::MatchOptions> {
    pipeline_options(&args.pipe, args.method, is_rich(&args.data))
}

/// Writes a k × k (or r × c) matrix as .npy.
fn write_mat_npy(path: &Path, c: &faer::Mat<f64>) -> Result<()> {
    let (r, k) = (c.nrows(), c.ncols());
    let dense = funcorr::io::DenseMatrix { rows: r, cols: k, data: (0..r * k).map(|t| c[(t / k, t % k)]).collect() };
    funcorr::io::npy::write_npy_matrix(path, &dense)
}

/// Parses `WIDTHxHEIGHT` of a side-by-side render and checks it against the renderer's limits
/// (each side ≤ 16384, at most 2²⁶ pixels in all), so that a bad size fails before any work.
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || Error::invalid("--size", format!("'{s}': expected WIDTHxHEIGHT, e.g. 1600x900"));
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (w, h) = (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?);
    funcorr::viz::render::check_size(w, h, 2).map_err(|e| match e {
        Error::Invalid { what, msg } => Error::invalid("--size", format!("'{s}': {what}: {msg}")),
        other => other,
    })?;
    Ok((w, h))
}

/// The colour-transfer outputs of a map: X coloured by position, Y by pulling the colours back
/// through `map_yx`; X.ply, Y.ply and (unless `size` is None) render.png.
fn write_colour_transfer(
    out: &Path,
    x: &Shape,
    y: &Shape,
    map_yx: &[usize],
    render: Option<((u32, u32), &funcorr::viz::View)>,
) -> Result<()> {
    let (Some(mut dx), Some(mut dy)) = (mesh_data(x), mesh_data(y)) else {
        return Ok(());
    };
    let colors_x = funcorr::viz::position_colors(&dx.vertices);
    let colors_y = funcorr::viz::pull_back_colors(&colors_x, map_yx)
        .ok_or_else(|| Error::invalid("map", "the map Y → X points outside X"))?;
    if let Some(((w, h), view)) = render {
        use funcorr::viz::{render_pair, write_png, ColoredShape};
        let sx = ColoredShape { vertices: &dx.vertices, faces: &dx.faces, colors: &colors_x };
        let sy = ColoredShape { vertices: &dy.vertices, faces: &dy.faces, colors: &colors_y };
        write_png(&out.join("render.png"), &render_pair(&sx, &sy, w, h, view)?)?;
    }
    dx.colors = Some(colors_x);
    dy.colors = Some(colors_y);
    funcorr::io::write_mesh(&out.join("X.ply"), &dx)?;
    funcorr::io::write_mesh(&out.join("Y.ply"), &dy)
}

fn match_shapes(args: &MatchArgs) -> Result<()> {
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    // A malformed --data fails before any work.
    args.data.parse::<funcorr::descriptors::spec::PairDataSpec>()?;
    let opts = match_options(args)?;
    let view = funcorr::viz::View::parse(&args.view)?;
    let size = parse_size(&args.size)?;
    let (basis_k, demand) = basis_demand(&args.pipe, &opts)?;
    let x = st.run("read", || Shape::load(&args.x))?;
    let y = st.run("read", || Shape::load(&args.y))?;
    for (path, shape) in [(&args.x, &x), (&args.y, &y)] {
        if basis_k >= shape.n_vertices() {
            return Err(Error::invalid(
                demand.split(' ').next().filter(|w| w.starts_with('-')).unwrap_or("k"),
                format!(
                    "{demand} asks for {basis_k} eigenpairs per shape, but {} has only n = {} vertices (at most n − 1); \
                     ask for fewer",
                    path.display(),
                    shape.n_vertices()
                ),
            ));
        }
    }
    if let Some(&bad) = args.soft.iter().find(|&&i| i >= x.n_vertices()) {
        return Err(Error::invalid("--soft", format!("vertex {bad} of X does not exist (n = {})", x.n_vertices())));
    }
    // The two shapes' Laplacians and bases are independent: prepared side by side.
    let (mut stx, mut sty) = (Stages { quiet: args.quiet, parts: vec![] }, Stages { quiet: args.quiet, parts: vec![] });
    let (px, py) = rayon::join(
        || prepared_shape(x, &args.x, &args.lap, &args.cache, basis_k, &mut stx),
        || prepared_shape(y, &args.y, &args.lap, &args.cache, basis_k, &mut sty),
    );
    let (px, py) = (px?, py?);
    st.parts.extend(stx.parts.into_iter().map(|s| format!("X {s}")));
    st.parts.extend(sty.parts.into_iter().map(|s| format!("Y {s}")));
    let (f, g) = st.run("data", || {
        pair_data(&args.data, (&px.shape, &px.laplacian, &px.basis), (&py.shape, &py.laplacian, &py.basis), &args.seg)
    })?;
    let r = funcorr::matching::run_prepared(&px, &py, &f, &g, &opts)?;
    let (x, y, bx, by) = (&px.shape, &py.shape, &px.basis, &py.basis);
    for (name, secs) in &r.stages {
        st.note(format!("{name} {secs:.3} s"));
    }
    let stages = st.parts.clone();
    st.run("write", || {
        // Everything goes into a staging directory, published whole at the end (io::staged).
        funcorr::io::staged::StagedDir::create(&args.output)?.write_with(|out| {
        write_map_files(out, &r.map_xy, args.one_based)?;
        write_mat_npy(&out.join("C.npy"), &r.c)?;
        if r.c_method.nrows() != r.c.nrows() || opts.refine != funcorr::matching::Refine::None {
            write_mat_npy(&out.join("C_method.npy"), &r.c_method)?;
        }
        if let Some((a, b)) = &r.coefficients {
            write_mat_npy(&out.join("A.npy"), a)?;
            write_mat_npy(&out.join("B.npy"), b)?;
        }
        for &i in &args.soft {
            let t = funcorr::pointwise::soft_map_column(
                bx.eigenvectors.as_ref(),
                by.eigenvectors.as_ref(),
                r.c_method.as_ref(),
                i,
            )?;
            funcorr::io::npy::write_npy_matrix(
                &out.join(format!("soft_{i}.npy")),
                &funcorr::io::DenseMatrix { rows: t.len(), cols: 1, data: t.clone() },
            )?;
            if let Some(mut dy) = mesh_data(y) {
                dy.colors = Some(funcorr::viz::diverging_colors(&t));
                funcorr::io::write_mesh(&out.join(format!("soft_{i}.ply")), &dy)?;
            }
        }
        let report = serde_json::json!({
            "x": args.x.display().to_string(), "y": args.y.display().to_string(),
            "n": x.n_vertices(), "m": y.n_vertices(),
            "data": args.data, "q": f.q(),
            "options": opts,
            "basis_size": basis_k,
            "final_k": r.c.nrows(),
            "solver": r.solver,
            "candidates": r.candidates.as_ref().map(|(c, i)| serde_json::json!({"candidates": c, "chosen": i})),
            "stages": r.stages.iter().map(|(n, s)| serde_json::json!({"stage": n, "seconds": s})).collect::<Vec<_>>(),
            "log": stages,
        });
        let p = out.join("report.json");
        funcorr::io::write_atomic(&p, serde_json::to_string_pretty(&report).expect("plain JSON"))?;
        write_colour_transfer(out, x, y, &r.map_yx, (!args.no_render).then_some((size, &view)))
        })
    })?;
    st.note(format!("q {} | C {}×{}", f.q(), r.c.nrows(), r.c.ncols()));
    st.finish();
    Ok(())
}

/// map.txt (one vertex of Y per line, 0- or 1-based) and map.npy (0-based, u64).
fn write_map_files(out: &Path, map_xy: &[usize], one_based: bool) -> Result<()> {
    let base = usize::from(one_based);
    let text: String = map_xy.iter().map(|j| format!("{}\n", j + base)).collect();
    let p = out.join("map.txt");
    funcorr::io::write_atomic(&p, text)?;
    funcorr::io::npy::write_npy_vec_u64(&out.join("map.npy"), &map_xy.iter().map(|&j| j as u64).collect::<Vec<_>>())
}

fn eval(args: &EvalArgs) -> Result<()> {
    use funcorr::eval::{cumulative_curve, hard_errors, standard_thresholds, summarize, GroundTruth};
    use funcorr::io::indices::read_index_list_file;
    let x = Shape::load(&args.source)?;
    let target = Shape::load(&args.target)?;
    let method = funcorr::geodesic::GeodesicMethod::from(args.geodesics);
    // A point-cloud target: geodesics along the edges of its local triangulation, area of its
    // surface (funcorr::cloud); a mesh: the chosen geodesics.
    let cloud = match &target {
        Shape::Mesh(_) => None,
        Shape::Points(p) if p.dim() == 3 && p.len() > 3 => {
            let pts: Vec<[f64; 3]> = (0..p.len()).map(|i| [p.point(i)[0], p.point(i)[1], p.point(i)[2]]).collect();
            let k = funcorr::cloud::DEFAULT_NEIGHBOURS.min(p.len() - 1);
            let surface = funcorr::cloud::cloud_surface(&pts, k)
                .map_err(|e| Error::invalid("--target", format!("{}: {e}", args.target.display())))?;
            if method != funcorr::geodesic::GeodesicMethod::Dijkstra {
                eprintln!(
                    "note: {} is a point cloud: geodesics along the edges of its local triangulation",
                    args.target.display()
                );
            }
            Some(surface)
        }
        Shape::Points(_) => {
            return Err(Error::invalid(
                "--target",
                format!("{}: geodesic evaluation needs a triangle mesh or 3-D points", args.target.display()),
            ))
        }
    };
    let (n, m) = (x.n_vertices(), target.n_vertices());
    let map = read_index_list_file(&args.map, args.one_based, m)?;
    if map.len() != n {
        return Err(Error::parse(
            &args.map,
            None,
            format!("expected {n} lines (one per vertex of X), found {}", map.len()),
        ));
    }
    let gt = GroundTruth {
        x: read_index_list_file(&args.gt_source, true, n)?,
        y: read_index_list_file(&args.gt_target, true, m)?,
        y_sym: args.gt_target_sym.as_ref().map(|p| read_index_list_file(p, true, m)).transpose()?,
    };
    // Template lists correspond line by line: a length mismatch names both files.
    let others =
        [(Some(&args.gt_target), Some(gt.y.len())), (args.gt_target_sym.as_ref(), gt.y_sym.as_ref().map(Vec::len))];
    for (path, len) in others {
        if let (Some(path), Some(len)) = (path, len) {
            if len != gt.x.len() {
                return Err(Error::parse(
                    path,
                    None,
                    format!(
                        "{len} template points, but {} has {} (the files must correspond line by line)",
                        args.gt_source.display(),
                        gt.x.len()
                    ),
                ));
            }
        }
    }
    let (geo, area, description): (Box<dyn funcorr::eval::Distances + Send + Sync + '_>, f64, &str) =
        match (&target, &cloud) {
            (Shape::Mesh(y), _) => (method.build(y)?, y.total_area(), method.description()),
            (_, Some(s)) => {
                (Box::new(s.geodesics()?), s.area(), "Dijkstra on the edges of the point cloud's local triangulation")
            }
            _ => unreachable!("point sets without a surface were rejected above"),
        };
    let errors = hard_errors(&map, &gt, &*geo, area)?;
    let s = summarize(&errors);
    let thresholds = standard_thresholds();
    let curve = cumulative_curve(&errors, &thresholds);
    if args.json {
        let v = serde_json::json!({
            "summary": s, "symmetric": gt.y_sym.is_some(), "geodesics": description,
            "thresholds": thresholds, "curve": curve, "errors": errors,
        });
        outln!("{}", serde_json::to_string_pretty(&v).expect("plain JSON"));
    } else {
        outln!("points            {}", errors.len());
        outln!("symmetric flips   {}", if gt.y_sym.is_some() { "allowed" } else { "not allowed" });
        outln!("mean error ×100   {:.3}", 100.0 * s.mean);
        outln!("≤ 0.05            {:.1}%", 100.0 * s.at_005);
        outln!("≤ 0.10            {:.1}%", 100.0 * s.at_010);
        outln!("≤ 0.25            {:.1}%", 100.0 * s.at_025);
        outln!("geodesics         {}", description);
    }
    Ok(())
}

/// Ground-truth template correspondences of the demo pair (1-based vertex ids; line i of X's file
/// corresponds to line i of Y's; `.sym` is the left–right mirrored version).
const DEMO_VTS: [&str; 4] = [
    include_str!("../../data/faust/tr_reg_000.vts"),
    include_str!("../../data/faust/tr_reg_001.vts"),
    include_str!("../../data/faust/tr_reg_000.sym.vts"),
    include_str!("../../data/faust/tr_reg_001.sym.vts"),
];

/// Demo step: persistence segments of both shapes, matched by their signatures, checked against
/// the ground truth; writes the matched indicators F.npy, G.npy (the paper's scarce data).
fn demo_segments(out: &Path, (mx, bx): (&TriMesh, &Basis), (my, by): (&TriMesh, &Basis)) -> Result<()> {
    use funcorr::descriptors::persistence as pers;
    let t = Instant::now();
    let lx = pers::segment(&mx.edges(), bx, pers::DEFAULT_THRESHOLD)?.labels;
    let ly = pers::segment(&my.edges(), by, pers::DEFAULT_THRESHOLD)?.labels;
    let (f, g, matches) = pers::matched_segment_indicators(&lx, bx, &ly, by)?;
    let seconds = t.elapsed().as_secs_f64();
    let label = |name: &str| name.trim_start_matches("segment:").parse::<u32>().unwrap_or(0);
    let map: std::collections::HashMap<u32, u32> =
        f.names.iter().zip(&g.names).map(|(a, b)| (label(a), label(b))).collect();
    let vts = |i: usize, n: usize| {
        funcorr::io::indices::read_index_list(DEMO_VTS[i].as_bytes(), Path::new("demo.vts"), true, n)
    };
    let (vx, vy, sx, sy) =
        (vts(0, mx.n_vertices())?, vts(1, my.n_vertices())?, vts(2, mx.n_vertices())?, vts(3, my.n_vertices())?);
    let hit = |a: usize, b: usize| map.get(&lx[a]) == Some(&ly[b]);
    let exact = (0..vx.len()).filter(|&i| hit(vx[i], vy[i])).count();
    let flips = (0..vx.len()).filter(|&i| hit(vx[i], vy[i]) || hit(sx[i], sy[i])).count();
    outln!(
        "\nPersistence segments (scarce data): {} on X, {} on Y, {} matched by signature in {seconds:.2} s",
        lx.iter().max().unwrap_or(&0),
        ly.iter().max().unwrap_or(&0),
        matches.len()
    );
    outln!(
        "  ground truth: {:.1}% of {} template points fall in matched segments ({:.1}% allowing the left-right flip)",
        100.0 * exact as f64 / vx.len() as f64,
        vx.len(),
        100.0 * flips as f64 / vx.len() as f64
    );
    funcorr::io::npy::write_npy_matrix(&out.join("F.npy"), &f.to_dense())?;
    funcorr::io::npy::write_npy_matrix(&out.join("G.npy"), &g.to_dense())?;
    Ok(())
}

/// Demo step: the default `funcorr match` pipeline evaluated against the bundled ground truth;
/// writes map.txt, X.ply, Y.ply and render.png.
fn demo_match(out: &Path, (mx, bx): (&TriMesh, &Basis), (my, by): (&TriMesh, &Basis)) -> Result<()> {
    use funcorr::eval::{hard_errors, summarize, GroundTruth};
    // What `funcorr match X Y` runs: the library's defaults, data `wks`.
    let opts = funcorr::matching::MatchOptions::default();
    let t = Instant::now();
    use funcorr::prepared::Surface;
    let px = funcorr::PreparedShape::from_parts(
        Shape::Mesh(mx.clone()),
        laplacian::cotangent(mx)?,
        bx.clone(),
        Some(Surface::Mesh),
    );
    let py = funcorr::PreparedShape::from_parts(
        Shape::Mesh(my.clone()),
        laplacian::cotangent(my)?,
        by.clone(),
        Some(Surface::Mesh),
    );
    // `--data wks` (the default): pyFM's WKS recipe.
    let recipe = funcorr::descriptors::signatures::WksRecipe::default();
    let (f, g) = (
        funcorr::descriptors::signatures::wks_recipe(bx, &recipe)?,
        funcorr::descriptors::signatures::wks_recipe(by, &recipe)?,
    );
    let r = funcorr::matching::run_prepared(&px, &py, &f, &g, &opts)?;
    let (x, y) = (&px.shape, &py.shape);
    let seconds = t.elapsed().as_secs_f64();
    let vts = |i: usize, n: usize| {
        funcorr::io::indices::read_index_list(DEMO_VTS[i].as_bytes(), Path::new("demo.vts"), true, n)
    };
    let geo = funcorr::geodesic::ExactGeodesics::new(my)?;
    let gt = GroundTruth { x: vts(0, mx.n_vertices())?, y: vts(1, my.n_vertices())?, y_sym: None };
    let plain = summarize(&hard_errors(&r.map_xy, &gt, &geo, my.total_area())?);
    let gt = GroundTruth { y_sym: Some(vts(3, my.n_vertices())?), ..gt };
    let sym = summarize(&hard_errors(&r.map_xy, &gt, &geo, my.total_area())?);
    outln!("\nMatching X → Y with the defaults of `funcorr match` ({}): {seconds:.1} s", describe(DEFAULT_DATA, &opts));
    for (name, secs) in &r.stages {
        outln!("  {name}: {secs:.2} s");
    }
    outln!(
        "  geodesic error (Princeton protocol, exact geodesics): mean ×100 = {:.2}, {:.1}% of points ≤ 0.05, {:.1}% ≤ 0.10",
        100.0 * plain.mean,
        100.0 * plain.at_005,
        100.0 * plain.at_010
    );
    outln!("  allowing the left-right flip: mean ×100 = {:.2}", 100.0 * sym.mean);
    write_map_files(out, &r.map_xy, false)?;
    let view = funcorr::viz::View::parse(DEFAULT_VIEW)?;
    write_colour_transfer(out, x, y, &r.map_yx, Some((parse_size(DEFAULT_SIZE)?, &view)))?;
    outln!("  colour transfer: X.ply, Y.ply (per-vertex colours) and render.png");
    Ok(())
}

/// One line saying what a match configuration does.
fn describe(data: &str, opts: &funcorr::matching::MatchOptions) -> String {
    use funcorr::matching::{Method, Refine as R};
    let method = match opts.method {
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            return format!(
                "data {} + {} signed, axiomatic functional maps (k = {:?}, orientation {:?}), best of the candidates after ZoomOut to {}, ZoomOut to {}{}",
                data,
                a.signed,
                a.candidates,
                a.fit.orientation,
                a.probe.k_final,
                a.refine.k_final,
                match a.polish {
                    0 => String::new(),
                    r => format!(", {r} round(s) of bijective polish"),
                }
            );
        }
        Method::Fmap if opts.commutativity > 0.0 => {
            format!("eq. (5) with Laplacian commutativity μ_c = {}, k = {}", opts.commutativity, opts.k)
        }
        Method::Fmap => format!("eq. (5), k = {}", opts.k),
        Method::Pokrass => format!("Pokrass et al. eq. (6), k = {}", opts.k),
        Method::Coupled => format!("coupled bases eq. (7), k = {}", opts.k),
        Method::Completion => format!(
            "matrix completion {:?} k' = {}, k = {}",
            opts.completion.form, opts.completion.k_prime, opts.completion.k
        ),
    };
    let refine = match opts.refine {
        R::None => "no refinement".to_string(),
        R::Icp => format!("ICP ({} iterations at most)", opts.icp.max_iterations),
        R::Zoomout => format!("ZoomOut to {} in steps of {}", opts.zoomout_to, opts.zoomout_step),
    };
    format!("data {}, {method}, {refine}", data)
}

/// The two bundled FAUST shapes (remeshed, ~5k vertices; Bogo et al. 2014, remeshed for
/// Ren et al. 2018), embedded so that the demo runs from any directory.
const DEMO_X: (&str, &[u8]) = ("tr_reg_000.off", include_bytes!("../../data/faust/tr_reg_000.off"));
const DEMO_Y: (&str, &[u8]) = ("tr_reg_001.off", include_bytes!("../../data/faust/tr_reg_001.off"));

fn demo(target: &Path, k: usize) -> Result<()> {
    let staged = funcorr::io::staged::StagedDir::create(target)?;
    demo_into(&staged, k).map_err(|e| staged.attribute(e))?;
    staged.publish()?;
    outln!("\nwrote {}", target.display());
    Ok(())
}

/// The demo, writing into a staging directory that `demo` publishes.
fn demo_into(staged: &funcorr::io::staged::StagedDir, k: usize) -> Result<()> {
    let out = staged.path();
    // Enough eigenpairs for the default match pipeline (as many as `funcorr match` computes).
    let k = k.max(funcorr::matching::MatchOptions::default().basis_size()).max(funcorr::matching::DEFAULT_BASIS_SIZE);
    outln!("funcorr demo: two FAUST humans (same subject, different poses), k = {k} eigenpairs\n");
    let mut shapes: Vec<(TriMesh, Basis)> = Vec::new();
    for (name, bytes) in [DEMO_X, DEMO_Y] {
        let t = Instant::now();
        let data = funcorr::io::off::read_off(std::io::Cursor::new(bytes), Path::new(name))?;
        let mesh = match Shape::from_data(data)? {
            Shape::Mesh(m) => m,
            Shape::Points(_) => return Err(Error::invalid("demo data", "expected a mesh")),
        };
        let t_read = t.elapsed().as_secs_f64();
        outln!(
            "{name}: {} vertices, {} faces, area {:.4} m², {} component(s), {} boundary loop(s), {} degenerate face(s)",
            mesh.n_vertices(),
            mesh.n_faces(),
            mesh.total_area(),
            mesh.components().0,
            mesh.boundary_loops().len(),
            mesh.degenerate_faces().len()
        );
        let t = Instant::now();
        let lap = laplacian::cotangent(&mesh)?;
        let t_lap = t.elapsed().as_secs_f64();
        let pb = progress_bar(k, false);
        let update = |done: usize, _k: usize| pb.set_position(done as u64);
        let (basis, info) = spectral::eigen_basis(&lap, &SpectralOptions::new(k), Some(&update))?;
        pb.finish_and_clear();
        let file = out.join(name.replace(".off", ".basis.npz"));
        spectral::save_basis(&file, &basis)?;
        outln!(
            "  read {t_read:.3} s, Laplacian {t_lap:.3} s, eigenbasis {:.3} s ({} restarts), max residual {:.1e} -> {}",
            info.factor_seconds + info.iterate_seconds,
            info.restarts,
            basis.residuals.iter().copied().fold(0.0, f64::max),
            staged.published_path(&file).display()
        );
        shapes.push((mesh, basis));
    }
    let ((mesh_x, x), (mesh_y, y)) = (&shapes[0], &shapes[1]);
    let (area_x, area_y) = (mesh_x.total_area(), mesh_y.total_area());
    outln!("\nNear-isometric shapes have nearly equal scale-free spectra λ_i · area:");
    outln!("{:>4} {:>14} {:>14} {:>10}", "i", "λ_i(X)·area", "λ_i(Y)·area", "rel. diff");
    for i in (1..11).chain([k / 2, k - 1]).filter(|&i| i < k) {
        let (a, b) = (x.eigenvalues[i] * area_x, y.eigenvalues[i] * area_y);
        outln!("{i:>4} {a:>14.6} {b:>14.6} {:>9.2}%", 100.0 * (a - b).abs() / a.max(b));
    }
    demo_segments(out, (mesh_x, x), (mesh_y, y))?;
    demo_match(out, (mesh_x, x), (mesh_y, y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use funcorr::matching::{MatchOptions, Method};

    fn parsed(args: &[&str]) -> MatchArgs {
        let mut line = vec!["funcorr", "match", "X", "Y", "-o", "out"];
        line.extend_from_slice(args);
        match Cli::try_parse_from(line).unwrap().command {
            Command::Match(a) => a,
            _ => unreachable!("a match command line"),
        }
    }

    fn json(o: &MatchOptions) -> String {
        serde_json::to_string(o).unwrap()
    }

    /// The library's defaults are what `funcorr match` runs, method by method and for scarce
    /// and rich data; an option given on the command line changes them.
    #[test]
    fn the_cli_runs_the_library_defaults() {
        assert_eq!(json(&match_options(&parsed(&[])).unwrap()), json(&MatchOptions::default()));
        for (flag, method) in [
            ("axiomatic", Method::Axiomatic),
            ("fmap", Method::Fmap),
            ("pokrass", Method::Pokrass),
            ("coupled", Method::Coupled),
            ("completion", Method::Completion),
        ] {
            for (data, rich) in [("wks", true), ("rich", true), ("persistence", false), ("landmarks:l.txt", false)] {
                let a = parsed(&["--method", flag, "--data", data]);
                assert_eq!(
                    json(&match_options(&a).unwrap()),
                    json(&MatchOptions::for_method(method, rich)),
                    "{flag} {data}"
                );
            }
        }
        let a = parsed(&["--polish", "0", "-k", "30"]);
        let o = match_options(&a).unwrap();
        assert_eq!((o.axiomatic.polish, o.axiomatic.candidates.clone()), (0, vec![30]));
        assert_ne!(json(&o), json(&MatchOptions::default()));
    }
}
