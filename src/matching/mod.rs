//! The matching pipeline: data F, G on two shapes → a functional map by one of the methods →
//! a point-to-point map X → Y, refined or not. The CLI's `match`, `demo`, the Python
//! `funcorr.match` and the experiment programs are thin layers over [`run`], with options
//! named as in [`options`] ([`MatchSettings`] → [`MatchOptions`]).
//!
//! **Direction.** Every method maps X (n vertices, basis Φ) to Y (m vertices, basis Ψ): the
//! point map `map_xy` gives for every vertex of X a vertex of Y, the completion method's T is
//! m × n, and the functional map C of [`MatchResult`] is k_Y × k_X (coefficients on X →
//! coefficients on Y, as in [`crate::fmap`]). The axiomatic method estimates the map through its
//! pull-back ([`crate::fmap::Pullback`], C_yx: k_X × k_Y, functions on Y → functions on X),
//! which is the type of its every intermediate; its result's C is the transpose of the final
//! pull-back ([`crate::fmap::Pullback::transposed`]).

pub mod axiomatic;
pub mod covered;
pub mod heat_scale;
pub mod landmarks;
pub mod options;
pub mod partial;
pub mod search;

pub use options::{BasisDemand, Keywords, MatchSettings, Spelling, Value, MATCH_OPTIONS};

use std::borrow::Cow;
use std::time::Instant;

use faer::{Mat, MatRef};
use serde::{Deserialize, Serialize};

use crate::completion::{self, CompletionOptions};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::fmap::{self, CoupledOptions, OvsjanikovOptions, PokrassOptions};
use crate::laplacian::Laplacian;
use crate::pointwise::{self, IcpOptions, ZoomOutOptions};
use crate::spectral::Basis;

/// The functional-map method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The orientation-aware axiomatic pipeline ([`axiomatic`]): descriptor preservation,
    /// resolvent Laplacian commutativity, descriptor commutativity and orientation, with signed
    /// descriptors, candidate selection and ZoomOut.
    Axiomatic,
    /// Ovsjanikov et al. 2012, eq. (5), with optional Laplacian commutativity.
    Fmap,
    /// Pokrass et al. 2013, eq. (6).
    Pokrass,
    /// Kovnatsky et al. 2013, eq. (7).
    Coupled,
    /// Kovnatsky et al. 2015, eqs. (8)–(11).
    Completion,
}

/// Point-wise refinement.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Refine {
    /// The point map of the method itself.
    None,
    /// The ICP of Ovsjanikov et al. 2012 (orthonormal C, paper §2).
    Icp,
    /// ZoomOut (Melzi et al. 2019).
    Zoomout,
}

/// How the completion method's correspondence T = L Rᵀ becomes a point map X → Y.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Extraction {
    /// Nearest neighbours of the rows of R (Φ_k' B) among the rows of L (Ψ_k' A).
    Nn,
    /// The largest entry of every column of T (max inner product of the rows of L and R).
    Argmax,
    /// Nearest neighbours of the rows of Φ_k' among the rows of Ψ_k' C (C = A Bᵀ, k' × k').
    Fmap,
}

/// Everything [`run`] needs besides the shapes and data: build it with
/// [`MatchOptions::default`] (what `funcorr match X Y` runs) or [`MatchOptions::for_method`], change
/// fields, check it with [`MatchOptions::validate`]; or from options by name,
/// [`MatchSettings::resolve`].
#[derive(Clone, Debug, Serialize)]
pub struct MatchOptions {
    /// The method.
    pub method: Method,
    /// Size k of the baselines' functional maps (k × k).
    pub k: usize,
    /// μ_c of eq. (5)'s Laplacian commutativity (baseline `fmap` and the completion start).
    pub commutativity: f64,
    /// Options of Pokrass et al.
    pub pokrass: PokrassOptions,
    /// Options of the coupled bases.
    pub coupled: CoupledOptions,
    /// Options of the completion method (form, scaling, weights, k', k, optimizer).
    pub completion: CompletionOptions,
    /// Size of the eq. (5) map (with `commutativity`) that starts the completion method.
    pub init_k: usize,
    /// Point-map extraction of the completion method (the output map only with `Refine::None`;
    /// a refinement starts from C and makes its own).
    pub extraction: Extraction,
    /// Refinement.
    pub refine: Refine,
    /// Size of the functional map the refinement of the completion method starts from (the
    /// leading block of its k' × k' map); the baselines start from their own k × k map.
    pub refine_k: usize,
    /// ICP options.
    pub icp: IcpOptions,
    /// Final size of ZoomOut.
    pub zoomout_to: usize,
    /// Size increment of ZoomOut.
    pub zoomout_step: usize,
    /// The axiomatic pipeline (method `Axiomatic`; its own refinement replaces `refine`).
    pub axiomatic: axiomatic::AxiomaticPipeline,
    /// Partial → full matching ([`partial`]): when it runs (detected by default) and its
    /// options. A path of the axiomatic method.
    pub partial: partial::PartialOptions,
}

/// Eigenpairs per shape that `funcorr match` computes for the baselines (the methods other than
/// completion and axiomatic) when the options need fewer (`--kprime` default).
pub const DEFAULT_BASIS_SIZE: usize = 200;

/// Eigenpairs per shape that `funcorr match` computes for the axiomatic method when X cannot be
/// a part, the data are the default WKS (or given) and its sizes need fewer (`--kprime` default,
/// [`options::MatchSettings::basis_demand_for`]): the 128 of its default data, the WKS recipe
/// ([`crate::descriptors::signatures::WksRecipe`]), the most its full path reads, so that its
/// maps are those of any larger basis (the first 128 eigenpairs of a basis of 200 agree with
/// them to 1e-14; the 97 faust_r pairs and the large pairs give the same maps) in about half the
/// eigensolver's time (BENCHMARKS.md). The partial path reads every eigenpair (its heat-kernel
/// scale and rectangular maps were tuned on 200: with 128 the faust_r_partial error rose from
/// 12.6 to 18.5), so a pair that may be partial keeps [`DEFAULT_BASIS_SIZE`].
pub const AXIOMATIC_BASIS_SIZE: usize = 128;

/// Weight of the completion method's Laplacian-commutativity (isometry prior) term by default
/// (EXPERIMENTS.md: it won on the faust_r dev pairs; 0 is the paper's pure form (11)).
pub const DEFAULT_COMPLETION_COMMUTATIVITY: f64 = 1e-2;

/// Size of the leading block of C that the completion's commutativity term acts on by default.
pub const DEFAULT_COMPLETION_COMMUTATIVITY_K: usize = 50;

/// Farthest-point samples per shape on which the completion method evaluates its L1 term by
/// default ([`completion::L1Sampling`]; every vertex on shapes with fewer vertices or without
/// 3-D positions, and with the paper's scaling, which the samples do not support). EXPERIMENTS.md, "The default completion setting": on the 97 faust_r pairs
/// as accurate as the 1000-sample f64 single-scale run, at 1/25 of the full term's cost.
pub const DEFAULT_L1_SAMPLES: usize = 1000;

/// Iteration cap of the completion optimizer by default: every accuracy measurement of the
/// method in EXPERIMENTS.md (Figure 7 on 8 and on 97 faust_r pairs) is at 150 iterations; the
/// objective's stopping rules do not end L-BFGS before 300 either, and 300 is not measured to
/// be better (one pair: 2.69 at 300 against 2.63 at 150).
pub const DEFAULT_COMPLETION_ITERATIONS: usize = 150;

/// Stages of the completion method's multiscale schedule by default
/// ([`CompletionOptions::multiscale`]).
pub const DEFAULT_COMPLETION_MULTISCALE: usize = 2;

/// The completion options of `funcorr match --method completion` for scarce or rich data, a
/// scaling and a form: the paper's k', k and the form's default weights
/// ([`CompletionOptions::paper`], [`CompletionOptions::with_form`]) plus the isometry prior
/// ([`DEFAULT_COMPLETION_COMMUTATIVITY`] on the leading [`DEFAULT_COMPLETION_COMMUTATIVITY_K`]
/// block), and for the subspace form (11) the speed settings measured to hold accuracy
/// (EXPERIMENTS.md, "The default completion setting"): the L1 term on
/// [`DEFAULT_L1_SAMPLES`] farthest-point samples, its products in f32 with f64 sums
/// ([`completion::Precision::F32`]), and a [`DEFAULT_COMPLETION_MULTISCALE`]-stage schedule.
/// The iteration cap is [`DEFAULT_COMPLETION_ITERATIONS`].
/// The paper's literal setting is [`CompletionOptions::paper`] (every vertex, f64, one scale).
pub fn completion_defaults(rich: bool, scaling: completion::Scaling, form: completion::Form) -> CompletionOptions {
    let mut c = CompletionOptions::paper(rich, scaling).with_form(form);
    c.optimize.max_iterations = DEFAULT_COMPLETION_ITERATIONS;
    c.params.mu_comm = DEFAULT_COMPLETION_COMMUTATIVITY;
    c.params.k_comm = DEFAULT_COMPLETION_COMMUTATIVITY_K;
    // Measured on the subspace form (11) only, which alone has the schedule and the samples
    // (the samples with the scale-free weights only, Scaling::Unit).
    if form == completion::Form::Subspace {
        if scaling == completion::Scaling::Unit {
            c.l1_sampling = completion::L1Sampling::farthest(DEFAULT_L1_SAMPLES);
        }
        c.params.l1_precision = completion::Precision::F32;
        c.multiscale = DEFAULT_COMPLETION_MULTISCALE;
    }
    c
}

impl MatchOptions {
    /// The options `funcorr match --method <method>` runs when no other option is given, for
    /// scarce data (a few functions: segments, persistence, MSER, landmarks) or rich data (many
    /// functions: WKS/HKS signatures, `rich`, a matrix; [`crate::descriptors::spec::PairDataSpec::is_rich`]). Per method and data, as measured best (EXPERIMENTS.md): eq. (5) with
    /// commutativity μ_c = 1e-3 for rich data and 0 for scarce data, k = 50; completion
    /// [`completion_defaults`] (unit scaling, subspace form); refinement ZoomOut (to 150 in steps
    /// of 1) for rich data and ICP (10 iterations at most) for scarce data; the axiomatic
    /// method's own pipeline ([`axiomatic::AxiomaticPipeline::default`]).
    pub fn for_method(method: Method, rich: bool) -> MatchOptions {
        MatchOptions {
            method,
            k: 50,
            commutativity: if rich { 1e-3 } else { 0.0 },
            pokrass: PokrassOptions::default(),
            coupled: CoupledOptions::default(),
            completion: completion_defaults(rich, completion::Scaling::Unit, completion::Form::Subspace),
            init_k: 50,
            extraction: Extraction::Nn,
            refine: if rich { Refine::Zoomout } else { Refine::Icp },
            refine_k: 50,
            icp: IcpOptions { max_iterations: 10 },
            zoomout_to: 150,
            zoomout_step: 1,
            axiomatic: axiomatic::AxiomaticPipeline::default(),
            partial: partial::PartialOptions::default(),
        }
    }
}

impl Default for MatchOptions {
    /// What `funcorr match X Y` runs: [`MatchOptions::for_method`] with [`Method::Axiomatic`]
    /// and the default data `--data wks` (100 WKS: rich).
    fn default() -> Self {
        MatchOptions::for_method(Method::Axiomatic, true)
    }
}

impl MatchOptions {
    /// The number of eigenpairs each basis must hold for these options.
    pub fn basis_size(&self) -> usize {
        let mut k = match self.method {
            // The start is fitted at min(init_k, k', k): no eigenpairs beyond k'.
            Method::Completion => self.completion.k_prime,
            Method::Axiomatic => return self.axiomatic.basis_size(),
            _ => self.k,
        };
        // refine_k needs no eigenpairs of its own: it only truncates the completion's k' × k'
        // map (min(refine_k, k')).
        if self.refine == Refine::Zoomout {
            k = k.max(self.zoomout_to);
        }
        k
    }
}

/// What the coupled-bases solver (eq. (7)) did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoupledReport {
    /// Conjugate-gradient iterations done.
    pub iterations: usize,
    /// Final data term ‖Âᵀ P − B̂ᵀ Q‖² / s.
    pub data: f64,
    /// Final off(Pᵀ Λ̃_X P) (not multiplied by μ1).
    pub off_x: f64,
    /// Final off(Qᵀ Λ̃_Y Q) (not multiplied by μ2).
    pub off_y: f64,
}

/// What the solver of a method did, for the methods that iterate: the coupled bases and the
/// completion method. Serialized as the report inside (no tag).
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum SolverReport {
    /// The coupled bases, eq. (7).
    Coupled(CoupledReport),
    /// The completion method, eqs. (8)–(11).
    Completion(completion::SolverReport),
}

impl SolverReport {
    /// Iterations the solver did.
    pub fn iterations(&self) -> usize {
        match self {
            SolverReport::Coupled(r) => r.iterations,
            SolverReport::Completion(r) => r.iterations(),
        }
    }
}

/// One stage of a run and its wall time.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTime<'a> {
    /// The stage's name.
    pub stage: &'a str,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// The axiomatic method's candidates and the one chosen.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateChoice<'a> {
    /// Every candidate and its scores.
    pub candidates: &'a [axiomatic::Candidate],
    /// Index of the chosen candidate.
    pub chosen: usize,
}

/// The serializable record of a run, with the sizes and options it ran with (the bulk of the
/// `report.json` of `funcorr match`, which adds the input files).
#[derive(Clone, Debug, Serialize)]
pub struct MatchReport<'a> {
    /// Vertices of X.
    pub n: usize,
    /// Vertices of Y.
    pub m: usize,
    /// Number of data functions.
    pub q: usize,
    /// The options of the run.
    pub options: &'a MatchOptions,
    /// Eigenpairs computed per shape.
    pub basis_size: usize,
    /// Size (rows) of the final functional map.
    pub final_k: usize,
    /// The solver's report (methods that iterate).
    pub solver: Option<&'a SolverReport>,
    /// The axiomatic method's candidates.
    pub candidates: Option<CandidateChoice<'a>>,
    /// The axiomatic method's basin search: what its correction did.
    pub correction: Option<&'a search::Correction>,
    /// The axiomatic method's partial detection: whether X was matched as a part of Y, and why.
    pub partial: Option<&'a partial::Detection>,
    /// Number of user landmarks the run used ([`landmarks`]; 0: none).
    pub landmarks: usize,
    /// With landmarks: how well they agree with each other ([`landmarks::LandmarkCheck`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub landmark_check: Option<&'a landmarks::LandmarkCheck>,
    /// The stages in order.
    pub stages: Vec<StageTime<'a>>,
}

/// What [`run`] produced.
#[derive(Clone, Debug)]
pub struct MatchResult {
    /// The point-to-point map X → Y (length n, vertices of Y).
    pub map_xy: Vec<usize>,
    /// A point-to-point map Y → X (length m): the completion method's own extracted map when
    /// it is not refined, else the pull-back of the final functional map (for colour transfer).
    pub map_yx: Vec<usize>,
    /// The final functional map (between the input bases): the method's, or the refined one.
    pub c: Mat<f64>,
    /// The method's own functional map before refinement (k × k, or k' × k' for completion).
    pub c_method: Mat<f64>,
    /// The completion method's subspace coefficients (A, B), k' × k each.
    pub coefficients: Option<(Mat<f64>, Mat<f64>)>,
    /// The completion method's factors (L: m × r, R: n × r) with T = L Rᵀ.
    pub factors: Option<(Mat<f64>, Mat<f64>)>,
    /// The solver's report, for the completion method and the coupled bases.
    pub solver: Option<SolverReport>,
    /// (stage, seconds) in order.
    pub stages: Vec<(String, f64)>,
    /// The axiomatic method's candidates and the index of the chosen one.
    pub candidates: Option<(Vec<axiomatic::Candidate>, usize)>,
    /// The axiomatic method's basin search: what its correction did.
    pub correction: Option<search::Correction>,
    /// The axiomatic method's partial detection (None for the other methods).
    pub partial: Option<partial::Detection>,
    /// For a part X of Y: for every vertex of Y (length m) the confidence in [0, 1] that X
    /// covers it ([`partial::coverage`]; ≥ ½: covered).
    pub coverage: Option<Vec<f64>>,
    /// With landmarks (the axiomatic method): how well they agree with each other
    /// ([`landmarks::LandmarkCheck`]).
    pub landmark_check: Option<landmarks::LandmarkCheck>,
}

impl MatchResult {
    /// The record of this run on shapes of n and m vertices with q data functions, `basis_size`
    /// eigenpairs per shape and the options `opts` it ran with.
    pub fn report<'a>(
        &'a self,
        opts: &'a MatchOptions,
        n: usize,
        m: usize,
        q: usize,
        basis_size: usize,
    ) -> MatchReport<'a> {
        MatchReport {
            n,
            m,
            q,
            options: opts,
            basis_size,
            final_k: self.c.nrows(),
            solver: self.solver.as_ref(),
            candidates: self.candidates.as_ref().map(|(c, i)| CandidateChoice { candidates: c, chosen: *i }),
            correction: self.correction.as_ref(),
            partial: self.partial.as_ref(),
            landmarks: if opts.method == Method::Axiomatic { opts.axiomatic.landmarks.pairs.len() } else { 0 },
            landmark_check: self.landmark_check.as_ref(),
            stages: self.stages.iter().map(|(s, t)| StageTime { stage: s, seconds: *t }).collect(),
        }
    }
}

/// Point maps X → Y (length n) and Y → X (length m).
type MapPair = (Vec<usize>, Vec<usize>);

/// Runs stage `name` (reported to [`crate::progress`], which may cancel it) and records its time.
fn timed<T>(stages: &mut Vec<(String, f64)>, name: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    crate::progress::stage(name)?;
    let t = Instant::now();
    let r = f()?;
    stages.push((name.to_string(), t.elapsed().as_secs_f64()));
    Ok(r)
}

/// Runs the method of `opts` on bases `bx` (X, n vertices), `by` (Y, m) and data F (n × q), G
/// (m × q), then the refinement: every method but the axiomatic one, which needs the shapes'
/// surfaces ([`run`]). The vertex forms of the completion method also need the Laplacians.
/// Errors: options that [`MatchOptions::validate`] rejects, the axiomatic method, bases smaller
/// than [`MatchOptions::basis_size`], and those of the methods.
#[allow(clippy::too_many_arguments)]
pub fn run_on_bases(
    bx: &Basis,
    by: &Basis,
    laplacians: Option<(&Laplacian, &Laplacian)>,
    f: &Descriptors,
    g: &Descriptors,
    opts: &MatchOptions,
) -> Result<MatchResult> {
    run_with_gradients(bx, by, laplacians, None, None, f, g, opts)
}

/// The completion method's optional axiomatic prior ([`completion::solve_with_prior`]) when its
/// weight `opts.completion.params.mu_prior` is > 0: the energy of the axiomatic fit
/// (`opts.axiomatic.fit`: Laplacian mask, weights, orientation) without its descriptor term, from
/// the completion's data F, G, on the leading k_c × k_c block (k_c = `params.k_comm`, all k' when
/// 0). The orientation term needs the face gradients of both shapes.
fn completion_prior(
    bx: &Basis,
    by: &Basis,
    gradients: Option<(&crate::operators::FaceGradients, &crate::operators::FaceGradients)>,
    f: &Descriptors,
    g: &Descriptors,
    opts: &MatchOptions,
) -> Result<Option<crate::fmap::energy::Energy>> {
    use crate::fmap::axiomatic::{spectral_side, ShapeData};
    use crate::fmap::energy::{Energy, EnergyWeights, Orientation};
    let params = &opts.completion.params;
    if params.mu_prior <= 0.0 {
        return Ok(None);
    }
    let kp = opts.completion.k_prime;
    let kc = if params.k_comm == 0 { kp } else { params.k_comm.min(kp) };
    let fit = &opts.axiomatic.fit;
    let w = EnergyWeights { descriptors: 0.0, ..fit.weights };
    let orient = w.orientation > 0.0 && fit.orientation != Orientation::Ignore;
    let (gx, gy) = match gradients {
        Some((gx, gy)) => (Some(gx), Some(gy)),
        None => (None, None),
    };
    let sx = ShapeData { basis: bx, gradients: gx, descriptors: f, cells: None };
    let sy = ShapeData { basis: by, gradients: gy, descriptors: g, cells: None };
    let side_x = spectral_side(&sx, kc, w.commutativity > 0.0, orient, fit.unit_gradients, "X")?;
    let side_y = spectral_side(&sy, kc, w.commutativity > 0.0, orient, fit.unit_gradients, "Y")?;
    Ok(Some(Energy::new(&side_x, &side_y, &w, fit.mask, fit.orientation)?))
}

/// [`run`] with the face gradients of both shapes, for the completion method's orientation prior.
#[allow(clippy::too_many_arguments)]
fn run_with_gradients(
    bx: &Basis,
    by: &Basis,
    laplacians: Option<(&Laplacian, &Laplacian)>,
    gradients: Option<(&crate::operators::FaceGradients, &crate::operators::FaceGradients)>,
    points: Option<crate::spatial::PositionPair>,
    f: &Descriptors,
    g: &Descriptors,
    opts: &MatchOptions,
) -> Result<MatchResult> {
    opts.validate()?;
    let need = opts.basis_size();
    if bx.k() < need || by.k() < need {
        return Err(Error::invalid(
            "bases",
            format!("these options need {need} eigenpairs per shape, the bases hold {} and {}", bx.k(), by.k()),
        ));
    }
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let mut stages = Vec::new();
    let mut solver = None;
    let (mut coefficients, mut factors) = (None, None);
    let ovs = OvsjanikovOptions { commutativity: opts.commutativity };
    // The method: a functional map and, for completion, a point map of its own.
    let (c_method, method_maps): (Mat<f64>, Option<MapPair>) = match opts.method {
        Method::Axiomatic => {
            return Err(Error::invalid("method", "the axiomatic method needs prepared shapes (matching::run)"));
        }
        Method::Fmap => (timed(&mut stages, "functional map", || fmap::ovsjanikov(bx, by, f, g, opts.k, &ovs))?, None),
        Method::Pokrass => {
            (timed(&mut stages, "functional map", || Ok(fmap::pokrass(bx, by, f, g, opts.k, &opts.pokrass)?.0))?, None)
        }
        Method::Coupled => {
            let (c, info) =
                timed(&mut stages, "functional map", || fmap::coupled(bx, by, f, g, opts.k, &opts.coupled))?;
            solver = Some(SolverReport::Coupled(CoupledReport {
                iterations: info.iterations,
                data: info.data,
                off_x: info.off_x,
                off_y: info.off_y,
            }));
            (c, None)
        }
        Method::Completion => {
            let kp = opts.completion.k_prime;
            // The start C0 (init_k × init_k) must fit in the k' × k coefficients.
            let init_k = opts.init_k.min(kp).min(opts.completion.k);
            let c0 = timed(&mut stages, "initial map", || fmap::ovsjanikov(bx, by, f, g, init_k, &ovs))?;
            let prior = timed(&mut stages, "prior", || completion_prior(bx, by, gradients, f, g, opts))?;
            let s = timed(&mut stages, "completion", || {
                completion::solve_with_prior(
                    bx,
                    by,
                    laplacians,
                    f,
                    g,
                    c0.as_ref(),
                    &opts.completion,
                    prior.as_ref(),
                    points,
                )
            })?;
            // The method's own point maps are the output only without a refinement (which starts
            // from C and makes its own).
            let maps = match opts.refine {
                Refine::None => Some(timed(&mut stages, "extraction", || extract(&s, bx, by, opts.extraction))?),
                Refine::Icp | Refine::Zoomout => None,
            };
            solver = Some(SolverReport::Completion(s.report.clone()));
            coefficients = s.coefficients.clone();
            factors = Some((s.left.clone(), s.right.clone()));
            (s.c, maps)
        }
    };
    let (c, map_xy) = timed(&mut stages, "point-wise map", || -> Result<(Mat<f64>, Vec<usize>)> {
        // The start of the refinement: the method's map, for completion its leading
        // refine_k × refine_k block (T projected on the first refine_k eigenfunctions).
        let c_start = if matches!(opts.method, Method::Completion) {
            let kr = opts.refine_k.min(c_method.nrows());
            c_method.submatrix(0, 0, kr, kr).to_owned()
        } else {
            c_method.clone()
        };
        let direct = method_maps.as_ref().map(|(map_xy, _)| map_xy.clone());
        match opts.refine {
            Refine::None => match direct {
                Some(map) => Ok((c_method.clone(), map)),
                None => Ok((c_method.clone(), pointwise::map_from_fmap(phi, psi, c_method.as_ref())?)),
            },
            Refine::Icp => pointwise::icp(phi, psi, c_start.as_ref(), &opts.icp),
            Refine::Zoomout => {
                let o = ZoomOutOptions { k_final: opts.zoomout_to.max(c_start.nrows()), step: opts.zoomout_step };
                pointwise::zoomout(phi, psi, &by.mass, c_start.as_ref(), &o)
            }
        }
    })?;
    let map_yx = match (&method_maps, opts.refine) {
        (Some((_, map_yx)), Refine::None) => map_yx.clone(),
        _ => timed(&mut stages, "map Y → X", || pointwise::map_yx_from_fmap(phi, psi, c.as_ref()))?,
    };
    Ok(MatchResult {
        map_xy,
        map_yx,
        c,
        c_method,
        coefficients,
        factors,
        solver,
        stages,
        candidates: None,
        correction: None,
        partial: None,
        coverage: None,
        landmark_check: None,
    })
}

/// The whole pipeline on prepared shapes X and Y with data F (n × q) on X and G (m × q) on Y:
/// every method (the axiomatic one reads the shapes' surfaces; the others run as
/// [`run_on_bases`] with their bases and Laplacians). For the axiomatic method `c` is the
/// transpose of the pull-back C_yx of `map_xy` (k × k; for a bijective isometry the two agree),
/// `c_method` the chosen candidate's fit, transposed the same way, and `map_yx` the point map
/// Y → X read off the same pull-back ([`crate::refine::map_yx_of_pullback`]). Errors: options
/// that [`MatchOptions::validate`] rejects, and those of the method.
///
/// ```no_run
/// use funcorr::descriptors::spec::PairDataSpec;
/// use funcorr::matching::{self, MatchOptions};
/// use funcorr::prepared::{LaplacianChoice, PreparedShape};
/// use funcorr::shape::Shape;
/// # fn main() -> funcorr::Result<()> {
/// let prepare = |p: &str| PreparedShape::new(Shape::load(std::path::Path::new(p))?, LaplacianChoice::Auto, 200, None);
/// let (x, y) = (prepare("data/faust/tr_reg_000.off")?, prepare("data/faust/tr_reg_001.off")?);
/// let (f, g) = "wks".parse::<PairDataSpec>()?.functions(x.parts(), y.parts(), &Default::default())?;
/// let mut opts = MatchOptions::default(); // what `funcorr match X Y` runs
/// opts.axiomatic.polish = 0;
/// opts.validate()?;
/// let r = matching::run(&x, &y, &f, &g, &opts)?;
/// assert_eq!(r.map_xy.len(), x.n()); // for every vertex of X a vertex of Y
/// # Ok(()) }
/// ```
pub fn run(
    x: &crate::prepared::PreparedShape,
    y: &crate::prepared::PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    opts: &MatchOptions,
) -> Result<MatchResult> {
    run_cow(x, y, Cow::Borrowed(f), Cow::Borrowed(g), opts)
}

/// [`run`] with the data F and G handed over: the default (axiomatic) method releases them as
/// soon as it has made its own data from them ([`axiomatic::axiomatic_pipeline_cow`]), so a
/// front end that needs them no more after the match (`funcorr match`) does not hold them
/// through the refinement. The result is [`run`]'s.
pub fn run_owned(
    x: &crate::prepared::PreparedShape,
    y: &crate::prepared::PreparedShape,
    f: Descriptors,
    g: Descriptors,
    opts: &MatchOptions,
) -> Result<MatchResult> {
    run_cow(x, y, Cow::Owned(f), Cow::Owned(g), opts)
}

fn run_cow(
    x: &crate::prepared::PreparedShape,
    y: &crate::prepared::PreparedShape,
    f: Cow<'_, Descriptors>,
    g: Cow<'_, Descriptors>,
    opts: &MatchOptions,
) -> Result<MatchResult> {
    opts.validate()?;
    if opts.method != Method::Axiomatic {
        if opts.partial.mode == partial::PartialMode::Always {
            return Err(Error::invalid(
                "partial",
                "partial matching is a path of the axiomatic method (the default); other methods match whole shapes",
            ));
        }
        if !opts.axiomatic.landmarks.is_empty() {
            return Err(Error::invalid(
                "landmarks",
                "landmarks act in the default (axiomatic) method only; for the other methods give them as data \
                 (landmarks:pairs.txt)",
            ));
        }
        let orient = opts.method == Method::Completion
            && opts.completion.params.mu_prior > 0.0
            && opts.axiomatic.fit.weights.orientation > 0.0
            && opts.axiomatic.fit.orientation != crate::fmap::energy::Orientation::Ignore;
        let gradients = match (orient, x.gradients(), y.gradients()) {
            (true, Some(gx), Some(gy)) => Some((gx, gy)),
            _ => None,
        };
        let points = x.positions().zip(y.positions());
        let r = run_with_gradients(
            &x.basis,
            &y.basis,
            Some((&x.laplacian, &y.laplacian)),
            gradients,
            points,
            &f,
            &g,
            opts,
        )?;
        return Ok(in_input_units(r, x, y));
    }
    let detection = partial::detect(x, y, &opts.partial);
    if detection.partial {
        return run_partial(x, y, &f, &g, opts, detection);
    }
    let r = axiomatic::axiomatic_pipeline_cow(x, y, f, g, &opts.axiomatic)?;
    let mut stages = r.stages;
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    // The map Y → X from the final pull-back (NearSearch: exact, or certified exact, up to
    // `inverse_certified_up_to` vertex pairs).
    let mut map_yx = timed(&mut stages, "map Y → X", || match (&r.near_samples, x.positions(), y.positions()) {
        (Some((sx, sy)), Some(px), Some(py)) => {
            let near = &opts.axiomatic.near;
            if (px.len() as u64).saturating_mul(py.len() as u64) <= near.inverse_certified_up_to {
                // Near the preimages of the final map X → Y, then certified exact.
                let near = crate::refine::Near { x: px, y: py, cells: near.cells, certify: true };
                crate::refine::map_yx_near_map(phi, psi, r.c_yx.as_ref(), &near, &r.map_xy)
            } else {
                // Near the samples' map, not certified.
                let near = crate::refine::Near { x: px, y: py, cells: near.cells, certify: false };
                let scope = crate::refine::Scope::Near { near: &near, x_cells: &sx.vertices, y_cells: &sy.vertices };
                crate::refine::map_yx_of_pullback(phi, psi, r.c_yx.as_ref(), scope)
            }
        }
        _ => crate::refine::map_yx_of_pullback(phi, psi, r.c_yx.as_ref(), crate::refine::Scope::Exact),
    })?;
    // The landmarks' images are pinned in the map back too (module `landmarks`).
    for &(i, j) in &opts.axiomatic.landmarks.pairs {
        map_yx[j] = i;
    }
    let r = MatchResult {
        map_xy: r.map_xy,
        map_yx,
        c: r.c_yx.transposed(),
        c_method: r.c_fit.transposed(),
        coefficients: None,
        factors: None,
        solver: None,
        stages,
        candidates: Some((r.candidates, r.chosen)),
        correction: r.correction,
        partial: Some(detection),
        coverage: None,
        landmark_check: r.landmark_check,
    };
    Ok(in_input_units(r, x, y))
}

/// The partial path of [`run_prepared`] ([`partial::partial_pipeline`]): `c` (k_Y × k_X) is the
/// transpose of the final pull-back C_yx, `map_yx` its pull-back point map Y → X (for colour
/// transfer: the vertices of Y that X does not cover get a vertex of X all the same; see
/// `coverage`).
fn run_partial(
    x: &crate::prepared::PreparedShape,
    y: &crate::prepared::PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    opts: &MatchOptions,
    mut detection: partial::Detection,
) -> Result<MatchResult> {
    let r = partial::partial_pipeline(x, y, f, g, &opts.axiomatic, &opts.partial)?;
    detection.used_ratio = Some(r.area_ratio);
    detection.heat_minima = Some(r.heat_minima.clone()).filter(|m| !m.is_empty());
    detection.metric_polish = r.polish;
    detection.covered_region = r.covered;
    detection.finalists = r.finalists;
    let mut stages = r.stages;
    let c = r.c_yx.transpose().to_owned();
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    let map_yx = timed(&mut stages, "map Y → X", || {
        crate::refine::map_of_pullback(psi, phi, c.as_ref(), None, crate::refine::Scope::Exact)
    })?;
    let r = MatchResult {
        map_xy: r.map_xy,
        map_yx,
        c,
        c_method: r.c_fit.transpose().to_owned(),
        coefficients: None,
        factors: None,
        solver: None,
        stages,
        candidates: Some((r.candidates, r.chosen)),
        correction: r.correction,
        partial: Some(detection),
        coverage: Some(r.coverage),
        landmark_check: r.landmark_check,
    };
    Ok(in_input_units(r, x, y))
}

/// A result computed between the unit-area bases of prepared shapes
/// ([`crate::prepared`], "Units") with its functional maps between the input bases: C (k_Y × k_X,
/// coefficients on X → on Y) scales by √(area_Y / area_X), and so does the completion method's
/// factor A of C = A Bᵀ. Point maps and the completion's T = L Rᵀ are unit-free.
fn in_input_units(
    mut r: MatchResult,
    x: &crate::prepared::PreparedShape,
    y: &crate::prepared::PreparedShape,
) -> MatchResult {
    let s = (y.area / x.area).sqrt();
    if s != 1.0 {
        r.c = &r.c * faer::Scale(s);
        r.c_method = &r.c_method * faer::Scale(s);
        if let Some((a, _)) = &mut r.coefficients {
            *a = &*a * faer::Scale(s);
        }
    }
    r
}

/// The completion method's point maps X → Y and Y → X by `how`.
fn extract(s: &completion::Solution, bx: &Basis, by: &Basis, how: Extraction) -> Result<(Vec<usize>, Vec<usize>)> {
    let (l, r): (MatRef<f64>, MatRef<f64>) = (s.left.as_ref(), s.right.as_ref());
    match how {
        Extraction::Nn => Ok((pointwise::nearest_neighbors(l, r)?, pointwise::nearest_neighbors(r, l)?)),
        Extraction::Argmax => Ok((pointwise::max_inner_product(l, r)?, pointwise::max_inner_product(r, l)?)),
        Extraction::Fmap => {
            let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
            Ok((
                pointwise::map_from_fmap(phi, psi, s.c.as_ref())?,
                pointwise::map_yx_from_fmap(phi, psi, s.c.as_ref())?,
            ))
        }
    }
}
