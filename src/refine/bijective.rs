//! Bijective ZoomOut and the bijective polish: the discrete solver of Ren, Melzi, Wonka,
//! Ovsjanikov 2021 with its coupling and bijectivity terms, both point maps (X → Y, Y → X) and
//! both pull-backs (C_yx, C_xy) refined together.

use faer::{Mat, MatRef, Side};
use serde::{Deserialize, Serialize};

use super::pullback::{rows_near, sample_images_near, Near, Scope};
use crate::error::{Error, Result};
use crate::linalg::{gather_rows_into, mul};
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

/// The embeddings of [`bijective_map`]: the reference rows `refs` of Y and the query rows `rows`
/// of X (each × 3k), whose squared distance is the map's cost.
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
    let (phi, psi) = (phi.subcols(0, k), psi.subcols(0, k));
    let sw = w.sqrt();
    // The three products side by side (each sequential), then the rows gathered column by
    // column: the same entries as gathering them one by one.
    let ((psi_ct, phi_c), psi_b) =
        rayon::join(|| rayon::join(|| mul(psi, c_yx.transpose()), || mul(phi, c_yx)), || mul(psi, c_xy));
    // [first | second | sw · third] of the gathered rows, written in place.
    let stack = |rows: &[usize], parts: [(MatRef<f64>, f64); 3]| {
        let mut out = Mat::<f64>::zeros(rows.len(), 3 * k);
        for (i, (p, scale)) in parts.into_iter().enumerate() {
            gather_rows_into(out.as_mut().subcols_mut(i * k, k), p, rows, 0..k, scale);
        }
        out
    };
    let (reference, query) = rayon::join(
        || stack(refs, [(psi_ct.as_ref(), 1.0), (psi, 1.0), (psi_b.as_ref(), sw)]),
        || stack(rows, [(phi, 1.0), (phi_c.as_ref(), 1.0), (phi, sw)]),
    );
    (reference, query)
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
    let (reference, query) = bijective_embeddings(phi, psi, c_yx, c_xy, w, &all_x, &all_y);
    let images = sample_images_near(reference.as_ref(), query.as_ref(), sx, y_cells, near)?;
    let all: Vec<usize> = (0..phi.nrows()).collect();
    rows_near(reference.as_ref(), query.as_ref(), near, (sx, &images, y_cells), &all)
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
