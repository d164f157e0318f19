//! ZoomOut (Melzi et al. 2019) in the pull-back direction, on samples of X.

use faer::{Mat, MatRef};

use super::pullback::{map_of_pullback, map_of_pullback_among, pullback, sample_images_near, Scope};
use crate::error::{Error, Result};
use crate::linalg::mul;
use crate::pointwise::{nearest_neighbors_near, CoarseMap};
use crate::spatial::Samples;

/// Options of [`zoomout`] (the same as [`crate::pointwise::zoomout`]'s).
pub use crate::pointwise::ZoomOutOptions;

/// ZoomOut (Melzi et al. 2019) in the pull-back direction, on samples of X: from C_yx (k × k),
/// alternate the point map of the samples (nearest rows of Ψ_k C_yxᵀ for the rows of Φ_k,
/// [`map_of_pullback`]) and the pull-back map of the next size k + step ([`pullback`]), up to K.
/// Returns the final K × K map C_yx; the point map of every vertex of X is
/// [`map_of_pullback`] of it (or the bijective polish's, [`crate::refine::bijective_polish`]).
///
/// `scope` says where the samples' images are searched: with [`Scope::Near`] (whose `x_cells`
/// must be the samples: each sample is its own cell) the first iteration matches every sample
/// coarse to fine (among the vertices `y_cells` of Y, then near that image), the later ones
/// near its previous image only: O(#samples · cells · m / #y_cells · k) per iteration instead
/// of O(#samples · m · k), for shapes of 10⁵–10⁶ vertices. Errors for a start that is not
/// square or larger than K, K beyond the bases, step 0, and as [`map_of_pullback`].
pub fn zoomout(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
    scope: Scope,
) -> Result<Mat<f64>> {
    zoomout_pinned(phi, psi, samples, c0, opts, scope, &[])
}

/// [`zoomout`] with known point pairs held fixed: every `(i, j)` of `pins` (vertex i of X, which
/// must be one of the `samples`, and vertex j of Y) is matched to j in every point-map step,
/// whatever the functional map says, so that every pull-back map is fitted to it (with the
/// sample's weight). No pins: exactly [`zoomout`]. Errors as [`zoomout`], and for a pinned vertex
/// that is not a sample or a vertex of Y out of range.
#[allow(clippy::too_many_arguments)]
pub fn zoomout_pinned(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
    scope: Scope,
    pins: &[(usize, usize)],
) -> Result<Mat<f64>> {
    zoomout_coarse_to_fine(phi, psi, samples, c0, opts, scope, pins, None)
}

/// [`zoomout_pinned`] coarse to fine in Y: with `coarse` (well-spread vertices of Y, e.g.
/// [`crate::prepared::PreparedShape::grid_vertices`]) every step but the last matches the
/// samples among those vertices only ([`map_of_pullback_among`]), exactly there; the last step,
/// whose point map the final pull-back C_yx (K × K) is fitted to, searches as `scope` says. The
/// steps before the last only carry C_yx from size to size; their images lie within about one
/// spacing of `coarse` of the full search's, a small error against the wavelengths of the first
/// K eigenfunctions while `coarse` is dense enough (12,500 vertices: the last eigenfunction's
/// wavelength at K = 128 is ≈ 18 spacings). Costs O(#samples · #coarse · k) per step instead of
/// O(#samples · m · k). `None`: exactly [`zoomout_pinned`]. Errors as [`zoomout_pinned`], and
/// for a coarse vertex out of range.
#[allow(clippy::too_many_arguments)]
pub fn zoomout_coarse_to_fine(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    samples: &Samples,
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
    scope: Scope,
    pins: &[(usize, usize)],
    coarse: Option<&[usize]>,
) -> Result<Mat<f64>> {
    check_zoomout(phi, psi, c0, opts)?;
    let pinned = pin_positions(samples, pins, psi.nrows())?;
    let pin = |mut map: Vec<usize>| {
        for &(s, j) in &pinned {
            map[s] = j;
        }
        map
    };
    // A step before the last (the next size still below K) searches among the coarse vertices.
    let coarse_step = |c: MatRef<f64>| -> Option<&[usize]> { coarse.filter(|_| c.nrows() + opts.step < opts.k_final) };
    let (near, y_cells) = match scope {
        Scope::Exact => {
            return zoomout_loop(phi, psi, samples, c0.to_owned(), opts, |c| {
                Ok(pin(match coarse_step(c) {
                    Some(refs) => map_of_pullback_among(phi, psi, c, &samples.vertices, refs)?,
                    None => map_of_pullback(phi, psi, c, Some(&samples.vertices), Scope::Exact)?,
                }))
            })
        }
        Scope::Near { near, x_cells, y_cells } => {
            if x_cells != samples.vertices.as_slice() {
                return Err(Error::invalid(
                    "zoomout",
                    "a search near a coarse map needs ZoomOut's samples as the cells of X",
                ));
            }
            (near, y_cells)
        }
    };
    if samples.vertices.iter().any(|&v| v >= near.x.len()) {
        return Err(Error::invalid("samples", "a vertex id is out of range"));
    }
    let positions: Vec<[f64; 3]> = samples.vertices.iter().map(|&v| near.x[v]).collect();
    let own: Vec<usize> = (0..samples.len()).collect();
    let previous = std::cell::RefCell::new(None::<Vec<usize>>);
    zoomout_loop(phi, psi, samples, c0.to_owned(), opts, |c| {
        let mut prev = previous.borrow_mut();
        if let Some(refs) = coarse_step(c) {
            let map = pin(map_of_pullback_among(phi, psi, c, &samples.vertices, refs)?);
            *prev = Some(map.clone());
            return Ok(map);
        }
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
        let map = pin(map);
        *prev = Some(map.clone());
        Ok(map)
    })
}

/// The positions in `samples` of the pinned vertices of X with their images: (sample position,
/// vertex of Y) for every pin (i, j). Errors for a vertex i that is not a sample, or j ≥ `m`.
pub(super) fn pin_positions(samples: &Samples, pins: &[(usize, usize)], m: usize) -> Result<Vec<(usize, usize)>> {
    pins.iter()
        .map(|&(i, j)| {
            let s = samples.vertices.iter().position(|&v| v == i).ok_or_else(|| {
                Error::invalid("pins", format!("pinned vertex {i} of X is not one of the {} samples", samples.len()))
            })?;
            if j >= m {
                return Err(Error::invalid("pins", format!("vertex {j} of Y is out of range (m = {m})")));
            }
            Ok((s, j))
        })
        .collect()
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
