//! Data terms F (n × q) and G (m × q): the corresponding functions the correspondence is
//! recovered from (paper §2 "Functional maps" and §4.1 "Data").
//!
//! - [`landmarks`]: delta functions at given vertices (the paper's "seeds");
//! - [`signatures`]: heat kernel signature (HKS), wave kernel signature (WKS), heat kernel maps
//!   (HKM), all from a Laplacian eigenbasis;
//! - [`segments`]: indicator functions of segments (the paper's scarce setting), from label files,
//!   and the matching of segments between two shapes;
//! - [`localized`]: any descriptor multiplied by segment indicators (the paper's rich setting);
//! - [`Descriptors::from_matrix`]: any user-provided n × q matrix.
//!
//! Every function returns a [`Descriptors`]: the n × q matrix with a name for each column.

pub mod matching;
pub mod mser;
pub mod persistence;
pub mod signatures;
pub mod spec;

use faer::Mat;

use crate::error::{Error, Result};
use crate::io::DenseMatrix;
use crate::spectral::Basis;

/// q functions on a shape with n vertices: `values` is n × q, column j is the function named
/// `names[j]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptors {
    /// n × q values.
    pub values: Mat<f64>,
    /// q column names (e.g. `hks:t=1.2e-3`, `segment:4`, `delta:117`).
    pub names: Vec<String>,
}

impl Descriptors {
    /// Wraps an n × q matrix and its q column names; errors on a count mismatch or a non-finite value.
    pub fn new(values: Mat<f64>, names: Vec<String>) -> Result<Self> {
        if values.ncols() != names.len() {
            return Err(Error::invalid("descriptors", format!("{} columns but {} names", values.ncols(), names.len())));
        }
        for j in 0..values.ncols() {
            if let Some(i) = values.col_as_slice(j).iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    "descriptors",
                    format!("column {j} ({}) is not finite at vertex {i}", names[j]),
                ));
            }
        }
        Ok(Descriptors { values, names })
    }

    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.values.nrows()
    }

    /// Number of functions q.
    pub fn q(&self) -> usize {
        self.values.ncols()
    }

    /// A user-provided n × q matrix (e.g. from [`crate::io::read_matrix`]); columns are named
    /// `column:0`, `column:1`, …. Errors when the row count is not n, when there are no columns,
    /// and when a value lies beyond ±[`MAX_VALUE`] or a column's largest magnitude is below
    /// [`MIN_VALUE`] without being 0 (where the squared norms of the solvers over- or
    /// underflow: the data must be rescaled).
    pub fn from_matrix(m: &DenseMatrix, n: usize) -> Result<Self> {
        if m.rows != n {
            return Err(Error::invalid(
                "data matrix",
                format!("it has {} rows but the shape has {n} vertices", m.rows),
            ));
        }
        if m.cols == 0 {
            return Err(Error::invalid("data matrix", format!("it has {n} rows but no columns (no descriptor)")));
        }
        let values = Mat::from_fn(m.rows, m.cols, |i, j| m.data[i * m.cols + j]);
        let d = Descriptors::new(values, (0..m.cols).map(|j| format!("column:{j}")).collect())?;
        for j in 0..d.q() {
            let col = d.values.col_as_slice(j);
            let (i, top) =
                col.iter().enumerate().fold((0, 0.0f64), |b, (i, v)| if v.abs() > b.1 { (i, v.abs()) } else { b });
            if top > MAX_VALUE {
                return Err(Error::invalid(
                    "data matrix",
                    format!(
                        "column {j} has the value {:e} at row {i}, beyond ±{MAX_VALUE:e} where squared norms overflow; \
                         rescale the data",
                        col[i]
                    ),
                ));
            }
            if top > 0.0 && top < MIN_VALUE {
                return Err(Error::invalid(
                    "data matrix",
                    format!(
                        "column {j} is at most {top:e} in magnitude, below {MIN_VALUE:e} where squared norms underflow; \
                         rescale the data"
                    ),
                ));
            }
        }
        Ok(d)
    }

    /// The values as a row-major n × q matrix, e.g. to write as `.npy`.
    pub fn to_dense(&self) -> DenseMatrix {
        let (n, q) = (self.n(), self.q());
        DenseMatrix { rows: n, cols: q, data: (0..n * q).map(|t| self.values[(t / q, t % q)]).collect() }
    }

    /// Columns of `self` followed by those of `other` (same n).
    pub fn concat(&self, other: &Descriptors) -> Result<Self> {
        if self.n() != other.n() {
            return Err(Error::invalid("descriptors", format!("cannot join {} and {} rows", self.n(), other.n())));
        }
        let (q1, q2) = (self.q(), other.q());
        let values =
            Mat::from_fn(
                self.n(),
                q1 + q2,
                |i, j| if j < q1 { self.values[(i, j)] } else { other.values[(i, j - q1)] },
            );
        Ok(Descriptors { values, names: self.names.iter().chain(&other.names).cloned().collect() })
    }
}

/// Delta functions δ_v (value 1 at vertex v, 0 elsewhere; the paper's F = (δ_{i1}, …, δ_{iq}))
/// on a shape with n vertices, one column per entry of `vertices`, named `delta:v`.
pub fn landmarks(n: usize, vertices: &[usize]) -> Result<Descriptors> {
    if vertices.is_empty() {
        return Err(Error::invalid("landmarks", "no vertices given"));
    }
    if let Some(&v) = vertices.iter().find(|&&v| v >= n) {
        return Err(Error::invalid("landmarks", format!("vertex {v} is out of range (n = {n})")));
    }
    let mut values = Mat::<f64>::zeros(n, vertices.len());
    for (j, &v) in vertices.iter().enumerate() {
        values[(v, j)] = 1.0;
    }
    Ok(Descriptors { values, names: vertices.iter().map(|v| format!("delta:{v}")).collect() })
}

/// Indicator functions of the segments given by per-vertex labels: one column per distinct label,
/// in ascending label order, named `segment:L` (1 on the vertices labelled L, 0 elsewhere).
pub fn segments(labels: &[u32]) -> Result<Descriptors> {
    if labels.is_empty() {
        return Err(Error::invalid("labels", "no labels given"));
    }
    let mut distinct: Vec<u32> = labels.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    let mut values = Mat::<f64>::zeros(labels.len(), distinct.len());
    for (i, l) in labels.iter().enumerate() {
        let j = distinct.binary_search(l).expect("label is in the list");
        values[(i, j)] = 1.0;
    }
    Ok(Descriptors { values, names: distinct.iter().map(|l| format!("segment:{l}")).collect() })
}

/// Corresponding segment indicators of two shapes whose label files agree (segment L on X is
/// segment L on Y, as in the benchmark segmentations): F (n × s) and G (m × s) for the s labels
/// present on both, in ascending label order. Errors when the shapes share no label.
pub fn matched_segments(labels_x: &[u32], labels_y: &[u32]) -> Result<(Descriptors, Descriptors)> {
    let (fa, fb) = (segments(labels_x)?, segments(labels_y)?);
    let common: Vec<&String> = fa.names.iter().filter(|n| fb.names.contains(n)).collect();
    if common.is_empty() {
        return Err(Error::invalid("segments", "the two label sets share no label"));
    }
    let pick = |d: &Descriptors| {
        let cols: Vec<usize> = common.iter().map(|c| d.names.iter().position(|n| n == *c).expect("common")).collect();
        Descriptors::new(
            Mat::from_fn(d.n(), cols.len(), |i, j| d.values[(i, cols[j])]),
            cols.iter().map(|&c| d.names[c].clone()).collect(),
        )
    };
    Ok((pick(&fa)?, pick(&fb)?))
}

/// Localized descriptors (paper §4.1, rich data): every column of `d` multiplied by every segment
/// indicator of `segments`, segment-major: column s·q + j is `d_j · 1_{segment s}`, named
/// `d_j@segment`. n × (q · S).
pub fn localized(d: &Descriptors, segments: &Descriptors) -> Result<Descriptors> {
    if d.n() != segments.n() {
        return Err(Error::invalid("localized descriptors", format!("{} vs {} vertices", d.n(), segments.n())));
    }
    let (q, s) = (d.q(), segments.q());
    let values = Mat::from_fn(d.n(), q * s, |i, c| d.values[(i, c % q)] * segments.values[(i, c / q)]);
    let names = (0..q * s).map(|c| format!("{}@{}", d.names[c % q], segments.names[c / q])).collect();
    Ok(Descriptors { values, names })
}

/// The paper's rich data (§4.1): `wks` WKS and about `hkm` heat kernel maps, localized on
/// matched segments. F_seg (n × s) and G_seg (m × s) are matched segment indicators (column j of
/// one ↔ column j of the other). The heat kernel maps start from one seed per segment, the
/// vertex of the segment where the scale-normalized HKS at t = 0.25/λ₁ (the persistence
/// segmentation's function) is largest, at ⌈`hkm` / s⌉ log-spaced times each. Every function
/// is then multiplied by every segment indicator ([`localized`]): (wks + s·⌈hkm/s⌉) · s columns.
/// Errors on sizes that do not match or bases too small for the signatures.
pub fn rich(
    bx: &Basis,
    by: &Basis,
    f_seg: &Descriptors,
    g_seg: &Descriptors,
    wks: usize,
    hkm: usize,
) -> Result<(Descriptors, Descriptors)> {
    if f_seg.q() != g_seg.q() || f_seg.q() == 0 {
        return Err(Error::invalid("segments", format!("{} and {} matched segments", f_seg.q(), g_seg.q())));
    }
    if f_seg.n() != bx.n() || g_seg.n() != by.n() {
        return Err(Error::invalid("segments", "the indicators do not have one row per vertex"));
    }
    let s = f_seg.q();
    let per_seed = hkm.div_ceil(s).max(1);
    let side = |b: &Basis, seg: &Descriptors| -> Result<Descriptors> {
        let f = persistence::default_function(b)?;
        let seeds: Vec<usize> = (0..s)
            .map(|j| {
                (0..b.n())
                    .filter(|&i| seg.values[(i, j)] > 0.5)
                    .max_by(|&a, &c| f[a].total_cmp(&f[c]))
                    .ok_or_else(|| Error::invalid("segments", format!("segment {} is empty", seg.names[j])))
            })
            .collect::<Result<_>>()?;
        let base = signatures::wks(b, wks, true)?.concat(&signatures::hkm(
            b,
            &seeds,
            &signatures::hks_times(b, per_seed)?,
            true,
        )?)?;
        localized(&base, seg)
    };
    Ok((side(bx, f_seg)?, side(by, g_seg)?))
}

/// Largest magnitude accepted in a user-provided data matrix ([`Descriptors::from_matrix`]):
/// beyond it squared norms overflow (as [`crate::shape::MAX_COORDINATE`] for coordinates).
pub const MAX_VALUE: f64 = 1e150;

/// Smallest non-zero largest magnitude of a column of a user-provided data matrix: below it
/// squared norms underflow.
pub const MIN_VALUE: f64 = 1e-150;

/// Every column divided by its L2(A) norm √(fᵀ A f) (A the vertex weights, length n), as pyFM
/// normalizes its descriptors: each then weighs the same in the functional-map energy whatever
/// its magnitude. Errors: a size mismatch, or a column of zero norm (named).
pub fn normalized(d: &Descriptors, mass: &[f64]) -> Result<Descriptors> {
    if mass.len() != d.n() {
        return Err(Error::invalid("descriptors", format!("{} weights for {} vertices", mass.len(), d.n())));
    }
    // Scaled by the column's largest magnitude, so that values near the ends of the f64 range
    // (whose squares over- or underflow) still have their norm.
    let norms: Vec<f64> = (0..d.q())
        .map(|j| {
            let col = d.values.col_as_slice(j);
            let top = col.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if top == 0.0 || !top.is_finite() {
                return top;
            }
            top * col.iter().zip(mass).map(|(v, a)| a * (v / top) * (v / top)).sum::<f64>().sqrt()
        })
        .collect();
    if let Some(j) = norms.iter().position(|&x| !(x > 0.0 && x.is_finite())) {
        let top = d.values.col_as_slice(j).iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let why = if top == 0.0 {
            "is zero everywhere".to_string()
        } else {
            format!("has no L2 norm with these vertex weights (largest magnitude {top:e}, norm {:e})", norms[j])
        };
        return Err(Error::invalid("descriptors", format!("column {j} ({}) {why}", d.names[j])));
    }
    Descriptors::new(Mat::from_fn(d.n(), d.q(), |i, j| d.values[(i, j)] / norms[j]), d.names.clone())
}

/// `count` distinct pairs (a, b) of q descriptors, spread over the columns: a = 7t mod q,
/// b = a + 1 + (3t mod (q − 1)) mod q for t = 0, 1, … (fewer when q is small).
pub fn signed_pairs(q: usize, count: usize) -> Vec<(usize, usize)> {
    let mut pairs = Vec::with_capacity(count);
    if q < 2 {
        return pairs;
    }
    for t in 0..q * q {
        if pairs.len() == count {
            break;
        }
        let a = (7 * t) % q;
        let b = (a + 1 + (3 * t) % (q - 1)) % q;
        if !pairs.contains(&(a, b)) && !pairs.contains(&(b, a)) {
            pairs.push((a, b));
        }
    }
    pairs
}

/// Signed (orientation) descriptors from the columns of `d`: for every pair (a, b), the
/// orientation function n · (∇f_a × ∇f_b) ([`crate::operators::orientation_function`]),
/// low-passed to the first `smooth_k` eigenfunctions of `basis` (the product of two gradients is
/// rough), not normalized (a pair whose gradients never cross, e.g. the indicators of segments
/// that do not touch, gives zero). Intrinsic descriptors such as the WKS are symmetric under a
/// shape's left–right symmetry; these change sign under it (and under any orientation-reversing
/// map), so they tell left from right once the surface is oriented. Named `signed:a,b`.
/// Errors: a pair out of range, sizes that do not match.
pub fn signed(
    d: &Descriptors,
    grads: &crate::operators::FaceGradients,
    basis: &Basis,
    pairs: &[(usize, usize)],
    smooth_k: usize,
) -> Result<Descriptors> {
    let (n, q) = (d.n(), d.q());
    if let Some(p) = pairs.iter().find(|p| p.0 >= q || p.1 >= q) {
        return Err(Error::invalid("signed descriptors", format!("pair {p:?} is out of range (q = {q})")));
    }
    if basis.n() != n || grads.n() != n {
        return Err(Error::invalid(
            "signed descriptors",
            format!("{n} rows, basis {} and mesh {} vertices", basis.n(), grads.n()),
        ));
    }
    let ks = smooth_k.clamp(1, basis.k());
    let phi = basis.eigenvectors.subcols(0, ks);
    let mut values = Mat::<f64>::zeros(n, pairs.len());
    for (t, &(a, b)) in pairs.iter().enumerate() {
        let h = crate::operators::orientation_function(grads, d.values.col_as_slice(a), d.values.col_as_slice(b))?;
        // Low-pass: Φ Φᵀ A h.
        let coef: Vec<f64> = (0..ks).map(|c| (0..n).map(|i| phi[(i, c)] * basis.mass[i] * h[i]).sum()).collect();
        for i in 0..n {
            values[(i, t)] = (0..ks).map(|c| phi[(i, c)] * coef[c]).sum();
        }
    }
    Descriptors::new(values, pairs.iter().map(|(a, b)| format!("signed:{a},{b}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_near_the_ends_of_the_range_are_named_not_called_zero() {
        let m = |v: f64| DenseMatrix { rows: 3, cols: 2, data: vec![v, 0.0, 2.0 * v, 0.0, -v, 1.0] };
        for v in [1e160, 1e200, 1e300, -1e300] {
            let e = Descriptors::from_matrix(&m(v), 3).unwrap_err().to_string();
            assert!(e.contains("beyond") && e.contains("rescale") && !e.contains("zero everywhere"), "{e}");
        }
        let e = Descriptors::from_matrix(&m(1e-200), 3).unwrap_err().to_string();
        assert!(e.contains("underflow") && e.contains("rescale"), "{e}");
        assert!(Descriptors::from_matrix(&m(5e149), 3).is_ok());
        assert!(Descriptors::from_matrix(&m(0.0), 3).is_ok(), "a zero column is data (normalized says so)");
        // Normalization of large and tiny values: computed with a scaled norm, not overflowed.
        for v in [1e200, 1e-200, 1e300] {
            let d = Descriptors::new(Mat::from_fn(3, 1, |i, _| v * (i + 1) as f64), vec!["x".into()]).unwrap();
            let n = normalized(&d, &[1.0, 1.0, 1.0]).unwrap();
            let norm: f64 = n.values.col_as_slice(0).iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-12, "{v}: {norm}");
        }
        let zero = Descriptors::new(Mat::zeros(3, 1), vec!["z".into()]).unwrap();
        assert!(normalized(&zero, &[1.0; 3]).unwrap_err().to_string().contains("zero everywhere"));
    }

    #[test]
    fn deltas_segments_localized() {
        let d = landmarks(4, &[2, 0]).unwrap();
        assert_eq!(d.values[(2, 0)], 1.0);
        assert_eq!(d.values[(0, 1)], 1.0);
        assert_eq!(d.values.col_as_slice(0).iter().sum::<f64>(), 1.0);
        assert!(landmarks(4, &[4]).is_err());
        let s = segments(&[3, 1, 3, 1]).unwrap();
        assert_eq!(s.names, vec!["segment:1", "segment:3"]);
        assert_eq!(s.values.col_as_slice(1), &[1.0, 0.0, 1.0, 0.0]);
        let f = Descriptors::new(Mat::from_fn(4, 1, |i, _| i as f64), vec!["x".into()]).unwrap();
        let l = localized(&f, &s).unwrap();
        assert_eq!(l.q(), 2);
        assert_eq!(l.values.col_as_slice(0), &[0.0, 1.0, 0.0, 3.0]);
        assert_eq!(l.names[1], "x@segment:3");
        assert!(localized(&f, &segments(&[1, 2]).unwrap()).is_err());
        let both = d.concat(&s).unwrap();
        assert_eq!(both.q(), 4);
        let dense = both.to_dense();
        assert_eq!(Descriptors::from_matrix(&dense, 4).unwrap().values, both.values);
        assert!(Descriptors::from_matrix(&dense, 5).is_err());
        let empty = DenseMatrix { rows: 4, cols: 0, data: vec![] };
        assert!(Descriptors::from_matrix(&empty, 4).is_err(), "an n × 0 matrix is no descriptor");
        assert!(Descriptors::new(Mat::from_fn(2, 1, |_, _| f64::NAN), vec!["nan".into()]).is_err());
    }
}
