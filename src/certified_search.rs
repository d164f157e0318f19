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
//! tightens a wrong one's threshold), then descends the tree, bounding every query against each
//! run of children in one product, and reads every leaf that some query cannot rule out. The
//! rows read, with the answers, are searched exactly.
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
//! read O(|G| · rows read · d) per group in one product. Memory: the cells' subspaces, about
//! (p + 1) / [`LEAF_ROWS`] of the embedding (≈ 0.3 m · d values), and one group's rows at a time.
//! At 52k vertices a map takes 1.1–1.3 s; at 840k, 48 s (the rows are gathered one by one from
//! the column-major embedding), which is why the matching pipeline certifies only up to a size
//! (its option `NearSearch::certified_up_to`).

use std::ops::Range;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
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

/// Cells with more rows than this are bounded by a ball (their rows are not copied).
pub const SUBSPACE_ROWS: usize = 16384;

/// Extra columns of the randomized range sketch of a cell's subspace.
const SUBSPACE_OVERSAMPLE: usize = 6;

/// Power iterations of that sketch.
const SUBSPACE_POWER: usize = 1;

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
    /// The first of its rows in its level's `stack`: e_C, then the p rows of U_Cᵀ.
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

/// One level of the hierarchy: its cells, and their means and basis rows stacked (Σ (1 + p_C) ×
/// d), so that a query group meets a run of cells (the children of one cell) in one product.
struct Level {
    cells: Vec<Cell>,
    stack: Mat<f64>,
}

/// The cells of the reference rows, top level first; every cell's rows are contiguous in `rows`.
struct CellTree {
    levels: Vec<Level>,
    rows: Vec<usize>,
    /// The leaf of every row (m).
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
    /// The cells of `reference`'s rows (m × d) by their positions (m × 3): a k-d tree with leaves
    /// of at most [`LEAF_ROWS`] rows, every log2([`FANOUT`])-th level kept (the top level holds at
    /// most [`FANOUT`] cells). Cells of more than [`SUBSPACE_ROWS`] rows get a ball, streamed;
    /// below, the rows of each cell of the first level that fits are gathered once and give the
    /// subspaces of that cell and of all its descendants.
    fn new(reference: MatRef<f64>, positions: &[[f64; 3]], seed: u64) -> Result<CellTree> {
        let (m, d) = (reference.nrows(), reference.ncols());
        let depth = kd_depth(m, LEAF_ROWS);
        let mut rows: Vec<usize> = (0..m).collect();
        kd_order(positions, &mut rows, depth);
        let step = FANOUT.trailing_zeros().max(1);
        // Kept depths, top first, leaves last: …, depth − step, depth.
        let mut kept: Vec<u32> =
            (0..).map(|i| depth as i64 - (i * step) as i64).take_while(|&t| t > 0).map(|t| t as u32).collect();
        if kept.is_empty() {
            kept.push(0);
        }
        kept.reverse();
        let cell_seed = |t: u32, i: usize| seed ^ ((t as u64) << 40) ^ i as u64;
        // The first kept level whose cells all fit SUBSPACE_ROWS.
        let h = kept.iter().position(|&t| m.div_ceil(1 << t) <= SUBSPACE_ROWS).unwrap_or(kept.len() - 1);
        let mut stats: Vec<Vec<Stats>> = Vec::with_capacity(kept.len());
        for &t in &kept[..h] {
            crate::progress::check()?;
            stats.push(
                (0..1usize << t).into_par_iter().map(|i| ball_stats(reference, &rows[kd_range(m, t, i)])).collect(),
            );
        }
        crate::progress::check()?;
        let th = kept[h];
        let blocks: Vec<Vec<Vec<Stats>>> = (0..1usize << th)
            .into_par_iter()
            .map(|i| {
                let top = kd_range(m, th, i);
                let block = Mat::from_fn(top.len(), d, |s, a| reference[(rows[top.start + s], a)]);
                kept[h..]
                    .iter()
                    .map(|&t| {
                        let g = t - th;
                        ((i << g)..((i + 1) << g))
                            .map(|j| {
                                let r = kd_range(m, t, j);
                                subspace_stats(block.subrows(r.start - top.start, r.len()), cell_seed(t, j))
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let below: Vec<Vec<Stats>> = (h..kept.len()).map(|_| Vec::new()).collect();
        let below = blocks.into_iter().fold(below, |mut acc, block| {
            for (level, cells) in acc.iter_mut().zip(block) {
                level.extend(cells);
            }
            acc
        });
        stats.extend(below);
        let mut levels = Vec::with_capacity(kept.len());
        for (l, (&t, level)) in kept.iter().zip(stats).enumerate() {
            let below = kept.get(l + 1).map(|&u| u - t);
            let total: usize = level.iter().map(|(_, basis, ..)| 1 + basis.len() / d).sum();
            let mut stack = Mat::<f64>::zeros(total, d);
            let mut cells = Vec::with_capacity(level.len());
            let mut at = 0;
            for (i, (mean, basis, lo, hi, eps)) in level.into_iter().enumerate() {
                let p = basis.len() / d;
                for a in 0..d {
                    stack[(at, a)] = mean[a];
                }
                for (c, u) in basis.chunks(d).enumerate() {
                    for a in 0..d {
                        stack[(at + 1 + c, a)] = u[a];
                    }
                }
                let mean_sq = mean.iter().map(|x| x * x).sum();
                let basis_mean = basis.chunks(d).map(|u| u.iter().zip(&mean).map(|(a, b)| a * b).sum()).collect();
                let children = match below {
                    Some(g) => (i << g)..((i + 1) << g),
                    None => 0..0,
                };
                cells.push(Cell { at, lo, hi, eps, mean_sq, basis_mean, rows: kd_range(m, t, i), children });
                at += 1 + p;
            }
            levels.push(Level { cells, stack });
        }
        let mut leaf_of = vec![0u32; m];
        if let Some(leaves) = levels.last() {
            for (t, cell) in leaves.cells.iter().enumerate() {
                for &j in &rows[cell.rows.clone()] {
                    leaf_of[j] = t as u32;
                }
            }
        }
        Ok(CellTree { levels, rows, leaf_of })
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

/// The statistics of one cell: (mean e (d), Uᵀ (p × d row-major, orthonormal rows), lo, hi, ε).
type Stats = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, f64);

/// [`Stats`] of a ball around the reference rows `ids`: p = 0, ε their largest distance from
/// their mean (rounded up), streamed without a copy of the rows (the top levels' large cells,
/// which only rule out far regions).
fn ball_stats(reference: MatRef<f64>, ids: &[usize]) -> Stats {
    let d = reference.ncols();
    let mut mean = vec![0.0; d];
    for &j in ids {
        for (a, m) in mean.iter_mut().enumerate() {
            *m += reference[(j, a)];
        }
    }
    mean.iter_mut().for_each(|m| *m /= ids.len().max(1) as f64);
    let (mut eps2, mut largest2) = (0.0f64, 0.0f64);
    for &j in ids {
        let (mut e2, mut n2) = (0.0, 0.0);
        for (a, m) in mean.iter().enumerate() {
            let x = reference[(j, a)];
            e2 += (x - m).powi(2);
            n2 += x * x;
        }
        eps2 = eps2.max(e2);
        largest2 = largest2.max(n2);
    }
    (mean, Vec::new(), Vec::new(), Vec::new(), eps2.sqrt() + 1e-12 * largest2.sqrt())
}

/// [`Stats`] of the rows of `block` (r × d) with a subspace of dimension p ≤ [`SUBSPACE`]: U spans
/// a randomized range finder's estimate of the centred rows' top principal directions (Halko,
/// Martinsson, Tropp 2011: a sketch with [`SUBSPACE_OVERSAMPLE`] extra columns, seeded,
/// [`SUBSPACE_POWER`] power iterations, Rayleigh–Ritz); the box and ε are measured on the rows
/// with that U, so the bound holds whatever U is.
fn subspace_stats(block: MatRef<f64>, seed: u64) -> Stats {
    let (r, d) = (block.nrows(), block.ncols());
    if r == 0 {
        return (vec![0.0; d], Vec::new(), Vec::new(), Vec::new(), 0.0);
    }
    let mean: Vec<f64> = (0..d).map(|a| (0..r).map(|i| block[(i, a)]).sum::<f64>() / r as f64).collect();
    let dm = Mat::from_fn(r, d, |i, a| block[(i, a)] - mean[a]);
    let p = SUBSPACE.min(r.saturating_sub(1)).min(d);
    let mut basis: Vec<f64> = Vec::new();
    if p > 0 {
        let w = (p + SUBSPACE_OVERSAMPLE).min(d);
        let mut rng = crate::rng::Normal::new(seed);
        let h = Mat::from_fn(r, w, |_, _| rng.sample());
        let mut qz = orthonormal_columns(crate::linalg::mul(dm.transpose(), h.as_ref()).as_ref());
        for _ in 0..SUBSPACE_POWER {
            let t = crate::linalg::mul(dm.as_ref(), qz.as_ref());
            qz = orthonormal_columns(crate::linalg::mul(dm.transpose(), t.as_ref()).as_ref());
        }
        let t = crate::linalg::mul(dm.as_ref(), qz.as_ref());
        let gram = crate::linalg::mul(t.transpose(), t.as_ref());
        if qz.ncols() > 0 {
            if let Ok(evd) = gram.self_adjoint_eigen(faer::Side::Lower) {
                let vals = evd.S().column_vector();
                let top = vals[qz.ncols() - 1].max(0.0);
                // Eigenvalues ascending: the last p, while above rounding.
                for c in (0..qz.ncols()).rev().take(p) {
                    if top == 0.0 || vals[c] <= 1e-24 * top {
                        break;
                    }
                    let u = crate::linalg::mul(qz.as_ref(), evd.U().subcols(c, 1));
                    basis.extend((0..d).map(|a| u[(a, 0)]));
                }
            }
        }
        // Orthonormal to rounding once more (the bound assumes it).
        let u = orthonormal_columns(MatRef::from_row_major_slice(&basis, basis.len() / d, d).transpose());
        basis = (0..u.ncols()).flat_map(|c| (0..d).map(move |a| (c, a))).map(|(c, a)| u[(a, c)]).collect();
    }
    let q = basis.len() / d;
    let ut = MatRef::from_row_major_slice(&basis, q, d);
    let t = crate::linalg::mul(dm.as_ref(), ut.transpose()); // r × q
    let residual = &dm - &t * ut; // r × d
    let (mut lo, mut hi) = (vec![f64::INFINITY; q], vec![f64::NEG_INFINITY; q]);
    let (mut eps2, mut largest2) = (0.0f64, 0.0f64);
    for i in 0..r {
        eps2 = eps2.max((0..d).map(|a| residual[(i, a)].powi(2)).sum());
        largest2 = largest2.max((0..d).map(|a| block[(i, a)].powi(2)).sum());
        for c in 0..q {
            lo[c] = lo[c].min(t[(i, c)]);
            hi[c] = hi[c].max(t[(i, c)]);
        }
    }
    // Rounded up by far more than the rounding of the products above.
    (mean, basis, lo, hi, eps2.sqrt() + 1e-12 * largest2.sqrt())
}

/// The nearest of the reference rows `read` (ascending vertex ids) to every row of `queries`
/// (|G| × d, squared norms `qn2`), by the exact search's key ‖r_j‖² − 2 q · r_j (row norms and dot
/// products summed over the columns in order, as [`crate::spatial::nearest_rows`] does), ties to
/// the smallest id: a product in f64 screens, the rows within rounding of the smallest key are
/// compared exactly.
fn nearest_among(reference: MatRef<f64>, read: &[usize], queries: MatRef<f64>, qn2: &[f64]) -> Vec<usize> {
    let d = reference.ncols();
    let refs = Mat::from_fn(read.len(), d, |t, a| reference[(read[t], a)]);
    let rn = crate::linalg::row_squared_norms(refs.as_ref());
    let rmax = rn.iter().fold(0.0f64, |a, &b| a.max(b));
    let mut dots = Mat::<f64>::zeros(queries.nrows(), read.len());
    matmul(dots.as_mut(), Accum::Replace, queries, refs.transpose(), 1.0, Par::Seq);
    (0..queries.nrows())
        .map(|i| {
            let key = |t: usize| rn[t] - 2.0 * dots[(i, t)];
            let low = (0..read.len()).map(key).fold(f64::INFINITY, f64::min);
            // Ascending t is ascending id: the strict comparison keeps the smallest id of a tie.
            // Both keys' rounding is below d · 2⁻⁵² · (‖q‖² + ‖r‖²).
            let slack = 1e-12 * (d as f64) * (qn2[i] + rmax);
            let mut best = (f64::INFINITY, usize::MAX);
            for t in (0..read.len()).filter(|&t| key(t) <= low + 2.0 * slack) {
                let dot: f64 = (0..d).map(|c| queries[(i, c)] * refs[(t, c)]).sum();
                let exact = rn[t] - 2.0 * dot;
                if exact < best.0 {
                    best = (exact, t);
                }
            }
            read[best.1]
        })
        .collect()
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

/// The bounds LB(q, C)² (module documentation) of the queries of a group (`queries` |G| × d,
/// squared norms `qn2`) for the run `run` of a level's cells, calling `keep(cell, lb²)` for each
/// cell with rows (lb² one per query). One product of the queries with the run's stacked mean
/// and basis rows; the normal part ‖P⊥(q − e_C)‖ from ‖q − e_C‖² − ‖U_Cᵀ(q − e_C)‖², lowered by a
/// rounding slack so that the bound stays a lower bound.
fn bound_run(level: &Level, run: Range<usize>, queries: MatRef<f64>, qn2: &[f64], mut keep: impl FnMut(usize, &[f64])) {
    let (first, last) = (&level.cells[run.start], &level.cells[run.end - 1]);
    let rows = first.at..last.at + 1 + last.lo.len();
    let mut prod = Mat::<f64>::zeros(queries.nrows(), rows.len());
    matmul(
        prod.as_mut(),
        Accum::Replace,
        queries,
        level.stack.subrows(rows.start, rows.len()).transpose(),
        1.0,
        Par::Seq,
    );
    let mut lb2 = vec![0.0; queries.nrows()];
    for t in run {
        let cell = &level.cells[t];
        if cell.rows.is_empty() {
            continue;
        }
        let o = cell.at - rows.start;
        for (i, lb) in lb2.iter_mut().enumerate() {
            let v2 = qn2[i] - 2.0 * prod[(i, o)] + cell.mean_sq;
            let (mut x2, mut box2) = (0.0, 0.0);
            for c in 0..cell.lo.len() {
                let x = prod[(i, o + 1 + c)] - cell.basis_mean[c];
                x2 += x * x;
                let out = (cell.lo[c] - x).max(x - cell.hi[c]).max(0.0);
                box2 += out * out;
            }
            let slack = 1e-12 * (qn2[i] + cell.mean_sq);
            let perp = (v2 - x2 - slack).max(0.0).sqrt();
            let normal = (perp - cell.eps).max(0.0);
            *lb = box2 + normal * normal;
        }
        keep(t, &lb2);
    }
}

/// The leaves that some query of a group cannot rule out with the squared thresholds `limit2`,
/// found top down; and the number of cells bounded.
fn candidate_leaves(tree: &CellTree, queries: MatRef<f64>, qn2: &[f64], limit2: &[f64]) -> (Vec<usize>, u64) {
    let top: Range<usize> = 0..tree.levels[0].cells.len();
    let mut runs: Vec<Range<usize>> = std::iter::once(top).collect();
    let mut bounded = 0u64;
    let depth = tree.levels.len();
    let mut leaves = Vec::new();
    for (l, level) in tree.levels.iter().enumerate() {
        let mut next = Vec::new();
        for run in runs {
            bounded += run.len() as u64;
            bound_run(level, run, queries, qn2, |t, lb2| {
                if lb2.iter().zip(limit2).any(|(b, l)| b <= l) {
                    if l + 1 == depth {
                        leaves.push(t);
                    } else {
                        next.push(level.cells[t].children.clone());
                    }
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
/// Errors: mismatched sizes, ids out of range, a non-finite entry in either embedding.
pub fn certify_nearest_rows(
    reference: MatRef<f64>,
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
    let mut cert = Certificate { queries: rows.len(), references: m, ..Certificate::default() };
    if rows.is_empty() {
        return Ok(cert);
    }
    let (Some(max_r), Some(max_q)) = (crate::linalg::max_abs_finite(reference), crate::linalg::max_abs_finite(query))
    else {
        return Err(Error::invalid("certified search", "an embedding contains a non-finite value"));
    };
    // Slack for rounding in the bounds: far above it (≈ 10⁻¹⁵ of the rows' norms), far below any
    // distance that matters.
    let tol = 1e-9 * (max_r + max_q) * (d as f64).sqrt();
    let t0 = std::time::Instant::now();
    let tree = CellTree::new(reference, reference_positions, seed)?;
    if std::env::var_os("FUNCORR_DEBUG_CERTIFIED").is_some() {
        eprintln!("certified search: cells in {:.2} s", t0.elapsed().as_secs_f64());
    }
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
                        (0..d).map(|a| (queries[(i, a)] - reference[(j, a)]).powi(2)).sum::<f64>().sqrt() + tol
                    })
                    .collect()
            };
            // The exact search among the rows of `leaves` and the current answers.
            let search = |leaves: &[usize], best: &[usize]| -> Result<(Vec<usize>, usize)> {
                let level = &tree.levels[tree.levels.len() - 1];
                let mut read: Vec<usize> = best.to_vec();
                for &t in leaves {
                    read.extend_from_slice(&tree.rows[level.cells[t].rows.clone()]);
                }
                read.sort_unstable();
                read.dedup();
                Ok((nearest_among(reference, &read, queries.as_ref(), &qn2), read.len()))
            };
            // First the leaves that hold the group's answers: the group's queries are
            // neighbours, so where a restricted answer is far off, its neighbours' answers
            // usually lie next to the right row, and the thresholds tighten before the descent.
            let mut own: Vec<usize> = best.iter().map(|&j| tree.leaf_of[j] as usize).collect();
            own.sort_unstable();
            own.dedup();
            let (found, r1) = search(&own, &best)?;
            best = found;
            // Then one descent with those thresholds, and every leaf it leaves that was not read.
            let limit2: Vec<f64> = thresholds(&best).iter().map(|x| x * x).collect();
            let (leaves, bounded) = candidate_leaves(&tree, queries.as_ref(), &qn2, &limit2);
            let rest: Vec<usize> = leaves.into_iter().filter(|t| own.binary_search(t).is_err()).collect();
            let (found, r2) = if rest.is_empty() { (best.clone(), 0) } else { search(&rest, &best)? };
            let pairs = group.iter().zip(found).map(|(&s, j)| (s, j)).collect();
            let read = r1 + r2;
            Ok((pairs, (len * read) as u64, bounded))
        })
        .collect();
    crate::progress::check()?;
    for r in results {
        let (pairs, rows_read, bounded) = r?;
        cert.rows_read += rows_read;
        cert.cells_bounded += bounded;
        for (s, j) in pairs {
            if answer[s] != j {
                answer[s] = j;
                cert.changed += 1;
            }
        }
    }
    Ok(cert)
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
        let reference = Mat::from_fn(m, d, |j, a| feature(&p[j], a));
        // Queries: the rows plus noise, at the positions of a rotated copy (so each query's nearest
        // row is nearby, and the groups are cells of another partition than Y's).
        let mut rng = crate::rng::Normal::new(3);
        let qpos: Vec<[f64; 3]> = p.iter().map(|x| [x[1], -x[0], x[2]]).collect();
        let query = Mat::from_fn(m, d - 2, |i, a| feature(&p[i], a) + 0.01 * rng.sample());
        let exact = crate::spatial::nearest_rows(
            reference.as_ref(),
            Mat::from_fn(m, d, |i, a| if a < d - 2 { query[(i, a)] } else { 0.0 }).as_ref(),
        )
        .unwrap();
        let rows: Vec<usize> = (0..m).collect();
        for start in
            [vec![0; m], exact.iter().enumerate().map(|(i, &j)| if i % 3 == 0 { (j + 1) % m } else { j }).collect()]
        {
            let mut answer = start.clone();
            let cert =
                certify_nearest_rows(reference.as_ref(), query.as_ref(), &p, &qpos, &rows, &mut answer, 1).unwrap();
            assert_eq!(answer, exact);
            assert_eq!(cert.changed, start.iter().zip(&exact).filter(|(a, b)| a != b).count());
        }
        // A near-exact start reads a small part of Y.
        let mut answer = exact.clone();
        let cert = certify_nearest_rows(reference.as_ref(), query.as_ref(), &p, &qpos, &rows, &mut answer, 1).unwrap();
        assert_eq!(cert.changed, 0);
        assert!(cert.share_read() < 0.5, "read {:.3} of Y", cert.share_read());
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = crate::primitives::icosphere(1).vertices().to_vec();
        let m = p.len();
        let r = Mat::from_fn(m, 3, |j, a| p[j][a]);
        let mut answer = vec![0; m];
        let rows: Vec<usize> = (0..m).collect();
        assert!(certify_nearest_rows(r.as_ref(), r.as_ref(), &p[1..], &p, &rows, &mut answer, 0).is_err());
        assert!(certify_nearest_rows(r.as_ref(), r.as_ref(), &p, &p, &rows[1..], &mut answer, 0).is_err());
        let mut bad = answer.clone();
        bad[0] = m;
        assert!(certify_nearest_rows(r.as_ref(), r.as_ref(), &p, &p, &rows, &mut bad, 0).is_err());
        let mut nan = r.clone();
        nan[(2, 1)] = f64::NAN;
        assert!(certify_nearest_rows(nan.as_ref(), r.as_ref(), &p, &p, &rows, &mut answer, 0).is_err());
    }
}
