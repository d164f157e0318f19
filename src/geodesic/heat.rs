//! [`HeatGeodesics`]: the heat method (Crane, Weischedel, Wardetzky 2013), a fast approximation,
//! computed on the *intrinsic Delaunay triangulation* of the mesh (see [`super::intrinsic`];
//! Crane et al. 2017, §"Robustness"):
//! 1. integrate the heat flow for a short time t = h² (h the mean edge length of the mesh):
//!    (A + t W) u = δ_s;
//! 2. normalize its gradient per triangle, X = −∇u / |∇u|;
//! 3. solve the Poisson problem W φ = −∇·X (W the cotangent stiffness, positive semi-definite) and
//!    shift φ so that φ(s) = 0.
//!
//! Why the intrinsic Delaunay triangulation: on a mesh with many obtuse triangles the cotangent
//! weights of the mesh's own edges can be negative (18 % of the edges of TOSCA `cat0`, angles up
//! to 177°), A + tW is then not an M-matrix and its solution u is not positive: far from the
//! source, where the true u is as small as 10⁻³⁰, 17–36 % of the vertices got u ≤ 0 (5 sources)
//! and the gradient directions there were noise. The distances came out short: mean heat / exact
//! 0.71 on tosca_r `cat0`, 0.51–0.93 over the TOSCA shapes, up to 100 % short at single vertices.
//! Flipping edges intrinsically until they are Delaunay changes the triangulation, not the
//! surface (same polyhedral metric, same vertices), makes every weight ≥ 0, and brings the error
//! back to that of well-shaped meshes (measured in `examples/heat_accuracy.rs`, table in
//! BENCHMARKS.md: 1.6–3.9 % mean relative error on every benchmark shape). On a mesh that is
//! already Delaunay nothing changes. Gradients and divergences are computed per intrinsic
//! triangle from its edge lengths (a planar layout), never from the 3D positions.
//!
//! Both matrices are factored once (sparse Cholesky), so every further source costs two
//! triangular solves per right-hand side; sources are processed in blocks. Distances are in
//! the mesh's units and scale with the mesh (all steps are scale-free: t ∝ h², W is
//! dimensionless). Accuracy, measured in the tests below (points farther than 0.1–0.2 from the
//! source): mean relative error 0.9–1.0 % on the unit icosphere with 2,562 vertices (three
//! sources) and 0.8 % on a 2 × 1 rectangle with 3,321 vertices; errors are larger within a few
//! edges of the source and near boundaries (Neumann boundary conditions). Against the exact polyhedral distances of
//! [`super::ExactGeodesics`] see the measurements in the [module documentation](super).

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::{Mat, Side};
use rayon::prelude::*;

use super::intrinsic::IntrinsicTriangulation;
use crate::error::{Error, Result};
use crate::laplacian::Laplacian;
use crate::shape::TriMesh;

/// Prefactored heat-method distance solver for one mesh.
pub struct HeatGeodesics {
    /// The intrinsic Delaunay triangulation the method runs on.
    tri: IntrinsicTriangulation,
    heat: Llt<usize, f64>,
    poisson: Llt<usize, f64>,
    /// Per intrinsic triangle: its corners laid out in the plane.
    layout: Vec<[[f64; 2]; 3]>,
    /// Per intrinsic triangle: the three cotangents of its corner angles.
    cots: Vec<[f64; 3]>,
    n: usize,
}

/// `lap.w + s · diag(d)`, factored.
fn factor_shifted(lap: &Laplacian, scale_w: f64, diag: &[f64]) -> Result<Llt<usize, f64>> {
    let mut m = lap.w.clone();
    let sym = lap.w.symbolic();
    let (cp, ri) = (sym.col_ptr().to_vec(), sym.row_idx().to_vec());
    let vals = m.val_mut();
    for c in 0..lap.n() {
        for p in cp[c]..cp[c + 1] {
            vals[p] *= scale_w;
            if ri[p] == c {
                vals[p] += diag[c];
            }
        }
    }
    m.sp_cholesky(Side::Lower).map_err(|e| Error::numerical("geodesics", format!("factorization failed: {e:?}")))
}

impl HeatGeodesics {
    /// Builds the intrinsic Delaunay triangulation of `mesh` and factors the heat and Poisson
    /// systems, with time step t = h² (h the mean edge length of `mesh`).
    ///
    /// Errors: those of [`crate::laplacian::cotangent`] (e.g. unreferenced vertices), or a mesh
    /// with several components (distances between components are infinite; split the mesh
    /// first).
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        Self::with_time_factor(mesh, 1.0)
    }

    /// As [`Self::new`] with time step t = m · h² (Crane et al. use m = 1; larger m smooths the
    /// distances, smaller m approaches graph-like distances and loses precision far from the
    /// source).
    ///
    /// Errors: `m` not finite and positive, and those of [`Self::new`].
    pub fn with_time_factor(mesh: &TriMesh, m: f64) -> Result<Self> {
        if !(m.is_finite() && m > 0.0) {
            return Err(Error::invalid("time factor", format!("{m} is not a finite positive number")));
        }
        let (components, _) = mesh.components();
        if components > 1 {
            return Err(Error::invalid(
                "mesh",
                format!("it has {components} connected components; geodesics need one"),
            ));
        }
        let tri = IntrinsicTriangulation::delaunay(mesh)?;
        let lap = tri.laplacian()?;
        let h = mesh.mean_edge_length();
        let t = m * h * h;
        let heat = factor_shifted(&lap, t, &lap.mass)?;
        // W is singular (constants); a tiny multiple of the mass makes it definite without
        // changing the solution measurably (φ is shifted afterwards anyway).
        let area: f64 = lap.mass.iter().sum();
        let eps: Vec<f64> = lap.mass.iter().map(|a| 1e-10 * a / area * lap.n() as f64).collect();
        let poisson = factor_shifted(&lap, 1.0, &eps)?;
        let layout: Vec<[[f64; 2]; 3]> = (0..tri.faces.len()).map(|f| tri.layout(f)).collect();
        let cots = layout
            .iter()
            .map(|p| {
                let mut c = [0.0; 3];
                for k in 0..3 {
                    let (a, b) = (sub(p[(k + 1) % 3], p[k]), sub(p[(k + 2) % 3], p[k]));
                    let s = cross(a, b).abs();
                    c[k] = if s > 0.0 { dot(a, b) / s } else { 0.0 };
                }
                c
            })
            .collect();
        Ok(HeatGeodesics { n: mesh.n_vertices(), tri, heat, poisson, layout, cots })
    }

    /// Number of vertices n of the mesh.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of intrinsic edge flips that made the triangulation Delaunay (0 for a Delaunay
    /// mesh).
    pub fn flips(&self) -> usize {
        self.tri.flips
    }

    /// Approximate geodesic distances from each of `sources` to every vertex: n × sources.len().
    pub fn distances(&self, sources: &[usize]) -> Result<Mat<f64>> {
        if let Some(&s) = sources.iter().find(|&&s| s >= self.n) {
            return Err(Error::invalid("source", format!("vertex {s} is out of range (n = {})", self.n)));
        }
        let mut out = Mat::<f64>::zeros(self.n, sources.len());
        const BLOCK: usize = 32;
        for (b, chunk) in sources.chunks(BLOCK).enumerate() {
            crate::progress::check()?;
            // 1. Heat flow.
            let mut u = Mat::<f64>::zeros(self.n, chunk.len());
            for (j, &s) in chunk.iter().enumerate() {
                u[(s, j)] = 1.0;
            }
            self.heat.solve_in_place(u.as_mut());
            // 2–3. Divergence of the normalized gradient field, then the Poisson solve.
            let cols: Vec<Vec<f64>> =
                (0..chunk.len()).into_par_iter().map(|j| self.divergence(u.col_as_slice(j))).collect();
            let mut phi = Mat::from_fn(self.n, chunk.len(), |i, j| -cols[j][i]);
            self.poisson.solve_in_place(phi.as_mut());
            for (j, &s) in chunk.iter().enumerate() {
                let base = phi[(s, j)];
                let col = out.col_as_slice_mut(b * BLOCK + j);
                for (i, o) in col.iter_mut().enumerate() {
                    *o = (phi[(i, j)] - base).max(0.0);
                }
            }
        }
        Ok(out)
    }

    /// ∇·X at every vertex for X = −∇u/|∇u| per intrinsic triangle (integrated divergence,
    /// Crane et al. eq. (4)), in each triangle's planar layout.
    fn divergence(&self, u: &[f64]) -> Vec<f64> {
        let mut div = vec![0.0; self.n];
        for (f, tri) in self.tri.faces.iter().enumerate() {
            let p = self.layout[f];
            let twice_area = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            if twice_area <= 0.0 {
                continue;
            }
            // ∇u = (1 / 2A) Σ_c u_c (J e_c), e_c the edge opposite corner c (counter-clockwise),
            // J the rotation by +90°.
            let mut g = [0.0; 2];
            for c in 0..3 {
                let e = sub(p[(c + 2) % 3], p[(c + 1) % 3]);
                let r = [-e[1], e[0]];
                for d in 0..2 {
                    g[d] += u[tri[c] as usize] * r[d] / twice_area;
                }
            }
            let gl = dot(g, g).sqrt();
            if gl == 0.0 {
                continue;
            }
            let x = [-g[0] / gl, -g[1] / gl];
            // For corner c: ½ (cot θ₁ (e₁ · X) + cot θ₂ (e₂ · X)), e₁, e₂ the edges leaving c,
            // θ₁, θ₂ the angles opposite them.
            for c in 0..3 {
                let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
                let e1 = sub(p[c1], p[c]);
                let e2 = sub(p[c2], p[c]);
                div[tri[c] as usize] += 0.5 * (self.cots[f][c2] * dot(e1, x) + self.cots[f][c1] * dot(e2, x));
            }
        }
        div
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
/// z-component of the cross product of two plane vectors.
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}
fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::ExactGeodesics;
    use crate::primitives::{icosphere, rectangle, sheared_grid};

    fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    /// Mean of |approx − exact| / exact over the entries with exact > `min`.
    fn mean_relative_error(approx: &[f64], exact: &[f64], min: f64) -> f64 {
        let (mut sum, mut cnt) = (0.0, 0);
        for (a, e) in approx.iter().zip(exact) {
            if *e > min {
                sum += (a - e).abs() / e;
                cnt += 1;
            }
        }
        sum / cnt as f64
    }

    #[test]
    fn sphere_distances_are_great_circle_arcs() {
        let mesh = icosphere(4);
        let g = HeatGeodesics::new(&mesh).unwrap();
        let sources = [0usize, 100, 2000];
        let d = g.distances(&sources).unwrap();
        for (j, &s) in sources.iter().enumerate() {
            let ps = mesh.vertices()[s];
            let (mut sum, mut cnt) = (0.0, 0);
            for (i, p) in mesh.vertices().iter().enumerate() {
                let exact = dot3(ps, *p).clamp(-1.0, 1.0).acos();
                if exact > 0.2 {
                    sum += (d[(i, j)] - exact).abs() / exact;
                    cnt += 1;
                }
            }
            let mean = sum / cnt as f64;
            assert!(mean < 0.02, "source {s}: mean relative error {mean}"); // measured 0.009–0.010
            assert_eq!(d[(s, j)], 0.0);
        }
    }

    #[test]
    fn flat_distances_are_euclidean() {
        let mesh = rectangle(2.0, 1.0, 80, 40);
        let g = HeatGeodesics::new(&mesh).unwrap();
        let s = 40 * 81 / 2 + 20; // an interior vertex
        let d = g.distances(&[s]).unwrap();
        let ps = mesh.vertices()[s];
        let (mut sum, mut cnt) = (0.0, 0);
        for (i, p) in mesh.vertices().iter().enumerate() {
            let exact = dot3(sub3(*p, ps), sub3(*p, ps)).sqrt();
            if exact > 0.1 {
                sum += (d[(i, 0)] - exact).abs() / exact;
                cnt += 1;
            }
        }
        let mean = sum / cnt as f64;
        assert!(mean < 0.02, "mean relative error {mean}"); // measured 0.008
    }

    /// A sphere of radius 100: distances are 100 × those of the unit sphere (every step of the
    /// method is scale-free) and great-circle arcs to within 1 %.
    #[test]
    fn sphere_of_radius_100_scales_exactly() {
        let unit = icosphere(4);
        let big = unit.map_vertices(|p| [100.0 * p[0], 100.0 * p[1], 100.0 * p[2]]).unwrap();
        let sources = [0usize, 100, 2000];
        let d1 = HeatGeodesics::new(&unit).unwrap().distances(&sources).unwrap();
        let d100 = HeatGeodesics::new(&big).unwrap().distances(&sources).unwrap();
        for (j, &s) in sources.iter().enumerate() {
            let ps = unit.vertices()[s];
            let arcs: Vec<f64> = unit.vertices().iter().map(|p| 100.0 * dot3(ps, *p).clamp(-1.0, 1.0).acos()).collect();
            let mean = mean_relative_error(d100.col_as_slice(j), &arcs, 20.0);
            assert!(mean < 0.015, "source {s}: mean relative error {mean}"); // measured 0.009–0.011
            for i in 0..unit.n_vertices() {
                assert!((d100[(i, j)] - 100.0 * d1[(i, j)]).abs() <= 1e-9 * d100[(i, j)].max(1.0));
            }
        }
    }

    /// An ellipsoid of semi-axes 100, 100, 400 (area 4.0 · 10⁵) triangulated by a stretched
    /// icosphere: its long triangles make 23 % of the cotangent weights negative. Before the
    /// intrinsic Delaunay flips the heat method was 17–25 % off the exact distances here (and
    /// 22 % on TOSCA cat0); now 1.3–1.7 %.
    #[test]
    fn obtuse_large_ellipsoid_matches_exact_distances() {
        let mesh = icosphere(4).map_vertices(|p| [100.0 * p[0], 100.0 * p[1], 400.0 * p[2]]).unwrap();
        let sources = [0usize, 100, 2000];
        let before = IntrinsicTriangulation::new(&mesh).unwrap();
        assert!(5 * before.non_delaunay_edges() > before.n_edges()); // 1,772 of 7,680
        let heat = HeatGeodesics::new(&mesh).unwrap();
        assert!(heat.flips() > 0);
        let d = heat.distances(&sources).unwrap();
        let exact = ExactGeodesics::new(&mesh).unwrap();
        let min = 0.01 * mesh.total_area().sqrt();
        for (j, &s) in sources.iter().enumerate() {
            let e = exact.distances_from_vertex(s).unwrap();
            let mean = mean_relative_error(d.col_as_slice(j), &e, min);
            assert!(mean < 0.03, "source {s}: mean relative error {mean}");
        }
    }

    /// A flat grid of obtuse triangles only (every diagonal non-Delaunay), 180 × 120 units:
    /// geodesics are straight lines. Before the flips: 38 % (centre source) and 89 % (corner
    /// source) mean relative error; now 1.3 % and 0.6 %.
    #[test]
    fn obtuse_planar_grid_distances_are_euclidean() {
        let (nx, ny) = (60u32, 40u32);
        let mesh = sheared_grid(nx, ny, 0.8).map_vertices(|p| [3.0 * p[0], 3.0 * p[1], 0.0]).unwrap();
        let sources = [((ny / 2) * (nx + 1) + nx / 2) as usize, 0];
        let d = HeatGeodesics::new(&mesh).unwrap().distances(&sources).unwrap();
        for (j, &s) in sources.iter().enumerate() {
            let ps = mesh.vertices()[s];
            let euclid: Vec<f64> = mesh.vertices().iter().map(|p| dot3(sub3(*p, ps), sub3(*p, ps)).sqrt()).collect();
            let mean = mean_relative_error(d.col_as_slice(j), &euclid, 3.0);
            assert!(mean < 0.03, "source {s}: mean relative error {mean}");
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mesh = icosphere(1);
        let g = HeatGeodesics::new(&mesh).unwrap();
        assert!(g.distances(&[mesh.n_vertices()]).is_err());
        let s = icosphere(1);
        let n = s.n_vertices() as u32;
        let mut v = s.vertices().to_vec();
        v.extend(s.vertices().iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
        let mut f = s.faces().to_vec();
        f.extend(s.faces().iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
        assert!(HeatGeodesics::new(&TriMesh::new(v, f).unwrap()).is_err());
        for m in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = HeatGeodesics::with_time_factor(&mesh, m).err().expect("an error").to_string();
            assert!(e.contains("time factor"), "{e}");
        }
    }
}
