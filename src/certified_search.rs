//! Provably exact nearest rows on large pairs: the answer of a restricted search (e.g.
//! [`crate::pointwise::nearest_neighbors_near_rows`], which reads a few cells of Y around each
//! query's expected image) checked against every reference row without reading most of them, and
//! corrected where a nearer row exists. The result is the exact search's
//! ([`crate::spatial::nearest_rows`]: nearest in f64, ties to the smallest index), whatever the
//! restricted answer was; a good answer only makes the check cheap.
//!
//! **The bound.** The reference rows (the embedding of Y, m × d) are split into cells by their
//! vertices' positions: a k-d tree of median splits, leaves of at most [`LEAF_ROWS`] rows, every
//! log2([`FANOUT`])-th level kept. Each cell C gets an affine subspace that its rows nearly lie
//! in: every row r of C is r = e_C + U_C t + η with e_C the cell's mean, U_C (d × p, orthonormal
//! columns, p ≤ [`SUBSPACE`]), t = U_Cᵀ(r − e_C) inside the box [lo_C, hi_C] ⊂ Rᵖ, and η ⊥
//! span(U_C) with ‖η‖ ≤ ε_C (cells of more than [`SUBSPACE_ROWS`] rows: p = 0, a ball). Since
//! ‖q − r‖² = ‖U_Cᵀ(q − e_C) − t‖² + ‖P⊥(q − e_C) − η‖² for any query q,
//!
//! ```text
//! min over r in C of ‖q − r‖  ≥  LB(q, C) = sqrt( dist(U_Cᵀ(q − e_C), box_C)² + max(0, ‖P⊥(q − e_C)‖ − ε_C)² ).
//! ```
//!
//! A cell with LB(q, C) above the distance from q to its current answer (plus a rounding slack)
//! holds no nearer row. Queries go in groups of neighbouring vertices (k-d leaves of at most
//! [`GROUP_ROWS`]): a group first reads the leaves that hold its answers (a neighbour's answer
//! tightens a wrong one's threshold), then descends the tree and reads every leaf that some query
//! cannot rule out. At each run of children the group's centre c is bounded first: LB(·, C) is
//! the distance to a set, so LB(q, C) ≥ LB(c, C) − ‖q − c‖, and a cell with LB(c, C) above
//! max over the group of ‖q − c‖ + threshold(q) is out for every query at the cost of one; the
//! cells left are bounded for every query in one product. The rows read, with the answers, are
//! searched exactly.
//!
//! **Layout.** The reference rows are put in the tree's order in place for the duration of the
//! call, so that every cell is a block of consecutive rows: the cells' statistics and the exact
//! searches read the embedding in streams, without copies.
//!
//! **Why a subspace and not a ball.** A cell's rows are a patch of a smooth surface embedded in
//! R^d; a handful of directions (the patch's tangent plane and curvature) hold it to a tiny
//! fraction of its radius. The ball bound ‖q − e_C‖ − R_C is loose by about R_C in every
//! direction, and the rows within that slack of a query fill a surface patch of fixed area: it
//! leaves 7–14 % of Y to read per query on david0 → david1 (52k vertices, k = 128), the subspace
//! bound with p = 8 about 0.3–0.4 % per query (0.5–0.8 % per group of 32; EXPERIMENTS.md, "A
//! provably exact final map").
//!
//! Costs: the cells' subspaces O(m · d · p) per kept level (randomized range finder, seeded:
//! deterministic), the bounds O(p · d) per query and cell visited, the exact search of the rows
//! read O(|G| · rows read · d) per group, one product per run of consecutive rows. Memory: the
//! cells' subspaces, about (p + 1) / [`LEAF_ROWS`] of the embedding (≈ 0.3 m · d values), four
//! integers or floats per reference row, and one group's products at a time. At 52k vertices
//! (d = 129) a map takes about 0.5 s; at 840k about 11 s (EXPERIMENTS.md, "The certificate at
//! 840k").

use std::ops::Range;

use faer::linalg::matmul::matmul;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Reference rows per leaf cell (about; grid samples of the positions).
pub const LEAF_ROWS: usize = 32;

/// Query rows per group (about).
pub const GROUP_ROWS: usize = 32;

/// Children per node of the cell hierarchy (a power of two: every log2(FANOUT)-th level of the
/// k-d tree is kept).
pub const FANOUT: usize = 8;

/// Largest dimension p of a cell's subspace.
pub const SUBSPACE: usize = 8;

/// Largest dimension p of a leaf's subspace (leaves hold about [`LEAF_ROWS`] rows; 6 read as
/// few rows as 8 at 840k vertices and hold 22 % less memory, EXPERIMENTS.md).
pub const LEAF_SUBSPACE: usize = 6;

/// Cells with more rows than this are bounded by a ball (their rows are not copied).
pub const SUBSPACE_ROWS: usize = 16384;

/// Extra columns of the randomized range sketch of a cell's subspace.
const SUBSPACE_OVERSAMPLE: usize = 6;

/// What [`certify_nearest_rows`] read and changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Certificate {
    /// Query rows checked.
    pub queries: usize,
    /// Reference rows m.
    pub references: usize,
    /// Σ over query groups of |G| × (rows searched exactly for G): the exact search's n · m
    /// would read every row for every query.
    pub rows_read: u64,
    /// Cells bounded, summed over the query groups (each bound covers the group's queries).
    pub cells_bounded: u64,
    /// Queries whose answer changed (a nearer row, or a tie at a smaller index, outside the
    /// restricted search).
    pub changed: usize,
}

impl Certificate {
    /// Rows read per query as a share of m (1 for the exact search).
    pub fn share_read(&self) -> f64 {
        if self.queries == 0 || self.references == 0 {
            return 0.0;
        }
        self.rows_read as f64 / (self.queries as f64 * self.references as f64)
    }
}

/// One cell of the hierarchy: its box, residual radius and where its mean and basis rows are.
struct Cell {
    /// The first of its columns in its level's `stack`: e_C, then the p columns of U_C.
    at: usize,
    /// The box [lo, hi] of t = U_Cᵀ(r − e_C) over the cell's rows (p each).
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// ε_C: the largest ‖P⊥(r − e_C)‖, rounded up.
    eps: f64,
    /// ‖e_C‖² and U_Cᵀ e_C (p).
    mean_sq: f64,
    basis_mean: Vec<f64>,
    /// The cell's rows: a range of [`CellTree::rows`] (empty: a cell without rows, never read).
    rows: Range<usize>,
    /// Its children: a range of the next level's cells (empty for a leaf).
    children: Range<usize>,
}

/// One level of the hierarchy: its cells, and their means and bases side by side (d × Σ (1 + p_C)),
/// so that a query group meets a run of cells (the children of one cell) in one product.
struct Level {
    cells: Vec<Cell>,
    stack: Mat<f64>,
}

/// The cells of the reference rows, top level first. The rows are in the tree's order (the
/// `order` of [`CellTree::order`]: the row at position s is reference row `order[s]`), so every
/// cell is a range of positions.
struct CellTree {
    levels: Vec<Level>,
    /// The position of every reference row in `order` (m).
    position: Vec<usize>,
    /// The squared norm of the row at every position (m), summed over the columns in order.
    norms: Vec<f64>,
    /// The leaf of every reference row (m).
    leaf_of: Vec<u32>,
}

/// Orders `ids` (indices of `positions`) as a k-d tree of `depth` levels of median splits: each
/// range of the order is halved (at its middle, the larger half first when odd) by the median of
/// its points along the axis of their largest extent. The node at depth t and index i then holds
/// the range [`kd_range`]`(len, t, i)` of the order: every node's points are contiguous, nodes of
/// one depth hold equally many points (±1) and are compact in space.
fn kd_order(positions: &[[f64; 3]], ids: &mut [usize], depth: u32) {
    if depth == 0 || ids.len() < 2 {
        return;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &j in ids.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(positions[j][a]);
            hi[a] = hi[a].max(positions[j][a]);
        }
    }
    let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b]))).unwrap_or(0);
    let mid = ids.len().div_ceil(2);
    ids.select_nth_unstable_by(mid - 1, |&x, &y| positions[x][axis].total_cmp(&positions[y][axis]).then(x.cmp(&y)));
    let (left, right) = ids.split_at_mut(mid);
    if left.len() + right.len() > 4096 {
        rayon::join(|| kd_order(positions, left, depth - 1), || kd_order(positions, right, depth - 1));
    } else {
        kd_order(positions, left, depth - 1);
        kd_order(positions, right, depth - 1);
    }
}

/// The range of [`kd_order`]'s order held by node `index` at depth `t` of `len` points.
fn kd_range(len: usize, t: u32, index: usize) -> Range<usize> {
    let (mut start, mut end) = (0, len);
    for level in (0..t).rev() {
        let mid = start + (end - start).div_ceil(2);
        if (index >> level) & 1 == 0 {
            end = mid;
        } else {
            start = mid;
        }
    }
    start..end
}

/// The depth of a k-d tree whose leaves hold at most `size` of `len` points.
fn kd_depth(len: usize, size: usize) -> u32 {
    let mut depth = 0;
    while len.div_ceil(1 << depth) > size.max(1) && depth < 40 {
        depth += 1;
    }
    depth
}

impl CellTree {
    /// The order of the reference rows by their vertices' positions (m × 3): a k-d tree with
    /// leaves of at most [`LEAF_ROWS`] rows.
    fn order(positions: &[[f64; 3]]) -> Vec<usize> {
        let m = positions.len();
        let mut order: Vec<usize> = (0..m).collect();
        kd_order(positions, &mut order, kd_depth(m, LEAF_ROWS));
        order
    }

    /// The cells of the reference rows `sorted` (m × d, the rows in the order `order` of
    /// [`CellTree::order`]): every log2([`FANOUT`])-th level of the k-d tree kept (the top level
    /// holds at most [`FANOUT`] cells). Cells of more than [`SUBSPACE_ROWS`] rows get a ball,
    /// the others a subspace of at most [`SUBSPACE`] directions ([`LEAF_SUBSPACE`] for the
    /// leaves). Every cell is a block of consecutive rows of `sorted` (nothing is copied), and
    /// writes its mean and basis straight into its slot of its level's stack.
    fn new(sorted: MatRef<f64>, order: &[usize], seed: u64) -> Result<CellTree> {
        let (m, d) = (sorted.nrows(), sorted.ncols());
        let depth = kd_depth(m, LEAF_ROWS);
        let step = FANOUT.trailing_zeros().max(1);
        // Kept depths, top first, leaves last: …, depth − step, depth.
        let mut kept: Vec<u32> =
            (0..).map(|i| depth as i64 - (i * step) as i64).take_while(|&t| t > 0).map(|t| t as u32).collect();
        if kept.is_empty() {
            kept.push(0);
        }
        kept.reverse();
        let mut levels = Vec::with_capacity(kept.len());
        for (l, &t) in kept.iter().enumerate() {
            crate::progress::check()?;
            let ball = m.div_ceil(1 << t) > SUBSPACE_ROWS;
            let slot = 1 + if ball {
                0
            } else if l + 1 == kept.len() {
                LEAF_SUBSPACE
            } else {
                SUBSPACE
            };
            let below = kept.get(l + 1).map(|&u| u - t);
            let mut stack = Mat::<f64>::zeros(d, slot << t);
            let cells: Vec<Cell> = stack
                .as_mut()
                .par_col_chunks_mut(slot)
                .enumerate()
                .map_init(
                    || Mat::<f64>::zeros(0, d),
                    |scratch, (i, mut out)| {
                        let rows = kd_range(m, t, i);
                        let block = sorted.subrows(rows.start, rows.len());
                        let (lo, hi, eps) = if ball {
                            (Vec::new(), Vec::new(), ball_stats(block, out.rb_mut()))
                        } else {
                            let seed = seed ^ ((t as u64) << 40) ^ i as u64;
                            subspace_stats(block, seed, scratch, out.rb_mut())
                        };
                        let out = out.rb();
                        let mean = out.col(0);
                        let mean_sq = (0..d).map(|a| mean[a] * mean[a]).sum();
                        let basis_mean =
                            (0..lo.len()).map(|c| (0..d).map(|a| out[(a, 1 + c)] * mean[a]).sum()).collect();
                        let children = match below {
                            Some(g) => (i << g)..((i + 1) << g),
                            None => 0..0,
                        };
                        Cell { at: i * slot, lo, hi, eps, mean_sq, basis_mean, rows, children }
                    },
                )
                .collect();
            levels.push(Level { cells, stack });
        }
        let mut leaf_of = vec![0u32; m];
        if let Some(leaves) = levels.last() {
            for (t, cell) in leaves.cells.iter().enumerate() {
                for &j in &order[cell.rows.clone()] {
                    leaf_of[j] = t as u32;
                }
            }
        }
        let mut position = vec![0; m];
        for (s, &j) in order.iter().enumerate() {
            position[j] = s;
        }
        let norms = crate::linalg::row_squared_norms(sorted);
        Ok(CellTree { levels, position, norms, leaf_of })
    }
}

/// Query groups: the leaves of a k-d tree of the query rows' positions (at most [`GROUP_ROWS`]
/// each), as positions in `rows`.
fn query_groups(positions: &[[f64; 3]], rows: &[usize]) -> Vec<Vec<usize>> {
    let qpos: Vec<[f64; 3]> = rows.iter().map(|&i| positions[i]).collect();
    let depth = kd_depth(rows.len(), GROUP_ROWS);
    let mut order: Vec<usize> = (0..rows.len()).collect();
    kd_order(&qpos, &mut order, depth);
    (0..1usize << depth).map(|i| order[kd_range(rows.len(), depth, i)].to_vec()).filter(|g| !g.is_empty()).collect()
}

/// A ball around the rows of `block` (r × d): their mean into `out`'s first column (d), and ε,
/// their largest distance from it (rounded up); without a copy of the rows (the top levels'
/// large cells, which only rule out far regions).
fn ball_stats(block: MatRef<f64>, mut out: MatMut<f64>) -> f64 {
    let (r, d) = (block.nrows(), block.ncols());
    let mean: Vec<f64> = (0..d).map(|a| (0..r).map(|i| block[(i, a)]).sum::<f64>() / r.max(1) as f64).collect();
    let (mut e2, mut n2) = (vec![0.0; r], vec![0.0; r]);
    for (a, m) in mean.iter().enumerate() {
        out[(a, 0)] = *m;
        for i in 0..r {
            let x = block[(i, a)];
            e2[i] += (x - m).powi(2);
            n2[i] += x * x;
        }
    }
    let eps2 = e2.iter().fold(0.0f64, |a, &b| a.max(b));
    let largest2 = n2.iter().fold(0.0f64, |a, &b| a.max(b));
    eps2.sqrt() + 1e-12 * largest2.sqrt()
}

/// The subspace of the rows of `block` (r × d): their mean e into `out`'s first column and U
/// (orthonormal, p ≤ `out.ncols()` − 1 columns) into the next; returns the box [lo, hi] (p each)
/// of t = Uᵀ(r − e) over the rows and ε, the largest ‖P⊥(r − e)‖ (rounded up). U spans
/// a randomized range finder's estimate of the centred rows' top principal directions (Halko,
/// Martinsson, Tropp 2011: a Rademacher sketch with [`SUBSPACE_OVERSAMPLE`] extra columns, seeded,
/// then Rayleigh–Ritz; no power iteration: one cost 30 % more time on the cells at 840k vertices
/// and changed neither the rows read nor the time of the descent); the box and ε are measured on
/// the rows with that U, so the bound holds whatever U is. `scratch` (at least r × d) holds the
/// centred rows, then their residuals.
fn subspace_stats(
    block: MatRef<f64>,
    seed: u64,
    scratch: &mut Mat<f64>,
    mut out: MatMut<f64>,
) -> (Vec<f64>, Vec<f64>, f64) {
    let (r, d) = (block.nrows(), block.ncols());
    if r == 0 {
        return (Vec::new(), Vec::new(), 0.0);
    }
    let mean: Vec<f64> = (0..d).map(|a| (0..r).map(|i| block[(i, a)]).sum::<f64>() / r as f64).collect();
    for (a, m) in mean.iter().enumerate() {
        out[(a, 0)] = *m;
    }
    // The centred rows, in scratch reused across cells (fresh r × d buffers would be paged in
    // and zeroed for every cell: the embedding's size again for every level).
    if scratch.nrows() < r || scratch.ncols() != d {
        *scratch = Mat::zeros(r, d);
    }
    let mut dm = scratch.as_mut().subrows_mut(0, r);
    for a in 0..d {
        for i in 0..r {
            dm[(i, a)] = block[(i, a)] - mean[a];
        }
    }
    let p = (out.ncols() - 1).min(r.saturating_sub(1)).min(d);
    let mut q = 0;
    if p > 0 {
        let w = (p + SUBSPACE_OVERSAMPLE).min(d);
        let mut rng = crate::rng::Normal::new(seed);
        // A Rademacher sketch (signs): as good a range finder as a Gaussian one, and cheaper.
        let h = Mat::from_fn(r, w, |_, _| if rng.uniform() < 0.5 { -1.0 } else { 1.0 });
        let qz = orthonormal_columns(crate::linalg::mul(dm.rb().transpose(), h.as_ref()).as_ref());
        let t = crate::linalg::mul(dm.rb(), qz.as_ref());
        let gram = crate::linalg::mul(t.transpose(), t.as_ref());
        let mut ritz = Mat::<f64>::zeros(qz.ncols(), 0);
        if qz.ncols() > 0 {
            if let Ok(evd) = gram.self_adjoint_eigen(faer::Side::Lower) {
                let vals = evd.S().column_vector();
                let top = vals[qz.ncols() - 1].max(0.0);
                // Eigenvalues ascending: the last p, while above rounding.
                let kept: Vec<usize> =
                    (0..qz.ncols()).rev().take(p).take_while(|&c| top > 0.0 && vals[c] > 1e-24 * top).collect();
                ritz = Mat::from_fn(qz.ncols(), kept.len(), |a, c| evd.U()[(a, kept[c])]);
            }
        }
        // Orthonormal to rounding once more (the bound assumes it).
        let u = orthonormal_columns(crate::linalg::mul(qz.as_ref(), ritz.as_ref()).as_ref());
        q = u.ncols();
        out.rb_mut().subcols_mut(1, q).copy_from(u.as_ref());
    }
    let u = out.rb().subcols(1, q);
    let t = crate::linalg::mul(dm.rb(), u); // r × q
                                            // The residuals (r − e) − U t, in place.
    matmul(dm.rb_mut(), Accum::Add, t.as_ref(), u.transpose(), -1.0, Par::Seq);
    let (mut lo, mut hi) = (vec![f64::INFINITY; q], vec![f64::NEG_INFINITY; q]);
    for c in 0..q {
        for i in 0..r {
            lo[c] = lo[c].min(t[(i, c)]);
            hi[c] = hi[c].max(t[(i, c)]);
        }
    }
    // Row norms summed column by column (the matrices are column-major).
    let largest = |x: MatRef<f64>| crate::linalg::row_squared_norms(x).into_iter().fold(0.0f64, f64::max);
    let (eps2, largest2) = (largest(dm.rb()), largest(block));
    // Rounded up by far more than the rounding of the products above.
    (lo, hi, eps2.sqrt() + 1e-12 * largest2.sqrt())
}

/// The nearest of the rows `read` of `sorted` (ascending positions; row s is reference row
/// `order[s]`, its squared norm `norms[s]`) to every row of `queries` (|G| × d, squared norms
/// `qn2`), as a reference row id, by the exact search's key ‖r_j‖² − 2 q · r_j (row norms and dot
/// products summed over the columns in order, as [`crate::spatial::nearest_rows`] does), ties to
/// the smallest id: a product in f64 screens, the rows within rounding of the smallest key are
/// compared exactly. The rows are read in place, one product per run of consecutive positions
/// (mostly whole leaves): no copy.
fn nearest_among(
    sorted: MatRef<f64>,
    order: &[usize],
    norms: &[f64],
    read: &[usize],
    queries: MatRef<f64>,
    qn2: &[f64],
) -> Vec<usize> {
    let d = sorted.ncols();
    let rmax = read.iter().map(|&s| norms[s]).fold(0.0f64, f64::max);
    let mut dots = Mat::<f64>::zeros(queries.nrows(), read.len());
    let mut t = 0;
    while t < read.len() {
        let mut end = t + 1;
        while end < read.len() && read[end] == read[end - 1] + 1 {
            end += 1;
        }
        matmul(
            dots.as_mut().subcols_mut(t, end - t),
            Accum::Replace,
            queries,
            sorted.subrows(read[t], end - t).transpose(),
            1.0,
            Par::Seq,
        );
        t = end;
    }
    // The keys, column by column (a column holds one row's keys for every query).
    let g = queries.nrows();
    let nr: Vec<f64> = read.iter().map(|&s| norms[s]).collect();
    let mut low = vec![f64::INFINITY; g];
    smallest_keys(dots.as_ref(), &nr, &mut low);
    // Both keys' rounding is below d · 2⁻⁵² · (‖q‖² + ‖r‖²).
    let limit: Vec<f64> = (0..g).map(|i| low[i] + 2.0 * 1e-12 * (d as f64) * (qn2[i] + rmax)).collect();
    let mut best = vec![(f64::INFINITY, usize::MAX); g];
    for (t, &n) in nr.iter().enumerate() {
        let col = &dots.col_as_slice(t)[..g];
        if !any_key_within(col, n, &limit) {
            continue;
        }
        for i in (0..g).filter(|&i| n - 2.0 * col[i] <= limit[i]) {
            let dot: f64 = (0..d).map(|c| queries[(i, c)] * sorted[(read[t], c)]).sum();
            let exact = (n - 2.0 * dot, order[read[t]]);
            if exact.0 < best[i].0 || (exact.0 == best[i].0 && exact.1 < best[i].1) {
                best[i] = exact;
            }
        }
    }
    best.into_iter().map(|(_, j)| j).collect()
}

/// `low[i]` = min(`low[i]`, min over t of `norms[t]` − 2 `dots[(i, t)]`): the smallest key of every
/// query (a row of `dots`, |G| × r, column-major) over the rows t.
#[inline(always)]
fn smallest_keys_generic(dots: MatRef<f64>, norms: &[f64], low: &mut [f64]) {
    let g = low.len();
    for (t, &n) in norms.iter().enumerate() {
        let col = &dots.col(t).try_as_col_major().expect("a column-major product").as_slice()[..g];
        for (l, &x) in low.iter_mut().zip(col) {
            *l = l.min(n - 2.0 * x);
        }
    }
}

crate::linalg::at_vector_width! {
    /// [`smallest_keys_generic`] at the widest vectors the CPU has.
    fn smallest_keys(dots: MatRef<f64>, norms: &[f64], low: &mut [f64]) = smallest_keys_generic
}

/// Whether some key `n` − 2 `col[i]` is at most `limit[i]`.
fn any_key_within(col: &[f64], n: f64, limit: &[f64]) -> bool {
    col.iter().zip(limit).fold(false, |any, (&x, &l)| any | (n - 2.0 * x <= l))
}

/// Orthonormal columns spanning those of `z` (d × w): modified Gram–Schmidt, twice per column;
/// columns that vanish against the ones before (below 10⁻¹⁰ of the largest) are dropped.
fn orthonormal_columns(z: MatRef<f64>) -> Mat<f64> {
    let d = z.nrows();
    let scale = (0..z.ncols()).map(|c| (0..d).map(|a| z[(a, c)].powi(2)).sum::<f64>().sqrt()).fold(0.0, f64::max);
    let mut kept: Vec<Vec<f64>> = Vec::new();
    for c in 0..z.ncols() {
        let mut v: Vec<f64> = (0..d).map(|a| z[(a, c)]).collect();
        for _ in 0..2 {
            for u in &kept {
                let x: f64 = u.iter().zip(&v).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(vi, ui)| *vi -= x * ui);
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > 1e-10 * scale && norm > 0.0 {
            kept.push(v.iter().map(|x| x / norm).collect());
        }
    }
    Mat::from_fn(d, kept.len(), |a, c| kept[c][a])
}

/// Scratch of a group's bounds, reused for every run of cells: the product (|G| × the run's
/// stacked rows) and two columns of |G|.
struct BoundScratch {
    prod: Mat<f64>,
    normal2: Vec<f64>,
    lb2: Vec<f64>,
}

impl BoundScratch {
    fn new(queries: usize) -> BoundScratch {
        BoundScratch {
            prod: Mat::zeros(queries, FANOUT * (1 + SUBSPACE)),
            normal2: vec![0.0; queries],
            lb2: vec![0.0; queries],
        }
    }
}

/// The bounds LB(q, C)² (module documentation) of the queries of a group (`queries` |G| × d,
/// squared norms `qn2`) for the run `run` of a level's cells, calling `keep(cell, lb²)` for each
/// cell with rows (lb² one per query). One product of the queries with the run's stacked mean
/// and basis rows; the normal part ‖P⊥(q − e_C)‖ from ‖q − e_C‖² − ‖U_Cᵀ(q − e_C)‖², lowered by a
/// rounding slack so that the bound stays a lower bound. The loops run over the queries, in the
/// product's columns.
fn bound_run(
    level: &Level,
    run: Range<usize>,
    queries: MatRef<f64>,
    qn2: &[f64],
    scratch: &mut BoundScratch,
    mut keep: impl FnMut(usize, &[f64]),
) {
    let g = queries.nrows();
    let (first, last) = (&level.cells[run.start], &level.cells[run.end - 1]);
    let rows = first.at..last.at + 1 + last.lo.len();
    if scratch.prod.ncols() < rows.len() {
        scratch.prod = Mat::zeros(g, rows.len());
    }
    matmul(
        scratch.prod.as_mut().subcols_mut(0, rows.len()),
        Accum::Replace,
        queries,
        level.stack.subcols(rows.start, rows.len()),
        1.0,
        Par::Seq,
    );
    let prod = scratch.prod.as_ref().subcols(0, rows.len());
    for t in run {
        let cell = &level.cells[t];
        if cell.rows.is_empty() {
            continue;
        }
        let (x2, lb2) = (&mut scratch.normal2, &mut scratch.lb2);
        cell_bounds(prod, cell.at - rows.start, cell, qn2, x2, lb2);
        keep(t, lb2);
    }
}

/// LB(q, C)² of every query of a group for one cell (`lb2`, |G|), from the product `prod` of the
/// queries with the run's stacked columns (the cell's mean at column `o`, its basis after it), as
/// in [`bound_run`]. `x2` is scratch (|G|).
#[inline(always)]
fn cell_bounds_generic(prod: MatRef<f64>, o: usize, cell: &Cell, qn2: &[f64], x2: &mut [f64], lb2: &mut [f64]) {
    let g = qn2.len();
    let col = |c: usize| -> &[f64] { &prod.col(c).try_as_col_major().expect("a column-major product").as_slice()[..g] };
    x2.fill(0.0);
    lb2.fill(0.0);
    for c in 0..cell.lo.len() {
        let (bm, lo, hi) = (cell.basis_mean[c], cell.lo[c], cell.hi[c]);
        for ((p, x2), b2) in col(o + 1 + c).iter().zip(x2.iter_mut()).zip(lb2.iter_mut()) {
            let x = p - bm;
            *x2 += x * x;
            let out = (lo - x).max(x - hi).max(0.0);
            *b2 += out * out;
        }
    }
    for (((pm, &q2), x2), b2) in col(o).iter().zip(qn2).zip(x2.iter()).zip(lb2.iter_mut()) {
        let v2 = q2 - 2.0 * pm + cell.mean_sq;
        let slack = 1e-12 * (q2 + cell.mean_sq);
        let perp = (v2 - x2 - slack).max(0.0).sqrt();
        let normal = (perp - cell.eps).max(0.0);
        *b2 += normal * normal;
    }
}

crate::linalg::at_vector_width! {
    /// [`cell_bounds_generic`] at the widest vectors the CPU has.
    fn cell_bounds(prod: MatRef<f64>, o: usize, cell: &Cell, qn2: &[f64], x2: &mut [f64], lb2: &mut [f64]) = cell_bounds_generic
}

/// The leaves that some query of a group cannot rule out with the squared thresholds `limit2`,
/// found top down; and the number of cells bounded.
fn candidate_leaves(tree: &CellTree, queries: MatRef<f64>, qn2: &[f64], limit2: &[f64]) -> (Vec<usize>, u64) {
    let (g, d) = (queries.nrows(), queries.ncols());
    // The group's centre c and reach: LB(·, C) is the distance to a set, so 1-Lipschitz, and
    // LB(q, C) ≥ LB(c, C) − ‖q − c‖; a cell with LB(c, C) above max over q of ‖q − c‖ + limit_q
    // holds no row nearer to any query than its threshold.
    let c: Vec<f64> = (0..d).map(|a| (0..g).map(|i| queries[(i, a)]).sum::<f64>() / g as f64).collect();
    let cn2: f64 = c.iter().map(|x| x * x).sum();
    let cm = MatRef::from_row_major_slice(&c, 1, d);
    let (cn2s, mut centre) = ([cn2], BoundScratch::new(1));
    let reach = (0..g)
        .map(|i| {
            let r2: f64 = (0..d).map(|a| (queries[(i, a)] - c[a]).powi(2)).sum();
            r2.sqrt() + limit2[i].sqrt() + 1e-12 * (qn2[i].sqrt() + cn2.sqrt())
        })
        .fold(0.0f64, f64::max);
    let reach2 = reach * reach;
    let top: Range<usize> = 0..tree.levels[0].cells.len();
    let mut runs: Vec<Range<usize>> = std::iter::once(top).collect();
    let mut bounded = 0u64;
    let depth = tree.levels.len();
    let mut leaves = Vec::new();
    let mut scratch = BoundScratch::new(queries.nrows());
    for (l, level) in tree.levels.iter().enumerate() {
        let mut next = Vec::new();
        let leaf = l + 1 == depth;
        let mut take = |t: usize, next: &mut Vec<Range<usize>>| {
            if leaf {
                leaves.push(t);
            } else {
                next.push(level.cells[t].children.clone());
            }
        };
        for run in runs {
            // The centre's bound first (one product row for the run), then every query's for
            // the cells from the first to the last the centre leaves.
            let mut alive: Option<Range<usize>> = None;
            bound_run(level, run, cm, &cn2s, &mut centre, |t, lb2| {
                if lb2[0] <= reach2 {
                    alive = Some(alive.as_ref().map_or(t, |a| a.start)..t + 1);
                }
            });
            let Some(run) = alive else {
                continue;
            };
            bounded += run.len() as u64;
            bound_run(level, run, queries, qn2, &mut scratch, |t, lb2| {
                if lb2.iter().zip(limit2).any(|(b, l)| b <= l) {
                    take(t, &mut next);
                }
            });
        }
        runs = next;
    }
    (leaves, bounded)
}

/// What one query group found: (position in `rows`, its exact answer) pairs, rows read, cells
/// bounded.
type GroupResult = (Vec<(usize, usize)>, u64, u64);

/// Makes `answer` the exact nearest reference rows of the query rows `rows`: for every s,
/// `answer[s]` becomes the row j of `reference` (m × d) nearest to row `rows[s]` of `query` (n ×
/// d_q, d_q ≤ d, its missing columns zero), ties to the smallest j — the exact search's map
/// ([`crate::spatial::nearest_rows`]) — reading only the cells of Y that the bound of the module's
/// documentation cannot rule out. `answer` on entry is any map (a restricted search's): the nearer
/// it is to exact, the fewer rows are read. `query_positions` (n × 3) and `reference_positions` (m
/// × 3) are the vertices' positions, which shape the cells and groups (any positions give the
/// exact result; a surface's keep the cells small in the embedding). `seed` seeds the cells'
/// subspaces (the result does not depend on it).
///
/// `reference` is mutable for the call's duration only: its rows are put in the cells' order in
/// place, so that every cell is a block of consecutive rows read in streams (gathered one by one
/// from a column-major 840k-vertex embedding they took 48 s; a reordered copy would double the
/// embedding's memory, 0.87 GB there), and put back before the function returns, also on error.
///
/// Errors: mismatched sizes, ids out of range, a non-finite entry in either embedding.
pub fn certify_nearest_rows(
    mut reference: MatMut<f64>,
    query: MatRef<f64>,
    reference_positions: &[[f64; 3]],
    query_positions: &[[f64; 3]],
    rows: &[usize],
    answer: &mut [usize],
    seed: u64,
) -> Result<Certificate> {
    let (m, d, n, dq) = (reference.nrows(), reference.ncols(), query.nrows(), query.ncols());
    if reference_positions.len() != m || query_positions.len() != n {
        return Err(Error::invalid(
            "certified search",
            format!(
                "{} and {} positions for embeddings of {n} and {m} rows",
                query_positions.len(),
                reference_positions.len()
            ),
        ));
    }
    if dq > d {
        return Err(Error::invalid("certified search", format!("query has {dq} columns, reference {d}")));
    }
    if rows.len() != answer.len() {
        return Err(Error::invalid("certified search", format!("{} answers for {} rows", answer.len(), rows.len())));
    }
    if rows.iter().any(|&i| i >= n) || answer.iter().any(|&j| j >= m) {
        return Err(Error::invalid("certified search", "a vertex id is out of range"));
    }
    let cert = Certificate { queries: rows.len(), references: m, ..Certificate::default() };
    if rows.is_empty() {
        return Ok(cert);
    }
    let (Some(max_r), Some(max_q)) =
        (crate::linalg::max_abs_finite(reference.rb()), crate::linalg::max_abs_finite(query))
    else {
        return Err(Error::invalid("certified search", "an embedding contains a non-finite value"));
    };
    // Slack for rounding in the bounds: far above it (≈ 10⁻¹⁵ of the rows' norms), far below any
    // distance that matters.
    let tol = 1e-9 * (max_r + max_q) * (d as f64).sqrt();
    let order = CellTree::order(reference_positions);
    permute_rows(reference.rb_mut(), &order, false);
    let t0 = std::time::Instant::now();
    let tree = CellTree::new(reference.rb(), &order, seed);
    if std::env::var_os("FUNCORR_DEBUG_CERTIFIED").is_some() {
        eprintln!("certified search: rows reordered and cells in {:.2} s", t0.elapsed().as_secs_f64());
    }
    let result =
        tree.and_then(|tree| certify_sorted(reference.rb(), &tree, &order, query, query_positions, rows, answer, tol));
    // Put back whatever happened (a cancelled or failed search too).
    permute_rows(reference.rb_mut(), &order, true);
    let (pairs, rows_read, cells_bounded) = result?;
    let mut cert = Certificate { rows_read, cells_bounded, ..cert };
    for (s, j) in pairs {
        if answer[s] != j {
            answer[s] = j;
            cert.changed += 1;
        }
    }
    Ok(cert)
}

/// Reorders the rows of `mat` in place: the new row s is the old row `order[s]` (`back`: the
/// inverse, the new row `order[s]` is the old row s), one column at a time through one column of
/// scratch per thread.
fn permute_rows(mat: MatMut<f64>, order: &[usize], back: bool) {
    let m = mat.nrows();
    mat.par_col_iter_mut().for_each_init(
        || vec![0.0; m],
        |scratch, mut col| {
            for (s, &j) in order.iter().enumerate() {
                if back {
                    scratch[j] = col[s];
                } else {
                    scratch[s] = col[j];
                }
            }
            for (s, x) in scratch.iter().enumerate() {
                col[s] = *x;
            }
        },
    );
}

/// The work of [`certify_nearest_rows`] on the reference rows in the tree's order (`sorted`, m ×
/// d): the exact answers of the query groups as (position in `rows`, reference row id) pairs, the
/// rows read and the cells bounded.
#[allow(clippy::too_many_arguments)]
fn certify_sorted(
    sorted: MatRef<f64>,
    tree: &CellTree,
    order: &[usize],
    query: MatRef<f64>,
    query_positions: &[[f64; 3]],
    rows: &[usize],
    answer: &[usize],
    tol: f64,
) -> Result<GroupResult> {
    let (d, dq) = (sorted.ncols(), query.ncols());
    let groups = query_groups(query_positions, rows);
    let qrow = |s: usize, a: usize| if a < dq { query[(rows[s], a)] } else { 0.0 };
    let results: Vec<Result<GroupResult>> = groups
        .par_iter()
        .filter(|g| !g.is_empty())
        .map(|group| {
            crate::progress::check()?;
            let len = group.len();
            let queries = Mat::from_fn(len, d, |i, a| qrow(group[i], a));
            let qn2: Vec<f64> = (0..len).map(|i| (0..d).map(|a| queries[(i, a)].powi(2)).sum()).collect();
            // Each query's threshold: the distance to its answer, plus the rounding slack.
            let mut best: Vec<usize> = group.iter().map(|&s| answer[s]).collect();
            let thresholds = |best: &[usize]| -> Vec<f64> {
                best.iter()
                    .enumerate()
                    .map(|(i, &j)| {
                        let at = tree.position[j];
                        (0..d).map(|a| (queries[(i, a)] - sorted[(at, a)]).powi(2)).sum::<f64>().sqrt() + tol
                    })
                    .collect()
            };
            // The exact search among the rows of `leaves` and the current answers.
            let search = |leaves: &[usize], best: &[usize]| -> (Vec<usize>, usize) {
                let level = &tree.levels[tree.levels.len() - 1];
                let mut read: Vec<usize> = best.iter().map(|&j| tree.position[j]).collect();
                for &t in leaves {
                    read.extend(level.cells[t].rows.clone());
                }
                read.sort_unstable();
                read.dedup();
                (nearest_among(sorted, order, &tree.norms, &read, queries.as_ref(), &qn2), read.len())
            };
            // First the leaves that hold the group's answers: the group's queries are
            // neighbours, so where a restricted answer is far off, its neighbours' answers
            // usually lie next to the right row, and the thresholds tighten before the descent.
            let mut own: Vec<usize> = best.iter().map(|&j| tree.leaf_of[j] as usize).collect();
            own.sort_unstable();
            own.dedup();
            let (found, r1) = search(&own, &best);
            best = found;
            // Then one descent with those thresholds, and every leaf it leaves that was not read.
            let limit2: Vec<f64> = thresholds(&best).iter().map(|x| x * x).collect();
            let (leaves, bounded) = candidate_leaves(tree, queries.as_ref(), &qn2, &limit2);
            let rest: Vec<usize> = leaves.into_iter().filter(|t| own.binary_search(t).is_err()).collect();
            let (found, r2) = if rest.is_empty() { (best.clone(), 0) } else { search(&rest, &best) };
            let pairs = group.iter().zip(found).map(|(&s, j)| (s, j)).collect();
            let read = r1 + r2;
            Ok((pairs, (len * read) as u64, bounded))
        })
        .collect();
    crate::progress::check()?;
    let mut all = (Vec::with_capacity(rows.len()), 0, 0);
    for r in results {
        let (pairs, rows_read, bounded) = r?;
        all.0.extend(pairs);
        all.1 += rows_read;
        all.2 += bounded;
    }
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth embedding of a sphere's vertices (low-degree polynomials of the position, as
    /// low-frequency eigenfunctions are), and a query set near it: the certified search from a
    /// bad start (every answer 0) and from a perturbed exact answer gives the exact search's map.
    #[test]
    fn the_certified_map_is_the_exact_map() {
        let p = crate::primitives::icosphere(4).vertices().to_vec(); // 2,562 vertices
        let m = p.len();
        let d = 12;
        let feature = |x: &[f64; 3], a: usize| -> f64 {
            let (u, v, w) = (x[0], x[1], x[2]);
            match a % 6 {
                0 => u,
                1 => v,
                2 => w,
                3 => u * v + 0.3 * w,
                4 => (a as f64 * 0.7 * u).sin() + v * w,
                _ => (u * u - v * v) * (1.0 + 0.1 * a as f64),
            }
        };
        let original = Mat::from_fn(m, d, |j, a| feature(&p[j], a));
        let mut reference = original.clone();
        // Queries: the rows plus noise, at the positions of a rotated copy (so each query's nearest
        // row is nearby, and the groups are cells of another partition than Y's).
        let mut rng = crate::rng::Normal::new(3);
        let qpos: Vec<[f64; 3]> = p.iter().map(|x| [x[1], -x[0], x[2]]).collect();
        let query = Mat::from_fn(m, d - 2, |i, a| feature(&p[i], a) + 0.01 * rng.sample());
        let exact = crate::spatial::nearest_rows(
            original.as_ref(),
            Mat::from_fn(m, d, |i, a| if a < d - 2 { query[(i, a)] } else { 0.0 }).as_ref(),
        )
        .unwrap();
        let rows: Vec<usize> = (0..m).collect();
        for start in
            [vec![0; m], exact.iter().enumerate().map(|(i, &j)| if i % 3 == 0 { (j + 1) % m } else { j }).collect()]
        {
            let mut answer = start.clone();
            let cert =
                certify_nearest_rows(reference.as_mut(), query.as_ref(), &p, &qpos, &rows, &mut answer, 1).unwrap();
            assert_eq!(answer, exact);
            assert!(reference == original, "the reference rows are put back in their order");
            assert_eq!(cert.changed, start.iter().zip(&exact).filter(|(a, b)| a != b).count());
        }
        // A near-exact start reads a small part of Y.
        let mut answer = exact.clone();
        let cert = certify_nearest_rows(reference.as_mut(), query.as_ref(), &p, &qpos, &rows, &mut answer, 1).unwrap();
        assert_eq!(cert.changed, 0);
        assert!(cert.share_read() < 0.5, "read {:.3} of Y", cert.share_read());
    }

    /// Rows repeated (every row of the first half again in the second, at other positions) and a
    /// cell of identical rows: the certified map breaks ties to the smallest row id, as the exact
    /// search does, although the rows are searched in the cells' order.
    #[test]
    fn ties_go_to_the_smallest_row_id() {
        let p = crate::primitives::icosphere(3).vertices().to_vec(); // 642 vertices
        let m = p.len();
        let half = m / 2;
        let feature = |x: &[f64; 3]| [x[0], x[1], x[2], x[0] * x[1], (2.0 * x[2]).sin()];
        // Rows half.. repeat rows 0..half; the first 40 rows are all the same.
        let row = |j: usize| if j % half < 40 { feature(&p[0]) } else { feature(&p[j % half]) };
        let original = Mat::from_fn(m, 5, |j, a| row(j)[a]);
        let mut reference = original.clone();
        let query = Mat::from_fn(m, 5, |i, a| feature(&p[i])[a]);
        let exact = crate::spatial::nearest_rows(original.as_ref(), query.as_ref()).unwrap();
        assert!(exact.iter().all(|&j| j < half), "the exact search keeps the smaller of two equal rows");
        let rows: Vec<usize> = (0..m).collect();
        // Start from the larger copy of each answer.
        let mut answer: Vec<usize> = exact.iter().map(|&j| j + half).collect();
        certify_nearest_rows(reference.as_mut(), query.as_ref(), &p, &p, &rows, &mut answer, 5).unwrap();
        assert_eq!(answer, exact);
        assert!(reference == original);
    }

    /// A cancelled certificate returns the cancellation and leaves the reference in its order.
    #[test]
    fn a_cancelled_certificate_puts_the_rows_back() {
        let p = crate::primitives::icosphere(3).vertices().to_vec();
        let m = p.len();
        let original = Mat::from_fn(m, 4, |j, a| p[j][a % 3] * (1.0 + a as f64));
        let mut reference = original.clone();
        let rows: Vec<usize> = (0..m).collect();
        let mut answer = vec![0; m];
        let monitor = crate::progress::Monitor::new();
        monitor.cancel();
        let r =
            monitor.run(|| certify_nearest_rows(reference.as_mut(), original.as_ref(), &p, &p, &rows, &mut answer, 2));
        assert!(matches!(r, Err(Error::Cancelled { .. })), "{r:?}");
        assert!(reference == original);
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = crate::primitives::icosphere(1).vertices().to_vec();
        let m = p.len();
        let q = Mat::from_fn(m, 3, |j, a| p[j][a]);
        let mut r = q.clone();
        let mut answer = vec![0; m];
        let rows: Vec<usize> = (0..m).collect();
        assert!(certify_nearest_rows(r.as_mut(), q.as_ref(), &p[1..], &p, &rows, &mut answer, 0).is_err());
        assert!(certify_nearest_rows(r.as_mut(), q.as_ref(), &p, &p, &rows[1..], &mut answer, 0).is_err());
        let mut bad = answer.clone();
        bad[0] = m;
        assert!(certify_nearest_rows(r.as_mut(), q.as_ref(), &p, &p, &rows, &mut bad, 0).is_err());
        let mut nan = q.clone();
        nan[(2, 1)] = f64::NAN;
        assert!(certify_nearest_rows(nan.as_mut(), q.as_ref(), &p, &p, &rows, &mut answer, 0).is_err());
    }
}
