//! Differential operators on triangle meshes besides the Laplacian: per-face gradients of
//! piecewise-linear (PL) functions, and the two families of operators that orientation-aware
//! functional maps compare across shapes (Nogneng & Ovsjanikov 2017; Ren, Poulenard, Wonka,
//! Ovsjanikov 2018), written in a basis Φ (n × k, Φᵀ A Φ = I):
//!
//! - the **multiplication operator** of a function f, g ↦ f g:
//!   `D_f = Φᵀ A diag(f) Φ` (k × k, symmetric);
//! - the **orientation operator** of f, g ↦ ⟨n × ∇f, ∇g⟩ (the derivative of g along ∇f rotated by
//!   90° in the tangent plane), in its Galerkin form
//!   `(O_f)_ab = ∫ φ_a ⟨n × ∇f, ∇φ_b⟩ dA = Σ_F area_F · mean_F(φ_a) · ⟨n_F × ∇f_F, ∇φ_b,F⟩`
//!   (k × k). The integral is exact for PL functions, and since the rotated gradient of a PL
//!   function is divergence-free (its flux across every edge is the tangential derivative of f,
//!   continuous across the edge), `O_f` is exactly skew-symmetric on a closed mesh. A mirror
//!   reflection flips n × ∇f, so orientation-reversing maps change the sign of `O_f`; this is
//!   what lets a functional map tell a shape from its mirror image.
//!
//! Sizes: X has n vertices and n_f faces; functions are length-n vectors, bases n × k.
//! Units: gradients are in (function units) / length; `O_f` is dimensionless for a
//! dimensionless f (∫ over area of 1/length²).

use faer::linalg::matmul::matmul;
use faer::reborrow::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::TriMesh;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Per-face geometry of a triangle mesh for gradients of PL functions.
///
/// For face F = (i, j, k) with unit normal n_F and area A_F, the gradient of the hat function of
/// corner i is `n_F × (x_k − x_j) / (2 A_F)` (the edge opposite i, turned inward), and the
/// gradient of a PL function f is `Σ_c f_c ∇φ_c`. Degenerate faces (A_F ≤ 1e-14 × the largest
/// face area) get zero gradients and zero weight: they carry no tangent plane.
#[derive(Debug, Clone)]
pub struct FaceGradients {
    n: usize,
    faces: Vec<[u32; 3]>,
    /// Unit normal of every face (n_f).
    pub normals: Vec<[f64; 3]>,
    /// Weight of every face in integrals (n_f, units²): its area, times the mesh's face weight
    /// (1 for meshes; ⅓ for the triangle soups of point clouds, whose triangles are counted
    /// about three times).
    pub weights: Vec<f64>,
    /// Gradients of the three hat functions of every face (n_f × 3 corners × 3 coordinates).
    pub hat: Vec<[[f64; 3]; 3]>,
}

impl FaceGradients {
    /// The face gradients of `mesh`, every face weighted by its area.
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        Self::weighted(mesh, 1.0)
    }

    /// The face gradients with every face's area multiplied by `face_weight` (> 0).
    pub fn weighted(mesh: &TriMesh, face_weight: f64) -> Result<Self> {
        if !(face_weight.is_finite() && face_weight > 0.0) {
            return Err(Error::invalid("face weight", format!("must be finite and > 0, got {face_weight}")));
        }
        if mesh.n_faces() == 0 {
            return Err(Error::invalid("mesh", "it has no faces, so no gradients"));
        }
        let areas = mesh.face_areas();
        let max_area = areas.iter().fold(0.0f64, |m, &a| m.max(a));
        let (mut normals, mut weights, mut hat) =
            (Vec::with_capacity(areas.len()), Vec::with_capacity(areas.len()), Vec::with_capacity(areas.len()));
        for (f, &area) in areas.iter().enumerate() {
            let p = mesh.corners(f);
            let nrm = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            if area.is_nan() || area <= 1e-14 * max_area {
                normals.push([0.0; 3]);
                weights.push(0.0);
                hat.push([[0.0; 3]; 3]);
                continue;
            }
            let unit = [nrm[0] / (2.0 * area), nrm[1] / (2.0 * area), nrm[2] / (2.0 * area)];
            let mut g = [[0.0; 3]; 3];
            for c in 0..3 {
                let e = sub(p[(c + 2) % 3], p[(c + 1) % 3]);
                let r = cross(unit, e);
                g[c] = [r[0] / (2.0 * area), r[1] / (2.0 * area), r[2] / (2.0 * area)];
            }
            normals.push(unit);
            weights.push(area * face_weight);
            hat.push(g);
        }
        Ok(FaceGradients { n: mesh.n_vertices(), faces: mesh.faces().to_vec(), normals, weights, hat })
    }

    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of faces n_f.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    /// The triangles (0-based vertex indices).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    fn check_function(&self, f: &[f64], what: &str) -> Result<()> {
        if f.len() != self.n {
            return Err(Error::invalid(what, format!("{} values for {} vertices", f.len(), self.n)));
        }
        if let Some(i) = f.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(what, format!("value at vertex {i} is not finite")));
        }
        Ok(())
    }

    /// ∇f on every face (n_f × 3) of a PL function f (length n).
    pub fn gradient(&self, f: &[f64]) -> Result<Vec<[f64; 3]>> {
        self.check_function(f, "function")?;
        Ok(self.gradient_unchecked(f))
    }

    fn gradient_unchecked(&self, f: &[f64]) -> Vec<[f64; 3]> {
        (0..self.faces.len()).map(|face| self.face_gradient(face, |i| f[i])).collect()
    }

    /// ∇f on one face of a PL function given by its vertex values `value(i)`.
    fn face_gradient(&self, face: usize, value: impl Fn(usize) -> f64) -> [f64; 3] {
        let (tri, g) = (self.faces[face], &self.hat[face]);
        let mut out = [0.0; 3];
        for c in 0..3 {
            let v = value(tri[c] as usize);
            for d in 0..3 {
                out[d] += v * g[c][d];
            }
        }
        out
    }

    /// n × ∇f on every face (n_f × 3): the gradient of f turned by +90° about the normal.
    pub fn rotated_gradient(&self, f: &[f64]) -> Result<Vec<[f64; 3]>> {
        let g = self.gradient(f)?;
        Ok(g.iter().zip(&self.normals).map(|(g, n)| cross(*n, *g)).collect())
    }

    /// The gradients of the k columns of a basis Φ (n × k) on every face: three n_f × k matrices
    /// (x, y and z components).
    pub fn basis_gradients(&self, phi: MatRef<f64>) -> Result<[Mat<f64>; 3]> {
        if phi.nrows() != self.n {
            return Err(Error::invalid("basis", format!("{} rows for {} vertices", phi.nrows(), self.n)));
        }
        let (nf, k) = (self.faces.len(), phi.ncols());
        let mut out = [Mat::<f64>::zeros(nf, k), Mat::<f64>::zeros(nf, k), Mat::<f64>::zeros(nf, k)];
        for (d, m) in out.iter_mut().enumerate() {
            for b in 0..k {
                let col = m.col_mut(b);
                let col = col.try_as_col_major_mut().expect("owned columns are contiguous").as_slice_mut();
                for (f, tri) in self.faces.iter().enumerate() {
                    let g = &self.hat[f];
                    col[f] = (0..3).map(|c| phi[(tri[c] as usize, b)] * g[c][d]).sum();
                }
            }
        }
        Ok(out)
    }

    /// The face means of a basis, weighted: row F is weight_F · (φ(i) + φ(j) + φ(k)) / 3
    /// (n_f × k), so that `means.transpose() · (per-face values)` integrates φ_a times a
    /// per-face constant exactly.
    pub fn weighted_face_means(&self, phi: MatRef<f64>) -> Result<Mat<f64>> {
        if phi.nrows() != self.n {
            return Err(Error::invalid("basis", format!("{} rows for {} vertices", phi.nrows(), self.n)));
        }
        Ok(Mat::from_fn(self.faces.len(), phi.ncols(), |f, a| {
            let tri = self.faces[f];
            self.weights[f] * (phi[(tri[0] as usize, a)] + phi[(tri[1] as usize, a)] + phi[(tri[2] as usize, a)]) / 3.0
        }))
    }
}

/// The orientation function of two functions on a mesh, n · (∇f × ∇g) = ⟨n × ∇f, ∇g⟩ (length n,
/// units of f g / length²): per face, then averaged to the vertices with the face weights. It
/// changes sign under any orientation-reversing map (a mirror image, a left–right symmetry)
/// while f and g do not, so a pair of symmetric descriptors yields an antisymmetric one.
pub fn orientation_function(grads: &FaceGradients, f: &[f64], g: &[f64]) -> Result<Vec<f64>> {
    let (gf, gg) = (grads.gradient(f)?, grads.gradient(g)?);
    let mut num = vec![0.0; grads.n()];
    let mut den = vec![0.0; grads.n()];
    for (face, tri) in grads.faces().iter().enumerate() {
        let w = grads.weights[face];
        let c = cross(gf[face], gg[face]);
        let nrm = grads.normals[face];
        let v = c[0] * nrm[0] + c[1] * nrm[1] + c[2] * nrm[2];
        for &i in tri {
            num[i as usize] += w * v;
            den[i as usize] += w;
        }
    }
    Ok(num.iter().zip(&den).map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 }).collect())
}

/// Multiplication operators `D_p = Φᵀ A diag(f_p) Φ` (k × k each) of the q columns of F
/// (n × q) in the basis Φ (n × k) with vertex weights A (length n). Symmetric.
pub fn multiplication_operators(phi: MatRef<f64>, mass: &[f64], f: MatRef<f64>) -> Result<Vec<Mat<f64>>> {
    let (n, k) = (phi.nrows(), phi.ncols());
    if mass.len() != n || f.nrows() != n {
        return Err(Error::invalid(
            "multiplication operators",
            format!("basis has {n} rows, mass {} entries, functions {} rows", mass.len(), f.nrows()),
        ));
    }
    Ok((0..f.ncols())
        .into_par_iter()
        .map(|p| {
            // (A f_p)_i φ_a(i), as (mass_i f_p(i)) φ_a(i).
            let af: Vec<f64> = (0..n).map(|i| mass[i] * f[(i, p)]).collect();
            let weighted = crate::linalg::scale_rows(phi, &af);
            let mut d = Mat::<f64>::zeros(k, k);
            matmul(d.as_mut(), Accum::Replace, phi.transpose(), weighted.as_ref(), 1.0, Par::Seq);
            // Exact symmetry (the two products round differently).
            Mat::from_fn(k, k, |a, b| 0.5 * (d[(a, b)] + d[(b, a)]))
        })
        .collect())
}

/// Faces per product block of [`orientation_operators`] (a block's n_f × k matrices stay in
/// cache: 2048 × 50 × 8 bytes = 0.8 MB each).
const FACE_BLOCK: usize = 2048;

/// At most this many partial sums (q k × k matrices each, 1 MB for q = k = 50) are held at once
/// by [`orientation_operators`]: the faces are split into this many contiguous groups (fewer
/// when there are fewer blocks), summed in group order, so the result does not depend on the
/// thread count.
const FACE_GROUPS: usize = 8;

/// W[t, b] = ⟨v_t, ∇φ_b⟩ = v_t,x g_x[t, b] + v_t,y g_y[t, b] + v_t,z g_z[t, b] on a block of
/// faces: `v` the three coordinates of the rotated descriptor gradients (len each), `g` the
/// three components of the basis' face gradients (len × k each), `w` len × k.
#[inline(always)]
fn rotated_gradient_products_generic<'a>(v: [&[f64]; 3], g: [MatRef<'a, f64>; 3], mut w: MatMut<'_, f64>) {
    let len = v[0].len();
    let col = |m: MatRef<'a, f64>, b: usize| -> &'a [f64] {
        let c = m.col(b).try_as_col_major().expect("gradient columns are contiguous");
        &c.as_slice()[..len]
    };
    for b in 0..w.ncols() {
        let (c0, c1, c2) = (col(g[0], b), col(g[1], b), col(g[2], b));
        let out = w.rb_mut().col_mut(b).try_as_col_major_mut().expect("owned columns are contiguous").as_slice_mut();
        for t in 0..len {
            out[t] = v[0][t] * c0[t] + v[1][t] * c1[t] + v[2][t] * c2[t];
        }
    }
}

crate::linalg::at_vector_width! {
    /// [`rotated_gradient_products_generic`] at the CPU's vector width.
    fn rotated_gradient_products(v: [&[f64]; 3], g: [MatRef<'_, f64>; 3], w: MatMut<'_, f64>) = rotated_gradient_products_generic
}

/// n_F × ∇f_p on `face` (f n × q, p a column), divided by its length with `unit_gradients`
/// (zero where that length is at most 1e-12 × `top`, the descriptor's largest).
pub(crate) fn rotated_unit_gradient(
    grads: &FaceGradients,
    f: MatRef<f64>,
    p: usize,
    face: usize,
    unit_gradients: bool,
    top: f64,
) -> [f64; 3] {
    let x = cross(grads.normals[face], grads.face_gradient(face, |i| f[(i, p)]));
    if !unit_gradients {
        return x;
    }
    let l = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    if l > 1e-12 * top {
        [x[0] / l, x[1] / l, x[2] / l]
    } else {
        [0.0; 3]
    }
}

/// The largest |n_F × ∇f_p| over the faces of every column of f (n × q), for the unit
/// gradients' zero test of [`rotated_unit_gradient`] (zeros without `unit_gradients`).
pub(crate) fn largest_rotated_gradients(grads: &FaceGradients, f: MatRef<f64>, unit_gradients: bool) -> Vec<f64> {
    if !unit_gradients {
        return vec![0.0; f.ncols()];
    }
    (0..f.ncols())
        .into_par_iter()
        .map(|p| {
            (0..grads.n_faces()).fold(0.0f64, |m, face| {
                let v = rotated_unit_gradient(grads, f, p, face, false, 0.0);
                m.max((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            })
        })
        .collect()
}

/// Orientation operators `O_p` (k × k each, see the module docs) of the q columns of F (n × q)
/// in the basis Φ (n × k): `(O_p)_ab = Σ_F w_F mean_F(φ_a) ⟨n_F × ∇f_p, ∇φ_b⟩`. With
/// `unit_gradients`, ∇f_p is replaced by ∇f_p / |∇f_p| on every face (as in the BCICP code of
/// Ren et al. 2018): every face then counts by its area alone, not by how fast f_p varies there
/// (faces where ∇f_p = 0 contribute nothing).
///
/// Cost O(n_f · k · (k + 3) · q). Computed over blocks of faces, every descriptor per block, so
/// that the basis' face gradients and means are read once (not once per descriptor) and the
/// n_f × k products live only block by block; memory: three n_f × k gradient matrices, the
/// n_f × k means, and at most `FACE_GROUPS` partial sums of the q operators.
pub fn orientation_operators(
    grads: &FaceGradients,
    phi: MatRef<f64>,
    f: MatRef<f64>,
    unit_gradients: bool,
) -> Result<Vec<Mat<f64>>> {
    if f.nrows() != grads.n() {
        return Err(Error::invalid("orientation operators", format!("{} rows for {} vertices", f.nrows(), grads.n())));
    }
    let g = grads.basis_gradients(phi)?;
    let means = grads.weighted_face_means(phi)?;
    let (nf, k, q) = (grads.n_faces(), phi.ncols(), f.ncols());
    let top = largest_rotated_gradients(grads, f, unit_gradients);
    let per_group = nf.div_ceil(FACE_GROUPS.min(nf.div_ceil(FACE_BLOCK))).max(1);
    let partials: Vec<Vec<Mat<f64>>> = (0..nf.div_ceil(per_group))
        .into_par_iter()
        .map(|group| {
            crate::progress::check()?;
            let mut ops = vec![Mat::<f64>::zeros(k, k); q];
            let (g0, g1) = (group * per_group, ((group + 1) * per_group).min(nf));
            let mut w = Mat::<f64>::zeros(FACE_BLOCK.min(g1 - g0), k);
            // The block's rotated gradients, one array per coordinate.
            let mut v = [vec![0.0; FACE_BLOCK], vec![0.0; FACE_BLOCK], vec![0.0; FACE_BLOCK]];
            for b0 in (g0..g1).step_by(FACE_BLOCK) {
                let len = FACE_BLOCK.min(g1 - b0);
                let gb: [MatRef<f64>; 3] = std::array::from_fn(|c| g[c].as_ref().subrows(b0, len));
                for (p, op) in ops.iter_mut().enumerate() {
                    for t in 0..len {
                        let x = rotated_unit_gradient(grads, f, p, b0 + t, unit_gradients, top[p]);
                        (v[0][t], v[1][t], v[2][t]) = (x[0], x[1], x[2]);
                    }
                    let vb = [&v[0][..len], &v[1][..len], &v[2][..len]];
                    rotated_gradient_products(vb, gb, w.as_mut().subrows_mut(0, len));
                    let wb = w.as_ref().subrows(0, len);
                    matmul(
                        op.as_mut(),
                        Accum::Add,
                        means.as_ref().subrows(b0, len).transpose(),
                        wb.as_ref(),
                        1.0,
                        Par::Seq,
                    );
                }
            }
            Ok(ops)
        })
        .collect::<Result<_>>()?;
    let mut out = vec![Mat::<f64>::zeros(k, k); q];
    for part in partials {
        for (o, p) in out.iter_mut().zip(part) {
            *o += p;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::primitives::{bumpy_sphere, icosphere};
    use crate::spectral::{eigen_basis, SpectralOptions};

    #[test]
    fn gradients_of_linear_functions_are_exact() {
        // On any mesh, a linear function a·x has gradient equal to the tangential part of a.
        let m = bumpy_sphere(2);
        let g = FaceGradients::new(&m).unwrap();
        let a = [0.3, -1.2, 0.7];
        let f: Vec<f64> = m.vertices().iter().map(|p| a[0] * p[0] + a[1] * p[1] + a[2] * p[2]).collect();
        let grad = g.gradient(&f).unwrap();
        for (gf, n) in grad.iter().zip(&g.normals) {
            let an = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
            for d in 0..3 {
                let want = a[d] - an * n[d];
                assert!((gf[d] - want).abs() < 1e-10, "{gf:?} vs tangential part of {a:?}");
            }
        }
        // The rotated gradient is tangent and orthogonal to the gradient.
        let rot = g.rotated_gradient(&f).unwrap();
        for ((r, gf), n) in rot.iter().zip(&grad).zip(&g.normals) {
            let dot = |u: &[f64; 3], v: &[f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
            assert!(dot(r, gf).abs() < 1e-10 && dot(r, n).abs() < 1e-10);
            assert!((dot(r, r) - dot(gf, gf)).abs() < 1e-10);
        }
    }

    #[test]
    fn orientation_operators_are_skew_and_flip_under_reflection() {
        let m = bumpy_sphere(2);
        let basis = eigen_basis(&cotangent(&m).unwrap(), &SpectralOptions::new(12), None).unwrap().0;
        let phi = basis.eigenvectors.as_ref();
        let f = Mat::from_fn(m.n_vertices(), 3, |i, p| basis.eigenvectors[(i, p + 1)] + 0.1 * m.vertices()[i][p]);
        let ops = orientation_operators(&FaceGradients::new(&m).unwrap(), phi, f.as_ref(), false).unwrap();
        for o in &ops {
            let skew = Mat::from_fn(12, 12, |a, b| o[(a, b)] + o[(b, a)]);
            assert!(skew.norm_max() < 1e-9 * o.norm_max(), "not skew: {} vs {}", skew.norm_max(), o.norm_max());
            assert!(o.norm_max() > 1e-3);
        }
        // Mirror the mesh (x → −x) and reverse its triangles so that normals point outward
        // again: the same functions get operators of the opposite sign.
        let mirrored = TriMesh::new(
            m.vertices().iter().map(|p| [-p[0], p[1], p[2]]).collect(),
            m.faces().iter().map(|t| [t[0], t[2], t[1]]).collect(),
        )
        .unwrap();
        let ops_m = orientation_operators(&FaceGradients::new(&mirrored).unwrap(), phi, f.as_ref(), false).unwrap();
        for (o, om) in ops.iter().zip(&ops_m) {
            let sum = o + om;
            assert!(sum.norm_max() < 1e-9 * o.norm_max(), "reflection did not flip the sign");
        }
    }

    /// The blocked computation (faces in groups and blocks of [`FACE_BLOCK`]) equals the
    /// definition summed face by face, on a mesh of 81,920 faces (8 groups of 10,240 faces, five
    /// blocks each), with and without unit gradients; a random basis and functions (only the
    /// sums matter).
    /// The block products ⟨v_t, ∇φ_b⟩ are the same bits at every vector width.
    #[test]
    fn rotated_gradient_products_are_the_same_at_every_vector_width() {
        let (len, k) = (37, 5);
        let mut rng = crate::spectral::Normal::new(11);
        let g: Vec<Mat<f64>> = (0..3).map(|_| Mat::from_fn(len, k, |_, _| rng.sample())).collect();
        let v: Vec<Vec<f64>> = (0..3).map(|_| (0..len).map(|_| rng.sample()).collect()).collect();
        let run = |widest: u8| {
            let mut w = Mat::<f64>::zeros(len, k);
            crate::linalg::with_widest(widest, || {
                rotated_gradient_products(
                    [&v[0], &v[1], &v[2]],
                    [g[0].as_ref(), g[1].as_ref(), g[2].as_ref()],
                    w.as_mut(),
                )
            });
            w
        };
        let want =
            Mat::from_fn(len, k, |t, b| v[0][t] * g[0][(t, b)] + v[1][t] * g[1][(t, b)] + v[2][t] * g[2][(t, b)]);
        for widest in 0..=2 {
            let w = run(widest);
            assert!((0..k).all(|b| (0..len).all(|t| w[(t, b)].to_bits() == want[(t, b)].to_bits())), "widest {widest}");
        }
    }

    #[test]
    fn blocked_orientation_operators_are_the_per_face_sums() {
        let m = icosphere(6);
        let (n, k, q) = (m.n_vertices(), 7, 3);
        let mut rng = crate::spectral::Normal::new(3);
        let phi = Mat::from_fn(n, k, |_, _| rng.sample());
        let f = Mat::from_fn(n, q, |_, _| rng.sample());
        let grads = FaceGradients::new(&m).unwrap();
        assert!(grads.n_faces() > FACE_GROUPS * FACE_BLOCK);
        for unit in [false, true] {
            let ops = orientation_operators(&grads, phi.as_ref(), f.as_ref(), unit).unwrap();
            for (p, o) in ops.iter().enumerate() {
                let fp: Vec<f64> = (0..n).map(|i| f[(i, p)]).collect();
                let mut v = grads.rotated_gradient(&fp).unwrap();
                if unit {
                    for x in &mut v {
                        let l = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                        *x = [x[0] / l, x[1] / l, x[2] / l];
                    }
                }
                let gphi: Vec<Vec<[f64; 3]>> =
                    (0..k).map(|b| grads.gradient(&(0..n).map(|i| phi[(i, b)]).collect::<Vec<_>>()).unwrap()).collect();
                for a in 0..k {
                    for b in 0..k {
                        let mut want = 0.0;
                        for (face, tri) in grads.faces().iter().enumerate() {
                            let mean = tri.iter().map(|&i| phi[(i as usize, a)]).sum::<f64>() / 3.0;
                            let g = gphi[b][face];
                            want += grads.weights[face]
                                * mean
                                * (v[face][0] * g[0] + v[face][1] * g[1] + v[face][2] * g[2]);
                        }
                        assert!(
                            (o[(a, b)] - want).abs() <= 1e-9 * (1.0 + want.abs()),
                            "unit {unit}, O_{p}[{a}, {b}] = {} against {want}",
                            o[(a, b)]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn multiplication_by_one_is_the_identity() {
        let m = icosphere(2);
        let basis = eigen_basis(&cotangent(&m).unwrap(), &SpectralOptions::new(10), None).unwrap().0;
        let ones = Mat::from_fn(m.n_vertices(), 1, |_, _| 1.0);
        let d = multiplication_operators(basis.eigenvectors.as_ref(), &basis.mass, ones.as_ref()).unwrap();
        assert!((&d[0] - Mat::<f64>::identity(10, 10)).norm_max() < 1e-10);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let m = icosphere(1);
        let g = FaceGradients::new(&m).unwrap();
        assert!(g.gradient(&[0.0; 3]).is_err());
        let mut f = vec![0.0; m.n_vertices()];
        f[2] = f64::NAN;
        assert!(g.gradient(&f).is_err());
        assert!(FaceGradients::weighted(&m, 0.0).is_err());
        let phi = Mat::<f64>::zeros(3, 2);
        assert!(g.basis_gradients(phi.as_ref()).is_err());
    }
}
