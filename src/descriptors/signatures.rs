//! Spectral point signatures computed from a Laplacian eigenbasis (λᵢ, φᵢ), i = 1..k, with
//! Φᵀ A Φ = I. Cost O(n·k·N) for N functions (one n × k by k × N product).
//!
//! - Heat kernel signature (Sun, Ovsjanikov, Guibas 2009): h_t(x) = Σᵢ e^{−λᵢt} φᵢ(x)², at N
//!   times log-spaced between t_min = 4 ln 10 / λ_k and t_max = 4 ln 10 / λ₁ (λ₁ the first non-zero
//!   eigenvalue), as in the original paper.
//! - Wave kernel signature (Aubry, Schlickewei, Cremers 2011): w_e(x) = Σᵢ φᵢ(x)² g_e(λᵢ) / Σᵢ g_e(λᵢ)
//!   with log-energy Gaussian bands g_e(λ) = exp(−(e − ln λ)² / 2σ²), N energies e evenly spaced in
//!   [ln λ₁ + 2σ, ln λ_k − 2σ], σ = 6 · (ln λ_k − ln λ₁) / N (the original's variance factor 6; the
//!   ±2σ margins as in pyFM). Zero eigenvalues are left out.
//! - Heat kernel maps (Ovsjanikov, Mérigot, Mémoli, Guibas 2010): k_t(p, x) = Σᵢ e^{−λᵢt} φᵢ(p) φᵢ(x)
//!   for seed vertices p.
//!
//! Scale normalization (`normalize = true`): heat quantities are multiplied by |A| / Σᵢ e^{−λᵢt}
//! and WKS by |A|, |A| = Σ aᵢ the total vertex weight (the area of a mesh). Each column then has
//! area-weighted mean 1 (over the k computed eigenpairs), and since times and energies are derived
//! from the spectrum, the signatures of a uniformly rescaled shape are unchanged.
//!
//! Determinism: the one product per signature runs on the calling thread (faer `Par::Seq`) and
//! every other sum is a sequential loop, so the values are bit-for-bit the same for any number of
//! threads (test `identical_bits_for_any_thread_count`, thread pools of 1 and 2).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

use super::Descriptors;
use crate::error::{Error, Result};
use crate::spectral::Basis;

/// Number of HKS times or WKS energies when the user gives none (`--data wks` = `wks:100` in the
/// CLI): the paper's rich setting uses 100 WKS.
pub const DEFAULT_COUNT: usize = 100;

/// Variance factor of the WKS energy bands (Aubry et al.'s `wks_variance`).
pub const WKS_VARIANCE: f64 = 6.0;

/// Indices of the non-zero eigenvalues (λ > 1e-8 · λ_k), and λ₁, λ_k.
fn nonzero(basis: &Basis) -> Result<(Vec<usize>, f64, f64)> {
    let lk = *basis.eigenvalues.last().ok_or_else(|| Error::invalid("basis", "it is empty"))?;
    let nz: Vec<usize> = (0..basis.k()).filter(|&i| basis.eigenvalues[i] > 1e-8 * lk).collect();
    if nz.len() < 2 {
        return Err(Error::invalid(
            "basis",
            "signatures need at least two non-zero eigenvalues; compute more eigenpairs",
        ));
    }
    Ok((nz.clone(), basis.eigenvalues[nz[0]], lk))
}

/// Most functions one signature call computes (HKS times, WKS energies).
pub const MAX_COUNT: usize = 100_000;

fn check_count(count: usize) -> Result<()> {
    if count == 0 || count > MAX_COUNT {
        return Err(Error::invalid("count", format!("need 1 ≤ N ≤ {MAX_COUNT} functions, got {count}")));
    }
    Ok(())
}

/// `count` values log-spaced (geometrically) from `lo` to `hi`; the geometric mean for one value.
fn logspace(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    if count == 1 {
        return vec![(lo * hi).sqrt()];
    }
    (0..count).map(|j| (lo.ln() + (hi.ln() - lo.ln()) * j as f64 / (count - 1) as f64).exp()).collect()
}

/// The HKS times of Sun et al.: `count` values log-spaced in [4 ln 10 / λ_k, 4 ln 10 / λ₁]
/// (in the units of 1/λ: area units for meshes).
pub fn hks_times(basis: &Basis, count: usize) -> Result<Vec<f64>> {
    check_count(count)?;
    let (_, l1, lk) = nonzero(basis)?;
    let c = 4.0 * 10f64.ln();
    Ok(logspace(c / lk, c / l1, count))
}

/// Φ² (n × k): squared eigenvectors.
fn phi_squared(basis: &Basis) -> Mat<f64> {
    Mat::from_fn(basis.n(), basis.k(), |i, j| basis.eigenvectors[(i, j)].powi(2))
}

fn heat_trace(basis: &Basis, t: f64) -> f64 {
    basis.eigenvalues.iter().map(|l| (-l * t).exp()).sum()
}

fn check_times(times: &[f64]) -> Result<()> {
    if times.is_empty() {
        return Err(Error::invalid("times", "no diffusion times given"));
    }
    if let Some(t) = times.iter().find(|t| !(t.is_finite() && **t > 0.0)) {
        return Err(Error::invalid("times", format!("diffusion times must be positive, got {t}")));
    }
    Ok(())
}

/// Heat kernel signature at the given times: n × times.len(), columns named `hks:t=…`.
pub fn hks(basis: &Basis, times: &[f64], normalize: bool) -> Result<Descriptors> {
    check_times(times)?;
    let total: f64 = basis.mass.iter().sum();
    // E (k × T): e^{−λᵢ t_j}, with the normalization folded into each column.
    let e = Mat::from_fn(basis.k(), times.len(), |i, j| {
        let scale = if normalize { total / heat_trace(basis, times[j]) } else { 1.0 };
        (-basis.eigenvalues[i] * times[j]).exp() * scale
    });
    let mut h = Mat::<f64>::zeros(basis.n(), times.len());
    matmul(h.as_mut(), Accum::Replace, phi_squared(basis).as_ref(), e.as_ref(), 1.0, Par::Seq);
    Descriptors::new(h, times.iter().map(|t| format!("hks:t={t:.6e}")).collect())
}

/// The WKS's `count` log-energies for the non-zero eigenvalues λ_1 ≤ … ≤ λ_k (`l1`, `lk`):
/// evenly spaced on [log λ_1, log λ_k], shrunk by 2σ at both ends when the range allows, and the
/// Gaussian width σ = [`WKS_VARIANCE`] · (log λ_k − log λ_1) / count (Aubry et al. 2011).
pub(crate) fn wks_energies(l1: f64, lk: f64, count: usize) -> (Vec<f64>, f64) {
    let (mut e_min, mut e_max) = (l1.ln(), lk.ln());
    let sigma = WKS_VARIANCE * (e_max - e_min) / count as f64;
    if e_max - e_min > 4.0 * sigma {
        e_min += 2.0 * sigma;
        e_max -= 2.0 * sigma;
    }
    let energies = if count == 1 {
        vec![0.5 * (e_min + e_max)]
    } else {
        (0..count).map(|j| e_min + (e_max - e_min) * j as f64 / (count - 1) as f64).collect()
    };
    (energies, sigma)
}

/// Wave kernel signature with `count` energies: n × count, columns named `wks:e=…`.
pub fn wks(basis: &Basis, count: usize, normalize: bool) -> Result<Descriptors> {
    check_count(count)?;
    let (nz, l1, lk) = nonzero(basis)?;
    let (energies, sigma) = wks_energies(l1, lk, count);
    let total: f64 = basis.mass.iter().sum();
    let mut c = Mat::<f64>::zeros(basis.k(), count);
    for (j, e) in energies.iter().enumerate() {
        let g: Vec<f64> =
            nz.iter().map(|&i| (-(e - basis.eigenvalues[i].ln()).powi(2) / (2.0 * sigma * sigma)).exp()).collect();
        let sum: f64 = g.iter().sum();
        let scale = if normalize { total } else { 1.0 } / sum;
        for (&i, gi) in nz.iter().zip(&g) {
            c[(i, j)] = gi * scale;
        }
    }
    let mut w = Mat::<f64>::zeros(basis.n(), count);
    matmul(w.as_mut(), Accum::Replace, phi_squared(basis).as_ref(), c.as_ref(), 1.0, Par::Seq);
    Descriptors::new(w, energies.iter().map(|e| format!("wks:e={e:.6}")).collect())
}

/// A WKS recipe: `energies` energies from the first `eigenpairs` eigenpairs, every
/// `keep_every`-th kept (pyFM's documented pipeline: 100 from 128, every 2nd, i.e. 50). Fewer,
/// lower-frequency, less correlated functions than WKS from the whole basis, and measurably
/// better maps from the axiomatic method (EXPERIMENTS.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WksRecipe {
    /// Number of energies.
    pub energies: usize,
    /// Eigenpairs used (capped at the basis size).
    pub eigenpairs: usize,
    /// Keep every n-th energy.
    pub keep_every: usize,
}

impl Default for WksRecipe {
    fn default() -> Self {
        WksRecipe { energies: 100, eigenpairs: 128, keep_every: 2 }
    }
}

/// The WKS of a [`WksRecipe`] (n × ⌈energies / keep_every⌉), scale-normalized as [`wks`].
pub fn wks_recipe(basis: &Basis, recipe: &WksRecipe) -> Result<Descriptors> {
    if recipe.keep_every == 0 || recipe.eigenpairs < 2 {
        return Err(Error::invalid("WKS recipe", "need keep_every ≥ 1 and at least 2 eigenpairs"));
    }
    let b = if recipe.eigenpairs < basis.k() { basis.truncate(recipe.eigenpairs)? } else { basis.clone() };
    let w = wks(&b, recipe.energies, true)?;
    let keep: Vec<usize> = (0..w.q()).step_by(recipe.keep_every).collect();
    Descriptors::new(
        Mat::from_fn(w.n(), keep.len(), |i, j| w.values[(i, keep[j])]),
        keep.iter().map(|&j| w.names[j].clone()).collect(),
    )
}

/// Heat kernel maps k_t(p, ·) for every seed vertex p and time t: n × (seeds · times), seed-major
/// (column s·T + j is seed s at time j), named `hkm:v=p,t=…`.
pub fn hkm(basis: &Basis, seeds: &[usize], times: &[f64], normalize: bool) -> Result<Descriptors> {
    check_times(times)?;
    if seeds.is_empty() {
        return Err(Error::invalid("seeds", "no seed vertices given"));
    }
    if let Some(&p) = seeds.iter().find(|&&p| p >= basis.n()) {
        return Err(Error::invalid("seeds", format!("vertex {p} is out of range (n = {})", basis.n())));
    }
    let total: f64 = basis.mass.iter().sum();
    let nt = times.len();
    // B (k × S·T): e^{−λᵢ t} φᵢ(p).
    let b = Mat::from_fn(basis.k(), seeds.len() * nt, |i, c| {
        let (p, t) = (seeds[c / nt], times[c % nt]);
        let scale = if normalize { total / heat_trace(basis, t) } else { 1.0 };
        (-basis.eigenvalues[i] * t).exp() * basis.eigenvectors[(p, i)] * scale
    });
    let mut h = Mat::<f64>::zeros(basis.n(), seeds.len() * nt);
    matmul(h.as_mut(), Accum::Replace, basis.eigenvectors.as_ref(), b.as_ref(), 1.0, Par::Seq);
    let names = (0..seeds.len() * nt).map(|c| format!("hkm:v={},t={:.6e}", seeds[c / nt], times[c % nt])).collect();
    Descriptors::new(h, names)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::shape::TriMesh;
    use crate::spectral::{eigen_basis, SpectralOptions};
    use faer::Side;

    fn basis_of(mesh: &TriMesh, k: usize, lanczos: bool) -> Basis {
        let mut o = SpectralOptions::new(k);
        if lanczos {
            o.dense_below = 0;
        }
        eigen_basis(&cotangent(mesh).unwrap(), &o, None).unwrap().0
    }

    #[test]
    fn match_an_independent_dense_computation() {
        let mesh = bumpy_sphere(3); // 642 vertices
        let k = 40;
        let b = basis_of(&mesh, k, true);
        // Reference: dense eigendecomposition of A^{-1/2} W A^{-1/2}, formulas summed by hand.
        let lap = cotangent(&mesh).unwrap();
        let n = lap.n();
        let w = lap.w.to_dense();
        let l = Mat::from_fn(n, n, |i, j| w[(i, j)] / (lap.mass[i] * lap.mass[j]).sqrt());
        let evd = l.self_adjoint_eigen(Side::Lower).unwrap();
        let lam: Vec<f64> = (0..k).map(|i| evd.S()[i].max(0.0)).collect();
        let phi = |x: usize, i: usize| evd.U()[(x, i)] / lap.mass[x].sqrt();
        let area: f64 = lap.mass.iter().sum();

        let times = hks_times(&b, 7).unwrap();
        let ours = hks(&b, &times, true).unwrap();
        for (j, &t) in times.iter().enumerate() {
            let trace: f64 = lam.iter().map(|l| (-l * t).exp()).sum();
            for x in (0..n).step_by(37) {
                let want: f64 = (0..k).map(|i| (-lam[i] * t).exp() * phi(x, i).powi(2)).sum::<f64>() * area / trace;
                let got = ours.values[(x, j)];
                assert!((got - want).abs() < 1e-6 * want.abs(), "hks x={x} t={t}: {got} vs {want}");
            }
        }
        let ours = wks(&b, 9, false).unwrap();
        let (e1, ek) = (lam[1].ln(), lam[k - 1].ln());
        let sigma = 6.0 * (ek - e1) / 9.0; // 4σ > range here: no margins
        for j in 0..9 {
            let e = e1 + (ek - e1) * j as f64 / 8.0;
            let g: Vec<f64> = (1..k).map(|i| (-(e - lam[i].ln()).powi(2) / (2.0 * sigma * sigma)).exp()).collect();
            for x in (0..n).step_by(41) {
                let want = (1..k).map(|i| g[i - 1] * phi(x, i).powi(2)).sum::<f64>() / g.iter().sum::<f64>();
                let got = ours.values[(x, j)];
                assert!((got - want).abs() < 1e-6 * want.abs(), "wks x={x} e={e}: {got} vs {want}");
            }
        }
        let seeds = [5usize, 300];
        let ours = hkm(&b, &seeds, &times[2..4], false).unwrap();
        for (s, &p) in seeds.iter().enumerate() {
            for (jt, &t) in times[2..4].iter().enumerate() {
                for x in (0..n).step_by(53) {
                    let want: f64 = (0..k).map(|i| (-lam[i] * t).exp() * phi(p, i) * phi(x, i)).sum();
                    let got = ours.values[(x, s * 2 + jt)];
                    assert!((got - want).abs() < 1e-6 * want.abs().max(1e-3), "hkm p={p} x={x}: {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn invariant_to_permutation_rigid_motion_and_scale() {
        let mesh = bumpy_sphere(3);
        let n = mesh.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect(); // new i ← old perm[i]
        let (c, s, scale) = (0.4f64.cos(), 0.4f64.sin(), 3.7);
        let moved = mesh
            .permuted(&perm)
            .unwrap()
            .map_vertices(|p| {
                [scale * (c * p[0] + s * p[2]) + 10.0, scale * p[1] - 4.0, scale * (-s * p[0] + c * p[2])]
            })
            .unwrap();
        let (ba, bb) = (basis_of(&mesh, 30, true), basis_of(&moved, 30, true));
        let pairs = [
            (
                hks(&ba, &hks_times(&ba, 16).unwrap(), true).unwrap(),
                hks(&bb, &hks_times(&bb, 16).unwrap(), true).unwrap(),
            ),
            (wks(&ba, 16, true).unwrap(), wks(&bb, 16, true).unwrap()),
            (
                hkm(&ba, &[perm[10], perm[200]], &hks_times(&ba, 3).unwrap(), true).unwrap(),
                hkm(&bb, &[10, 200], &hks_times(&bb, 3).unwrap(), true).unwrap(),
            ),
        ];
        for (a, b) in &pairs {
            let scale_a = a.values.norm_max();
            for j in 0..a.q() {
                for new in 0..n {
                    let (x, y) = (a.values[(perm[new], j)], b.values[(new, j)]);
                    assert!((x - y).abs() <= 1e-6 * scale_a, "{} at vertex {new}: {x} vs {y}", a.names[j]);
                }
            }
        }
    }

    /// HKS, WKS and HKM are bit-for-bit the same whatever the number of threads (the bases are).
    #[test]
    fn identical_bits_for_any_thread_count() {
        let b = basis_of(&bumpy_sphere(4), 100, true); // 2,562 vertices
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let times = hks_times(&b, 100).unwrap();
                [
                    hks(&b, &times, true).unwrap(),
                    wks(&b, 100, true).unwrap(),
                    hkm(&b, &[3, 700], &times[..5], true).unwrap(),
                ]
            })
        };
        let bits = |d: &Descriptors| -> Vec<u64> {
            (0..d.q()).flat_map(|j| d.values.col_as_slice(j).iter().map(|v| v.to_bits()).collect::<Vec<_>>()).collect()
        };
        let (one, two) = (run(1), run(2));
        for (a, b) in one.iter().zip(&two) {
            assert_eq!(a.names, b.names);
            let differing = bits(a).iter().zip(bits(b)).filter(|(x, y)| **x != *y).count();
            assert_eq!(differing, 0, "{}: {differing} values differ between 1 and 2 threads", a.names[0]);
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        let b = basis_of(&bumpy_sphere(2), 10, false);
        assert!(hks(&b, &[], true).is_err());
        assert!(hks(&b, &[-1.0], true).is_err());
        assert!(wks(&b, 0, true).is_err());
        assert!(hkm(&b, &[b.n()], &[1.0], true).is_err());
        assert!(hkm(&b, &[], &[1.0], true).is_err());
        let one = b.truncate(1).unwrap();
        assert!(hks_times(&one, 5).is_err());
    }
}
