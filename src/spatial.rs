//! Spatial queries on points and vertices, shared by the layers above (Laplacians, point-cloud
//! surfaces, graph geodesics, benchmark templates, rendering): exact K nearest neighbours and
//! farthest-point sampling, of candidate vertices ([`farthest_points`]) or of all points with
//! the mass of their Voronoi cells ([`farthest_point_samples`], the samples of ZoomOut in
//! [`crate::refine`]).

use std::num::NonZero;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::{PointSet, TriMesh};

/// The K nearest neighbours of every 3-D point (excluding itself) by a k-d tree (kiddo): for
/// point i, `K` pairs (squared distance, index), ascending, ties by index. The caller checks
/// 1 ≤ K < n.
pub(crate) fn knn3(points: &[[f64; 3]], k: usize) -> Vec<Vec<(f64, usize)>> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(points);
    let want = NonZero::new(k + 1).expect("k + 1 > 0");
    points
        .par_iter()
        .enumerate()
        .map(|(i, q)| {
            let mut nb: Vec<(f64, usize)> = tree
                .nearest_n::<kiddo::SquaredEuclidean>(q, want)
                .into_iter()
                .map(|nn| (nn.distance, nn.item as usize))
                .filter(|&(_, j)| j != i)
                .collect();
            nb.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            nb.truncate(k);
            nb
        })
        .collect()
}

/// For every query point, the index of the nearest of `points` (Euclidean, by a k-d tree:
/// kiddo's exact nearest neighbour). `points` must not be empty (the caller checks).
pub fn nearest3(points: &[[f64; 3]], queries: &[[f64; 3]]) -> Vec<usize> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(points);
    let one = NonZero::new(1).expect("1 > 0");
    queries.par_iter().map(|q| tree.nearest_n::<kiddo::SquaredEuclidean>(q, one)[0].item as usize).collect()
}

/// About `count` well-spread points of a surface sampled by `points` (n × 3), in O(n) per
/// pass: one point per occupied cube of a voxel grid (the one nearest the cube's centre, ties to
/// the smallest index), the cube's side adjusted (at most 8 passes) until the occupied cubes
/// number within ×1.25 of `count`. Returns point indices, ascending; every point when `count`
/// ≥ n. Where farthest-point sampling (O(n · count)) is too slow: the fine cells of restricted
/// searches on 10⁵–10⁶ points. `points` must be finite (the shapes' positions are).
pub fn grid_samples(points: &[[f64; 3]], count: usize) -> Vec<usize> {
    let n = points.len();
    if count >= n || n == 0 {
        return (0..n).collect();
    }
    let count = count.max(1);
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let e: Vec<f64> = (0..3).map(|c| (hi[c] - lo[c]).max(f64::MIN_POSITIVE)).collect();
    // A surface's area is of the order of the box's half surface: a first side length.
    let mut side = ((e[0] * e[1] + e[1] * e[2] + e[2] * e[0]) / count as f64).sqrt().max(f64::MIN_POSITIVE);
    let key = |p: &[f64; 3], side: f64| -> [i64; 3] { std::array::from_fn(|c| ((p[c] - lo[c]) / side).floor() as i64) };
    let mut best: std::collections::HashMap<[i64; 3], (f64, usize)> = std::collections::HashMap::new();
    for _ in 0..8 {
        best.clear();
        for (i, p) in points.iter().enumerate() {
            let k = key(p, side);
            let d: f64 = (0..3).map(|c| (p[c] - (lo[c] + (k[c] as f64 + 0.5) * side)).powi(2)).sum();
            let e = best.entry(k).or_insert((f64::INFINITY, usize::MAX));
            if d < e.0 || (d == e.0 && i < e.1) {
                *e = (d, i);
            }
        }
        let ratio = best.len() as f64 / count as f64;
        if (0.8..=1.25).contains(&ratio) {
            break;
        }
        side *= ratio.sqrt();
    }
    let mut chosen: Vec<usize> = best.values().map(|&(_, i)| i).collect();
    chosen.sort_unstable();
    chosen
}

/// For every query point, the indices of the `k` nearest of `points` (Euclidean, by a k-d tree),
/// nearest first. `points` must not be empty and 1 ≤ k ≤ its length (the caller checks).
pub fn nearest_n3(points: &[[f64; 3]], queries: &[[f64; 3]], k: usize) -> Vec<Vec<usize>> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(points);
    let want = NonZero::new(k).expect("k ≥ 1");
    queries
        .par_iter()
        .map(|q| tree.nearest_n::<kiddo::SquaredEuclidean>(q, want).into_iter().map(|nn| nn.item as usize).collect())
        .collect()
}

/// The K nearest neighbours of every point (excluding itself): for point i, `K` pairs
/// (squared distance, index), ascending. Exact.
///
/// d = 3 uses a k-d tree (kiddo); other dimensions use a parallel brute-force scan (kiddo's
/// dimension is a compile-time constant, and k-d trees lose their edge in high dimension).
pub fn knn(points: &PointSet, k: usize) -> Result<Vec<Vec<(f64, usize)>>> {
    let n = points.len();
    if k == 0 || k >= n {
        return Err(Error::invalid("knn", format!("K = {k} neighbours needs 1 ≤ K < n = {n}")));
    }
    let result: Vec<Vec<(f64, usize)>> = if points.dim() == 3 {
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let p = points.point(i);
                [p[0], p[1], p[2]]
            })
            .collect();
        knn3(&pts, k)
    } else {
        (0..n)
            .into_par_iter()
            .map(|i| {
                let p = points.point(i);
                let mut all: Vec<(f64, usize)> = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| (p.iter().zip(points.point(j)).map(|(a, b)| (a - b) * (a - b)).sum(), j))
                    .collect();
                let cmp = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                all.select_nth_unstable_by(k - 1, cmp);
                all.truncate(k);
                all.sort_by(cmp);
                all
            })
            .collect()
    };
    // With many coincident points a k-d tree query may return fewer than K others.
    if let Some(i) = result.iter().position(|nb| nb.len() < k) {
        return Err(Error::invalid("knn", format!("point {i} has fewer than K = {k} distinct neighbours")));
    }
    Ok(result)
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

/// Vertex positions of two shapes X (n × 3) and Y (m × 3).
pub type PositionPair<'a> = (&'a [[f64; 3]], &'a [[f64; 3]]);

/// A weighted subset of the vertices of a shape.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    /// Vertex ids (distinct).
    pub vertices: Vec<usize>,
    /// Weight of every sample (> 0): the vertex weight it stands for (units²).
    pub weights: Vec<f64>,
}

impl Samples {
    /// Every vertex, weighted by its mass (length n).
    pub fn all(mass: &[f64]) -> Samples {
        Samples { vertices: (0..mass.len()).collect(), weights: mass.to_vec() }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// `count` independent draws of a vertex with probability ∝ `mass` (length n), duplicates
    /// merged: each distinct vertex drawn c times gets the weight c · Σ mass / `count`.
    /// Deterministic in `seed` (SplitMix64).
    ///
    /// Unbiased: for any f, E[Σ_s w_s f(v_s)] = Σ_i mass_i f(i), so a sum over the samples is
    /// an unbiased estimate of the mass-weighted sum over every vertex (a Monte Carlo quadrature;
    /// [`farthest_point_samples`] is the deterministic one, with smaller error for smooth f).
    ///
    /// Errors: no vertices, `count` = 0, a negative or non-finite mass, or a zero total.
    pub fn random(mass: &[f64], count: usize, seed: u64) -> Result<Samples> {
        if mass.is_empty() || count == 0 {
            return Err(Error::invalid("samples", format!("{count} draws from {} vertices", mass.len())));
        }
        if mass.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
            return Err(Error::invalid("samples", "vertex weights must be finite and ≥ 0"));
        }
        let mut cumulative = Vec::with_capacity(mass.len());
        let mut total = 0.0;
        for m in mass {
            total += m;
            cumulative.push(total);
        }
        if total <= 0.0 || !total.is_finite() {
            return Err(Error::invalid("samples", "vertex weights sum to 0 or overflow"));
        }
        let mut rng = crate::rng::Normal::new(seed);
        let mut hits = vec![0u64; mass.len()];
        for _ in 0..count {
            let u = rng.uniform() * total;
            // The first vertex whose cumulative weight exceeds u (never one of weight 0).
            let i = cumulative.partition_point(|&c| c <= u).min(mass.len() - 1);
            hits[i] += 1;
        }
        let per_draw = total / count as f64;
        let vertices: Vec<usize> = (0..mass.len()).filter(|&i| hits[i] > 0).collect();
        let weights = vertices.iter().map(|&i| hits[i] as f64 * per_draw).collect();
        Ok(Samples { vertices, weights })
    }
}

/// `count` farthest-point samples of the points (n × 3, Euclidean, deterministic: the first
/// sample is the point farthest from the centroid), each weighted by the total mass of the
/// points nearest to it (its Voronoi cell; `mass` has length n, e.g. the vertex areas A_X).
/// All points when count ≥ n.
///
/// Errors: no points, `mass.len()` ≠ n, `count` = 0.
pub fn farthest_point_samples(points: &[[f64; 3]], mass: &[f64], count: usize) -> Result<Samples> {
    let n = points.len();
    if mass.len() != n || n == 0 {
        return Err(Error::invalid("samples", format!("{n} points and {} weights", mass.len())));
    }
    if count == 0 {
        return Err(Error::invalid("samples", "need at least one sample"));
    }
    if count >= n {
        return Ok(Samples::all(mass));
    }
    let d2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
    let mut centroid = [0.0; 3];
    for p in points {
        for c in 0..3 {
            centroid[c] += p[c] / n as f64;
        }
    }
    let mut next =
        (0..n).max_by(|&a, &b| d2(&points[a], &centroid).total_cmp(&d2(&points[b], &centroid))).expect("n > 0");
    let mut best = vec![f64::INFINITY; n];
    let mut owner = vec![0usize; n];
    let mut chosen = Vec::with_capacity(count);
    while chosen.len() < count {
        let s = chosen.len();
        chosen.push(next);
        let far = farthest_update(points, points[next], s, &mut best, &mut owner);
        if far.1 <= 0.0 {
            break;
        }
        next = far.0;
    }
    let mut weights = vec![0.0; chosen.len()];
    for i in 0..n {
        weights[owner[i]] += mass[i];
    }
    Ok(Samples { vertices: chosen, weights })
}

/// One step of [`farthest_point_samples`]: every point's squared distance to its nearest sample
/// so far (`best`) and that sample's number (`owner`) updated with sample number `s` at `c`;
/// returns the farthest point and its squared distance (the first index on ties; (0, −1) when
/// no distance is a number).
#[inline(always)]
fn farthest_update_generic(
    points: &[[f64; 3]],
    c: [f64; 3],
    s: usize,
    best: &mut [f64],
    owner: &mut [usize],
) -> (usize, f64) {
    for ((p, b), o) in points.iter().zip(best.iter_mut()).zip(owner.iter_mut()) {
        let d = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
        if d < *b {
            *b = d;
            *o = s;
        }
    }
    // The largest distance in LANES independent running maxima (a compare-and-select: `maxpd`),
    // then its first occurrence.
    let mut lanes = [-1.0f64; LANES];
    let chunks = best.chunks_exact(LANES);
    let tail = chunks.remainder().iter().fold(-1.0f64, |m, &v| if v > m { v } else { m });
    for chunk in chunks {
        for l in 0..LANES {
            lanes[l] = if chunk[l] > lanes[l] { chunk[l] } else { lanes[l] };
        }
    }
    let far = lanes.iter().fold(tail, |m, &v| if v > m { v } else { m });
    match best.iter().position(|&v| v == far) {
        Some(i) => (i, far),
        None => (0, -1.0),
    }
}

crate::linalg::at_vector_width! {
    /// [`farthest_update_generic`] at the CPU's vector width.
    fn farthest_update(points: &[[f64; 3]], c: [f64; 3], s: usize, best: &mut [f64], owner: &mut [usize]) -> (usize, f64) = farthest_update_generic
}

/// The largest embedding value the nearest-neighbour searches accept: their squared norms and
/// f64 sums (d · 10⁶⁰) stay far from f64's range (the single-precision screen scales its copies
/// into [−1, 1]); [`crate::pointwise::nearest_neighbors_near_rows`] holds its input to the same
/// bound.
pub(crate) const MAX_EMBEDDING: f64 = 1e30;

/// Query rows per task of the nearest-neighbour search.
const QUERY_BLOCK: usize = 256;

/// Reference rows per product block of the nearest-neighbour search (256 × 2048 × 4 bytes = 2 MB).
const REFERENCE_CHUNK: usize = 2048;

/// Safety factor on the rounding-error bound of the single-precision screen of [`nearest_rows`].
const SCREEN_SAFETY: f64 = 4.0;

/// Relative slack of the screen's bounds rounded to f32 (round to nearest may lower them by
/// 2⁻²⁴).
const SLACK: f64 = 1.0 + 1.0 / (1 << 20) as f64;

/// Independent lanes of the screen's vectorized test (one AVX-512 register of f64).
const LANES: usize = 8;

/// One chunk of the screen of [`best_rows`], in single precision and in the screen's scaled
/// units: the products of a block of queries (rows of `dots`) with the reference rows c0 … c0 +
/// w − 1 (its first w columns), and per row its squared norm (0 for the inner-product search),
/// its norm, and the part of the error bound that does not scale with ‖q‖.
#[derive(Clone, Copy)]
struct Chunk<'a> {
    dots: &'a Mat<f32>,
    c0: usize,
    w: usize,
    ref_norm: &'a [f32],
    ref_len: &'a [f32],
    ref_bound: &'a [f32],
}

/// Queries screened together, their bounds in registers (four AVX-512 vectors of f32, eight of
/// AVX2: enough independent `minps` chains to hide their latency).
const SCREEN_ROWS: usize = 64;

crate::linalg::at_vector_width! {
    /// The screen of one chunk: lowers every query's best upper bound `best_hi` over the chunk,
    /// then adds to `cands` the rows whose lower bound does not exceed it (`scale`: the bound's
    /// factor of ‖r_j‖ per query, see [`best_rows`]), at the CPU's vector width
    /// ([`crate::linalg::at_vector_width`]).
    fn screen(chunk: Chunk, scale: &[f32], best_hi: &mut [f32], cands: &mut [Vec<(f32, usize)>]) = screen_generic
}

#[inline(always)]
fn screen_generic(chunk: Chunk, scale: &[f32], best_hi: &mut [f32], cands: &mut [Vec<(f32, usize)>]) {
    let len = best_hi.len();
    let full = len - len % SCREEN_ROWS;
    for i0 in (0..full).step_by(SCREEN_ROWS) {
        let sc: &[f32; SCREEN_ROWS] = scale[i0..i0 + SCREEN_ROWS].try_into().unwrap();
        let hi: &mut [f32; SCREEN_ROWS] = (&mut best_hi[i0..i0 + SCREEN_ROWS]).try_into().unwrap();
        screen_rows(chunk, i0, sc, hi, &mut cands[i0..i0 + SCREEN_ROWS]);
    }
    // The last rows, one at a time (the same bounds, in the same order).
    for i in full..len {
        let (sc, hi) = (&[scale[i]], (&mut best_hi[i..=i]).try_into().unwrap());
        screen_rows::<1>(chunk, i, sc, hi, &mut cands[i..=i]);
    }
}

/// [`screen_generic`] on the R queries i0 … i0 + R − 1, their bounds held in registers while
/// every column of the chunk passes (two passes: the smallest upper bound, then the
/// candidates; the R × w products stay in cache between them).
#[inline(always)]
fn screen_rows<const R: usize>(
    chunk: Chunk,
    i0: usize,
    sc: &[f32; R],
    best_hi: &mut [f32; R],
    cands: &mut [Vec<(f32, usize)>],
) {
    let Chunk { dots, c0, w, ref_norm, ref_len, ref_bound } = chunk;
    let col = |j: usize| -> &[f32; R] { dots.col_as_slice(j)[i0..i0 + R].try_into().unwrap() };
    // Pass 1 (branch-free, vectorized): the smallest upper bound of every query over the chunk.
    let mut hi = *best_hi;
    for j in 0..w {
        let (dot, rn, rl, rb) = (col(j), ref_norm[j], ref_len[j], ref_bound[j]);
        for l in 0..R {
            // A compare-and-select, not f32::min: it compiles to `minps` (the values are
            // finite: the caller scales them into [−1, 1]), f32::min's NaN rule to scalar code.
            let v = (rn - 2.0 * dot[l]) + sc[l] * rl + rb;
            hi[l] = if v < hi[l] { v } else { hi[l] };
        }
    }
    *best_hi = hi;
    // Pass 2: the candidates, lower bound ≤ best upper bound; the queries of a column are
    // visited one at a time only when one of them keeps it (a vectorized test first).
    for j in 0..w {
        let (dot, rn, rl, rb) = (col(j), ref_norm[j], ref_len[j], ref_bound[j]);
        let lo: [f32; R] = std::array::from_fn(|l| (rn - 2.0 * dot[l]) - sc[l] * rl - rb);
        // (An OR of comparisons: a reduction the compiler vectorizes, unlike a max of floats.)
        if !(0..R).fold(false, |any, l| any | (lo[l] <= hi[l])) {
            continue;
        }
        for (l, list) in cands.iter_mut().enumerate() {
            if lo[l] <= hi[l] {
                list.push((lo[l], c0 + j));
                if list.len() >= 64 {
                    let h = hi[l];
                    list.retain(|c| c.0 <= h);
                }
            }
        }
    }
}

/// The units and rounding-error bounds of a single-precision screen of rows of dimension d
/// ([`best_rows`] documents the bound; [`crate::pointwise::nearest_neighbors_near_rows`] screens
/// with the same): entries are multiplied by σ, the power of two that brings the largest entry
/// (in magnitude, over the queries and the reference rows) into [−1, 1].
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScreenScale {
    /// σ (exact power of two).
    pub(crate) sigma: f64,
    d: usize,
}

impl ScreenScale {
    /// The scale for entries of magnitude at most `largest` (finite, ≥ 0) in d dimensions.
    pub(crate) fn new(largest: f64, d: usize) -> Self {
        // (The exponent is clamped so that σ stays finite when every entry is a subnormal f64.)
        let sigma = if largest > 0.0 { 2f64.powi(-(largest.log2().ceil() as i32).clamp(-1000, 1000)) } else { 1.0 };
        ScreenScale { sigma, d }
    }

    /// u₃₂ = 2⁻²⁴.
    const U: f64 = f32::EPSILON as f64 / 2.0;

    /// The spacing of f32's subnormal numbers, 2⁻¹⁴⁹.
    fn tiny() -> f64 {
        2f64.powi(-149)
    }

    /// A reference row's screen terms from its squared norm `sq` (f64, unscaled): (σ ‖r‖, the
    /// norm term σ² ‖r‖² — 0 for an inner-product search, `euclidean` false —, the bound's part
    /// that does not scale with ‖q‖), in f32.
    pub(crate) fn reference(&self, sq: f64, euclidean: bool) -> (f32, f32, f32) {
        let sigma = self.sigma;
        let norm = if euclidean { sq } else { 0.0 };
        let len = (sigma * sq.sqrt()) as f32;
        let bound = (SLACK * (32.0 * Self::U * sigma * sigma * norm + 8.0 * self.d as f64 * Self::tiny())) as f32;
        (len, (sigma * sigma * norm) as f32, bound)
    }

    /// The additive term of a screen in coordinates centred on c (rows r − c, queries q − c,
    /// the distance ‖q − r‖² formed as κ + ‖r − c‖² − 2 (q − c)·(r − c), κ = ‖q − c‖²): 32 u₃₂ κ
    /// for the rounding of κ and of the sums it joins (the rows' ‖r‖² term of
    /// [`ScreenScale::reference`], for κ), and twice the rounding bound (d + 2) u₆₄ (R² + 2 ‖q‖ R)
    /// of the f64 check's ‖r‖² − 2 q·r, doubled, so that the check's f64 argmin is kept even where
    /// the centred bound is far below the f64 rounding of the uncentred values. From κ
    /// (`centred_sq`), ‖q‖² (`query_sq`) and R, the largest ‖r‖ searched, all f64 and unscaled;
    /// in the screen's units.
    pub(crate) fn centred(&self, centred_sq: f64, query_sq: f64, reach: f64) -> f32 {
        let (s, u64) = (self.sigma * self.sigma, f64::EPSILON / 2.0);
        let check = 4.0 * (self.d as f64 + 2.0) * u64 * (reach * reach + 2.0 * query_sq.sqrt() * reach);
        (SLACK * s * (32.0 * Self::U * centred_sq + check)) as f32
    }

    /// A query row's factor of σ ‖r_j‖ in the bound, from its squared norm `sq` (f64,
    /// unscaled): 2 ε ‖q‖ for the products and 16 u₃₂ ‖q‖ for the f32 evaluation of the bounds,
    /// doubled, and 4 √d 2⁻¹⁴⁹ for entries below f32's normal range (scaled units).
    pub(crate) fn query(&self, sq: f64) -> f32 {
        let (u, d) = (Self::U, self.d as f64);
        let eps = SCREEN_SAFETY * (d + 3.0) * u;
        let qn = self.sigma * sq.sqrt();
        (SLACK * (2.0 * (2.0 * eps * qn + 16.0 * u * qn) + 4.0 * d.sqrt() * Self::tiny())) as f32
    }
}

/// argmin_j (‖r_j‖² − 2 q·r_j) (`euclidean`) or argmax_j q·r_j for every query row.
///
/// Two passes, exact in double precision. *Screen:* the products q·r_j in single precision
/// (one f32 GEMM per block: half the memory traffic and twice the SIMD width of f64), each
/// with a rigorous bound on its error, |fl₃₂(q·r_j) − q·r_j| ≤ ε ‖q‖ ‖r_j‖ with
/// ε = 4 (d + 3) u₃₂ (the rounding of q and r_j to f32, and γ_d of a d-term dot product, with a
/// safety factor 4 for the kernel's summation order; u₃₂ = 2⁻²⁴). A reference row is kept as a
/// candidate unless its distance, lowered by its bound, exceeds the best distance raised by
/// its bound; the true optimum is always kept. The screen runs entirely in f32 (sixteen lanes
/// per AVX-512 vector) on σ q and σ r_j, σ the power of two that brings the largest entry into
/// [−1, 1] (exact, so the argmin is unchanged; without it products of entries below 10⁻¹⁹
/// fell below f32's range and the bound failed). Its bound on |e − (‖r‖² − 2 q·r)| for the f32
/// value e = fl₃₂(‖r‖²) − 2 fl₃₂(q·r) is 2 (2 ε + 16 u₃₂) ‖q‖ ‖r_j‖ + 32 u₃₂ ‖r_j‖² +
/// 4 √d 2⁻¹⁴⁹ ‖r_j‖ + 8 d 2⁻¹⁴⁹ (scaled units): the products' bound, the rounding of ‖r‖² and of
/// the f32 sums that form the bounds (each ≤ u₃₂ times quantities no larger than
/// ‖r‖² + 2 ‖q‖ ‖r‖), doubled, and the absolute error of entries in f32's subnormal range.
/// *Check:* the candidates' distances in f64
/// (‖r_j‖² − 2 Σ q_c r_jc, summed in order), the smallest wins, ties to the smallest index. The
/// result is the exact f64 argmin up to the rounding of that last f64 sum (a near-tie below
/// 1e-15 relative may resolve differently from a blocked f64 GEMM).
fn best_rows(reference: MatRef<f64>, query: MatRef<f64>, euclidean: bool) -> Result<Vec<usize>> {
    crate::progress::check()?;
    let (m, d) = (reference.nrows(), reference.ncols());
    if query.ncols() != d {
        return Err(Error::invalid(
            "embedding",
            format!("query has dimension {} but reference has {d}", query.ncols()),
        ));
    }
    if m == 0 {
        return Err(Error::invalid("embedding", "the reference set is empty"));
    }
    use crate::linalg::{max_abs_finite, round_to_f32_scaled, row_squared_norms};
    let (Some(max_ref), Some(max_query)) = (max_abs_finite(reference), max_abs_finite(query)) else {
        return Err(Error::invalid("embedding", "it contains a non-finite value"));
    };
    // Values beyond f32's range cannot be screened in single precision.
    if max_ref.max(max_query) > MAX_EMBEDDING {
        return Err(Error::invalid("embedding", "a value exceeds 1e30 in magnitude"));
    }
    // The screen works in units scaled by a power of two σ (exact) that brings every entry into
    // [−1, 1]: no f32 overflow, and no product below f32's range unless the entries' magnitudes
    // span more than 10³⁸ (covered by the bound's absolute term).
    let screen_scale = ScreenScale::new(max_ref.max(max_query), d);
    let sigma = screen_scale.sigma;
    let ref_sq = row_squared_norms(reference);
    let terms: Vec<(f32, f32, f32)> = ref_sq.iter().map(|&v| screen_scale.reference(v, euclidean)).collect();
    let ref_len: Vec<f32> = terms.iter().map(|t| t.0).collect();
    let ref_norm: Vec<f32> = terms.iter().map(|t| t.1).collect();
    let ref_bound: Vec<f32> = terms.iter().map(|t| t.2).collect();
    drop(terms);
    let ref_norm64: Vec<f64> = if euclidean { ref_sq } else { vec![0.0; m] };
    let reference32 = round_to_f32_scaled(reference, sigma);
    let n = query.nrows();
    let starts: Vec<usize> = (0..n).step_by(QUERY_BLOCK).collect();
    let blocks: Vec<Vec<usize>> = starts
        .par_iter()
        .map(|&r0| {
            if crate::progress::cancelled() {
                return Vec::new(); // discarded: the check below fails
            }
            let len = QUERY_BLOCK.min(n - r0);
            let q = query.subrows(r0, len);
            let q32 = round_to_f32_scaled(q, sigma);
            // The bound's factor of ‖r_j‖ (see the function's documentation).
            let scale: Vec<f32> = row_squared_norms(q).iter().map(|&v| screen_scale.query(v)).collect();
            // The reference rows in chunks, so that the block of products stays in cache.
            let mut best_hi = vec![f32::INFINITY; len];
            let mut cands: Vec<Vec<(f32, usize)>> = vec![Vec::new(); len];
            let mut dots = Mat::<f32>::zeros(len, REFERENCE_CHUNK.min(m));
            for c0 in (0..m).step_by(REFERENCE_CHUNK) {
                let w = REFERENCE_CHUNK.min(m - c0);
                matmul(
                    dots.as_mut().subcols_mut(0, w),
                    Accum::Replace,
                    q32.as_ref(),
                    reference32.subrows(c0, w).transpose(),
                    1.0f32,
                    Par::Seq,
                );
                let r = c0..c0 + w;
                let chunk = Chunk {
                    dots: &dots,
                    c0,
                    w,
                    ref_norm: &ref_norm[r.clone()],
                    ref_len: &ref_len[r.clone()],
                    ref_bound: &ref_bound[r],
                };
                screen(chunk, &scale, &mut best_hi, &mut cands);
            }
            (0..len)
                .map(|i| {
                    let hi = best_hi[i];
                    let mut best = (f64::INFINITY, usize::MAX);
                    for &(lo, j) in &cands[i] {
                        if lo > hi {
                            continue;
                        }
                        let dot: f64 = (0..d).map(|c| q[(i, c)] * reference[(j, c)]).sum();
                        let dist = ref_norm64[j] - 2.0 * dot;
                        if dist < best.0 || (dist == best.0 && j < best.1) {
                            best = (dist, j);
                        }
                    }
                    best.1
                })
                .collect()
        })
        .collect();
    crate::progress::check()?;
    Ok(blocks.into_iter().flatten().collect())
}

/// Exact Euclidean nearest rows: for every row of `query` (n × d) the index of the nearest row
/// of `reference` (m × d), ties to the smallest index (blocked brute force with a
/// single-precision screen, exact in f64; [`crate::pointwise::nearest_neighbors`] documents it).
pub fn nearest_rows(reference: MatRef<f64>, query: MatRef<f64>) -> Result<Vec<usize>> {
    best_rows(reference, query, true)
}

/// Maximum inner product rows: for every row of `query` the index of the row of `reference` with
/// the largest inner product, ties to the smallest index.
pub fn max_inner_rows(reference: MatRef<f64>, query: MatRef<f64>) -> Result<Vec<usize>> {
    best_rows(reference, query, false)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid samples of a 10,242-vertex sphere: near the asked count, ascending and
    /// distinct, and covering the sphere (every vertex within three sample spacings of one).
    #[test]
    fn grid_samples_cover_the_surface() {
        let p = crate::primitives::icosphere(5).vertices().to_vec();
        for count in [50, 500, 3000] {
            let s = grid_samples(&p, count);
            assert!(
                s.len() as f64 >= 0.8 * count as f64 && s.len() as f64 <= 1.25 * count as f64,
                "{count}: {}",
                s.len()
            );
            assert!(s.windows(2).all(|w| w[0] < w[1]));
            let spacing = (4.0 * std::f64::consts::PI / s.len() as f64).sqrt();
            let chosen: Vec<[f64; 3]> = s.iter().map(|&i| p[i]).collect();
            let nearest = nearest3(&chosen, &p);
            let far = p
                .iter()
                .zip(&nearest)
                .map(|(a, &t)| (0..3).map(|c| (a[c] - chosen[t][c]).powi(2)).sum::<f64>().sqrt())
                .fold(0.0, f64::max);
            assert!(far < 3.0 * spacing, "{count}: a vertex {far} from every sample (spacing {spacing})");
        }
        assert_eq!(grid_samples(&p[..10], 20), (0..10).collect::<Vec<_>>());
        assert!(grid_samples(&[], 5).is_empty());
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

    #[test]
    fn voronoi_samples_carry_the_whole_mass() {
        let mesh = crate::primitives::icosphere(2);
        let mass: Vec<f64> = (0..mesh.n_vertices()).map(|i| 1.0 + (i % 3) as f64).collect();
        let s = farthest_point_samples(mesh.vertices(), &mass, 10).unwrap();
        assert_eq!(s.len(), 10);
        assert!(s.weights.iter().all(|&w| w > 0.0));
        assert!((s.weights.iter().sum::<f64>() - mass.iter().sum::<f64>()).abs() < 1e-9);
        assert_eq!(farthest_point_samples(mesh.vertices(), &mass, 10_000).unwrap(), Samples::all(&mass));
        assert!(farthest_point_samples(mesh.vertices(), &mass[1..], 10).is_err());
    }

    /// Every vector width of the screen (AVX-512, AVX2 where the CPU has them, the baseline)
    /// gives the same bounds and candidates bit for bit, on products with near-ties and a
    /// query count that is not a multiple of the lanes.
    #[test]
    fn screen_is_the_same_at_every_vector_width() {
        let (len, w, c0) = (203, 300, 17);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Products on a coarse grid: many exact ties between columns.
        let dots = Mat::<f32>::from_fn(len, w, |_, _| (next() * 64.0).floor() as f32 / 16.0);
        let ref_norm: Vec<f32> = (0..w).map(|_| (next() * 32.0).floor() as f32 / 4.0).collect();
        let ref_len: Vec<f32> = ref_norm.iter().map(|v| v.sqrt()).collect();
        let ref_bound: Vec<f32> = ref_norm.iter().map(|v| 1e-6 * v).collect();
        let scale: Vec<f32> = (0..len).map(|_| 1e-3 * next() as f32).collect();
        // None: the generic function itself; Some(w): the dispatched one, limited to width w.
        let run = |widest: Option<u8>| {
            let mut best_hi = vec![f32::INFINITY; len];
            let mut cands = vec![Vec::new(); len];
            let chunk = Chunk { dots: &dots, c0, w, ref_norm: &ref_norm, ref_len: &ref_len, ref_bound: &ref_bound };
            match widest {
                None => screen_generic(chunk, &scale, &mut best_hi, &mut cands),
                Some(wd) => crate::linalg::with_widest(wd, || screen(chunk, &scale, &mut best_hi, &mut cands)),
            }
            let bits: Vec<u32> = best_hi.iter().map(|v| v.to_bits()).collect();
            let cands: Vec<Vec<(u32, usize)>> =
                cands.iter().map(|l| l.iter().map(|&(v, j)| (v.to_bits(), j)).collect()).collect();
            (bits, cands)
        };
        let generic = run(None);
        assert!(generic.1.iter().any(|l| l.len() > 1), "the data should leave several candidates");
        for widest in 0..=2 {
            let dispatched = run(Some(widest));
            assert_eq!(dispatched, generic, "widest {widest}");
        }
    }

    /// The farthest-point step at every vector width equals its definition (a running argmin of
    /// the distance to the samples, then the first farthest point), ties and all.
    #[test]
    fn farthest_update_is_its_definition_at_every_vector_width() {
        // Points on a coarse grid: many equal distances.
        let points: Vec<[f64; 3]> = (0..203).map(|i| [(i % 5) as f64, ((i / 5) % 4) as f64, (i % 3) as f64]).collect();
        let n = points.len();
        let (mut best, mut owner) = (vec![f64::INFINITY; n], vec![0usize; n]);
        for (s, &c) in [17usize, 3, 150].iter().enumerate() {
            // The definition, as the loop of `farthest_point_samples` was written.
            let (mut want_best, mut want_owner, mut far) = (best.clone(), owner.clone(), (0usize, -1.0f64));
            for (i, p) in points.iter().enumerate() {
                let d = (0..3).map(|k| (p[k] - points[c][k]).powi(2)).sum::<f64>();
                if d < want_best[i] {
                    (want_best[i], want_owner[i]) = (d, s);
                }
                if want_best[i] > far.1 {
                    far = (i, want_best[i]);
                }
            }
            for widest in 0..=2 {
                let (mut b, mut o) = (best.clone(), owner.clone());
                let got = crate::linalg::with_widest(widest, || farthest_update(&points, points[c], s, &mut b, &mut o));
                assert_eq!((got, &b, &o), (far, &want_best, &want_owner), "widest {widest}, step {s}");
            }
            (best, owner) = (want_best, want_owner);
        }
    }

    /// The single-precision screen keeps the exact f64 argmin at every magnitude the search
    /// accepts (both searches; ties to the smallest index).
    #[test]
    fn screen_keeps_the_exact_argmin_at_every_magnitude() {
        let (m, n, d) = (300, 120, 20);
        let mut rng = crate::spectral::Normal::new(5);
        let r0 = Mat::from_fn(m, d, |_, _| rng.sample());
        // Queries near reference rows (small gaps: many candidates to tell apart), one duplicate.
        let q0 = Mat::from_fn(n, d, |i, c| r0[((i * 7) % m, c)] + 1e-4 * rng.sample());
        for magnitude in [1e-30, 1e-3, 1.0, 1e20, 1e29] {
            // (1e-30 failed before the screen scaled its copies: f32 products underflowed.)
            let (r, q) = (&r0 * magnitude, &q0 * magnitude);
            let brute = |euclidean: bool| -> Vec<usize> {
                (0..n)
                    .map(|i| {
                        let mut best = (f64::INFINITY, usize::MAX);
                        for j in 0..m {
                            let rn: f64 = if euclidean { (0..d).map(|c| r[(j, c)].powi(2)).sum() } else { 0.0 };
                            let dot: f64 = (0..d).map(|c| q[(i, c)] * r[(j, c)]).sum();
                            let v = rn - 2.0 * dot;
                            if v < best.0 {
                                best = (v, j);
                            }
                        }
                        best.1
                    })
                    .collect()
            };
            assert_eq!(nearest_rows(r.as_ref(), q.as_ref()).unwrap(), brute(true), "nearest, magnitude {magnitude}");
            assert_eq!(max_inner_rows(r.as_ref(), q.as_ref()).unwrap(), brute(false), "inner, magnitude {magnitude}");
        }
    }
}
