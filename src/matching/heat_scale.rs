//! The scale of a part X against a whole Y from their heat kernels, with no correspondence.
//!
//! Both bases are at unit area ([`crate::prepared`]). If X covers the fraction r of Y's area
//! (X's area in Y's units over area(Y), the area ratio the partial path needs), X's lengths at
//! unit area are Y's lengths / √r and X's diffusion times Y's times / r. The dimensionless heat
//! kernel diagonal
//!
//! u(v, t) = t · k_t(v, v),  k_t(v, v) = Σ_i e^{−λ_i t} φ_i(v)²,
//!
//! is unchanged by an isometry and by scaling (t k_t has no unit), so where X is an isometric
//! piece of Y, u_X(x, t / r) = u_Y(T x, t) at every time t small enough that heat from x has not
//! reached X's cut (Neumann boundary). This is the scale covariance behind the scale-invariant
//! HKS (Bronstein & Kokkinos 2010, "Scale-invariant heat kernel signatures"): a change of scale is
//! a shift of log t. So r is the ratio at which X's log-time profiles, shifted by log r, find
//! the closest partners among Y's: for every r of a log grid,
//!
//! E(r) = mean over the better ¾ of X's samples x of min_y ‖p_X(x; r) − p_Y(y)‖² / V(r),
//!
//! p_X(x; r)_j = log u_X(x, t_j / r), p_Y(y)_j = log u_Y(y, t_j), V(r) the total variance of X's
//! profiles p_X(·; r) over the samples: without it E prefers the ratios at which X's profiles all
//! look alike (large r, short times on X: every profile near the flat limit u = 1/4π) and
//! picked r = 1.2 for parts covering 0.6 of their whole. The times t_j are log-spaced over
//! a span of 16 (`TIME_SPAN`) from the smallest time both truncated bases resolve; the better ¾ discards the
//! samples near X's cut (their heat reaches the boundary) and those whose partners X does not
//! hold. r = argmin E. k_t is truncated to the basis
//! and completed by Weyl's law at unit area: Σ_{i>k} e^{−λ_i t} φ_i(v)² ≈ e^{−λ_k t} / (4π t).
//!
//! **Near X's cut.** Heat on the part is reflected at its boundary (Neumann), which Y, whole
//! there, does not do: by the method of images for a straight boundary at distance d,
//! t k_t(x, x) = (1 + e^{−d²/t}) / 4π, so a sample near a cut looks like a smaller shape and the
//! ratio errs high where the cut is long (more than the discarded quarter of the samples lie
//! near it). Given each sample's distance d to X's boundary (unit area), X's profiles are
//! corrected by that first-order term: p_X(x; r)_j − log(1 + e^{−d² r / t_j}).
//!
//! **Several minima.** E can have two nearly equal minima: a human's legs and pelvis, at
//! half their area, look to the heat kernel like the arms and shoulders (faust_r_partial
//! tr_reg_021_cut → 042: minima at r = 0.35 and 0.74, E 1.00 : 1.18 on the coarse grid, true
//! covered fraction 0.71). Intrinsic quantities cannot tell the two apart (the geodesic
//! distortion of the maps found at either ratio is the same, 0.074 against 0.073), the units
//! can. So when the caller gives a prior ratio (the inputs' area ratio), the local minima of E
//! on the coarse grid within `TIE` (30 %) of the least are taken as equally good and the
//! one nearest the prior in log r is refined; without a prior, the least. Over faust_r_partial's
//! 97 pairs this leaves the ratio of 8 pairs more than 15 % off the covered fraction, against
//! 11 for the least E; tosca_r_partial's 109 none either way (EXPERIMENTS.md).

use kiddo::ImmutableKdTree;
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::spectral::Basis;

/// Number of diffusion times (the dimension of the log-time profiles).
const TIMES: usize = 8;
/// The times run from t₀ to TIME_SPAN · t₀ (t₀ = [`FIRST_TIME`] / λ_k of the smaller band).
const TIME_SPAN: f64 = 16.0;
/// t₀ λ_k: the truncated sum misses a fraction ≈ e^{−4} ≈ 2 % of the kernel at the first time
/// (before the Weyl completion).
const FIRST_TIME: f64 = 4.0;
/// The share of X's samples whose misfits count (the better ones: the rest lie near X's cut
/// or have no partner on Y).
const KEPT: f64 = 0.75;
/// Local minima of E within this share of the least are taken as equally good, and the prior
/// ratio, when there is one, chooses among them (module docs, "Several minima").
const TIE: f64 = 0.3;
/// Grid of log r: coarse steps, then fine steps around the coarse minimum.
const COARSE_STEP: f64 = 0.04;
const FINE_STEP: f64 = 0.005;

/// What [`heat_scale_ratio`] found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeatScale {
    /// The estimated area ratio r (X's area in Y's units / area(Y)).
    pub ratio: f64,
    /// E(r) at the estimate (squared log-profile distance, dimensionless).
    pub energy: f64,
    /// The diffusion times t_j on Y (unit area).
    pub times: Vec<f64>,
    /// E at the prior ratio given to [`heat_scale_ratio`] (None without one).
    pub prior_energy: Option<f64>,
    /// E on the coarse grid of the search: (r, E(r)) in increasing r, log-spaced by
    /// `COARSE_STEP` (the landscape: a part that looks like a smaller piece of Y, arms for legs,
    /// gives a second minimum).
    pub curve: Vec<(f64, f64)>,
    /// The ratios of the local minima of E on the coarse grid within `TIE` (30 %) of the least,
    /// in increasing r: more than one, and the heat profiles cannot tell them apart (module
    /// docs, "Several minima").
    pub minima: Vec<f64>,
}

/// log u(v, t_j) of `basis` at the vertices `rows`, the times `times` multiplied by `factor`:
/// one `TIMES`-vector per row.
fn log_profiles(basis: &Basis, rows: &[usize], times: &[f64; TIMES], factor: f64) -> Vec<[f64; TIMES]> {
    let k = basis.k();
    let lk = basis.eigenvalues[k - 1];
    let decay: Vec<[f64; TIMES]> =
        basis.eigenvalues.iter().map(|&l| std::array::from_fn(|j| (-l.max(0.0) * times[j] * factor).exp())).collect();
    let tail: [f64; TIMES] = std::array::from_fn(|j| (-lk * times[j] * factor).exp() / (4.0 * std::f64::consts::PI));
    rows.iter()
        .map(|&v| {
            let mut s = [0.0; TIMES];
            for (i, d) in decay.iter().enumerate() {
                let p = basis.eigenvectors[(v, i)].powi(2);
                for j in 0..TIMES {
                    s[j] += d[j] * p;
                }
            }
            std::array::from_fn(|j| (times[j] * factor * s[j] + tail[j]).ln())
        })
        .collect()
}

/// The total variance of the profiles `p` (sum over the times of the variance over the rows).
fn profile_variance(p: &[[f64; TIMES]]) -> f64 {
    let n = p.len() as f64;
    (0..TIMES)
        .map(|j| {
            let mean = p.iter().map(|q| q[j]).sum::<f64>() / n;
            p.iter().map(|q| (q[j] - mean).powi(2)).sum::<f64>() / n
        })
        .sum()
}

/// The local minima of E on the coarse grid `curve` ((r, E) in increasing r) whose E is within
/// `TIE` of the least, in increasing r (module docs, "Several minima"): the ratios the heat
/// profiles fit about equally well.
fn near_equal_minima(curve: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let least = curve.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    let is_minimum = |i: usize| {
        let e = curve[i].1;
        // No neighbour lower (a NaN neighbour is not).
        let lower = |j: usize| curve[j].1.partial_cmp(&e) == Some(std::cmp::Ordering::Less);
        (i == 0 || !lower(i - 1)) && (i + 1 == curve.len() || !lower(i + 1))
    };
    (0..curve.len()).filter(|&i| is_minimum(i) && curve[i].1 <= (1.0 + TIE) * least).map(|i| curve[i]).collect()
}

/// Of the near-equal `minima` of `curve` ([`near_equal_minima`]), the one nearest the prior
/// ratio `prior` in log r (the least E of `curve` when there is none).
fn nearest_minimum(curve: &[(f64, f64)], minima: &[(f64, f64)], prior: f64) -> (f64, f64) {
    minima
        .iter()
        .copied()
        .min_by(|a, b| (a.0 / prior).ln().abs().total_cmp(&(b.0 / prior).ln().abs()))
        .unwrap_or_else(|| curve.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((f64::NAN, f64::NAN)))
}

/// The area ratio r of a part X to a whole Y (module docs) from their unit-area bases: X's
/// samples `xs` (vertex ids of X, the rows whose profiles are matched) against every vertex of
/// Y, r searched in lo ..= hi (dimensionless, 0 < lo < hi). Errors: bases with fewer than 2
/// eigenpairs or a non-positive largest eigenvalue, no samples, a sample out of range, a bad
/// range, boundary distances of another length or negative or NaN. `boundary`: the geodesic
/// distance of every sample to X's boundary at X's unit area (module docs, "Near X's cut"; ∞
/// for a sample that reaches no boundary; None for a shape without one). `prior`: a ratio
/// that breaks ties between near-equal minima (module docs, "Several minima"; its E is
/// [`HeatScale::prior_energy`]); None: the least E.
pub fn heat_scale_ratio(
    x: &Basis,
    y: &Basis,
    xs: &[usize],
    boundary: Option<&[f64]>,
    (lo, hi): (f64, f64),
    prior: Option<f64>,
) -> Result<HeatScale> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Err(Error::invalid("scale range", format!("need 0 < lo < hi, got [{lo}, {hi}]")));
    }
    if x.k() < 2 || y.k() < 2 {
        return Err(Error::invalid("bases", "the heat scale needs at least 2 eigenpairs of each shape"));
    }
    let (lx, ly) = (x.eigenvalues[x.k() - 1], y.eigenvalues[y.k() - 1]);
    if !(lx > 0.0 && ly > 0.0 && lx.is_finite() && ly.is_finite()) {
        return Err(Error::invalid("bases", format!("largest eigenvalues {lx} and {ly}: need > 0")));
    }
    if xs.is_empty() {
        return Err(Error::invalid("samples", "no samples of X"));
    }
    if let Some(&v) = xs.iter().find(|&&v| v >= x.n()) {
        return Err(Error::invalid("samples", format!("vertex {v} of X, which has {}", x.n())));
    }
    if let Some(d) = boundary {
        if d.len() != xs.len() || d.iter().any(|v| v.is_nan() || *v < 0.0) {
            return Err(Error::invalid(
                "boundary distances",
                format!("need one distance ≥ 0 per sample ({}), got {} values", xs.len(), d.len()),
            ));
        }
    }
    // X is read at t / r ≥ t / hi: both truncations resolve the first time at every r ≤ hi.
    let t0 = FIRST_TIME / ly.min(lx * hi);
    let times: [f64; TIMES] = std::array::from_fn(|j| t0 * TIME_SPAN.powf(j as f64 / (TIMES - 1) as f64));
    let all_y: Vec<usize> = (0..y.n()).collect();
    let py = log_profiles(y, &all_y, &times, 1.0);
    let tree: ImmutableKdTree<f64, TIMES> = ImmutableKdTree::new_from_slice(&py);
    let energy = |r: f64| -> f64 {
        let mut px = log_profiles(x, xs, &times, 1.0 / r);
        if let Some(d) = boundary {
            // The reflection at the cut (module docs, "Near X's cut"), X's times t_j / r.
            for (p, &d) in px.iter_mut().zip(d) {
                for (q, &t) in p.iter_mut().zip(&times) {
                    *q -= (-d * d * r / t).exp().ln_1p();
                }
            }
        }
        let mut d: Vec<f64> = px.par_iter().map(|q| tree.nearest_one::<kiddo::SquaredEuclidean>(q).distance).collect();
        d.sort_by(|a, b| a.total_cmp(b));
        let kept = ((d.len() as f64 * KEPT).ceil() as usize).clamp(1, d.len());
        let misfit = d[..kept].iter().sum::<f64>() / kept as f64;
        // A floor for shapes whose profiles are all alike (a round sphere): E is then the misfit.
        misfit / profile_variance(&px).max(1e-12)
    };
    let grid = |a: f64, b: f64, step: f64| -> Vec<f64> {
        let count = ((b.ln() - a.ln()) / step).ceil().max(0.0) as usize;
        (0..=count).map(|i| (a.ln() + step * i as f64).exp().min(b)).collect()
    };
    let best = |rs: &[(f64, f64)]| -> (f64, f64) {
        rs.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)).expect("a non-empty grid")
    };
    let curve: Vec<(f64, f64)> = grid(lo, hi, COARSE_STEP).into_iter().map(|r| (r, energy(r))).collect();
    let minima = near_equal_minima(&curve);
    let (coarse, _) = match prior {
        Some(p) => nearest_minimum(&curve, &minima, p),
        None => best(&curve),
    };
    let fine: Vec<(f64, f64)> =
        grid((coarse * (-COARSE_STEP).exp()).max(lo), (coarse * COARSE_STEP.exp()).min(hi), FINE_STEP)
            .into_iter()
            .map(|r| (r, energy(r)))
            .collect();
    let (ratio, e) = best(&fine);
    if !e.is_finite() {
        return Err(Error::invalid("bases", "the heat profiles are not finite"));
    }
    let prior_energy = prior.map(energy);
    let minima = minima.into_iter().map(|m| m.0).collect();
    Ok(HeatScale { ratio, energy: e, times: times.to_vec(), prior_energy, curve, minima })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::spectral::{eigen_basis, SpectralOptions};

    fn basis() -> Basis {
        let m = bumpy_sphere(3);
        let mut b = eigen_basis(&cotangent(&m).unwrap(), &SpectralOptions::new(60), None).unwrap().0;
        // At unit area, as the prepared shapes' bases: λ × area, φ × √area.
        let area: f64 = b.mass.iter().sum();
        b.eigenvalues.iter_mut().for_each(|l| *l *= area);
        b.eigenvectors = &b.eigenvectors * faer::Scale(area.sqrt());
        b.mass.iter_mut().for_each(|a| *a /= area);
        b
    }

    #[test]
    fn a_whole_shape_against_itself_has_ratio_one() {
        let b = basis();
        let xs: Vec<usize> = (0..b.n()).step_by(3).collect();
        let h = heat_scale_ratio(&b, &b, &xs, None, (0.1, 1.2), Some(1.0)).unwrap();
        assert!((h.ratio - 1.0).abs() <= 0.01, "{h:?}");
        // The prior is the minimum (0: every sample is its own partner).
        assert!(h.prior_energy.unwrap() <= h.energy + 1e-15, "{h:?}");
        assert!(h.times.windows(2).all(|w| w[1] > w[0]) && h.times.len() == TIMES);
        // A ratio far from 1 fits worse.
        let far = heat_scale_ratio(&b, &b, &xs, None, (0.1, 1.2), Some(0.3)).unwrap();
        assert!(far.prior_energy.unwrap() > 2.0 * h.energy.max(1e-6), "{far:?}");
    }

    /// Of near-equal minima the prior picks the nearest; a minimum above the tie, or a point
    /// on a slope, is never picked.
    #[test]
    fn the_prior_chooses_among_near_equal_minima() {
        let curve = [(0.3, 1.4), (0.35, 1.0), (0.4, 1.3), (0.6, 1.5), (0.7, 1.2), (0.8, 1.6), (0.9, 1.35), (1.0, 1.5)];
        assert_eq!(nearest_minimum(&curve, &near_equal_minima(&curve), 0.67), (0.7, 1.2));
        assert_eq!(nearest_minimum(&curve, &near_equal_minima(&curve), 0.2), (0.35, 1.0));
        // Nearest in log r: 0.45 is nearer 0.35 (by 0.25), 0.52 nearer 0.7 (by 0.30 against 0.40).
        assert_eq!(nearest_minimum(&curve, &near_equal_minima(&curve), 0.45), (0.35, 1.0));
        assert_eq!(nearest_minimum(&curve, &near_equal_minima(&curve), 0.52), (0.7, 1.2));
        // 0.9 is a minimum 35 % above the least: not a tie.
        assert_eq!(nearest_minimum(&curve, &near_equal_minima(&curve), 0.95), (0.7, 1.2));
        assert_eq!(near_equal_minima(&curve).iter().map(|m| m.0).collect::<Vec<_>>(), [0.35, 0.7]);
        // The least is always a candidate; NaN energies are never picked.
        let odd = [(0.5, f64::NAN), (0.6, 2.0), (0.7, 3.0)];
        assert_eq!(nearest_minimum(&odd, &near_equal_minima(&odd), 0.5), (0.6, 2.0));
    }

    #[test]
    fn bad_inputs_are_errors_naming_them() {
        let b = basis();
        for (range, what) in
            [((0.0, 1.0), "scale range"), ((1.0, 0.5), "scale range"), ((0.1, f64::NAN), "scale range")]
        {
            let e = heat_scale_ratio(&b, &b, &[0], None, range, None).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
        let e = heat_scale_ratio(&b, &b, &[], None, (0.1, 1.0), None).unwrap_err().to_string();
        assert!(e.contains("samples"), "{e}");
        let e = heat_scale_ratio(&b, &b, &[b.n()], None, (0.1, 1.0), None).unwrap_err().to_string();
        assert!(e.contains("samples") && e.contains(&b.n().to_string()), "{e}");
        for d in [vec![0.1], vec![0.1, f64::NAN], vec![0.1, -1.0]] {
            let e = heat_scale_ratio(&b, &b, &[0, 1], Some(&d), (0.1, 1.0), None).unwrap_err().to_string();
            assert!(e.contains("boundary distances"), "{e}");
        }
    }

    /// The correction near a cut vanishes far from it: samples at distance ∞ from a boundary
    /// give the ratio and energy of no boundary; samples on the boundary (d = 0) are read as if
    /// their heat were halved, which moves the ratio.
    #[test]
    fn the_cut_correction_acts_only_near_the_cut() {
        let b = basis();
        let xs: Vec<usize> = (0..b.n()).step_by(3).collect();
        let plain = heat_scale_ratio(&b, &b, &xs, None, (0.1, 1.2), None).unwrap();
        let far = vec![f64::INFINITY; xs.len()];
        let with = heat_scale_ratio(&b, &b, &xs, Some(&far), (0.1, 1.2), None).unwrap();
        assert_eq!((plain.ratio, plain.energy), (with.ratio, with.energy));
        let on = vec![0.0; xs.len()];
        let halved = heat_scale_ratio(&b, &b, &xs, Some(&on), (0.1, 1.2), None).unwrap();
        assert!(halved.ratio < 0.9 * plain.ratio, "{halved:?} against {plain:?}");
    }
}
