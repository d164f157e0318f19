//! Bijective ZoomOut and the bijective polish: the discrete solver of Ren, Melzi, Wonka,
//! Ovsjanikov 2021 with its coupling and bijectivity terms, both point maps (X → Y, Y → X) and
//! both pull-backs (C_yx, C_xy) refined together.

use faer::{Mat, MatRef, Side};
use serde::{Deserialize, Serialize};

use super::pullback::{rows_near_exact, sample_images_near, Near, Scope};
use crate::error::{Error, Result};
use crate::linalg::{gather_rows, gather_rows_into, mul};
use crate::pointwise::nearest_neighbors;
use crate::spatial::Samples;

/// Options of [`bijective_zoomout`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BijectiveOptions {
    /// Final size K of the functional maps.
    pub k_final: usize,
    /// Size increment per iteration.
    pub step: usize,
    /// Weight of the bijectivity term relative to the coupling terms (Ren et al. 2021 use 1).
    pub bijectivity: f64,
}

/// Weighted Gram matrix Σ_s w_s a_s a_sᵀ and cross term Σ_s w_s a_s b_sᵀ of the rows of a and b
/// at the given rows (k_a × k_a and k_a × k_b).
fn weighted_products(
    a: MatRef<f64>,
    a_rows: &[usize],
    b: MatRef<f64>,
    b_rows: &[usize],
    w: &[f64],
    ka: usize,
    kb: usize,
) -> (Mat<f64>, Mat<f64>) {
    let ns = w.len();
    let wa = Mat::from_fn(ns, ka, |s, c| w[s] * a[(a_rows[s], c)]);
    let aa = Mat::from_fn(ns, ka, |s, c| a[(a_rows[s], c)]);
    let bb = Mat::from_fn(ns, kb, |s, c| b[(b_rows[s], c)]);
    (mul(wa.transpose(), aa.as_ref()), mul(wa.transpose(), bb.as_ref()))
}

#[allow(clippy::too_many_arguments)]
/// The functional-map step of the bijective refinement: C_yx (k × k) minimizing
/// ‖Φ C − Π_xy Ψ‖²_{W_X} + w ‖Π_yx Φ C − Ψ‖²_{W_Y} on the samples of both shapes (W the sample
/// weights): C pulls Y's functions back along π_xy and is inverted by π_yx.
fn bijective_fmap(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    map_xy: &[usize],
    sy: &Samples,
    map_yx: &[usize],
    k: usize,
    w: f64,
) -> Result<Mat<f64>> {
    let (g1, r1) = weighted_products(phi, &sx.vertices, psi, map_xy, &sx.weights, k, k);
    let (g2, r2) = weighted_products(phi, map_yx, psi, &sy.vertices, &sy.weights, k, k);
    let gram = &g1 + &g2 * w;
    let rhs = &r1 + &r2 * w;
    let llt = gram.llt(Side::Lower).map_err(|_| {
        Error::numerical("bijective refinement", format!("the {k} basis functions are not independent on the samples"))
    })?;
    use faer::linalg::solvers::Solve;
    Ok(llt.solve(&rhs))
}

/// The point map X → Y of the bijective refinement on the query rows of X (`rows`, or all),
/// among the reference rows of Y (`refs`, or all): π(i) minimizes
/// ‖Φ_i − (Ψ C_yxᵀ)_j‖² + ‖(Φ C_yx)_i − Ψ_j‖² + w ‖Φ_i − (Ψ C_xy)_j‖² (orthogonality, coupling
/// and bijectivity terms; each separates over the rows of Π).
fn bijective_map(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    c_xy: MatRef<f64>,
    w: f64,
    rows: Option<&[usize]>,
    refs: Option<&[usize]>,
) -> Result<Vec<usize>> {
    let all_y: Vec<usize>;
    let refs = match refs {
        Some(r) => r,
        None => {
            all_y = (0..psi.nrows()).collect();
            &all_y
        }
    };
    let all: Vec<usize>;
    let r = match rows {
        Some(r) => r,
        None => {
            all = (0..phi.nrows()).collect();
            &all
        }
    };
    let (reference, query) = bijective_embeddings(phi, psi, c_yx, c_xy, w, r, refs);
    Ok(nearest_neighbors(reference.as_ref(), query.as_ref())?.into_iter().map(|t| refs[t]).collect())
}

/// Rows of Y per block of [`bijective_embeddings`]' reference rows.
const EMBEDDING_BLOCK: usize = 2048;

/// The embeddings of [`bijective_map`]: the reference rows `refs` of Y and the query rows `rows`
/// of X (each × (k + 1)), whose squared distance is the map's cost up to a constant per query
/// row, so both have the same nearest reference row.
///
/// The cost of i ↦ j, ‖Φ_i − (Ψ C_yxᵀ)_j‖² + ‖(Φ C_yx)_i − Ψ_j‖² + w ‖Φ_i − (Ψ C_xy)_j‖², is, up
/// to terms of i alone, β_j − 4 Φ_i · b_j with b_j = (Ψ B)_j, B = C_yxᵀ + (w/2) C_xy (the two
/// first cross terms are both Φ_i · (Ψ C_yxᵀ)_j) and β_j = ‖(Ψ C_yxᵀ)_j‖² + ‖Ψ_j‖² +
/// w ‖(Ψ C_xy)_j‖². With the query row [2 Φ_i, 0] and the reference row [b_j, c_j],
/// c_j² = β_j − ‖b_j‖² + μ (μ ≥ 0 the smallest shift making every c_j² ≥ 0), the squared
/// distance is 4 ‖Φ_i‖² + μ + β_j − 4 Φ_i · b_j: one k-dimensional search instead of the three
/// stacked terms' 3k dimensions, and no n × 3k matrix (the reference is built in blocks of
/// [`EMBEDDING_BLOCK`] rows of Y).
fn bijective_embeddings(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    c_xy: MatRef<f64>,
    w: f64,
    rows: &[usize],
    refs: &[usize],
) -> (Mat<f64>, Mat<f64>) {
    let k = c_yx.nrows();
    let reference = bijective_reference(psi, c_yx, c_xy, w, refs, 1.0);
    let mut query = Mat::<f64>::zeros(rows.len(), k + 1);
    gather_rows_into(query.as_mut().subcols_mut(0, k), phi.subcols(0, k), rows, 0..k, 2.0);
    (reference, query)
}

/// The reference rows [b_j, c_j] of [`bijective_embeddings`] for the rows `refs` of Y (|refs| ×
/// (k + 1)), times `scale` (a power of two keeps every distance's comparisons exact: ×½ pairs
/// them with the query rows [Φ_i, 0] instead of [2 Φ_i, 0], all distances ×¼).
fn bijective_reference(
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    c_xy: MatRef<f64>,
    w: f64,
    refs: &[usize],
    scale: f64,
) -> Mat<f64> {
    use rayon::prelude::*;
    let k = c_yx.nrows();
    let psi = psi.subcols(0, k);
    // [C_yxᵀ | C_xy | B] (k × 3k): one product per block of Ψ's rows gives all three.
    let ops = Mat::from_fn(k, 3 * k, |a, c| match c / k {
        0 => c_yx[(c, a)],
        1 => c_xy[(a, c - k)],
        _ => c_yx[(c - 2 * k, a)] + 0.5 * w * c_xy[(a, c - 2 * k)],
    });
    let mut reference = Mat::<f64>::zeros(refs.len(), k + 1);
    // Blocks of rows of Y side by side; c_j² before the shift μ goes in the last column.
    reference.as_mut().par_row_chunks_mut(EMBEDDING_BLOCK).zip(refs.par_chunks(EMBEDDING_BLOCK)).for_each(
        |(mut out, chunk)| {
            let rows_psi = gather_rows(psi, chunk, 0..k, 1.0);
            let prod = mul(rows_psi.as_ref(), ops.as_ref());
            let sq = |m: &Mat<f64>, s: usize, from: usize| (from..from + k).map(|c| m[(s, c)] * m[(s, c)]).sum::<f64>();
            for s in 0..chunk.len() {
                let beta = sq(&prod, s, 0) + sq(&rows_psi, s, 0) + w * sq(&prod, s, k);
                out[(s, k)] = beta - sq(&prod, s, 2 * k);
            }
            for c in 0..k {
                for s in 0..chunk.len() {
                    out[(s, c)] = scale * prod[(s, 2 * k + c)];
                }
            }
        },
    );
    let shift = (0..refs.len()).map(|j| reference[(j, k)]).fold(0.0f64, |a, v| a.max(-v));
    for j in 0..refs.len() {
        reference[(j, k)] = scale * (reference[(j, k)] + shift).max(0.0).sqrt();
    }
    reference
}

/// [`bijective_map`] of every vertex of X searched near the map of the samples `sx` (found coarse
/// to fine, as in [`map_of_pullback`] with [`Scope::Near`]), among the cells of Y around `y_cells`.
#[allow(clippy::too_many_arguments)]
fn bijective_map_near(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    c_xy: MatRef<f64>,
    w: f64,
    sx: &[usize],
    y_cells: &[usize],
    near: &Near,
) -> Result<Vec<usize>> {
    let (all_x, all_y): (Vec<usize>, Vec<usize>) = ((0..phi.nrows()).collect(), (0..psi.nrows()).collect());
    // The query rows [Φ_i, 0] are Φ's first k columns, read in place (the restricted search
    // takes the missing column as zero): no n × (k + 1) copy; the reference ×½ to match.
    let mut reference = bijective_reference(psi, c_yx, c_xy, w, &all_y, 0.5);
    let query = phi.subcols(0, c_yx.nrows());
    let images = sample_images_near(reference.as_ref(), query, sx, y_cells, near)?;
    rows_near_exact(&mut reference, query, near, (sx, &images, y_cells), &all_x)
}

/// Pins ([`bijective_polish_pinned`]) as positions in the samples of both shapes: (position in
/// the samples of X, vertex of Y) and (position in the samples of Y, vertex of X).
#[derive(Default)]
struct PinnedSamples {
    xy: Vec<(usize, usize)>,
    yx: Vec<(usize, usize)>,
}

impl PinnedSamples {
    /// The positions of the pins (i on X, j on Y): i among the samples `sx`, and j, when it is one
    /// of the samples `sy`, pinned to i in the map Y → X. Errors for an i that is not a sample of
    /// X, and for vertex ids out of range.
    fn new(sx: &Samples, sy: &Samples, pins: &[(usize, usize)], n: usize, m: usize) -> Result<PinnedSamples> {
        let xy = super::zoomout::pin_positions(sx, pins, m)?;
        if let Some(&(i, _)) = pins.iter().find(|&&(i, _)| i >= n) {
            return Err(Error::invalid("pins", format!("vertex {i} of X is out of range (n = {n})")));
        }
        let yx = pins.iter().filter_map(|&(i, j)| sy.vertices.iter().position(|&v| v == j).map(|t| (t, i))).collect();
        Ok(PinnedSamples { xy, yx })
    }

    fn apply(&self, map_xy: &mut [usize], map_yx: &mut [usize]) {
        for &(s, j) in &self.xy {
            map_xy[s] = j;
        }
        for &(t, i) in &self.yx {
            map_yx[t] = i;
        }
    }
}

/// One round of the bijective refinement: both point maps on the samples of their shape (each
/// against every vertex of the other shape, or with `sampled_references` against its samples
/// only), then both functional maps at size `k`. Returns (C_yx, C_xy).
#[allow(clippy::too_many_arguments)]
fn bijective_round(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    sy: &Samples,
    (c_yx, c_xy): (MatRef<f64>, MatRef<f64>),
    k: usize,
    w: f64,
    sampled_references: bool,
    pinned: &PinnedSamples,
) -> Result<(Mat<f64>, Mat<f64>)> {
    let (ry, rx) = if sampled_references { (Some(&sy.vertices[..]), Some(&sx.vertices[..])) } else { (None, None) };
    let mut map_xy = bijective_map(phi, psi, c_yx, c_xy, w, Some(&sx.vertices), ry)?;
    let mut map_yx = bijective_map(psi, phi, c_xy, c_yx, w, Some(&sy.vertices), rx)?;
    pinned.apply(&mut map_xy, &mut map_yx);
    Ok((
        bijective_fmap(phi, psi, sx, &map_xy, sy, &map_yx, k, w)?,
        bijective_fmap(psi, phi, sy, &map_yx, sx, &map_xy, k, w)?,
    ))
}

/// Bijective ZoomOut: the discrete solver of Ren, Melzi, Wonka, Ovsjanikov 2021 with its
/// coupling and bijectivity terms (as in the bijective ZoomOut of Magnet et al.'s
/// SmoothFunctionalMaps): both point maps π_xy, π_yx and both pull-backs C_yx, C_xy are refined
/// together while the size grows from that of the start maps to K; each point map uses both
/// functional maps (`bijective_map`), each functional map both point maps. `c_yx0`, `c_xy0` are
/// k × k starts (C_xy ≈ C_yxᵀ for near-isometries). Returns (C_yx, map_xy on every vertex of X,
/// map_yx on every vertex of Y).
pub fn bijective_zoomout(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    sy: &Samples,
    c_yx0: MatRef<f64>,
    c_xy0: MatRef<f64>,
    opts: &BijectiveOptions,
) -> Result<(Mat<f64>, Vec<usize>, Vec<usize>)> {
    let k0 = c_yx0.nrows();
    let kf = opts.k_final;
    if c_yx0.ncols() != k0
        || c_xy0.nrows() != k0
        || c_xy0.ncols() != k0
        || kf < k0
        || kf > phi.ncols()
        || kf > psi.ncols()
        || opts.step == 0
    {
        return Err(Error::invalid(
            "bijective zoomout",
            format!("need square k × k starts, k ≤ K ≤ basis sizes and step ≥ 1 (K = {kf}, step {})", opts.step),
        ));
    }
    if !(opts.bijectivity.is_finite() && opts.bijectivity >= 0.0) {
        return Err(Error::invalid("bijectivity", format!("must be finite and ≥ 0, got {}", opts.bijectivity)));
    }
    let w = opts.bijectivity;
    let (mut c_yx, mut c_xy) = (c_yx0.to_owned(), c_xy0.to_owned());
    let mut k = k0;
    while k < kf {
        k = (k + opts.step).min(kf);
        (c_yx, c_xy) =
            bijective_round(phi, psi, sx, sy, (c_yx.as_ref(), c_xy.as_ref()), k, w, false, &PinnedSamples::default())?;
    }
    let map_xy = bijective_map(phi, psi, c_yx.as_ref(), c_xy.as_ref(), w, None, None)?;
    let map_yx = bijective_map(psi, phi, c_xy.as_ref(), c_yx.as_ref(), w, None, None)?;
    Ok((c_yx, map_xy, map_yx))
}

/// Bijectivity weight of [`bijective_polish`] (Ren et al. 2021 weigh the bijectivity and
/// coupling terms equally).
pub const POLISH_BIJECTIVITY: f64 = 1.0;

/// Bijective polish of a refined map (the discrete solver of Ren, Melzi, Wonka, Ovsjanikov 2021
/// at a fixed size): from C_yx (K × K, e.g. ZoomOut's result) and C_xy = C_yxᵀ (the inverse of an
/// orthonormal pull-back), `rounds` alternations of both point maps on the samples of each shape
/// (samples of X matched to samples of Y and back, `bijective_map` with weight
/// [`POLISH_BIJECTIVITY`]) and both functional maps (`bijective_fmap`); then the point map of
/// every vertex of X with the orthogonality, coupling and bijectivity terms. On every faust_r
/// pair one round after ZoomOut lowers the mean error on 64 of 97 pairs and raises it on 30, by
/// at most 0.1 ×100 (EXPERIMENTS.md). `scope` says where the final map of every vertex is
/// searched: among every vertex of Y, or near the map of the cells of X among the cells of Y
/// around the cells of Y (usually both shapes' samples; [`Scope::Near`]). Returns (C_yx, map_xy
/// on every vertex of X).
pub fn bijective_polish(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    sy: &Samples,
    c_yx: MatRef<f64>,
    rounds: usize,
    scope: Scope,
) -> Result<(Mat<f64>, Vec<usize>)> {
    bijective_polish_pinned(phi, psi, sx, sy, c_yx, rounds, scope, &[])
}

/// [`bijective_polish`] with known point pairs held fixed: for every `(i, j)` of `pins` (vertex
/// i of X, which must be one of the samples `sx`, and vertex j of Y) the map X → Y sends i to j
/// in every round and in the final map of every vertex, and the map Y → X sends j back to i in
/// every round where j is one of the samples `sy`. No pins: exactly [`bijective_polish`].
#[allow(clippy::too_many_arguments)]
pub fn bijective_polish_pinned(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    sy: &Samples,
    c_yx: MatRef<f64>,
    rounds: usize,
    scope: Scope,
    pins: &[(usize, usize)],
) -> Result<(Mat<f64>, Vec<usize>)> {
    let k = c_yx.nrows();
    if c_yx.ncols() != k || k == 0 || k > phi.ncols() || k > psi.ncols() {
        return Err(Error::invalid(
            "bijective polish",
            format!(
                "need a square start no larger than the bases ({}, {}), got {k}×{}",
                phi.ncols(),
                psi.ncols(),
                c_yx.ncols()
            ),
        ));
    }
    let pinned = PinnedSamples::new(sx, sy, pins, phi.nrows(), psi.nrows())?;
    let w = POLISH_BIJECTIVITY;
    let (mut c_yx, mut c_xy) = (c_yx.to_owned(), c_yx.transpose().to_owned());
    for _ in 0..rounds {
        (c_yx, c_xy) = bijective_round(phi, psi, sx, sy, (c_yx.as_ref(), c_xy.as_ref()), k, w, true, &pinned)?;
    }
    let mut map_xy = match scope {
        Scope::Near { near, x_cells, y_cells } => {
            bijective_map_near(phi, psi, c_yx.as_ref(), c_xy.as_ref(), w, x_cells, y_cells, near)?
        }
        Scope::Exact => bijective_map(phi, psi, c_yx.as_ref(), c_xy.as_ref(), w, None, None)?,
    };
    for &(i, j) in pins {
        map_xy[i] = j;
    }
    Ok((c_yx, map_xy))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cost of [`bijective_map`] written out: ‖Φ_i − (Ψ C_yxᵀ)_j‖² + ‖(Φ C_yx)_i − Ψ_j‖² +
    /// w ‖Φ_i − (Ψ C_xy)_j‖².
    fn cost(
        phi: MatRef<f64>,
        psi: MatRef<f64>,
        c_yx: MatRef<f64>,
        c_xy: MatRef<f64>,
        w: f64,
        i: usize,
        j: usize,
    ) -> f64 {
        let k = c_yx.nrows();
        let (a, b) = (phi.subrows(i, 1).subcols(0, k), psi.subrows(j, 1).subcols(0, k));
        let (psi_ct, phi_c, psi_b) = (mul(b, c_yx.transpose()), mul(a, c_yx), mul(b, c_xy));
        (0..k)
            .map(|c| {
                (a[(0, c)] - psi_ct[(0, c)]).powi(2)
                    + (phi_c[(0, c)] - b[(0, c)]).powi(2)
                    + w * (a[(0, c)] - psi_b[(0, c)]).powi(2)
            })
            .sum()
    }

    /// A random polish problem: Φ (400 × 9), Ψ (500 × 9), C_yx (6 × 6), C_xy near C_yxᵀ, random
    /// positions of both shapes, every 20th vertex of X as a sample and every 25th of Y as a cell.
    struct RandomPolish {
        phi: Mat<f64>,
        psi: Mat<f64>,
        c_yx: Mat<f64>,
        c_xy: Mat<f64>,
        px: Vec<[f64; 3]>,
        py: Vec<[f64; 3]>,
        sx: Vec<usize>,
        y_cells: Vec<usize>,
    }

    fn random_polish(seed: u64) -> RandomPolish {
        let mut rng = crate::rng::Normal::new(seed);
        let (n, m, k) = (400, 500, 6);
        let mut g = |r: usize, c: usize, s: f64| Mat::from_fn(r, c, |_, _| s * rng.sample());
        let (phi, psi, c_yx) = (g(n, k + 3, 1.0), g(m, k + 3, 1.0), g(k, k, 1.0));
        let c_xy = c_yx.transpose().to_owned() + g(k, k, 0.2);
        let pos = |p: Mat<f64>| (0..p.nrows()).map(|i| [p[(i, 0)], p[(i, 1)], p[(i, 2)]]).collect::<Vec<_>>();
        let (px, py) = (pos(g(n, 3, 1.0)), pos(g(m, 3, 1.0)));
        RandomPolish {
            phi,
            psi,
            c_yx,
            c_xy,
            px,
            py,
            sx: (0..n).step_by(20).collect(),
            y_cells: (0..m).step_by(25).collect(),
        }
    }

    /// The restricted polish (query rows Φ read in place, the reference ×½) searching every cell
    /// of Y gives the exact search's map on the full embeddings ([2 Φ_i, 0] and [b_j, c_j]).
    #[test]
    fn the_restricted_map_over_every_cell_is_the_exact_map() {
        let RandomPolish { phi, psi, c_yx, c_xy, px, py, sx, y_cells } = random_polish(8);
        let near = Near { x: &px, y: &py, cells: y_cells.len(), certify: false };
        for w in [1.0, 0.0] {
            let exact = bijective_map(phi.as_ref(), psi.as_ref(), c_yx.as_ref(), c_xy.as_ref(), w, None, None).unwrap();
            let restricted =
                bijective_map_near(phi.as_ref(), psi.as_ref(), c_yx.as_ref(), c_xy.as_ref(), w, &sx, &y_cells, &near)
                    .unwrap();
            assert_eq!(restricted, exact, "w = {w}");
        }
    }

    /// The restricted polish searching one cell of Y per query (so that many answers are wrong)
    /// gives the exact search's map once certified ([`crate::certified_search`]).
    #[test]
    fn the_certified_restricted_map_is_the_exact_map() {
        let RandomPolish { phi, psi, c_yx, c_xy, px, py, sx, y_cells } = random_polish(9);
        let n = phi.nrows();
        let exact = bijective_map(phi.as_ref(), psi.as_ref(), c_yx.as_ref(), c_xy.as_ref(), 1.0, None, None).unwrap();
        let run = |certify: bool| {
            let near = Near { x: &px, y: &py, cells: 1, certify };
            bijective_map_near(phi.as_ref(), psi.as_ref(), c_yx.as_ref(), c_xy.as_ref(), 1.0, &sx, &y_cells, &near)
                .unwrap()
        };
        let wrong = run(false).iter().zip(&exact).filter(|(a, b)| a != b).count();
        assert!(wrong > n / 10, "only {wrong} of {n} restricted answers differ: the test needs wrong ones");
        assert_eq!(run(true), exact);
    }

    #[test]
    fn the_embeddings_distance_is_the_cost_up_to_a_constant_per_query() {
        let mut rng = crate::rng::Normal::new(5);
        let (n, m, k) = (30, 5000, 7);
        let mut g = |r: usize, c: usize, s: f64| Mat::from_fn(r, c, |_, _| s * rng.sample());
        // Near-inverse maps (C_xy ≈ C_yxᵀ) and unrelated ones, with more basis columns than k.
        let (phi, psi) = (g(n, k + 2, 1.0), g(m, k + 2, 1.0));
        let c = g(k, k, 1.0);
        for (c_xy, w) in [(c.transpose().to_owned() + g(k, k, 0.1), 1.0), (g(k, k, 2.0), 0.3), (g(k, k, 1.0), 0.0)] {
            let rows: Vec<usize> = (0..n).rev().collect();
            let refs: Vec<usize> = (0..m).step_by(3).collect();
            let (reference, query) =
                bijective_embeddings(phi.as_ref(), psi.as_ref(), c.as_ref(), c_xy.as_ref(), w, &rows, &refs);
            assert_eq!(
                (reference.nrows(), reference.ncols(), query.nrows(), query.ncols()),
                (refs.len(), k + 1, n, k + 1)
            );
            for (s, &i) in rows.iter().enumerate() {
                let d = |t: usize| (0..=k).map(|a| (query[(s, a)] - reference[(t, a)]).powi(2)).sum::<f64>();
                let costs: Vec<f64> = refs
                    .iter()
                    .map(|&j| cost(phi.as_ref(), psi.as_ref(), c.as_ref(), c_xy.as_ref(), w, i, j))
                    .collect();
                let offset = d(0) - costs[0];
                let scale = costs.iter().fold(0.0f64, |a, &b| a.max(b));
                for (t, &ct) in costs.iter().enumerate() {
                    assert!((d(t) - ct - offset).abs() <= 1e-11 * scale, "query {i}, reference {t}");
                }
            }
            // The map: the cost's argmin (no near ties among these random rows).
            let map = bijective_map(phi.as_ref(), psi.as_ref(), c.as_ref(), c_xy.as_ref(), w, Some(&rows), Some(&refs))
                .unwrap();
            for (s, &i) in rows.iter().enumerate() {
                let best = refs
                    .iter()
                    .copied()
                    .min_by(|&a, &b| {
                        let ca = cost(phi.as_ref(), psi.as_ref(), c.as_ref(), c_xy.as_ref(), w, i, a);
                        ca.total_cmp(&cost(phi.as_ref(), psi.as_ref(), c.as_ref(), c_xy.as_ref(), w, i, b))
                    })
                    .unwrap();
                assert_eq!(map[s], best, "query {i}");
            }
        }
    }
}
