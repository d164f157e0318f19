//! Pull-back functional maps and the point maps read off them: [`pullback`] (point map on
//! samples → C_yx), [`map_of_pullback`] (C_yx → point map), and where that point map is searched
//! ([`Scope`]: among every vertex of Y, or near a coarse map for pairs of 10⁵–10⁶ vertices).

use faer::{Mat, MatRef, Side};

use crate::error::{Error, Result};
use crate::linalg::{gather_rows, mul};
use crate::pointwise::{nearest_neighbors, nearest_neighbors_near_rows, CoarseMap};
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
    let phi_s = gather_rows(phi, &samples.vertices, 0..kx, 1.0);
    let psi_pi = gather_rows(psi, map_on_samples, 0..ky, 1.0);
    let wphi = Mat::from_fn(ns, kx, |s, a| samples.weights[s] * phi_s[(s, a)]);
    // The right-hand side and the Gram matrix side by side (each one sequential product).
    let (rhs, gram) = rayon::join(|| mul(wphi.transpose(), psi_pi.as_ref()), || mul(wphi.transpose(), phi_s.as_ref()));
    let llt = gram.llt(Side::Lower).map_err(|_| {
        Error::numerical(
            "pullback",
            format!("the {kx} basis functions are not independent on {ns} samples; use more samples"),
        )
    })?;
    use faer::linalg::solvers::Solve;
    Ok(llt.solve(&rhs))
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
    /// Whether the final maps searched this way are made exact
    /// ([`crate::certified_search::certify_nearest_rows`]: the restricted answers checked
    /// against every vertex of the other shape by bounds, and corrected).
    pub certify: bool,
}

impl<'a> Near<'a> {
    /// The same search in the other direction (Y → X).
    pub fn reversed(&self) -> Near<'a> {
        Near { x: self.y, y: self.x, cells: self.cells, certify: self.certify }
    }
}

/// Where a point map X → Y looks for the image of a vertex of X: the one search parameter of
/// [`map_of_pullback`], [`crate::refine::zoomout`] and [`crate::refine::bijective_polish`].
#[derive(Clone, Copy, Debug)]
pub enum Scope<'a> {
    /// Among every vertex of Y: the exact O(n·m·k) search.
    Exact,
    /// Near a coarse map, for shapes of 10⁵–10⁶ vertices: the vertices `x_cells` of X are
    /// matched coarse to fine (among the vertices `y_cells` of Y, then near that image), every
    /// other vertex of X near the image of its nearest one in `x_cells`, among the vertices of Y
    /// in the `near.cells` cells (around the vertices `y_cells`) nearest to that image
    /// ([`crate::pointwise::nearest_neighbors_near`]). Equal to the exact search whenever a
    /// vertex's nearest row lies within those cells.
    Near {
        /// Positions of both shapes and the number of cells searched.
        near: &'a Near<'a>,
        /// The cells of X (e.g. its farthest-point samples).
        x_cells: &'a [usize],
        /// The cells of Y.
        y_cells: &'a [usize],
    },
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

/// The point map X → Y of a pull-back functional map C_yx (k_X × k_Y): for every query vertex i
/// of X (`rows`, in that order, or all), the vertex j of Y whose row of Ψ_{k_Y} C_yxᵀ is nearest
/// to row i of Φ_{k_X}, searched as `scope` says. This minimizes ‖Φ − Π Ψ C_yxᵀ‖_F over point
/// maps Π row by row: the update of ZoomOut's orthogonality energy (Ren et al. 2021), and pyFM's
/// default conversion. (The "adjoint" alternative, rows of Ψ against rows of Φ C_yx, agrees for
/// orthonormal C but is far worse from the non-orthonormal maps of the energy: 23.1 against 6.3
/// mean error on 20 faust_r pairs.) Errors for a map that does not fit the bases, a vertex id
/// out of range, and as [`crate::pointwise::nearest_neighbors_near`].
pub fn map_of_pullback(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    rows: Option<&[usize]>,
    scope: Scope,
) -> Result<Vec<usize>> {
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    let reference = mul(psi.subcols(0, ky), c_yx.transpose());
    match scope {
        Scope::Exact => {
            if let Some(r) = rows {
                if r.iter().any(|&i| i >= phi.nrows()) {
                    return Err(Error::invalid("rows", "a vertex id is out of range"));
                }
            }
            let query = match rows {
                Some(r) => Mat::from_fn(r.len(), kx, |s, a| phi[(r[s], a)]),
                None => Mat::from_fn(phi.nrows(), kx, |i, a| phi[(i, a)]),
            };
            nearest_neighbors(reference.as_ref(), query.as_ref())
        }
        Scope::Near { near, x_cells, y_cells } => {
            let query = phi.subcols(0, kx);
            let images = sample_images_near(reference.as_ref(), query, x_cells, y_cells, near)?;
            let all: Vec<usize>;
            let rows = match rows {
                Some(r) => r,
                None => {
                    all = (0..phi.nrows()).collect();
                    &all
                }
            };
            rows_near(reference.as_ref(), query, near, (x_cells, &images, y_cells), rows)
        }
    }
}

/// The point map Y → X read off the pull-back C_yx (k_X × k_Y) of a map X → Y: for every vertex
/// j of Y, the vertex i of X whose row of Φ_{k_X} C_yx is nearest to row j of Ψ_{k_Y} (the
/// adjoint reading of C_yx, exact for an orthonormal one: then C_yxᵀ is the pull-back of the
/// inverse map). `scope` is that of the map X → Y ([`map_of_pullback`]); with [`Scope::Near`]
/// every vertex of Y is matched near the images of its cells `y_cells` among the vertices of X
/// in the `near.cells` cells around `x_cells`. Errors as [`map_of_pullback`].
pub fn map_yx_of_pullback(phi: MatRef<f64>, psi: MatRef<f64>, c_yx: MatRef<f64>, scope: Scope) -> Result<Vec<usize>> {
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    let mut reference = mul(phi.subcols(0, kx), c_yx);
    match scope {
        Scope::Exact => {
            let query = Mat::from_fn(psi.nrows(), ky, |j, b| psi[(j, b)]);
            nearest_neighbors(reference.as_ref(), query.as_ref())
        }
        Scope::Near { near, x_cells, y_cells } => {
            let (query, back) = (psi.subcols(0, ky), near.reversed());
            let images = sample_images_near(reference.as_ref(), query, y_cells, x_cells, &back)?;
            let all: Vec<usize> = (0..psi.nrows()).collect();
            rows_near_exact(&mut reference, query, &back, (y_cells, &images, x_cells), &all)
        }
    }
}

/// [`map_yx_of_pullback`] searched near the preimages of the point map X → Y `map_xy` (length
/// n, vertices of Y): Y is cut into cells of about 32 vertices (`FINE_CELL`; the Euclidean
/// Voronoi cells of grid samples), and every vertex j of Y is matched among the vertices of X
/// that `map_xy` sends into the `near.cells` cells nearest to j's cell that receive any, then
/// the answers are certified when `near.certify` ([`crate::certified_search`]). `near` is
/// oriented X → Y (as for `map_xy`). Where the map X → Y is right, the nearest row of j lies
/// there: the exact answer's image under `map_xy` lies within a few edge lengths of j (david0 →
/// david1, 52k vertices: 99 % within 4.2 mean edge lengths), on every sheet that `map_xy` folds
/// onto that place; a search around one coarse image (`sample_images_near`) misses the other
/// sheets (5.5 % of the answers wrong on that pair, up to 56 edge lengths away; here 8, all
/// corrected by the certificate). The cost grows with the square of the local vertex density
/// (the cells are even in space): 0.4 s at 52k vertices per shape, 71 s at 840k (TOSCA's
/// uneven meshes subdivided), where [`NearSearch::inverse_certified_up_to`](crate::matching::axiomatic::NearSearch)
/// leaves the map Y → X to [`map_yx_of_pullback`]'s search near the samples' map.
///
/// Errors: those of [`map_yx_of_pullback`], `map_xy` of the wrong length or out of range,
/// positions of the wrong lengths, `near.cells` = 0.
pub fn map_yx_near_map(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    near: &Near,
    map_xy: &[usize],
) -> Result<Vec<usize>> {
    use rayon::prelude::*;
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    let (n, m) = (phi.nrows(), psi.nrows());
    if map_xy.len() != n || map_xy.iter().any(|&j| j >= m) || near.x.len() != n || near.y.len() != m {
        return Err(Error::invalid(
            "map_xy",
            format!("need n = {n} vertex ids of Y (< m = {m}) and the positions of both shapes"),
        ));
    }
    if near.cells == 0 {
        return Err(Error::invalid("cells", "must be at least 1"));
    }
    let mut reference = mul(phi.subcols(0, kx), c_yx);
    let query = psi.subcols(0, ky);
    // Cells of Y of about FINE_CELL vertices (Euclidean Voronoi cells of grid samples: even in
    // space, so that "near" means the same distance on every part of the surface).
    let centres: Vec<[f64; 3]> =
        crate::spatial::grid_samples(near.y, m / FINE_CELL).into_iter().map(|j| near.y[j]).collect();
    let owner = crate::spatial::nearest3(&centres, near.y);
    let (mut members, mut preimages) = (vec![Vec::new(); centres.len()], vec![Vec::new(); centres.len()]);
    for (j, &c) in owner.iter().enumerate() {
        members[c].push(j);
    }
    for (i, &j) in map_xy.iter().enumerate() {
        preimages[owner[j]].push(i);
    }
    // For every cell of Y, the `cells` nearest cells of Y that hold a preimage (at least one
    // does: n ≥ 1).
    let covered: Vec<usize> = (0..centres.len()).filter(|&c| !preimages[c].is_empty()).collect();
    let covered_centres: Vec<[f64; 3]> = covered.iter().map(|&c| centres[c]).collect();
    let around = crate::spatial::nearest_n3(&covered_centres, &centres, near.cells.min(covered.len()));
    let answers: Vec<Vec<usize>> = (0..centres.len())
        .into_par_iter()
        .map(|c| -> Result<Vec<usize>> {
            if members[c].is_empty() {
                return Ok(Vec::new());
            }
            let mut candidates: Vec<usize> =
                around[c].iter().flat_map(|&a| preimages[covered[a]].iter().copied()).collect();
            candidates.sort_unstable();
            let refs = gather_rows(reference.as_ref(), &candidates, 0..ky, 1.0);
            let queries = gather_rows(query, &members[c], 0..ky, 1.0);
            Ok(nearest_neighbors(refs.as_ref(), queries.as_ref())?.into_iter().map(|t| candidates[t]).collect())
        })
        .collect::<Result<_>>()?;
    let mut map = vec![0; m];
    for (c, found) in answers.into_iter().enumerate() {
        for (&j, i) in members[c].iter().zip(found) {
            map[j] = i;
        }
    }
    if near.certify {
        let all: Vec<usize> = (0..m).collect();
        let back = near.reversed();
        certify_rows(&mut reference, query, &back, &all, &mut map)?;
    }
    Ok(map)
}

/// [`rows_near`] made exact (when `near.certify`): its answer checked against every row of `reference` and corrected
/// where a nearer row lies outside the cells it read
/// ([`crate::certified_search::certify_nearest_rows`], which reads about 0.1–1 % of the rows per
/// query). The final point maps of large pairs: the exact search's maps at a fraction of its
/// cost. The certificate (rows read, answers changed) goes to the log.
pub(crate) fn rows_near_exact(
    reference: &mut Mat<f64>,
    query: MatRef<f64>,
    near: &Near,
    cells: (&[usize], &[usize], &[usize]),
    rows: &[usize],
) -> Result<Vec<usize>> {
    let mut map = rows_near(reference.as_ref(), query, near, cells, rows)?;
    if near.certify {
        certify_rows(reference, query, near, rows, &mut map)?;
    }
    Ok(map)
}

/// Checks the answers `map` (one per query row of `rows`) of a restricted search against every
/// row of `reference` and corrects them ([`crate::certified_search::certify_nearest_rows`]);
/// the certificate goes to the log (`FUNCORR_DEBUG_CERTIFIED`).
fn certify_rows(
    reference: &mut Mat<f64>,
    query: MatRef<f64>,
    near: &Near,
    rows: &[usize],
    map: &mut [usize],
) -> Result<()> {
    let t0 = std::time::Instant::now();
    let cert = crate::certified_search::certify_nearest_rows(
        reference.as_mut(),
        query,
        near.y,
        near.x,
        rows,
        map,
        CERTIFY_SEED,
    )?;
    if std::env::var_os("FUNCORR_DEBUG_CERTIFIED").is_some() {
        eprintln!(
            "certified search: {} queries, {} rows, {:.3} % of the rows read per query, {:.1} cells bounded per query, {} answers changed, {:.2} s",
            cert.queries,
            cert.references,
            100.0 * cert.share_read(),
            cert.cells_bounded as f64 / cert.queries.max(1) as f64,
            cert.changed,
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Seed of the certified search's cell subspaces (the maps do not depend on it).
const CERTIFY_SEED: u64 = 0x5EED_CE27;

/// [`map_of_pullback`] of the query rows `rows` of X searched among the vertices `refs` of Y
/// only (exactly, among those): for every i in `rows`, the vertex j in `refs` whose row of
/// Ψ_{k_Y} C_yxᵀ is nearest to row i of Φ_{k_X}. Costs O(|rows| · |refs| · k) and a
/// |refs| × k reference instead of m × k: ZoomOut's steps before its last on large shapes
/// ([`crate::refine::zoomout_coarse_to_fine`]). Errors as [`map_of_pullback`], and for empty
/// `refs` or a vertex id out of range.
pub fn map_of_pullback_among(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    c_yx: MatRef<f64>,
    rows: &[usize],
    refs: &[usize],
) -> Result<Vec<usize>> {
    let (kx, ky) = check_map_fits(phi, psi, c_yx)?;
    if rows.iter().any(|&i| i >= phi.nrows()) || refs.iter().any(|&j| j >= psi.nrows()) {
        return Err(Error::invalid("rows", "a vertex id is out of range"));
    }
    if refs.is_empty() {
        return Err(Error::invalid("refs", "no vertex of Y to search among"));
    }
    let reference = mul(gather_rows(psi, refs, 0..ky, 1.0).as_ref(), c_yx.transpose());
    let query = gather_rows(phi, rows, 0..kx, 1.0);
    Ok(nearest_neighbors(reference.as_ref(), query.as_ref())?.into_iter().map(|t| refs[t]).collect())
}

/// Vertices per cell of the finer levels of [`rows_near`].
const FINE_CELL: usize = 32;

/// [`rows_near`] adds a level while the cells of Y hold more than this many times
/// [`FINE_CELL`] vertices on average (and there are this many times more query rows than cells
/// of X).
const LEVEL_ABOVE: usize = 4;

/// The cells of a level of [`rows_near`] grow at most this many times from the level before.
const LEVEL_GROWTH: usize = 16;

/// The images of the query rows `rows` of X near the map `images` of the cells `x_cells` of X
/// among the cells `y_cells` of Y ([`crate::pointwise::nearest_neighbors_near_rows`] with
/// `near.cells` cells), through finer levels where the cells are large: while Y's cells hold on
/// average more than [`LEVEL_ABOVE`] × [`FINE_CELL`] vertices, up to [`LEVEL_GROWTH`] times more
/// cells on each shape ([`crate::spatial::grid_samples`], at most n / [`FINE_CELL`] and
/// m / [`FINE_CELL`]) are matched near the current level first, and become the cells of the
/// next. The cells searched per query then stay small as m grows (O(cells · FINE_CELL) rows
/// instead of O(cells · m / #y_cells)); each level's samples get exactly the images the
/// one-level search would give them. No level is added on pairs of ≲ 10⁵ vertices with the
/// default 2,000 cells (52k: 26 vertices per cell).
pub(crate) fn rows_near(
    reference: MatRef<f64>,
    query: MatRef<f64>,
    near: &Near,
    (x_cells, images, y_cells): (&[usize], &[usize], &[usize]),
    rows: &[usize],
) -> Result<Vec<usize>> {
    let (n, m) = (near.x.len(), near.y.len());
    let (mut xs, mut im, mut ys) = (x_cells.to_vec(), images.to_vec(), y_cells.to_vec());
    while m > LEVEL_ABOVE * FINE_CELL * ys.len().max(1) && rows.len() > LEVEL_ABOVE * xs.len() {
        let fx = crate::spatial::grid_samples(near.x, (xs.len() * LEVEL_GROWTH).min(n / FINE_CELL));
        let fy = crate::spatial::grid_samples(near.y, (ys.len() * LEVEL_GROWTH).min(m / FINE_CELL));
        if fx.len() <= xs.len() || fy.len() <= ys.len() {
            break;
        }
        let coarse = CoarseMap { x: near.x, y: near.y, samples: &xs, images: &im, y_cells: &ys };
        im = nearest_neighbors_near_rows(reference, query, &coarse, near.cells, &fx)?;
        (xs, ys) = (fx, fy);
    }
    let coarse = CoarseMap { x: near.x, y: near.y, samples: &xs, images: &im, y_cells: &ys };
    nearest_neighbors_near_rows(reference, query, &coarse, near.cells, rows)
}

/// The nearest reference row (rows of Y, `reference` m × d) of every sample `sx` of X (rows of
/// `query`, n × d), coarse to fine: each sample is first matched among the rows `y_cells` of Y
/// only, then searched among the vertices of Y in the `near.cells` cells around that image
/// ([`crate::pointwise::nearest_neighbors_near_rows`], each sample its own cell).
/// O(#sx · (#y_cells + cells · m / #y_cells) · d) instead of the exact O(#sx · m · d); equal to
/// the exact search whenever a sample's nearest row lies within those cells of its coarse image.
pub(super) fn sample_images_near(
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
    // (Query columns beyond its own are zero, as in `nearest_neighbors_near_rows`.)
    let (d, dq) = (reference.ncols(), query.ncols());
    let coarse_refs = Mat::from_fn(y_cells.len(), d, |t, a| reference[(y_cells[t], a)]);
    let queries = Mat::from_fn(sx.len(), d, |s, a| if a < dq { query[(sx[s], a)] } else { 0.0 });
    let coarse: Vec<usize> =
        nearest_neighbors(coarse_refs.as_ref(), queries.as_ref())?.into_iter().map(|t| y_cells[t]).collect();
    let map = CoarseMap { x: near.x, y: near.y, samples: sx, images: &coarse, y_cells };
    nearest_neighbors_near_rows(reference, query, &map, near.cells, sx)
}
