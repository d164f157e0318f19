//! The axiomatic functional map: the exact minimizer of the energy of [`super::energy`]
//! (descriptor preservation, Laplacian commutativity, descriptor commutativity, orientation)
//! between two shapes, from their bases, their face gradients and corresponding descriptors.
//!
//! Conventions (as in [`super`]): X has n vertices and basis Φ, Y has m and Ψ; C is k × k and
//! maps coefficients on X to coefficients on Y. The first column of C is fixed to map the
//! constant function on X to the constant on Y (`C e₁ = ±√(area_Y / area_X) e₁`, the sign that of
//! the two first eigenvectors), as in Ren et al. 2018: a constraint every map satisfies, and
//! the one datum the descriptors cannot carry after their normalization.

use faer::Mat;
use serde::{Deserialize, Serialize};

use super::energy::{Energy, EnergyTerms, EnergyWeights, Mask, Orientation, SpectralSide};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::operators::{multiplication_operators, orientation_operators, FaceGradients};
use crate::spectral::Basis;

/// Options of [`axiomatic`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxiomaticOptions {
    /// Size k of the functional map (k × k).
    pub k: usize,
    /// Term weights (dimensionless, see [`super::energy`]).
    pub weights: EnergyWeights,
    /// Laplacian-commutativity mask.
    pub mask: Mask,
    /// Which maps the orientation term favours.
    pub orientation: Orientation,
    /// Fix the first column of C to map constants to constants.
    pub fix_constant: bool,
    /// Orientation operators from unit descriptor gradients (see
    /// [`crate::operators::orientation_operators`]).
    pub unit_gradients: bool,
}

impl Default for AxiomaticOptions {
    fn default() -> Self {
        AxiomaticOptions {
            k: 30,
            weights: EnergyWeights { descriptors: 1.0, laplacian: 1e-2, commutativity: 1.0, orientation: 1.0 },
            mask: Mask::Resolvent { gamma: 0.5 },
            orientation: Orientation::Preserve,
            fix_constant: true,
            unit_gradients: false,
        }
    }
}

/// One side of the problem: a basis with at least k eigenpairs, the face gradients of the shape
/// (needed for the orientation term) and its descriptors (n × q).
#[derive(Clone, Copy)]
pub struct ShapeData<'a> {
    /// The eigenbasis (n × ≥ k).
    pub basis: &'a Basis,
    /// Face gradients of the mesh (or triangle soup); `None` when the orientation term is off.
    pub gradients: Option<&'a FaceGradients>,
    /// Descriptors (n × q).
    pub descriptors: &'a Descriptors,
    /// Quadrature cells of the vertices (length n), for large meshes: the operators are then
    /// computed by [`crate::cell_quadrature`] (None: exactly).
    pub cells: Option<&'a [u32]>,
}

/// Builds one side of the energy in the first k eigenpairs: coefficients Φ_kᵀ A F and the
/// operators whose weights are > 0.
pub fn spectral_side(
    s: &ShapeData,
    k: usize,
    multiplication: bool,
    orientation: bool,
    unit_gradients: bool,
    side: &str,
) -> Result<SpectralSide> {
    let b = s.basis;
    if k == 0 || k > b.k() {
        return Err(Error::invalid("k", format!("need 1 ≤ k ≤ {} (the basis size of {side}), got {k}", b.k())));
    }
    let f = &s.descriptors.values;
    if f.nrows() != b.n() {
        return Err(Error::invalid(
            format!("descriptors of {side}"),
            format!("{} rows for {} vertices", f.nrows(), b.n()),
        ));
    }
    let phi = b.eigenvectors.subcols(0, k);
    let af = Mat::from_fn(b.n(), f.ncols(), |i, j| b.mass[i] * f[(i, j)]);
    let mut coefficients = Mat::<f64>::zeros(k, f.ncols());
    faer::linalg::matmul::matmul(
        coefficients.as_mut(),
        faer::Accum::Replace,
        phi.transpose(),
        af.as_ref(),
        1.0,
        faer::Par::Seq,
    );
    let mult = match (multiplication, s.cells) {
        (false, _) => vec![],
        (true, None) => multiplication_operators(phi, &b.mass, f.as_ref())?,
        (true, Some(cells)) => {
            crate::cell_quadrature::multiplication_operators_on_cells(phi, &b.mass, f.as_ref(), cells)?
        }
    };
    let orient = if orientation {
        let g = s.gradients.ok_or_else(|| {
            Error::invalid(
                "orientation",
                format!("the orientation term needs the faces of {side} (a mesh or a point-cloud triangulation)"),
            )
        })?;
        match s.cells {
            None => orientation_operators(g, phi, f.as_ref(), unit_gradients)?,
            Some(cells) => {
                crate::cell_quadrature::orientation_operators_on_cells(g, phi, f.as_ref(), unit_gradients, cells)?
            }
        }
    } else {
        vec![]
    };
    Ok(SpectralSide {
        coefficients,
        eigenvalues: b.eigenvalues[..k].to_vec(),
        multiplication: mult,
        orientation: orient,
    })
}

/// The column C e₁ (k entries) that maps the constant on X to the constant on Y:
/// ±√(area_Y / area_X) e₁, with the sign of φ₁ψ₁ (the first eigenvectors are constant).
pub fn constant_column(x: &Basis, y: &Basis, k: usize) -> Vec<f64> {
    let ax: f64 = x.mass.iter().sum();
    let ay: f64 = y.mass.iter().sum();
    let sign = (x.eigenvectors[(0, 0)] * y.eigenvectors[(0, 0)]).signum();
    let mut col = vec![0.0; k];
    col[0] = sign * (ay / ax).sqrt();
    col
}

/// What [`axiomatic`] returns besides C.
#[derive(Clone, Debug, Serialize)]
pub struct AxiomaticReport {
    /// The terms of the energy at the solution (each divided by its scale).
    pub terms: EnergyTerms,
    /// E at the solution.
    pub energy: f64,
}

/// The functional map C (k × k) minimizing the axiomatic energy between X and Y (see the module
/// docs). Errors: bases smaller than k, descriptors of different column counts or sizes, the
/// orientation term without face gradients, and those of [`Energy::new`].
pub fn axiomatic(x: &ShapeData, y: &ShapeData, opts: &AxiomaticOptions) -> Result<(Mat<f64>, AxiomaticReport)> {
    Ok(axiomatic_sizes(x, y, opts, &[opts.k])?.remove(0))
}

/// [`axiomatic`] at several sizes `ks` (`opts.k` is ignored): the descriptor coefficients and
/// operators are computed once, at the largest size, and their leading blocks serve the smaller
/// ones ([`SpectralSide::leading`]); the fits run in parallel. Returns one (C, report) per size,
/// in the order of `ks`.
pub fn axiomatic_sizes(
    x: &ShapeData,
    y: &ShapeData,
    opts: &AxiomaticOptions,
    ks: &[usize],
) -> Result<Vec<(Mat<f64>, AxiomaticReport)>> {
    fit_sizes((x, "X"), (y, "Y"), opts, ks)
}

/// The pull-backs ([`super::Pullback`], C_yx: k × k, functions on Y → functions on X) of a map
/// X → Y that minimize the axiomatic energy at the sizes `ks` (`opts.k` is ignored): the energy
/// of the map from Y's data to X's, its first column mapping the constant on Y to the constant
/// on X (`C_yx e₁ = ±√(area_X / area_Y) e₁`). Errors as [`axiomatic_sizes`], naming X and Y.
pub fn axiomatic_pullbacks(
    x: &ShapeData,
    y: &ShapeData,
    opts: &AxiomaticOptions,
    ks: &[usize],
) -> Result<Vec<(super::Pullback, AxiomaticReport)>> {
    Ok(fit_sizes((y, "Y"), (x, "X"), opts, ks)?.into_iter().map(|(c, r)| (super::Pullback(c), r)).collect())
}

/// The fits of [`axiomatic_sizes`] of the map from the functions of `source` to those of
/// `target`, each side with the name its errors give it.
/// The most memory the two sides' face matrices of [`fit_sizes`] may take when built side by
/// side (bytes): 64 MB, a 5k-vertex pair's sides at k = 50 are ≈ 16 MB.
const SIDES_TOGETHER_BYTES: usize = 64 << 20;

fn fit_sizes(
    (x, x_name): (&ShapeData, &str),
    (y, y_name): (&ShapeData, &str),
    opts: &AxiomaticOptions,
    ks: &[usize],
) -> Result<Vec<(Mat<f64>, AxiomaticReport)>> {
    use rayon::prelude::*;
    let k = ks.iter().copied().max().ok_or_else(|| Error::invalid("k", "need at least one size"))?;
    if ks.contains(&0) {
        return Err(Error::invalid("k", "sizes must be at least 1"));
    }
    let w = &opts.weights;
    let orient = w.orientation > 0.0 && opts.orientation != Orientation::Ignore;
    let comm = w.commutativity > 0.0;
    if x.descriptors.q() != y.descriptors.q() {
        return Err(Error::invalid(
            "data",
            format!(
                "{} functions on {x_name} but {} on {y_name}; they must correspond",
                x.descriptors.q(),
                y.descriptors.q()
            ),
        ));
    }
    // The two sides side by side (their face gradients and means are sequential), unless
    // holding both sides' n_f × k face matrices at once (four per side) would take more than
    // SIDES_TOGETHER_BYTES: large meshes build one side after the other.
    // (Sides with quadrature cells hold no face matrix: `crate::cell_quadrature`.)
    let faces = |s: &ShapeData| if s.cells.is_some() { 0 } else { s.gradients.map_or(0, |g| g.n_faces()) };
    let together = orient && 4 * 8 * k * (faces(x) + faces(y)) <= SIDES_TOGETHER_BYTES;
    let (sx, sy) = if together || !orient {
        rayon::join(
            || spectral_side(x, k, comm, orient, opts.unit_gradients, x_name),
            || spectral_side(y, k, comm, orient, opts.unit_gradients, y_name),
        )
    } else {
        (
            spectral_side(x, k, comm, orient, opts.unit_gradients, x_name),
            spectral_side(y, k, comm, orient, opts.unit_gradients, y_name),
        )
    };
    let (sx, sy) = (sx?, sy?);
    ks.par_iter()
        .map(|&k| {
            crate::progress::check()?;
            let (sx, sy) = (sx.leading(k), sy.leading(k));
            let energy = Energy::new(&sx, &sy, w, opts.mask, opts.orientation)?;
            let c = if opts.fix_constant {
                energy.solve_with_first_column(&constant_column(x.basis, y.basis, k))?
            } else {
                energy.solve()?
            };
            let report = AxiomaticReport { terms: energy.terms(c.as_ref()), energy: energy.value(c.as_ref()) };
            Ok((c, report))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectral::{eigen_basis, SpectralOptions};

    #[test]
    fn several_sizes_at_once_equal_one_fit_per_size() {
        let mesh = crate::primitives::bumpy_sphere(2);
        let lap = crate::laplacian::cotangent(&mesh).unwrap();
        let basis = eigen_basis(&lap, &SpectralOptions::new(14), None).unwrap().0;
        let moved = crate::primitives::bumpy_sphere(2).map_vertices(|p| [p[0] * 1.1, p[1], p[2] * 0.95]).unwrap();
        let lap_y = crate::laplacian::cotangent(&moved).unwrap();
        let basis_y = eigen_basis(&lap_y, &SpectralOptions::new(14), None).unwrap().0;
        let (dx, dy) = (
            crate::descriptors::signatures::wks(&basis, 6, true).unwrap(),
            crate::descriptors::signatures::wks(&basis_y, 6, true).unwrap(),
        );
        let (gx, gy) = (FaceGradients::new(&mesh).unwrap(), FaceGradients::new(&moved).unwrap());
        let x = ShapeData { basis: &basis, gradients: Some(&gx), descriptors: &dx, cells: None };
        let y = ShapeData { basis: &basis_y, gradients: Some(&gy), descriptors: &dy, cells: None };
        let opts = AxiomaticOptions::default();
        let all = axiomatic_sizes(&x, &y, &opts, &[5, 12, 8]).unwrap();
        for ((c, report), k) in all.iter().zip([5, 12, 8]) {
            let (c1, r1) = axiomatic(&x, &y, &AxiomaticOptions { k, ..opts }).unwrap();
            assert_eq!((c.nrows(), c.ncols()), (k, k));
            let diff = (0..k).flat_map(|i| (0..k).map(move |j| (i, j))).map(|(i, j)| (c[(i, j)] - c1[(i, j)]).abs());
            let scale = (0..k).map(|i| c1[(i, i)].abs()).fold(0.0, f64::max);
            assert!(diff.fold(0.0, f64::max) <= 1e-9 * scale, "k = {k}");
            assert!((report.energy - r1.energy).abs() <= 1e-9 * r1.energy.abs().max(1e-12), "k = {k}");
        }
        assert!(axiomatic_sizes(&x, &y, &opts, &[]).is_err());
        assert!(axiomatic_sizes(&x, &y, &opts, &[0, 4]).is_err());
        // The pull-backs of the map X → Y: the energy's map from Y's data to X's, its constant
        // column ±√(area_X / area_Y); errors name each shape by its own name.
        let back = axiomatic_pullbacks(&x, &y, &opts, &[8]).unwrap();
        let (c_yx, _) = &back[0];
        assert_eq!(c_yx.0, axiomatic(&y, &x, &AxiomaticOptions { k: 8, ..opts }).unwrap().0);
        let ratio = (basis.mass.iter().sum::<f64>() / basis_y.mass.iter().sum::<f64>()).sqrt();
        assert!((c_yx.0[(0, 0)].abs() - ratio).abs() < 1e-9 * ratio, "{} {ratio}", c_yx.0[(0, 0)]);
        let small = eigen_basis(&lap_y, &SpectralOptions::new(6), None).unwrap().0;
        let y6 = ShapeData { basis: &small, ..y };
        let e = axiomatic_pullbacks(&x, &y6, &opts, &[8]).unwrap_err().to_string();
        assert!(e.contains("the basis size of Y"), "{e}");
    }
}
