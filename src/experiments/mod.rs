//! The paper's "sterile" experiments (§4.2, Figures 5 and 6): a near-isometric pair with
//! ideally corresponding data F, G (T0 F = G for the ground-truth correspondence T0), scored by
//! the soft error (13) of the functional correspondence T = Ψ C Φᵀ itself, so that no
//! point-map conversion blurs the comparison.
//!
//! *Ideal data.* The benchmark's ground truth is a list of template points (x_i on X, y_i on
//! Y), not a dense map. T0 is made dense on Y: every vertex of Y takes the template point
//! nearest to it on Y (Euclidean, a k-d tree) and maps to that point's x_i. F holds q heat
//! kernel maps k_t(p, ·) on X (t = 4 ln 10 / λ_q) at farthest-point-sampled template points p, and G = T0 F holds
//! their values pulled back to Y, so T0 F = G holds exactly up to the remeshing (on faust_r,
//! 4415 of Y's 5000 vertices are template points; the others sit within one edge of one).
//!
//! The sweeps of the two figures, one typed row per point, are in [`sweep`]; `viz` draws them.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

use crate::descriptors::{signatures as sig, Descriptors};
use crate::error::{Error, Result};
use crate::eval::{self, GroundTruth};
use crate::geodesic::Distances;
use crate::shape::TriMesh;
use crate::spatial::farthest_points;
use crate::spectral::Basis;

pub mod sweep;
pub use sweep::{run_sweep, Sweep, SweepMethod, SweepRow, SweepSettings};

/// For every vertex of Y (m), a vertex of X: the counterpart x_i of the template point y_i
/// nearest to it on Y. Errors when the ground truth is empty or out of range.
pub fn dense_map_yx(y: &TriMesh, gt: &GroundTruth, n: usize) -> Result<Vec<usize>> {
    let m = y.n_vertices();
    if gt.x.is_empty() || gt.x.len() != gt.y.len() {
        return Err(Error::invalid("ground truth", "empty or of different lengths"));
    }
    if gt.x.iter().any(|&i| i >= n) || gt.y.iter().any(|&j| j >= m) {
        return Err(Error::invalid("ground truth", format!("a vertex id is out of range (n = {n}, m = {m})")));
    }
    let v = y.vertices();
    let pts: Vec<[f64; 3]> = gt.y.iter().map(|&j| v[j]).collect();
    Ok(crate::spatial::nearest3(&pts, v).into_iter().map(|i| gt.x[i]).collect())
}

/// Ideally corresponding data: F (n × q) heat kernel maps on X at q farthest-point-sampled
/// template points, at time t = 4 ln 10 / λ_q of `bx` (bumps about as wide as the q-th
/// eigenfunction's wavelength), and G = T0 F (m × q) with T0 from `map_yx` ([`dense_map_yx`]).
/// Errors when q = 0, q ≥ the basis size or there are fewer than q template points.
pub fn ideal_functions(
    x: &TriMesh,
    bx: &Basis,
    gt: &GroundTruth,
    map_yx: &[usize],
    q: usize,
) -> Result<(Descriptors, Descriptors)> {
    if q == 0 {
        return Err(Error::invalid("q", "need at least one function"));
    }
    let seeds: Vec<usize> = farthest_points(x, &gt.x, q).into_iter().map(|i| gt.x[i]).collect();
    if seeds.len() < q {
        return Err(Error::invalid("q", format!("only {} distinct template points for q = {q}", seeds.len())));
    }
    // Heat time t = 4 ln 10 / λ_q: e^{−λ t} ≤ 1e-4 beyond the q-th eigenvalue, so the q bumps
    // live (numerically) in the first q eigenfunctions and q of them carry about q dimensions.
    if q >= bx.k() {
        return Err(Error::invalid("q", format!("q = {q} needs more than q eigenpairs, the basis has {}", bx.k())));
    }
    let lambda_q = bx.eigenvalues[q];
    if !(lambda_q.is_finite() && lambda_q > 0.0) {
        return Err(Error::invalid("basis", format!("eigenvalue {q} is {lambda_q}, expected positive")));
    }
    let f = sig::hkm(bx, &seeds, &[4.0 * 10f64.ln() / lambda_q], false)?;
    if let Some(&i) = map_yx.iter().find(|&&i| i >= f.n()) {
        return Err(Error::invalid("map_yx", format!("vertex {i} out of range (n = {})", f.n())));
    }
    let g = Mat::from_fn(map_yx.len(), q, |j, c| f.values[(map_yx[j], c)]);
    let g = Descriptors::new(g, f.names.clone())?;
    Ok((f, g))
}

/// Geodesic distances on Y precomputed from a fixed set of sources (m × s), answering
/// [`Distances`] queries for those sources only: the soft error (13) of many maps against the
/// same template points needs the same full distance columns every time.
#[derive(Debug, Clone)]
pub struct DistanceTable {
    sources: Vec<usize>,
    columns: Mat<f64>,
}

impl DistanceTable {
    /// Distances of `dist` from every vertex of `sources` (computed once).
    pub fn new(dist: &dyn Distances, sources: &[usize]) -> Result<DistanceTable> {
        let mut sorted = sources.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        let columns = dist.distances_from(&sorted)?;
        Ok(DistanceTable { sources: sorted, columns })
    }
}

impl Distances for DistanceTable {
    fn n_vertices(&self) -> usize {
        self.columns.nrows()
    }
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
        let idx: Vec<usize> = sources
            .iter()
            .map(|s| {
                self.sources.binary_search(s).map_err(|_| {
                    Error::invalid("distance table", format!("vertex {s} is not one of the precomputed sources"))
                })
            })
            .collect::<Result<_>>()?;
        Ok(Mat::from_fn(self.columns.nrows(), idx.len(), |i, j| self.columns[(i, idx[j])]))
    }
}

/// Template points used by a soft-error evaluation: `count` of them, evenly spaced in the
/// template order (all when `count` ≥ their number).
pub fn sample_ground_truth(gt: &GroundTruth, count: usize) -> GroundTruth {
    let len = gt.x.len();
    let picks: Vec<usize> =
        if count >= len { (0..len).collect() } else { (0..count).map(|i| i * len / count).collect() };
    GroundTruth {
        x: picks.iter().map(|&i| gt.x[i]).collect(),
        y: picks.iter().map(|&i| gt.y[i]).collect(),
        y_sym: gt.y_sym.as_ref().map(|s| picks.iter().map(|&i| s[i]).collect()),
    }
}

/// The soft error (13) of the functional correspondence T = Ψ_k C Φ_kᵀ (C: ky × kx, the first
/// columns of the bases) at the template points of `gt`: column i of the soft map is
/// T δ_{x_i} = Ψ C Φ[x_i, :]ᵀ (values on Y's vertices; (13) is invariant to its scale).
pub fn soft_errors(
    bx: &Basis,
    by: &Basis,
    c: MatRef<f64>,
    gt: &GroundTruth,
    dist: &dyn Distances,
    area_y: f64,
) -> Result<Vec<f64>> {
    let (ky, kx) = (c.nrows(), c.ncols());
    if kx > bx.k() || ky > by.k() {
        return Err(Error::invalid("C", format!("{ky} × {kx} exceeds the bases ({} and {})", by.k(), bx.k())));
    }
    if let Some(&i) = gt.x.iter().find(|&&i| i >= bx.n()) {
        return Err(Error::invalid("ground truth", format!("vertex {i} out of range (n = {})", bx.n())));
    }
    let s = gt.x.len();
    let phi_s = Mat::from_fn(kx, s, |a, j| bx.eigenvectors[(gt.x[j], a)]);
    let mut coef = Mat::<f64>::zeros(ky, s);
    matmul(coef.as_mut(), Accum::Replace, c, phi_s.as_ref(), 1.0, Par::rayon(0));
    let mut cols = Mat::<f64>::zeros(by.n(), s);
    matmul(cols.as_mut(), Accum::Replace, by.eigenvectors.as_ref().subcols(0, ky), coef.as_ref(), 1.0, Par::rayon(0));
    eval::soft_errors(cols.as_ref(), gt, dist, area_y)
}

/// The sterile setting of §4.2 on one pair: bases, ideal data F, G, the template points
/// scored (without symmetric flips: ideal data break the symmetry) and their distance table.
#[derive(Debug, Clone)]
pub struct Sterile<'a> {
    /// Basis of X (n × k).
    pub bx: &'a Basis,
    /// Basis of Y (m × k).
    pub by: &'a Basis,
    /// Ideal data on X (n × q).
    pub f: Descriptors,
    /// Ideal data on Y (m × q), G = T0 F.
    pub g: Descriptors,
    /// The scored template points.
    pub sample: GroundTruth,
    /// Geodesic distances on Y from the scored points.
    pub table: DistanceTable,
    /// Area of Y.
    pub area_y: f64,
    /// The dense ground-truth map Y → X ([`dense_map_yx`]).
    pub map_yx: Vec<usize>,
}

impl<'a> Sterile<'a> {
    /// Ideal data with q functions ([`ideal_functions`]) and `samples` scored template points
    /// with distances by `geodesics`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        x: &TriMesh,
        bx: &'a Basis,
        y: &TriMesh,
        by: &'a Basis,
        gt: &GroundTruth,
        q: usize,
        samples: usize,
        geodesics: crate::geodesic::GeodesicMethod,
    ) -> Result<Sterile<'a>> {
        let map_yx = dense_map_yx(y, gt, x.n_vertices())?;
        let (f, g) = ideal_functions(x, bx, gt, &map_yx, q)?;
        let sample = GroundTruth { y_sym: None, ..sample_ground_truth(gt, samples) };
        let geo = geodesics.build(y)?;
        let table = DistanceTable::new(&*geo, &sample.y)?;
        Ok(Sterile { bx, by, f, g, sample, table, area_y: y.total_area(), map_yx })
    }

    /// Mean soft error (13) of T = Ψ C Φᵀ over the scored points.
    pub fn mean_soft_error(&self, c: MatRef<f64>) -> Result<f64> {
        let e = soft_errors(self.bx, self.by, c, &self.sample, &self.table, self.area_y)?;
        Ok(e.iter().sum::<f64>() / e.len().max(1) as f64)
    }

    /// The ground-truth functional map C0 = Ψ_kᵀ A_Y Φ_k(T0) (k × k): the best T = Ψ C Φᵀ of
    /// rank k can do, a reference line for the methods.
    pub fn ground_truth(&self, k: usize) -> Result<Mat<f64>> {
        crate::pointwise::fmap_from_map_yx(
            self.bx.eigenvectors.as_ref(),
            self.by.eigenvectors.as_ref(),
            &self.by.mass,
            &self.map_yx,
            k,
        )
    }

    /// C (k × k) of eq. (5) without regularization (Ovsjanikov et al.).
    pub fn ovsjanikov(&self, k: usize) -> Result<Mat<f64>> {
        crate::fmap::ovsjanikov(self.bx, self.by, &self.f, &self.g, k, &crate::fmap::OvsjanikovOptions::default())
    }

    /// C (k × k) of eq. (6) (Pokrass et al.) and the fraction of data columns its permutation
    /// matched correctly (the ideal data come in the right order).
    pub fn pokrass(&self, k: usize, opts: &crate::fmap::PokrassOptions) -> Result<(Mat<f64>, f64)> {
        let (c, perm) = crate::fmap::pokrass(self.bx, self.by, &self.f, &self.g, k, opts)?;
        let right = perm.iter().enumerate().filter(|(j, p)| j == *p).count();
        Ok((c, right as f64 / perm.len().max(1) as f64))
    }

    /// C (k' × k') of the completion method, started from eq. (5) at size `init_k` (≤ k');
    /// and the solver's report.
    pub fn completion(
        &self,
        opts: &crate::completion::CompletionOptions,
        init_k: usize,
    ) -> Result<(Mat<f64>, crate::completion::SolverReport)> {
        let c0 = self.ovsjanikov(init_k.min(opts.k_prime).min(opts.k))?;
        let s = crate::completion::solve(self.bx, self.by, None, &self.f, &self.g, c0.as_ref(), opts)?;
        Ok((s.c, s.report))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::GraphGeodesics;
    use crate::laplacian::cotangent;
    use crate::primitives::icosphere;
    use crate::spectral::{eigen_basis, SpectralOptions};

    #[test]
    fn the_identity_correspondence_has_a_small_soft_error_and_ideal_data_agree() {
        let mesh = icosphere(3);
        let n = mesh.n_vertices();
        let basis = eigen_basis(&cotangent(&mesh).unwrap(), &SpectralOptions::new(60), None).unwrap().0;
        let ids: Vec<usize> = (0..n).collect();
        let gt = GroundTruth { x: ids.clone(), y: ids.clone(), y_sym: None };
        // T0 is the identity: G equals F.
        let map = dense_map_yx(&mesh, &gt, n).unwrap();
        assert_eq!(map, ids);
        let (f, g) = ideal_functions(&mesh, &basis, &gt, &map, 8).unwrap();
        assert_eq!((f.q(), g.q()), (8, 8));
        assert!((0..n).all(|i| (0..8).all(|j| f.values[(i, j)] == g.values[(i, j)])));
        // Soft error of C = I (the truncated identity kernel) is small and shrinks with k; a
        // reflected C (the sign flip of odd-degree harmonics) is worse.
        let geo = GraphGeodesics::mesh_edges(&mesh).unwrap();
        let sample = sample_ground_truth(&gt, 40);
        assert_eq!(sample.x.len(), 40);
        let table = DistanceTable::new(&geo, &sample.y).unwrap();
        let area = mesh.total_area();
        let mean = |k: usize| {
            let e = soft_errors(&basis, &basis, Mat::<f64>::identity(k, k).as_ref(), &sample, &table, area).unwrap();
            e.iter().sum::<f64>() / e.len() as f64
        };
        // A uniform spread over the unit sphere has soft error (π/2) / √(4π) ≈ 0.443; the
        // truncated identity kernels do better, the more so the larger k (their Gibbs ringing
        // still spreads weight over the whole sphere).
        let uniform = std::f64::consts::FRAC_PI_2 / area.sqrt();
        let (e9, e36) = (mean(9), mean(36));
        assert!(e36 < e9 && e9 < uniform && e36 < 0.8 * uniform, "{e9} {e36} {uniform}");
        let flip = Mat::<f64>::from_fn(9, 9, |i, j| {
            if i != j {
                0.0
            } else if (1..4).contains(&i) {
                -1.0
            } else {
                1.0
            }
        });
        let e = soft_errors(&basis, &basis, flip.as_ref(), &sample, &table, area).unwrap();
        let e_flip = e.iter().sum::<f64>() / 40.0;
        assert!(e_flip > e9 + 0.05, "{e_flip} vs {e9}");
        // Queries outside the table are errors.
        assert!(table.distances_from(&[n + 5]).is_err());
    }
}
