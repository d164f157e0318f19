//! From functional maps to point-to-point maps (paper §2, last paragraphs).
//!
//! A functional map C (k × k) sends the coefficients of a function on X (in Φ, n × k) to
//! coefficients on Y (in Ψ, m × k). Thinking of the rows of Φ Cᵀ and of Ψ as points in R^k, the
//! point-wise map X → Y sends vertex i of X to the vertex of Y whose row of Ψ is nearest to row i
//! of Φ Cᵀ (Ovsjanikov et al. 2012). A point-to-point map `map_xy` is a vector of length n whose
//! entry i is the vertex of Y matched to vertex i of X.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Exact Euclidean nearest neighbours: for every row of `query` (n × d) the index of the nearest
/// row of `reference` (m × d); ties go to the smallest index.
///
/// Blocked brute force: for a block of query rows, ‖q − r‖² = ‖q‖² − 2 q·r + ‖r‖² with the q·r
/// products from one GEMM (block × m), blocks in parallel. O(n·m·d) flops and O(block·m) memory,
/// exact in any dimension (the embeddings here have d = k up to hundreds, where k-d trees
/// degenerate to scanning anyway).
pub fn nearest_neighbors(reference: MatRef<f64>, query: MatRef<f64>) -> Result<Vec<usize>> {
    crate::spatial::nearest_rows(reference, query)
}

/// Maximum inner product search: for every row of `query` (n × d) the index of the row of
/// `reference` (m × d) with the largest inner product; ties go to the smallest index. For
/// factors T = L Rᵀ (L: m × k, R: n × k) of a correspondence, `max_inner_product(L, R)` is the
/// argmax of every column of T, computed in blocks without forming T (blocked GEMM as in
/// [`nearest_neighbors`]).
pub fn max_inner_product(reference: MatRef<f64>, query: MatRef<f64>) -> Result<Vec<usize>> {
    crate::spatial::max_inner_rows(reference, query)
}

/// A coarse point map X → Y given on samples of X, and a partition of Y into cells, which
/// restrict the search of [`nearest_neighbors_near`] to a neighbourhood of each sample's image.
#[derive(Clone, Copy, Debug)]
pub struct CoarseMap<'a> {
    /// Vertex positions of X, the query shape (n × 3).
    pub x: &'a [[f64; 3]],
    /// Vertex positions of Y, the reference shape (m × 3).
    pub y: &'a [[f64; 3]],
    /// Sample vertices of X (e.g. farthest-point samples); every vertex of X belongs to the
    /// cell of its nearest sample (Euclidean).
    pub samples: &'a [usize],
    /// The vertex of Y each sample maps to (as many as `samples`).
    pub images: &'a [usize],
    /// Cell centres of Y (vertex ids, e.g. farthest-point samples): every vertex of Y belongs
    /// to the cell of its nearest centre.
    pub y_cells: &'a [usize],
}

/// [`nearest_neighbors`] restricted by a coarse map ("nearest neighbours on vertex samples", for
/// shapes of 10⁵–10⁶ vertices where the exact O(n·m·d) search is out of reach): every query
/// vertex i of X, in the cell of sample s, is searched among the vertices of Y in the `cells`
/// cells of Y nearest to the image of s. Costs O(n · cells · m / #cells · d) instead of
/// O(n · m · d), plus k-d tree queries in 3-D.
///
/// The result equals the exact search whenever each vertex's true nearest row lies in those
/// cells — for a continuous map, when the coarse map is right and `cells` covers the distance a
/// vertex's image can lie from its sample's image (the test compares with the exact search).
/// Rows of `query` (n × d) and `reference` (m × d) are the vertices of X and Y.
///
/// Errors: those of [`nearest_neighbors`], mismatched sizes, vertex ids out of range, empty
/// samples or cells, `cells` = 0.
pub fn nearest_neighbors_near(
    reference: MatRef<f64>,
    query: MatRef<f64>,
    coarse: &CoarseMap,
    cells: usize,
) -> Result<Vec<usize>> {
    let all: Vec<usize> = (0..query.nrows()).collect();
    nearest_neighbors_near_rows(reference, query, coarse, cells, &all)
}

/// [`nearest_neighbors_near`] for the query rows `rows` only (vertex ids of X, any order,
/// repeats allowed): returns the image of each, in the order of `rows`. The query may have fewer
/// columns than the reference (d_q ≤ d): its missing columns are zero, so a caller need not copy
/// an n × d_q matrix to append them. Costs O(|rows| · cells ·
/// m / #cells · d) plus the cells of Y; used where a point map is needed on part of X only (the
/// probes of large pairs score a candidate around samples, [`crate::refine::metric_distortion_around`]).
///
/// Errors: those of [`nearest_neighbors_near`], a row id ≥ n.
pub fn nearest_neighbors_near_rows(
    reference: MatRef<f64>,
    query: MatRef<f64>,
    coarse: &CoarseMap,
    cells: usize,
    rows: &[usize],
) -> Result<Vec<usize>> {
    let (n, m) = (query.nrows(), reference.nrows());
    if coarse.x.len() != n || coarse.y.len() != m {
        return Err(Error::invalid(
            "coarse map",
            format!("{} and {} positions for embeddings of {n} and {m} rows", coarse.x.len(), coarse.y.len()),
        ));
    }
    if coarse.samples.is_empty() || coarse.samples.len() != coarse.images.len() || coarse.y_cells.is_empty() {
        return Err(Error::invalid(
            "coarse map",
            format!(
                "{} samples, {} images, {} cells of Y: need as many images as samples, at least one of each",
                coarse.samples.len(),
                coarse.images.len(),
                coarse.y_cells.len()
            ),
        ));
    }
    if cells == 0 {
        return Err(Error::invalid("cells", "must be at least 1"));
    }
    if coarse.samples.iter().any(|&v| v >= n) || coarse.images.iter().chain(coarse.y_cells).any(|&v| v >= m) {
        return Err(Error::invalid("coarse map", "a vertex id is out of range"));
    }
    if rows.iter().any(|&i| i >= n) {
        return Err(Error::invalid("rows", format!("a query row id is ≥ n = {n}")));
    }
    if query.ncols() > reference.ncols() {
        return Err(Error::invalid(
            "embedding",
            format!("query has dimension {} but reference has {}", query.ncols(), reference.ncols()),
        ));
    }
    // Query columns beyond its own are zero (`dq` ≤ d).
    let (d, dq) = (reference.ncols(), query.ncols());
    let points = |ids: &[usize], p: &[[f64; 3]]| ids.iter().map(|&v| p[v]).collect::<Vec<[f64; 3]>>();
    let centres = points(coarse.y_cells, coarse.y);
    // Members of every cell of X (around a sample) and of Y (around a centre), ascending.
    // (Positions in `rows` for X.)
    let members = |owner: Vec<usize>, count: usize| {
        let mut lists = vec![Vec::new(); count];
        for (v, o) in owner.into_iter().enumerate() {
            lists[o].push(v);
        }
        lists
    };
    let x_cells = members(
        crate::spatial::nearest3(&points(coarse.samples, coarse.x), &points(rows, coarse.x)),
        coarse.samples.len(),
    );
    let mut y_members = members(crate::spatial::nearest3(&centres, coarse.y), centres.len());
    let near = crate::spatial::nearest_n3(&centres, &points(coarse.images, coarse.y), cells.min(centres.len()));
    // Only the cells of Y that some query searches are copied below (a few rows of X search a
    // small part of Y).
    let mut needed = vec![false; centres.len()];
    for (queries, near_cells) in x_cells.iter().zip(&near) {
        if !queries.is_empty() {
            near_cells.iter().for_each(|&c| needed[c] = true);
        }
    }
    for (list, _) in y_members.iter_mut().zip(&needed).filter(|(_, &n)| !n) {
        list.clear();
    }
    // The screen's units: σ brings the largest entry of the queries' rows and of Y's rows into
    // [−1, 1] (`spatial::ScreenScale`).
    let usable = |v: f64| v.is_finite() && v.abs() <= crate::spatial::MAX_EMBEDDING;
    let mut largest = 0.0f64;
    for c in 0..dq {
        let col = query.col(c);
        for &i in rows {
            let v = col[i];
            if !usable(v) {
                return Err(Error::invalid(
                    "embedding",
                    "it contains a non-finite value or one beyond 1e30 in magnitude",
                ));
            }
            largest = largest.max(v.abs());
        }
    }
    // Y's rows by cell: every cell one contiguous block, in f64 rows and in f32 strips.
    let (mut cells_y, largest_y) = CellBlocks::new(reference, &y_members)?;
    let scale = crate::spatial::ScreenScale::new(largest.max(largest_y), d);
    cells_y.screen_in(&scale);
    crate::progress::check()?;
    let results: Vec<Vec<(usize, usize)>> = x_cells
        .par_iter()
        .zip(near.par_iter())
        .map(|(queries, near_cells)| {
            if queries.is_empty() || crate::progress::cancelled() {
                return Vec::new(); // a cancelled search is discarded by the check below
            }
            let qn = queries.len();
            // The queries' rows, row-major: in f64, and scaled in f32 padded with zero rows to
            // whole tiles; each query's factor of the screen's bound.
            let mut q64 = vec![0.0f64; qn * d];
            for c in 0..dq {
                let col = query.col(c);
                for (a, &i) in queries.iter().enumerate() {
                    q64[a * d + c] = col[rows[i]];
                }
            }
            let query_sq: Vec<f64> = q64.chunks_exact(d).map(|r| r.iter().fold(0.0, |s, v| s + v * v)).collect();
            // Per cell: the queries centred on the cell's centre c (q − c in f64, then scaled
            // in f32), κ = ‖q − c‖², the bound's factor and additive term.
            let mut q32 = vec![0.0f32; qn.div_ceil(QUERY_TILE) * QUERY_TILE * d];
            let (mut kappa, mut factor, mut extra) = (vec![0.0f32; qn], vec![0.0f32; qn], vec![0.0f32; qn]);
            let mut best_hi = vec![f32::INFINITY; qn];
            let mut cands: Vec<Vec<(f32, usize)>> = vec![Vec::new(); qn];
            for &cell in near_cells {
                if cells_y.starts[cell] == cells_y.starts[cell + 1] {
                    continue;
                }
                let centre = &cells_y.centres[cell * d..(cell + 1) * d];
                for (a, (row, out)) in q64.chunks_exact(d).zip(q32.chunks_exact_mut(d)).enumerate() {
                    let mut sq = 0.0;
                    for ((x, &v), &c) in out.iter_mut().zip(row).zip(centre) {
                        let t = v - c;
                        *x = (scale.sigma * t) as f32;
                        sq += t * t;
                    }
                    kappa[a] = (scale.sigma * scale.sigma * sq) as f32;
                    factor[a] = scale.query(sq);
                    extra[a] = scale.centred(sq, query_sq[a], cells_y.reach);
                }
                let screen = Screen { y: &cells_y, cell, q: &q32, kappa: &kappa, factor: &factor, extra: &extra };
                screen_cells(screen, &mut best_hi, &mut cands);
            }
            queries
                .iter()
                .enumerate()
                .map(|(a, &i)| (i, check_candidates(&cells_y, &q64[a * d..(a + 1) * d], &cands[a], best_hi[a])))
                .collect()
        })
        .collect();
    crate::progress::check()?;
    let mut map = vec![0usize; rows.len()];
    for (i, j) in results.into_iter().flatten() {
        if j == usize::MAX {
            return Err(Error::invalid("coarse map", "a query's cells of Y hold no vertex"));
        }
        map[i] = j;
    }
    Ok(map)
}

/// The rows of Y (m × d) grouped by cell, each cell padded to a multiple of [`ROW_TILE`] rows:
/// cell `c` holds the padded rows `starts[c]..starts[c + 1]`, `order[t]` the vertex of padded
/// row t (ascending within a cell; `usize::MAX` for padding). Each padded row is stored twice:
/// in f64, row-major (`rows`, entry (t, col) at t · d + col: the check reads a candidate's row
/// contiguously), with its squared norm `norms[t]` (summed over the columns in order, as the
/// exact search sums them; +∞ for padding); and scaled by σ in f32 for the screen (`strips`: in
/// tiles of [`ROW_TILE`] rows, each tile column-major, entry (t, col) at ⌊t / ROW_TILE⌋ ·
/// ROW_TILE · d + col · ROW_TILE + t mod ROW_TILE), with the screen's terms `len`, `norm` and
/// `bound` ([`crate::spatial::ScreenScale::reference`]; `norm` = f32::MAX for padding, so a
/// padding row never passes the screen).
struct CellBlocks {
    order: Vec<usize>,
    starts: Vec<usize>,
    rows: Vec<f64>,
    norms: Vec<f64>,
    /// Each cell's centre c (the mean of its rows, f64, #cells × d) and, per padded row, the
    /// screen's f32 strips of σ (r − c) and terms of ‖r − c‖ (a screen in centred coordinates).
    centres: Vec<f64>,
    strips: Vec<f32>,
    len: Vec<f32>,
    norm: Vec<f32>,
    bound: Vec<f32>,
    /// The largest ‖r‖ among the rows.
    reach: f64,
    d: usize,
}

/// Rows of a cell per register tile of the screen (one AVX-512 vector of f32, two of AVX2).
const ROW_TILE: usize = 16;

/// Query rows per register tile of the screen.
const QUERY_TILE: usize = 4;

/// Padded rows that the fill of [`CellBlocks`] copies column by column at a time (64 rows × d
/// f64: within L2 for d up to a few hundred).
const FILL_ROWS: usize = 64;

impl CellBlocks {
    /// The f64 rows of `reference` (m × d) for the cells `members` (vertex lists of Y) and the
    /// largest magnitude among them; the f32 strips follow in [`CellBlocks::screen_in`]. Errors:
    /// a value that is not finite or beyond [`crate::spatial::MAX_EMBEDDING`] in those rows.
    fn new(reference: MatRef<f64>, members: &[Vec<usize>]) -> Result<(Self, f64)> {
        let d = reference.ncols();
        let padded = |len: usize| len.div_ceil(ROW_TILE) * ROW_TILE;
        let mut starts = Vec::with_capacity(members.len() + 1);
        starts.push(0usize);
        for l in members {
            starts.push(starts[starts.len() - 1] + padded(l.len()));
        }
        let total = starts[starts.len() - 1];
        let mut order = vec![usize::MAX; total];
        for (cell, list) in members.iter().enumerate() {
            order[starts[cell]..starts[cell] + list.len()].copy_from_slice(list);
        }
        let mut rows = vec![0.0f64; total * d];
        // Blocks of FILL_ROWS padded rows in parallel, each filled column by column (a column's
        // reads stay within that column; the block's rows stay in cache), with the largest
        // magnitude (NaN when a value is not usable).
        let largest = rows
            .par_chunks_mut(FILL_ROWS * d)
            .zip(order.par_chunks(FILL_ROWS))
            .map(|(rows, order)| {
                let mut largest = 0.0f64;
                for c in 0..d {
                    let col = reference.col(c);
                    for (row, &j) in rows.chunks_exact_mut(d).zip(order) {
                        if j != usize::MAX {
                            let v = col[j];
                            row[c] = v;
                            let a = v.abs();
                            largest = if a > largest || a.is_nan() { a } else { largest };
                        }
                    }
                }
                largest
            })
            .reduce(|| 0.0, |a, b| if b > a || b.is_nan() { b } else { a });
        if largest.is_nan() || largest > crate::spatial::MAX_EMBEDDING {
            return Err(Error::invalid("embedding", "it contains a non-finite value or one beyond 1e30 in magnitude"));
        }
        let norms: Vec<f64> = rows
            .par_chunks(d)
            .zip(order.par_iter())
            .map(|(row, &j)| if j == usize::MAX { f64::INFINITY } else { row.iter().fold(0.0, |s, v| s + v * v) })
            .collect();
        let blocks = CellBlocks {
            order,
            starts,
            rows,
            norms,
            centres: Vec::new(),
            strips: Vec::new(),
            len: Vec::new(),
            norm: Vec::new(),
            bound: Vec::new(),
            reach: 0.0,
            d,
        };
        Ok((blocks, largest))
    }

    /// The cells' centres, the f32 strips of the centred rows and the screen's terms, in the
    /// screen's units `scale`. Centring makes the screen's bound scale with the rows' spread
    /// within a cell rather than their magnitude: where the rows carry a large common part
    /// (the bijective polish's rows hold ≈ ‖Ψ_j‖ in one coordinate), the uncentred bound exceeded
    /// the gaps between neighbouring rows and the screen kept nearly every row.
    fn screen_in(&mut self, scale: &crate::spatial::ScreenScale) {
        let d = self.d;
        let cells = self.starts.len() - 1;
        let mut centres = vec![0.0f64; cells * d];
        centres.par_chunks_mut(d).enumerate().for_each(|(cell, centre)| {
            let mut real = 0usize;
            for t in (self.starts[cell]..self.starts[cell + 1]).filter(|&t| self.order[t] != usize::MAX) {
                for (c, &v) in centre.iter_mut().zip(&self.rows[t * d..(t + 1) * d]) {
                    *c += v;
                }
                real += 1;
            }
            if real > 0 {
                centre.iter_mut().for_each(|c| *c /= real as f64);
            }
        });
        // Cells are whole strips (padded to ROW_TILE rows), so each strip has one centre.
        let cell_of_strip: Vec<usize> = (0..cells)
            .flat_map(|cell| std::iter::repeat_n(cell, (self.starts[cell + 1] - self.starts[cell]) / ROW_TILE))
            .collect();
        let mut strips = vec![0.0f32; self.rows.len()];
        let mut centred_sq = vec![f64::INFINITY; self.order.len()];
        strips
            .par_chunks_mut(ROW_TILE * d)
            .zip(self.rows.par_chunks(ROW_TILE * d))
            .zip(centred_sq.par_chunks_mut(ROW_TILE))
            .zip(cell_of_strip.par_iter())
            .for_each(|(((strip, rows), sq), &cell)| {
                let centre = &centres[cell * d..(cell + 1) * d];
                for (l, row) in rows.chunks_exact(d).enumerate() {
                    let mut s = 0.0;
                    for (c, (&v, &m)) in row.iter().zip(centre).enumerate() {
                        let t = v - m;
                        strip[c * ROW_TILE + l] = (scale.sigma * t) as f32;
                        s += t * t;
                    }
                    sq[l] = s;
                }
            });
        let terms: Vec<(f32, f32, f32)> = self
            .norms
            .iter()
            .zip(&centred_sq)
            .map(|(&sq, &c)| if sq.is_finite() { scale.reference(c, true) } else { (0.0, f32::MAX, 0.0) })
            .collect();
        self.reach = self.norms.iter().filter(|v| v.is_finite()).fold(0.0f64, |a, &b| a.max(b)).sqrt();
        self.centres = centres;
        self.strips = strips;
        self.len = terms.iter().map(|t| t.0).collect();
        self.norm = terms.iter().map(|t| t.1).collect();
        self.bound = terms.iter().map(|t| t.2).collect();
    }
}

/// One screen of [`nearest_neighbors_near_rows`]: the cell `cell` of Y against the query rows
/// `q` centred on the cell's centre c (q − c, scaled, f32, row-major, d values per row, padded
/// with zero rows to a multiple of [`QUERY_TILE`]); per real query κ = σ² ‖q − c‖² (`kappa`),
/// the bound's factor of σ ‖r − c‖ ([`crate::spatial::ScreenScale::query`] of ‖q − c‖²) and its
/// additive term ([`crate::spatial::ScreenScale::centred`]).
#[derive(Clone, Copy)]
struct Screen<'a> {
    y: &'a CellBlocks,
    cell: usize,
    q: &'a [f32],
    kappa: &'a [f32],
    factor: &'a [f32],
    extra: &'a [f32],
}

crate::linalg::at_vector_width! {
    /// [`screen_cells_generic`] at the CPU's vector width.
    fn screen_cells(screen: Screen, best_hi: &mut [f32], cands: &mut [Vec<(f32, usize)>]) = screen_cells_generic
}

/// The single-precision screen of the restricted search (as [`crate::spatial`]'s exact search
/// screens, with its bound in coordinates centred on the cell): for every query, the smallest
/// upper bound `best_hi` of its squared distance ‖q − r_j‖² = κ + ‖r_j − c‖² − 2 (q − c)·(r_j − c)
/// over the rows of the cells screened so far, and in `cands` (lower bound, padded row)
/// of every row whose lower bound does not exceed it (a superset of the rows that can be nearest;
/// the list is pruned as the upper bound falls). A register tile of [`QUERY_TILE`] queries ×
/// [`ROW_TILE`] rows is accumulated over all d columns, vectorized across the rows.
#[inline(always)]
fn screen_cells_generic(screen: Screen, best_hi: &mut [f32], cands: &mut [Vec<(f32, usize)>]) {
    let Screen { y, cell, q, kappa, factor, extra } = screen;
    let (d, qn) = (y.d, factor.len());
    for t0 in (y.starts[cell]..y.starts[cell + 1]).step_by(ROW_TILE) {
        // One strip of ROW_TILE rows × d (in L1 while every query passes over it).
        let strip = &y.strips[t0 * d..(t0 + ROW_TILE) * d];
        let rn: &[f32; ROW_TILE] = y.norm[t0..t0 + ROW_TILE].try_into().unwrap();
        let rl: &[f32; ROW_TILE] = y.len[t0..t0 + ROW_TILE].try_into().unwrap();
        let rb: &[f32; ROW_TILE] = y.bound[t0..t0 + ROW_TILE].try_into().unwrap();
        for g0 in (0..qn).step_by(QUERY_TILE) {
            let tile: [&[f32]; QUERY_TILE] = std::array::from_fn(|a| &q[(g0 + a) * d..(g0 + a + 1) * d]);
            let mut acc = [[0.0f32; ROW_TILE]; QUERY_TILE];
            for (c, col) in strip.chunks_exact(ROW_TILE).enumerate() {
                let col: &[f32; ROW_TILE] = col.try_into().unwrap();
                for (sums, row) in acc.iter_mut().zip(&tile) {
                    let qc = row[c];
                    for l in 0..ROW_TILE {
                        sums[l] += qc * col[l];
                    }
                }
            }
            for (a, dots) in acc.iter().enumerate().take(qn - g0) {
                let (i, sc, k, x) = (g0 + a, factor[g0 + a], kappa[g0 + a], extra[g0 + a]);
                // The bounds as `spatial`'s screen forms them (its error analysis covers
                // their rounding; κ's and the f64 check's in `x`); compare-and-select folds
                // (`minps`, `maxps`).
                let e: [f32; ROW_TILE] = std::array::from_fn(|l| (k + rn[l]) - 2.0 * dots[l]);
                let min = |m: f32, v: f32| if v < m { v } else { m };
                let hi = (0..ROW_TILE).map(|l| e[l] + sc * rl[l] + rb[l] + x).fold(f32::INFINITY, min);
                if hi < best_hi[i] {
                    best_hi[i] = hi;
                }
                let h = best_hi[i];
                let lo: [f32; ROW_TILE] = std::array::from_fn(|l| e[l] - sc * rl[l] - rb[l] - x);
                let margin = lo.iter().fold(f32::NEG_INFINITY, |m, &v| if h - v > m { h - v } else { m });
                if margin < 0.0 {
                    continue;
                }
                let list = &mut cands[i];
                for (l, &v) in lo.iter().enumerate() {
                    if v <= h {
                        list.push((v, t0 + l));
                    }
                }
                if list.len() >= 64 {
                    list.retain(|c| c.0 <= h);
                }
            }
        }
    }
}

/// The nearest of the screen's candidates `cands` (lower bound, padded row of `y`) that pass its
/// final upper bound `hi`, to the query row `q` (f64, d values): the vertex j minimizing ‖r_j‖² −
/// 2 q·r_j, the dot product summed over the columns in order, ties to the smallest vertex id —
/// the exact search's rule, so the result equals [`nearest_neighbors`] among the cells' rows.
/// Candidates are evaluated eight at a time (one lane each). `usize::MAX` when there are none.
fn check_candidates(y: &CellBlocks, q: &[f64], cands: &[(f32, usize)], hi: f32) -> usize {
    const LANES: usize = 8;
    let d = y.d;
    let kept: Vec<usize> = cands.iter().filter(|c| c.0 <= hi).map(|c| c.1).collect();
    let mut best = (f64::INFINITY, usize::MAX);
    for group in kept.chunks(LANES) {
        let mut dots = [0.0f64; LANES];
        let rows: [&[f64]; LANES] = std::array::from_fn(|l| {
            let t = group.get(l).copied().unwrap_or(group[0]);
            &y.rows[t * d..(t + 1) * d]
        });
        for (c, &qc) in q.iter().enumerate() {
            for l in 0..LANES {
                dots[l] += qc * rows[l][c];
            }
        }
        for (l, &t) in group.iter().enumerate() {
            let (dist, j) = (y.norms[t] - 2.0 * dots[l], y.order[t]);
            if dist < best.0 || (dist == best.0 && j < best.1) {
                best = (dist, j);
            }
        }
    }
    best.1
}

/// Point-to-point map X → Y of a functional map C (k_Y × k_X, coefficients on X → coefficients
/// on Y; square k × k in the paper) between the bases Φ (n × k') and Ψ (m × k'') with k_X ≤ k',
/// k_Y ≤ k'', as in the paper (§2): vertex i of X goes to the vertex j of Y whose row of
/// Ψ_{k_Y} C is nearest to row i of Φ_{k_X}. Returns `map_xy` (length n, vertices of Y).
pub fn map_from_fmap(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>) -> Result<Vec<usize>> {
    let (kx, ky) = check_fmap(phi, psi, c)?;
    let mut psi_c = Mat::<f64>::zeros(psi.nrows(), kx);
    matmul(psi_c.as_mut(), Accum::Replace, psi.subcols(0, ky), c, 1.0, Par::Seq);
    nearest_neighbors(psi_c.as_ref(), phi.subcols(0, kx))
}

/// Point-to-point map Y → X induced by a functional map C (k_Y × k_X, X → Y): vertex j of Y
/// goes to the vertex of X whose row of Φ_{k_X} Cᵀ is nearest to row j of Ψ_{k_Y} (the pull-back
/// direction, as used by ZoomOut; pyFM's `FM_to_p2p`). Returns `map_yx` (length m, vertices of
/// X).
pub fn map_yx_from_fmap(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>) -> Result<Vec<usize>> {
    let (kx, ky) = check_fmap(phi, psi, c)?;
    let mut phi_ct = Mat::<f64>::zeros(phi.nrows(), ky);
    matmul(phi_ct.as_mut(), Accum::Replace, phi.subcols(0, kx), c.transpose(), 1.0, Par::Seq);
    nearest_neighbors(phi_ct.as_ref(), psi.subcols(0, ky))
}

/// Point-to-point map Y → X by the adjoint of a functional map C (k_Y × k_X, X → Y): vertex j
/// of Y goes to the vertex of X whose row of Φ_{k_X} is nearest to row j of Ψ_{k_Y} C (the
/// deltas of Y carried to X's coefficients by Cᵀ; pyFM's `FM_to_p2p(use_adj=True)`). Returns
/// `map_yx` (length m, vertices of X).
pub fn map_yx_from_fmap_adjoint(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>) -> Result<Vec<usize>> {
    let (kx, ky) = check_fmap(phi, psi, c)?;
    let mut psi_c = Mat::<f64>::zeros(psi.nrows(), kx);
    matmul(psi_c.as_mut(), Accum::Replace, psi.subcols(0, ky), c, 1.0, Par::Seq);
    nearest_neighbors(phi.subcols(0, kx), psi_c.as_ref())
}

/// (k_X, k_Y) of a functional map C (k_Y × k_X) that fits the bases.
fn check_fmap(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>) -> Result<(usize, usize)> {
    let (ky, kx) = (c.nrows(), c.ncols());
    if kx == 0 || ky == 0 || kx > phi.ncols() || ky > psi.ncols() {
        return Err(Error::invalid(
            "C",
            format!(
                "a {}×{} map (k_Y × k_X) does not fit bases with {} (X) and {} (Y) columns",
                c.nrows(),
                c.ncols(),
                phi.ncols(),
                psi.ncols()
            ),
        ));
    }
    Ok((kx, ky))
}

/// The functional map C (k × k, X → Y) of the pull-back by a point-to-point map Y → X
/// (`map_yx`, length m): C = Ψ_kᵀ A_Y Φ_k(map_yx), the coefficients on Y of f ∘ map_yx for the
/// basis functions f of X. `mass_y` is A_Y (length m).
pub fn fmap_from_map_yx(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    mass_y: &[f64],
    map_yx: &[usize],
    k: usize,
) -> Result<Mat<f64>> {
    fmap_from_map_yx_sizes(phi, psi, mass_y, map_yx, k, k)
}

/// [`fmap_from_map_yx`] with k_X basis functions on X and k_Y on Y: C = Ψ_{k_Y}ᵀ A_Y
/// Φ_{k_X}(map_yx), k_Y × k_X (pyFM's `p2p_to_FM`).
pub fn fmap_from_map_yx_sizes(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    mass_y: &[f64],
    map_yx: &[usize],
    kx: usize,
    ky: usize,
) -> Result<Mat<f64>> {
    let (n, m) = (phi.nrows(), psi.nrows());
    if map_yx.len() != m || mass_y.len() != m {
        return Err(Error::invalid(
            "map",
            format!("{} map entries and {} weights for {m} vertices of Y", map_yx.len(), mass_y.len()),
        ));
    }
    if kx == 0 || ky == 0 || kx > phi.ncols() || ky > psi.ncols() {
        let got = if kx == ky { format!("{kx}") } else { format!("({kx}, {ky})") };
        return Err(Error::invalid("k", format!("need 1 ≤ k ≤ {} and {}, got {got}", phi.ncols(), psi.ncols())));
    }
    if let Some(&bad) = map_yx.iter().find(|&&i| i >= n) {
        return Err(Error::invalid("map", format!("vertex {bad} of X does not exist (n = {n})")));
    }
    let a_psi = Mat::from_fn(m, ky, |j, i| mass_y[j] * psi[(j, i)]);
    let phi_map = Mat::from_fn(m, kx, |j, i| phi[(map_yx[j], i)]);
    let mut c = Mat::<f64>::zeros(ky, kx);
    matmul(c.as_mut(), Accum::Replace, a_psi.transpose(), phi_map.as_ref(), 1.0, Par::Seq);
    Ok(c)
}

/// The soft map of vertex i of X (paper Figures 5, 6): the column T δ_i = Ψ_{k_Y} C Φ_{k_X}(i)ᵀ
/// (length m) of the correspondence kernel of a functional map C (k_Y × k_X, between
/// mass-orthonormal bases), a function on Y that is ideally concentrated at the image of x_i
/// (density, in units of 1 / area of Y).
pub fn soft_map_column(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>, i: usize) -> Result<Vec<f64>> {
    let (kx, ky) = check_fmap(phi, psi, c)?;
    if i >= phi.nrows() {
        return Err(Error::invalid("vertex", format!("vertex {i} of X does not exist (n = {})", phi.nrows())));
    }
    let coeff: Vec<f64> = (0..ky).map(|a| (0..kx).map(|b| c[(a, b)] * phi[(i, b)]).sum()).collect();
    Ok((0..psi.nrows()).map(|j| (0..ky).map(|a| psi[(j, a)] * coeff[a]).sum()).collect())
}

/// Options of [`icp`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IcpOptions {
    /// Maximum number of iterations.
    pub max_iterations: usize,
}

impl Default for IcpOptions {
    fn default() -> Self {
        IcpOptions { max_iterations: 50 }
    }
}

/// The ICP-like refinement of Ovsjanikov et al. 2012 (paper §2): alternate the point-wise map
/// (nearest rows of Ψ_k C for the rows of Φ_k) and the orthonormal C minimizing
/// ‖Φ_k − Ψ_k(map) C‖ (orthogonal Procrustes: C = U Vᵀ from the SVD of Ψ_k(map)ᵀ Φ_k), until
/// the map stops changing. Returns the refined C (k × k) and `map_xy` (length n). A rectangular
/// C (k_Y × k_X) is refined the same way, C = U Vᵀ from the thin SVD (orthonormal columns or
/// rows).
pub fn icp(phi: MatRef<f64>, psi: MatRef<f64>, c0: MatRef<f64>, opts: &IcpOptions) -> Result<(Mat<f64>, Vec<usize>)> {
    let (kx, ky) = check_fmap(phi, psi, c0)?;
    let (phi, psi) = (phi.subcols(0, kx), psi.subcols(0, ky));
    let mut c = c0.to_owned();
    let mut map = map_from_fmap(phi, psi, c.as_ref())?;
    for _ in 0..opts.max_iterations {
        let mut m = Mat::<f64>::zeros(ky, kx);
        let psi_map = Mat::from_fn(phi.nrows(), ky, |i, j| psi[(map[i], j)]);
        matmul(m.as_mut(), Accum::Replace, psi_map.transpose(), phi, 1.0, Par::Seq);
        if kx == ky {
            let svd = m.svd().map_err(|e| Error::numerical("icp", format!("SVD failed: {e:?}")))?;
            matmul(c.as_mut(), Accum::Replace, svd.U(), svd.V().transpose(), 1.0, Par::Seq);
        } else {
            let svd = m.thin_svd().map_err(|e| Error::numerical("icp", format!("SVD failed: {e:?}")))?;
            matmul(c.as_mut(), Accum::Replace, svd.U(), svd.V().transpose(), 1.0, Par::Seq);
        }
        let next = map_from_fmap(phi, psi, c.as_ref())?;
        let changed = next != map;
        map = next;
        if !changed {
            break;
        }
    }
    Ok((c, map))
}

/// Options of [`zoomout`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ZoomOutOptions {
    /// Final size K of the functional map.
    pub k_final: usize,
    /// Size increment per iteration.
    pub step: usize,
}

/// ZoomOut (Melzi et al. 2019): spectral upsampling of a k × k functional map (X → Y) to
/// K × K in steps: at each size k, the point-wise map Y → X of the current C gives the next
/// C = Ψ_{k+s}ᵀ A_Y Φ_{k+s}(map_yx) ((k+s) × (k+s)). `mass_y` is A_Y (length m). Returns the
/// final C (K × K) and `map_xy` (length n) from it.
pub fn zoomout(
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    mass_y: &[f64],
    c0: MatRef<f64>,
    opts: &ZoomOutOptions,
) -> Result<(Mat<f64>, Vec<usize>)> {
    let (k0, ky0) = check_fmap(phi, psi, c0)?;
    if ky0 != k0 {
        return Err(Error::invalid("C", format!("ZoomOut starts from a square map, got {ky0} × {k0}")));
    }
    let kf = opts.k_final;
    if kf < k0 || kf > phi.ncols() || kf > psi.ncols() || opts.step == 0 {
        return Err(Error::invalid(
            "zoomout",
            format!(
                "need {k0} ≤ K ≤ basis sizes ({}, {}) and step ≥ 1, got K = {kf}, step {}",
                phi.ncols(),
                psi.ncols(),
                opts.step
            ),
        ));
    }
    if mass_y.len() != psi.nrows() {
        return Err(Error::invalid("mass", format!("{} weights for {} vertices of Y", mass_y.len(), psi.nrows())));
    }
    let mut c = c0.to_owned();
    let mut k = k0;
    while k < kf {
        let map_yx = map_yx_from_fmap(phi, psi, c.as_ref())?;
        k = (k + opts.step).min(kf);
        c = fmap_from_map_yx(phi, psi, mass_y, &map_yx, k)?;
    }
    let map = map_from_fmap(phi, psi, c.as_ref())?;
    Ok((c, map))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::spectral::Normal;

    #[test]
    fn nearest_neighbors_match_brute_force() {
        let mut rng = Normal::new(7);
        // The nearest row of r for every row of q, by brute force against `nearest_neighbors`.
        let check_nearest = |r: &Mat<f64>, q: &Mat<f64>| {
            let got = nearest_neighbors(r.as_ref(), q.as_ref()).unwrap();
            for i in 0..q.nrows() {
                let dist = |j: usize| (0..r.ncols()).map(|c| (q[(i, c)] - r[(j, c)]).powi(2)).sum::<f64>();
                let want = (0..r.nrows()).min_by(|&a, &b| dist(a).total_cmp(&dist(b))).unwrap();
                assert_eq!(got[i], want, "query {i}");
            }
        };
        let (m, n, d) = (700, 600, 13);
        let r = Mat::from_fn(m, d, |_, _| rng.sample());
        let q = Mat::from_fn(n, d, |_, _| rng.sample());
        check_nearest(&r, &q);
        let mip = max_inner_product(r.as_ref(), q.as_ref()).unwrap();
        for i in 0..n {
            let dot = |j: usize| (0..d).map(|c| q[(i, c)] * r[(j, c)]).sum::<f64>();
            let want = (0..m).max_by(|&a, &b| dot(a).total_cmp(&dot(b)).then(b.cmp(&a))).unwrap();
            assert_eq!(mip[i], want, "query {i}");
        }
        // A point of the reference set finds itself.
        let self_map = nearest_neighbors(r.as_ref(), r.as_ref()).unwrap();
        assert!(self_map.iter().enumerate().all(|(i, &j)| i == j));
        // Several reference chunks and query blocks, sizes not multiples of the lanes.
        let (m, n, d) = (4_501, 263, 5);
        let r = Mat::from_fn(m, d, |_, _| rng.sample());
        let q = Mat::from_fn(n, d, |_, _| rng.sample());
        check_nearest(&r, &q);
    }

    #[test]
    fn the_single_precision_screen_keeps_the_double_precision_answer() {
        // Rows that single precision cannot tell apart: r_j = base + δ_j with |δ_j| ~ 1e-10
        // relative, far from the origin (‖r‖² ≫ the distances), exact duplicates (ties go to
        // the smallest index), and a wide dimension (d = 300, the largest bound).
        let mut rng = Normal::new(11);
        for &(m, n, d, spread, offset) in &[(500, 300, 8, 1e-9, 1e3), (300, 200, 300, 1e-7, 0.0), (64, 64, 3, 1.0, 1e6)]
        {
            let base: Vec<f64> = (0..d).map(|_| rng.sample()).collect();
            let mut r = Mat::from_fn(m, d, |_, c| offset + base[c] + spread * rng.sample());
            for c in 0..d {
                r[(m - 1, c)] = r[(m / 2, c)]; // a duplicate: the smaller index must win
            }
            let q = Mat::from_fn(
                n,
                d,
                |i, c| {
                    if i == 0 {
                        r[(m / 2, c)]
                    } else {
                        offset + base[c] + spread * rng.sample()
                    }
                },
            );
            let dist = |i: usize, j: usize| {
                let dot: f64 = (0..d).map(|c| q[(i, c)] * r[(j, c)]).sum();
                (0..d).map(|c| r[(j, c)].powi(2)).sum::<f64>() - 2.0 * dot
            };
            let got = nearest_neighbors(r.as_ref(), q.as_ref()).unwrap();
            for (i, &g) in got.iter().enumerate() {
                let want = (0..m).min_by(|&a, &b| dist(i, a).total_cmp(&dist(i, b)).then(a.cmp(&b))).unwrap();
                assert_eq!(g, want, "m {m} d {d}: query {i}");
            }
            // (Query 0 is a copy of row m/2, but far from the origin the f64 formula itself
            // cannot separate rows 1e-9 apart; the brute force above uses the same formula.)
            assert!(!got.contains(&(m - 1)), "the duplicate's larger index never wins");
            let mip = max_inner_product(r.as_ref(), q.as_ref()).unwrap();
            for (i, &g) in mip.iter().enumerate() {
                let dot = |j: usize| (0..d).map(|c| q[(i, c)] * r[(j, c)]).sum::<f64>();
                let want = (0..m).max_by(|&a, &b| dot(a).total_cmp(&dot(b)).then(b.cmp(&a))).unwrap();
                assert_eq!(g, want, "mip m {m} d {d}: query {i}");
            }
        }
        // Values single precision cannot hold are an error, not a wrong answer.
        let huge = Mat::from_fn(4, 2, |i, _| if i == 0 { 1e300 } else { 1.0 });
        let e = nearest_neighbors(huge.as_ref(), huge.as_ref()).unwrap_err().to_string();
        assert!(e.contains("1e30"), "{e}");
    }

    #[test]
    fn identity_map_of_a_permuted_embedding() {
        let mut rng = Normal::new(3);
        let (n, k) = (500, 10);
        let phi = Mat::from_fn(n, k, |_, _| rng.sample());
        let perm: Vec<usize> = (0..n).map(|i| (i * 211 + 5) % n).collect(); // row i of Ψ is row perm[i] of Φ
        let psi = Mat::from_fn(n, k, |i, j| phi[(perm[i], j)]);
        let c = Mat::<f64>::identity(k, k);
        let map = map_from_fmap(phi.as_ref(), psi.as_ref(), c.as_ref()).unwrap();
        for (i, &p) in perm.iter().enumerate() {
            assert_eq!(map[p], i);
        }
        let back = map_yx_from_fmap(phi.as_ref(), psi.as_ref(), c.as_ref()).unwrap();
        assert_eq!(back, perm);
        assert_eq!(map_yx_from_fmap_adjoint(phi.as_ref(), psi.as_ref(), c.as_ref()).unwrap(), perm);
        // Rectangular maps (k_Y × k_X): Ψ has 3 more columns than C reads; C = [I 0]ᵀ-like
        // blocks keep the first k_X coordinates, so the maps are those of the square case.
        let psi_wide = Mat::from_fn(n, k + 3, |i, j| if j < k { psi[(i, j)] } else { rng.sample() });
        let tall = Mat::from_fn(k + 3, k, |i, j| if i == j { 1.0 } else { 0.0 });
        let map_t = map_from_fmap(phi.as_ref(), psi_wide.as_ref(), tall.as_ref()).unwrap();
        assert_eq!(map_t, map);
        let adj = map_yx_from_fmap_adjoint(phi.as_ref(), psi_wide.as_ref(), tall.as_ref()).unwrap();
        assert_eq!(adj, perm);
        let c_back = fmap_from_map_yx_sizes(phi.as_ref(), psi_wide.as_ref(), &vec![1.0; n], &back, k, k + 3).unwrap();
        assert_eq!((c_back.nrows(), c_back.ncols()), (k + 3, k));
        let (c_icp, map_icp) = icp(phi.as_ref(), psi_wide.as_ref(), tall.as_ref(), &IcpOptions::default()).unwrap();
        assert_eq!((c_icp.nrows(), c_icp.ncols()), (k + 3, k));
        assert_eq!(map_icp, map);
    }

    /// A random k × k orthonormal matrix (Q of a QR factorization).
    fn orthonormal(k: usize, rng: &mut Normal) -> Mat<f64> {
        let m = Mat::from_fn(k, k, |_, _| rng.sample());
        m.qr().compute_thin_Q()
    }

    #[test]
    fn icp_recovers_a_known_orthonormal_map() {
        let mut rng = Normal::new(11);
        let (n, k) = (400, 8);
        let phi = Mat::from_fn(n, k, |_, _| rng.sample());
        let c_true = orthonormal(k, &mut rng);
        // Row perm[i] of Ψ is row i of Φ Cᵀ, so that Ψ[perm] C = Φ.
        let perm: Vec<usize> = (0..n).map(|i| (i * 37 + 11) % n).collect();
        let mut psi = Mat::<f64>::zeros(n, k);
        for i in 0..n {
            for a in 0..k {
                psi[(perm[i], a)] = (0..k).map(|b| phi[(i, b)] * c_true[(a, b)]).sum();
            }
        }
        let c0 = Mat::from_fn(k, k, |a, b| c_true[(a, b)] + 0.15 * rng.sample());
        let (c, map) = icp(phi.as_ref(), psi.as_ref(), c0.as_ref(), &IcpOptions::default()).unwrap();
        assert_eq!(map, perm);
        assert!((&c - &c_true).norm_max() < 1e-10, "C error {}", (&c - &c_true).norm_max());
    }

    #[test]
    fn zoomout_recovers_the_permutation_of_a_mesh() {
        use crate::laplacian::cotangent;
        use crate::primitives::icosphere;
        use crate::shape::TriMesh;
        use crate::spectral::{eigen_basis, SpectralOptions};
        // A bumpy (asymmetric) sphere and a vertex-permuted copy.
        let s = icosphere(3);
        let bump = |p: [f64; 3]| {
            let r = 1.0 + 0.15 * (3.0 * p[0] + 1.0).sin() * (2.0 * p[1] + 0.3).cos() + 0.1 * p[2].powi(3);
            [1.3 * r * p[0], r * p[1], 0.9 * r * p[2]]
        };
        let n = s.n_vertices();
        let x = TriMesh::new(s.vertices().iter().map(|&p| bump(p)).collect(), s.faces().to_vec()).unwrap();
        let perm: Vec<usize> = (0..n).map(|i| (i * 101 + 7) % n).collect(); // Y vertex perm[i] = X vertex i
        let mut yv = vec![[0.0; 3]; n];
        for i in 0..n {
            yv[perm[i]] = x.vertices()[i];
        }
        let yf = x
            .faces()
            .iter()
            .map(|f| [perm[f[0] as usize] as u32, perm[f[1] as usize] as u32, perm[f[2] as usize] as u32])
            .collect();
        let y = TriMesh::new(yv, yf).unwrap();
        let basis = |m: &TriMesh| eigen_basis(&cotangent(m).unwrap(), &SpectralOptions::new(40), None).unwrap().0;
        let (bx, by) = (basis(&x), basis(&y));
        // The true map as a functional map, truncated to 4 × 4 as a coarse start.
        let full = Mat::from_fn(40, 40, |a, b| {
            (0..n).map(|i| by.mass[perm[i]] * by.eigenvectors[(perm[i], a)] * bx.eigenvectors[(i, b)]).sum::<f64>()
        });
        let c0 = full.submatrix(0, 0, 4, 4).to_owned();
        let opts = ZoomOutOptions { k_final: 40, step: 2 };
        let (c, map) =
            zoomout(bx.eigenvectors.as_ref(), by.eigenvectors.as_ref(), &by.mass, c0.as_ref(), &opts).unwrap();
        assert_eq!((c.nrows(), c.ncols()), (40, 40));
        assert_eq!(map, perm, "ZoomOut must recover the permutation exactly");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let a = Mat::<f64>::zeros(5, 3);
        let b = Mat::<f64>::zeros(5, 4);
        assert!(nearest_neighbors(a.as_ref(), b.as_ref()).is_err());
        assert!(nearest_neighbors(Mat::<f64>::zeros(0, 3).as_ref(), a.as_ref()).is_err());
        let nan = Mat::from_fn(5, 3, |_, _| f64::NAN);
        assert!(nearest_neighbors(a.as_ref(), nan.as_ref()).is_err());
        assert!(map_from_fmap(a.as_ref(), a.as_ref(), Mat::<f64>::identity(4, 4).as_ref()).is_err());
        let i2 = Mat::<f64>::identity(2, 2);
        let bad = ZoomOutOptions { k_final: 5, step: 1 };
        assert!(zoomout(a.as_ref(), a.as_ref(), &[1.0; 5], i2.as_ref(), &bad).is_err());
        let ok = ZoomOutOptions { k_final: 3, step: 1 };
        assert!(zoomout(a.as_ref(), a.as_ref(), &[1.0; 4], i2.as_ref(), &ok).is_err());
    }

    /// With every cell of Y searched, the restricted search is the exact one, ties included:
    /// coarse integer embeddings (many equal distances) in dimensions that leave partial
    /// register tiles (1, 7, 33 columns; cells of every size; query groups not a multiple of 4).
    #[test]
    fn restricted_search_with_every_cell_is_the_exact_search_ties_included() {
        let x = crate::primitives::icosphere(2);
        let p = x.vertices().to_vec();
        let n = p.len();
        let mut rng = crate::rng::Normal::new(3);
        for d in [1, 7, 33] {
            let mut coarse_value = || (rng.sample() * 1.5).round();
            let reference = Mat::from_fn(n, d, |_, _| coarse_value());
            let query = Mat::from_fn(n, d, |_, _| coarse_value());
            let exact = nearest_neighbors(reference.as_ref(), query.as_ref()).unwrap();
            let mass = vec![1.0; n];
            let sx = crate::spatial::farthest_point_samples(&p, &mass, 13).unwrap().vertices;
            let sy = crate::spatial::farthest_point_samples(&p, &mass, 11).unwrap().vertices;
            let images: Vec<usize> = sx.iter().map(|&s| (s * 5) % n).collect();
            let coarse = CoarseMap { x: &p, y: &p, samples: &sx, images: &images, y_cells: &sy };
            let near = nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, sy.len()).unwrap();
            assert_eq!(near, exact, "d = {d}");
        }
        // A non-finite embedding value is an error, as in the exact search.
        let mut reference = Mat::from_fn(n, 3, |i, c| p[i][c]);
        reference[(5, 1)] = f64::NAN;
        let mass = vec![1.0; n];
        let s = crate::spatial::farthest_point_samples(&p, &mass, 10).unwrap().vertices;
        let coarse = CoarseMap { x: &p, y: &p, samples: &s, images: &s, y_cells: &s };
        let query = Mat::from_fn(n, 3, |i, c| p[i][c]);
        assert!(nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, 4).is_err());
    }

    /// The restricted searches' test case: a mesh X, a renumbered copy Y (Y vertex j is X vertex
    /// (7919 j + 11) mod n), the true map X → Y, and 6-D embeddings of both (the positions and
    /// their pairwise products; Y's with Gaussian noise of standard deviation `noise`, seed 5).
    /// Returns (X's positions, Y's positions, the true map, query n × 6, reference n × 6).
    #[allow(clippy::type_complexity)]
    pub(crate) fn renumbered_embeddings(
        x: &crate::shape::TriMesh,
        noise: f64,
    ) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<usize>, Mat<f64>, Mat<f64>) {
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919 + 11) % n).collect();
        let mut truth = vec![0usize; n];
        for (j, &i) in perm.iter().enumerate() {
            truth[i] = j;
        }
        let px = x.vertices().to_vec();
        let py: Vec<[f64; 3]> = perm.iter().map(|&i| px[i]).collect();
        let features = |p: &[f64; 3]| [p[0], p[1], p[2], p[0] * p[1], p[1] * p[2], p[2] * p[0]];
        let mut rng = crate::rng::Normal::new(5);
        let query = Mat::from_fn(n, 6, |i, c| features(&px[i])[c]);
        let reference = Mat::from_fn(n, 6, |j, c| features(&py[j])[c] + noise * rng.sample());
        (px, py, truth, query, reference)
    }

    /// A query with fewer columns than the reference is searched as if its missing columns were
    /// zero; one with more is an error.
    #[test]
    fn restricted_query_columns_beyond_its_own_are_zero() {
        let (m, n, d) = (200, 90, 5);
        let mut rng = crate::spectral::Normal::new(4);
        let r = Mat::from_fn(m, d, |_, _| rng.sample());
        let q = Mat::from_fn(n, d, |_, c| if c + 1 < d { rng.sample() } else { 0.0 });
        let mut pos = |count: usize| -> Vec<[f64; 3]> {
            (0..count).map(|_| [rng.sample(), rng.sample(), rng.sample()]).collect()
        };
        let (px, py) = (pos(n), pos(m));
        let samples: Vec<usize> = (0..n).step_by(9).collect();
        let images: Vec<usize> = samples.iter().map(|&s| (s * 3) % m).collect();
        let y_cells: Vec<usize> = (0..m).step_by(11).collect();
        let coarse = CoarseMap { x: &px, y: &py, samples: &samples, images: &images, y_cells: &y_cells };
        let all: Vec<usize> = (0..n).collect();
        let full = nearest_neighbors_near_rows(r.as_ref(), q.as_ref(), &coarse, 3, &all).unwrap();
        let short = nearest_neighbors_near_rows(r.as_ref(), q.as_ref().subcols(0, d - 1), &coarse, 3, &all).unwrap();
        assert_eq!(short, full);
        assert!(nearest_neighbors_near_rows(r.as_ref().subcols(0, d - 1), q.as_ref(), &coarse, 3, &all).is_err());
    }

    /// The search near a coarse map equals the exact search when the coarse map is right (a
    /// 2562-vertex sphere and a renumbered copy, 6-D embeddings with noise, 100 samples, 8
    /// cells), and differs from it when the coarse map is wrong (so the restriction is real).
    /// The restricted search's single-precision screen keeps the exact f64 argmin (ties to the
    /// smallest vertex id) at every magnitude and vector width: with cells covering all of Y it
    /// equals the brute-force search written out, on queries in tight clusters of rows (many
    /// candidates to tell apart), exact copies of rows and a tie.
    #[test]
    fn restricted_screen_keeps_the_exact_argmin_at_every_magnitude() {
        let (m, n, d) = (300, 120, 20);
        let mut rng = crate::spectral::Normal::new(9);
        // Rows in 30 tight clusters of 10 (within 1e-3 of their centre, ‖r‖² ≈ 20): the
        // distances of a query to its cluster's rows differ by about 1e-6 relative, below what
        // single precision tells apart, so the screen keeps several candidates per query.
        let centres = Mat::from_fn(30, d, |_, _| rng.sample());
        let mut r0 = Mat::from_fn(m, d, |j, c| centres[(j / 10, c)] + 1e-3 * rng.sample());
        for c in 0..d {
            r0[(140, c)] = r0[(250, c)]; // a tie for query 20 (= row 140): row 140 must win
        }
        let q0 = Mat::from_fn(n, d, |i, c| {
            if i % 5 == 0 {
                r0[((i * 7) % m, c)]
            } else {
                centres[((i * 7) % m / 10, c)] + 1e-3 * rng.sample()
            }
        });
        let pos = |count: usize, seed: u64| -> Vec<[f64; 3]> {
            let mut g = crate::spectral::Normal::new(seed);
            (0..count).map(|_| [g.sample(), g.sample(), g.sample()]).collect()
        };
        let (px, py) = (pos(n, 1), pos(m, 2));
        let samples: Vec<usize> = (0..n).step_by(10).collect();
        let images: Vec<usize> = samples.iter().map(|&s| (s * 7) % m).collect();
        let y_cells: Vec<usize> = (0..m).step_by(13).collect();
        let coarse = CoarseMap { x: &px, y: &py, samples: &samples, images: &images, y_cells: &y_cells };
        let all: Vec<usize> = (0..n).collect();
        // A large part common to every row and query (offset): the bijective polish's rows carry
        // ≈ ‖Ψ_j‖ in one coordinate; the screen in centred coordinates must still keep the f64
        // argmin of the uncentred ‖r‖² − 2 q·r.
        for (magnitude, offset) in
            [(1e-30, 0.0), (1e-3, 0.0), (1.0, 0.0), (1.0, 1e4), (1e20, 0.0), (1e20, 300.0), (1e29, 0.0)]
        {
            let shift = |a: &Mat<f64>| {
                Mat::from_fn(a.nrows(), d, |i, c| magnitude * (a[(i, c)] + if c == 0 { offset } else { 0.0 }))
            };
            let (r, q) = (shift(&r0), shift(&q0));
            let brute: Vec<usize> = (0..n)
                .map(|i| {
                    let mut best = (f64::INFINITY, usize::MAX);
                    for j in 0..m {
                        let rn = (0..d).fold(0.0, |s, c| s + r[(j, c)] * r[(j, c)]);
                        let dot = (0..d).fold(0.0, |s, c| s + q[(i, c)] * r[(j, c)]);
                        if rn - 2.0 * dot < best.0 {
                            best = (rn - 2.0 * dot, j);
                        }
                    }
                    best.1
                })
                .collect();
            assert_eq!(brute[20], 140, "the tie");
            for widest in 0..=2u8 {
                let near = crate::linalg::with_widest(widest, || {
                    nearest_neighbors_near_rows(r.as_ref(), q.as_ref(), &coarse, y_cells.len(), &all).unwrap()
                });
                assert_eq!(near, brute, "magnitude {magnitude}, offset {offset}, width {widest}");
            }
        }
    }

    #[test]
    fn search_near_a_coarse_map_equals_the_exact_search() {
        let x = crate::primitives::bumpy_sphere(4);
        let n = x.n_vertices();
        let (px, py, truth, query, reference) = renumbered_embeddings(&x, 0.02);
        let exact = nearest_neighbors(reference.as_ref(), query.as_ref()).unwrap();
        let mass = vec![1.0; n];
        let sx = crate::spatial::farthest_point_samples(&px, &mass, 100).unwrap().vertices;
        let sy = crate::spatial::farthest_point_samples(&py, &mass, 100).unwrap().vertices;
        let images: Vec<usize> = sx.iter().map(|&s| truth[s]).collect();
        let coarse = CoarseMap { x: &px, y: &py, samples: &sx, images: &images, y_cells: &sy };
        let near = nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, 8).unwrap();
        let agree = |a: &[usize], b: &[usize]| a.iter().zip(b).filter(|(p, q)| p == q).count();
        assert_eq!(agree(&near, &exact), n);
        assert!(agree(&exact, &truth) < n, "the noise makes the exact map differ from the truth somewhere");
        // Some rows only, in any order and with repeats: the same images.
        let rows = [n - 1, 0, 17, 17, n / 2];
        let part = nearest_neighbors_near_rows(reference.as_ref(), query.as_ref(), &coarse, 8, &rows).unwrap();
        assert_eq!(part, rows.iter().map(|&i| exact[i]).collect::<Vec<_>>());
        assert!(nearest_neighbors_near_rows(reference.as_ref(), query.as_ref(), &coarse, 8, &[n]).is_err());
        // A wrong coarse map (every sample sent to the image of another) confines the search
        // to the wrong places.
        let wrong: Vec<usize> = (0..sx.len()).map(|s| images[(s + sx.len() / 2) % sx.len()]).collect();
        let coarse = CoarseMap { images: &wrong, ..coarse };
        let off = nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, 8).unwrap();
        assert!(agree(&off, &exact) < n / 2, "{}", agree(&off, &exact));
        // Bad input.
        assert!(nearest_neighbors_near(reference.as_ref(), query.as_ref(), &coarse, 0).is_err());
        let short = CoarseMap { images: &wrong[1..], ..coarse };
        assert!(nearest_neighbors_near(reference.as_ref(), query.as_ref(), &short, 8).is_err());
    }
}
