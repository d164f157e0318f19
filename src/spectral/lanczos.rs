//! Block Lanczos with full reorthogonalization and thick restart, in shift-invert mode, for the
//! low end of the spectrum of W φ = λ A φ. See the documentation of [`crate::spectral`].

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::matmul;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::column as col;
use super::{relative_residuals_scaled, Normal, Progress, SolveInfo, SpectralOptions};
use crate::cholesky::SparseLlt;
use crate::error::{Error, Result};
use crate::laplacian::Laplacian;
use crate::linalg::{a_b_in_place, a_b_into, at_b_as_bt_a, dot, RowChunks};

// The Krylov basis is tall and skinny (n × p with p ≪ n) and the blocks are thin (b columns):
// its products are `crate::linalg`'s row-chunked ones, with the chunking tuned for them.
const CHUNKS: RowChunks = RowChunks::KRYLOV;

/// Eigen-decomposition (ascending) of the small symmetric projected matrix, sequentially:
/// faer's parallel tridiagonal solver spins at barriers and is slower for p ≲ 1000 here.
fn ritz_eigen(h: MatRef<f64>) -> Result<(Vec<f64>, Mat<f64>)> {
    use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
    let p = h.nrows();
    let mut s = faer::diag::Diag::<f64>::zeros(p);
    let mut u = Mat::<f64>::zeros(p, p);
    let mut buf =
        MemBuffer::new(self_adjoint_evd_scratch::<f64>(p, ComputeEigenvectors::Yes, Par::Seq, Default::default()));
    self_adjoint_evd(h, s.as_mut(), Some(u.as_mut()), Par::Seq, MemStack::new(&mut buf), Default::default())
        .map_err(|e| Error::numerical("eigensolver", format!("Ritz eigenproblem failed: {e:?}")))?;
    Ok(((0..p).map(|i| s[i]).collect(), u))
}

/// The shift-invert operator Op = A^{1/2} (W + sA)⁻¹ A^{1/2}.
struct ShiftInvert<'a> {
    llt: SparseLlt,
    sqrt_m: &'a [f64],
}

impl ShiftInvert<'_> {
    /// out = Op x, for an n × b block.
    fn apply(&self, x: MatRef<f64>, mut out: MatMut<f64>) {
        out.copy_from(x);
        scale_rows(out.rb_mut(), self.sqrt_m);
        self.llt.solve_in_place(out.rb_mut());
        scale_rows(out.rb_mut(), self.sqrt_m);
    }
}

fn scale_rows(mut x: MatMut<f64>, s: &[f64]) {
    for j in 0..x.ncols() {
        let mut c = x.rb_mut().col_mut(j);
        for (i, si) in s.iter().enumerate() {
            c[i] *= si;
        }
    }
}

/// Factors W + sA with a shift s > 0 small against the low end of the spectrum. s starts at
/// 1e-6 · tr(W)/tr(A) (tr(W)/tr(A) is the mean of the spectrum, so s is far below the
/// eigenvalues we want on any mesh or graph of more than a few hundred vertices, yet keeps the
/// matrix safely definite) and grows tenfold if the factorization reports a non-positive pivot.
fn factor<'a>(lap: &Laplacian, sqrt_m: &'a [f64]) -> Result<(ShiftInvert<'a>, f64)> {
    let mut s = super::low_end_scale(lap);
    if !(s.is_finite() && s > 0.0) {
        return Err(Error::invalid("W", "the stiffness matrix has no positive diagonal (no edges?)"));
    }
    let symbolic = lap.symbolic_cholesky()?;
    let mut last_err = String::new();
    for _ in 0..6 {
        let k_mat = lap.combination(1.0, s);
        match SparseLlt::new(k_mat.as_ref(), symbolic.clone()) {
            Ok(llt) => return Ok((ShiftInvert { llt, sqrt_m }, s)),
            Err(e) => {
                last_err = e;
                s *= 10.0;
            }
        }
    }
    Err(Error::numerical("eigensolver", format!("Cholesky factorization of W + sA failed: {last_err}")))
}

/// Euclidean norm of a slice.
fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Orthogonalizes the columns of `w` (n × b) against the orthonormal columns of `v` (n × j)
/// with two passes of block classical Gram–Schmidt, accumulating the coefficients into `c` (j × b).
fn project_out(v: MatRef<f64>, mut w: MatMut<f64>, mut c: MatMut<f64>) {
    c.fill(0.0);
    for _pass in 0..2 {
        gram_schmidt_pass(v, w.rb_mut(), c.rb_mut());
    }
}

/// One pass of block classical Gram–Schmidt: w ← w − V (Vᵀ w), c += Vᵀ w (V n × j, w n × b,
/// c j × b).
fn gram_schmidt_pass(v: MatRef<f64>, mut w: MatMut<f64>, mut c: MatMut<f64>) {
    let coef = at_b_as_bt_a(v, w.rb(), CHUNKS);
    a_b_into(w.rb_mut(), true, v, coef.as_ref(), -1.0, CHUNKS);
    c += &coef;
}

/// Orthogonalizes the new block w = Op V[:, j0..j1] (n × b) against the basis V[:, ..j1]
/// (n × j1), accumulating the coefficients into `c` (j1 × b): the column block H[..j1, j0..j1].
///
/// In exact arithmetic the block Lanczos recurrence makes w orthogonal to every column before
/// `local_from` (the previous block, or the whole basis for the first block after a thick
/// restart, whose image couples to every kept Ritz vector), so a first pass against
/// V[:, local_from..j1] removes everything but round-off. Then full passes against all of V,
/// repeated while a pass removes more than 1 − 1/√2 of a column's norm (the Daniel–Gragg–
/// Kaufman–Stewart test, "twice is enough" of Parlett): orthogonality to working precision,
/// with one full pass where the old scheme always made two (the full passes read the whole
/// n × j1 basis twice each; they were half of the solver's time at 5k vertices).
fn reorthogonalize(v: MatRef<f64>, local_from: usize, mut w: MatMut<f64>, mut c: MatMut<f64>) {
    const ETA: f64 = std::f64::consts::FRAC_1_SQRT_2;
    let j1 = v.ncols();
    c.fill(0.0);
    let mut full_passes = 0;
    if local_from > 0 {
        gram_schmidt_pass(
            v.subcols(local_from, j1 - local_from),
            w.rb_mut(),
            c.rb_mut().subrows_mut(local_from, j1 - local_from),
        );
    } else {
        gram_schmidt_pass(v, w.rb_mut(), c.rb_mut());
        full_passes = 1;
    }
    // At most three full passes: a vector that keeps losing norm lies (numerically) in the span
    // of V; orthonormalize_block then replaces it by a fresh direction.
    while full_passes < 3 {
        let before: Vec<f64> = (0..w.ncols()).map(|j| norm(col(w.rb(), j))).collect();
        gram_schmidt_pass(v, w.rb_mut(), c.rb_mut());
        full_passes += 1;
        let enough = (0..w.ncols()).all(|j| norm(col(w.rb(), j)) >= ETA * before[j]);
        if enough {
            break;
        }
    }
}

/// Orthonormalizes the block `w` (n × b, already orthogonal to `v`) in place: w = Q β with β
/// upper triangular (b × b), by modified Gram–Schmidt applied twice. A column that is
/// (numerically) in the span of the previous ones (norm below 1e-10 of its norm before
/// projection) is replaced by a fresh random direction orthogonal to everything, with a zero
/// diagonal in β.
fn orthonormalize_block(v: MatRef<f64>, w: &mut Mat<f64>, norms_before: &[f64], rng: &mut Normal) -> Mat<f64> {
    let (n, b) = (w.nrows(), w.ncols());
    let mut beta = Mat::<f64>::zeros(b, b);
    for i in 0..b {
        let (done, mut rest) = w.as_mut().split_at_col_mut(i);
        let done = done.rb();
        let wi = rest.rb_mut().col_mut(0).try_as_col_major_mut().expect("column-major").as_slice_mut();
        for _pass in 0..2 {
            for l in 0..i {
                let q = col(done, l);
                let d = dot(q, wi);
                beta[(l, i)] += d;
                wi.iter_mut().zip(q).for_each(|(x, y)| *x -= d * y);
            }
        }
        let nrm = norm(wi);
        if nrm > 0.0 && nrm > 1e-10 * norms_before[i] {
            beta[(i, i)] = nrm;
            wi.iter_mut().for_each(|x| *x /= nrm);
        } else {
            // Deflation: the Krylov space lost a direction; continue with a random one.
            let mut fresh = Mat::<f64>::from_fn(n, 1, |_, _| rng.sample());
            let mut c = Mat::<f64>::zeros(v.ncols(), 1);
            project_out(v, fresh.as_mut(), c.as_mut());
            let f = fresh.col_as_slice_mut(0);
            for _pass in 0..2 {
                for l in 0..i {
                    let q = col(done, l);
                    let d = dot(q, f);
                    f.iter_mut().zip(q).for_each(|(x, y)| *x -= d * y);
                }
            }
            let fnorm = norm(f);
            wi.iter_mut().zip(f.iter()).for_each(|(x, y)| *x = y / fnorm);
            beta[(i, i)] = 0.0;
        }
    }
    beta
}

/// Block Lanczos with full reorthogonalization and thick restart for the k largest eigenvalues
/// θ of Op. Returns (λ = 1/θ − s ascending, U n × k orthonormal).
///
/// Exact multiplicities. A block Krylov space started from b vectors contains at most b
/// independent vectors of any eigenspace, so an eigenvalue of multiplicity m > b (symmetric
/// shapes: 5 on an icosphere, 2l+1 on a round sphere) would be returned only b times, with the
/// wrong eigenvalues filling the gap. When a run returns a cluster of b or more equal eigenvalues
/// (relative spread ≤ 1e-6 of λ_k), we cannot tell whether copies are missing, so the solve is
/// repeated with twice that block size until every cluster is smaller than the block.
pub(super) fn lanczos(
    lap: &Laplacian,
    sqrt_m: &[f64],
    opts: &SpectralOptions,
    progress: Option<Progress>,
) -> Result<(Vec<f64>, Mat<f64>, SolveInfo)> {
    let k = opts.k;
    let t0 = Instant::now();
    let (op, shift) = factor(lap, sqrt_m)?;
    let factor_seconds = t0.elapsed().as_secs_f64();
    // Measured on FAUST (5k), TOSCA cat (28k) and david (52k): small blocks win for small k
    // (higher Krylov degree per dimension), larger ones for large k (better GEMM efficiency) —
    // except below CHUNKS.parallel_from rows, where the basis products run on one core and 16
    // columns buy less than they cost: k = 350 on tr_reg_000 (4,999 vertices), fastest of 7,
    // 0.661 s with 16, 0.528 s with 8 (cat0, 28k: 2.48 against 2.65 s; david0: 4.79 against
    // 4.96 s, fastest of 3).
    let mut b = opts
        .block_size
        .unwrap_or(if k <= 120 {
            4
        } else if k <= 250 || lap.n() < CHUNKS.parallel_from {
            8
        } else {
            16
        })
        .max(1);
    let mut applications = 0;
    loop {
        let (lambda, u, mut info) = lanczos_run(lap, sqrt_m, &op, shift, b, opts, progress)?;
        info.factor_seconds = factor_seconds;
        applications += info.operator_applications;
        info.operator_applications = applications;
        let tol = 1e-6 * lambda[k - 1].abs();
        let mut largest = 1;
        let mut run = 1;
        for i in 1..k {
            run = if lambda[i] - lambda[i - 1] <= tol { run + 1 } else { 1 };
            largest = largest.max(run);
        }
        if largest < b {
            info.iterate_seconds = t0.elapsed().as_secs_f64() - factor_seconds;
            return Ok((lambda, u, info));
        }
        b = 2 * largest;
    }
}

/// Residuals (relative to the tolerance) below which a thick-restart cycle of [`lanczos_run`]
/// checks its Ritz pairs before the basis is full: four orders of magnitude, about what one cycle
/// gains on our meshes (david0, k = 50: 2.4e-4 → 1.1e-8 from the second restart to the third).
const EARLY_RESIDUALS: f64 = 1e4;

/// Ritz vectors a thick restart keeps in a basis of at most `pmax` columns (k wanted pairs,
/// block size b): about k + (pmax − k) / 3, rounded so that pmax − keep is a whole number of
/// blocks.
fn restart_keep(pmax: usize, k: usize, b: usize) -> usize {
    pmax - (pmax - (k + (pmax - k) / 3).min(pmax - 2 * b)).div_ceil(b) * b
}

/// One block Lanczos solve with block size b.
#[allow(clippy::too_many_arguments)]
fn lanczos_run(
    lap: &Laplacian,
    sqrt_m: &[f64],
    op: &ShiftInvert,
    shift: f64,
    b: usize,
    opts: &SpectralOptions,
    progress: Option<Progress>,
) -> Result<(Vec<f64>, Mat<f64>, SolveInfo)> {
    let n = lap.n();
    let k = opts.k;
    let t1 = Instant::now();
    // Maximum basis size: about 2k (as ARPACK's default ncv), at least k + 4b.
    // (Measured: 1.5k restarts too often, 2.5k–3k spend more in orthogonalization than they save.)
    if opts.block_size.is_some() && b.saturating_mul(6) > n {
        // A user's block size: say so, rather than blaming k (the basis holds ≥ k + 5 blocks).
        return Err(Error::invalid(
            "block_size",
            format!(
                "a Lanczos block size of {b} needs more than {} vertices (n = {n}); use at most {}",
                b.saturating_mul(6),
                n / 6
            ),
        ));
    }
    let pmax = (2 * k).max(k + 4 * b).div_ceil(b) * b;
    if pmax + b > n {
        return Err(Error::invalid(
            "k",
            format!("k = {k} is too large for the iterative solver on n = {n} vertices (needs n > {}); ask for fewer eigenpairs", pmax + b),
        ));
    }
    let keep = restart_keep(pmax, k, b);

    let mut rng = Normal::new(opts.seed);
    let mut v = Mat::<f64>::zeros(n, pmax + b);
    let mut h = Mat::<f64>::zeros(pmax + b, pmax + b);
    // Start block.
    {
        let mut w = Mat::<f64>::from_fn(n, b, |_, _| rng.sample());
        let norms: Vec<f64> = (0..b).map(|j| norm(w.col_as_slice(j))).collect();
        let empty = Mat::<f64>::zeros(n, 0);
        orthonormalize_block(empty.as_ref(), &mut w, &norms, &mut rng);
        v.subcols_mut(0, b).copy_from(&w);
    }
    // Columns of V whose Op-image has been projected.
    let mut p = 0usize;
    // First column of the block whose image couples to the whole basis (the start block, then
    // the residual block after each thick restart).
    let mut restart_block = 0usize;
    // Seconds in the solves, the reorthogonalization, the in-block orthonormalization, the
    // Rayleigh–Ritz steps with their residuals, and the restarts (FUNCORR_DEBUG_LANCZOS).
    let mut phase_seconds = [0.0f64; 5];
    let mut info =
        SolveInfo { method: "block-lanczos".into(), shift, block_size: b, max_basis: pmax, ..Default::default() };
    let mut w = Mat::<f64>::zeros(n, b);
    let mut tol = opts.tol;
    let floor = super::low_end_scale(lap);
    // In a cycle that starts with every unconverged pair's residual within EARLY_RESIDUALS ×
    // tol, the Ritz pairs are also checked every `stride` columns (about four times per cycle),
    // not only at pmax: the last pairs to converge tend to pass just after a check (david0,
    // k = 50: 49 of 50 at 1.07 tol), and a whole cycle of solves was spent on that margin. (In
    // other cycles a check, O(p³) for the projected matrix, rarely finishes the solve.)
    let stride = ((pmax - keep) / 4).div_ceil(b).max(1) * b;
    let mut check_early = false;
    loop {
        // Expand the Krylov basis up to pmax columns, checking the Ritz pairs on the way.
        if p < pmax {
            crate::progress::check()?;
            let (j0, j1) = (p, p + b);
            let ta = Instant::now();
            op.apply(v.subcols(j0, b), w.as_mut());
            phase_seconds[0] += ta.elapsed().as_secs_f64();
            let ta = Instant::now();
            info.operator_applications += b;
            let norms: Vec<f64> = (0..b).map(|j| norm(w.col_as_slice(j))).collect();
            let mut c = Mat::<f64>::zeros(j1, b);
            let local_from = if j0 <= restart_block { 0 } else { j0 - b };
            reorthogonalize(v.subcols(0, j1), local_from, w.as_mut(), c.as_mut());
            phase_seconds[1] += ta.elapsed().as_secs_f64();
            let ta = Instant::now();
            let beta = orthonormalize_block(v.subcols(0, j1), &mut w, &norms, &mut rng);
            phase_seconds[2] += ta.elapsed().as_secs_f64();
            h.submatrix_mut(0, j0, j1, b).copy_from(&c);
            h.submatrix_mut(j1, j0, b, b).copy_from(&beta);
            v.subcols_mut(j1, b).copy_from(&w);
            p = j1;
            let early = check_early && p >= k + b && (p - restart_block).is_multiple_of(stride);
            if p < pmax && !early {
                continue;
            }
        }
        let tr = Instant::now();
        // Rayleigh–Ritz on the symmetrized projected matrix.
        let mut hs = Mat::<f64>::zeros(p, p);
        for j in 0..p {
            for i in 0..p {
                hs[(i, j)] = 0.5 * (h[(i, j)] + h[(j, i)]);
            }
        }
        let (evals, evecs) = ritz_eigen(hs.as_ref())?;
        // Descending θ: column p−1−i of the ascending decomposition.
        let theta: Vec<f64> = (0..p).map(|i| evals[p - 1 - i]).collect();
        let y = Mat::<f64>::from_fn(p, p, |r, c| evecs[(r, p - 1 - c)]);
        // Residuals. The block Lanczos relation Op V = V H + V_next β Eᵀ gives, for a Ritz pair
        // (θ, u = V y), Op u − θu = V_next β y_last, and multiplying by (L̃ + s):
        //   (L̃ − λ) u = −(L̃ + s) V_next β y_last / θ,   λ = 1/θ − s.
        // With G = (L̃ + s) V_next β (n × b, b sparse products) the true residual of every pair is
        // ‖G y_last‖/θ = √(y_lastᵀ (GᵀG) y_last)/θ: the same measure as the final verification,
        // unlike ‖β y_last‖, which can underestimate it by orders of magnitude.
        let beta_last = h.submatrix(p, p - b, b, b).to_owned();
        let mut g = Mat::<f64>::zeros(n, b);
        for j in 0..b {
            let x: Vec<f64> = col(v.as_ref(), p + j).iter().zip(sqrt_m).map(|(x, s)| x / s).collect();
            let wx = lap.apply_w(&x);
            for (i, gi) in g.col_as_slice_mut(j).iter_mut().enumerate() {
                *gi = (wx[i] / sqrt_m[i]) + shift * col(v.as_ref(), p + j)[i];
            }
        }
        let g = {
            let mut gb = Mat::<f64>::zeros(n, b);
            a_b_into(gb.as_mut(), false, g.as_ref(), beta_last.as_ref(), 1.0, CHUNKS);
            gb
        };
        let gram = at_b_as_bt_a(g.as_ref(), g.as_ref(), CHUNKS);
        let lambda_ref = super::residual_scale(1.0 / theta[k - 1] - shift, floor);
        let resid: Vec<f64> = (0..k)
            .map(|i| {
                let yl = y.submatrix(p - b, i, b, 1);
                let q = yl.transpose() * &gram * yl;
                q[(0, 0)].max(0.0).sqrt() / theta[i] / lambda_ref
            })
            .collect();
        phase_seconds[3] += tr.elapsed().as_secs_f64();
        let converged = (0..k).take_while(|&i| theta[i] > 0.0 && resid[i] <= tol).count();
        if p >= pmax {
            check_early = (0..k).all(|i| theta[i] > 0.0 && resid[i] <= EARLY_RESIDUALS * tol);
        }
        if let Some(cb) = progress {
            cb(converged, k);
        }
        crate::progress::step(converged, k)?;
        if std::env::var_os("FUNCORR_DEBUG_LANCZOS").is_some() {
            let worst = resid.iter().copied().fold(0.0, f64::max);
            eprintln!("restart {} p {p} converged {converged}/{k} worst {worst:.2e} tol {tol:.1e} seconds solve/reorth/block/ritz/restart {phase_seconds:.3?}", info.restarts);
        }
        // Ritz vectors the next restart keeps (fewer after a failed final check, below).
        let mut kept = keep;
        if converged == k {
            // U = V Y[:, ..k] in place, in V's leading k columns: no second n × k matrix (fresh
            // memory costs 2–5 s per GB at first touch on our VMs; 0.67 GB at 840k, k = 100).
            a_b_in_place(v.subcols_mut(0, p), p, y.subcols(0, k), CHUNKS);
            let lambda: Vec<f64> = (0..k).map(|i| 1.0 / theta[i] - shift).collect();
            // Verify explicitly; if round-off made the estimate optimistic, tighten once and go on.
            if tol < opts.tol || residuals_ok(lap, sqrt_m, v.subcols(0, k), &lambda, opts.max_residual) {
                info.iterate_seconds = t1.elapsed().as_secs_f64();
                v.truncate(n, k);
                return Ok((lambda, v, info));
            }
            tol *= 0.1;
            // V's leading columns hold the k leading Ritz vectors now (the other Krylov vectors
            // they came from are overwritten): the restart keeps those, rounded down to whole
            // blocks so that the basis still fills up to pmax in whole blocks.
            kept = k / b * b;
        }
        if converged < k && p < pmax {
            // An early check (see `stride`): expand on.
            continue;
        }
        if info.restarts >= opts.max_restarts {
            return Err(Error::numerical(
                "eigensolver",
                format!(
                    "only {converged} of {k} eigenpairs converged after {} restarts (tol {:.1e})",
                    info.restarts, tol
                ),
            ));
        }
        // Thick restart: keep the `keep` leading Ritz vectors and the residual block.
        info.restarts += 1;
        let tr = Instant::now();
        if kept == keep {
            a_b_in_place(v.subcols_mut(0, p), p, y.subcols(0, keep), CHUNKS);
        }
        let resid_block = v.subcols(p, b).to_owned();
        v.subcols_mut(kept, b).copy_from(&resid_block);
        h.fill(0.0);
        for i in 0..kept {
            h[(i, i)] = theta[i];
        }
        // Coupling of the residual block to the kept Ritz vectors: β_last · Y[last block, :kept].
        let mut coupling = Mat::<f64>::zeros(b, kept);
        matmul(coupling.as_mut(), Accum::Replace, beta_last.as_ref(), y.submatrix(p - b, 0, b, kept), 1.0, Par::Seq);
        h.submatrix_mut(kept, 0, b, kept).copy_from(&coupling);
        p = kept;
        restart_block = kept;
        phase_seconds[4] += tr.elapsed().as_secs_f64();
    }
}

/// Checks the relative residuals of the Ritz vectors U (n × k, symmetric form) against max_res.
fn residuals_ok(lap: &Laplacian, sqrt_m: &[f64], u: MatRef<f64>, lambda: &[f64], max_res: f64) -> bool {
    relative_residuals_scaled(lap, u, Some(sqrt_m), lambda).iter().all(|r| *r <= max_res)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first k eigenvalues λ of the unit-area problem, scaled back by the area `total`,
    /// equal the dense solver's to 10⁻⁹ λ_k.
    fn assert_eigenvalues_match(lambda: &[f64], total: f64, dense: &[f64], k: usize) {
        for i in 0..k {
            let l = lambda[i] / total;
            assert!((l - dense[i]).abs() < 1e-9 * dense[k - 1], "λ[{i}] {l} vs {}", dense[i]);
        }
    }

    /// A final check that fails (an acceptance threshold no residual meets) restarts from the
    /// k Ritz vectors computed in place, rounded down to whole blocks (k = 30, b = 4: 28 kept),
    /// and the pairs it then returns are the dense solver's.
    #[test]
    fn a_failed_final_check_restarts_from_the_ritz_vectors_in_place() {
        let lap = crate::laplacian::cotangent(&crate::primitives::icosphere(3)).unwrap();
        let k = 30;
        let dense = super::super::eigen_basis(&lap, &SpectralOptions::new(k), None).unwrap().0;
        let total: f64 = lap.mass.iter().sum();
        let unit = lap.with_mass(lap.mass.iter().map(|a| a / total).collect());
        let sqrt_m: Vec<f64> = unit.mass.iter().map(|a| a.sqrt()).collect();
        let mut opts = SpectralOptions::new(k);
        opts.block_size = Some(4);
        opts.max_residual = 1e-300;
        let (lambda, u, info) = lanczos(&unit, &sqrt_m, &opts, None).unwrap();
        assert!(info.restarts >= 1, "{info:?}");
        assert_eq!((u.nrows(), u.ncols()), (lap.n(), k));
        assert_eigenvalues_match(&lambda, total, &dense.eigenvalues, k);
        let gram = u.transpose() * &u;
        for i in 0..k {
            for j in 0..k {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((gram[(i, j)] - e).abs() < 1e-10, "UᵀU[{i},{j}] = {}", gram[(i, j)]);
            }
        }
    }

    /// A cycle that starts near convergence stops at an early check, before the basis is full
    /// (bumpy sphere, 2,562 vertices, k = 50, b = 2: 158 solves instead of the 168 of whole
    /// cycles), and the pairs it returns are the dense solver's.
    #[test]
    fn a_cycle_near_convergence_stops_at_an_early_check() {
        let lap = crate::laplacian::cotangent(&crate::primitives::bumpy_sphere(4)).unwrap();
        let (k, b) = (50, 2);
        let mut dense_opts = SpectralOptions::new(k);
        dense_opts.dense_below = usize::MAX;
        let dense = super::super::eigen_basis(&lap, &dense_opts, None).unwrap().0;
        let total: f64 = lap.mass.iter().sum();
        let unit = lap.with_mass(lap.mass.iter().map(|a| a / total).collect());
        let sqrt_m: Vec<f64> = unit.mass.iter().map(|a| a.sqrt()).collect();
        let mut opts = SpectralOptions::new(k);
        opts.block_size = Some(b);
        let (lambda, _, info) = lanczos(&unit, &sqrt_m, &opts, None).unwrap();
        // Whole cycles: pmax solves, then pmax − keep per restart.
        let pmax = info.max_basis;
        let keep = restart_keep(pmax, k, b);
        let whole = pmax + info.restarts * (pmax - keep);
        assert!(info.restarts >= 1 && info.operator_applications < whole, "{info:?}, whole cycles {whole}");
        assert_eigenvalues_match(&lambda, total, &dense.eigenvalues, k);
    }

    /// A block almost entirely in the span of the basis, partly outside the local range: the
    /// local pass and the repeated full passes (the DGKS test fires) leave it orthogonal to
    /// every column to round-off, and the coefficients are those of the projection.
    #[test]
    fn reorthogonalization_repeats_full_passes_until_orthogonal() {
        let (n, j, b) = (600, 40, 4);
        let mut rng = Normal::new(7);
        let v = Mat::<f64>::from_fn(n, j, |_, _| rng.sample()).qr().compute_thin_Q();
        let coef = Mat::<f64>::from_fn(j, b, |_, _| rng.sample());
        let fresh = Mat::<f64>::from_fn(n, b, |_, _| 1e-9 * rng.sample());
        for local_from in [0, j - 2 * b] {
            let mut w = &v * &coef + &fresh;
            let mut c = Mat::<f64>::zeros(j, b);
            reorthogonalize(v.as_ref(), local_from, w.as_mut(), c.as_mut());
            let left = v.transpose() * &w;
            let worst =
                (0..j).flat_map(|r| (0..b).map(move |q| (r, q))).fold(0.0f64, |m, (r, q)| m.max(left[(r, q)].abs()));
            let wnorm = (0..b).map(|q| norm(col(w.as_ref(), q))).fold(0.0, f64::max);
            assert!(worst <= 1e-12 * wnorm, "local_from {local_from}: |Vᵀw| {worst:e}, |w| {wnorm:e}");
            // Coefficients: coef plus the (tiny) projection of the fresh part.
            let expect = &coef + v.transpose() * &fresh;
            let err = (0..j)
                .flat_map(|r| (0..b).map(move |q| (r, q)))
                .fold(0.0f64, |m, (r, q)| m.max((c[(r, q)] - expect[(r, q)]).abs()));
            assert!(err < 1e-12, "local_from {local_from}: coefficients off by {err:e}");
        }
    }
}
