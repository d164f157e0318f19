//! Argument groups and value enums shared by the commands, declared once, and the defaults
//! they take from the library.

use std::path::PathBuf;

use clap::ValueEnum;
use serde::Serialize;

use funcorr::spectral::BasisCache;

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum LaplacianChoice {
    /// Cotangent weights with barycentric lumped mass (paper eq. (2)); meshes only. Default for meshes.
    Cotan,
    /// The cotangent Laplacian of the mesh's intrinsic Delaunay triangulation (the same surface,
    /// re-triangulated by intrinsic edge flips): non-negative weights on meshes with obtuse or
    /// sliver triangles, the cotangent Laplacian itself on Delaunay meshes; meshes only.
    Intrinsic,
    /// The point-cloud Laplacian of local Delaunay triangulations of --cloud-neighbours nearest
    /// neighbours (Sharp & Crane 2020): spectrum and mass agree with the cotangent Laplacian of
    /// the sampled surface. 3-D points (a mesh is used as its vertices). Default for 3-D point sets.
    Cloud,
    /// Symmetric K-nearest-neighbour graph with Gaussian weights (paper eq. (1)); any shape
    /// (a mesh is used as its point cloud). Default for point sets of other dimensions.
    Knn,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum WeightsChoice {
    /// A = I: unnormalized graph Laplacian.
    Identity,
    /// A = D: random-walk Laplacian.
    Degree,
}

/// How to build the Laplacian of a shape.
#[derive(clap::Args)]
pub(crate) struct LaplacianArgs {
    /// Laplacian discretization (default: cotan for meshes — built on the geometry smoothed by
    /// one implicit step when a mesh is rough with noise, said on stderr and in report.json's
    /// `denoised`; an explicit `--laplacian cotan` takes the mesh as it is —, cloud for 3-D
    /// point sets, knn for other point sets).
    #[arg(long, value_enum)]
    pub(crate) laplacian: Option<LaplacianChoice>,
    /// Neighbours of the point-cloud Laplacian's local triangulations (default: 30, or n − 1
    /// for a cloud of fewer points; only with the point-cloud Laplacian, else ignored with a
    /// warning).
    #[arg(long)]
    pub(crate) cloud_neighbours: Option<usize>,
    /// Number of neighbours K of the kNN graph (default: 10; only with the kNN Laplacian, else
    /// ignored with a warning).
    #[arg(long = "knn")]
    pub(crate) knn_k: Option<usize>,
    /// Vertex weights of the kNN graph Laplacian (default: identity; only with the kNN
    /// Laplacian).
    #[arg(long, value_enum)]
    pub(crate) vertex_weights: Option<WeightsChoice>,
    /// Fixed Gaussian bandwidth σ > 0 of the kNN weights, in coordinate units
    /// (default: self-tuning, σᵢ = distance to the K-th neighbour; only with the kNN Laplacian).
    #[arg(long)]
    pub(crate) sigma: Option<f64>,
}

/// Where eigenbases are cached.
#[derive(clap::Args)]
pub(crate) struct CacheArgs {
    /// Do not read or write the basis cache.
    #[arg(long)]
    pub(crate) no_cache: bool,
    /// Cache directory (default: $FUNCORR_CACHE_DIR, $XDG_CACHE_HOME/funcorr or ~/.cache/funcorr).
    #[arg(long)]
    pub(crate) cache_dir: Option<PathBuf>,
}

impl CacheArgs {
    pub(crate) fn cache(&self) -> Option<BasisCache> {
        if self.no_cache {
            None
        } else {
            self.cache_dir.clone().or_else(BasisCache::default_dir).map(BasisCache::new)
        }
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum Refine {
    /// The method's own point map (nearest neighbours in the spectral embedding).
    None,
    /// The ICP refinement of Ovsjanikov et al. 2012 (orthonormal C).
    Icp,
    /// ZoomOut (Melzi et al. 2019) up to --zoomout-to eigenpairs.
    Zoomout,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
pub(crate) enum MethodChoice {
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

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum OrientationChoice {
    /// Orientation-preserving maps (two scans of the same kind of object).
    Preserve,
    /// Orientation-reversing maps (a shape and a mirror image).
    Reverse,
    /// No orientation term and no signed descriptors.
    Ignore,
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum MaskChoice {
    /// The resolvent mask of Ren et al. 2019 (γ = 0.5).
    Resolvent,
    /// The standard (λᵢ − λⱼ)² mask.
    Standard,
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum FormChoice {
    /// (11): T = Ψ_k' A Bᵀ Φ_k'ᵀ, A and B k' × k.
    Subspace,
    /// (8): T = U Vᵀ of rank k on the vertices (Riemannian CG).
    FixedRank,
    /// (9): convex, nuclear norm on the dense m × n T (small shapes: m·n ≤ 4·10⁶).
    LowRank,
    /// (10): T = U Vᵀ with ½(‖U‖² + ‖V‖²) on the vertices.
    LowNorm,
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum ScalingChoice {
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

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum ExtractChoice {
    /// Nearest neighbours of the rows of Φ_k' B among the rows of Ψ_k' A.
    Nn,
    /// The largest entry of every column of T (never formed).
    Argmax,
    /// Nearest neighbours of the rows of Φ_k' among the rows of Ψ_k' C.
    Fmap,
}

/// The preconditioner of the completion method's L-BFGS (subspace form).
#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum PreconditionChoice {
    /// None (L-BFGS's scalar initial Hessian).
    Off,
    /// Diagonal Gauss–Newton curvature of the quadratic terms (data, Dirichlet, commutativity).
    Quadratic,
    /// `quadratic` plus the L1 term's diagonal curvature (refreshed every 10 iterations).
    Full,
}

impl From<PreconditionChoice> for funcorr::completion::Precondition {
    fn from(p: PreconditionChoice) -> Self {
        use funcorr::completion::Precondition as P;
        match p {
            PreconditionChoice::Off => P::Off,
            PreconditionChoice::Quadratic => P::Quadratic,
            PreconditionChoice::Full => P::Full,
        }
    }
}

/// Arithmetic of the completion method's L1 products ([`funcorr::completion::Precision`]).
#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum PrecisionChoice {
    /// f64 products.
    F64,
    /// f32 products, f64 sums and smoothed absolute value.
    F32,
}

/// The L1 precision from `--l1-precision` and the legacy `--l1-f32` (they conflict), or the
/// method's default when neither is given.
pub(crate) fn l1_precision(
    choice: Option<PrecisionChoice>,
    l1_f32: bool,
    default: funcorr::completion::Precision,
) -> funcorr::completion::Precision {
    use funcorr::completion::Precision as P;
    match (choice, l1_f32) {
        (Some(PrecisionChoice::F32), _) | (None, true) => P::F32,
        (Some(PrecisionChoice::F64), _) => P::F64,
        (None, false) => default,
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum InitChoice {
    /// A = C₀ zero-padded, B = I.
    Pad,
    /// A, B from the SVD of C₀.
    Svd,
}

#[derive(Clone, Copy, PartialEq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum OptimizerChoice {
    /// L-BFGS on the factors.
    Lbfgs,
    /// Riemannian conjugate gradients on the fixed-rank manifold (needs --mu4 0).
    Rcg,
}

/// `funcorr match`'s default data, camera and image size (also the demo's).
pub(crate) const DEFAULT_DATA: &str = "wks";

/// A count of vertex pairs n·m (`--near-above` and the like): an integer, or a whole number
/// written as a float ("1e10", "2.5e9"), from 0 to 2⁶⁴ − 1.
pub(crate) fn vertex_pairs(s: &str) -> Result<u64, String> {
    if let Ok(v) = s.parse::<u64>() {
        return Ok(v);
    }
    match s.parse::<f64>() {
        // 2⁶⁴ is the first f64 above u64's range.
        Ok(v) if v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v < 18_446_744_073_709_551_616.0 => Ok(v as u64),
        _ => Err(format!("'{s}' is not a whole number of vertex pairs from 0 to 2^64 - 1 (e.g. 2000000000 or 2e9)")),
    }
}
pub(crate) const DEFAULT_VIEW: &str = "0,0";
pub(crate) const DEFAULT_SIZE: &str = "1600x900";

/// The library's defaults (what `funcorr match X Y` runs): the single source of the option
/// defaults below.
pub(crate) fn defaults() -> funcorr::matching::MatchOptions {
    funcorr::matching::MatchOptions::default()
}

/// A finite real number: the options' numbers (NaN and ±∞ are refused as they are parsed).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub(crate) struct Finite(pub(crate) f64);

impl std::str::FromStr for Finite {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let x: f64 = s.parse().map_err(|e: std::num::ParseFloatError| e.to_string())?;
        if x.is_finite() {
            Ok(Finite(x))
        } else {
            Err(format!("must be finite, got {x}"))
        }
    }
}

impl std::fmt::Display for Finite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        std::fmt::Display::fmt(&self.0, f)
    }
}

/// Settings of the matching pipeline shared by `match` and `bench`: the method's parameters,
/// the point-map extraction and the refinement. Every field is the option of the library's table
/// of its name (`funcorr::matching::MATCH_OPTIONS`, the flag with `_` for `-`), to which
/// `crate::options::settings` hands it.
#[derive(clap::Args, Clone, Serialize)]
pub(crate) struct PipelineArgs {
    /// Form of the completion method.
    #[arg(long, value_enum, default_value = "subspace")]
    pub(crate) form: FormChoice,
    /// Size k of the functional map (baselines; default 50; for the axiomatic method a single
    /// candidate size) or the rank k of the completion method (default 250 for scarce data, 30
    /// for rich data: wks, hks, rich, matrix).
    #[arg(short)]
    pub(crate) k: Option<usize>,
    /// Eigenpairs per shape k': the basis size of the baselines and the axiomatic method
    /// (default 200; 128 for the axiomatic method with the default data where X cannot be a
    /// part) or the subspace size
    /// of the completion method (default 350 for scarce data, 50 for rich data).
    #[arg(long)]
    pub(crate) kprime: Option<usize>,
    /// Weight μ_c of the Laplacian-commutativity term of eq. (5) relative to its normalized data
    /// term (0: the paper's plain eq. (5)); also used for the completion method's start.
    /// Default: 1e-3 for rich data, 0 for scarce data (measured best, EXPERIMENTS.md).
    #[arg(long)]
    pub(crate) commutativity: Option<Finite>,
    /// Normalization of the completion method's weights.
    #[arg(long, value_enum, default_value = "unit")]
    pub(crate) scaling: ScalingChoice,
    /// μ1, weight of the Dirichlet energy on X (default: per --scaling and --form; with
    /// --scaling unit 0.01 for the subspace form, 0.3 for fixed-rank, low-rank and low-norm).
    #[arg(long)]
    pub(crate) mu1: Option<Finite>,
    /// μ2, weight of the Dirichlet energy on Y (default: as μ1).
    #[arg(long)]
    pub(crate) mu2: Option<Finite>,
    /// μ3, weight of the L1 term.
    #[arg(long)]
    pub(crate) mu3: Option<Finite>,
    /// μ4, weight of the low-norm term.
    #[arg(long)]
    pub(crate) mu4: Option<Finite>,
    /// ξ of the smoothed absolute value √(t² + ξ).
    #[arg(long)]
    pub(crate) xi: Option<Finite>,
    /// Weight of the Laplacian-commutativity term (isometry prior) added to the completion
    /// objective; on by default because it won on the faust_r dev pairs (EXPERIMENTS.md);
    /// 0 gives the paper's pure form (11).
    #[arg(long, default_value_t = Finite(funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY))]
    pub(crate) completion_commutativity: Finite,
    /// Size of the leading block of C the completion's commutativity term acts on (0: all k');
    /// also the block of the axiomatic prior (--completion-prior).
    #[arg(long, default_value_t = funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY_K)]
    pub(crate) completion_commutativity_k: usize,
    /// Weight of the axiomatic prior added to the completion objective (0: off): the energy of
    /// the axiomatic method without its descriptor term — Laplacian commutativity with --mask,
    /// descriptor commutativity and orientation with --w-laplacian, --w-commutativity,
    /// --w-orientation and --orientation — on the leading block of C (subspace form (11) only).
    #[arg(long, default_value_t = Finite(0.0))]
    pub(crate) completion_prior: Finite,
    /// Initialization of the completion method from the eq. (5) map.
    #[arg(long, value_enum, default_value = "pad")]
    pub(crate) init: InitChoice,
    /// Size of the eq. (5) map that starts the completion method.
    #[arg(long, default_value_t = defaults().init_k)]
    pub(crate) init_k: usize,
    /// Optimizer of the completion method (default: L-BFGS, RCG for --form fixed-rank).
    #[arg(long, value_enum)]
    pub(crate) optimizer: Option<OptimizerChoice>,
    /// Iteration cap of the completion optimizer.
    #[arg(long, default_value_t = defaults().completion.optimize.max_iterations)]
    pub(crate) max_iterations: usize,
    /// Stop when the objective's relative decrease in one iteration is at most this.
    #[arg(long, default_value_t = Finite(defaults().completion.optimize.rel_tol))]
    pub(crate) rel_tol: Finite,
    /// Evaluate the completion method's L1 term on this many farthest-point samples of each
    /// shape, weighted by their Voronoi areas (0: on every pair of vertices, as the paper).
    /// Default: 1000 with the unit scaling, 0 with `--scaling paper` (the samples need the
    /// scale-free weights).
    #[arg(long)]
    pub(crate) l1_samples: Option<usize>,
    /// Arithmetic of the products of the completion method's L1 term (f32: the smoothed |·| and
    /// the sums across blocks stay in f64; relative differences ~1e-7 in its gradient).
    /// Default: f32 for the subspace form (11), f64 for the others.
    #[arg(long, value_enum)]
    pub(crate) l1_precision: Option<PrecisionChoice>,
    /// The same as --l1-precision f32 (kept for scripts written before f32 became the default).
    #[arg(long, hide = true, conflicts_with = "l1_precision")]
    pub(crate) l1_f32: bool,
    /// Preconditioner of the completion method's L-BFGS (subspace form).
    #[arg(long, value_enum, default_value = "off")]
    pub(crate) precondition: PreconditionChoice,
    /// Continuation in ξ of the completion method: this many stages ξ·10^(N−1), …, ξ, sharing the
    /// iteration cap (0 or 1: off).
    #[arg(long, default_value_t = 0)]
    pub(crate) xi_stages: usize,
    /// Multiscale schedule of the completion method (subspace form): this many stages of
    /// growing k' and k, sharing the iteration cap (0 or 1: off). Default: 2.
    #[arg(long)]
    pub(crate) multiscale: Option<usize>,
    /// Also stop the completion optimizer when its point map has settled: check it every this
    /// many iterations (0: off), on the L1 samples of X or every vertex.
    #[arg(long, default_value_t = defaults().completion.settled.map_or(0, |s| s.every))]
    pub(crate) map_check_every: usize,
    /// Fraction of the checked vertices whose image may change between two checks
    /// (--map-check-every).
    #[arg(long, default_value_t = Finite(defaults().completion.settled.map_or(0.005, |s| s.tolerance)))]
    pub(crate) map_tolerance: Finite,
    /// Point-map extraction of the completion method (used with --refine none; a refinement
    /// starts from C).
    #[arg(long, value_enum, default_value = "nn")]
    pub(crate) extract: ExtractChoice,
    /// Point-wise refinement (default: zoomout for rich data, icp for scarce data, as measured
    /// best on faust_r, see EXPERIMENTS.md).
    #[arg(long, value_enum)]
    pub(crate) refine: Option<Refine>,
    /// Size of the map the refinement of the completion method starts from.
    #[arg(long, default_value_t = defaults().refine_k)]
    pub(crate) refine_k: usize,
    /// Maximum number of ICP iterations.
    #[arg(long, default_value_t = defaults().icp.max_iterations)]
    pub(crate) icp_iterations: usize,
    /// Final size of ZoomOut (default: 128 for axiomatic, 150 for the other methods).
    #[arg(long)]
    pub(crate) zoomout_to: Option<usize>,
    /// Size increment per ZoomOut iteration (default: 5 for axiomatic, 1 for the others, as in
    /// Melzi et al.).
    #[arg(long)]
    pub(crate) zoomout_step: Option<usize>,
    /// Farthest-point samples of X the axiomatic method's ZoomOut maps are computed on (0: every
    /// vertex).
    #[arg(long, default_value_t = defaults().axiomatic.refine.samples)]
    pub(crate) zoomout_samples: usize,
    /// Rounds of the axiomatic method's bijective polish after ZoomOut (both point maps and both
    /// functional maps with the coupling and bijectivity terms of Ren et al. 2021; 0: none).
    #[arg(long, default_value_t = defaults().axiomatic.polish)]
    pub(crate) polish: usize,
    /// X is a part of Y (a cut, a scan from one side): match it with the partial path
    /// (rectangular functional maps, coverage of Y). Without it the axiomatic method detects a
    /// part by its boundary (longer than Y's by ≥ 0.25 √area) and area (≤ 1.5 × Y's; from the
    /// heat kernels where the inputs' units make X look larger); report.json says what it found.
    #[arg(long, conflicts_with = "no_partial")]
    pub(crate) partial: bool,
    /// Match X as a whole shape even when it looks like a part of Y (no detection): the
    /// library's option `partial` set to false.
    #[arg(long)]
    #[serde(skip)]
    pub(crate) no_partial: bool,
    /// The share of Y's area that X covers, in (0, 1.5], when you know it (e.g. 0.7 for a body
    /// without its head and an arm): the partial path uses it instead of its estimate from the
    /// heat kernels, which can fit two ratios about as well (legs and pelvis at half their area
    /// look like arms and shoulders). Implies --partial.
    #[arg(long, conflicts_with = "no_partial")]
    pub(crate) partial_ratio: Option<Finite>,
    /// Vertex pairs n·m above which the axiomatic method's final point maps are searched near
    /// the map of its samples instead of exactly (large shapes).
    #[arg(long, default_value_t = defaults().axiomatic.near.above_pairs, value_parser = vertex_pairs)]
    pub(crate) near_above: u64,
    /// Cells of the other shape searched around each sample's image (--near-above).
    #[arg(long, default_value_t = defaults().axiomatic.near.cells)]
    pub(crate) near_cells: usize,
    /// Vertex pairs n·m above which the map Y → X (map_yx.npy) is searched near the final map
    /// X → Y while that map is still exact (up to --near-above).
    #[arg(long, default_value_t = defaults().axiomatic.near.inverse_above_pairs, value_parser = vertex_pairs)]
    pub(crate) near_inverse_above: u64,
    /// Vertex pairs n·m up to which the final map X → Y, where searched near the samples' map, is
    /// made exact by a certificate (bounds rule out the cells of Y that cannot hold a nearer
    /// vertex); the default, 2⁶⁴ − 1, is every size.
    #[arg(long, default_value_t = defaults().axiomatic.near.certified_up_to, value_parser = vertex_pairs)]
    pub(crate) near_certified_up_to: u64,
    /// Vertex pairs n·m up to which the map Y → X (map_yx.npy), where restricted, is searched
    /// near the preimages of the map X → Y and made exact by a certificate; above, it is searched
    /// near the samples' map, not certified.
    #[arg(long, default_value_t = defaults().axiomatic.near.inverse_certified_up_to, value_parser = vertex_pairs)]
    pub(crate) near_inverse_certified_up_to: u64,
    /// Which maps the axiomatic method looks for (orientation term and signed descriptors).
    #[arg(long, value_enum, default_value = "preserve")]
    pub(crate) orientation: OrientationChoice,
    /// Signed (orientation) descriptors the axiomatic method adds to the data.
    #[arg(long, default_value_t = defaults().axiomatic.signed)]
    pub(crate) signed: usize,
    /// Sizes k of the axiomatic method's candidate functional maps (the one with the least
    /// metric distortion after a short ZoomOut is kept; default 20,30,40,50, or -k alone).
    #[arg(long, value_delimiter = ',')]
    pub(crate) candidates: Option<Vec<usize>>,
    /// Weight of descriptor preservation in the axiomatic energy.
    #[arg(long, default_value_t = Finite(defaults().axiomatic.fit.weights.descriptors))]
    pub(crate) w_descriptors: Finite,
    /// Weight of Laplacian commutativity in the axiomatic energy.
    #[arg(long, default_value_t = Finite(defaults().axiomatic.fit.weights.laplacian))]
    pub(crate) w_laplacian: Finite,
    /// Weight of descriptor commutativity in the axiomatic energy.
    #[arg(long, default_value_t = Finite(defaults().axiomatic.fit.weights.commutativity))]
    pub(crate) w_commutativity: Finite,
    /// Weight of the orientation term in the axiomatic energy.
    #[arg(long, default_value_t = Finite(defaults().axiomatic.fit.weights.orientation))]
    pub(crate) w_orientation: Finite,
    /// Laplacian-commutativity mask of the axiomatic energy.
    #[arg(long, value_enum, default_value = "resolvent")]
    pub(crate) mask: MaskChoice,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
pub(crate) enum GeodesicsChoice {
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

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SegFunction {
    /// Scale-normalized heat kernel signature at t = --hks-time / λ₁ (maxima at protrusions).
    Hks,
    /// Average geodesic distance from 32 farthest-point sources (heat-method geodesics on meshes,
    /// kNN-graph distances on point clouds).
    Agd,
}

impl SegmentationArgs {
    pub(crate) fn options(&self) -> funcorr::descriptors::persistence::SegmentationOptions {
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
pub(crate) struct SegmentationArgs {
    /// Function whose maxima seed the persistence segments.
    #[arg(long, value_enum, default_value = "hks")]
    pub(crate) function: SegFunction,
    /// Persistence threshold τ as a fraction of the function's range (0–1).
    #[arg(long, default_value_t = funcorr::descriptors::persistence::DEFAULT_THRESHOLD)]
    pub(crate) threshold: f64,
    /// HKS time of the segmentation function, in units of 1/λ₁.
    #[arg(long, default_value_t = funcorr::descriptors::persistence::DEFAULT_HKS_TIME)]
    pub(crate) hks_time: f64,
}
