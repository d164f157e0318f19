//! Prepared shapes (shape + Laplacian + eigenbasis; picklable, so that Ray can keep them in its
//! object store), `prepare`, and the shape, basis and mesh arguments of the other functions.

use std::sync::{Arc, OnceLock};

use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use funcorr::prepared::{LaplacianChoice, PreparedShape};
use funcorr::shape::{PointSet, Shape, TriMesh};
use funcorr::spectral::{Basis, BasisCache};

use crate::arrays::{self, value_error, F64s, I64s};
use crate::{compute, options};

/// A shape with its Laplacian and its first k eigenpairs, computed once and reused by every
/// pair it takes part in (`funcorr.prepare`). Pickles to its geometry and basis (the Laplacian
/// is rebuilt on unpickling, bit for bit), so it can be put in Ray's object store.
///
/// Units: the library's [`PreparedShape`] is the shape scaled to unit area (what matching
/// computes on); Python shows the basis in the shape's own units (λ / area, φ / √area,
/// A · area: `PreparedShape::input_basis`, computed on first access and kept), as
/// `cotangent_laplacian` and pyFM give it. Functional maps in and out of the bindings are
/// between these input bases (as `match`'s C).
#[pyclass(frozen, module = "funcorr._funcorr", name = "PreparedShape")]
pub(crate) struct PyPrepared {
    pub(crate) inner: Arc<PreparedShape>,
    pub(crate) choice: LaplacianChoice,
    /// The basis in the input's units (on first use).
    input: OnceLock<Basis>,
}

impl PyPrepared {
    pub(crate) fn new(inner: Arc<PreparedShape>, choice: LaplacianChoice) -> Self {
        PyPrepared { inner, choice, input: OnceLock::new() }
    }

    /// The basis in the shape's own units (computed once).
    pub(crate) fn input_basis(&self) -> &Basis {
        self.input.get_or_init(|| self.inner.input_basis())
    }
}

#[pymethods]
impl PyPrepared {
    /// Number of vertices n.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n()
    }
    /// Number of eigenpairs k.
    #[getter]
    fn k(&self) -> usize {
        self.inner.basis.k()
    }
    /// Vertex positions (n × 3; for feature point sets the points, n × d).
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        match &self.inner.shape {
            Shape::Mesh(m) => arrays::points3_out(py, m.vertices()).into_any(),
            Shape::Points(p) => point_set_out(py, p).into_any(),
        }
    }
    /// Triangles (f × 3, int64; (0, 3) for point clouds).
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<i64>> {
        match &self.inner.shape {
            Shape::Mesh(m) => arrays::faces_out(py, m.faces()),
            Shape::Points(_) => arrays::faces_out(py, &[]),
        }
    }
    /// λ₁ ≤ … ≤ λ_k in the shape's units (1 / area; read-only view, no copy).
    #[getter]
    fn eigenvalues<'py>(this: Bound<'py, Self>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let v = numpy::ndarray::ArrayView1::from(&this.get().input_basis().eigenvalues[..]);
        // SAFETY: the basis lives in a OnceLock owned by `this`, never mutated nor reallocated
        // once set; the array keeps `this` alive as its base, and is made read-only.
        readonly(unsafe { PyArray1::borrow_from_array(&v, this.clone().into_any()) })
    }
    /// Φ (n × k), Φᵀ diag(A) Φ = I with A = `mass` (read-only view, Fortran order, no copy).
    #[getter]
    fn eigenvectors<'py>(this: Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        use numpy::ndarray::ShapeBuilder;
        let m = this.get().input_basis().eigenvectors.as_ref();
        let (rs, cs) = (m.row_stride(), m.col_stride());
        if rs < 0 || cs < 0 {
            return Ok(arrays::mat_out(this.py(), m));
        }
        // SAFETY: `m` is a column-major matrix of n × k finite elements with these strides
        // (in elements); the memory is owned as in `eigenvalues`.
        let view = unsafe {
            numpy::ndarray::ArrayView2::from_shape_ptr(
                (m.nrows(), m.ncols()).strides((rs as usize, cs as usize)),
                m.as_ptr(),
            )
        };
        readonly(unsafe { PyArray2::borrow_from_array(&view, this.clone().into_any()) })
    }
    /// A (n): the vertex weights in the shape's units (lumped mass, area²; read-only view).
    #[getter]
    fn mass<'py>(this: Bound<'py, Self>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let v = numpy::ndarray::ArrayView1::from(&this.get().input_basis().mass[..]);
        // SAFETY: as in `eigenvalues`.
        readonly(unsafe { PyArray1::borrow_from_array(&v, this.clone().into_any()) })
    }
    /// Σ A: the total vertex weight (a mesh's area) in the shape's units. Matching works on the
    /// shape scaled to unit area (eigenvalues · area, eigenvectors · √area, mass / area).
    #[getter]
    fn area(&self) -> f64 {
        self.inner.area
    }
    /// The stiffness matrix W as CSR parts (indptr, indices, data) (W is symmetric).
    fn _stiffness<'py>(&self, py: Python<'py>) -> (I64s<'py>, I64s<'py>, F64s<'py>) {
        arrays::csr_parts(py, &self.inner.laplacian)
    }
    /// What the smoothing of a mesh rough with noise did before its Laplacian was built
    /// (`funcorr::denoise`; with `laplacian="auto"`, the default): a dict with
    /// `roughness_before`, `roughness_after`, `time` (of the one implicit step, in squared mean
    /// edge lengths), `area_ratio`, `folded_before`, `folded_after`; None when the shape's own
    /// geometry is used.
    #[getter]
    fn denoised<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(d) = self.inner.denoising() else { return Ok(None) };
        let out = PyDict::new(py);
        out.set_item("roughness_before", d.roughness_before)?;
        out.set_item("roughness_after", d.roughness_after)?;
        out.set_item("time", d.time)?;
        out.set_item("area_ratio", d.area_ratio)?;
        out.set_item("folded_before", d.folded_before)?;
        out.set_item("folded_after", d.folded_after)?;
        Ok(Some(out))
    }
    /// Whether the shape is a triangle mesh.
    #[getter]
    fn is_mesh(&self) -> bool {
        matches!(self.inner.shape, Shape::Mesh(_))
    }
    fn __repr__(&self) -> String {
        let kind = match &self.inner.shape {
            Shape::Mesh(m) => format!("mesh, {} faces", m.n_faces()),
            Shape::Points(p) => format!("{}-D points", p.dim()),
        };
        format!("PreparedShape(n={}, {kind}, k={})", self.inner.n(), self.inner.basis.k())
    }
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let f = py.import("funcorr._funcorr")?.getattr("_prepared_from_state")?;
        let (pts, faces) = match &self.inner.shape {
            Shape::Mesh(m) => {
                (arrays::points3_out(py, m.vertices()).into_any(), arrays::faces_out(py, m.faces()).into_any())
            }
            Shape::Points(p) => (point_set_out(py, p).into_any(), py.None().into_bound(py)),
        };
        let choice = serde_json::to_string(&self.choice).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let b = &self.inner.basis;
        let args = PyTuple::new(
            py,
            [
                pts,
                faces,
                choice.into_pyobject(py)?.into_any(),
                arrays::vec_out(py, b.eigenvalues.clone()).into_any(),
                arrays::mat_out(py, b.eigenvectors.as_ref()).into_any(),
                arrays::vec_out(py, b.mass.clone()).into_any(),
                arrays::vec_out(py, b.residuals.clone()).into_any(),
            ],
        )?;
        Ok((f, args))
    }
}

/// The array made read-only (it views data that Rust shares).
fn readonly<'py, T>(a: Bound<'py, T>) -> PyResult<Bound<'py, T>> {
    a.as_any().getattr("flags")?.set_item("WRITEABLE", false)?;
    Ok(a)
}

fn point_set_out<'py>(py: Python<'py>, p: &PointSet) -> Bound<'py, PyArray2<f64>> {
    use numpy::IntoPyArray;
    let d = p.dim();
    numpy::ndarray::Array2::from_shape_fn((p.len(), d), |(i, j)| p.coords()[i * d + j]).into_pyarray(py)
}

/// Rebuilds a pickled [`PyPrepared`]: the shape, its Laplacian (recomputed, deterministic) and
/// the stored basis (at unit area, as `PreparedShape` holds it, so that nothing is rescaled and
/// the shape comes back bit for bit).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn _prepared_from_state(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
    choice: &str,
    eigenvalues: &Bound<'_, PyAny>,
    eigenvectors: &Bound<'_, PyAny>,
    mass: &Bound<'_, PyAny>,
    residuals: &Bound<'_, PyAny>,
) -> PyResult<PyPrepared> {
    let shape = if faces.is_none() {
        Shape::Points(arrays::points(points, "points")?)
    } else {
        Shape::Mesh(arrays::mesh(points, faces, "vertices", "faces")?)
    };
    let choice: LaplacianChoice = serde_json::from_str(choice).map_err(|e| value_error("choice", e))?;
    let unit = Basis {
        eigenvalues: arrays::vector(eigenvalues, "eigenvalues")?,
        eigenvectors: arrays::matrix(eigenvectors, "eigenvectors")?,
        mass: arrays::vector(mass, "mass")?,
        residuals: arrays::vector(residuals, "residuals")?,
    };
    if unit.n() != shape.n_vertices() || unit.mass.len() != unit.n() || unit.eigenvalues.len() != unit.k() {
        return Err(value_error("eigenvectors", "the basis does not fit the shape"));
    }
    let p = compute(py, move || {
        let (lap, surface) = funcorr::prepared::build_laplacian(&shape, choice)?;
        // `from_parts` scales a basis in the input's units to unit area, with the area Σ A of
        // its mass: given the rebuilt Laplacian's own mass (as when the shape was prepared),
        // the area, the unit-area Laplacian and surface come out as before; the stored
        // unit-area eigenpairs then replace the placeholder ones unchanged.
        let placeholder = Basis {
            eigenvalues: vec![],
            eigenvectors: faer::Mat::zeros(unit.n(), 0),
            mass: lap.mass.clone(),
            residuals: vec![],
        };
        let mut p = PreparedShape::from_parts(shape, lap, placeholder, surface);
        if p.basis.mass != unit.mass {
            return Err(funcorr::Error::invalid("mass", "the pickled basis does not fit the shape's Laplacian"));
        }
        p.basis = unit;
        Ok(p)
    })?;
    Ok(PyPrepared::new(Arc::new(p), choice))
}

/// Laplacian options of `prepare` and `match`, read from a dict (keys `laplacian`,
/// `cloud_neighbours`, `knn`, `vertex_weights`, `sigma`).
pub(crate) fn laplacian_choice(opts: &mut options::Opts) -> PyResult<LaplacianChoice> {
    use funcorr::laplacian::{Bandwidth, KnnOptions, VertexWeights};
    let kind = opts.string("laplacian")?;
    let cloud_k = opts.usize("cloud_neighbours")?.unwrap_or(funcorr::cloud::DEFAULT_NEIGHBOURS);
    let knn_k = opts.usize("knn")?.unwrap_or(10);
    let weights = opts.string("vertex_weights")?;
    let sigma = opts.f64("sigma")?;
    Ok(match kind.as_deref().unwrap_or("auto") {
        "auto" => LaplacianChoice::Auto,
        "cotan" | "cotangent" => LaplacianChoice::Cotangent,
        "intrinsic" => LaplacianChoice::Intrinsic,
        "cloud" => LaplacianChoice::Cloud { k: cloud_k },
        "knn" => LaplacianChoice::Knn(KnnOptions {
            k: knn_k,
            vertex_weights: match weights.as_deref().unwrap_or("identity") {
                "identity" => VertexWeights::Identity,
                "degree" => VertexWeights::Degree,
                other => {
                    return Err(value_error("vertex_weights", format!("{other:?}: expected 'identity' or 'degree'")))
                }
            },
            bandwidth: sigma.map_or(Bandwidth::SelfTuning, Bandwidth::Fixed),
        }),
        other => {
            return Err(value_error(
                "laplacian",
                format!("{other:?}: expected 'auto', 'cotan', 'intrinsic', 'cloud' or 'knn'"),
            ))
        }
    })
}

/// The cache of `cache_dir` (None: no cache; True: the default directory).
pub(crate) fn cache_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<BasisCache>> {
    let Some(obj) = obj else { return Ok(None) };
    if obj.is_none() {
        return Ok(None);
    }
    if let Ok(b) = obj.extract::<bool>() {
        return Ok(if b { BasisCache::default_dir().map(BasisCache::new) } else { None });
    }
    match arrays::path_arg(obj) {
        Some(p) => Ok(Some(BasisCache::new(p))),
        None => Err(value_error("cache_dir", "expected a directory path, True (the default directory) or None")),
    }
}

pub(crate) fn check_k(shape: &Shape, k: usize, name: &str, what: &str) -> PyResult<()> {
    let n = shape.n_vertices();
    if k == 0 || k >= n {
        return Err(value_error(
            name,
            format!("{what} asks for {k} eigenpairs, but the shape has n = {n} vertices (need 1 ≤ k < n)"),
        ));
    }
    Ok(())
}

/// `prepare(shape, k, cache_dir, progress, **laplacian options)`; `progress` a callable
/// `(stage, done, total)` or None.
#[pyfunction]
#[pyo3(signature = (shape, k=200, cache_dir=None, progress=None, **kwargs))]
fn prepare(
    py: Python<'_>,
    shape: &Bound<'_, PyAny>,
    k: usize,
    cache_dir: Option<&Bound<'_, PyAny>>,
    progress: Option<&Bound<'_, PyAny>>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyPrepared> {
    let mut opts = options::Opts::new(kwargs)?;
    let choice = laplacian_choice(&mut opts)?;
    opts.finish()?;
    let cache = cache_arg(cache_dir)?;
    let s = arrays::shape(shape, "shape")?;
    check_k(&s, k, "k", "k")?;
    let p = crate::compute_reporting(py, progress, move || PreparedShape::new(s, choice, k, cache.as_ref()))?;
    Ok(PyPrepared::new(Arc::new(p), choice))
}

pub(crate) fn prepared_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Arc<PreparedShape>> {
    prepared_py(obj, name).map(|p| p.get().inner.clone())
}

/// A PreparedShape argument as the Python object (for its basis in input units).
pub(crate) fn prepared_py<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyPrepared>> {
    obj.cast::<PyPrepared>()
        .cloned()
        .map_err(|_| value_error(name, "expected a PreparedShape (funcorr.prepare(shape, k))"))
}

/// A basis argument: a PreparedShape (its basis in the shape's units, as its `eigenvalues`,
/// `eigenvectors` and `mass` show it) or a tuple (eigenvalues, eigenvectors, mass).
pub(crate) fn basis_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Basis> {
    if let Ok(p) = obj.cast::<PyPrepared>() {
        return Ok(p.get().input_basis().clone());
    }
    let t = obj
        .cast::<PyTuple>()
        .map_err(|_| value_error(name, "expected a PreparedShape or a tuple (eigenvalues, eigenvectors, mass)"))?;
    if t.len() != 3 {
        return Err(value_error(name, "expected a tuple (eigenvalues, eigenvectors, mass)"));
    }
    let evals = arrays::vector(&t.get_item(0)?, &format!("{name}[0] (eigenvalues)"))?;
    let evecs = arrays::matrix(&t.get_item(1)?, &format!("{name}[1] (eigenvectors)"))?;
    let mass = arrays::vector(&t.get_item(2)?, &format!("{name}[2] (mass)"))?;
    if evecs.ncols() != evals.len() || evecs.nrows() != mass.len() || evals.is_empty() {
        return Err(value_error(
            name,
            format!(
                "eigenvectors {}×{} do not fit {} eigenvalues and {} weights",
                evecs.nrows(),
                evecs.ncols(),
                evals.len(),
                mass.len()
            ),
        ));
    }
    if let Some(i) = mass.iter().position(|a| *a <= 0.0) {
        return Err(value_error(&format!("{name}[2] (mass)"), format!("entry {i} is not positive")));
    }
    let k = evals.len();
    Ok(Basis { eigenvalues: evals, eigenvectors: evecs, mass, residuals: vec![0.0; k] })
}

/// The mesh of a prepared shape or a shape argument (errors unless it is a triangle mesh).
pub(crate) fn mesh_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Arc<TriMesh>> {
    if let Ok(p) = obj.cast::<PyPrepared>() {
        return match &p.get().inner.shape {
            Shape::Mesh(m) => Ok(Arc::new(m.clone())),
            _ => Err(value_error(name, "expected a triangle mesh, got a point set")),
        };
    }
    match arrays::shape(obj, name)? {
        Shape::Mesh(m) => Ok(Arc::new(m)),
        _ => Err(value_error(name, "expected a triangle mesh (V, F), got a point set")),
    }
}

/// The geometry of a shape argument for drawing: vertices and faces (none for point clouds).
pub(crate) fn geometry_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<arrays::Geometry> {
    let shape = match obj.cast::<PyPrepared>() {
        Ok(p) => p.get().inner.shape.clone(),
        Err(_) => arrays::shape(obj, name)?,
    };
    match shape {
        Shape::Mesh(m) => Ok((m.vertices().to_vec(), m.faces().to_vec())),
        Shape::Points(p) if p.dim() == 3 => Ok((p.coords().chunks(3).map(|c| [c[0], c[1], c[2]]).collect(), vec![])),
        Shape::Points(p) => Err(value_error(name, format!("expected a mesh or 3-D points, got {}-D points", p.dim()))),
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPrepared>()?;
    m.add_function(wrap_pyfunction!(_prepared_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(prepare, m)?)?;
    Ok(())
}
