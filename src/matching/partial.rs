//! Partial → full matching: X is a part of Y (a scan from one side, a shape cut by a plane, a
//! missing limb), and every vertex of X is matched to a vertex of Y while most of Y has no
//! preimage.
//!
//! **Why the pull-back direction suits a part.** The pipeline works with C_yx (k_X × k_Y), the
//! pull-back of functions on Y to functions on X (`crate::refine`). Restricting a function of Y
//! to the part is exact, so the data identity F = Π G, the descriptor commutativity and the
//! orientation term hold for a part as for a whole; what changes is the spectrum. The part's
//! Laplacian (cotangent, natural Neumann boundary conditions) has, by Weyl's law, eigenvalue j
//! near the whole's eigenvalue j / r, r = area(X) / area(Y), in the same units: the j-th
//! function of Y restricted to X lives in the first ≈ r·j functions of X, and C_yx is slanted,
//! k_X ≈ r k_Y (Rodolà et al. 2017, "Partial functional correspondence"). So:
//!
//! 0. **Scale** ([`PartialOptions::scale`]): r is the area of Y that X covers over area(Y). It
//!    is area(X) / area(Y) only when the shapes share a scale, which shapes scaled to a common
//!    height do not (FAUST's poses differ in area by up to 1.9×), nor a part in millimetres
//!    and a whole in metres. By default ([`PartialScale::Heat`]) r is found without units from
//!    the heat kernels ([`super::heat_scale`]: X's log-time heat profiles shifted by log r
//!    against Y's, [`part_heat_scale`]: X's profiles corrected for the reflection of heat at
//!    its cut). Their energy can have two near-equal minima (a body's legs and pelvis at half
//!    their area look like its arms and shoulders): area(X) / area(Y) chooses among the minima
//!    within 30 % of the least, and is itself kept when the profiles fit it within
//!    [`HEAT_PRIOR_TOLERANCE`] of the chosen minimum. On faust_r_partial the ratio so found is
//!    off the covered fraction by more than 15 % on 8 of 97 pairs (11 with the least energy
//!    alone, 35 with the area ratio); on tosca_r_partial (shared scale) on none
//!    (EXPERIMENTS.md). A ratio the user knows ([`PartialOptions::ratio`], `--partial-ratio`)
//!    replaces the estimate. The data ([`pair_wks`]) are then computed again at r. The older
//!    estimate from sample maps found by geodesic distances alone ([`estimate_ratio()`],
//!    [`PartialScale::Distances`]) errs low on many pairs.
//! 1. **Data** in common units: the descriptors F, G are divided by the norms of G's columns on
//!    Y (not each by its own: F is a piece of G), plus signed descriptors (low-passed to
//!    r · `signed_smoothing` functions of X and `signed_smoothing` of Y). [`pair_wks`] gives WKS
//!    at the same energies on both shapes (X's eigenvalues in Y's units), the default data.
//! 2. **Candidates**: the axiomatic energy ([`crate::fmap::energy`]) of a rectangular C_yx,
//!    k_X = ⌈`slope` · r · k_Y⌉, at the sizes k_Y of `candidates`, X's eigenvalues divided by r
//!    (the mask then follows the slanted diagonal).
//! 3. **Basin search** ([`super::search`]): each candidate refined by a short ZoomOut for a
//!    part (below) and scored by the geodesic distortion of its map on 200 samples of X against
//!    500 anchors of Y (X's distances in Y's units: distances on a part are at least those on
//!    the whole, so the score is valid for a part), its data misfit and its orientation; its
//!    samples corrected by L1 trilateration and the best correction probed as one more
//!    candidate; the spectral choice is the best of these. Then [`PartialOptions::seeded`]
//!    sample maps found by distances alone ([`search::seeded_maps`]: three far-apart samples of
//!    X placed on every consistent triple of Y's anchors) challenge it: the one of least
//!    distortion after the correction (orientation as asked) replaces it when its corrected
//!    sample map fits X's distances better at [`SEEDED_DOMINANCE`] (¾) of the samples or more
//!    ([`search::sample_distortions`], [`search::dominance`]; both maps corrected alike, so that
//!    neither is favoured by more optimization). Distances alone find the basin where the
//!    descriptors of a part are too weak (a body without its arms, whose raised arms the fits
//!    took for legs), but cannot tell a part from the part turned by half a turn; a near-symmetric
//!    map fits about half of the samples better, a map in a truly better basin almost all of
//!    them. On faust_r_partial the mean error went from 12.50 to 9.25 (pairs above 10: 24 →
//!    17; 11 pairs better, 1 worse), on tosca_r_partial from 10.21 to 8.54 (EXPERIMENTS.md);
//!    about 0.45 s more on a 2k → 5k pair.
//! 4. **Refinement**: ZoomOut for a part (k_Y up to `refine.k_final`) on farthest-point samples
//!    of X, then rounds on every vertex of X. Each step pulls the point map back with twice the
//!    slope's k_X (so that X's functions hold the restrictions of Y's almost exactly) and reads
//!    the map the way a part's map is exact (`restricted_map`: rows of Ψ against rows of
//!    Φ C_yx, not rows of Φ against Ψ C_yxᵀ, which would need X's functions carried to Y, cut
//!    off at the edge of the covered region). No bijective polish: the map is not a bijection.
//! 5. **Metric polish** ([`refine::metric_polish`], [`PartialOptions::metric_anchors`]): the
//!    restricted reading holds the basin but leaves regions slid by one to three edges, or laid
//!    on a nearby sheet of Y; every vertex of X is moved to the vertex of Y whose geodesic
//!    distances to the images of 128 anchors best repeat its own (X's distances in Y's units,
//!    trimmed: a geodesic of the part that runs around the cut is dropped), combined with the
//!    restricted reading, each term divided by its own floor. A distance on the part is a
//!    distance on the whole, so on a part cut from the same mesh the distances decide and give
//!    the identity (`tests/partial.rs`: 98.9 % of the vertices, against 32.8 % before); on
//!    faust_r_partial the pairs below 10 gain a little, tosca_r_partial is unchanged
//!    (EXPERIMENTS.md). About 0.35 s on a 2k → 5k pair.
//! 6. **Coverage** ([`coverage`]): a confidence on every vertex of Y that X covers it, from the
//!    geodesic distance to the nearest image of X, thresholded so that the covered area is
//!    r · area(Y).
//! 7. **The covered region as a whole shape** ([`PartialOptions::covered`],
//!    [`super::covered`]): the region of Y the map covers (confidence ≥ ½) has a boundary where
//!    X has its cut, so X and it are matched as two whole shapes are: the whole pipeline's
//!    ZoomOut and bijective polish from the map's smooth part, then the metric polish with the
//!    region's own distances; the coverage is computed again from the result. Y's
//!    eigenfunctions, which steps 2–5 read maps with, do not turn at the cut, and left typical
//!    pairs' maps slid by a few edges everywhere: on faust_r_partial the mean went from 7.68 to
//!    7.09 and the pairs below 10 from 4.10 to 3.27, on tosca_r_partial from 8.54 to 8.01
//!    (EXPERIMENTS.md). About 1 s on a 2k → 5k pair.
//! 8. **Finalists** ([`PartialOptions::finalists`]): a choice between two basins made on
//!    samples can be undone only by a final map. When step 3's challenger fits at least
//!    [`FINALIST_DOMINANCE`] (½) of the samples better than the choice (whichever of the two
//!    was chosen), both are finished (steps 4–7) and the other replaces the choice when its
//!    final map's orientation score ([`search::orientation`]) is higher by
//!    [`FINALIST_ORIENTATION_MARGIN`] or more. Distances cannot judge the two: a map in the
//!    wrong basin, finished, fits its covered region as well as the right one (a body's halves
//!    are near-isometric), and the samples' orientation is noisy before the refinement; the
//!    finished maps' orientation tells a part turned or mirrored from the right map. On
//!    faust_r_partial the mean went from 7.09 to 5.97 (pairs above 10: 14 → 11; 3 switched,
//!    all right), on tosca_r_partial from 8.01 to 7.84 (1 switched), the faust parts as clouds
//!    from 15.13 to 14.22 (3 switched), none worse (EXPERIMENTS.md). About 2 s more on a contested 2k → 5k pair (half of the pairs).
//!
//! **Landmarks** (`AxiomaticPipeline::landmarks`, `--landmarks`; [`super::landmarks`]): a few
//! known pairs decide what distances and orientation cannot — a part of another body against
//! the same part turned by half a turn about its long axis or mirrored front to back, which fit
//! the samples' distances as well as the right map or better (EXPERIMENTS.md, "Which basins a
//! part's candidates hold"). As in the whole pipeline's choice: one more candidate from the
//! landmarks alone (the search samples trilaterated from their distances to the landmarks, X's
//! in Y's units, corrected by the search's rounds with that as their data term), every
//! candidate's landmark error (its probe's map at the landmarks of X) joins the score in units
//! of `landmarks.tolerance`, and where no candidate of the asked orientation respects them they,
//! not the orientation, tell a map from its mirror image. The choice is then final (no seeded
//! challenger, no second finalist), and the landmarks are pinned in the final map. Not used on
//! this path: the landmark functions in the fits' data and the pins inside ZoomOut and the
//! polishes. `tests/partial.rs`: five landmarks at the mirrored images turn the cut copy's map
//! into the mirror map against the orientation asked.
//!
//! **Detection** ([`detect`]): X is taken for a part when its boundary (total length of its
//! boundary loops, / √area(X)) exceeds Y's (/ √area(Y)) by at least `min_boundary` and its area
//! is at most `max_area_ratio` of Y's: in the inputs' units, or, where those say X is larger,
//! without units from the heat kernels (as in step 0, over [0.1, 2 · `max_area_ratio`]), since
//! two files need not share a unit (a part in millimetres, the whole in metres). The default
//! 1.5 is loose on purpose: remeshed FAUST bodies differ in area by up to 1.9× between poses,
//! and 17 of faust_r_partial's 97 parts have more area than their target; the boundary tells
//! (whole benchmark shapes have none). Point clouds have no boundary to measure: only
//! `--partial` (`PartialMode::Always`) sends them here.
//!
//! One module over 600 lines: detection, scale, data, rectangular fits, the partial reading of
//! the maps and the coverage are the steps of one algorithm whose parts share its conventions
//! (the slope k_X ≈ r k_Y, the restricted reading); its tests are in `tests/partial.rs`.

use faer::Mat;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::axiomatic::{agrees, choose, samples_of, AxiomaticPipeline, Candidate};
use super::landmarks::LandmarkData;
use super::search::{self, SampleDistances};
use crate::descriptors::signatures::{wks_energies, WksRecipe};
use crate::descriptors::spec::PairDataSpec;
use crate::descriptors::{self, Descriptors};
use crate::error::{Error, Result};
use crate::fmap::axiomatic::{constant_column, spectral_side, ShapeData};
use crate::fmap::energy::{Energy, Orientation};
use crate::geodesic::GraphGeodesics;
use crate::prepared::PreparedShape;
use crate::refine::{self, Scope};
use crate::shape::Shape;
use crate::spatial::Samples;

/// When the partial path runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PartialMode {
    /// When [`detect`] finds X to be a part of Y (the default).
    #[default]
    Auto,
    /// Always (`--partial`): X is a part of Y.
    Always,
    /// Never: X is matched as a whole shape.
    Never,
}

/// Options of the partial path.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartialOptions {
    /// When it runs.
    pub mode: PartialMode,
    /// Detection: largest area ratio of a part, X's area in Y's units / area(Y) (dimensionless;
    /// default 1.5, module docs).
    pub max_area_ratio: f64,
    /// Detection: smallest excess of X's boundary length (in units of √area(X)) over Y's (in
    /// units of √area(Y)) for a part (dimensionless).
    pub min_boundary: f64,
    /// k_X = ⌈slope · r · k_Y⌉ for the rectangular functional maps C_yx (k_X × k_Y).
    pub slope: f64,
    /// Sample maps found from distances alone ([`search::seeded_maps`]) probed as challengers of
    /// the spectral choice (module docs, step 3; default [`SEEDED`]; 0: none). They are blind to
    /// orientation and to near-symmetries: as ordinary candidates they turned parts by half a
    /// turn (EXPERIMENTS.md), so one replaces the spectral choice only when it fits
    /// [`SEEDED_DOMINANCE`] of the samples better.
    #[serde(default = "seeded")]
    pub seeded: usize,
    /// The data F, G are [`pair_wks`] of this recipe: when the area ratio r is estimated
    /// ([`PartialOptions::scale`]) and differs from area(X) / area(Y) they are computed again
    /// at r (None: other data, kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wks: Option<WksRecipe>,
    /// How the area ratio r is found (module docs, step 0; default [`PartialScale::Heat`]).
    #[serde(default)]
    pub scale: PartialScale,
    /// Anchors (farthest-point samples of X) of the metric polish of the final map (module
    /// docs, step 5; default [`METRIC_ANCHORS`]; 0: no polish; skipped when m times this
    /// exceeds [`METRIC_MAX_ENTRIES`]).
    #[serde(default = "metric_anchors")]
    pub metric_anchors: usize,
    /// The area ratio r when the user knows it: the share of Y's area that X covers
    /// (dimensionless, in (0, `max_area_ratio`]); it replaces step 0's estimate ([`scale`]),
    /// for the pairs whose heat profiles fit two ratios about as well (module docs, step 0).
    /// None (default): estimated.
    ///
    /// [`scale`]: PartialOptions::scale
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
    /// Refine the map on the covered region of Y as between two whole shapes (module docs,
    /// step 7; [`super::covered`]; default true).
    #[serde(default = "covered")]
    pub covered: bool,
    /// Finish both the choice and a challenger that contests it and keep the one whose final
    /// map keeps the orientation clearly better (module docs, step 8; default true).
    #[serde(default = "finalists")]
    pub finalists: bool,
}

fn covered() -> bool {
    true
}

fn finalists() -> bool {
    true
}

/// [`PartialOptions::metric_anchors`] by default: 128 (on the cut copy of `tests/partial.rs`,
/// with an earlier schedule of the polish, 64 anchors left 9 % of the vertices off the
/// identity, 96 and 128 none; EXPERIMENTS.md).
pub const METRIC_ANCHORS: usize = 128;

/// The metric polish runs when m · [`PartialOptions::metric_anchors`] is at most this (2·10⁷:
/// about 500 MB of distance fields and sorted lists; 128 anchors up to m = 156,250).
pub const METRIC_MAX_ENTRIES: usize = 20_000_000;

/// [`PartialOptions::seeded`] by default.
pub const SEEDED: usize = 4;

fn seeded() -> usize {
    SEEDED
}

fn metric_anchors() -> usize {
    METRIC_ANCHORS
}

impl Default for PartialOptions {
    fn default() -> Self {
        PartialOptions {
            mode: PartialMode::Auto,
            max_area_ratio: 1.5,
            min_boundary: 0.25,
            slope: 1.0,
            seeded: SEEDED,
            wks: None,
            scale: PartialScale::Heat,
            metric_anchors: METRIC_ANCHORS,
            ratio: None,
            covered: covered(),
            finalists: finalists(),
        }
    }
}

/// How the partial path finds the area ratio r (the area of Y that X covers / area(Y)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PartialScale {
    /// area(X) / area(Y) in the inputs' units: right only when the two share a scale.
    Area,
    /// From the heat kernels, without units ([`super::heat_scale`]); area(X) / area(Y) chooses
    /// among near-equal minima of the heat-profile energy, and is kept when it fits the heat
    /// profiles within [`HEAT_PRIOR_TOLERANCE`] of the chosen minimum.
    #[default]
    Heat,
    /// From sample maps found by geodesic distances alone ([`estimate_ratio()`]), replacing
    /// area(X) / area(Y) when the two differ by more than 10 % (errs low on many pairs,
    /// EXPERIMENTS.md).
    Distances,
}

/// [`PartialScale::Heat`]: area(X) / area(Y) is used when its heat-profile energy E is within
/// this relative margin of the minimum's (measured on faust_r_partial and tosca_r_partial: the
/// margins 0.05–0.2 give the same ratios within 1 %, EXPERIMENTS.md).
pub const HEAT_PRIOR_TOLERANCE: f64 = 0.1;
/// [`PartialScale::Heat`]: the range of r searched (a part of at least a tenth of the whole,
/// at most 1.2 times it for parts stretched against their whole) and the samples of X matched.
const HEAT_RANGE: (f64, f64) = (0.1, 1.2);
const HEAT_SAMPLES: usize = 500;

/// [`detect`]: the range of the unit-free area ratio searched from the heat kernels, up to
/// twice the largest ratio of a part (so that a shape larger than that is seen to be larger).
const DETECT_RANGE_FACTOR: f64 = 2.0;

/// What [`detect`] measured and decided.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Detection {
    /// area(X) / area(Y) (total vertex weights of the inputs, in the inputs' units).
    pub area_ratio: f64,
    /// The area ratio without units, from the heat kernels ([`super::heat_scale`]), when X's
    /// boundary made it a candidate part and its area in the inputs' units was too large (None
    /// otherwise, or when it could not be estimated).
    pub heat_ratio: Option<f64>,
    /// Total length of X's boundary loops / √area(X) (None for a point set).
    pub boundary_x: Option<f64>,
    /// The same for Y.
    pub boundary_y: Option<f64>,
    /// Whether the partial path runs.
    pub partial: bool,
    /// The area ratio the partial path used ([`PartialResult::area_ratio`]; None before it ran).
    pub used_ratio: Option<f64>,
    /// The ratios the heat profiles fit about equally well ([`PartialResult::heat_minima`]):
    /// more than one, and a ratio the user knows decides (`--partial-ratio`). None when not
    /// estimated from the heat kernels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heat_minima: Option<Vec<f64>>,
    /// What the metric polish of the final map did ([`PartialResult::polish`]; None before the
    /// partial path ran, with the polish off, or skipped for Y's size).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metric_polish: Option<crate::refine::MetricPolished>,
    /// What the refinement on the covered region did ([`PartialResult::covered`]; None before
    /// the partial path ran, with the step off, or skipped for a region too small).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covered_region: Option<super::covered::CoveredRefinement>,
    /// Both maps of a contested choice, finished and judged by their orientation
    /// ([`PartialResult::finalists`]; empty when the choice was not contested).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub finalists: Vec<Finalist>,
    /// Why, in words.
    pub reason: String,
}

/// Total length of the boundary loops of a shape / √area (None for a point set).
fn relative_boundary(s: &PreparedShape) -> Option<f64> {
    boundary_per_root_area(&s.shape, s.area)
}

/// Total length of the boundary loops of `shape` / √`area` (None for a point set).
fn boundary_per_root_area(shape: &Shape, area: f64) -> Option<f64> {
    let Shape::Mesh(m) = shape else { return None };
    let v = m.vertices();
    let length: f64 = m
        .boundary_loops()
        .iter()
        .map(|l| {
            (0..l.len())
                .map(|i| {
                    let (a, b) = (v[l[i] as usize], v[l[(i + 1) % l.len()] as usize]);
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                })
                .sum::<f64>()
        })
        .sum();
    // abs: the empty sum is −0.
    Some(length.abs() / area.sqrt())
}

/// Detection's first test: X's boundary (`bx`, in units of √area(X)) exceeds Y's (`by`) by
/// `opts.min_boundary` or more.
fn is_open(bx: f64, by: Option<f64>, opts: &PartialOptions) -> bool {
    bx - by.unwrap_or(0.0) >= opts.min_boundary
}

/// Whether [`detect`] can find X a part of Y, from the shapes as loaded and their areas alone
/// (`area_x`, `area_y`: Σ A of their Laplacians, [`crate::prepared::area_of_mass`], as
/// [`PreparedShape::area`]), before any eigenpair: `opts.mode` Always, or Auto with X a mesh whose
/// boundary exceeds Y's by `opts.min_boundary` (detection's first test, on the same areas; without
/// it X is whole whatever the eigenpairs say). The basis size depends on it
/// ([`super::MatchSettings::basis_demand_for`]): the partial path reads every eigenpair of the
/// bases, the full path only the first [`super::AXIOMATIC_BASIS_SIZE`].
pub fn may_be_partial(x: &Shape, area_x: f64, y: &Shape, area_y: f64, opts: &PartialOptions) -> bool {
    match opts.mode {
        PartialMode::Always => true,
        PartialMode::Never => false,
        PartialMode::Auto => match boundary_per_root_area(x, area_x) {
            None => false,
            Some(bx) => is_open(bx, boundary_per_root_area(y, area_y), opts),
        },
    }
}

/// The heat-kernel scale of a part X against Y ([`super::heat_scale::heat_scale_ratio`]) on
/// X's 500 farthest-point samples, with their geodesic distances to X's boundary
/// when X is a mesh with one (the correction near the cut), over `range`. Errors: X without
/// positions, and as [`super::heat_scale::heat_scale_ratio`].
pub fn part_heat_scale(
    x: &PreparedShape,
    y: &PreparedShape,
    range: (f64, f64),
    prior: Option<f64>,
) -> Result<super::heat_scale::HeatScale> {
    let positions =
        x.positions().ok_or_else(|| Error::invalid("shapes", "the heat scale of a part needs its vertex positions"))?;
    let xs = crate::spatial::farthest_point_samples(positions, &x.basis.mass, HEAT_SAMPLES)?;
    // A mesh's boundary only: a point cloud's triangle soup has open edges everywhere.
    let distances = match (&x.shape, x.triangles()) {
        (Shape::Mesh(_), Some(t)) => {
            let boundary: Vec<usize> = t.boundary_loops().into_iter().flatten().map(|v| v as usize).collect();
            if boundary.is_empty() {
                None
            } else {
                let (d, _) = GraphGeodesics::mesh_edges(t)?.nearest_sources(&boundary)?;
                Some(xs.vertices.iter().map(|&v| d[v]).collect::<Vec<f64>>())
            }
        }
        _ => None,
    };
    super::heat_scale::heat_scale_ratio(&x.basis, &y.basis, &xs.vertices, distances.as_deref(), range, prior)
}

/// The area ratio of X to Y without units ([`part_heat_scale`] over [0.1,
/// [`DETECT_RANGE_FACTOR`] · `max_area_ratio`]); None when it cannot be estimated (no positions,
/// too few eigenpairs).
fn unitless_ratio(x: &PreparedShape, y: &PreparedShape, max_area_ratio: f64) -> Option<f64> {
    let hi = DETECT_RANGE_FACTOR * max_area_ratio;
    if !(hi.is_finite() && hi > HEAT_RANGE.0) {
        return None;
    }
    part_heat_scale(x, y, (HEAT_RANGE.0, hi), None).ok().map(|h| h.ratio)
}

/// Whether X is a part of Y (module docs, "Detection"), or what `opts.mode` says.
pub fn detect(x: &PreparedShape, y: &PreparedShape, opts: &PartialOptions) -> Detection {
    let area_ratio = x.area / y.area;
    let (boundary_x, boundary_y) = (relative_boundary(x), relative_boundary(y));
    let mut heat_ratio = None;
    let (partial, reason) = match (opts.mode, boundary_x) {
        (PartialMode::Always, _) => (true, "asked (option partial)".to_string()),
        (PartialMode::Never, _) => (false, "partial matching turned off".to_string()),
        (PartialMode::Auto, None) => {
            (false, "X is a point set: no boundary to measure (use --partial for a part)".to_string())
        }
        (PartialMode::Auto, Some(b)) => {
            let open = is_open(b, boundary_y, opts);
            // The areas are in the inputs' units, which two files need not share (a part in
            // millimetres, the whole in metres): where they say that an open X is too large,
            // the ratio without units decides. Not everywhere: where the units are shared the
            // areas are exact, and on parts whose cut is long (boundary ≳ 3 √area) the heat ratio
            // erred high before its correction at the cut (5 of the 206 parts of faust_r_partial
            // and tosca_r_partial, EXPERIMENTS.md).
            let small_in_units = area_ratio <= opts.max_area_ratio;
            heat_ratio = if open && !small_in_units { unitless_ratio(x, y, opts.max_area_ratio) } else { None };
            let (ratio, what) = match heat_ratio {
                Some(r) => (r, "area ratio from the heat kernels"),
                None => (area_ratio, "area ratio"),
            };
            let small = ratio <= opts.max_area_ratio;
            let reason = format!(
                "{what} {ratio:.3} ({} {}), boundary length {b:.3} √area(X) beyond Y's ({} {})",
                if small { "≤" } else { ">" },
                opts.max_area_ratio,
                if open { "≥" } else { "<" },
                opts.min_boundary
            );
            (small && open, reason)
        }
    };
    Detection {
        area_ratio,
        heat_ratio,
        boundary_x,
        boundary_y,
        partial,
        used_ratio: None,
        heat_minima: None,
        metric_polish: None,
        covered_region: None,
        finalists: Vec::new(),
        reason,
    }
}

/// The WKS of both shapes at the same energies, for a part X of Y (module docs, step 1): the
/// energies of `recipe` from Y's first `recipe.eigenpairs` eigenvalues (as
/// [`crate::descriptors::signatures::wks_recipe`]), X's eigenvalues taken in Y's units (λ / r,
/// φ² / r on the unit-area bases) and cut at Y's largest one, so that both sums run over the
/// same band of frequencies. Not normalized per shape (the pipeline divides both by G's norms).
/// F: n × q, G: m × q. Errors: fewer than two non-zero eigenvalues, a bad recipe.
pub fn pair_wks(x: &PreparedShape, y: &PreparedShape, recipe: &WksRecipe) -> Result<(Descriptors, Descriptors)> {
    pair_wks_at(x, y, recipe, x.area / y.area)
}

/// The data functions of a pair that the partial path needs instead of `spec`'s: for the
/// axiomatic method with the default WKS recipe (`spec` [`PairDataSpec::WksRecipe`]) on a pair
/// whose X is a part of Y ([`detect`] under `opts.partial`), the WKS at the same energies on
/// both shapes ([`pair_wks`], F n × q and G m × q), and `opts.partial.wks` set so that the
/// pipeline computes them again at an estimated area ratio. None otherwise: the pair's data are
/// `spec`'s as for whole shapes. The one place the front ends (CLI, Python, benchmark) ask.
pub fn partial_pair_data(
    x: &PreparedShape,
    y: &PreparedShape,
    spec: &PairDataSpec,
    opts: &mut super::MatchOptions,
) -> Result<Option<(Descriptors, Descriptors)>> {
    if opts.method != super::Method::Axiomatic
        || *spec != PairDataSpec::WksRecipe
        || !detect(x, y, &opts.partial).partial
    {
        return Ok(None);
    }
    let recipe = WksRecipe::default();
    opts.partial.wks = Some(recipe);
    pair_wks(x, y, &recipe).map(Some)
}

/// [`pair_wks`] with the area ratio r of X (in Y's units) to Y given: X's eigenvalues are taken
/// as λ / r. Errors: as [`pair_wks`], and r not finite and > 0.
pub fn pair_wks_at(
    x: &PreparedShape,
    y: &PreparedShape,
    recipe: &WksRecipe,
    r: f64,
) -> Result<(Descriptors, Descriptors)> {
    if recipe.keep_every == 0 || recipe.eigenpairs < 2 || recipe.energies == 0 {
        return Err(Error::invalid("WKS recipe", "need energies ≥ 1, keep_every ≥ 1 and at least 2 eigenpairs"));
    }
    if !(r.is_finite() && r > 0.0) {
        return Err(Error::invalid("area ratio", format!("must be finite and > 0, got {r}")));
    }
    let ky = recipe.eigenpairs.min(y.basis.k());
    let mu = &y.basis.eigenvalues[..ky];
    let top = mu[ky - 1];
    let nonzero = |l: f64| l > 1e-8 * top;
    let first = mu.iter().copied().find(|&l| nonzero(l));
    let Some(first) = first.filter(|_| mu.iter().filter(|&&l| nonzero(l)).count() >= 2) else {
        return Err(Error::invalid("basis", "the WKS needs at least two non-zero eigenvalues of Y"));
    };
    let (all, sigma) = wks_energies(first, top, recipe.energies);
    let energies: Vec<f64> = all.into_iter().step_by(recipe.keep_every).collect();
    // One side: Σ_i φ_i(v)² g_e(λ_i) over the non-zero λ_i ≤ top, in Y's units.
    let side = |b: &crate::spectral::Basis, scale: f64| -> Result<Descriptors> {
        let used: Vec<usize> = (0..b.k())
            .filter(|&i| nonzero(b.eigenvalues[i] / scale) && b.eigenvalues[i] / scale <= top * (1.0 + 1e-9))
            .collect();
        let g = Mat::from_fn(used.len(), energies.len(), |t, j| {
            let l = b.eigenvalues[used[t]] / scale;
            (-(energies[j] - l.ln()).powi(2) / (2.0 * sigma * sigma)).exp()
        });
        let sq = Mat::from_fn(b.n(), used.len(), |v, t| b.eigenvectors[(v, used[t])].powi(2) / scale);
        Descriptors::new(
            crate::linalg::mul(sq.as_ref(), g.as_ref()),
            energies.iter().map(|e| format!("wks:e={e:.6}")).collect(),
        )
    };
    Ok((side(&x.basis, r)?, side(&y.basis, 1.0)?))
}

/// The L2 norm on Y (unit area) of every column of G.
fn column_norms(g: &Descriptors, mass: &[f64]) -> Vec<f64> {
    (0..g.q()).map(|j| g.values.col_as_slice(j).iter().zip(mass).map(|(v, a)| a * v * v).sum::<f64>().sqrt()).collect()
}

/// F and G divided by G's column norms on Y, and the signed descriptors of both in Y's units
/// (module docs, step 1). Errors: different column counts, a column of G of zero norm.
fn partial_data(
    x: &PreparedShape,
    y: &PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    p: &AxiomaticPipeline,
    r: f64,
) -> Result<(Descriptors, Descriptors)> {
    if f.q() != g.q() || f.n() != x.n() || g.n() != y.n() {
        return Err(Error::invalid(
            "data",
            format!("{} × {} on X and {} × {} on Y: need n × q and m × q", f.n(), f.q(), g.n(), g.q()),
        ));
    }
    let norms = column_norms(g, &y.basis.mass);
    if let Some(j) = norms.iter().position(|&v| !(v > 0.0 && v.is_finite())) {
        return Err(Error::invalid("data", format!("column {j} ({}) of Y's data has no norm", g.names[j])));
    }
    let scaled = |d: &Descriptors, norms: &[f64], s: f64| {
        Descriptors::new(Mat::from_fn(d.n(), d.q(), |i, j| s * d.values[(i, j)] / norms[j]), d.names.clone())
    };
    let (fx, gy) = (scaled(f, &norms, 1.0)?, scaled(g, &norms, 1.0)?);
    let (Some(grads_x), Some(grads_y)) = (x.gradients(), y.gradients()) else {
        return Ok((fx, gy));
    };
    if p.signed == 0 || p.fit.orientation == Orientation::Ignore || fx.q() < 2 {
        return Ok((fx, gy));
    }
    let pairs = descriptors::signed_pairs(fx.q(), 2 * p.signed);
    let smooth_x = ((r * p.signed_smoothing as f64).ceil() as usize).max(1);
    let sx = descriptors::signed(&fx, grads_x, &x.basis, &pairs, smooth_x)?;
    let sy = descriptors::signed(&gy, grads_y, &y.basis, &pairs, p.signed_smoothing)?;
    // X's gradients at unit area are √r times those in Y's units: the products, r times.
    let ny = column_norms(&sy, &y.basis.mass);
    let nx: Vec<f64> = column_norms(&sx, &x.basis.mass).iter().map(|v| v / r).collect();
    let (mx, my) = (nx.iter().fold(0.0f64, |a, &b| a.max(b)), ny.iter().fold(0.0f64, |a, &b| a.max(b)));
    let keep: Vec<usize> =
        (0..pairs.len()).filter(|&j| nx[j] > 1e-6 * mx && ny[j] > 1e-6 * my).take(p.signed).collect();
    if keep.is_empty() {
        return Ok((fx, gy));
    }
    let sign = if p.fit.orientation == Orientation::Reverse { -1.0 } else { 1.0 };
    let pick = |d: &Descriptors, s: f64| {
        Descriptors::new(
            Mat::from_fn(d.n(), keep.len(), |i, t| s * d.values[(i, keep[t])] / ny[keep[t]]),
            keep.iter().map(|&j| d.names[j].clone()).collect(),
        )
    };
    Ok((fx.concat(&pick(&sx, 1.0 / r)?)?, gy.concat(&pick(&sy, sign)?)?))
}

/// What [`partial_pipeline`] returns.
#[derive(Clone, Debug)]
pub struct PartialResult {
    /// The point map X → Y (length n).
    pub map_xy: Vec<usize>,
    /// The final pull-back functional map (k_X × k_Y, Y → X).
    pub c_yx: Mat<f64>,
    /// The chosen candidate's fit (k_X × k_Y, Y → X).
    pub c_fit: Mat<f64>,
    /// Every candidate, in the order of the options, then the corrected ones.
    pub candidates: Vec<Candidate>,
    /// Index of the chosen one.
    pub chosen: usize,
    /// (stage, seconds).
    pub stages: Vec<(String, f64)>,
    /// For every vertex of Y (length m) the confidence in [0, 1] that X covers it ([`coverage`]).
    pub coverage: Vec<f64>,
    /// What the correction of the candidate it started from did.
    pub correction: Option<search::Correction>,
    /// The area ratio r the result was computed with: area(X) / area(Y) or its estimate
    /// ([`PartialOptions::scale`], module docs step 0).
    pub area_ratio: f64,
    /// Step 0's near-equal minima of the heat-profile energy ([`super::heat_scale::HeatScale::minima`]):
    /// empty when r was given or found otherwise.
    pub heat_minima: Vec<f64>,
    /// What the metric polish did (module docs, step 5; None when it is off).
    pub polish: Option<refine::MetricPolished>,
    /// The refinement on the covered region (step 7), when it ran.
    pub covered: Option<super::covered::CoveredRefinement>,
    /// With a contested choice, both maps finished (the first choice first; module docs,
    /// step 8); empty otherwise.
    pub finalists: Vec<Finalist>,
    /// With landmarks: how well they agree with each other, X's distances in Y's units
    /// ([`super::landmarks::LandmarkCheck`]).
    pub landmark_check: Option<super::landmarks::LandmarkCheck>,
}

/// A candidate finished to a final map and judged by its orientation (module docs, step 8).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finalist {
    /// Its index among the candidates ([`PartialResult::candidates`]).
    pub candidate: usize,
    /// The orientation score of its final map on the search's samples of X
    /// ([`search::orientation`], in [−1, 1]).
    pub orientation: f64,
    /// Whether it is the result.
    pub chosen: bool,
    /// Its final map X → Y (length n, vertex ids of Y).
    #[serde(skip)]
    pub map_xy: Vec<usize>,
}

/// The index of the finalist kept (module docs, step 8): the second when its orientation score
/// exceeds the first's by [`FINALIST_ORIENTATION_MARGIN`] or more in the asked direction (the
/// score negated for orientation-reversing maps), else the first (0 for none; always the first
/// when orientation is ignored).
pub fn final_choice(finalists: &[Finalist], orientation: Orientation) -> usize {
    let sign = match orientation {
        Orientation::Preserve => 1.0,
        Orientation::Reverse => -1.0,
        Orientation::Ignore => return 0,
    };
    match finalists {
        [first, second] if sign * (second.orientation - first.orientation) >= FINALIST_ORIENTATION_MARGIN => 1,
        _ => 0,
    }
}

/// A challenger whose corrected sample map fits at least this share of the samples better than
/// the choice's ([`search::dominance`]) contests it (module docs, step 8): both are finished.
pub const FINALIST_DOMINANCE: f64 = 0.5;

/// The other finalist replaces the choice when its final map's orientation score exceeds the
/// choice's (in the asked direction, [`final_choice`]) by at least this (module docs, step 8). On faust_r_partial the other finalist's
/// score was higher by 0.51–0.69 where it was right and by at most 0.25 where it was in a wrong
/// basin; every margin in (0.25, 0.51] gives the same maps there (EXPERIMENTS.md).
pub const FINALIST_ORIENTATION_MARGIN: f64 = 0.4;

/// A seeded map (module docs, step 3) replaces the spectral choice when its corrected sample map
/// fits X's distances better at this share of the samples or more (per-sample distortions,
/// [`search::dominance`]). A map in another basin that is really better fits almost every
/// sample better; a near-symmetric one (a part turned by half a turn) about half of them. On
/// faust_r_partial the seeded maps that were right fitted 70–100 % of the samples better, the
/// wrong ones at most 68 % (EXPERIMENTS.md).
pub const SEEDED_DOMINANCE: f64 = 0.75;

/// Rounds of the final map read the other way (after the final ZoomOut).
const FINAL_ROUNDS: usize = 3;

/// The sample maps from distances alone ([`search::seeded_maps`]): check samples, triples kept
/// and placed (at least [`PartialOptions::seeded`]), the relative tolerance of the distances.
const SEED_CHECKS: usize = 6;
const SEED_KEEP: usize = 12;
const SEED_TOLERANCE: f64 = 0.15;

/// The sizes of the rectangular maps: k_X for a given k_Y.
#[derive(Clone, Copy)]
struct Slope {
    ratio: f64,
    max_x: usize,
}

impl Slope {
    fn kx(&self, ky: usize) -> usize {
        ((self.ratio * ky as f64).ceil() as usize).clamp(2.min(self.max_x), self.max_x)
    }
}

/// The point map X → Y of the pull-back C_yx (k_X × k_Y) of a point map, read in the direction
/// in which a part's map is exact: for every vertex i of X (`rows`, in that order, or all) the
/// vertex j of Y whose row of Ψ_{k_Y} is nearest to row i of Φ_{k_X} C_yx, the functions of Y
/// restricted to X as X's basis holds them (Π Ψ = Φ C_yx for the map Π when X's functions
/// represent the restrictions). The other reading, rows of Φ against rows of Ψ C_yxᵀ
/// ([`refine::map_of_pullback`], the whole pipeline's), needs X's functions carried to Y, and
/// on a part they are carried to the covered region only: cut off at its edge, which Y's first
/// functions cannot represent.
fn restricted_map(
    phi: faer::MatRef<f64>,
    psi: faer::MatRef<f64>,
    c: &Mat<f64>,
    rows: Option<&[usize]>,
) -> Result<Vec<usize>> {
    let (kx, ky) = (c.nrows(), c.ncols());
    let query = match rows {
        Some(r) => Mat::from_fn(r.len(), kx, |s, a| phi[(r[s], a)]),
        None => phi.subcols(0, kx).to_owned(),
    };
    let embedded = crate::linalg::mul(query.as_ref(), c.as_ref());
    crate::pointwise::nearest_neighbors(psi.subcols(0, ky), embedded.as_ref())
}

/// How a point map is read off a functional map C_yx.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Reading {
    /// [`restricted_map`] (rows of Ψ against rows of Φ C_yx), the pull-backs with twice the
    /// slope's k_X: exact for a part, but every smooth map is near a fixed point, so it holds a
    /// basin without pulling the map to an isometry.
    Restricted,
    /// [`refine::map_of_pullback`] (rows of Φ against rows of Ψ C_yxᵀ, ZoomOut's reading), the
    /// pull-backs with the slope's k_X: X's functions carried to Y are cut off at the edge of the
    /// covered region, which misleads it from a start far from the truth, but near the truth it
    /// pulls the map to an isometry (C_yx towards orthonormal rows), as ZoomOut does.
    Pushed,
}

/// Rectangular ZoomOut for a part on `samples` of X: the samples' images read off `c0` as
/// `first` says, then, up to k_Y = `ky_final`, the pull-back map of the next size (k_Y + step)
/// and its map read as `then` says; at least one step, so that the result is always a pull-back
/// of a point map (of k_X from `slope`, twice it for [`Reading::Restricted`]).
#[allow(clippy::too_many_arguments)]
fn zoomout(
    x: &PreparedShape,
    y: &PreparedShape,
    samples: &Samples,
    c0: &Mat<f64>,
    (first, then): (Reading, Reading),
    ky_final: usize,
    step: usize,
    slope: Slope,
) -> Result<Mat<f64>> {
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    let wide = Slope { ratio: 2.0 * slope.ratio, max_x: slope.max_x };
    let mut c = c0.clone();
    let mut ky = c.ncols();
    let step = step.max(1);
    let mut reading = first;
    loop {
        crate::progress::check()?;
        let map = match reading {
            Reading::Pushed => refine::map_of_pullback(phi, psi, c.as_ref(), Some(&samples.vertices), Scope::Exact)?,
            Reading::Restricted => restricted_map(phi, psi, &c, Some(&samples.vertices))?,
        };
        reading = then;
        ky = (ky + step).min(ky_final.max(ky));
        let kx = if then == Reading::Restricted { wide.kx(ky) } else { slope.kx(ky) };
        c = refine::pullback(phi, psi, samples, &map, kx, ky)?;
        if ky >= ky_final {
            return Ok(c);
        }
    }
}

/// The search's data (as the whole pipeline's), X's distances in Y's units.
struct PartialSearch {
    x: SampleDistances,
    y: SampleDistances,
    neighbours: Vec<Vec<usize>>,
    descriptors: Mat<f64>,
}

/// A probed candidate.
struct Probe {
    candidate: Candidate,
    c: Mat<f64>,
    images: Vec<usize>,
    corrected: [Option<(Vec<usize>, search::Correction)>; 2],
    /// Its sample map corrected by distances and data (empty without the correction).
    basin: Vec<usize>,
}

/// Runs the partial pipeline (module docs) from descriptors F (n × q) on the part X and G
/// (m × q) on the whole Y, with the pipeline options `p` (candidate sizes k_Y, probe and final
/// ZoomOut, search, signed descriptors, energy) and the partial options `o` (slope). Needs the
/// surfaces of both shapes (meshes or point clouds). Errors: as [`super::axiomatic::axiomatic_pipeline`], and a
/// shape without a surface.
pub fn partial_pipeline(
    x: &PreparedShape,
    y: &PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    p: &AxiomaticPipeline,
    o: &PartialOptions,
) -> Result<PartialResult> {
    if p.candidates.is_empty() || p.candidates.contains(&0) {
        return Err(Error::invalid("candidates", "need at least one functional-map size ≥ 1"));
    }
    if let Some(r) = o.ratio.filter(|r| !(r.is_finite() && *r > 0.0 && *r <= o.max_area_ratio)) {
        return Err(Error::invalid(
            "partial ratio",
            format!("the share of Y's area a part covers must be in (0, {}], got {r}", o.max_area_ratio),
        ));
    }
    if !(o.slope.is_finite() && o.slope > 0.0) {
        return Err(Error::invalid("partial slope", format!("must be finite and > 0, got {}", o.slope)));
    }
    let need = p.basis_size();
    if x.basis.k() < 2 || y.basis.k() < need {
        return Err(Error::invalid(
            "bases",
            format!(
                "the partial pipeline needs {need} eigenpairs of Y, the bases hold {} and {}",
                x.basis.k(),
                y.basis.k()
            ),
        ));
    }
    let (Some(tx), Some(ty), Some(px), Some(nx), Some(py), Some(ny)) =
        (x.triangles(), y.triangles(), x.positions(), x.normals(), y.positions(), y.normals())
    else {
        return Err(Error::invalid(
            "shapes",
            "partial matching needs the surfaces of both shapes (meshes or 3-D point clouds)",
        ));
    };
    let r0 = x.area / y.area;
    if !(r0.is_finite() && r0 > 0.0) {
        return Err(Error::invalid("shapes", format!("area ratio {r0} of X to Y")));
    }
    let t = std::time::Instant::now();
    crate::progress::stage("search samples")?;
    let (gx, gy) = rayon::join(|| GraphGeodesics::mesh_edges(tx), || GraphGeodesics::mesh_edges(ty));
    let (gx, gy) = (gx?, gy?);
    let surfaces = Surfaces { px, nx, py, ny, gx: &gx, gy: &gy };
    // The user's landmarks, checked before the work (module docs, "Landmarks").
    let lm = LandmarkData::from_graphs(&gx, &gy, &p.landmarks)?;
    let (sx, sy) = rayon::join(
        || SampleDistances::new(tx, &x.basis.mass, &gx, p.search.samples.max(3)),
        || SampleDistances::new(ty, &y.basis.mass, &gy, p.search.anchors.max(3)),
    );
    let (sx, sy) = (sx?, sy?);
    let search_seconds = t.elapsed().as_secs_f64();
    // The shapes' scales may differ (FAUST's bodies, remeshed and scaled to a common height,
    // differ in area by up to 1.9× between poses; a part in millimetres and a whole in metres):
    // r is estimated as `o.scale` says (module docs, step 0).
    let t = std::time::Instant::now();
    crate::progress::stage("area ratio")?;
    let mut heat_minima = Vec::new();
    let r = match (o.ratio, o.scale) {
        (Some(r), _) => r,
        (None, PartialScale::Area) => r0,
        (None, PartialScale::Distances) => {
            let guess = estimate_ratio(&sx, &sy, r0, p.search.rounds)?;
            if (guess / r0 - 1.0).abs() > 0.1 {
                guess
            } else {
                r0
            }
        }
        (None, PartialScale::Heat) => {
            let prior = Some(r0).filter(|r| (HEAT_RANGE.0..=HEAT_RANGE.1).contains(r));
            let h = part_heat_scale(x, y, HEAT_RANGE, prior)?;
            heat_minima.clone_from(&h.minima);
            match h.prior_energy {
                Some(e0) if e0 <= (1.0 + HEAT_PRIOR_TOLERANCE) * h.energy => r0,
                _ => h.ratio,
            }
        }
    };
    let ratio_seconds = t.elapsed().as_secs_f64();
    let (f1, g1) = match &o.wks {
        Some(recipe) if r != r0 => pair_wks_at(x, y, recipe, r)?,
        _ => (f.clone(), g.clone()),
    };
    let mut result = pass(x, y, &f1, &g1, p, o, &surfaces, (&sx, &sy), lm, r)?;
    result.stages.insert(0, ("area ratio".to_string(), ratio_seconds));
    result.heat_minima = heat_minima;
    result.stages.insert(0, ("search samples".to_string(), search_seconds));
    Ok(result)
}

/// The area ratio of a map of X's samples: (median over the pairs of samples of
/// d_Y(π(s_i), π(s_j)) / d_X(s_i, s_j))², X's distances at unit area (`sx`), over the pairs
/// whose images lie farther apart than four covering radii of Y's anchors (`sy`), at most 1;
/// None without such pairs. `images` are vertex ids of Y.
pub fn ratio_of_map(sx: &SampleDistances, sy: &SampleDistances, images: &[usize]) -> Option<f64> {
    let anchors: Vec<usize> = images.iter().map(|&v| sy.nearest[v] as usize).collect();
    let floor = 4.0 * sy.radius;
    let mut ratios = Vec::new();
    for i in 0..anchors.len() {
        for j in (i + 1)..anchors.len() {
            let (a, b) = (sx.distances[(i, j)], sy.distances[(anchors[i], anchors[j])]);
            if a.is_finite() && b.is_finite() && a > 0.0 && b > floor {
                ratios.push(b / a);
            }
        }
    }
    ratios.sort_by(|a, b| a.total_cmp(b));
    ratios.get(ratios.len() / 2).map(|&q| (q * q).min(1.0)).filter(|q| q.is_finite() && *q > 0.0)
}

/// A map of X's samples (vertex ids of Y) and its geodesic distortion.
type SampleMap = (Vec<usize>, f64);

/// X's sample distances in Y's units for the area ratio r: lengths at unit area scale by √r.
fn scaled(sx: &SampleDistances, r: f64) -> SampleDistances {
    let root = r.sqrt();
    let mut s = sx.clone();
    s.distances = &s.distances * faer::Scale(root);
    s.radius *= root;
    s
}

/// The area ratio r (the area of Y that X covers / area(Y)) from maps of X's samples (`sx`, at
/// unit area) to Y's anchors (`sy`) found by distances alone ([`search::seeded_maps`], blind to
/// orientation, which the scale does not need). The scale of X against Y is unknown (shapes
/// scaled to a common height differ in area between poses): at every r of the geometric grid
/// r0 · 1.15^j, j = −5 … 5, r ≤ 1, the best map by distances at that r and its geodesic
/// distortion E (relative to X's distances, so comparable between scales); the r of the lowest
/// E, then r from that map (`ratio_of_map`) while it changes by 3 % or more, twice at most.
/// Returns `r0` when no map is found.
pub fn estimate_ratio(sx: &SampleDistances, sy: &SampleDistances, r0: f64, rounds: usize) -> Result<f64> {
    let best_at = |r: f64| -> Result<Option<SampleMap>> {
        Ok(search::seeded_maps(&scaled(sx, r), sy, None, SEED_CHECKS, 1, SEED_TOLERANCE, rounds)?.into_iter().next())
    };
    let grid: Vec<f64> = (-5..=5).map(|j| r0 * 1.15f64.powi(j)).filter(|&r| r <= 1.0).collect();
    let found: Vec<(f64, Option<SampleMap>)> =
        grid.iter().map(|&r| best_at(r).map(|m| (r, m))).collect::<Result<_>>()?;
    let Some((mut r, Some((mut map, _)))) = found
        .into_iter()
        .filter(|(_, m)| m.is_some())
        .min_by(|a, b| a.1.as_ref().map(|m| m.1).unwrap().total_cmp(&b.1.as_ref().map(|m| m.1).unwrap()))
    else {
        return Ok(r0);
    };
    for _ in 0..2 {
        let Some(next) = ratio_of_map(sx, sy, &map) else { break };
        let done = (next / r - 1.0).abs() < 0.03;
        r = next;
        if done {
            break;
        }
        match best_at(r)? {
            Some((m, _)) => map = m,
            None => break,
        }
    }
    Ok(r)
}

/// The surfaces of both shapes at unit area: positions and normals.
struct Surfaces<'a> {
    px: &'a [[f64; 3]],
    nx: &'a [[f64; 3]],
    py: &'a [[f64; 3]],
    ny: &'a [[f64; 3]],
    /// The edge graphs of both surfaces (the search's distances and the metric polish).
    gx: &'a GraphGeodesics,
    gy: &'a GraphGeodesics,
}

/// One pass of [`partial_pipeline`] with the area ratio r (area of X in Y's units / area of Y),
/// the search's samples of X (distances at unit area) and anchors of Y, and the landmarks' data
/// (X's distances at unit area) when given.
#[allow(clippy::too_many_arguments)]
fn pass(
    x: &PreparedShape,
    y: &PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    p: &AxiomaticPipeline,
    o: &PartialOptions,
    surfaces: &Surfaces,
    (sx, sy): (&SampleDistances, &SampleDistances),
    lm: Option<LandmarkData>,
    r: f64,
) -> Result<PartialResult> {
    let Surfaces { px, nx, py, ny, .. } = *surfaces;
    let slope = Slope { ratio: o.slope * r, max_x: x.basis.k() };
    // The pull-backs of point maps: twice as many functions of X as the slope gives, so that the
    // restrictions of Y's functions are represented almost exactly.
    let wide = Slope { ratio: 2.0 * slope.ratio, max_x: slope.max_x };
    let mut stages = Vec::new();
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());

    let t = std::time::Instant::now();
    crate::progress::stage("descriptors")?;
    let (fx, gy) = partial_data(x, y, f, g, p, r)?;
    stages.push(("descriptors".to_string(), t.elapsed().as_secs_f64()));

    // Candidates: rectangular C_yx, Y's side the source, X's eigenvalues in Y's units.
    let t = std::time::Instant::now();
    crate::progress::stage("functional maps")?;
    let w = &p.fit.weights;
    let orient = w.orientation > 0.0 && p.fit.orientation != Orientation::Ignore;
    let comm = w.commutativity > 0.0;
    let dx = ShapeData { basis: &x.basis, gradients: x.gradients(), descriptors: &fx, cells: x.quadrature_cells() };
    let dy = ShapeData { basis: &y.basis, gradients: y.gradients(), descriptors: &gy, cells: y.quadrature_cells() };
    let ky_max = p.candidates.iter().copied().max().unwrap_or(1).min(y.basis.k());
    let side_y = spectral_side(&dy, ky_max, comm, orient, p.fit.unit_gradients, "Y")?;
    let mut side_x = spectral_side(&dx, slope.kx(ky_max), comm, orient, p.fit.unit_gradients, "X")?;
    in_units_of_y(&mut side_x, r, p.fit.unit_gradients);
    let fits: Vec<Mat<f64>> = p
        .candidates
        .par_iter()
        .map(|&ky| {
            let ky = ky.min(ky_max);
            let kx = slope.kx(ky);
            let energy = Energy::new(&side_y.leading(ky), &side_x.leading(kx), w, p.fit.mask, p.fit.orientation)?;
            energy.solve_with_first_column(&constant_column(&y.basis, &x.basis, kx))
        })
        .collect::<Result<_>>()?;
    stages.push(("functional maps".to_string(), t.elapsed().as_secs_f64()));

    let t = std::time::Instant::now();
    crate::progress::stage("search samples")?;
    let probe_samples = samples_of(x, p.probe.samples)?;
    // X's distances in Y's units.
    let sx = scaled(sx, r);
    let sy = sy.clone();
    let neighbours = search::sample_neighbours(&sx, 8);
    let descriptors = search::descriptor_distances(&sx, &sy, fx.values.as_ref(), gy.values.as_ref());
    let s = PartialSearch { x: sx, y: sy, neighbours, descriptors };
    stages.push(("search samples".to_string(), t.elapsed().as_secs_f64()));

    let t = std::time::Instant::now();
    crate::progress::stage("candidate probes")?;
    let probe = |c: &Mat<f64>, fitted: bool, k: usize, correct: bool| -> Result<Probe> {
        let first = if fitted { Reading::Pushed } else { Reading::Restricted };
        let c = zoomout(
            x,
            y,
            &probe_samples,
            c,
            (first, Reading::Restricted),
            p.probe.k_final.max(c.ncols()),
            p.probe.step,
            slope,
        )?;
        let xs = &s.x.samples.vertices;
        let images = restricted_map(phi, psi, &c, Some(xs))?;
        let mut candidate = Candidate::unscored(k);
        candidate.distortion = search::distortion(&s.x, &s.y, &images);
        candidate.orientation = search::orientation(px, nx, py, ny, xs, &images, &s.neighbours);
        let (fv, gv) = (&fx.values, &gy.values);
        candidate.data_misfit = xs
            .iter()
            .zip(&images)
            .map(|(&v, &u)| (0..fv.ncols()).map(|j| (fv[(v, j)] - gv[(u, j)]).powi(2)).sum::<f64>().sqrt())
            .sum::<f64>()
            / images.len().max(1) as f64;
        candidate.sample_images = images.clone();
        let mut corrected = [None, None];
        // The bottom of its basin: the sample map corrected by distances and data. A fit's comes
        // with its corrections below; with seeded challengers, a candidate made of a sample map
        // is corrected here, so that the maps compared with them (below) are corrected alike.
        let mut basin = Vec::new();
        if !correct && o.seeded > 0 && p.search.rounds > 0 {
            let (fixed, report) = search::correct(&s.x, &s.y, &images, Some(&s.descriptors), p.search.rounds)?;
            candidate.corrected_distortion = report.trace.iter().copied().fold(f64::INFINITY, f64::min);
            candidate.corrected_orientation = search::orientation(px, nx, py, ny, xs, &fixed, &s.neighbours);
            basin = fixed;
        }
        if correct && p.search.rounds > 0 {
            for (slot, desc) in [Some(&s.descriptors), None].into_iter().enumerate() {
                let (fixed, report) = search::correct(&s.x, &s.y, &images, desc, p.search.rounds)?;
                let e = report.trace.iter().copied().fold(f64::INFINITY, f64::min);
                let or = search::orientation(px, nx, py, ny, xs, &fixed, &s.neighbours);
                if slot == 0 {
                    (candidate.corrected_distortion, candidate.corrected_orientation) = (e, or);
                    candidate.moved = report.moved;
                } else {
                    (candidate.geodesic_corrected_distortion, candidate.geodesic_corrected_orientation) = (e, or);
                }
                if slot == 0 {
                    basin.clone_from(&fixed);
                }
                corrected[slot] = Some((fixed, report));
            }
        }
        Ok(Probe { candidate, c, images, corrected, basin })
    };
    let mut probed: Vec<Probe> =
        fits.par_iter().zip(p.candidates.par_iter()).map(|(c, &k)| probe(c, true, k, true)).collect::<Result<_>>()?;
    stages.push(("candidate probes".to_string(), t.elapsed().as_secs_f64()));

    // The correction, as in the whole pipeline: for each form, the corrected sample map of the
    // candidate of lowest corrected distortion (of the asked orientation), probed as one more.
    let t = std::time::Instant::now();
    crate::progress::stage("correction")?;
    let mut correction = None;
    let mut starts = fits;
    let originals = probed.len();
    let mut hybrids: Vec<(usize, bool, Vec<usize>)> = Vec::new();
    for joint in [true, false] {
        let scored: Vec<Candidate> = probed[..originals]
            .iter()
            .map(|q| {
                let c = &q.candidate;
                let (distortion, orientation) = if joint {
                    (c.corrected_distortion, c.corrected_orientation)
                } else {
                    (c.geodesic_corrected_distortion, c.geodesic_corrected_orientation)
                };
                Candidate { distortion, orientation, ..c.clone() }
            })
            .collect();
        let from = choose(&scored, p.fit.orientation, |c| c.distortion);
        let slot = usize::from(!joint);
        let Some((fixed, mut report)) = probed[from].corrected[slot].take() else { continue };
        let images = &probed[from].images;
        let moved: Vec<bool> = images.iter().zip(&fixed).map(|(&a, &b)| search::has_moved(&s.x, &s.y, a, b)).collect();
        report.moved = moved.iter().filter(|&&m| m).count();
        if report.moved > 0 {
            let hybrid = fixed.iter().zip(images).zip(&moved).map(|((&f, &o), &m)| if m { f } else { o }).collect();
            hybrids.push((from, joint, hybrid));
        }
        if joint {
            correction = Some(report);
        }
    }
    // Sample maps found from distances alone (module docs, step 3), the best SEEDED probed.
    let seeded = if o.seeded > 0 {
        search::seeded_maps(
            &s.x,
            &s.y,
            Some(&s.descriptors),
            SEED_CHECKS,
            SEED_KEEP.max(o.seeded),
            SEED_TOLERANCE,
            p.search.rounds,
        )?
    } else {
        Vec::new()
    };
    // (corrected from, seeded rank, the sample map).
    type Start<'a> = (Option<(usize, bool)>, Option<usize>, &'a Vec<usize>);
    let starts_of_samples: Vec<Start> = hybrids
        .iter()
        .map(|(from, joint, h)| (Some((*from, *joint)), None, h))
        .chain(seeded.iter().take(o.seeded).enumerate().map(|(i, (m, _))| (None, Some(i), m)))
        .collect();
    let k0 = p.candidates.iter().copied().min().unwrap_or(1).min(s.x.len() / 4).max(1);
    let extra: Vec<(Probe, Mat<f64>)> = starts_of_samples
        .par_iter()
        .map(|(from, rank, hybrid)| {
            let c0 = refine::pullback(phi, psi, &s.x.samples, hybrid, wide.kx(k0), k0)?;
            let mut q = probe(&c0, false, k0, false)?;
            q.candidate.corrected_from = *from;
            q.candidate.seeded = *rank;
            Ok((q, c0))
        })
        .collect::<Result<_>>()?;
    for (q, c0) in extra {
        probed.push(q);
        starts.push(c0);
    }
    // The spectral choice among the fits and their corrections; then the seeded maps as
    // challengers (module docs, step 3).
    let spectral = probed.len() - seeded.len().min(o.seeded);
    // With landmarks (module docs, "Landmarks"): one more candidate from the landmarks alone, and
    // every candidate's landmark error, read off its probe's map at the landmarks of X.
    let lm = lm.map(|mut l| {
        // X's distances in Y's units, as the search's.
        l.dist_x = &l.dist_x * faer::Scale(r.sqrt());
        l
    });
    let landmark_check = lm.as_ref().map(LandmarkData::check);
    if let Some(l) = &lm {
        let fixed = l.trilaterated(&s.x, &s.y, p.search.rounds)?;
        let c0 = refine::pullback(phi, psi, &s.x.samples, &fixed, wide.kx(k0), k0)?;
        let mut q = probe(&c0, false, k0, false)?;
        q.candidate.from_landmarks = true;
        probed.push(q);
        starts.push(c0);
        for q in probed.iter_mut() {
            q.candidate.landmark_error = l.error(&restricted_map(phi, psi, &q.c, Some(&l.xs))?);
        }
    }
    let mut candidates: Vec<Candidate> = probed.iter().map(|q| q.candidate.clone()).collect();
    let median = |f: &dyn Fn(&Candidate) -> f64| {
        let mut v: Vec<f64> = candidates[..spectral].iter().map(f).filter(|x| x.is_finite() && *x > 0.0).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        v.get(v.len() / 2).copied().unwrap_or(1.0)
    };
    let (me, md) = (median(&|c| c.distortion), median(&|c| c.data_misfit));
    let spectral_choice =
        choose(&candidates[..spectral], p.fit.orientation, |c| c.distortion / me + c.data_misfit / md);
    let mut chosen = spectral_choice;
    // With landmarks they choose, as in the whole pipeline: their error in units of the
    // tolerance joins the score over every candidate, and when no candidate of the asked
    // orientation respects them (within one tolerance of the lowest error), they, not that
    // orientation, tell a map from its mirror image. No challenger and no second finalist.
    if lm.is_some() {
        let tol = p.landmarks.tolerance;
        let best = candidates.iter().map(|c| c.landmark_error).fold(f64::INFINITY, f64::min);
        let respected = candidates.iter().any(|c| agrees(c, p.fit.orientation) && c.landmark_error <= best + tol);
        let orientation = if respected { p.fit.orientation } else { Orientation::Ignore };
        chosen = choose(&candidates, orientation, |c| c.distortion / me + c.data_misfit / md + c.landmark_error / tol);
    }
    let challenger = (spectral..probed.len())
        .filter(|_| lm.is_none())
        .filter(|&i| agrees(&candidates[i], p.fit.orientation) && candidates[i].corrected_distortion.is_finite())
        .min_by(|&a, &b| candidates[a].corrected_distortion.total_cmp(&candidates[b].corrected_distortion));
    if let Some(b) = challenger {
        let of = |i: usize| search::sample_distortions(&s.x, &s.y, &probed[i].basin);
        // An empty basin (no correction) gives no distortions and a share of 0.
        let share = search::dominance(&of(chosen), &of(b));
        candidates[b].dominance = share;
        if share >= SEEDED_DOMINANCE {
            chosen = b;
        }
    }
    stages.push(("correction".to_string(), t.elapsed().as_secs_f64()));

    // The finalists (module docs, step 8): the choice and, when a challenger fits at least
    // half of the samples better, the other of the two, both finished; the other replaces the
    // choice when its final map keeps the orientation clearly better.
    let mut order = vec![chosen];
    if let Some(b) = challenger {
        let other = if chosen == b { spectral_choice } else { b };
        if o.finalists && candidates[b].dominance >= FINALIST_DOMINANCE && other != chosen {
            order.push(other);
        }
    }
    let tail = Tail { x, y, p, o, surfaces, slope, wide, r };
    let mut finished: Vec<Finished> =
        order.iter().map(|&i| tail.finish(&starts[i], &probed[i].c)).collect::<Result<_>>()?;
    // Judged only when contested: an uncontested choice has one finished map and no finalists.
    let mut finalists = Vec::new();
    let mut best = 0;
    if order.len() > 1 {
        let xs = &s.x.samples.vertices;
        finalists = order
            .iter()
            .zip(&finished)
            .map(|(&i, f)| {
                let images: Vec<usize> = xs.iter().map(|&v| f.map_xy[v]).collect();
                let orientation = search::orientation(px, nx, py, ny, xs, &images, &s.neighbours);
                Finalist { candidate: i, orientation, chosen: false, map_xy: f.map_xy.clone() }
            })
            .collect();
        best = final_choice(&finalists, p.fit.orientation);
        finalists[best].chosen = true;
    }
    let chosen = order[best];
    let Finished { mut map_xy, c_yx, polish, coverage, covered, stages: tail_stages } = finished.swap_remove(best);
    // The landmarks' images are the user's (module docs, "Landmarks").
    for (a, b) in lm.as_ref().map_or_else(Vec::new, LandmarkData::pins) {
        map_xy[a] = b;
    }
    stages.extend(tail_stages);
    // The other finalist's time, reported apart.
    for other in finished {
        stages.extend(other.stages.into_iter().map(|(s, t)| (format!("other finalist: {s}"), t)));
    }
    let c_fit = starts.swap_remove(chosen);
    Ok(PartialResult {
        map_xy,
        c_yx,
        c_fit,
        candidates,
        chosen,
        stages,
        coverage,
        correction,
        area_ratio: r,
        heat_minima: Vec::new(),
        polish,
        covered,
        finalists,
        landmark_check,
    })
}

/// What the end of a pass needs to finish a start.
struct Tail<'a> {
    x: &'a PreparedShape,
    y: &'a PreparedShape,
    p: &'a AxiomaticPipeline,
    o: &'a PartialOptions,
    surfaces: &'a Surfaces<'a>,
    slope: Slope,
    wide: Slope,
    r: f64,
}

/// A start finished: the final map and what made it.
struct Finished {
    map_xy: Vec<usize>,
    c_yx: Mat<f64>,
    polish: Option<refine::MetricPolished>,
    coverage: Vec<f64>,
    covered: Option<super::covered::CoveredRefinement>,
    stages: Vec<(String, f64)>,
}

impl Tail<'_> {
    /// The rest of a pass from the probed map `c_start` of the fit `c_fit` (both k_X × k_Y,
    /// Y → X): ZoomOut on X's samples and FINAL_ROUNDS on every vertex (the fit's map without
    /// ZoomOut), the metric polish, the coverage and step 7.
    fn finish(&self, c_fit: &Mat<f64>, c_start: &Mat<f64>) -> Result<Finished> {
        let Tail { x, y, p, o, surfaces, slope, wide, r } = *self;
        let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
        let mut stages = Vec::new();
        let t = std::time::Instant::now();
        crate::progress::stage("zoomout")?;
        let (c_yx, map_xy) = if p.refine.k_final == 0 {
            (c_fit.clone(), refine::map_of_pullback(phi, psi, c_fit.as_ref(), None, Scope::Exact)?)
        } else {
            let samples = samples_of(x, p.refine.samples)?;
            let ky = p.refine.k_final.max(c_start.ncols()).min(y.basis.k());
            // Read as the probe found it: ZoomOut's reading ([`Reading::Pushed`]) from here loses the
            // basin on real pairs (EXPERIMENTS.md).
            let c =
                zoomout(x, y, &samples, c_start, (Reading::Restricted, Reading::Restricted), ky, p.refine.step, slope)?;
            let map = restricted_map(phi, psi, &c, None)?;
            // FINAL_ROUNDS more at the final size on every vertex of X.
            let all = Samples::all(&x.basis.mass);
            let (mut c, mut map) = (c, map);
            for _ in 0..FINAL_ROUNDS {
                crate::progress::check()?;
                c = refine::pullback(phi, psi, &all, &map, wide.kx(ky), ky)?;
                map = restricted_map(phi, psi, &c, None)?;
            }
            (c, map)
        };
        stages.push(("zoomout".to_string(), t.elapsed().as_secs_f64()));
        // The metric polish (module docs, step 5) with the final reading as its spectral term.
        // Its memory is about 24 (n + m) A bytes (distance fields and the annulus lists): above
        // METRIC_MAX_ENTRIES entries (m A) the polish is skipped (a part of a 10⁶-vertex whole).
        let fits = y.n().saturating_mul(o.metric_anchors) <= METRIC_MAX_ENTRIES;
        let anchors = if fits { o.metric_anchors } else { 0 };
        let (mut map_xy, polish) = if anchors > 0 {
            let t = std::time::Instant::now();
            crate::progress::stage("metric polish")?;
            let anchors = samples_of(x, anchors.max(3))?.vertices;
            let embedded = crate::linalg::mul(phi.subcols(0, c_yx.nrows()), c_yx.as_ref());
            let reading = Some((embedded.as_ref(), psi.subcols(0, c_yx.ncols())));
            let o = refine::MetricPolishOptions::default();
            let mut r = refine::metric_polish(surfaces.gx, surfaces.gy, surfaces.gy, &anchors, &map_xy, &o, reading)?;
            stages.push(("metric polish".to_string(), t.elapsed().as_secs_f64()));
            (std::mem::take(&mut r.map_xy), Some(r))
        } else {
            (map_xy, None)
        };

        let t = std::time::Instant::now();
        crate::progress::stage("coverage")?;
        let mut coverage = coverage(y, &map_xy, r)?;
        stages.push(("coverage".to_string(), t.elapsed().as_secs_f64()));
        // Step 7: the map refined on the covered region of Y, with the metric polish there (module
        // docs; `super::covered`); then the coverage of its map and the pull-back of that map (the
        // map Y → X is read off it).
        let mut c_yx = c_yx;
        let mut covered = if o.covered {
            super::covered::refine_on_covered_region(x, y, &map_xy, &coverage, p, anchors)?
        } else {
            None
        };
        if let Some(refined) = &mut covered {
            let t = std::time::Instant::now();
            map_xy = std::mem::take(&mut refined.map_xy);
            stages.append(&mut refined.stages);
            let all = Samples::all(&x.basis.mass);
            c_yx = refine::pullback(phi, psi, &all, &map_xy, c_yx.nrows(), c_yx.ncols())?;
            coverage = self::coverage(y, &map_xy, r)?;
            stages.push(("covered coverage".to_string(), t.elapsed().as_secs_f64()));
        }
        Ok(Finished { map_xy, c_yx, polish, coverage, covered, stages })
    }
}

/// X's side of the energy (computed on X at unit area) with its differential operators in Y's
/// units, X's area there being r (Y at unit area): X's lengths at unit area are Y's / √r, so
/// its eigenvalues are r times Y's units' (λ / r here) and its orientation operators, built from
/// gradients, √r times (unit descriptor gradients: one gradient, of the basis function) or r
/// times (raw gradients: two). The basis stays X's own (orthonormal at unit area), and with it
/// the descriptor coefficients and the multiplication operators (pointwise products, no unit).
/// Before 2026-12-05 the orientation operators were left at X's unit area, √r times too large
/// against Y's (EXPERIMENTS.md).
fn in_units_of_y(side: &mut crate::fmap::energy::SpectralSide, r: f64, unit_gradients: bool) {
    side.eigenvalues.iter_mut().for_each(|l| *l /= r);
    let f = if unit_gradients { r.sqrt().recip() } else { r.recip() };
    side.orientation.iter_mut().for_each(|o| *o = &*o * faer::Scale(f));
}

/// The confidence (length m, in [0, 1]) that X covers each vertex of Y, from the images
/// `map_xy` of X's vertices: with d(v) the distance along Y's edges (unit area) from v to the
/// nearest image and ρ the distance within which the vertices nearest to the images hold
/// `area_ratio` of Y's area (the area of X in Y's units), the confidence is 1 / (1 + (d / ρ)⁴):
/// 1 on the images, ½ at ρ, so that the vertices of confidence ≥ ½ have X's area. ρ is at least
/// half of Y's mean edge length. Y without a surface: 1 on the images, 0 elsewhere. Errors: an
/// image out of range.
pub fn coverage(y: &PreparedShape, map_xy: &[usize], area_ratio: f64) -> Result<Vec<f64>> {
    let m = y.n();
    if let Some(&bad) = map_xy.iter().find(|&&v| v >= m) {
        return Err(Error::invalid("map", format!("vertex {bad} of Y does not exist (m = {m})")));
    }
    let mut hit = vec![false; m];
    map_xy.iter().for_each(|&v| hit[v] = true);
    let Some(ty) = y.triangles() else {
        return Ok(hit.iter().map(|&h| f64::from(u8::from(h))).collect());
    };
    let sources: Vec<usize> = (0..m).filter(|&v| hit[v]).collect();
    let (dist, _) = GraphGeodesics::mesh_edges(ty)?.nearest_sources(&sources)?;
    let mut order: Vec<usize> = (0..m).filter(|&v| dist[v].is_finite()).collect();
    order.sort_by(|&a, &b| dist[a].total_cmp(&dist[b]));
    let total: f64 = y.basis.mass.iter().sum();
    let target = area_ratio.clamp(0.0, 1.0) * total;
    let mut acc = 0.0;
    let mut rho = 0.0;
    for &v in &order {
        acc += y.basis.mass[v];
        rho = dist[v];
        if acc >= target {
            break;
        }
    }
    let rho = rho.max(0.5 * ty.mean_edge_length()).max(f64::MIN_POSITIVE);
    Ok(dist.iter().map(|&d| if d.is_finite() { 1.0 / (1.0 + (d / rho).powi(4)) } else { 0.0 }).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::operators::FaceGradients;
    use crate::primitives::bumpy_sphere;
    use crate::shape::TriMesh;
    use crate::spectral::{eigen_basis, Basis, SpectralOptions};

    /// The second finalist is kept only when its orientation is higher by the margin.
    #[test]
    fn the_second_finalist_replaces_the_first_only_by_a_clear_orientation_margin() {
        let f = |orientation: f64| Finalist { candidate: 0, orientation, chosen: false, map_xy: Vec::new() };
        let m = FINALIST_ORIENTATION_MARGIN;
        let keep = Orientation::Preserve;
        assert_eq!(final_choice(&[], keep), 0);
        assert_eq!(final_choice(&[f(0.1)], keep), 0);
        assert_eq!(final_choice(&[f(0.1), f(0.1 + m + 1e-9)], keep), 1);
        assert_eq!(final_choice(&[f(0.1), f(0.1 + 0.9 * m)], keep), 0);
        assert_eq!(final_choice(&[f(0.9), f(-0.9)], keep), 0);
        assert_eq!(final_choice(&[f(-0.5), f(0.5)], keep), 1);
        assert_eq!(final_choice(&[f(0.2), f(f64::NAN)], keep), 0);
        // Orientation-reversing maps: the lower score is the better one; ignored: no switch.
        assert_eq!(final_choice(&[f(0.5), f(-0.5)], Orientation::Reverse), 1);
        assert_eq!(final_choice(&[f(-0.5), f(0.5)], Orientation::Reverse), 0);
        assert_eq!(final_choice(&[f(-0.5), f(0.5)], Orientation::Ignore), 0);
    }

    /// X's side at unit area, brought to Y's units by [`in_units_of_y`], equals the side of X at
    /// its size in Y's units (area r), in the same basis.
    #[test]
    fn the_side_of_x_in_units_of_y_is_the_side_of_x_at_that_size() {
        let m = bumpy_sphere(2);
        let scaled = |area: f64| {
            let s = (area / m.total_area()).sqrt();
            TriMesh::new(m.vertices().iter().map(|p| p.map(|c| c * s)).collect(), m.faces().to_vec()).unwrap()
        };
        let r = 0.6;
        let (unit, small) = (scaled(1.0), scaled(r));
        let b = eigen_basis(&cotangent(&unit).unwrap(), &SpectralOptions::new(12), None).unwrap().0;
        // The same functions at area r: orthonormal for the mass r A.
        let b_small = Basis {
            eigenvalues: b.eigenvalues.iter().map(|l| l / r).collect(),
            eigenvectors: &b.eigenvectors * faer::Scale(r.sqrt().recip()),
            mass: b.mass.iter().map(|a| a * r).collect(),
            residuals: b.residuals.clone(),
        };
        let v = unit.vertices();
        let f = Descriptors::new(
            Mat::from_fn(v.len(), 2, |i, j| if j == 0 { v[i][2] } else { v[i][0] * v[i][1] + 0.1 }),
            vec!["a".into(), "b".into()],
        )
        .unwrap();
        let (g, g_small) = (FaceGradients::new(&unit).unwrap(), FaceGradients::new(&small).unwrap());
        for unit_gradients in [true, false] {
            let data = ShapeData { basis: &b, gradients: Some(&g), descriptors: &f, cells: None };
            let mut side = spectral_side(&data, 12, true, true, unit_gradients, "X").unwrap();
            in_units_of_y(&mut side, r, unit_gradients);
            let data_small = ShapeData { basis: &b_small, gradients: Some(&g_small), descriptors: &f, cells: None };
            let truth = spectral_side(&data_small, 12, true, true, unit_gradients, "X").unwrap();
            let close = |a: &Mat<f64>, b: &Mat<f64>| (a - b).norm_l2() <= 1e-9 * b.norm_l2().max(1e-300);
            for (a, b) in side.eigenvalues.iter().zip(&truth.eigenvalues) {
                assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
            }
            assert!(side.orientation.iter().zip(&truth.orientation).all(|(a, b)| close(a, b)), "unit {unit_gradients}");
            assert!(side.multiplication.iter().zip(&truth.multiplication).all(|(a, b)| close(a, b)));
            // The descriptor coefficients stay in X's own basis (Φᵀ A F at unit area): √r apart.
            assert!(close(&(&side.coefficients * faer::Scale(r.sqrt())), &truth.coefficients));
        }
    }
}
