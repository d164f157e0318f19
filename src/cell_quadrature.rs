//! The operators of [`crate::operators`] on large meshes by a quadrature over cells: the
//! descriptor's factor of each integrand (f_p in `D_p`, the rotated gradient n × ∇f_p in `O_p`)
//! is replaced on each cell by its weighted mean, while the basis' factors stay exact:
//!
//! `D_p ≈ Σ_C f̄_p(C) Σ_{i∈C} A_i φ(i) φ(i)ᵀ`,
//! `(O_p)_ab ≈ Σ_C Σ_c v̄_p,c(C) Σ_{F∈C} w_F mean_F(φ_a) ∂_c φ_b,F` (v = n × ∇f_p, c = x, y, z).
//!
//! The k × k cell products are formed once for all q descriptors, so the cost falls from
//! O(n k² q) to O(n k² + #cells k² q): on a mesh of 52k vertices with 12,500 cells
//! ([`crate::prepared::QUADRATURE_CELLS`]), 4 times fewer operations per descriptor, at 840k 67
//! times. Exact wherever the descriptor's factor is constant on each cell; otherwise off by its
//! covariance with the basis' factors inside a cell, of order (cell diameter / wavelength)² for
//! smooth descriptors. That ratio depends on the number of cells, not of vertices: 12,500 cells
//! on a shape of area a are ≈ √(a / 12,500) across, a tenth of the half wavelength
//! ½ √(π a / k) of a k = 110 eigenfunction (Weyl: λ_k ≈ 4πk / a).
//!
//! Sizes: X has n vertices and n_f faces; Φ is n × k, F is n × q; `cells` (length n) holds each
//! vertex's cell, < #cells.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::linalg::gather_rows;
use crate::operators::{rotated_unit_gradient, FaceGradients};

/// Cells per product block of [`contract`] (a block's k² × (parts · block) matrix: 15 MB at
/// k = 50 with three parts).
const CELL_BLOCK: usize = 256;

/// At most this many partial sums (q k × k matrices each) are held at once by [`contract`]: the
/// cells are split into this many contiguous groups, summed in group order, so the result does
/// not depend on the thread count.
const CELL_GROUPS: usize = 8;

/// The elements (vertices or faces) of every cell: `members[start[c]..start[c + 1]]`, ascending.
struct CellMembers {
    start: Vec<usize>,
    members: Vec<usize>,
}

impl CellMembers {
    /// A counting sort of the elements by `cell` (length T, each < `cells`).
    fn new(cell: &[u32], cells: usize) -> CellMembers {
        let mut start = vec![0usize; cells + 1];
        for &c in cell {
            start[c as usize + 1] += 1;
        }
        for c in 0..cells {
            start[c + 1] += start[c];
        }
        let mut members = vec![0usize; cell.len()];
        let mut next = start.clone();
        for (t, &c) in cell.iter().enumerate() {
            members[next[c as usize]] = t;
            next[c as usize] += 1;
        }
        CellMembers { start, members }
    }

    fn cells(&self) -> usize {
        self.start.len() - 1
    }

    fn of(&self, c: usize) -> &[usize] {
        &self.members[self.start[c]..self.start[c + 1]]
    }
}

/// Σ_C Σ_r ū_r,p(C) P_r,C for every column p of the means `ubar[r]` (#cells × q each, one per
/// part r), the k × k cell products P_r,C = `products(C)[r]` computed block by block. Returns q
/// matrices k × k.
fn contract(
    cells: usize,
    k: usize,
    ubar: &[MatRef<f64>],
    products: impl Fn(usize) -> Vec<Mat<f64>> + Sync,
) -> Result<Vec<Mat<f64>>> {
    let (parts, q) = (ubar.len(), ubar.first().map_or(0, |u| u.ncols()));
    let per_group = cells.div_ceil(CELL_GROUPS).max(1);
    let partials: Vec<Mat<f64>> = (0..cells.div_ceil(per_group))
        .into_par_iter()
        .map(|group| {
            crate::progress::check()?;
            let (g0, g1) = (group * per_group, ((group + 1) * per_group).min(cells));
            let mut acc = Mat::<f64>::zeros(k * k, q);
            // Column r · len + j of the block holds vec(P_r,C) of its j-th cell (column-major:
            // entry (x, y) at x + y k); the means' rows are stacked the same way.
            let mut block = Mat::<f64>::zeros(k * k, parts * CELL_BLOCK);
            let mut means = Mat::<f64>::zeros(parts * CELL_BLOCK, q);
            for c0 in (g0..g1).step_by(CELL_BLOCK) {
                let len = CELL_BLOCK.min(g1 - c0);
                for j in 0..len {
                    for (r, p) in products(c0 + j).into_iter().enumerate() {
                        let col = block.col_mut(r * len + j);
                        let col = col.try_as_col_major_mut().expect("owned columns are contiguous").as_slice_mut();
                        for y in 0..k {
                            col[y * k..(y + 1) * k]
                                .copy_from_slice(p.col(y).try_as_col_major().expect("contiguous").as_slice());
                        }
                    }
                }
                for (r, u) in ubar.iter().enumerate() {
                    means.as_mut().subrows_mut(r * len, len).copy_from(u.subrows(c0, len));
                }
                matmul(
                    acc.as_mut(),
                    Accum::Add,
                    block.as_ref().subcols(0, parts * len),
                    means.as_ref().subrows(0, parts * len),
                    1.0,
                    Par::Seq,
                );
            }
            Ok(acc)
        })
        .collect::<Result<_>>()?;
    let mut total = Mat::<f64>::zeros(k * k, q);
    for part in partials {
        total += part;
    }
    Ok((0..q).map(|p| Mat::from_fn(k, k, |x, y| total[(x + y * k, p)])).collect())
}

/// The weighted means ū(C) = Σ_{t∈C} w_t u_t / Σ_{t∈C} w_t (#cells × q for each of the `parts`
/// components of u_t; 0 on a cell of zero weight), `u(t)` giving element t's q × parts values
/// (row-major: value p of part r at p · parts + r).
fn cell_means(
    cells: &CellMembers,
    w: &[f64],
    q: usize,
    parts: usize,
    u: impl Fn(usize, &mut [f64]) + Sync,
) -> Vec<Mat<f64>> {
    let per_cell: Vec<Vec<f64>> = (0..cells.cells())
        .into_par_iter()
        .map_init(
            || vec![0.0; q * parts],
            |value, c| {
                let (mut sum, mut weight) = (vec![0.0; q * parts], 0.0);
                for &t in cells.of(c) {
                    u(t, value);
                    weight += w[t];
                    sum.iter_mut().zip(value.iter()).for_each(|(s, v)| *s += w[t] * v);
                }
                if weight > 0.0 {
                    sum.iter_mut().for_each(|s| *s /= weight);
                }
                sum
            },
        )
        .collect();
    (0..parts).map(|r| Mat::from_fn(cells.cells(), q, |c, p| per_cell[c][p * parts + r])).collect()
}

/// Checks `cells` (one cell per vertex, length n) and returns the number of cells.
fn cell_count(cells: &[u32], n: usize) -> Result<usize> {
    if cells.len() != n {
        return Err(Error::invalid("cells", format!("{} cells for {n} vertices", cells.len())));
    }
    match cells.iter().max() {
        Some(&m) if m < u32::MAX => Ok(m as usize + 1),
        Some(_) => Err(Error::invalid("cells", "a vertex has no cell")),
        None => Ok(0),
    }
}

/// [`crate::operators::multiplication_operators`] by the cell quadrature (module docs): q
/// symmetric k × k operators of the columns of F (n × q) in the basis Φ (n × k) with vertex
/// weights A (length n), F's columns averaged over the cells `cells` (length n).
pub fn multiplication_operators_on_cells(
    phi: MatRef<f64>,
    mass: &[f64],
    f: MatRef<f64>,
    cells: &[u32],
) -> Result<Vec<Mat<f64>>> {
    let (n, k, q) = (phi.nrows(), phi.ncols(), f.ncols());
    if mass.len() != n || f.nrows() != n {
        return Err(Error::invalid(
            "multiplication operators",
            format!("basis has {n} rows, mass {} entries, functions {} rows", mass.len(), f.nrows()),
        ));
    }
    let members = CellMembers::new(cells, cell_count(cells, n)?);
    let fbar = cell_means(&members, mass, q, 1, |i, v| v.iter_mut().enumerate().for_each(|(p, x)| *x = f[(i, p)]));
    let ops = contract(members.cells(), k, &[fbar[0].as_ref()], |c| {
        let rows = members.of(c);
        let b = gather_rows(phi, rows, 0..k, 1.0);
        let a = Mat::from_fn(rows.len(), k, |s, x| mass[rows[s]] * b[(s, x)]);
        let mut p = Mat::<f64>::zeros(k, k);
        matmul(p.as_mut(), Accum::Replace, a.transpose(), b.as_ref(), 1.0, Par::Seq);
        vec![p]
    })?;
    // Exact symmetry (the cell products round differently in their two triangles).
    Ok(ops.into_iter().map(|d| Mat::from_fn(k, k, |a, b| 0.5 * (d[(a, b)] + d[(b, a)]))).collect())
}

/// [`crate::operators::orientation_operators`] by the cell quadrature (module docs): q k × k
/// operators of the columns of F (n × q) in the basis Φ (n × k), the rotated (with
/// `unit_gradients`, unit) gradients n_F × ∇f_p averaged with the face weights over the cells of
/// the faces (a face's cell is its first corner's in `cells`, length n). The faces' basis
/// gradients and means are formed cell by cell: no n_f × k matrix is held.
pub fn orientation_operators_on_cells(
    grads: &FaceGradients,
    phi: MatRef<f64>,
    f: MatRef<f64>,
    unit_gradients: bool,
    cells: &[u32],
) -> Result<Vec<Mat<f64>>> {
    if f.nrows() != grads.n() || phi.nrows() != grads.n() {
        return Err(Error::invalid(
            "orientation operators",
            format!("{} and {} rows for {} vertices", f.nrows(), phi.nrows(), grads.n()),
        ));
    }
    let count = cell_count(cells, grads.n())?;
    let (k, q) = (phi.ncols(), f.ncols());
    let faces = grads.faces();
    let face_cell: Vec<u32> = faces.iter().map(|t| cells[t[0] as usize]).collect();
    let members = CellMembers::new(&face_cell, count);
    let top = crate::operators::largest_rotated_gradients(grads, f, unit_gradients);
    let vbar = cell_means(&members, &grads.weights, q, 3, |face, v| {
        for p in 0..q {
            let x = rotated_unit_gradient(grads, f, p, face, unit_gradients, top[p]);
            v[3 * p..3 * p + 3].copy_from_slice(&x);
        }
    });
    let ubar: Vec<MatRef<f64>> = vbar.iter().map(|m| m.as_ref()).collect();
    contract(count, k, &ubar, |c| {
        let rows = members.of(c);
        // The faces' weighted means of the basis (as `FaceGradients::weighted_face_means`) and
        // the basis' gradients along x, y, z (as `FaceGradients::basis_gradients`).
        let means = Mat::from_fn(rows.len(), k, |s, a| {
            let t = faces[rows[s]];
            grads.weights[rows[s]] * (phi[(t[0] as usize, a)] + phi[(t[1] as usize, a)] + phi[(t[2] as usize, a)]) / 3.0
        });
        (0..3)
            .map(|d| {
                let g = Mat::from_fn(rows.len(), k, |s, b| {
                    let (t, h) = (faces[rows[s]], &grads.hat[rows[s]]);
                    (0..3).map(|c| phi[(t[c] as usize, b)] * h[c][d]).sum::<f64>()
                });
                let mut p = Mat::<f64>::zeros(k, k);
                matmul(p.as_mut(), Accum::Replace, means.transpose(), g.as_ref(), 1.0, Par::Seq);
                p
            })
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::operators::{multiplication_operators, orientation_operators};
    use crate::primitives::bumpy_sphere;
    use crate::spectral::{eigen_basis, SpectralOptions};

    fn max_abs(m: &Mat<f64>) -> f64 {
        (0..m.nrows())
            .flat_map(|i| (0..m.ncols()).map(move |j| (i, j)))
            .fold(0.0f64, |a, (i, j)| a.max(m[(i, j)].abs()))
    }

    /// One cell per vertex: the multiplication operators are exact (up to rounding); cells of
    /// about 8 vertices on smooth descriptors: both families close to the exact ones; and a
    /// descriptor constant on every cell gives the exact multiplication operator.
    #[test]
    fn cell_operators_agree_with_the_exact_ones() {
        let mesh = bumpy_sphere(4);
        let n = mesh.n_vertices();
        let lap = cotangent(&mesh).unwrap();
        let (basis, _) = eigen_basis(&lap, &SpectralOptions::new(12), None).unwrap();
        let phi = basis.eigenvectors.as_ref();
        let grads = FaceGradients::new(&mesh).unwrap();
        let p = mesh.vertices();
        let f = Mat::from_fn(n, 3, |i, c| match c {
            0 => p[i][0] + 0.3 * p[i][1] * p[i][1],
            1 => (2.0 * p[i][2]).sin(),
            _ => p[i][0] * p[i][1],
        });
        let own: Vec<u32> = (0..n as u32).collect();
        let cells = crate::spatial::grid_samples(p, n / 8);
        let geo = crate::geodesic::GraphGeodesics::mesh_edges(&mesh).unwrap();
        let (_, coarse) = geo.nearest_sources(&cells).unwrap();
        let exact_d = multiplication_operators(phi, &basis.mass, f.as_ref()).unwrap();
        let exact_o = orientation_operators(&grads, phi, f.as_ref(), true).unwrap();
        // (cells, tolerance of D, tolerance of O): with one cell per vertex D is exact, O still
        // averages the rotated gradients of the faces sharing a first corner.
        for (labels, tol_d, tol_o) in [(&own, 1e-12, 1e-2), (&coarse, 0.04, 0.04)] {
            let d = multiplication_operators_on_cells(phi, &basis.mass, f.as_ref(), labels).unwrap();
            let o = orientation_operators_on_cells(&grads, phi, f.as_ref(), true, labels).unwrap();
            for p in 0..3 {
                let (sd, so) = (max_abs(&exact_d[p]), max_abs(&exact_o[p]));
                let ed = max_abs(&(&d[p] - &exact_d[p])) / sd;
                let eo = max_abs(&(&o[p] - &exact_o[p])) / so;
                assert!(ed <= tol_d && eo <= tol_o, "descriptor {p}: relative errors {ed:.2e}, {eo:.2e}");
            }
        }
        // Constant on every cell: exact multiplication operators.
        let g = Mat::from_fn(n, 2, |i, c| (coarse[i] as f64 * (c + 1) as f64).sin());
        let d = multiplication_operators_on_cells(phi, &basis.mass, g.as_ref(), &coarse).unwrap();
        let exact = multiplication_operators(phi, &basis.mass, g.as_ref()).unwrap();
        for p in 0..2 {
            assert!(max_abs(&(&d[p] - &exact[p])) <= 1e-12 * max_abs(&exact[p]));
        }
        // Bad cells.
        assert!(multiplication_operators_on_cells(phi, &basis.mass, f.as_ref(), &own[1..]).is_err());
        let mut holes = own.clone();
        holes[3] = u32::MAX;
        assert!(multiplication_operators_on_cells(phi, &basis.mass, f.as_ref(), &holes).is_err());
    }
}
