//! numpy in and out: arguments checked and converted with errors naming the argument, results
//! as numpy arrays.
//!
//! Inputs may be numpy arrays of any memory order (C, Fortran, strided views, `np.memmap`) or
//! anything `numpy.asarray` accepts; floats of any width are widened to f64 (the library's one
//! precision), indices of any integer type are checked against their range.

use faer::{Mat, MatRef};
use numpy::ndarray::{Array2, ShapeBuilder};
use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};

use funcorr::laplacian::Laplacian;
use funcorr::shape::{PointSet, Shape, TriMesh};

/// A 1-D float64 numpy array.
pub(crate) type F64s<'py> = Bound<'py, PyArray1<f64>>;
/// A 1-D int64 numpy array.
pub(crate) type I64s<'py> = Bound<'py, PyArray1<i64>>;
/// A 2-D float64 numpy array.
pub(crate) type F64m<'py> = Bound<'py, PyArray2<f64>>;
/// A 2-D int64 numpy array.
pub(crate) type I64m<'py> = Bound<'py, PyArray2<i64>>;
/// Vertices and triangles.
pub(crate) type Geometry = (Vec<[f64; 3]>, Vec<[u32; 3]>);

pub(crate) fn value_error(name: &str, msg: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{name}: {msg}"))
}

/// `numpy.asarray(obj)` as an untyped array.
fn as_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = obj.py();
    let a = py.import("numpy")?.call_method1("asarray", (obj,)).map_err(|e| {
        value_error(
            name,
            format!(
                "expected an array, got {} ({e})",
                obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
            ),
        )
    })?;
    a.cast_into::<PyUntypedArray>().map_err(|_| value_error(name, "expected an array"))
}

fn dtype_name(a: &Bound<'_, PyUntypedArray>) -> String {
    a.dtype().str().map(|s| s.to_string()).unwrap_or_else(|_| "?".into())
}

/// A float array of `ndim` dimensions as an f64 array (converted from other float widths).
fn float_array<'py>(obj: &Bound<'py, PyAny>, name: &str, ndim: usize, shape: &str) -> PyResult<Bound<'py, PyAny>> {
    let a = as_array(obj, name)?;
    if a.ndim() != ndim {
        return Err(value_error(name, format!("expected shape {shape}, got an array of shape {:?}", a.shape())));
    }
    let kind = a.dtype().kind();
    if kind != b'f' {
        return Err(value_error(
            name,
            format!("expected a floating-point array (float16/32/64), got dtype {}", dtype_name(&a)),
        ));
    }
    let f64_dtype = numpy::dtype::<f64>(obj.py());
    if a.dtype().is_equiv_to(&f64_dtype) {
        Ok(a.into_any())
    } else {
        a.call_method1("astype", (f64_dtype,))
    }
}

/// An integer array of `ndim` dimensions as int64.
fn int_array<'py>(obj: &Bound<'py, PyAny>, name: &str, ndim: usize, shape: &str) -> PyResult<Bound<'py, PyAny>> {
    let a = as_array(obj, name)?;
    if a.ndim() != ndim {
        return Err(value_error(name, format!("expected shape {shape}, got an array of shape {:?}", a.shape())));
    }
    let kind = a.dtype().kind();
    // An empty list becomes a float array: accept it as no indices.
    let empty_float = kind == b'f' && a.len() == 0;
    if kind != b'i' && kind != b'u' && !empty_float {
        return Err(value_error(
            name,
            format!("expected an integer array (int32 or int64), got dtype {}", dtype_name(&a)),
        ));
    }
    let i64_dtype = numpy::dtype::<i64>(obj.py());
    if a.dtype().is_equiv_to(&i64_dtype) {
        Ok(a.into_any())
    } else {
        if kind == b'u' && a.dtype().itemsize() >= 8 {
            // uint64 beyond i64::MAX would wrap: such an index is out of range anyway.
            let too_big: bool = a.call_method0("max")?.gt(i64::MAX as u64)?;
            if too_big {
                return Err(value_error(name, "an index is out of range (above 2^63)"));
            }
        }
        a.call_method1("astype", (i64_dtype,))
    }
}

/// Vertex positions (n × 3, n ≥ 1), finite.
pub(crate) fn vertices(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[f64; 3]>> {
    let a = float_array(obj, name, 2, "(n, 3)")?;
    let r: PyReadonlyArray2<f64> = a.extract()?;
    let v = r.as_array();
    if v.ncols() != 3 || v.nrows() == 0 {
        return Err(value_error(name, format!("expected shape (n, 3) with n ≥ 1, got {:?}", v.shape())));
    }
    let out: Vec<[f64; 3]> = v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
    if let Some(i) = out.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(value_error(name, format!("row {i} has a NaN or infinite coordinate {:?}", out[i])));
    }
    Ok(out)
}

/// Points (n × d, n ≥ 1, d ≥ 1), finite, row-major.
pub(crate) fn points(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<PointSet> {
    let a = float_array(obj, name, 2, "(n, d)")?;
    let r: PyReadonlyArray2<f64> = a.extract()?;
    let v = r.as_array();
    let (n, d) = v.dim();
    if n == 0 || d == 0 {
        return Err(value_error(name, format!("expected shape (n, d) with n, d ≥ 1, got {:?}", v.shape())));
    }
    let coords: Vec<f64> = v.iter().copied().collect();
    if let Some(p) = coords.iter().position(|c| !c.is_finite()) {
        return Err(value_error(name, format!("row {} has a NaN or infinite coordinate", p / d)));
    }
    PointSet::new(n, d, coords).map_err(|e| value_error(name, e))
}

/// Triangles (f × 3) of 0-based indices into `n` vertices.
pub(crate) fn faces(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<[u32; 3]>> {
    let a = int_array(obj, name, 2, "(f, 3)")?;
    let r: PyReadonlyArray2<i64> = a.extract()?;
    let v = r.as_array();
    if v.ncols() != 3 {
        return Err(value_error(name, format!("expected shape (f, 3), got {:?}", v.shape())));
    }
    let mut out = Vec::with_capacity(v.nrows());
    for (f, row) in v.rows().into_iter().enumerate() {
        let mut t = [0u32; 3];
        for c in 0..3 {
            let i = row[c];
            if i < 0 || i as u64 >= n as u64 {
                return Err(value_error(
                    name,
                    format!("face {f} has vertex index {i} out of range [0, {n}) (indices are 0-based)"),
                ));
            }
            t[c] = i as u32;
        }
        out.push(t);
    }
    Ok(out)
}

/// A 1-D array of indices, each `< bound`.
pub(crate) fn indices(obj: &Bound<'_, PyAny>, name: &str, bound: usize) -> PyResult<Vec<usize>> {
    let a = int_array(obj, name, 1, "(s,)")?;
    let r: PyReadonlyArray1<i64> = a.extract()?;
    r.as_array()
        .iter()
        .enumerate()
        .map(|(p, &i)| {
            if i < 0 || i as u64 >= bound as u64 {
                Err(value_error(name, format!("entry {p} is {i}, out of range [0, {bound}) (indices are 0-based)")))
            } else {
                Ok(i as usize)
            }
        })
        .collect()
}

/// A (k, 2) array of index pairs (i, j) with i < `n` and j < `m` (0-based), k ≥ 1.
pub(crate) fn index_pairs(obj: &Bound<'_, PyAny>, name: &str, n: usize, m: usize) -> PyResult<Vec<(usize, usize)>> {
    let a = int_array(obj, name, 2, "(k, 2)")?;
    let r: PyReadonlyArray2<i64> = a.extract()?;
    let v = r.as_array();
    if v.ncols() != 2 || v.nrows() == 0 {
        return Err(value_error(name, format!("expected shape (k, 2) with k ≥ 1, got {:?}", v.shape())));
    }
    (0..v.nrows())
        .map(|p| {
            let (i, j) = (v[(p, 0)], v[(p, 1)]);
            if i < 0 || i as u64 >= n as u64 || j < 0 || j as u64 >= m as u64 {
                Err(value_error(
                    name,
                    format!("row {p} is ({i}, {j}), out of range: X has {n} vertices, Y has {m} (indices are 0-based)"),
                ))
            } else {
                Ok((i as usize, j as usize))
            }
        })
        .collect()
}

/// A finite float matrix (rows × cols) as a faer matrix.
pub(crate) fn matrix(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Mat<f64>> {
    let a = float_array(obj, name, 2, "(rows, cols)")?;
    let r: PyReadonlyArray2<f64> = a.extract()?;
    let v = r.as_array();
    if let Some(((i, j), x)) = v.indexed_iter().find(|(_, x)| !x.is_finite()) {
        return Err(value_error(name, format!("entry ({i}, {j}) is {x}; all must be finite")));
    }
    Ok(Mat::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)]))
}

/// A finite 1-D float array.
pub(crate) fn vector(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    let a = float_array(obj, name, 1, "(n,)")?;
    let r: PyReadonlyArray1<f64> = a.extract()?;
    let v: Vec<f64> = r.as_array().iter().copied().collect();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(value_error(name, format!("entry {i} is {}; all must be finite", v[i])));
    }
    Ok(v)
}

/// A path argument (str or os.PathLike).
pub(crate) fn path_arg(obj: &Bound<'_, PyAny>) -> Option<std::path::PathBuf> {
    if obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__").unwrap_or(false) {
        obj.extract::<std::path::PathBuf>().ok()
    } else {
        None
    }
}

/// A shape argument: a file path, a tuple `(V, F)` (F None: a point cloud), or an (n, d) array
/// of points.
pub(crate) fn shape(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Shape> {
    let py = obj.py();
    if let Some(p) = path_arg(obj) {
        return py.detach(|| Shape::load(&p)).map_err(crate::to_py);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        if t.len() != 2 {
            return Err(value_error(name, format!("expected (V, F), a path or an array, got a tuple of {}", t.len())));
        }
        let (v, f) = (t.get_item(0)?, t.get_item(1)?);
        if f.is_none() {
            return Ok(Shape::Points(points(&v, &format!("{name}[0] (points)"))?));
        }
        let v = vertices(&v, &format!("{name}[0] (vertices)"))?;
        let f = faces(&f, &format!("{name}[1] (faces)"), v.len())?;
        if f.is_empty() {
            let n = v.len();
            return Ok(Shape::Points(PointSet::new(n, 3, v.into_iter().flatten().collect()).map_err(crate::to_py)?));
        }
        return Ok(Shape::Mesh(TriMesh::new(v, f).map_err(|e| value_error(name, e))?));
    }
    Ok(Shape::Points(points(obj, name)?))
}

/// A triangle mesh from vertices and faces.
pub(crate) fn mesh(v: &Bound<'_, PyAny>, f: &Bound<'_, PyAny>, vname: &str, fname: &str) -> PyResult<TriMesh> {
    let v = vertices(v, vname)?;
    let f = faces(f, fname, v.len())?;
    if f.is_empty() {
        return Err(value_error(fname, "a triangle mesh needs at least one face"));
    }
    TriMesh::new(v, f).map_err(|e| value_error(vname, e))
}

/// A matrix as a numpy array (Fortran order: the layout of faer's column-major matrices).
pub(crate) fn mat_out<'py>(py: Python<'py>, m: MatRef<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()).f(), |(i, j)| m[(i, j)]).into_pyarray(py)
}

pub(crate) fn vec_out<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

pub(crate) fn index_out<'py>(py: Python<'py>, v: &[usize]) -> Bound<'py, PyArray1<i64>> {
    PyArray1::from_vec(py, v.iter().map(|&i| i as i64).collect())
}

pub(crate) fn points3_out<'py>(py: Python<'py>, v: &[[f64; 3]]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((v.len(), 3), |(i, j)| v[i][j]).into_pyarray(py)
}

pub(crate) fn faces_out<'py>(py: Python<'py>, f: &[[u32; 3]]) -> Bound<'py, PyArray2<i64>> {
    Array2::from_shape_fn((f.len(), 3), |(i, j)| f[i][j] as i64).into_pyarray(py)
}

/// A sparse matrix as numpy CSR parts (indptr, indices, data).
pub(crate) type Csr<'py> = (I64s<'py>, I64s<'py>, F64s<'py>);

/// W (symmetric, stored by columns) as CSR parts: the columns of a symmetric matrix are its rows.
pub(crate) fn csr_parts<'py>(py: Python<'py>, lap: &Laplacian) -> Csr<'py> {
    let w = lap.w.as_ref();
    let s = w.symbolic();
    (
        PyArray1::from_vec(py, s.col_ptr().iter().map(|&p| p as i64).collect()),
        PyArray1::from_vec(py, s.row_idx().iter().map(|&i| i as i64).collect()),
        PyArray1::from_vec(py, w.val().to_vec()),
    )
}
