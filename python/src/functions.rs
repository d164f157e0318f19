//! Meshes in and out, Laplacians, eigenbases, descriptors, regions, geodesics, evaluation and
//! pictures: one function per library entry point.

use std::sync::Arc;

use numpy::ndarray::Array3;
use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadwriteArray2};
use pyo3::prelude::*;

use funcorr::geodesic::{Distances, GeodesicMethod};
use funcorr::shape::{Shape, TriMesh};

use crate::arrays::{self, csr_parts, value_error, Csr, F64m, F64s, I64m};
use crate::compute;
use crate::prepared::{basis_arg, geometry_arg, mesh_arg, prepared_arg as prepared};

/// `read_mesh(path) -> (V (n, 3) float64, F (f, 3) int64)`; F is (0, 3) for point clouds.
#[pyfunction]
fn read_mesh<'py>(py: Python<'py>, path: std::path::PathBuf) -> PyResult<(F64m<'py>, I64m<'py>)> {
    let d = compute(py, move || funcorr::io::read_mesh(&path))?;
    Ok((arrays::points3_out(py, &d.vertices), arrays::faces_out(py, &d.faces)))
}

/// `write_mesh(path, V, F=None, colors=None)`: OFF, PLY or NPY by extension, atomically.
#[pyfunction]
#[pyo3(signature = (path, vertices, faces=None, colors=None))]
fn write_mesh(
    py: Python<'_>,
    path: std::path::PathBuf,
    vertices: &Bound<'_, PyAny>,
    faces: Option<&Bound<'_, PyAny>>,
    colors: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let v = arrays::vertices(vertices, "vertices")?;
    let f = match faces {
        Some(f) if !f.is_none() => arrays::faces(f, "faces", v.len())?,
        _ => vec![],
    };
    let colors = match colors {
        Some(c) if !c.is_none() => {
            let a: numpy::PyReadonlyArray2<u8> =
                c.extract().map_err(|_| value_error("colors", "expected a (n, 3) uint8 array of RGB colours"))?;
            let a = a.as_array();
            if a.dim() != (v.len(), 3) {
                return Err(value_error("colors", format!("expected shape ({}, 3), got {:?}", v.len(), a.shape())));
            }
            Some(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
        }
        _ => None,
    };
    let data = funcorr::io::MeshData { vertices: v, faces: f, colors };
    compute(py, move || funcorr::io::write_mesh(&path, &data))
}

/// `cotangent_laplacian(V, F) -> (indptr, indices, data, mass)`.
#[pyfunction]
fn cotangent_laplacian<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
) -> PyResult<(Csr<'py>, Bound<'py, PyArray1<f64>>)> {
    let mesh = arrays::mesh(vertices, faces, "V", "F")?;
    let lap = compute(py, move || funcorr::laplacian::cotangent(&mesh))?;
    Ok((csr_parts(py, &lap), arrays::vec_out(py, lap.mass.clone())))
}

/// `intrinsic_laplacian(V, F) -> (indptr, indices, data, mass)`: the cotangent Laplacian of the
/// mesh's intrinsic Delaunay triangulation.
#[pyfunction]
fn intrinsic_laplacian<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
) -> PyResult<(Csr<'py>, Bound<'py, PyArray1<f64>>)> {
    let mesh = arrays::mesh(vertices, faces, "V", "F")?;
    let lap = compute(py, move || funcorr::geodesic::intrinsic_delaunay_laplacian(&mesh))?;
    Ok((csr_parts(py, &lap), arrays::vec_out(py, lap.mass.clone())))
}

/// `nearest_rows(reference (r, d), query (q, d)) -> (q,)`: for every row of `query` the index of
/// the nearest row of `reference` (Euclidean; the library's spectral-embedding search).
#[pyfunction]
fn nearest_rows<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    query: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let r = arrays::matrix(reference, "reference")?;
    let q = arrays::matrix(query, "query")?;
    if r.ncols() != q.ncols() || r.nrows() == 0 || r.ncols() == 0 {
        return Err(value_error(
            "query",
            format!(
                "reference is {}×{} and query {}×{}: need the same number d ≥ 1 of columns and a reference row",
                r.nrows(),
                r.ncols(),
                q.nrows(),
                q.ncols()
            ),
        ));
    }
    let idx = compute(py, move || funcorr::pointwise::nearest_neighbors(r.as_ref(), q.as_ref()))?;
    Ok(arrays::index_out(py, &idx))
}

/// `knn_laplacian(points, k=10, sigma=None, vertex_weights="identity")`: the paper's eq. (1).
#[pyfunction]
#[pyo3(signature = (points, k=10, sigma=None, vertex_weights="identity"))]
fn knn_laplacian<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    k: usize,
    sigma: Option<f64>,
    vertex_weights: &str,
) -> PyResult<(Csr<'py>, Bound<'py, PyArray1<f64>>)> {
    use funcorr::laplacian::{Bandwidth, KnnOptions, VertexWeights};
    let p = arrays::points(points, "points")?;
    let weights = match vertex_weights {
        "identity" => VertexWeights::Identity,
        "degree" => VertexWeights::Degree,
        other => return Err(value_error("vertex_weights", format!("{other:?}: expected 'identity' or 'degree'"))),
    };
    let o = KnnOptions { k, vertex_weights: weights, bandwidth: sigma.map_or(Bandwidth::SelfTuning, Bandwidth::Fixed) };
    let lap = compute(py, move || funcorr::laplacian::knn_graph(&p, &o))?;
    Ok((csr_parts(py, &lap), arrays::vec_out(py, lap.mass.clone())))
}

/// `cloud_laplacian(points, k=30)`: the point-cloud Laplacian (Sharp & Crane 2020).
#[pyfunction]
#[pyo3(signature = (points, k=funcorr::cloud::DEFAULT_NEIGHBOURS))]
fn cloud_laplacian<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    k: usize,
) -> PyResult<(Csr<'py>, Bound<'py, PyArray1<f64>>)> {
    let p = arrays::vertices(points, "points")?;
    let (lap, _) = compute(py, move || funcorr::cloud::cloud_laplacian(&p, k))?;
    Ok((csr_parts(py, &lap), arrays::vec_out(py, lap.mass.clone())))
}

/// `hks(basis, count=100, times=None, normalize=True) -> (n, q)`.
#[pyfunction]
#[pyo3(signature = (basis, count=100, times=None, normalize=true))]
fn hks<'py>(
    py: Python<'py>,
    basis: &Bound<'py, PyAny>,
    count: usize,
    times: Option<&Bound<'py, PyAny>>,
    normalize: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let b = basis_arg(basis, "basis")?;
    let times = times.filter(|t| !t.is_none()).map(|t| arrays::vector(t, "times")).transpose()?;
    let d = compute(py, move || {
        let t = match times {
            Some(t) => t,
            None => funcorr::descriptors::signatures::hks_times(&b, count)?,
        };
        funcorr::descriptors::signatures::hks(&b, &t, normalize)
    })?;
    Ok(arrays::mat_out(py, d.values.as_ref()))
}

/// `wks(basis, count=100, normalize=True) -> (n, count)`.
#[pyfunction]
#[pyo3(signature = (basis, count=100, normalize=true))]
fn wks<'py>(
    py: Python<'py>,
    basis: &Bound<'py, PyAny>,
    count: usize,
    normalize: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let b = basis_arg(basis, "basis")?;
    let d = compute(py, move || funcorr::descriptors::signatures::wks(&b, count, normalize))?;
    Ok(arrays::mat_out(py, d.values.as_ref()))
}

/// `wks_recipe(basis, energies=100, eigenpairs=128, keep_every=2)`: the default data of `match`.
#[pyfunction]
#[pyo3(signature = (basis, energies=100, eigenpairs=128, keep_every=2))]
fn wks_recipe<'py>(
    py: Python<'py>,
    basis: &Bound<'py, PyAny>,
    energies: usize,
    eigenpairs: usize,
    keep_every: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let b = basis_arg(basis, "basis")?;
    let r = funcorr::descriptors::signatures::WksRecipe { energies, eigenpairs, keep_every };
    let d = compute(py, move || funcorr::descriptors::signatures::wks_recipe(&b, &r))?;
    Ok(arrays::mat_out(py, d.values.as_ref()))
}

/// `hkm(basis, seeds, count=10, times=None, normalize=True) -> (n, seeds · times)`, seed-major.
#[pyfunction]
#[pyo3(signature = (basis, seeds, count=10, times=None, normalize=true))]
fn hkm<'py>(
    py: Python<'py>,
    basis: &Bound<'py, PyAny>,
    seeds: &Bound<'py, PyAny>,
    count: usize,
    times: Option<&Bound<'py, PyAny>>,
    normalize: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let b = basis_arg(basis, "basis")?;
    let seeds = arrays::indices(seeds, "seeds", b.n())?;
    let times = times.filter(|t| !t.is_none()).map(|t| arrays::vector(t, "times")).transpose()?;
    let d = compute(py, move || {
        let t = match times {
            Some(t) => t,
            None => funcorr::descriptors::signatures::hks_times(&b, count)?,
        };
        funcorr::descriptors::signatures::hkm(&b, &seeds, &t, normalize)
    })?;
    Ok(arrays::mat_out(py, d.values.as_ref()))
}

/// `persistence_segments(prepared, seg_function="hks", threshold=0.1, hks_time=0.25)`: labels 1..=s.
#[pyfunction]
#[pyo3(signature = (shape, **kwargs))]
fn persistence_segments<'py>(
    py: Python<'py>,
    shape: &Bound<'py, PyAny>,
    kwargs: Option<&Bound<'py, pyo3::types::PyDict>>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let p = prepared(shape, "shape")?;
    let mut o = crate::options::Opts::new(kwargs)?;
    let seg = crate::options::segmentation(&mut o)?;
    o.finish()?;
    let labels =
        compute(py, move || funcorr::descriptors::persistence::segment_labels(&p.shape, &p.laplacian, &p.basis, &seg))?;
    Ok(PyArray1::from_vec(py, labels.into_iter().map(i64::from).collect()))
}

/// `regions(X, Y, kind="persistence", labels_x=None, labels_y=None, **seg)`: matched region
/// indicators (F (n × q), G (m × q)).
#[pyfunction]
#[pyo3(signature = (x, y, kind="persistence", labels_x=None, labels_y=None, **kwargs))]
fn regions<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    kind: &str,
    labels_x: Option<&Bound<'py, PyAny>>,
    labels_y: Option<&Bound<'py, PyAny>>,
    kwargs: Option<&Bound<'py, pyo3::types::PyDict>>,
) -> PyResult<(F64m<'py>, F64m<'py>)> {
    use funcorr::descriptors::{mser, persistence as pers};
    let (px, py_) = (prepared(x, "X")?, prepared(y, "Y")?);
    let mut o = crate::options::Opts::new(kwargs)?;
    let seg = crate::options::segmentation(&mut o)?;
    o.finish()?;
    let labels = |obj: Option<&Bound<'py, PyAny>>, name: &str, n: usize| -> PyResult<Vec<u32>> {
        let obj = obj
            .filter(|o| !o.is_none())
            .ok_or_else(|| value_error(name, "kind='labels' needs labels of both shapes"))?;
        let l = arrays::indices(obj, name, u32::MAX as usize)?;
        if l.len() != n {
            return Err(value_error(name, format!("{} labels for {n} vertices", l.len())));
        }
        Ok(l.into_iter().map(|v| v as u32).collect())
    };
    let (f, g) = match kind {
        "labels" => {
            let (a, b) = (labels(labels_x, "labels_x", px.n())?, labels(labels_y, "labels_y", py_.n())?);
            compute(py, move || pers::matched_segment_indicators(&a, &px.basis, &b, &py_.basis))
        }
        "persistence" => compute(py, move || {
            let a = pers::segment_labels(&px.shape, &px.laplacian, &px.basis, &seg)?;
            let b = pers::segment_labels(&py_.shape, &py_.laplacian, &py_.basis, &seg)?;
            pers::matched_segment_indicators(&a, &px.basis, &b, &py_.basis)
        }),
        "mser" => match (&px.shape, &py_.shape) {
            (Shape::Mesh(_), Shape::Mesh(_)) => compute(py, move || {
                let (Shape::Mesh(mx), Shape::Mesh(my)) = (&px.shape, &py_.shape) else { unreachable!("checked") };
                mser::matched_mser_indicators((mx, &px.basis), (my, &py_.basis), &mser::MserOptions::default())
            }),
            _ => Err(value_error("kind", "'mser' needs two triangle meshes")),
        },
        other => Err(value_error("kind", format!("{other:?}: expected 'persistence', 'mser' or 'labels'"))),
    }
    .map(|(f, g, _)| (f, g))?;
    Ok((arrays::mat_out(py, f.values.as_ref()), arrays::mat_out(py, g.values.as_ref())))
}

fn geodesic_method(s: &str) -> PyResult<GeodesicMethod> {
    s.parse::<GeodesicMethod>()
        .map_err(|_| value_error("method", format!("{s:?}: expected 'exact', 'heat' or 'dijkstra'")))
}

/// `geodesic_distances(mesh, sources, method="exact") -> (n, len(sources))`.
#[pyfunction]
#[pyo3(signature = (mesh, sources, method="exact"))]
fn geodesic_distances<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    sources: &Bound<'py, PyAny>,
    method: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = mesh_arg(mesh, "mesh")?;
    let s = arrays::indices(sources, "sources", m.n_vertices())?;
    let how = geodesic_method(method)?;
    let d = compute(py, move || how.build(&m)?.distances_from(&s))?;
    Ok(arrays::mat_out(py, d.as_ref()))
}

/// `geodesic_pairs(mesh, pairs (p, 2), method="exact") -> (p,)`: d(s, t) for every row (s, t).
#[pyfunction]
#[pyo3(signature = (mesh, pairs, method="exact"))]
fn geodesic_pairs<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    pairs: &Bound<'py, PyAny>,
    method: &str,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = mesh_arg(mesh, "mesh")?;
    let flat = py.import("numpy")?.call_method1("asarray", (pairs,))?;
    let shape: Vec<usize> = flat.getattr("shape")?.extract()?;
    if shape.len() != 2 || shape[1] != 2 {
        return Err(value_error("pairs", format!("expected shape (p, 2), got {shape:?}")));
    }
    let idx = arrays::indices(&flat.call_method1("reshape", (-1,))?, "pairs", m.n_vertices())?;
    let pairs: Vec<(usize, usize)> = idx.chunks(2).map(|c| (c[0], c[1])).collect();
    let how = geodesic_method(method)?;
    let d = compute(py, move || how.build(&m)?.pair_distances(&pairs))?;
    Ok(arrays::vec_out(py, d))
}

/// `geodesic_all_pairs(mesh, out, method="exact", chunk=64, progress=None)`: every distance into
/// `out` (n × n float64, writable, any memory order; e.g. an np.memmap), `chunk` sources at a
/// time; `progress` a callable `(stage, done, total)` (sources done of n) or None.
#[pyfunction]
#[pyo3(signature = (mesh, out, method="exact", chunk=64, progress=None))]
fn geodesic_all_pairs<'py>(
    py: Python<'py>,
    mesh: &Bound<'py, PyAny>,
    out: &Bound<'py, PyAny>,
    method: &str,
    chunk: usize,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<()> {
    let m: Arc<TriMesh> = mesh_arg(mesh, "mesh")?;
    let n = m.n_vertices();
    let mut w: PyReadwriteArray2<f64> = out.extract().map_err(|_| {
        value_error("out", format!("expected a writable ({n}, {n}) float64 numpy array (np.empty or np.memmap)"))
    })?;
    if w.as_array().dim() != (n, n) {
        return Err(value_error("out", format!("expected shape ({n}, {n}), got {:?}", w.as_array().shape())));
    }
    if chunk == 0 {
        return Err(value_error("chunk", "must be at least 1"));
    }
    let how = geodesic_method(method)?;
    // One session for the whole call: its progress is the sources done of n.
    let session = crate::Session::new(progress)?;
    let solver = {
        let m = m.clone();
        // Built once (the exact solver's preprocessing, the heat method's factorization).
        session.run(py, move || {
            funcorr::progress::stage("geodesics")?;
            let s: Box<dyn Distances + Send + Sync> = match how {
                GeodesicMethod::Exact => Box::new(funcorr::geodesic::ExactGeodesics::new(&m)?),
                GeodesicMethod::Heat => Box::new(funcorr::geodesic::HeatGeodesics::new(&m)?),
                GeodesicMethod::Dijkstra => Box::new(funcorr::geodesic::GraphGeodesics::mesh_edges(&m)?),
            };
            Ok(s)
        })?
    };
    let solver: Arc<dyn Distances + Send + Sync> = Arc::from(solver);
    let mut view = w.as_array_mut();
    for start in (0..n).step_by(chunk) {
        let sources: Vec<usize> = (start..(start + chunk).min(n)).collect();
        let s = solver.clone();
        let src = sources.clone();
        let d = session.run(py, move || {
            funcorr::progress::step(start, n)?;
            s.distances_from(&src)
        })?;
        // Column j of d holds the distances from source j: row `source` of the output (and,
        // the distances being symmetric up to the solver's accuracy, not mirrored).
        for (j, &src) in sources.iter().enumerate() {
            let mut row = view.row_mut(src);
            for t in 0..n {
                row[t] = d[(t, j)];
            }
        }
        py.check_signals()?;
    }
    session.report_now(py, &funcorr::progress::Status { stage: "geodesics".into(), done: n, total: n });
    Ok(())
}

/// `read_vts(path, n=None)`: a 1-based vertex list (.vts) as 0-based int64 indices (< n if given).
#[pyfunction]
#[pyo3(signature = (path, n=None))]
fn read_vts<'py>(py: Python<'py>, path: std::path::PathBuf, n: Option<usize>) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let v = compute(py, move || funcorr::io::indices::read_index_list_file(&path, true, n.unwrap_or(usize::MAX)))?;
    Ok(arrays::index_out(py, &v))
}

/// `evaluate(map_xy, Y, gt_x, gt_y, gt_y_sym=None, geodesics="exact") -> dict`.
#[pyfunction]
#[pyo3(signature = (map_xy, y, gt_x, gt_y, gt_y_sym=None, geodesics="exact"))]
fn evaluate<'py>(
    py: Python<'py>,
    map_xy: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    gt_x: &Bound<'py, PyAny>,
    gt_y: &Bound<'py, PyAny>,
    gt_y_sym: Option<&Bound<'py, PyAny>>,
    geodesics: &str,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let m = mesh_arg(y, "Y")?;
    let my = m.n_vertices();
    let map = arrays::indices(map_xy, "map_xy", my)?;
    let gt = funcorr::eval::GroundTruth {
        x: arrays::indices(gt_x, "gt_x", map.len())?,
        y: arrays::indices(gt_y, "gt_y", my)?,
        y_sym: gt_y_sym.filter(|s| !s.is_none()).map(|s| arrays::indices(s, "gt_y_sym", my)).transpose()?,
    };
    if gt.y.len() != gt.x.len() || gt.y_sym.as_ref().is_some_and(|s| s.len() != gt.x.len()) || gt.x.is_empty() {
        return Err(value_error("gt_y", "gt_x, gt_y (and gt_y_sym) must be non-empty and of the same length"));
    }
    let how = geodesic_method(geodesics)
        .map_err(|_| value_error("geodesics", format!("{geodesics:?}: expected 'exact', 'heat' or 'dijkstra'")))?;
    let ev = compute(py, move || {
        let d = how.build(&m)?;
        funcorr::eval::Evaluation::of_map(&map, &gt, &*d, m.total_area(), how.description())
    })?;
    let out = pyo3::types::PyDict::new(py);
    out.set_item("mean", ev.summary.mean)?;
    out.set_item("at_005", ev.summary.at_005)?;
    out.set_item("at_010", ev.summary.at_010)?;
    out.set_item("at_025", ev.summary.at_025)?;
    out.set_item("symmetric", ev.symmetric)?;
    out.set_item("geodesics", ev.geodesics)?;
    out.set_item("thresholds", arrays::vec_out(py, ev.thresholds))?;
    out.set_item("curve", arrays::vec_out(py, ev.curve))?;
    out.set_item("errors", arrays::vec_out(py, ev.errors))?;
    Ok(out)
}

/// `cumulative_curve(errors, thresholds=None)`: the fraction of errors ≤ each threshold
/// (default 0, 0.005, …, 0.25).
#[pyfunction]
#[pyo3(signature = (errors, thresholds=None))]
fn cumulative_curve<'py>(
    py: Python<'py>,
    errors: &Bound<'py, PyAny>,
    thresholds: Option<&Bound<'py, PyAny>>,
) -> PyResult<(F64s<'py>, F64s<'py>)> {
    let e = arrays::vector(errors, "errors")?;
    let t = match thresholds.filter(|t| !t.is_none()) {
        Some(t) => arrays::vector(t, "thresholds")?,
        None => funcorr::eval::standard_thresholds(),
    };
    let c = funcorr::eval::cumulative_curve(&e, &t);
    Ok((arrays::vec_out(py, t), arrays::vec_out(py, c)))
}

fn image_out<'py>(py: Python<'py>, img: funcorr::viz::Image) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let a = Array3::from_shape_vec((img.height as usize, img.width as usize, 3), img.rgb)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

fn view_arg(view: (f64, f64)) -> PyResult<funcorr::viz::View> {
    funcorr::viz::View::new(view.0, view.1).map_err(crate::to_py)
}

/// `render_pair(X, Y, map_yx, width=1600, height=900, view=(0, 0)) -> (h, w, 3) uint8`: X coloured
/// by position, Y by pulling X's colours back through `map_yx` (length m, vertices of X).
#[pyfunction]
#[pyo3(signature = (x, y, map_yx, width=1600, height=900, view=(0.0, 0.0)))]
fn render_pair<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    map_yx: &Bound<'py, PyAny>,
    width: u32,
    height: u32,
    view: (f64, f64),
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let (vx, fx) = geometry_arg(x, "X")?;
    let (vy, fy) = geometry_arg(y, "Y")?;
    let map = arrays::indices(map_yx, "map_yx", vx.len())?;
    if map.len() != vy.len() {
        return Err(value_error("map_yx", format!("length {} but Y has m = {} vertices", map.len(), vy.len())));
    }
    let view = view_arg(view)?;
    let img = compute(py, move || {
        use funcorr::viz::{position_colors, pull_back_colors, render_pair, ColoredShape};
        let cx = position_colors(&vx);
        let cy = pull_back_colors(&cx, &map).ok_or_else(|| funcorr::Error::invalid("map_yx", "points outside X"))?;
        let sx = ColoredShape { vertices: &vx, faces: &fx, colors: &cx };
        let sy = ColoredShape { vertices: &vy, faces: &fy, colors: &cy };
        render_pair(&sx, &sy, width, height, &view)
    })?;
    image_out(py, img)
}

/// `render(shape, colors=None, width=800, height=900, view=(0, 0)) -> (h, w, 3) uint8`.
#[pyfunction]
#[pyo3(signature = (shape, colors=None, width=800, height=900, view=(0.0, 0.0)))]
fn render<'py>(
    py: Python<'py>,
    shape: &Bound<'py, PyAny>,
    colors: Option<&Bound<'py, PyAny>>,
    width: u32,
    height: u32,
    view: (f64, f64),
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let (v, f) = geometry_arg(shape, "shape")?;
    let colors: Vec<[u8; 3]> = match colors.filter(|c| !c.is_none()) {
        Some(c) => {
            let a: numpy::PyReadonlyArray2<u8> =
                c.extract().map_err(|_| value_error("colors", "expected a (n, 3) uint8 array of RGB colours"))?;
            let a = a.as_array();
            if a.dim() != (v.len(), 3) {
                return Err(value_error("colors", format!("expected shape ({}, 3), got {:?}", v.len(), a.shape())));
            }
            a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect()
        }
        None => funcorr::viz::position_colors(&v),
    };
    let view = view_arg(view)?;
    let img = compute(py, move || {
        funcorr::viz::render(
            &funcorr::viz::ColoredShape { vertices: &v, faces: &f, colors: &colors },
            width,
            height,
            &view,
        )
    })?;
    image_out(py, img)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(write_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(cotangent_laplacian, m)?)?;
    m.add_function(wrap_pyfunction!(knn_laplacian, m)?)?;
    m.add_function(wrap_pyfunction!(intrinsic_laplacian, m)?)?;
    m.add_function(wrap_pyfunction!(nearest_rows, m)?)?;
    m.add_function(wrap_pyfunction!(cloud_laplacian, m)?)?;
    m.add_function(wrap_pyfunction!(hks, m)?)?;
    m.add_function(wrap_pyfunction!(wks, m)?)?;
    m.add_function(wrap_pyfunction!(wks_recipe, m)?)?;
    m.add_function(wrap_pyfunction!(hkm, m)?)?;
    m.add_function(wrap_pyfunction!(persistence_segments, m)?)?;
    m.add_function(wrap_pyfunction!(regions, m)?)?;
    m.add_function(wrap_pyfunction!(geodesic_distances, m)?)?;
    m.add_function(wrap_pyfunction!(geodesic_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(geodesic_all_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(read_vts, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(cumulative_curve, m)?)?;
    m.add_function(wrap_pyfunction!(render_pair, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    Ok(())
}
