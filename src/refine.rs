//! Point-wise refinement of functional maps: ZoomOut (Melzi et al. 2019) on vertex samples, its
//! bijective two-direction variant (the discrete solver of Ren, Melzi, Wonka, Ovsjanikov 2021
//! with bijectivity and coupling terms), and an orientation check of point maps.
//!
//! **Conventions.** A point map π: X → Y is `map_xy` (length n, for every vertex of X a vertex of
//! Y). Its pull-back functional map `C_yx = Φᵀ A_X Π Ψ` (k_X × k_Y) takes the coefficients of a
//! function g on Y (in Ψ, m × k_Y) to those of g ∘ π on X (in Φ, n × k_X) — pyFM's `FM_12` with
//! mesh1 = Y, and the transpose direction of the C of [`crate::fmap`]. Conversely, from C_yx the
//! point map is read off by nearest neighbours ([`map_of_pullback`]). Estimating the map X → Y through
//! its own pull-back (rather than through the push-forward C of the opposite direction) is the
//! direction ZoomOut's analysis is for, and measurably better (EXPERIMENTS.md).
//!
//! **Samples.** ZoomOut's functional maps only need the point map on a few thousand vertices
//! (Melzi et al. §4.4): on a sample S of X with weights w (the area of each sample's Voronoi
//! cell), C_yx is the weighted least-squares solution of Φ_S C ≈ Ψ_π(S). With every vertex and
//! w = A_X this is exactly Φᵀ A_X Π Ψ.
//!
//! **Why one file (≈ 590 lines without tests).** ZoomOut on samples, its bijective variants and
//! the map-quality measures the pipeline selects with (metric distortion, orientation
//! agreement) share the samples ([`crate::spatial::farthest_point_samples`]) and the pull-back
//! helpers; they are the refinement layer of the
//! default pipeline and are read together.

use crate::linalg::mul;
use faer::{Mat, MatRef, Side};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::pointwise::{nearest_neighbors, nearest_neighbors_near, CoarseMap};
use crate::shape::TriMesh;
// The samples live with the other spatial queries; re-exported for the pipeline
// (`crate::matching::axiomatic` names them through this module).
use crate::spatial::Samples;

/// The pull-back functional map C_yx (k_X × k_Y) of a point map given on the samples of X:
/// the weighted least-squares solution of Φ_S C ≈ Ψ_{π(S)} (Φ: n × ≥k_X, Ψ: m × ≥k_Y,
/// `map_on_samples[s]` the vertex of Y of sample s). With all vertices and their masses this is
/// Φᵀ A_X Π Ψ.
pub fn pullback(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    map_on_samples: &[usize],
    kx: usize,
    ky: usize,
) -> Result<Mat<f64>> {
    let (n, m) = (phi.nrows(), psi.nrows());
    if map_on_samples.len() != samples.len() {
        return Err(Error::invalid("map", format!("{} entries for {} samples", map_on_samples.len(), samples.len())));
    }
    if kx == 0 || ky == 0 || kx > phi.ncols() || ky > psi.ncols() {
        return Err(Error::invalid("k", format!("need 1 ≤ k_X ≤ {}, 1 ≤ k_Y ≤ {}", phi.ncols(), psi.ncols())));
    }
    if samples.vertices.iter().any(|&v| v >= n) || map_on_samples.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", "a vertex id is out of range"));
    }
    let ns = samples.len();
    let wphi = Mat::from_fn(ns, kx, |s, a| samples.weights[s] * phi[(samples.vertices[s], a)]);
    let psi_pi = Mat::from_fn(ns, ky, |s, b| psi[(map_on_samples[s], b)]);
    let rhs = mul(wphi.transpose(), psi_pi.as_ref());
    let phi_s = Mat::from_fn(ns, kx, |s, a| phi[(samples.vertices[s], a)]);
    let gram = mul(wphi.transpose(), phi_s.as_ref());
    let llt = gram.llt(Side::Lower).map_err(|_| {
        Error::numerical(
            "pullback",
            format!("the {kx} basis functions are not independent on {ns} samples; use more samples"),
        )
    })?;
    use faer::linalg::solvers::Solve;
    Ok(llt.solve(&rhs))
}

/// The point map X → Y of a pull-back functional map C_yx (k_X × k_Y): for every query vertex i
/// of X (`rows`, or all), the vertex j of Y whose row of Ψ_{k_Y} C_yxᵀ is nearest to row i of
/// Φ_{k_X}. This minimizes ‖Φ − Π Ψ C_yxᵀ‖_F over point maps Π row by row: the update of
/// ZoomOut's orthogonality energy (Ren et al. 2021), and pyFM's default conversion. (The
/// "adjoint" alternative, rows of Ψ against rows of Φ C_yx, agrees for orthonormal C but is far
/// worse from the non-orthonormal maps of the energy: 23.1 against 6.3 mean error on 20 faust_r
/// pairs.)
pub fn map_of_pullback(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    rows: Option<&[usize]>,
) -> Result<Vec<usize>> {
    map_of_pullback_with(phi, psi, c_yx, None, rows)
}

/// Pointwise descriptors that the point map should also preserve: F (n × d) on X and G (m × d) on
/// Y, already weighted (their columns enter the nearest-neighbour embeddings as they are).
#[derive(Clone, Copy)]
pub struct DescriptorBlock<'a> {
    /// F (n × d).
    pub x: MatRef<'a, f64>,
    /// G (m × d).
    pub y: MatRef<'a, f64>,
}

/// The size (k_X, k_Y) of C_yx (k_X × k_Y), or an error naming "C" when it is empty or has more
/// rows than Φ or columns than Ψ has.
fn check_map_fits(phi: MatRef<f64>, psi: MatRef<f64>, c_yx: MatRef<f64>) -> Result<(usize, usize)> {
    let (kx, ky) = (c_yx.nrows(), c_yx.ncols());
    if kx == 0 || ky == 0 || kx > phi.ncols() || ky > psi.ncols() {
        return Err(Error::invalid(
            "C",
            format!("a {kx}×{ky} map does not fit bases with {} and {} columns", phi.ncols(), psi.ncols()),
        ));
    }
    Ok((kx, ky))
}

/// [`map_of_pullback`] with a descriptor block: π(i) minimizes
/// ‖Φ_i − (Ψ C_yxᵀ)_j‖² + ‖F_i − G_j‖² (the descriptor term of Ren et al. 2021's discrete
/// solver: ‖Π G − F‖² separates over the rows of Π).
pub fn map_of_pullback_with(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    block: Option<DescriptorBlock>,
    rows: Option<&[usize]>,
) -> Result<Vec<usize>> {
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    if let Some(r) = rows {
        if r.iter().any(|&i| i >= phi.nrows()) {
            return Err(Error::invalid("rows", "a vertex id is out of range"));
        }
    }
    let d = match block {
        Some(b) => {
            if b.x.nrows() != phi.nrows() || b.y.nrows() != psi.nrows() || b.x.ncols() != b.y.ncols() {
                return Err(Error::invalid(
                    "descriptor block",
                    format!("{}×{} on X and {}×{} on Y", b.x.nrows(), b.x.ncols(), b.y.nrows(), b.y.ncols()),
                ));
            }
            b.x.ncols()
        }
        None => 0,
    };
    let psi_c = mul(psi.subcols(0, ky), c_yx.transpose());
    let reference = Mat::from_fn(psi.nrows(), kx + d, |j, a| match block {
        Some(b) if a >= kx => b.y[(j, a - kx)],
        _ => psi_c[(j, a)],
    });
    let query_row = |i: usize, a: usize| match block {
        Some(b) if a >= kx => b.x[(i, a - kx)],
        _ => phi[(i, a)],
    };
    let query = match rows {
        Some(r) => Mat::from_fn(r.len(), kx + d, |s, a| query_row(r[s], a)),
        None => Mat::from_fn(phi.nrows(), kx + d, query_row),
    };
    nearest_neighbors(reference.as_ref(), query.as_ref())
}

/// Vertex positions of both shapes and a cell count, for computing the point map of every vertex
/// near a coarse map on samples ([`crate::pointwise::nearest_neighbors_near`]) instead of by the
/// exact O(n·m·k) search: the final maps of pairs of 10⁵–10⁶ vertices.
#[derive(Clone, Copy, Debug)]
pub struct Near<'a> {
    /// Vertex positions of the query shape X (n × 3).
    pub x: &'a [[f64; 3]],
    /// Vertex positions of the reference shape Y (m × 3).
    pub y: &'a [[f64; 3]],
    /// Cells of Y searched around the image of each sample of X.
    pub cells: usize,
}

impl<'a> Near<'a> {
    /// The same search in the other direction (Y → X).
    pub fn reversed(&self) -> Near<'a> {
        Near { x: self.y, y: self.x, cells: self.cells }
    }
}

/// The nearest reference row (rows of Y, `reference` m × d) of every sample `sx` of X (rows of
/// `query`, n × d), coarse to fine: each sample is first matched among the rows `y_cells` of Y
/// only, then searched among the vertices of Y in the `near.cells` cells around that image
/// ([`crate::pointwise::nearest_neighbors_near_rows`], each sample its own cell).
/// O(#sx · (#y_cells + cells · m / #y_cells) · d) instead of the exact O(#sx · m · d); equal to
/// the exact search whenever a sample's nearest row lies within those cells of its coarse image.
fn sample_images_near(
    reference: MatRef<f64>,
    query: MatRef<f64>,
    sx: &[usize],
    y_cells: &[usize],
    near: &Near,
) -> Result<Vec<usize>> {
    let (n, m) = (query.nrows(), reference.nrows());
    if sx.iter().any(|&i| i >= n) || y_cells.iter().any(|&j| j >= m) {
        return Err(Error::invalid("samples", "a vertex id is out of range"));
    }
    let d = query.ncols();
    let coarse_refs = Mat::from_fn(y_cells.len(), d, |t, a| reference[(y_cells[t], a)]);
    let queries = Mat::from_fn(sx.len(), d, |s, a| query[(sx[s], a)]);
    let coarse: Vec<usize> =
        nearest_neighbors(coarse_refs.as_ref(), queries.as_ref())?.into_iter().map(|t| y_cells[t]).collect();
    let map = CoarseMap { x: near.x, y: near.y, samples: sx, images: &coarse, y_cells };
    crate::pointwise::nearest_neighbors_near_rows(reference, query, &map, near.cells, sx)
}

/// [`map_of_pullback`] of every vertex of X searched near the map of the samples `sx` of X
/// (found coarse to fine: among the vertices `y_cells` of Y, then near that image), among the
/// cells of Y around `y_cells` ([`crate::pointwise::nearest_neighbors_near`]). Errors as [`map_of_pullback`] and
/// [`crate::pointwise::nearest_neighbors_near`].
pub fn map_of_pullback_near(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    sx: &[usize],
    y_cells: &[usize],
    near: &Near,
) -> Result<Vec<usize>> {
    let all: Vec<usize> = (0..phi.nrows()).collect();
    map_of_pullback_near_at(phi, psi, c_yx, sx, y_cells, near, &all)
}

/// [`map_of_pullback_near`] for the vertices `rows` of X only: the image of each (in the order
/// of `rows`). Errors as [`map_of_pullback_near`] and for a vertex id ≥ n.
pub fn map_of_pullback_near_at(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    sx: &[usize],
    y_cells: &[usize],
    near: &Near,
    rows: &[usize],
) -> Result<Vec<usize>> {
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    let reference = mul(psi.subcols(0, ky), c_yx.transpose());
    let query = phi.subcols(0, kx);
    let images = sample_images_near(reference.as_ref(), query, sx, y_cells, near)?;
    let coarse = CoarseMap { x: near.x, y: near.y, samples: sx, images: &images, y_cells };
    crate::pointwise::nearest_neighbors_near_rows(reference.as_ref(), query, &coarse, near.cells, rows)
}

/// Options of [`zoomout`] (the same as [`crate::pointwise::zoomout`]'s).
pub use crate::pointwise::ZoomOutOptions;

/// ZoomOut (Melzi et al. 2019) in the pull-back direction, on samples of X: from C_yx (k × k),
/// alternate the point map on the samples (nearest rows of Ψ_k for the rows of Φ_k C_yx) and
/// the pull-back map of the next size k + step, up to K; then the point map of every vertex of
/// X from the final K × K map. Returns (C_yx, map_xy).
pub fn zoomout(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
) -> Result<(Mat<f64>, Vec<usize>)> {
    zoomout_with(phi, psi, samples, c0, None, opts)
}

/// [`zoomout`] whose point maps also match a descriptor block ([`map_of_pullback_with`]).
pub fn zoomout_with(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    block: Option<DescriptorBlock>,
    opts: &ZoomOutOptions,
) -> Result<(Mat<f64>, Vec<usize>)> {
    check_zoomout(phi, psi, c0, opts)?;
    let c = zoomout_iterations(phi, psi, samples, c0.to_owned(), block, opts)?;
    let map = map_of_pullback_with(phi, psi, c.as_ref(), block, None)?;
    Ok((c, map))
}

/// The iterations of [`zoomout`] on the samples only: the final K × K map C_yx, without the
/// point map of every vertex (for callers that read the map off differently, such as
/// [`bijective_polish`]). Errors as [`zoomout`].
pub fn zoomout_fmap(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
) -> Result<Mat<f64>> {
    check_zoomout(phi, psi, c0, opts)?;
    zoomout_iterations(phi, psi, samples, c0.to_owned(), None, opts)
}

/// The argument checks of [`zoomout`]: a square start no larger than K, K within the bases,
/// step ≥ 1.
fn check_zoomout(phi: MatRef<f64>, psi: MatRef<f64>, c0: MatRef<f64>, opts: &ZoomOutOptions) -> Result<()> {
    let k0 = c0.nrows();
    let kf = opts.k_final;
    if c0.ncols() != k0 || k0 == 0 || kf < k0 || kf > phi.ncols() || kf > psi.ncols() || opts.step == 0 {
        Err(Error::invalid(
            "zoomout",
            format!(
                "need a square start C (got {}×{}), its size ≤ K ≤ the basis sizes ({}, {}) and step ≥ 1; got K = {kf}, step {}",
                c0.nrows(),
                c0.ncols(),
                phi.ncols(),
                psi.ncols(),
                opts.step
            ),
        ))
    } else {
        Ok(())
    }
}

/// [`zoomout_fmap`] for shapes of 10⁵–10⁶ vertices: in the first iteration every sample of X is
/// matched coarse to fine (among the vertices `y_cells` of Y, then near that image), after it
/// near its previous image only, among the vertices of Y in
/// the `near.cells` Voronoi cells (around the vertices `y_cells` of Y) nearest to that image
/// ([`crate::pointwise::nearest_neighbors_near`] with each sample its own cell):
/// O(#samples · cells · m / #y_cells · k) per iteration instead of O(#samples · m · k).
/// Errors as [`zoomout`] and [`crate::pointwise::nearest_neighbors_near`].
pub fn zoomout_fmap_near(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    y_cells: &[usize],
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
    near: &Near,
) -> Result<Mat<f64>> {
    check_zoomout(phi, psi, c0, opts)?;
    if samples.vertices.iter().any(|&v| v >= near.x.len()) {
        return Err(Error::invalid("samples", "a vertex id is out of range"));
    }
    let positions: Vec<[f64; 3]> = samples.vertices.iter().map(|&v| near.x[v]).collect();
    let own: Vec<usize> = (0..samples.len()).collect();
    let previous = std::cell::RefCell::new(None::<Vec<usize>>);
    zoomout_loop(phi, psi, samples, c0.to_owned(), opts, |c| {
        let mut prev = previous.borrow_mut();
        let (kx, ky) = (c.nrows(), c.ncols());
        let reference = mul(psi.subcols(0, ky), c.transpose());
        let map = match prev.as_ref() {
            None => sample_images_near(reference.as_ref(), phi.subcols(0, kx), &samples.vertices, y_cells, near)?,
            Some(images) => {
                let query = Mat::from_fn(samples.len(), kx, |s, a| phi[(samples.vertices[s], a)]);
                let coarse = CoarseMap { x: &positions, y: near.y, samples: &own, images, y_cells };
                nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, near.cells)?
            }
        };
        *prev = Some(map.clone());
        Ok(map)
    })
}

fn zoomout_iterations(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c: Mat<f64>,
    block: Option<DescriptorBlock>,
    opts: &ZoomOutOptions,
) -> Result<Mat<f64>> {
    zoomout_loop(phi, psi, samples, c, opts, |c| map_of_pullback_with(phi, psi, c, block, Some(&samples.vertices)))
}

/// The ZoomOut loop: the map of the samples by `map_of` (C_yx → the vertex of Y of every sample),
/// then the pull-back map of the next size, until K.
fn zoomout_loop(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    mut c: Mat<f64>,
    opts: &ZoomOutOptions,
    map_of: impl Fn(MatRef<f64>) -> Result<Vec<usize>>,
) -> Result<Mat<f64>> {
    let mut k = c.nrows();
    while k < opts.k_final {
        let map = map_of(c.as_ref())?;
        k = (k + opts.step).min(opts.k_final);
        c = pullback(phi, psi, samples, &map, k, k)?;
    }
    Ok(c)
}

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
    let (psi_ct, phi_c, psi_b) = (mul(psi, c_yx.transpose()), mul(phi, c_yx), mul(psi, c_xy));
    let reference = Mat::from_fn(refs.len(), 3 * k, |t, a| {
        let j = refs[t];
        match a / k {
            0 => psi_ct[(j, a)],
            1 => psi[(j, a - k)],
            _ => sw * psi_b[(j, a - 2 * k)],
        }
    });
    let query = Mat::from_fn(rows.len(), 3 * k, |s, a| match a / k {
        0 => phi[(rows[s], a)],
        1 => phi_c[(rows[s], a - k)],
        _ => sw * phi[(rows[s], a - 2 * k)],
    });
    (reference, query)
}

/// [`bijective_map`] of every vertex of X searched near the map of the samples `sx` (found coarse
/// to fine, as in [`map_of_pullback_near`]), among the cells of Y around `y_cells`.
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
    let coarse = CoarseMap { x: near.x, y: near.y, samples: sx, images: &images, y_cells };
    nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, near.cells)
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
) -> Result<(Mat<f64>, Mat<f64>)> {
    let (ry, rx) = if sampled_references { (Some(&sy.vertices[..]), Some(&sx.vertices[..])) } else { (None, None) };
    let map_xy = bijective_map(phi, psi, c_yx, c_xy, w, Some(&sx.vertices), ry)?;
    let map_yx = bijective_map(psi, phi, c_xy, c_yx, w, Some(&sy.vertices), rx)?;
    Ok((
        bijective_fmap(phi, psi, sx, &map_xy, sy, &map_yx, k, w)?,
        bijective_fmap(psi, phi, sy, &map_yx, sx, &map_xy, k, w)?,
    ))
}

/// Bijective ZoomOut: the discrete solver of Ren, Melzi, Wonka, Ovsjanikov 2021 with its
/// coupling and bijectivity terms (as in the bijective ZoomOut of Magnet et al.'s
/// SmoothFunctionalMaps): both point maps π_xy, π_yx and both pull-backs C_yx, C_xy are refined
/// together while the size grows from that of the start maps to K; each point map uses both
/// functional maps ([`bijective_map`]), each functional map both point maps. `c_yx0`, `c_xy0` are
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
        (c_yx, c_xy) = bijective_round(phi, psi, sx, sy, (c_yx.as_ref(), c_xy.as_ref()), k, w, false)?;
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
/// (samples of X matched to samples of Y and back, [`bijective_map`] with weight
/// [`POLISH_BIJECTIVITY`]) and both functional maps ([`bijective_fmap`]); then the point map of
/// every vertex of X with the orthogonality, coupling and bijectivity terms. On every faust_r
/// pair one round after ZoomOut lowers the mean error on 64 of 97 pairs and raises it on 30, by
/// at most 0.1 ×100 (EXPERIMENTS.md). With `near`, the final map of every vertex is searched
/// near the map of the samples of X, among the cells of Y around its samples
/// ([`crate::pointwise::nearest_neighbors_near`]). Returns (C_yx, map_xy on every vertex of X).
pub fn bijective_polish(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    sx: &Samples,
    sy: &Samples,
    c_yx: MatRef<f64>,
    rounds: usize,
    near: Option<&Near>,
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
    let w = POLISH_BIJECTIVITY;
    let (mut c_yx, mut c_xy) = (c_yx.to_owned(), c_yx.transpose().to_owned());
    for _ in 0..rounds {
        (c_yx, c_xy) = bijective_round(phi, psi, sx, sy, (c_yx.as_ref(), c_xy.as_ref()), k, w, true)?;
    }
    let map_xy = match near {
        Some(near) => bijective_map_near(phi, psi, c_yx.as_ref(), c_xy.as_ref(), w, &sx.vertices, &sy.vertices, near)?,
        None => bijective_map(phi, psi, c_yx.as_ref(), c_xy.as_ref(), w, None, None)?,
    };
    Ok((c_yx, map_xy))
}

/// Orientation agreement of a point map X → Y, in [−1, 1]: the area-weighted mean over the
/// triangles of X of the sign of ⟨n', N⟩, n' the normal of the image triangle (π(a), π(b), π(c))
/// and N the sum of Y's vertex normals at its corners (0 for a degenerate image). Near +1 for an
/// orientation-preserving map, near −1 for a mirrored one; a map mirrored on part of the shape
/// scores in between. `y_normals` are Y's unit vertex normals (length m).
pub fn orientation_agreement(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
) -> Result<f64> {
    orientation_on_faces(x, y_vertices, y_normals, map_xy, None)
}

/// [`orientation_agreement`] estimated from the triangles of X incident to the vertices
/// `centres`; `map_xy` needs to be right only on their corners ([`incident_vertices`]). Errors
/// as [`orientation_agreement`], and for a centre ≥ n.
pub fn orientation_agreement_around(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
    centres: &[usize],
) -> Result<f64> {
    let mark = centre_marks(x.n_vertices(), centres)?;
    orientation_on_faces(x, y_vertices, y_normals, map_xy, Some(&mark))
}

/// [`orientation_agreement`] over every triangle, or over those with a corner marked in `around`.
fn orientation_on_faces(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
    around: Option<&[bool]>,
) -> Result<f64> {
    let (n, m) = (x.n_vertices(), y_vertices.len());
    if map_xy.len() != n || y_normals.len() != m {
        return Err(Error::invalid(
            "map",
            format!(
                "{} entries for {n} vertices of X; {} normals for {m} vertices of Y",
                map_xy.len(),
                y_normals.len()
            ),
        ));
    }
    if map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("it points to a vertex ≥ m = {m}")));
    }
    let areas = x.face_areas();
    let (mut sum, mut total) = (0.0, 0.0);
    for (f, tri) in x.faces().iter().enumerate() {
        if around.is_some_and(|mark| !tri.iter().any(|&v| mark[v as usize])) {
            continue;
        }
        let [a, b, c] = tri.map(|v| map_xy[v as usize]);
        total += areas[f];
        if a == b || b == c || a == c {
            continue;
        }
        let (pa, pb, pc) = (y_vertices[a], y_vertices[b], y_vertices[c]);
        let u = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
        let v = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
        let nrm = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        let nsum: [f64; 3] = std::array::from_fn(|d| y_normals[a][d] + y_normals[b][d] + y_normals[c][d]);
        let dot = nrm[0] * nsum[0] + nrm[1] * nsum[1] + nrm[2] * nsum[2];
        if dot > 0.0 {
            sum += areas[f];
        } else if dot < 0.0 {
            sum -= areas[f];
        }
    }
    Ok(if total > 0.0 { sum / total } else { 0.0 })
}

/// Metric distortion of a point map X → Y on the edges of X's surface (mesh or point-cloud
/// triangulation): Σ_edges |‖y_π(i) − y_π(j)‖ − s ‖x_i − x_j‖| / Σ_edges s ‖x_i − x_j‖, with
/// s = √(area_Y / area_X) the scale between the shapes (`scale`). 0 for an isometry at the
/// resolution of the edges; a map that tears (neighbours sent far apart, as where a limb is
/// matched to the wrong one) or collapses (neighbours sent to one vertex) scores higher. The
/// chord lengths stand in for geodesic ones, exact enough at edge scale.
pub fn metric_distortion(x: &TriMesh, y_positions: &[[f64; 3]], scale: f64, map_xy: &[usize]) -> Result<f64> {
    distortion_on_edges(x, y_positions, scale, map_xy, None)
}

/// [`metric_distortion`] estimated from the edges of X incident to the vertices `centres` (e.g.
/// farthest-point samples): the same ratio, summed over those edges only. `map_xy` (length n)
/// needs to be right only on their endpoints ([`incident_vertices`]); its other entries are
/// read as vertex ids of Y but do not enter the result. Errors as [`metric_distortion`], and for
/// a centre ≥ n.
pub fn metric_distortion_around(
    x: &TriMesh,
    y_positions: &[[f64; 3]],
    scale: f64,
    map_xy: &[usize],
    centres: &[usize],
) -> Result<f64> {
    let mark = centre_marks(x.n_vertices(), centres)?;
    distortion_on_edges(x, y_positions, scale, map_xy, Some(&mark))
}

/// The vertices of X on the triangles incident to `centres` (the centres and their one-ring
/// neighbours), ascending: where [`metric_distortion_around`] and
/// [`orientation_agreement_around`] read the map. Ids ≥ n are ignored.
pub fn incident_vertices(x: &TriMesh, centres: &[usize]) -> Vec<usize> {
    let n = x.n_vertices();
    let mut mark = vec![false; n];
    centres.iter().filter(|&&v| v < n).for_each(|&v| mark[v] = true);
    let mut keep = mark.clone();
    for tri in x.faces() {
        if tri.iter().any(|&v| mark[v as usize]) {
            tri.iter().for_each(|&v| keep[v as usize] = true);
        }
    }
    (0..n).filter(|&v| keep[v]).collect()
}

/// A mask of length n, true at the `centres`.
fn centre_marks(n: usize, centres: &[usize]) -> Result<Vec<bool>> {
    if centres.iter().any(|&v| v >= n) {
        return Err(Error::invalid("centres", format!("a vertex id is ≥ n = {n}")));
    }
    let mut mark = vec![false; n];
    centres.iter().for_each(|&v| mark[v] = true);
    Ok(mark)
}

/// [`metric_distortion`] over every edge, or over the edges with an end marked in `around`.
fn distortion_on_edges(
    x: &TriMesh,
    y_positions: &[[f64; 3]],
    scale: f64,
    map_xy: &[usize],
    around: Option<&[bool]>,
) -> Result<f64> {
    let (n, m) = (x.n_vertices(), y_positions.len());
    if map_xy.len() != n || map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("need {n} entries < m = {m}")));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid("scale", format!("must be finite and > 0, got {scale}")));
    }
    let xv = x.vertices();
    let dist =
        |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let (mut num, mut den) = (0.0, 0.0);
    for e in x.edges() {
        let (i, j) = (e[0] as usize, e[1] as usize);
        if around.is_some_and(|mark| !mark[i] && !mark[j]) {
            continue;
        }
        let dx = scale * dist(xv[i], xv[j]);
        num += (dist(y_positions[map_xy[i]], y_positions[map_xy[j]]) - dx).abs();
        den += dx;
    }
    Ok(if den > 0.0 { num / den } else { 0.0 })
}

/// Per-vertex orientation of a point map X → Y, in [−1, 1] (length n): at every vertex of X the
/// area-weighted mean over its triangles of the sign of [`orientation_agreement`]'s test (+1
/// where the map preserves orientation, −1 where it mirrors, 0 where the images degenerate).
pub fn vertex_orientation(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
) -> Result<Vec<f64>> {
    let (n, m) = (x.n_vertices(), y_vertices.len());
    if map_xy.len() != n || y_normals.len() != m || map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("need {n} entries < m = {m} and {m} normals")));
    }
    let areas = x.face_areas();
    let mut num = vec![0.0; n];
    let mut den = vec![0.0; n];
    for (f, tri) in x.faces().iter().enumerate() {
        let [a, b, c] = tri.map(|v| map_xy[v as usize]);
        let sign = if a == b || b == c || a == c {
            0.0
        } else {
            let (pa, pb, pc) = (y_vertices[a], y_vertices[b], y_vertices[c]);
            let u = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
            let v = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
            let nrm = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let d: f64 = (0..3).map(|k| nrm[k] * (y_normals[a][k] + y_normals[b][k] + y_normals[c][k])).sum();
            d.signum() * f64::from(u8::from(d != 0.0))
        };
        for &i in tri {
            num[i as usize] += areas[f] * sign;
            den[i as usize] += areas[f];
        }
    }
    Ok(num.iter().zip(&den).map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 }).collect())
}

/// A function on X low-passed to its first k eigenfunctions: Φ_k Φ_kᵀ A v (length n).
pub fn low_pass(phi: MatRef<f64>, mass: &[f64], v: &[f64], k: usize) -> Vec<f64> {
    let k = k.min(phi.ncols());
    let n = phi.nrows();
    let coef: Vec<f64> = (0..k).map(|c| (0..n).map(|i| phi[(i, c)] * mass[i] * v[i]).sum()).collect();
    (0..n).map(|i| (0..k).map(|c| phi[(i, c)] * coef[c]).sum()).collect()
}

/// Repairs the mirrored parts of a point map X → Y with the intrinsic symmetry s_Y of Y
/// (`sym_y`, length m, an orientation-reversing involution): where the map mirrors
/// (`orientation[i] < 0`, e.g. the low-passed [`vertex_orientation`]), π(i) = s_Y(π_true(i)), so
/// π_true(i) = s_Y(π(i)). Returns the repaired map and the number of vertices changed.
pub fn repair_mirrored(map_xy: &[usize], orientation: &[f64], sym_y: &[usize]) -> Result<(Vec<usize>, usize)> {
    if orientation.len() != map_xy.len()
        || map_xy.iter().any(|&j| j >= sym_y.len())
        || sym_y.iter().any(|&j| j >= sym_y.len())
    {
        return Err(Error::invalid("repair", "map, orientation and symmetry sizes do not agree"));
    }
    let mut changed = 0;
    let out = map_xy
        .iter()
        .zip(orientation)
        .map(|(&j, &o)| {
            if o < 0.0 {
                changed += 1;
                sym_y[j]
            } else {
                j
            }
        })
        .collect();
    Ok((out, changed))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::spatial::farthest_point_samples;
    use crate::spectral::{eigen_basis, SpectralOptions};

    #[test]
    fn zoomout_recovers_a_permutation_from_a_coarse_start_on_samples() {
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 101 + 7) % n).collect(); // vertex i of X is vertex perm[i] of Y
        let mut inv = vec![0; n];
        for (i, &p) in perm.iter().enumerate() {
            inv[p] = i;
        }
        let y = x.permuted(&inv).unwrap();
        assert_eq!(y.vertices()[perm[17]], x.vertices()[17]);
        let basis = |m: &TriMesh| eigen_basis(&cotangent(m).unwrap(), &SpectralOptions::new(40), None).unwrap().0;
        let (bx, by) = (basis(&x), basis(&y));
        let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
        let full = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 40, 40).unwrap();
        let c0 = full.submatrix(0, 0, 4, 4).to_owned();
        let samples = farthest_point_samples(x.vertices(), &bx.mass, 300).unwrap();
        assert_eq!(samples.len(), 300);
        let total: f64 = samples.weights.iter().sum();
        assert!((total - bx.mass.iter().sum::<f64>()).abs() < 1e-12);
        let (c, map) = zoomout(phi, psi, &samples, c0.as_ref(), &ZoomOutOptions { k_final: 40, step: 3 }).unwrap();
        assert_eq!(c.nrows(), 40);
        assert_eq!(map, perm, "ZoomOut on samples must recover the permutation");
        // The identity permutation is orientation-preserving; the same map read on a mirrored
        // copy of Y is orientation-reversing.
        let normals = y.vertex_normals();
        let s = orientation_agreement(&x, y.vertices(), &normals, &map).unwrap();
        assert!(s > 0.99, "agreement {s}");
        let ym: Vec<[f64; 3]> = y.vertices().iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let nm: Vec<[f64; 3]> = normals.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let s = orientation_agreement(&x, &ym, &nm, &map).unwrap();
        assert!(s < -0.99, "mirrored agreement {s}");
    }

    #[test]
    fn distortion_and_orientation_around_samples_estimate_the_whole() {
        let x = bumpy_sphere(4);
        let n = x.n_vertices();
        let mass = vec![1.0; n];
        // A map that is right on one half and sends the other half to one vertex.
        let map: Vec<usize> = (0..n).map(|i| if x.vertices()[i][0] > 0.0 { i } else { 0 }).collect();
        let normals = x.vertex_normals();
        let (whole_d, whole_o) = (
            metric_distortion(&x, x.vertices(), 1.0, &map).unwrap(),
            orientation_agreement(&x, x.vertices(), &normals, &map).unwrap(),
        );
        // Around every vertex: exactly the whole.
        let all: Vec<usize> = (0..n).collect();
        assert_eq!(incident_vertices(&x, &all), all);
        assert!((metric_distortion_around(&x, x.vertices(), 1.0, &map, &all).unwrap() - whole_d).abs() < 1e-14);
        assert!(
            (orientation_agreement_around(&x, x.vertices(), &normals, &map, &all).unwrap() - whole_o).abs() < 1e-14
        );
        // Around 60 farthest-point samples, with the map known on their one-rings only: close.
        let centres = farthest_point_samples(x.vertices(), &mass, 60).unwrap().vertices;
        let patch = incident_vertices(&x, &centres);
        assert!(patch.len() > centres.len() && patch.len() < n / 2, "{} of {n}", patch.len());
        let mut partial = vec![0usize; n];
        patch.iter().for_each(|&v| partial[v] = map[v]);
        let d = metric_distortion_around(&x, x.vertices(), 1.0, &partial, &centres).unwrap();
        let o = orientation_agreement_around(&x, x.vertices(), &normals, &partial, &centres).unwrap();
        assert!((d - whole_d).abs() < 0.25 * whole_d, "{d} vs {whole_d}");
        assert!((o - whole_o).abs() < 0.25, "{o} vs {whole_o}");
        assert!(whole_d > 0.1 && metric_distortion_around(&x, x.vertices(), 1.0, &all, &centres).unwrap() == 0.0);
        assert!(metric_distortion_around(&x, x.vertices(), 1.0, &map, &[n]).is_err());
        assert!(orientation_agreement_around(&x, x.vertices(), &normals, &map, &[n]).is_err());
    }

    #[test]
    fn bijective_polish_repairs_a_noisy_map() {
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 101 + 7) % n).collect();
        let mut inv = vec![0; n];
        for (i, &p) in perm.iter().enumerate() {
            inv[p] = i;
        }
        let y = x.permuted(&inv).unwrap();
        let basis = |m: &TriMesh| eigen_basis(&cotangent(m).unwrap(), &SpectralOptions::new(30), None).unwrap().0;
        let (bx, by) = (basis(&x), basis(&y));
        let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
        let truth = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 30, 30).unwrap();
        // A deterministic perturbation of the true map.
        let noisy = Mat::from_fn(30, 30, |i, j| truth[(i, j)] + 0.15 * (((i * 31 + j * 17) % 13) as f64 / 6.0 - 1.0));
        let agreement = |m: &[usize]| m.iter().zip(&perm).filter(|(a, b)| a == b).count() as f64 / n as f64;
        let plain = agreement(&map_of_pullback(phi, psi, noisy.as_ref(), None).unwrap());
        assert!(plain < 0.95, "the perturbation must break the plain read-off ({plain})");
        let (sx, sy) = (
            farthest_point_samples(x.vertices(), &bx.mass, 300).unwrap(),
            farthest_point_samples(y.vertices(), &by.mass, 300).unwrap(),
        );
        let (c, map) = bijective_polish(phi, psi, &sx, &sy, noisy.as_ref(), 3, None).unwrap();
        assert_eq!(c.nrows(), 30);
        let polished = agreement(&map);
        assert!(polished > 0.99 && polished > plain, "polish {polished}, plain read-off {plain}");
        assert!(bijective_polish(phi, psi, &sx, &sy, noisy.submatrix(0, 0, 30, 20), 1, None).is_err());
    }

    #[test]
    fn pullback_of_all_vertices_is_the_mass_projection() {
        let x = bumpy_sphere(2);
        let b = eigen_basis(&cotangent(&x).unwrap(), &SpectralOptions::new(10), None).unwrap().0;
        let phi = b.eigenvectors.as_ref();
        let id: Vec<usize> = (0..x.n_vertices()).collect();
        let c = pullback(phi, phi, &Samples::all(&b.mass), &id, 10, 10).unwrap();
        assert!((&c - Mat::<f64>::identity(10, 10)).norm_max() < 1e-10);
        assert!(pullback(phi, phi, &Samples::all(&b.mass), &id[1..], 10, 10).is_err());
        assert!(farthest_point_samples(x.vertices(), &b.mass, 0).is_err());
    }
}
