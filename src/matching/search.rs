//! The basin search of the default pipeline: which candidate map lies in the right basin, and a
//! correction of the chosen map's samples where a limb, a half of the body or a twisted trunk
//! went to the wrong place.
//!
//! **The score** of a point map π: X → Y is its geodesic distortion on `s` farthest-point
//! samples s_1 … s_s of X (shapes at unit area, [`crate::prepared`]):
//!
//! E(π) = Σ_{i<j} |d_X(s_i, s_j) − d_Y(π(s_i), π(s_j))| / Σ_{i<j} d_X(s_i, s_j),
//!
//! the Gromov-type energy of isometric matching restricted to the samples, with d the
//! shortest-path distances along the edges of each surface ([`GraphGeodesics`]). On Y the
//! distances are those between `a` farthest-point anchors, each vertex read as its nearest anchor
//! (its geodesic Voronoi cell): d_Y(u, v) ≈ d_Y(ā(u), ā(v)), off by at most twice the anchors'
//! covering radius, so that scoring a map or moving a sample costs table look-ups, not
//! shortest-path runs. Unlike the metric distortion of edges
//! ([`crate::refine::metric_distortion`]), which is dominated by the vertex-level jitter of any
//! point map, E compares distances across the whole shape: a map with two legs swapped, a
//! mirrored arm or a trunk turned by half a turn changes the distances between the parts by a
//! fair share of their length (EXPERIMENTS.md, "The basin search").
//!
//! **The correction** is coordinate descent on the same energy: every sample's image is moved to
//! the anchor of Y whose distances to the other samples' images best agree with the distances on
//! X (an L1 trilateration),
//!
//! π(s_i) ← argmin_{anchors a} Σ_{j ≠ i} |d_X(s_i, s_j) − d_Y(a, π(s_j))|,
//!
//! for all i at once, repeated while E decreases. A part mapped to the wrong limb is pulled to the
//! limb whose distances to the rest of the map fit. The isometry alone cannot tell a map from its
//! mirror image: the candidates come from orientation-aware fits, and the rounds keep their
//! orientation (every image is placed by the others).
//!
//! Cost: s + a shortest-path runs (once per shape), then s · a · s additions per round.

use faer::{Mat, MatRef};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geodesic::GraphGeodesics;
use crate::shape::TriMesh;
use crate::spatial::{farthest_point_samples, Samples};

/// Options of the basin search.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SearchOptions {
    /// Farthest-point samples of X the score and the correction are computed on (0: no search,
    /// the candidates are compared by the metric distortion of their edges).
    pub samples: usize,
    /// Farthest-point anchors of Y: its distances, and the places a corrected image can take.
    pub anchors: usize,
    /// Rounds of the correction at most (0: none).
    pub rounds: usize,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions { samples: 200, anchors: 500, rounds: 10 }
    }
}

/// Cells of the Voronoi graph ([`GraphGeodesics::voronoi_graph`]) in which [`SampleDistances`]
/// measures the samples' distances on meshes of more than twice as many vertices (the mesh's own
/// edge graph below). The search compares distances at the resolution of its anchors (500 by
/// default): 25 cells per anchor, five times finer in spacing. The cells' detours lengthen the
/// distances by ≈ 6.6 % on average, alike on both shapes, and each sample's Dijkstra visits
/// 12,500 nodes instead of n, on a mesh of any size. Measured (EXPERIMENTS.md, "The search and
/// the fits on cells"): 20 faust_r pairs subdivided to 20k vertices with 8,000 cells here and
/// in the quadrature mean error 1.822 → 1.818, every pair within 0.05; cat0 → cat10 (28k)
/// 1.248 → 1.234, david0 → david1 (52k) 1.105 → 1.108 while the stage takes 0.44 s instead of
/// 1.17 s and 0.56 s instead of 2.48 s; too few cells do hurt: 2,400 on the 5k faust_r shapes
/// (five per anchor) 1.857 → 1.882 over 97 pairs, one pair 4.57.
pub const GRAPH_NODES: usize = 12_500;

/// Farthest-point samples of a shape, the geodesic distances between them and each vertex's
/// nearest sample.
#[derive(Clone, Debug)]
pub struct SampleDistances {
    /// The samples (vertex ids and Voronoi-area weights).
    pub samples: Samples,
    /// d(s_i, s_j) (samples × samples).
    pub distances: Mat<f64>,
    /// For every vertex (length n) the position of its nearest sample in `samples`.
    pub nearest: Vec<u32>,
    /// Covering radius of the samples: the largest distance from a vertex to its nearest sample.
    pub radius: f64,
}

impl SampleDistances {
    /// `count` farthest-point samples of the surface `mesh` (vertex weights `mass`, length n),
    /// their pairwise distances along `graph` (the edges of `mesh`) and the geodesic Voronoi
    /// cells. Errors: fewer than 3 samples, and those of the sampling and of the graph.
    pub fn new(mesh: &TriMesh, mass: &[f64], graph: &GraphGeodesics, count: usize) -> Result<Self> {
        let samples = farthest_point_samples(mesh.vertices(), mass, count)?;
        let s = samples.len();
        if s < 3 {
            return Err(Error::invalid("search samples", format!("need at least 3, got {s}")));
        }
        let v = &samples.vertices;
        let rows: Vec<Vec<f64>> = if graph.n() > 2 * GRAPH_NODES {
            // Large meshes: the samples' distances in the Voronoi graph of GRAPH_NODES cells
            // (the samples' own among them), one Dijkstra per sample of O(GRAPH_NODES log) instead
            // of O(n log n).
            let mut nodes = v.clone();
            let mut taken = vec![false; graph.n()];
            v.iter().for_each(|&a| taken[a] = true);
            nodes.extend(crate::spatial::grid_samples(mesh.vertices(), GRAPH_NODES).into_iter().filter(|&a| !taken[a]));
            let coarse = graph.voronoi_graph(&nodes)?;
            (0..s)
                .into_par_iter()
                .map(|a| coarse.pair_distances(&(0..s).map(|b| (a, b)).collect::<Vec<_>>()))
                .collect::<Result<_>>()?
        } else {
            v.par_iter()
                .map(|&a| graph.pair_distances(&v.iter().map(|&b| (a, b)).collect::<Vec<_>>()))
                .collect::<Result<_>>()?
        };
        let distances = Mat::from_fn(s, s, |i, j| 0.5 * (rows[i][j] + rows[j][i]));
        let (to_nearest, nearest) = graph.nearest_sources(v)?;
        let radius = to_nearest.iter().copied().filter(|r| r.is_finite()).fold(0.0, f64::max);
        Ok(SampleDistances { samples, distances, nearest, radius })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether there is no sample (never true for a value built by [`SampleDistances::new`]).
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

/// mean |p − q| over the pairs (p, q) whose two values are finite (distances, unreachable = ∞);
/// None when no pair is. The comparison of two shapes' distances that the per-sample
/// distortion, the landmarks' trilateration costs and their residual share.
pub(super) fn mean_abs_difference(pairs: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    let (sum, count) = pairs
        .filter(|(p, q)| p.is_finite() && q.is_finite())
        .fold((0.0, 0usize), |(sum, count), (p, q)| (sum + (p - q).abs(), count + 1));
    (count > 0).then(|| sum / count as f64)
}

/// The anchors of Y (positions in `y.samples`) of the images of X's samples.
fn anchors_of(y: &SampleDistances, images: &[usize]) -> Vec<usize> {
    images.iter().map(|&v| y.nearest[v] as usize).collect()
}

/// E(π) of the module docs from X's samples (`x`), Y's anchors (`y`) and the images of X's
/// samples (vertex ids of Y, length `x.len()`). Pairs at infinite distance on either shape
/// (different components) are skipped; ∞ when no pair is left.
pub fn distortion(x: &SampleDistances, y: &SampleDistances, images: &[usize]) -> f64 {
    anchored_distortion(&x.distances, &y.distances, &anchors_of(y, images))
}

/// The distortion of every sample of X under a sample map: for sample i,
/// mean_{j ≠ i} |d_X(s_i, s_j) − d_Y(π(s_i), π(s_j))| over the pairs at finite distance on both
/// shapes (the terms of E(π) that involve sample i; Y's distances between the anchors nearest
/// the images, as [`distortion`]), in X's units (`x`); ∞ for a sample without such a pair.
/// `images`: vertex ids of Y, length `x.len()`. Length `x.len()`.
pub fn sample_distortions(x: &SampleDistances, y: &SampleDistances, images: &[usize]) -> Vec<f64> {
    let anchors = anchors_of(y, images);
    let (dx, dy) = (&x.distances, &y.distances);
    (0..anchors.len())
        .map(|i| {
            let pairs = (0..anchors.len()).filter(|&j| j != i).map(|j| (dx[(i, j)], dy[(anchors[i], anchors[j])]));
            mean_abs_difference(pairs).unwrap_or(f64::INFINITY)
        })
        .collect()
}

/// The share of the samples that the sample map of distortions `b` fits better than the one of
/// distortions `a` (both from [`sample_distortions`] on the same samples): the fraction of i with
/// b_i < a_i, in [0, 1]; 0 for no samples.
pub fn dominance(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    a.iter().zip(b).filter(|(a, b)| b < a).count() as f64 / n as f64
}

fn anchored_distortion(dx: &Mat<f64>, dy: &Mat<f64>, anchors: &[usize]) -> f64 {
    let s = anchors.len();
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..s {
        for j in (i + 1)..s {
            let (a, b) = (dx[(i, j)], dy[(anchors[i], anchors[j])]);
            if a.is_finite() && b.is_finite() {
                num += (a - b).abs();
                den += a;
            }
        }
    }
    if den > 0.0 {
        num / den
    } else {
        f64::INFINITY
    }
}

/// cost_r += |t − d_r| for every anchor r (f32; each entry its own sum, in the callers' order).
#[inline(always)]
fn add_abs_differences_generic(cost: &mut [f32], t: f32, d: &[f32]) {
    for (c, d) in cost.iter_mut().zip(d) {
        *c += (t - d).abs();
    }
}

crate::linalg::at_vector_width! {
    /// [`add_abs_differences_generic`] at the CPU's vector width.
    fn add_abs_differences(cost: &mut [f32], t: f32, d: &[f32]) = add_abs_differences_generic
}

/// One round of the correction (module docs): for every sample i of X the anchor a of Y
/// minimizing its cost in the energy J of [`correct`],
/// mean_{j≠i} |d_X(s_i, s_j) − d_Y(a, π(s_j))| / δ̄ + ‖F(s_i) − G(a)‖ / σ̄,
/// given the current anchors of the images (positions in `y.samples`), all samples against the
/// same current images. `dy` holds Y's anchor distances in single precision, column by column,
/// with unreachable pairs at a large finite value ([`finite_f32`]); `desc` (s × a, optional) the
/// descriptor distances ‖F(s_i) − G(a)‖; `scales` = (δ̄, σ̄). Returns the new anchors.
fn trilaterate(
    dx: &Mat<f64>,
    dy: &[f32],
    a: usize,
    current: &[usize],
    desc: Option<&Mat<f64>>,
    scales: (f64, f64),
) -> Vec<usize> {
    let s = current.len();
    (0..s)
        .into_par_iter()
        .map(|i| {
            let mut cost = vec![0.0f32; a];
            let mut pairs = 0usize;
            for (j, &cj) in current.iter().enumerate() {
                let t = dx[(i, j)];
                if j == i || !t.is_finite() {
                    continue;
                }
                pairs += 1;
                let t = t as f32;
                // Column cj: the distances of every anchor to the image of sample j.
                add_abs_differences(&mut cost, t, &dy[cj * a..(cj + 1) * a]);
            }
            let geo = 1.0 / (pairs.max(1) as f64 * scales.0);
            let mut best = (f64::INFINITY, current[i]);
            for (r, &c) in cost.iter().enumerate() {
                let total = f64::from(c) * geo + desc.map_or(0.0, |d| d[(i, r)] / scales.1);
                if total < best.0 {
                    best = (total, r);
                }
            }
            best.1
        })
        .collect()
}

/// The mean |d_X − d_Y| over the pairs of samples of a map given by the anchors of its images.
fn mean_misfit(dx: &Mat<f64>, dy: &Mat<f64>, anchors: &[usize]) -> f64 {
    let s = anchors.len();
    let (mut sum, mut count) = (0.0, 0usize);
    for i in 0..s {
        for j in (i + 1)..s {
            let e = (dx[(i, j)] - dy[(anchors[i], anchors[j])]).abs();
            if e.is_finite() {
                sum += e;
                count += 1;
            }
        }
    }
    if count > 0 {
        sum / count as f64
    } else {
        0.0
    }
}

/// The mean descriptor misfit ‖F(s_i) − G(π(s_i))‖ of a map given by the anchors of its images.
fn mean_descriptor_misfit(desc: &Mat<f64>, anchors: &[usize]) -> f64 {
    anchors.iter().enumerate().map(|(i, &a)| desc[(i, a)]).sum::<f64>() / anchors.len().max(1) as f64
}

/// The descriptor distances ‖F(s_i) − G(a)‖ (s × a) between X's samples and Y's anchors, from
/// descriptors F (n × q) on X and G (m × q) on Y.
pub fn descriptor_distances(x: &SampleDistances, y: &SampleDistances, f: MatRef<f64>, g: MatRef<f64>) -> Mat<f64> {
    use rayon::prelude::*;
    let q = f.ncols().min(g.ncols());
    let (xs, ys) = (&x.samples.vertices, &y.samples.vertices);
    if q == 0 {
        return Mat::zeros(xs.len(), ys.len());
    }
    // The samples' rows, contiguous (row-major), then the columns of the result in parallel.
    let rows = |m: MatRef<f64>, vs: &[usize]| -> Vec<f64> {
        vs.iter().flat_map(|&v| (0..q).map(move |c| m[(v, c)])).collect()
    };
    let (fr, gr) = (rows(f, xs), rows(g, ys));
    let cols: Vec<Vec<f64>> = (0..ys.len())
        .into_par_iter()
        .map(|a| {
            let ga = &gr[a * q..(a + 1) * q];
            fr.chunks_exact(q).map(|fi| fi.iter().zip(ga).map(|(u, v)| (u - v).powi(2)).sum::<f64>().sqrt()).collect()
        })
        .collect();
    Mat::from_fn(xs.len(), ys.len(), |i, a| cols[a][i])
}

/// The a × a anchor distances as f32, column-major, ∞ (other components) replaced by ten times
/// the largest finite distance: such a pair then costs more than any placement within a
/// component. Single precision is ample for choosing among anchors (7 digits of distances
/// between 10⁻³ and 10 on a unit-area shape); E itself is summed in f64.
fn finite_f32(dy: &Mat<f64>) -> Vec<f32> {
    let big = 10.0
        * (0..dy.ncols())
            .flat_map(|j| dy.col_as_slice(j).iter())
            .copied()
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max);
    (0..dy.ncols())
        .flat_map(|j| dy.col_as_slice(j).iter().map(move |&d| if d.is_finite() { d } else { big } as f32))
        .collect()
}

/// Neighbours of every sample for [`orientation`]: its `count` nearest other samples (by the
/// geodesic distances between samples).
pub fn sample_neighbours(x: &SampleDistances, count: usize) -> Vec<Vec<usize>> {
    let s = x.len();
    (0..s)
        .map(|i| {
            let mut others: Vec<usize> = (0..s).filter(|&j| j != i && x.distances[(i, j)].is_finite()).collect();
            others.sort_by(|&a, &b| x.distances[(i, a)].total_cmp(&x.distances[(i, b)]));
            others.truncate(count);
            others
        })
        .collect()
}

/// Orientation of a map on samples, in [−1, 1]: the mean over the samples of X of the sign of
/// det(Aᵢᵀ Bᵢ), where the rows of Aᵢ are the offsets from sample i to its neighbours
/// (`neighbours`) in a tangent frame of X at i (oriented by X's normal) and the rows of Bᵢ the
/// offsets between their images in a tangent frame of Y at i's image (oriented by Y's normal):
/// the sign of the determinant of the least-squares linear map between the two tangent planes.
/// +1 where the sample map preserves orientation, −1 where it mirrors. `px`, `nx` are X's
/// positions and unit normals (length n), `py`, `ny` Y's (length m), `samples` X's samples and
/// `images` their images (same length).
pub fn orientation(
    px: &[[f64; 3]],
    nx: &[[f64; 3]],
    py: &[[f64; 3]],
    ny: &[[f64; 3]],
    samples: &[usize],
    images: &[usize],
    neighbours: &[Vec<usize>],
) -> f64 {
    let frame = |n: [f64; 3]| -> ([f64; 3], [f64; 3]) {
        let a = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
        let t1 = normalize(cross(a, n));
        (t1, cross(n, t1))
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut sum = 0.0;
    for (i, nb) in neighbours.iter().enumerate() {
        let (xi, yi) = (samples[i], images[i]);
        let ((u1, u2), (v1, v2)) = (frame(nx[xi]), frame(ny[yi]));
        let mut m = [[0.0; 2]; 2];
        for &j in nb {
            let (a, b) = (sub(px[samples[j]], px[xi]), sub(py[images[j]], py[yi]));
            let (a, b) = ([dot(a, u1), dot(a, u2)], [dot(b, v1), dot(b, v2)]);
            for r in 0..2 {
                for c in 0..2 {
                    m[r][c] += a[r] * b[c];
                }
            }
        }
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        sum += det.signum() * f64::from(u8::from(det != 0.0));
    }
    sum / neighbours.len().max(1) as f64
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if l > 0.0 {
        [a[0] / l, a[1] / l, a[2] / l]
    } else {
        a
    }
}

/// What the correction did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Correction {
    /// The geodesic distortion E after each round that lowered J, starting with the candidate's.
    pub trace: Vec<f64>,
    /// Samples whose corrected image lies farther from the candidate's image than the covering
    /// radius of X's samples (the resolution of the search: closer moves are within the spacing
    /// of the samples and say nothing about the basin).
    pub moved: usize,
    /// The covering radius of X's samples (unit-area units).
    pub radius: f64,
}

/// Coordinate descent from `images` (vertex ids of Y of X's samples) on
/// J(π) = Σ_i [mean_{j≠i} |d_X(s_i, s_j) − d_Y(π(s_i), π(s_j))| / δ̄ + ‖F(s_i) − G(π(s_i))‖ / σ̄],
/// δ̄ and σ̄ the mean distance and descriptor misfits of the start: the geodesic distortion of the
/// module docs and, with `desc` ([`descriptor_distances`]), the data the candidates were fitted
/// to, each counted in units of its own typical misfit. Between non-isometric shapes (a body
/// with its arms raised stretches the shoulders) distances alone are fitted better by sliding
/// whole limbs along themselves than by the true map; the descriptors of a limb's parts (a hand
/// is not a forearm) forbid that slide, and say nothing against swapping a limb for its mirror
/// image, which distances do. Rounds while J decreases, at most `rounds`. Returns the corrected
/// images (vertex ids of Y: the anchors' vertices) and what the rounds did.
pub fn correct(
    x: &SampleDistances,
    y: &SampleDistances,
    images: &[usize],
    desc: Option<&Mat<f64>>,
    rounds: usize,
) -> Result<(Vec<usize>, Correction)> {
    if images.len() != x.len() || images.iter().any(|&v| v >= y.nearest.len()) {
        return Err(Error::invalid("images", format!("need {} vertex ids of Y < {}", x.len(), y.nearest.len())));
    }
    if desc.is_some_and(|d| d.nrows() != x.len() || d.ncols() != y.len()) {
        return Err(Error::invalid("descriptor distances", format!("need {} × {}", x.len(), y.len())));
    }
    let (dx, dy) = (&x.distances, &y.distances);
    let dy32 = finite_f32(dy);
    let start = anchors_of(y, images);
    let scales = (
        mean_misfit(dx, dy, &start).max(f64::MIN_POSITIVE),
        desc.map_or(1.0, |d| mean_descriptor_misfit(d, &start)).max(f64::MIN_POSITIVE),
    );
    let energy = |anchors: &[usize]| {
        mean_misfit(dx, dy, anchors) / scales.0 + desc.map_or(0.0, |d| mean_descriptor_misfit(d, anchors) / scales.1)
    };
    let mut best = (energy(&start), start.clone());
    let mut trace = vec![anchored_distortion(dx, dy, &start)];
    for _ in 0..rounds {
        crate::progress::check()?;
        let next = trilaterate(dx, &dy32, dy.nrows(), &best.1, desc, scales);
        if next == best.1 {
            break;
        }
        let j = energy(&next);
        if j.partial_cmp(&best.0) != Some(std::cmp::Ordering::Less) {
            break;
        }
        trace.push(anchored_distortion(dx, dy, &next));
        best = (j, next);
    }
    let corrected: Vec<usize> = best.1.iter().map(|&a| y.samples.vertices[a]).collect();
    let moved = images.iter().zip(&corrected).filter(|(&b, &a)| has_moved(x, y, b, a)).count();
    Ok((corrected, Correction { trace, moved, radius: x.radius }))
}

/// Sample maps of X's samples to Y's anchors found from scratch by the consistency of distances
/// alone (no functional map, no descriptor): the basin search's candidates come from spectral
/// fits, and when the data of a part mislead every fit the same way (the legs and hips of a
/// lower body taken for the arms and shoulders) no correction reaches the right basin.
///
/// Three reference samples r₁, r₂, r₃ of X far apart (r₁ an end of the longest distance
/// between samples, r₂ the other end, r₃ the farthest from both), and `checks` more by the same
/// farthest rule. Every triple of anchors (a₁, a₂, a₃) of Y whose distances agree with those of
/// the references within δ(d) = `tolerance` · d + 2 ρ_Y (ρ_Y the anchors' covering radius) is
/// scored by how well the check samples can be placed against it,
/// Σ_c min_a Σ_t |d_X(c, r_t) − d_Y(a, a_t)| (the references' own misfits added); the `keep`
/// best triples, no two with all three anchors within δ of each other, are placed: every sample
/// at the anchor that best fits its distances to the references and checks (the checks at their
/// best anchors), then corrected ([`correct`] with `desc`, at most `rounds` rounds). Returns the
/// corrected images (vertex ids of Y) with their geodesic distortion E, best first. Cost: a · a
/// for the triples' candidates, a · 3 more for each consistent triple and `checks` · a · 3 for
/// the best 64 · `keep` of them, then as [`correct`] for each kept one.
pub fn seeded_maps(
    x: &SampleDistances,
    y: &SampleDistances,
    desc: Option<&Mat<f64>>,
    checks: usize,
    keep: usize,
    tolerance: f64,
    rounds: usize,
) -> Result<Vec<(Vec<usize>, f64)>> {
    let (dx, dy) = (&x.distances, &y.distances);
    let (s, a) = (x.len(), y.len());
    if s < 3 || a < 3 || keep == 0 {
        return Ok(Vec::new());
    }
    let fin = |d: f64| if d.is_finite() { d } else { -1.0 };
    // The references and checks: farthest first, each next the farthest from those chosen.
    let ecc: Vec<f64> = (0..s).map(|i| (0..s).map(|j| fin(dx[(i, j)])).fold(0.0, f64::max)).collect();
    let first = (0..s).max_by(|&i, &j| ecc[i].total_cmp(&ecc[j])).unwrap_or(0);
    let mut refs = vec![first];
    while refs.len() < (3 + checks).min(s) {
        let next = (0..s)
            .filter(|i| !refs.contains(i))
            .max_by(|&i, &j| {
                let m = |k: usize| refs.iter().map(|&r| dx[(k, r)]).fold(f64::INFINITY, f64::min);
                fin(m(i)).total_cmp(&fin(m(j)))
            })
            .expect("samples left");
        refs.push(next);
    }
    let (r, c) = (&refs[..3], &refs[3..]);
    if r.iter().enumerate().any(|(i, &p)| r[i + 1..].iter().any(|&q| !dx[(p, q)].is_finite())) {
        return Ok(Vec::new());
    }
    let tol = |d: f64| tolerance * d + 2.0 * y.radius;
    let dy32 = finite_f32(dy);
    let col = |k: usize| &dy32[k * a..(k + 1) * a];
    // The misfit of a check sample k against a triple: min over anchors of Σ_t |d_X(k, r_t) − d_Y(a, a_t)|.
    let check_cost = |k: usize, t: [usize; 3], cost: &mut Vec<f32>| -> f64 {
        cost.iter_mut().for_each(|v| *v = 0.0);
        for (p, &an) in t.iter().enumerate() {
            let d = dx[(k, r[p])];
            if d.is_finite() {
                let d = d as f32;
                cost.iter_mut().zip(col(an)).for_each(|(v, e)| *v += (d - e).abs());
            }
        }
        f64::from(cost.iter().copied().fold(f32::INFINITY, f32::min))
    };
    // Every consistent triple scored by its own misfits and the first check, in parallel over a₁.
    let (d12, d13, d23) = (dx[(r[0], r[1])], dx[(r[0], r[2])], dx[(r[1], r[2])]);
    let mut triples: Vec<(f64, [usize; 3])> = (0..a)
        .into_par_iter()
        .flat_map_iter(|a1| {
            let mut out = Vec::new();
            let mut cost = vec![0.0f32; a];
            // The anchors at the right distance from a₁ for r₃ (in increasing order).
            let thirds: Vec<usize> = (0..a).filter(|&a3| a3 != a1 && (dy[(a1, a3)] - d13).abs() <= tol(d13)).collect();
            for a2 in 0..a {
                let e12 = (dy[(a1, a2)] - d12).abs();
                if a2 == a1 || e12 > tol(d12) {
                    continue;
                }
                for &a3 in &thirds {
                    let (e13, e23) = ((dy[(a1, a3)] - d13).abs(), (dy[(a2, a3)] - d23).abs());
                    if a3 == a2 || e23 > tol(d23) {
                        continue;
                    }
                    let first = c.first().map_or(0.0, |&k| check_cost(k, [a1, a2, a3], &mut cost));
                    out.push((e12 + e13 + e23 + first, [a1, a2, a3]));
                }
            }
            out.into_iter()
        })
        .collect();
    triples.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
    // The best of them scored by every check.
    triples.truncate(64 * keep);
    let mut triples: Vec<(f64, [usize; 3])> = triples
        .into_par_iter()
        .map(|(v, t)| {
            let mut cost = vec![0.0f32; a];
            (v + c.iter().skip(1).map(|&k| check_cost(k, t, &mut cost)).sum::<f64>(), t)
        })
        .collect();
    triples.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
    let mut kept: Vec<[usize; 3]> = Vec::new();
    let near = |p: &[usize; 3], q: &[usize; 3]| (0..3).all(|t| dy[(p[t], q[t])] <= tol(0.0));
    for (_, t) in &triples {
        if kept.len() == keep {
            break;
        }
        if !kept.iter().any(|k| near(k, t)) {
            kept.push(*t);
        }
    }
    // Place every sample against the references and the checks at their best anchors.
    let place = |fixed: &[(usize, usize)]| -> Vec<usize> {
        (0..s)
            .map(|i| {
                let mut cost = vec![0.0f32; a];
                for &(k, an) in fixed {
                    let t = dx[(i, k)];
                    if t.is_finite() {
                        let t = t as f32;
                        cost.iter_mut().zip(col(an)).for_each(|(v, d)| *v += (t - d).abs());
                    }
                }
                (0..a).min_by(|&p, &q| cost[p].total_cmp(&cost[q])).unwrap_or(0)
            })
            .collect()
    };
    let mut maps: Vec<(Vec<usize>, f64)> = kept
        .par_iter()
        .map(|t| {
            let mut fixed: Vec<(usize, usize)> = (0..3).map(|k| (r[k], t[k])).collect();
            let checks_placed = place(&fixed);
            c.iter().for_each(|&k| fixed.push((k, checks_placed[k])));
            let anchors = place(&fixed);
            let images: Vec<usize> = anchors.iter().map(|&an| y.samples.vertices[an]).collect();
            let (fixed, _) = correct(x, y, &images, desc, rounds)?;
            let e = distortion(x, y, &fixed);
            Ok((fixed, e))
        })
        .collect::<Result<_>>()?;
    maps.sort_by(|p, q| p.1.total_cmp(&q.1));
    Ok(maps)
}

/// Whether a sample's image moved from the vertex `before` to `after` of Y by more than the
/// covering radius of X's samples `x` (as counted in [`Correction::moved`]; distances between
/// Y's anchors `y`).
pub fn has_moved(x: &SampleDistances, y: &SampleDistances, before: usize, after: usize) -> bool {
    y.distances[(y.nearest[before] as usize, y.nearest[after] as usize)] > x.radius
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::bumpy_sphere;

    /// On a shape matched to itself, the true map scores 0; a map with some samples sent to the
    /// antipode of their place scores higher, and the correction brings every one back.
    #[test]
    fn the_correction_repairs_misplaced_samples() {
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let mass = x.vertex_areas();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        let side = SampleDistances::new(&x, &mass, &g, 60).unwrap();
        assert_eq!(side.len(), 60);
        assert!(side.radius > 0.0 && side.nearest.len() == n);
        let truth = side.samples.vertices.clone();
        assert!(distortion(&side, &side, &truth) < 1e-12);
        let antipode = |v: usize| {
            let p = x.vertices()[v];
            let d = |u: usize| (0..3).map(|c| (x.vertices()[u][c] + p[c]).powi(2)).sum::<f64>();
            (0..n).min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap()
        };
        let mut wrong = truth.clone();
        for w in wrong.iter_mut().take(10) {
            *w = antipode(*w);
        }
        let e = distortion(&side, &side, &wrong);
        assert!(e > 0.05, "distortion of the wrong map {e}");
        let (fixed, report) = correct(&side, &side, &wrong, None, 5).unwrap();
        assert_eq!(fixed, truth, "trace {:?}", report.trace);
        assert_eq!(report.moved, 10);
        assert!(report.trace.len() >= 2 && report.trace.last().unwrap() < &1e-12);
        assert!((0..10).all(|i| has_moved(&side, &side, wrong[i], fixed[i])));
        assert!(!has_moved(&side, &side, wrong[20], fixed[20]));
        assert!(SampleDistances::new(&x, &mass, &g, 2).is_err());
        assert!(correct(&side, &side, &wrong[1..], None, 1).is_err());
    }

    /// The per-sample distortions are zero for the true map and grow at the misplaced samples
    /// and their partners; their mean over the samples is E's numerator over its denominator up
    /// to the pair weights; a better map dominates a worse one on every sample it changes.
    #[test]
    fn per_sample_distortions_and_dominance() {
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let mass = x.vertex_areas();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        let side = SampleDistances::new(&x, &mass, &g, 40).unwrap();
        let truth = side.samples.vertices.clone();
        let zero = sample_distortions(&side, &side, &truth);
        assert_eq!(zero.len(), 40);
        assert!(zero.iter().all(|&v| v.abs() < 1e-12), "{zero:?}");
        // Three samples sent to the farthest vertex from their place.
        let far = |v: usize| {
            let d = g.distances_from_vertex(v).unwrap();
            (0..n).max_by(|&a, &b| d[a].total_cmp(&d[b])).unwrap()
        };
        let mut wrong = truth.clone();
        for w in wrong.iter_mut().take(3) {
            *w = far(*w);
        }
        let d = sample_distortions(&side, &side, &wrong);
        // A misplaced sample is off against most others; a placed one against three at most.
        assert!(d[..3].iter().all(|&v| v > 0.1), "{d:?}");
        assert!(d[..3].iter().cloned().fold(f64::INFINITY, f64::min) > d[3..].iter().cloned().fold(0.0, f64::max));
        // Relation to E: Σ_i d_i (s − 1) = 2 Σ_{i<j} |…| (every pair counted from both ends).
        let e = distortion(&side, &side, &wrong);
        let dx = &side.distances;
        let den: f64 = (0..40).flat_map(|i| ((i + 1)..40).map(move |j| (i, j))).map(|(i, j)| dx[(i, j)]).sum();
        let num = d.iter().sum::<f64>() * 39.0 / 2.0;
        assert!((num / den - e).abs() < 1e-9 * e.max(1.0), "{} against {e}", num / den);
        // Every sample has a misplaced partner, so the truth fits (almost) every one better.
        let share = dominance(&d, &zero);
        assert!((0.9..=1.0).contains(&share), "{share}");
        assert_eq!(dominance(&zero, &d), 0.0);
        assert_eq!(dominance(&zero, &zero), 0.0);
        assert_eq!(dominance(&[], &[]), 0.0);
    }

    /// Maps found from distances alone: on a shape against itself the best fits the distances
    /// (the identity scores 0), best first; and from them the scale of a shape against itself
    /// is 1 (area ratio), from a start 40 % off.
    #[test]
    fn maps_from_distances_alone_fit_the_distances() {
        let x = bumpy_sphere(3);
        let mass = x.vertex_areas();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        let side = SampleDistances::new(&x, &mass, &g, 60).unwrap();
        let maps = seeded_maps(&side, &side, None, 4, 3, 0.1, 5).unwrap();
        assert!(!maps.is_empty() && maps.len() <= 3);
        assert!(maps.windows(2).all(|w| w[0].1 <= w[1].1));
        assert!(maps[0].1 < 0.05, "distortion of the best map {}", maps[0].1);
        assert!(maps.iter().all(|(m, e)| m.len() == 60 && (distortion(&side, &side, m) - e).abs() < 1e-12));
        let r = crate::matching::partial::estimate_ratio(&side, &side, 0.6, 5).unwrap();
        assert!((r - 1.0).abs() < 0.05, "area ratio {r}");
        assert!(seeded_maps(&side, &side, None, 4, 0, 0.1, 5).unwrap().is_empty());
    }

    /// cost += |t − d| entry by entry, the same bits at every vector width.
    #[test]
    fn abs_differences_are_the_same_at_every_vector_width() {
        let d: Vec<f32> = (0..53).map(|i| (i as f32 * 0.37).sin() * 3.0).collect();
        let want: Vec<f32> = d.iter().map(|&x| 1.5 + (0.25f32 - x).abs()).collect();
        for widest in 0..=2 {
            let mut cost = vec![1.5f32; d.len()];
            crate::linalg::with_widest(widest, || add_abs_differences(&mut cost, 0.25, &d));
            assert_eq!(cost, want, "widest {widest}");
        }
    }
}
