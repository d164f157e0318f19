//! The default pipeline: orientation-aware axiomatic functional maps, refined by ZoomOut.
//!
//! 1. **Data**: the given descriptors (normalized, [`crate::descriptors::normalized`]) and
//!    `signed` orientation descriptors built from them ([`crate::descriptors::signed`]), which
//!    change sign under the left–right symmetry the others cannot see.
//! 2. **Functional maps**: the exact minimizer of the axiomatic energy for the pull-back C_yx
//!    of the map X → Y ([`crate::fmap::axiomatic::axiomatic_pullbacks`]; so that the map is
//!    read off in the direction ZoomOut refines it), at several sizes k (`candidates`).
//! 3. **Selection**: every candidate is refined cheaply (ZoomOut to `probe.k_final` on
//!    `probe.samples` vertices) and the one whose point map has the smallest metric distortion
//!    ([`crate::refine::metric_distortion`]) is kept: a start that ZoomOut turns into a map with
//!    a limb matched to the wrong limb or a mirrored part tears at the seams; an isometry does
//!    not.
//! 4. **Refinement**: ZoomOut of the chosen candidate, continued from its probe result (or from
//!    its fit, `continue_probe` off), to `refine.k_final` on `refine.samples` vertices
//!    ([`crate::refine::zoomout`]), then the point map of every vertex.
//! 5. **Polish**: `polish` rounds of the bijective refinement at the final size
//!    ([`crate::refine::bijective_polish`]: both point maps and both functional maps, with the
//!    coupling and bijectivity terms of Ren et al. 2021).
//!
//! Map direction: X → Y throughout. Every functional map of the pipeline, from the fits to the
//! result, is a pull-back [`Pullback`] (C_yx, k × k, functions on Y → functions on X); the result
//! is `map_xy` (for every vertex of X a vertex of Y) and its pull-back.

use std::borrow::Cow;

use faer::Mat;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::descriptors::{self, Descriptors};
use crate::error::{Error, Result};
use crate::fmap::axiomatic::{axiomatic_pullbacks, AxiomaticOptions, ShapeData};
use crate::fmap::energy::{EnergyWeights, Orientation};
use crate::fmap::Pullback;
use crate::geodesic::GraphGeodesics;
use crate::prepared::PreparedShape;
use crate::refine::{self, Scope, ZoomOutOptions};
use crate::spatial::{farthest_point_samples, Samples};

use super::landmarks::{self, LandmarkData, Landmarks};
use super::search::{self, SampleDistances, SearchOptions};

/// A ZoomOut schedule on vertex samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ZoomOutSchedule {
    /// Final size K.
    pub k_final: usize,
    /// Size increment per iteration.
    pub step: usize,
    /// Farthest-point samples of X the intermediate maps are computed on (0: every vertex).
    pub samples: usize,
}

/// Options of [`axiomatic_pipeline`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxiomaticPipeline {
    /// The energy (its `k` is ignored: see `candidates`).
    pub fit: AxiomaticOptions,
    /// Sizes k of the candidate functional maps.
    pub candidates: Vec<usize>,
    /// Number of signed descriptors added to the data (0: none).
    pub signed: usize,
    /// Eigenfunctions the signed descriptors are low-passed to.
    pub signed_smoothing: usize,
    /// The cheap ZoomOut that compares the candidates (unused with one candidate).
    pub probe: ZoomOutSchedule,
    /// The final refinement (`k_final` 0: none, the map of the chosen functional map). Default:
    /// to 128, every eigenpair of the default basis (the one the default WKS read): more
    /// accurate than the earlier 110 in the mean of every dev set (better on 76 of 97 faust_r
    /// and 91 of 109 tosca_r pairs); larger sizes need a larger basis (EXPERIMENTS.md, "The
    /// final ZoomOut to the whole basis").
    pub refine: ZoomOutSchedule,
    /// Weight of the bijectivity term of the final refinement, > 0: the bijective ZoomOut of
    /// [`crate::refine::bijective_zoomout`] (Ren, Melzi, Wonka, Ovsjanikov 2021: both point maps
    /// and both functional maps refined together, `refine.samples` samples on each shape) instead
    /// of ZoomOut; 0 (the default, chosen by measurement, EXPERIMENTS.md): ZoomOut.
    #[serde(default)]
    pub bijective: f64,
    /// Start the final ZoomOut from the chosen candidate's probe result (its functional map at
    /// `probe.k_final`) instead of from its fit, skipping the steps the probe already took
    /// (default on: half the ZoomOut time at the same accuracy on faust_r and tosca_r,
    /// EXPERIMENTS.md).
    #[serde(default)]
    pub continue_probe: bool,
    /// Rounds of the bijective polish after ZoomOut ([`crate::refine::bijective_polish`] on
    /// `refine.samples` samples of each shape; 0: none). Default 1: on every faust_r pair the
    /// mean error drops from 3.36 to 3.33 ×100 (64 pairs better, 30 worse, none by more than
    /// 0.1), for about 0.6 s per 5k pair (EXPERIMENTS.md).
    #[serde(default)]
    pub polish: usize,
    /// ZoomOut coarse to fine on large shapes (Y of more than 2 × [`crate::prepared::QUADRATURE_CELLS`]
    /// vertices, which have [`PreparedShape::grid_vertices`]): every step of the probes' and the
    /// final ZoomOut but the last matches the samples among Y's 12,500 grid vertices only
    /// ([`crate::refine::zoomout_coarse_to_fine`]); the last step, the polish and the final maps
    /// search as before. Default on (EXPERIMENTS.md, "ZoomOut coarse to fine").
    #[serde(default = "coarse_zoomout_default")]
    pub coarse_zoomout: bool,
    /// When the final point maps of every vertex are searched near the map of the samples
    /// instead of exactly ([`NearSearch`]).
    #[serde(default)]
    pub near: NearSearch,
    /// The basin search: candidates scored by geodesic distortion on samples, the chosen one's
    /// samples corrected ([`super::search`]).
    #[serde(default)]
    pub search: SearchOptions,
    /// Known corresponding points and how strongly they act ([`super::landmarks`]; none by
    /// default).
    #[serde(default)]
    pub landmarks: Landmarks,
}

/// The default of [`AxiomaticPipeline::coarse_zoomout`] (on).
fn coarse_zoomout_default() -> bool {
    true
}

/// The searches of the pipeline on large pairs. Above `above_pairs` vertex pairs n · m (with
/// positions on both shapes and samples on): the ZoomOut iterations (probes and final) match
/// each sample of X near its previous image only ([`crate::refine::zoomout`] with [`crate::refine::Scope::Near`]); a
/// probe's metric distortion and orientation are measured on the edges and triangles incident to
/// its samples ([`crate::refine::metric_distortion_around`]), so its map is needed on their
/// one-rings only; and every point map (those one-rings, the final X → Y and Y → X maps) matches
/// each vertex among the vertices of the other shape in the `cells` Voronoi cells nearest to the
/// image of its own sample ([`crate::pointwise::nearest_neighbors_near`]). Below it, every
/// search is exact. Up to `certified_up_to` vertex pairs (by default, always) the final map X → Y
/// searched that way is then made exact: a certificate checks every restricted answer against every vertex of Y by
/// bounds and corrects it ([`crate::certified_search`]). The exact searches cost O(n · m · k):
/// 2·10¹³ flops for the 330-dimensional embedding of the polish at 250k vertices per shape,
/// 10¹⁴ at 840k.
///
/// The point map Y → X, read off the final pull-back beside the map X → Y (for colour transfer
/// and `map_yx`), is searched from `inverse_above_pairs` on, even where the map X → Y is still
/// exact: up to `inverse_certified_up_to` pairs among the preimages of the final map X → Y near
/// each vertex and then certified ([`crate::refine::map_yx_near_map`]), so that it equals the
/// exact search's; above, near the samples' map, not certified.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NearSearch {
    /// n · m above which the search is restricted (the default 2·10⁹, about 45k × 45k vertices,
    /// keeps every faust_r, tosca_r and 28k-vertex tosca_hires pair exact).
    pub above_pairs: u64,
    /// Cells searched around the image of each sample.
    pub cells: usize,
    /// n · m above which the map Y → X is searched near the final map X → Y (the default 6.25·10⁸,
    /// 25k × 25k vertices, the size from which ZoomOut runs coarse to fine; every faust_r,
    /// tosca_r and faust_lps pair stays exact).
    #[serde(default = "inverse_above_pairs_default")]
    pub inverse_above_pairs: u64,
    /// n · m up to which the final map X → Y, where it is searched near the samples' map, is
    /// made exact by a certificate ([`crate::certified_search`]: bounds rule out the cells of Y
    /// that cannot hold a nearer row, the rest is searched). The default, `u64::MAX`, certifies
    /// every size, so the final map X → Y always equals the exact search's: 0.45 s at 52k
    /// vertices per shape, about 11 s at 840k (EXPERIMENTS.md, "The certificate at 840k"). A
    /// lower value skips it above that size (the map then stays restricted, not proven).
    #[serde(default = "certified_up_to_default")]
    pub certified_up_to: u64,
    /// n · m up to which the map Y → X, where it is restricted (`inverse_above_pairs`), is
    /// searched near the preimages of the final map X → Y and certified exact
    /// ([`crate::refine::map_yx_near_map`]; 0.3 s at 52k vertices per shape); above, it is
    /// searched near the samples' map and not certified. The default 10¹⁰ (100k × 100k
    /// vertices): at 840k the preimage search costs 71 s and leaves 5.6 % of the answers for
    /// the certificate, against 14 s for the search near the samples' map (EXPERIMENTS.md, "The
    /// map Y → X near the preimages of the map X → Y").
    #[serde(default = "inverse_certified_up_to_default")]
    pub inverse_certified_up_to: u64,
}

/// The default of [`NearSearch::inverse_certified_up_to`] (100k × 100k vertex pairs).
fn inverse_certified_up_to_default() -> u64 {
    10_000_000_000
}

/// The default of [`NearSearch::certified_up_to`]: every size.
fn certified_up_to_default() -> u64 {
    u64::MAX
}

/// The default of [`NearSearch::inverse_above_pairs`] (25k × 25k vertex pairs).
fn inverse_above_pairs_default() -> u64 {
    625_000_000
}

impl Default for NearSearch {
    fn default() -> Self {
        NearSearch {
            above_pairs: 2_000_000_000,
            cells: 16,
            inverse_above_pairs: inverse_above_pairs_default(),
            certified_up_to: certified_up_to_default(),
            inverse_certified_up_to: inverse_certified_up_to_default(),
        }
    }
}

impl Default for AxiomaticPipeline {
    fn default() -> Self {
        AxiomaticPipeline {
            fit: AxiomaticOptions {
                weights: EnergyWeights { descriptors: 1.0, laplacian: 0.1, commutativity: 1.0, orientation: 3.0 },
                unit_gradients: true,
                ..AxiomaticOptions::default()
            },
            candidates: vec![20, 30, 40, 50],
            signed: 10,
            signed_smoothing: 50,
            probe: ZoomOutSchedule { k_final: 60, step: 5, samples: 1000 },
            refine: ZoomOutSchedule { k_final: 128, step: 5, samples: 2000 },
            bijective: 0.0,
            continue_probe: true,
            coarse_zoomout: true,
            polish: 1,
            near: NearSearch::default(),
            search: SearchOptions::default(),
            landmarks: Landmarks::default(),
        }
    }
}

impl AxiomaticPipeline {
    /// The number of eigenpairs each basis must hold.
    pub fn basis_size(&self) -> usize {
        let kmax = self.candidates.iter().copied().max().unwrap_or(0);
        kmax.max(self.probe.k_final).max(self.refine.k_final)
    }
}

/// One candidate of [`axiomatic_pipeline`] and how it scored.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// Size k of its functional map.
    pub k: usize,
    /// Distortion of its probe map: with the basin search the geodesic distortion on the
    /// search samples ([`super::search::distortion`]), else the metric distortion of the edges
    /// ([`crate::refine::metric_distortion`]).
    pub distortion: f64,
    /// Orientation agreement of its probe map ([`crate::refine::orientation_agreement`], around
    /// the search samples with the basin search).
    pub orientation: f64,
    /// Mean descriptor misfit ‖F(s_i) − G(π(s_i))‖ of its probe map on the search samples, in
    /// the fits' data (NaN without the search).
    pub data_misfit: f64,
    /// Geodesic distortion after the correction of its samples by distances and data
    /// ([`super::search::correct`] with descriptors; NaN without it).
    pub corrected_distortion: f64,
    /// Orientation of that corrected sample map ([`super::search::orientation`]; NaN without it).
    pub corrected_orientation: f64,
    /// Samples that correction moved.
    pub moved: usize,
    /// Geodesic distortion after the correction by distances alone (NaN without it).
    pub geodesic_corrected_distortion: f64,
    /// Orientation of that corrected sample map.
    pub geodesic_corrected_orientation: f64,
    /// For a candidate made of a corrected sample map: the candidate it was corrected from, and
    /// whether by distances and data (true) or by distances alone.
    pub corrected_from: Option<(usize, bool)>,
    /// For a candidate made of a sample map found from distances alone
    /// ([`super::search::seeded_maps`], the partial path): its rank among those maps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seeded: Option<usize>,
    /// With landmarks: the mean geodesic distance on Y (unit area) between the images of the
    /// landmarks of X under its probe's functional map and their given images
    /// ([`super::landmarks`]; NaN without landmarks).
    #[serde(skip_serializing_if = "is_nan")]
    pub landmark_error: f64,
    /// Whether the candidate was made from the landmarks alone (their trilateration).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub from_landmarks: bool,
    /// For a seeded map of the partial path: the share of the search samples that its corrected
    /// sample map fits better than the spectral choice's ([`super::search::dominance`]; it
    /// replaces that choice from [`super::partial::SEEDED_DOMINANCE`] on; NaN otherwise).
    #[serde(skip_serializing_if = "is_nan")]
    pub dominance: f64,
    /// The images of the search samples under its probe map (vertex ids of Y; the partial path
    /// only, empty elsewhere; not in the report).
    #[serde(skip)]
    pub sample_images: Vec<usize>,
}

/// Whether a score is missing (NaN): not written to the report.
fn is_nan(v: &f64) -> bool {
    v.is_nan()
}

impl Candidate {
    /// A candidate of size k with no score yet.
    pub(super) fn unscored(k: usize) -> Candidate {
        Candidate {
            k,
            distortion: f64::NAN,
            orientation: f64::NAN,
            data_misfit: f64::NAN,
            corrected_distortion: f64::NAN,
            corrected_orientation: f64::NAN,
            moved: 0,
            geodesic_corrected_distortion: f64::NAN,
            geodesic_corrected_orientation: f64::NAN,
            corrected_from: None,
            seeded: None,
            landmark_error: f64::NAN,
            from_landmarks: false,
            dominance: f64::NAN,
            sample_images: Vec::new(),
        }
    }
}

/// What [`axiomatic_pipeline`] returns.
#[derive(Clone, Debug)]
pub struct AxiomaticResult {
    /// The point map X → Y (length n).
    pub map_xy: Vec<usize>,
    /// The pull-back functional map of `map_xy` (final size × final size).
    pub c_yx: Pullback,
    /// The chosen candidate's pull-back before refinement (k × k).
    pub c_fit: Pullback,
    /// Every candidate, in the order of the options.
    pub candidates: Vec<Candidate>,
    /// Index of the chosen one.
    pub chosen: usize,
    /// (stage, seconds).
    pub stages: Vec<(String, f64)>,
    /// The samples of X and Y of the final refinement when the map Y → X is to be searched near
    /// their map ([`NearSearch`]: the final maps were, or the pair has more than
    /// `inverse_above_pairs` vertex pairs).
    pub near_samples: Option<(Samples, Samples)>,
    /// What the basin search's correction did (the correction of the candidate it started
    /// from; None without the search).
    pub correction: Option<super::search::Correction>,
    /// With landmarks: how well they agree with each other ([`super::landmarks::LandmarkCheck`]).
    pub landmark_check: Option<super::landmarks::LandmarkCheck>,
}

pub(super) fn samples_of(s: &PreparedShape, count: usize) -> Result<Samples> {
    match (s.positions(), count) {
        (Some(p), c) if c > 0 => farthest_point_samples(p, &s.basis.mass, c),
        _ => Ok(Samples::all(&s.basis.mass)),
    }
}

/// The descriptors the energy sees: F and G normalized, then up to `signed` signed descriptors
/// from the same pairs of columns on both shapes, keeping the pairs that are non-zero on both
/// (negated on Y for orientation-reversing maps, under which they change sign).
fn pipeline_data(
    x: &PreparedShape,
    y: &PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    p: &AxiomaticPipeline,
) -> Result<(Descriptors, Descriptors)> {
    let (fx, gy) = (descriptors::normalized(f, &x.basis.mass)?, descriptors::normalized(g, &y.basis.mass)?);
    if fx.q() != gy.q() {
        return Err(Error::invalid(
            "data",
            format!("{} functions on X but {} on Y; they must correspond", fx.q(), gy.q()),
        ));
    }
    let (Some(grads_x), Some(grads_y)) = (x.gradients(), y.gradients()) else {
        return Ok((fx, gy));
    };
    if p.signed == 0 || p.fit.orientation == Orientation::Ignore || fx.q() < 2 {
        return Ok((fx, gy));
    }
    // Twice as many candidates as wanted, of which the first usable ones are kept.
    let pairs = descriptors::signed_pairs(fx.q(), 2 * p.signed);
    let (sx, sy) = rayon::join(
        || descriptors::signed(&fx, grads_x, &x.basis, &pairs, p.signed_smoothing),
        || descriptors::signed(&gy, grads_y, &y.basis, &pairs, p.signed_smoothing),
    );
    let (sx, sy) = (sx?, sy?);
    let norm = |d: &Descriptors, mass: &[f64], j: usize| {
        d.values.col_as_slice(j).iter().zip(mass).map(|(v, a)| a * v * v).sum::<f64>().sqrt()
    };
    let (nx, ny): (Vec<f64>, Vec<f64>) = (
        (0..pairs.len()).map(|j| norm(&sx, &x.basis.mass, j)).collect(),
        (0..pairs.len()).map(|j| norm(&sy, &y.basis.mass, j)).collect(),
    );
    let (mx, my) = (nx.iter().fold(0.0f64, |a, &b| a.max(b)), ny.iter().fold(0.0f64, |a, &b| a.max(b)));
    let keep: Vec<usize> =
        (0..pairs.len()).filter(|&j| nx[j] > 1e-6 * mx && ny[j] > 1e-6 * my).take(p.signed).collect();
    if keep.is_empty() {
        return Ok((fx, gy));
    }
    let sign = if p.fit.orientation == Orientation::Reverse { -1.0 } else { 1.0 };
    let pick = |d: &Descriptors, norms: &[f64], s: f64| {
        Descriptors::new(
            Mat::from_fn(d.n(), keep.len(), |i, t| s * d.values[(i, keep[t])] / norms[keep[t]]),
            keep.iter().map(|&j| d.names[j].clone()).collect(),
        )
    };
    Ok((fx.concat(&pick(&sx, &nx, 1.0)?)?, gy.concat(&pick(&sy, &ny, sign)?)?))
}

/// Runs the default pipeline (module docs) from descriptors F (n × q) on X and G (m × q) on Y.
/// Errors: no candidate sizes, bases smaller than [`AxiomaticPipeline::basis_size`], and those of
/// the steps.
pub fn axiomatic_pipeline(
    x: &PreparedShape,
    y: &PreparedShape,
    f: &Descriptors,
    g: &Descriptors,
    p: &AxiomaticPipeline,
) -> Result<AxiomaticResult> {
    axiomatic_pipeline_cow(x, y, Cow::Borrowed(f), Cow::Borrowed(g), p)
}

/// [`axiomatic_pipeline`] with F and G borrowed or handed over: data handed over are released
/// as soon as the pipeline has made its own (normalized, with the signed descriptors), so that
/// they are not held through the refinement (at 10⁶ vertices the default WKS hold ≈ 0.34 GB per
/// shape; held through the polish they set its memory peak, BENCHMARKS.md). The maps are the
/// same either way.
pub fn axiomatic_pipeline_cow(
    x: &PreparedShape,
    y: &PreparedShape,
    f: Cow<'_, Descriptors>,
    g: Cow<'_, Descriptors>,
    p: &AxiomaticPipeline,
) -> Result<AxiomaticResult> {
    if p.candidates.is_empty() || p.candidates.contains(&0) {
        return Err(Error::invalid("candidates", "need at least one functional-map size ≥ 1"));
    }
    if !(p.bijective.is_finite() && p.bijective >= 0.0) {
        return Err(Error::invalid("bijectivity weight", format!("must be finite and ≥ 0, got {}", p.bijective)));
    }
    let need = p.basis_size();
    if x.basis.k() < need || y.basis.k() < need {
        return Err(Error::invalid(
            "bases",
            format!(
                "the pipeline needs {need} eigenpairs per shape, the bases hold {} and {}",
                x.basis.k(),
                y.basis.k()
            ),
        ));
    }
    let mut stages = Vec::new();
    let t = std::time::Instant::now();
    crate::progress::stage("descriptors")?;
    let (fx, gy) = pipeline_data(x, y, &f, &g, p)?;
    drop((f, g));
    // User landmarks: their bumps join the data (module `landmarks`).
    let lm = LandmarkData::new(x, y, &p.landmarks)?;
    let (fx, gy) = match &lm {
        Some(l) => l.functions(x, y, &fx, &gy, &p.landmarks)?,
        None => (fx, gy),
    };
    let pins = lm.as_ref().map_or_else(Vec::new, LandmarkData::pins);
    let lm_x: Vec<usize> = pins.iter().map(|&(i, _)| i).collect();
    let dx = ShapeData { basis: &x.basis, gradients: x.gradients(), descriptors: &fx, cells: x.quadrature_cells() };
    let dy = ShapeData { basis: &y.basis, gradients: y.gradients(), descriptors: &gy, cells: y.quadrature_cells() };
    stages.push(("descriptors".to_string(), t.elapsed().as_secs_f64()));
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    // Candidates: the pull-backs of the fits.
    let t = std::time::Instant::now();
    crate::progress::stage("functional maps")?;
    let fits: Vec<Pullback> = axiomatic_pullbacks(&dx, &dy, &p.fit, &p.candidates)?.into_iter().map(|r| r.0).collect();
    stages.push(("functional maps".to_string(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    crate::progress::stage("search samples")?;
    let probe_samples = landmarks::with_landmarks(samples_of(x, p.probe.samples)?, &lm_x, p.landmarks.pin_weight);
    let near_positions = near_positions(x, y, p);
    let probe_refs = match near_positions {
        Some(_) if fits.len() > 1 => Some(samples_of(y, p.probe.samples)?),
        _ => None,
    };
    let scale = (y.basis.mass.iter().sum::<f64>() / x.basis.mass.iter().sum::<f64>()).sqrt();
    let (tx, ty) = (x.triangles(), y.triangles());
    // The basin search (module `search`): samples of X and anchors of Y with their geodesic
    // distances.
    let search = match (tx, ty) {
        (Some(tx), Some(ty)) if p.search.samples > 0 => {
            let (sx, sy) = rayon::join(
                || SampleDistances::new(tx, &x.basis.mass, &GraphGeodesics::mesh_edges(tx)?, p.search.samples),
                || SampleDistances::new(ty, &y.basis.mass, &GraphGeodesics::mesh_edges(ty)?, p.search.anchors),
            );
            let sx = sx?;
            let neighbours = search::sample_neighbours(&sx, ORIENTATION_NEIGHBOURS);
            let sy = sy?;
            let descriptors = search::descriptor_distances(&sx, &sy, fx.values.as_ref(), gy.values.as_ref());
            Some(Search { x: sx, y: sy, neighbours, descriptors })
        }
        _ => None,
    };
    if search.is_some() {
        stages.push(("search samples".to_string(), t.elapsed().as_secs_f64()));
    }
    let t = std::time::Instant::now();
    crate::progress::stage("candidate probes")?;
    // Where a probe's map is read: the search samples' one-rings (score and orientation), or
    // without the search on large pairs the probe samples' one-rings, else every vertex.
    let patch: Option<Vec<usize>> = match (&search, tx) {
        (Some(s), Some(tx)) => Some(refine::incident_vertices(tx, &s.x.samples.vertices)),
        (None, Some(tx)) if probe_refs.is_some() => Some(refine::incident_vertices(tx, &probe_samples.vertices)),
        _ => None,
    };
    let centres: &[usize] = match &search {
        Some(s) => &s.x.samples.vertices,
        None => &probe_samples.vertices,
    };
    let ctx = ProbeContext {
        x,
        y,
        p,
        probe_samples: &probe_samples,
        near: &near_positions,
        probe_refs: &probe_refs,
        patch: &patch,
        centres,
        search: &search,
        scale,
        data: (&fx, &gy),
        landmarks: lm.as_ref(),
        pins: &pins,
        coarse: y.grid_vertices().filter(|_| p.coarse_zoomout),
    };
    // The candidates are probed independently: side by side, unless two probes' restricted
    // ZoomOuts would hold more than PROBES_TOGETHER_BYTES (at 10⁶ vertices they set the peak);
    // then one at a time, each probe's searches on both cores.
    let ky = p.probe.k_final.max(p.candidates.iter().copied().max().unwrap_or(0));
    let min_len = if probes_one_at_a_time(near_positions.is_some(), y.basis.n(), ky) { usize::MAX } else { 1 };
    let mut probed: Vec<Probe> = fits
        .par_iter()
        .zip(p.candidates.par_iter())
        .with_min_len(min_len)
        .map(|(c, &k)| {
            if fits.len() == 1 && search.is_none() {
                return Ok(Probe { candidate: Candidate::unscored(k), c: None, images: None, corrected: [None, None] });
            }
            ctx.probe(c, k, true)
        })
        .collect::<Result<_>>()?;
    stages.push(("candidate probes".to_string(), t.elapsed().as_secs_f64()));
    // The correction (module `search`): for each of its two forms (distances and data, distances
    // alone), the candidates' corrected sample maps of the asked orientation; the one of lowest
    // distortion becomes one more candidate (its moved samples take their corrected images, the
    // others keep theirs), probed as the others.
    let t = std::time::Instant::now();
    crate::progress::stage("correction")?;
    let mut correction = None;
    let mut starts: Vec<Pullback> = fits;
    if let Some(s) = &search {
        let originals = probed.len();
        // The hybrid sample map of each form (cheap), then their probes, in parallel.
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
            let (Some((fixed, mut report)), Some(images)) =
                (probed[from].corrected[slot].take(), probed[from].images.as_ref())
            else {
                continue;
            };
            // The samples the correction moved away from the candidate's images by more than
            // the search's resolution take their corrected images, the others keep the
            // candidate's.
            let moved: Vec<bool> =
                images.iter().zip(&fixed).map(|(&o, &f)| search::has_moved(&s.x, &s.y, o, f)).collect();
            report.moved = moved.iter().filter(|&&m| m).count();
            if report.moved > 0 {
                let hybrid: Vec<usize> =
                    fixed.iter().zip(images).zip(&moved).map(|((&f, &o), &m)| if m { f } else { o }).collect();
                hybrids.push((from, joint, hybrid));
            }
            if joint {
                correction = Some(report);
            }
        }
        let k0 = p.candidates.iter().copied().min().unwrap_or(1).min(s.x.len() / 4).max(1);
        let extra: Vec<(Probe, Pullback)> = hybrids
            .par_iter()
            .with_min_len(min_len)
            .map(|(from, joint, hybrid)| {
                let c0 = Pullback(refine::pullback(phi, psi, &s.x.samples, hybrid, k0, k0)?);
                let mut q = ctx.probe(&c0, k0, false)?;
                q.candidate.corrected_from = Some((*from, *joint));
                Ok((q, c0))
            })
            .collect::<Result<_>>()?;
        for (q, c0) in extra {
            probed.push(q);
            starts.push(c0);
        }
        // With landmarks, one more candidate from the landmarks alone: the samples trilaterated
        // from their distances to the landmarks, corrected with that as the data term.
        if let Some(l) = &lm {
            let fixed = l.trilaterated(&s.x, &s.y, p.search.rounds)?;
            let c0 = Pullback(refine::pullback(phi, psi, &s.x.samples, &fixed, k0, k0)?);
            let mut q = ctx.probe(&c0, k0, false)?;
            q.candidate.from_landmarks = true;
            probed.push(q);
            starts.push(c0);
        }
    }
    let candidates: Vec<Candidate> = probed.iter().map(|p| p.candidate.clone()).collect();
    // With the search: the geodesic distortion and the data misfit, each in units of its median
    // over the candidates (a map that fits distances by sliding a limb along itself fits the
    // data worse; one with a limb swapped for its mirror image fits distances worse).
    let median = |f: &dyn Fn(&Candidate) -> f64| {
        let mut v: Vec<f64> = candidates.iter().map(f).filter(|x| x.is_finite() && *x > 0.0).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        v.get(v.len() / 2).copied().unwrap_or(1.0)
    };
    let (me, md) = (median(&|c| c.distortion), median(&|c| c.data_misfit));
    let chosen = match (search.is_some(), lm.is_some()) {
        (true, false) => choose(&candidates, p.fit.orientation, |c| c.distortion / me + c.data_misfit / md),
        (false, false) => choose(&candidates, p.fit.orientation, |c| c.distortion),
        // With landmarks, their error in units of the tolerance joins the score; and when no
        // candidate of the asked orientation respects them (an error within one tolerance of the
        // lowest), they, not that orientation, tell a map from its mirror image.
        (_, true) => {
            let tol = p.landmarks.tolerance;
            let best = candidates.iter().map(|c| c.landmark_error).fold(f64::INFINITY, f64::min);
            let respected = candidates.iter().any(|c| agrees(c, p.fit.orientation) && c.landmark_error <= best + tol);
            let orientation = if respected { p.fit.orientation } else { Orientation::Ignore };
            let misfit = |c: &Candidate| if search.is_some() { c.data_misfit / md } else { 0.0 };
            choose(&candidates, orientation, |c| c.distortion / me + misfit(c) + c.landmark_error / tol)
        }
    };
    stages.push(("correction".to_string(), t.elapsed().as_secs_f64()));
    let c_fit = starts.swap_remove(chosen);
    // The final refinement starts from the fit, or (continue_probe) from the probe's result.
    let c_start = match (p.continue_probe, probed[chosen].c.take()) {
        (true, Some(c)) => c,
        _ => c_fit.clone(),
    };
    // The fits' data, the probes and the search are not read by the final refinement: released
    // before it (at 10⁶ vertices F and G hold ≈ 0.3 GB each, and the polish sets the peak).
    drop(probed);
    drop(search);
    drop((fx, gy));
    let (c_yx, map_xy, near_samples) =
        refine_from(x, y, c_start, &c_fit, p, &near_positions, (&pins, lm.as_ref()), &mut stages)?;
    let landmark_check = lm.as_ref().map(LandmarkData::check);
    Ok(AxiomaticResult { map_xy, c_yx, c_fit, candidates, chosen, stages, near_samples, correction, landmark_check })
}

/// What every probe of [`axiomatic_pipeline`] reads.
struct ProbeContext<'a> {
    x: &'a PreparedShape,
    y: &'a PreparedShape,
    p: &'a AxiomaticPipeline,
    probe_samples: &'a Samples,
    near: &'a Option<refine::Near<'a>>,
    probe_refs: &'a Option<Samples>,
    patch: &'a Option<Vec<usize>>,
    centres: &'a [usize],
    search: &'a Option<Search>,
    scale: f64,
    /// The fits' data F (n × q), G (m × q).
    data: (&'a Descriptors, &'a Descriptors),
    /// The user's landmarks (module `landmarks`), pinned in the probes' ZoomOut.
    landmarks: Option<&'a LandmarkData>,
    pins: &'a [(usize, usize)],
    /// Y's grid vertices for ZoomOut's steps before the last (`coarse_zoomout`), or None.
    coarse: Option<&'a [usize]>,
}

impl ProbeContext<'_> {
    /// ZoomOut from the start `c` (k × k) to the probe size on the probe samples, the map
    /// where it is scored, its orientation and distortion (geodesic on the search samples, or of
    /// the edges), and with `correct` the correction of its search samples.
    fn probe(&self, c: &Pullback, k: usize, correct: bool) -> Result<Probe> {
        let (x, y, p) = (self.x, self.y, self.p);
        let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
        let (tx, py, ny) = (x.triangles(), y.positions(), y.normals());
        let o = ZoomOutOptions { k_final: p.probe.k_final.max(k), step: p.probe.step };
        // The probe samples matched near their previous images on large pairs, else exactly.
        let scope = match (self.near, self.probe_refs) {
            (Some(near), Some(sy)) => {
                Scope::Near { near, x_cells: &self.probe_samples.vertices, y_cells: &sy.vertices }
            }
            _ => Scope::Exact,
        };
        let c = refine::zoomout_coarse_to_fine(
            phi,
            psi,
            self.probe_samples,
            c.as_ref(),
            &o,
            scope,
            self.pins,
            self.coarse,
        )?;
        let map = match self.patch {
            // The images of the patch; other entries stay 0 (unread).
            Some(patch) => {
                spread(phi.nrows(), patch, &refine::map_of_pullback(phi, psi, c.as_ref(), Some(patch), scope)?)
            }
            None => refine::map_of_pullback(phi, psi, c.as_ref(), None, scope)?,
        };
        let mut candidate = Candidate::unscored(k);
        if let Some(l) = self.landmarks {
            let images = refine::map_of_pullback(phi, psi, c.as_ref(), Some(&l.xs), Scope::Exact)?;
            candidate.landmark_error = l.error(&images);
        }
        candidate.orientation = match (tx, py, ny) {
            (Some(tx), Some(py), Some(ny)) if self.patch.is_some() => {
                refine::orientation_agreement_around(tx, py, ny, &map, self.centres)?
            }
            (Some(tx), Some(py), Some(ny)) => refine::orientation_agreement(tx, py, ny, &map)?,
            _ => f64::NAN,
        };
        let images = match (self.search, tx, py) {
            (Some(s), _, _) => {
                let images: Vec<usize> = s.x.samples.vertices.iter().map(|&v| map[v]).collect();
                candidate.distortion = search::distortion(&s.x, &s.y, &images);
                let (f, g) = (&self.data.0.values, &self.data.1.values);
                candidate.data_misfit =
                    s.x.samples
                        .vertices
                        .iter()
                        .zip(&images)
                        .map(|(&v, &w)| (0..f.ncols()).map(|c| (f[(v, c)] - g[(w, c)]).powi(2)).sum::<f64>().sqrt())
                        .sum::<f64>()
                        / images.len() as f64;
                Some(images)
            }
            (None, Some(tx), Some(py)) => {
                candidate.distortion = if self.patch.is_some() {
                    refine::metric_distortion_around(tx, py, self.scale, &map, self.centres)?
                } else {
                    refine::metric_distortion(tx, py, self.scale, &map)?
                };
                None
            }
            _ => None,
        };
        // The corrections of this candidate's samples (by distances and data, by distances
        // alone), and the orientation of their results.
        let mut corrected = [None, None];
        if let (Some(s), Some(images), Some(px), Some(nx), Some(py), Some(ny)) =
            (self.search, &images, x.positions(), x.normals(), py, ny)
        {
            if correct && p.search.rounds > 0 {
                let xs = &s.x.samples.vertices;
                for (slot, desc) in [Some(&s.descriptors), None].into_iter().enumerate() {
                    let (fixed, report) = search::correct(&s.x, &s.y, images, desc, p.search.rounds)?;
                    let e = report.trace.iter().copied().fold(f64::INFINITY, f64::min);
                    let o = search::orientation(px, nx, py, ny, xs, &fixed, &s.neighbours);
                    if slot == 0 {
                        (candidate.corrected_distortion, candidate.corrected_orientation) = (e, o);
                        candidate.moved = report.moved;
                    } else {
                        (candidate.geodesic_corrected_distortion, candidate.geodesic_corrected_orientation) = (e, o);
                    }
                    corrected[slot] = Some((fixed, report));
                }
            }
        }
        Ok(Probe { candidate, c: Some(Pullback(c)), images, corrected })
    }
}

/// The search's data: X's samples and Y's anchors with their distances, the samples'
/// neighbours for the orientation of sample maps.
struct Search {
    x: SampleDistances,
    y: SampleDistances,
    neighbours: Vec<Vec<usize>>,
    /// ‖F(s_i) − G(a)‖ between X's samples and Y's anchors, from the fits' data.
    descriptors: Mat<f64>,
}

/// Bytes a restricted probe holds per row of Y and column of its ZoomOut's largest size: the
/// reference Ψ Cᵀ (f64), its copy by cells (f64) and the cells' f32 strips.
const PROBE_BYTES_PER_ENTRY: usize = 8 + 8 + 4;

/// The most memory two candidate probes' restricted ZoomOuts may hold side by side (bytes): 1 GiB
/// (the 52k-vertex pairs need ≈ 0.13 GB, the 840k-vertex pair ≈ 2 GB, which then set the peak).
const PROBES_TOGETHER_BYTES: usize = 1 << 30;

/// Whether the candidate probes run one at a time: with restricted searches (`near`) on a Y of
/// m vertices, when two probes' ZoomOuts up to size k would hold more than
/// [`PROBES_TOGETHER_BYTES`] side by side.
fn probes_one_at_a_time(near: bool, m: usize, k: usize) -> bool {
    near && (2 * PROBE_BYTES_PER_ENTRY).saturating_mul(m).saturating_mul(k) > PROBES_TOGETHER_BYTES
}

/// Neighbours per sample in the orientation of sample maps ([`search::orientation`]).
const ORIENTATION_NEIGHBOURS: usize = 8;

/// A probed candidate: its scores, its probe's functional map and, with the search, the images
/// of the search samples and their correction.
struct Probe {
    candidate: Candidate,
    c: Option<Pullback>,
    images: Option<Vec<usize>>,
    /// The corrections by distances and data, and by distances alone.
    corrected: [Option<(Vec<usize>, search::Correction)>; 2],
}

/// A map of length n from the images of the vertices `rows` (0 elsewhere, unread).
fn spread(n: usize, rows: &[usize], images: &[usize]) -> Vec<usize> {
    let mut map = vec![0usize; n];
    rows.iter().zip(images).for_each(|(&v, &j)| map[v] = j);
    map
}

/// Whether a candidate's orientation agrees with the asked one (≥ 0 for preserving maps, ≤ 0 for
/// reversing ones; NaN and `Ignore` always).
pub(super) fn agrees(c: &Candidate, orientation: Orientation) -> bool {
    match orientation {
        Orientation::Preserve => c.orientation >= 0.0 || c.orientation.is_nan(),
        Orientation::Reverse => c.orientation <= 0.0 || c.orientation.is_nan(),
        Orientation::Ignore => true,
    }
}

/// The candidate with the smallest `score` among those whose orientation agrees with the asked
/// one (orientation ≥ 0 for preserving maps, ≤ 0 for reversing ones; all when none does or
/// orientation is ignored); the first candidate when no score could be measured (NaN).
pub(super) fn choose(candidates: &[Candidate], orientation: Orientation, score: impl Fn(&Candidate) -> f64) -> usize {
    let agrees = |c: &Candidate| agrees(c, orientation);
    let any = candidates.iter().any(agrees);
    (0..candidates.len())
        .filter(|&a| !any || agrees(&candidates[a]))
        .min_by(|&a, &b| {
            let (da, db) = (score(&candidates[a]), score(&candidates[b]));
            match (da.is_nan(), db.is_nan()) {
                (false, false) => da.total_cmp(&db),
                (true, false) => std::cmp::Ordering::Greater,
                (false, true) => std::cmp::Ordering::Less,
                (true, true) => a.cmp(&b),
            }
        })
        .unwrap_or(0)
}

/// Samples of X (the first of the final ZoomOut's farthest-point samples) on which the start
/// and the end of the final ZoomOut are compared when there are landmarks.
const LANDMARK_CHECK_SAMPLES: usize = 500;
/// The final ZoomOut's start is kept over its end when its landmark-distance residual is lower
/// by at least this share. On near-isometric pairs the two differ by noise: on the 97 faust_r
/// pairs with 5 landmarks the residual of the map at 60 over that at 128 lies in 0.96–1.07,
/// and the longer ZoomOut is the more accurate on 95 of them; where the end drifted on the
/// gorilla pairs, the start's residual was 21–37 % lower (EXPERIMENTS.md).
const LANDMARK_START_MARGIN: f64 = 0.1;

/// With landmarks (module `landmarks`, 3.): the final ZoomOut's start `c_start` instead of its
/// result `c` when the start's map of the first [`LANDMARK_CHECK_SAMPLES`] of `sx` repeats the
/// distances to the landmarks better by [`LANDMARK_START_MARGIN`] or more
/// ([`LandmarkData::distance_residual`]). `c` as
/// it is without landmarks, when ZoomOut did not grow the map, or above `near.above_pairs`
/// vertex pairs (the sample maps would need the restricted searches).
fn closer_to_landmarks(
    x: &PreparedShape,
    y: &PreparedShape,
    p: &AxiomaticPipeline,
    lm: Option<&LandmarkData>,
    sx: &Samples,
    c_start: &Pullback,
    c: Mat<f64>,
) -> Result<Mat<f64>> {
    let pairs = (x.n() as u64).saturating_mul(y.n() as u64);
    let Some(lm) = lm.filter(|_| c_start.as_ref().nrows() < c.nrows() && pairs <= p.near.above_pairs) else {
        return Ok(c);
    };
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    let check = &sx.vertices[..sx.vertices.len().min(LANDMARK_CHECK_SAMPLES)];
    let residual = |c: faer::MatRef<f64>| -> Result<f64> {
        Ok(lm.distance_residual(check, &refine::map_of_pullback(phi, psi, c, Some(check), Scope::Exact)?))
    };
    let (start, end) = (residual(c_start.as_ref())?, residual(c.as_ref())?);
    Ok(if start < (1.0 - LANDMARK_START_MARGIN) * end { c_start.as_ref().to_owned() } else { c })
}

/// Large pairs (n · m above `p.near.above_pairs`, both shapes with positions, sampled probes
/// and refinement): every search restricted to samples or near the samples' map (NearSearch);
/// None otherwise.
pub(super) fn near_positions<'a>(
    x: &'a PreparedShape,
    y: &'a PreparedShape,
    p: &AxiomaticPipeline,
) -> Option<refine::Near<'a>> {
    let (px, py) = (x.positions()?, y.positions()?);
    let pairs = (px.len() as u64).saturating_mul(py.len() as u64);
    (pairs > p.near.above_pairs && p.probe.samples > 0 && p.refine.samples > 0).then_some(refine::Near {
        x: px,
        y: py,
        cells: p.near.cells,
        certify: pairs <= p.near.certified_up_to,
    })
}

/// The final refinement from the pull-back `c_start`: ZoomOut (or its bijective variant) to
/// `p.refine.k_final`, then the polish. Returns (the final pull-back, map_xy, the samples of the
/// restricted final searches) and appends its stage times.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub(super) fn refine_from(
    x: &PreparedShape,
    y: &PreparedShape,
    c_start: Pullback,
    c_fit: &Pullback,
    p: &AxiomaticPipeline,
    near_positions: &Option<refine::Near>,
    (pins, lm): (&[(usize, usize)], Option<&LandmarkData>),
    stages: &mut Vec<(String, f64)>,
) -> Result<(Pullback, Vec<usize>, Option<(Samples, Samples)>)> {
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
    let coarse = y.grid_vertices().filter(|_| p.coarse_zoomout);
    let t = std::time::Instant::now();
    crate::progress::stage("zoomout")?;
    // Landmarks (module `landmarks`) are samples of both shapes, pinned in every point map.
    let (lm_x, lm_y): (Vec<usize>, Vec<usize>) = pins.iter().copied().unzip();
    let pin = |mut map: Vec<usize>| {
        for &(i, j) in pins {
            map[i] = j;
        }
        map
    };
    if p.refine.k_final == 0 {
        let map = pin(refine::map_of_pullback(phi, psi, c_fit.as_ref(), None, Scope::Exact)?);
        let unrefined = (c_fit.clone(), map, None);
        stages.push(("zoomout".to_string(), t.elapsed().as_secs_f64()));
        return Ok(unrefined);
    }
    // Samples computed once for ZoomOut (or its bijective variant) and the polish.
    let pw = p.landmarks.pin_weight;
    // The two shapes' farthest-point samples (sequential each) side by side.
    let (sx, sy) = rayon::join(
        || samples_of(x, p.refine.samples),
        || (p.bijective > 0.0 || p.polish > 0).then(|| samples_of(y, p.refine.samples)).transpose(),
    );
    let sx = landmarks::with_landmarks(sx?, &lm_x, pw);
    let sy = sy?.map(|s| landmarks::with_landmarks(s, &lm_y, pw));
    let (c, map) = match &sy {
        Some(sy) if p.bijective > 0.0 => {
            let o = refine::BijectiveOptions {
                k_final: p.refine.k_final.max(c_start.k_x()),
                step: p.refine.step,
                bijectivity: p.bijective,
            };
            // The start of the pull-back of the inverse map: C_yxᵀ (orthonormal maps).
            let c_xy0 = c_start.transposed();
            let (c, m, _) = refine::bijective_zoomout(phi, psi, &sx, sy, c_start.as_ref(), c_xy0.as_ref(), &o)?;
            (c, Some(pin(m)))
        }
        _ => {
            let o = ZoomOutOptions { k_final: p.refine.k_final.max(c_start.k_x()), step: p.refine.step };
            if p.polish > 0 {
                // The polish reads the point map off itself.
                let scope = match (near_positions, &sy) {
                    (Some(near), Some(sy)) => Scope::Near { near, x_cells: &sx.vertices, y_cells: &sy.vertices },
                    _ => Scope::Exact,
                };
                let c = refine::zoomout_coarse_to_fine(phi, psi, &sx, c_start.as_ref(), &o, scope, pins, coarse)?;
                (closer_to_landmarks(x, y, p, lm, &sx, &c_start, c)?, None)
            } else {
                let c =
                    refine::zoomout_coarse_to_fine(phi, psi, &sx, c_start.as_ref(), &o, Scope::Exact, pins, coarse)?;
                let c = closer_to_landmarks(x, y, p, lm, &sx, &c_start, c)?;
                let m = pin(refine::map_of_pullback(phi, psi, c.as_ref(), None, Scope::Exact)?);
                (c, Some(m))
            }
        }
    };
    stages.push(("zoomout".to_string(), t.elapsed().as_secs_f64()));
    match map {
        Some(m) if p.polish == 0 => Ok((Pullback(c), m, None)),
        _ => {
            let t = std::time::Instant::now();
            crate::progress::stage("polish")?;
            let sy = match sy {
                Some(sy) => sy,
                None => landmarks::with_landmarks(samples_of(y, p.refine.samples)?, &lm_y, pw),
            };
            let near = near_positions.as_ref().filter(|_| p.refine.samples > 0);
            let scope = match near {
                Some(near) => Scope::Near { near, x_cells: &sx.vertices, y_cells: &sy.vertices },
                None => Scope::Exact,
            };
            let (c, map) = refine::bijective_polish_pinned(phi, psi, &sx, &sy, c.as_ref(), p.polish, scope, pins)?;
            stages.push(("polish".to_string(), t.elapsed().as_secs_f64()));
            let pairs = (phi.nrows() as u64).saturating_mul(psi.nrows() as u64);
            let inverse_near = p.refine.samples > 0
                && x.positions().is_some()
                && y.positions().is_some()
                && (near.is_some() || pairs > p.near.inverse_above_pairs);
            Ok((Pullback(c), map, inverse_near.then_some((sx, sy))))
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::descriptors::signatures::{wks_recipe, WksRecipe};
    use crate::fmap::axiomatic::spectral_side;
    use crate::fmap::energy::operator_commutativity;
    use crate::prepared::LaplacianChoice;
    use crate::primitives::mirror_symmetric_blob;
    use crate::shape::Shape;

    /// X (a mirror-symmetric blob), a vertex-permuted copy Y, the true map X → Y and its mirror
    /// image (also the pair of `landmarks`' tests).
    pub(in crate::matching) fn pair() -> (PreparedShape, PreparedShape, Vec<usize>, Vec<usize>) {
        let (x, mirror) = mirror_symmetric_blob(3);
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 211 + 17) % n).collect(); // X vertex i is Y vertex perm[i]
        let mut inv = vec![0; n];
        for (i, &p) in perm.iter().enumerate() {
            inv[p] = i;
        }
        let y = x.permuted(&inv).unwrap();
        let mirrored: Vec<usize> = (0..n).map(|i| perm[mirror[i]]).collect();
        let prep =
            |m: crate::shape::TriMesh| PreparedShape::new(Shape::Mesh(m), LaplacianChoice::Auto, 128, None).unwrap();
        (prep(x), prep(y), perm, mirrored)
    }

    /// The share of vertices on which two maps agree.
    pub(in crate::matching) fn agreement(a: &[usize], b: &[usize]) -> f64 {
        a.iter().zip(b).filter(|(p, q)| p == q).count() as f64 / a.len() as f64
    }

    /// The landmark-distance residual sees a whole map: 0 for the true map, clearly more for its
    /// mirror image, which agrees with the truth at the landmarks' neighbours only. Of the final
    /// ZoomOut's start and end, the one the landmarks' distances agree with is kept.
    #[test]
    fn the_distances_to_landmarks_choose_the_start_or_the_end_of_the_final_zoomout() {
        let (x, y, truth, mirrored) = pair();
        let all: Vec<usize> = (0..x.n()).collect();
        let picks = crate::spatial::farthest_points(x.triangles().unwrap(), &all, 5);
        let pairs: Vec<(usize, usize)> = picks.iter().map(|&i| (i, truth[i])).collect();
        let lm = LandmarkData::new(&x, &y, &Landmarks { pairs, ..Landmarks::default() }).unwrap().unwrap();
        let sx = samples_of(&x, 300).unwrap();
        let on = |m: &[usize]| -> Vec<usize> { sx.vertices.iter().map(|&v| m[v]).collect() };
        let (good, bad) =
            (lm.distance_residual(&sx.vertices, &on(&truth)), lm.distance_residual(&sx.vertices, &on(&mirrored)));
        assert!(good < 1e-9 && bad > 0.05, "residual of the true map {good}, of its mirror image {bad}");
        let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
        let c_of = |m: &[usize], k: usize| refine::pullback(phi, psi, &sx, &on(m), k, k).unwrap();
        let p = AxiomaticPipeline::default();
        // The start is the true map at 20, the end its mirror image at 40: the start is kept.
        let start = Pullback(c_of(&truth, 20));
        let kept = closer_to_landmarks(&x, &y, &p, Some(&lm), &sx, &start, c_of(&mirrored, 40)).unwrap();
        assert_eq!(kept.nrows(), 20);
        // The other way round, the end; without landmarks, always the end.
        let start = Pullback(c_of(&mirrored, 20));
        assert_eq!(closer_to_landmarks(&x, &y, &p, Some(&lm), &sx, &start, c_of(&truth, 40)).unwrap().nrows(), 40);
        let start = Pullback(c_of(&truth, 20));
        assert_eq!(closer_to_landmarks(&x, &y, &p, None, &sx, &start, c_of(&mirrored, 40)).unwrap().nrows(), 40);
    }

    #[test]
    fn the_pipeline_finds_the_true_map_not_its_mirror_image() {
        let (x, y, truth, mirrored) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        // The descriptors cannot tell the two maps apart: they are mirror-symmetric.
        let mut worst = 0.0f64;
        for j in 0..f.q() {
            for i in 0..x.n() {
                worst = worst.max(
                    (f.values[(i, j)] - g.values[(mirrored[i], j)]).abs()
                        / f.values.col_as_slice(j).iter().fold(0.0f64, |a, b| a.max(b.abs())),
                );
            }
        }
        assert!(worst < 1e-6, "descriptors differ between a vertex and its mirror image by {worst}");
        // The orientation term is lower for the true map than for the mirrored one (both
        // functional maps exact pull-backs at k = 20).
        let (phi, psi) = (x.basis.eigenvectors.as_ref(), y.basis.eigenvectors.as_ref());
        let all = Samples::all(&x.basis.mass);
        let c_true = refine::pullback(phi, psi, &all, &truth, 20, 20).unwrap();
        let c_mirror = refine::pullback(phi, psi, &all, &mirrored, 20, 20).unwrap();
        let p = AxiomaticPipeline::default();
        let (fx, gy) = pipeline_data(&x, &y, &f, &g, &p).unwrap();
        let sx = spectral_side(
            &ShapeData { basis: &x.basis, gradients: x.gradients(), descriptors: &fx, cells: None },
            20,
            false,
            true,
            true,
            "X",
        )
        .unwrap();
        let sy = spectral_side(
            &ShapeData { basis: &y.basis, gradients: y.gradients(), descriptors: &gy, cells: None },
            20,
            false,
            true,
            true,
            "Y",
        )
        .unwrap();
        // C_yx: from Y's operators to X's.
        let e_true = operator_commutativity(c_true.as_ref(), &sy.orientation, &sx.orientation, 1.0);
        let e_mirror = operator_commutativity(c_mirror.as_ref(), &sy.orientation, &sx.orientation, 1.0);
        assert!(e_true < 0.1 * e_mirror, "orientation term: true map {e_true}, mirror image {e_mirror}");
        // The default pipeline recovers the true permutation; reversed, it finds the mirror.
        let res = axiomatic_pipeline(&x, &y, &f, &g, &p).unwrap();
        let (good, bad) = (agreement(&res.map_xy, &truth), agreement(&res.map_xy, &mirrored));
        assert!(good > 0.95 && bad < 0.1, "recovered {good} of the true map, {bad} of its mirror image");
        let rev = AxiomaticPipeline { fit: AxiomaticOptions { orientation: Orientation::Reverse, ..p.fit }, ..p };
        let res = axiomatic_pipeline(&x, &y, &f, &g, &rev).unwrap();
        let (good, bad) = (agreement(&res.map_xy, &truth), agreement(&res.map_xy, &mirrored));
        assert!(bad > 0.95 && good < 0.1, "reversed: {bad} of the mirror image, {good} of the true map");
    }

    /// With every search of the pipeline restricted to the neighbourhood of the samples' maps
    /// (NearSearch forced on this 642-vertex pair, 100 probe and 200 refinement samples, 8
    /// cells), the maps X → Y and Y → X agree with those of the exact searches on ≥ 95 % of the
    /// vertices and recover the true map; with the map Y → X alone restricted, the map X → Y, the
    /// pull-back and (certified) the map Y → X are the exact searches' own.
    #[test]
    fn restricted_searches_agree_with_the_exact_ones() {
        use crate::matching::{run, MatchOptions, Method};
        let (x, y, truth, _) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        let mut p = AxiomaticPipeline::default();
        p.probe.samples = 100;
        p.refine.samples = 200;
        let run = |p: &AxiomaticPipeline| {
            let o = MatchOptions { method: Method::Axiomatic, axiomatic: p.clone(), ..MatchOptions::default() };
            run(&x, &y, &f, &g, &o).unwrap()
        };
        let exact = run(&p);
        p.near = NearSearch { above_pairs: 0, cells: 8, ..Default::default() };
        let near = run(&p);
        let mut inverse = vec![0; truth.len()];
        for (i, &j) in truth.iter().enumerate() {
            inverse[j] = i;
        }
        let (xy, yx) = (agreement(&near.map_xy, &exact.map_xy), agreement(&near.map_yx, &exact.map_yx));
        let (txy, tyx) = (agreement(&near.map_xy, &truth), agreement(&near.map_yx, &inverse));
        eprintln!("agreement with the exact searches: X → Y {xy:.3}, Y → X {yx:.3}; with the truth {txy:.3}, {tyx:.3}");
        assert!(xy >= 0.95 && yx >= 0.95, "{xy} {yx}");
        assert!(txy >= 0.95 && tyx >= 0.95, "{txy} {tyx}");
        // The map Y → X alone restricted (`inverse_above_pairs`): the map X → Y and the
        // pull-back stay those of the exact searches, and the map back, certified (the
        // default), is the exact search's; uncertified it agrees with it.
        p.near = NearSearch { above_pairs: u64::MAX, cells: 8, inverse_above_pairs: 0, ..Default::default() };
        let inverse_near = run(&p);
        assert_eq!(inverse_near.map_xy, exact.map_xy);
        assert_eq!(inverse_near.c, exact.c);
        assert_eq!(inverse_near.map_yx, exact.map_yx);
        p.near.inverse_certified_up_to = 0;
        let uncertified = run(&p);
        let (yx, tyx) = (agreement(&uncertified.map_yx, &exact.map_yx), agreement(&uncertified.map_yx, &inverse));
        eprintln!("Y → X alone restricted near the samples' map, uncertified: agreement with the exact search {yx:.3}, with the truth {tyx:.3}");
        assert!(yx >= 0.95 && tyx >= 0.95, "{yx} {tyx}");
    }

    /// Data handed over (`matching::run_owned`, released inside the pipeline) give the match of
    /// borrowed data (`matching::run`): the same maps both ways and the same C.
    #[test]
    fn handed_over_data_give_the_borrowed_data_match() {
        use crate::matching::{run, run_owned, MatchOptions, Method};
        let (x, y, _, _) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        let mut p = AxiomaticPipeline::default();
        p.probe.samples = 100;
        p.refine.samples = 200;
        let o = MatchOptions { method: Method::Axiomatic, axiomatic: p, ..MatchOptions::default() };
        let borrowed = run(&x, &y, &f, &g, &o).unwrap();
        let owned = run_owned(&x, &y, f, g, &o).unwrap();
        assert_eq!(owned.map_xy, borrowed.map_xy);
        assert_eq!(owned.map_yx, borrowed.map_yx);
        assert_eq!(owned.c, borrowed.c);
    }

    /// The completion method with the axiomatic prior (orientation on) finds the true map on the
    /// mirror-symmetric pair, and its mirror image with the orientation reversed.
    #[test]
    fn the_completion_prior_tells_the_map_from_its_mirror_image() {
        use crate::completion::{CompletionOptions, Scaling};
        use crate::matching::{run, Extraction, MatchOptions, Method, Refine};
        let (x, y, truth, mirrored) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        let p = AxiomaticPipeline::default();
        // Unsigned WKS: the data cannot tell the map from its mirror image; the prior must.
        let (fx, gy) = (f.clone(), g.clone());
        let mut completion = CompletionOptions::paper(true, Scaling::Unit);
        completion.params.mu_prior = 1.0;
        completion.params.k_comm = 20;
        let opts = |orientation| MatchOptions {
            method: Method::Completion,
            commutativity: 1e-3,
            completion: completion.clone(),
            init_k: 20,
            extraction: Extraction::Fmap,
            refine: Refine::None,
            axiomatic: AxiomaticPipeline { fit: AxiomaticOptions { orientation, ..p.fit }, ..p.clone() },
            ..MatchOptions::default()
        };
        let res = run(&x, &y, &fx, &gy, &opts(Orientation::Preserve)).unwrap();
        let Some(crate::matching::SolverReport::Completion(report)) = &res.solver else {
            panic!("no completion report")
        };
        let prior = report.terms().prior;
        assert!(prior > 0.0, "the prior is part of the objective: {:?}", report.terms());
        let (good, bad) = (agreement(&res.map_xy, &truth), agreement(&res.map_xy, &mirrored));
        assert!(good > 0.5 && bad < 0.1, "preserve: recovered {good} of the true map, {bad} of its mirror image");
        let res = run(&x, &y, &fx, &gy, &opts(Orientation::Reverse)).unwrap();
        let (good, bad) = (agreement(&res.map_xy, &truth), agreement(&res.map_xy, &mirrored));
        assert!(bad > 0.5 && good < 0.1, "reverse: recovered {bad} of the mirror image, {good} of the true map");
        // Without its energy, or in a vertex form, the weight is an error.
        let mut o = opts(Orientation::Preserve);
        o.completion.form = crate::completion::Form::LowNorm;
        assert!(run(&x, &y, &fx, &gy, &o).is_err());
    }

    /// The probes run side by side on the 52k-vertex pairs and one at a time on the 840k one
    /// (the default probe size 60), and always side by side without restricted searches.
    #[test]
    fn only_probes_too_large_for_memory_run_one_at_a_time() {
        assert!(!probes_one_at_a_time(true, 52_565, 60));
        assert!(probes_one_at_a_time(true, 840_455, 60));
        assert!(!probes_one_at_a_time(false, 840_455, 60));
        assert!(probes_one_at_a_time(true, usize::MAX, usize::MAX));
    }

    #[test]
    fn bad_options_are_errors() {
        let (x, y, _, _) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        let p = AxiomaticPipeline { candidates: vec![], ..AxiomaticPipeline::default() };
        assert!(axiomatic_pipeline(&x, &y, &f, &g, &p).is_err());
        let p = AxiomaticPipeline {
            refine: ZoomOutSchedule { k_final: 500, step: 5, samples: 0 },
            ..AxiomaticPipeline::default()
        };
        let e = axiomatic_pipeline(&x, &y, &f, &g, &p).unwrap_err().to_string();
        assert!(e.contains("eigenpairs"), "{e}");
        let short = Descriptors::new(g.values.subcols(0, 3).to_owned(), g.names[..3].to_vec()).unwrap();
        assert!(axiomatic_pipeline(&x, &y, &f, &short, &AxiomaticPipeline::default()).is_err());
        let p = AxiomaticPipeline { bijective: f64::NAN, ..AxiomaticPipeline::default() };
        let e = axiomatic_pipeline(&x, &y, &f, &g, &p).unwrap_err().to_string();
        assert!(e.contains("bijectivity"), "{e}");
    }
}
