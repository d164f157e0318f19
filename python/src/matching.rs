//! `match` (the pipeline of `funcorr match`), the point-wise refinements, the axiomatic fit and
//! soft maps, between prepared shapes.

use std::sync::Arc;

use faer::Mat;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use funcorr::descriptors::Descriptors;
use funcorr::matching::Keywords;
use funcorr::prepared::PreparedShape;
use funcorr::shape::Shape;

use crate::arrays::{self, value_error, I64s};
use crate::prepared::{cache_arg, laplacian_choice, prepared_arg, prepared_py, PyPrepared};
use crate::{compute, options};

/// A shape argument of `match`: prepared already, or to be prepared with `k` eigenpairs.
enum Side {
    Ready(Arc<PreparedShape>),
    Raw(Shape),
}

fn side(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Side> {
    if let Ok(p) = obj.cast::<PyPrepared>() {
        return Ok(Side::Ready(p.get().inner.clone()));
    }
    Ok(Side::Raw(arrays::shape(obj, name)?))
}

/// Data F on X and G on Y: a `--data` spec string or a tuple of two (n × q), (m × q) arrays.
enum Data {
    Spec(funcorr::descriptors::spec::PairDataSpec),
    Given(Descriptors, Descriptors),
}

fn data_arg(obj: &Bound<'_, PyAny>) -> PyResult<Data> {
    if let Ok(s) = obj.extract::<String>() {
        let spec =
            s.parse::<funcorr::descriptors::spec::PairDataSpec>().and_then(|s| s.standalone()).map_err(crate::to_py)?;
        return Ok(Data::Spec(spec));
    }
    let t = obj
        .cast::<PyTuple>()
        .map_err(|_| value_error("data", "expected a spec string (e.g. 'wks') or a tuple (F, G) of arrays"))?;
    if t.len() != 2 {
        return Err(value_error("data", "expected a tuple (F, G): F (n × q) on X, G (m × q) on Y"));
    }
    let f = arrays::matrix(&t.get_item(0)?, "data[0] (F)")?;
    let g = arrays::matrix(&t.get_item(1)?, "data[1] (G)")?;
    if f.ncols() != g.ncols() || f.ncols() == 0 {
        return Err(value_error(
            "data",
            format!("F has {} columns and G {}: need the same q ≥ 1", f.ncols(), g.ncols()),
        ));
    }
    let names: Vec<String> = (0..f.ncols()).map(|j| format!("column {j}")).collect();
    Ok(Data::Given(
        Descriptors::new(f, names.clone()).map_err(crate::to_py)?,
        Descriptors::new(g, names).map_err(crate::to_py)?,
    ))
}

/// `match(X, Y, data, options, progress)`: the whole pipeline of `funcorr match`. Returns a dict.
/// `progress`: a callable `(stage, done, total)` or None.
#[pyfunction]
#[pyo3(signature = (x, y, data, options=None, progress=None))]
fn match_shapes<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    data: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    // Everything is checked before any work: data, options, shapes.
    let data = data_arg(data)?;
    let rich = match &data {
        Data::Spec(s) => s.is_rich(),
        Data::Given(..) => true,
    };
    let mut o = options::Opts::new(options)?;
    let settings = options::match_settings(&mut o)?;
    let opts = settings.resolve(rich).map_err(options::library_error)?;
    // Options that ask for too few eigenpairs fail before the shapes are read; the fewest
    // eigenpairs per shape they may ask (the eigenpairs of this pair are known after the
    // Laplacians: fewer where X cannot be a part, whose partial path reads them all).
    let least = settings.basis_demand_for(&opts, &Keywords, true).map_err(options::library_error)?;
    let preparation_keys = ["laplacian", "cloud_neighbours", "knn", "vertex_weights", "sigma", "cache_dir"];
    let given: Vec<&str> = preparation_keys.iter().copied().filter(|k| o.has(k)).collect();
    let choice = laplacian_choice(&mut o)?;
    let seg = options::segmentation(&mut o)?;
    let cache = cache_arg(o.take("cache_dir").as_ref())?;
    let landmarks = o.take("landmarks").filter(|v| !v.is_none());
    o.finish()?;
    let (sx, sy) = (side(x, "X")?, side(y, "Y")?);
    if let (Some(key), true) = (given.first(), matches!(sx, Side::Ready(_)) && matches!(sy, Side::Ready(_))) {
        return Err(value_error(
            key,
            "X and Y are prepared already (their Laplacians and bases are fixed): give it to funcorr.prepare",
        ));
    }
    for (s, name) in [(&sx, "X"), (&sy, "Y")] {
        if let Side::Raw(shape) = s {
            if least.size >= shape.n_vertices() {
                let e = settings.too_small(name, shape.n_vertices(), &opts, &least, &Keywords);
                return Err(options::library_error(e));
            }
        }
        if needs_surface(&opts) {
            check_surface(s, choice, name)?;
        }
    }
    let n_of = |s: &Side| match s {
        Side::Ready(p) => p.n(),
        Side::Raw(s) => s.n_vertices(),
    };
    // `landmarks=`: a file of pairs (as `funcorr match --landmarks`) or a (k, 2) integer array.
    let mut opts = opts;
    if let Some(l) = &landmarks {
        if opts.method != funcorr::matching::Method::Axiomatic {
            return Err(value_error(
                "landmarks",
                "landmarks act in the default method (method='axiomatic'); for the others give them as data, \
                 data='landmarks:FILE'",
            ));
        }
        let (n, m) = (n_of(&sx), n_of(&sy));
        opts.axiomatic.landmarks.pairs = match arrays::path_arg(l) {
            Some(path) => funcorr::io::indices::read_index_pairs_file(&path, false, n, m).map_err(crate::to_py)?,
            None => arrays::index_pairs(l, "landmarks", n, m)?,
        };
    }
    if let Data::Given(f, g) = &data {
        if f.n() != n_of(&sx) || g.n() != n_of(&sy) {
            return Err(value_error(
                "data",
                format!("F has {} rows and G {}, X has {} vertices and Y {}", f.n(), g.n(), n_of(&sx), n_of(&sy)),
            ));
        }
    }
    let mut opts_run = opts.clone();
    let (px, py_, f, g, r, basis_k) = crate::compute_reporting(py, progress, move || {
        // As `funcorr match`: the Laplacians, the eigenpairs this pair needs, the bases as
        // computed (or cached), not truncated.
        enum Laplacianed {
            Ready(Arc<PreparedShape>),
            Raw(Box<(Shape, funcorr::laplacian::Laplacian, Option<funcorr::prepared::Surface>)>),
        }
        let laplacian = |s: Side| -> funcorr::Result<Laplacianed> {
            match s {
                Side::Ready(p) => Ok(Laplacianed::Ready(p)),
                Side::Raw(shape) => {
                    funcorr::progress::stage("laplacian")?;
                    let (lap, surface) = funcorr::prepared::build_laplacian(&shape, choice)?;
                    Ok(Laplacianed::Raw(Box::new((shape, lap, surface))))
                }
            }
        };
        let (lx, ly) = rayon::join(|| laplacian(sx), || laplacian(sy));
        let (lx, ly) = (lx?, ly?);
        fn shape_area(l: &Laplacianed) -> (&Shape, f64) {
            match l {
                Laplacianed::Ready(p) => (&p.shape, p.area),
                Laplacianed::Raw(raw) => (&raw.0, funcorr::prepared::area_of_mass(&raw.1.mass)),
            }
        }
        let ((shx, ax), (shy, ay)) = (shape_area(&lx), shape_area(&ly));
        // Fewer where X cannot be a part and the data are the default WKS or given (the partial
        // path and descriptors such as wks:N read them all); the sides still to be computed are
        // checked against it.
        let to_compute = |l: &Laplacianed, name: &'static str| matches!(l, Laplacianed::Raw(_)).then_some(name);
        let basis_k = settings
            .pair_basis_demand(
                &opts_run,
                &Keywords,
                (shx, ax, to_compute(&lx, "X")),
                (shy, ay, to_compute(&ly, "Y")),
                matches!(data, Data::Given(..) | Data::Spec(funcorr::descriptors::spec::PairDataSpec::WksRecipe)),
            )?
            .size;
        let prep = |l: Laplacianed| -> funcorr::Result<Arc<PreparedShape>> {
            match l {
                Laplacianed::Ready(p) => Ok(p),
                Laplacianed::Raw(raw) => {
                    let (shape, lap, surface) = *raw;
                    funcorr::progress::stage("eigenbasis")?;
                    let (basis, _) = funcorr::spectral::eigen_basis_cached(
                        &lap,
                        &funcorr::spectral::SpectralOptions::new(basis_k),
                        cache.as_ref(),
                        None,
                    )?;
                    Ok(Arc::new(PreparedShape::from_parts(shape, lap, basis, surface)))
                }
            }
        };
        let (px, py_) = rayon::join(|| prep(lx), || prep(ly));
        let (px, py_) = (px?, py_?);
        funcorr::progress::stage("data")?;
        // As `funcorr match`: a part of Y (detected or partial=True) with the default WKS gets
        // them at the same energies on both shapes.
        let (f, g) = match data {
            Data::Spec(spec) => match funcorr::matching::partial::partial_pair_data(&px, &py_, &spec, &mut opts_run)? {
                Some(fg) => fg,
                None => spec.functions(px.parts(), py_.parts(), &seg)?,
            },
            Data::Given(f, g) => (f, g),
        };
        let r = funcorr::matching::run(&px, &py_, &f, &g, &opts_run)?;
        Ok((px, py_, f, g, r, basis_k))
    })?;
    let out = PyDict::new(py);
    out.set_item("map_xy", arrays::index_out(py, &r.map_xy))?;
    out.set_item("map_yx", arrays::index_out(py, &r.map_yx))?;
    out.set_item("C", arrays::mat_out(py, r.c.as_ref()))?;
    out.set_item("C_method", arrays::mat_out(py, r.c_method.as_ref()))?;
    match &r.coefficients {
        Some((a, b)) => {
            out.set_item("coefficients", (arrays::mat_out(py, a.as_ref()), arrays::mat_out(py, b.as_ref())))?
        }
        None => out.set_item("coefficients", py.None())?,
    }
    match &r.coverage {
        Some(c) => out.set_item("coverage", arrays::vec_out(py, c.clone()))?,
        None => out.set_item("coverage", py.None())?,
    }
    let stages = PyList::empty(py);
    for (name, secs) in &r.stages {
        stages.append((name, secs))?;
    }
    out.set_item("stages", stages)?;
    let report = r.report(&opts, px.n(), py_.n(), f.q(), basis_k);
    out.set_item("report", funcorr::io::to_json_sorted(&report).map_err(crate::to_py)?)?;
    out.set_item("q", f.q())?;
    let _ = g;
    out.set_item("X", PyPrepared::new(px, choice))?;
    out.set_item("Y", PyPrepared::new(py_, choice))?;
    Ok(out)
}

/// Whether the options need each shape's surface (the axiomatic method's orientation term reads
/// face gradients).
fn needs_surface(opts: &funcorr::matching::MatchOptions) -> bool {
    let fit = &opts.axiomatic.fit;
    opts.method == funcorr::matching::Method::Axiomatic
        && fit.weights.orientation > 0.0
        && fit.orientation != funcorr::fmap::energy::Orientation::Ignore
}

/// A shape without a surface (points of another dimension than 3, or a kNN-graph Laplacian) is
/// refused before any work when the options need one, naming the argument and the shape it
/// should have.
fn check_surface(s: &Side, choice: funcorr::prepared::LaplacianChoice, name: &str) -> PyResult<()> {
    use funcorr::prepared::LaplacianChoice as L;
    let why = match s {
        Side::Ready(p) if p.triangles().is_none() => Some("this PreparedShape has none".to_string()),
        Side::Ready(_) => None,
        Side::Raw(_) if matches!(choice, L::Knn(_)) => Some("laplacian='knn' gives it none".to_string()),
        Side::Raw(Shape::Points(p)) if p.dim() != 3 => {
            Some(format!("got an array of shape ({}, {}) (taken as {}-D points)", p.len(), p.dim(), p.dim()))
        }
        Side::Raw(_) => None,
    };
    match why {
        Some(why) => Err(value_error(
            name,
            format!(
                "expected a mesh (V, F) or 3-D points of shape (n, 3): the axiomatic method's orientation term \
                 needs a surface; {why} (for feature data use method='fmap', or orientation='ignore')"
            ),
        )),
        None => Ok(()),
    }
}

/// The eigenpairs per shape `match` computes for these data and options (`funcorr match`'s
/// rule for any pair: what the method and its refinement need, at least 200 unless `kprime` says
/// otherwise; `match` itself computes 128 for the axiomatic method where X cannot be a part, and
/// a larger basis gives the same maps there), so that shapes prepared with it give exactly the
/// maps of raw shapes.
#[pyfunction]
#[pyo3(signature = (data, options=None))]
fn match_basis_size(data: &Bound<'_, PyAny>, options: Option<&Bound<'_, PyDict>>) -> PyResult<usize> {
    let rich = match data_arg(data)? {
        Data::Spec(s) => s.is_rich(),
        Data::Given(..) => true,
    };
    let mut o = options::Opts::new(options)?;
    let settings = options::match_settings(&mut o)?;
    let opts = settings.resolve(rich).map_err(options::library_error)?;
    Ok(settings.basis_demand(&opts, &Keywords).map_err(options::library_error)?.size)
}

/// A functional map argument C (k_Y × k_X, coefficients on X → coefficients on Y).
fn fmap_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Mat<f64>> {
    let c = arrays::matrix(obj, name)?;
    if c.nrows() == 0 || c.ncols() == 0 {
        return Err(value_error(
            name,
            format!("expected a k_Y × k_X functional map, got {} × {}", c.nrows(), c.ncols()),
        ));
    }
    Ok(c)
}

fn square_fmap_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Mat<f64>> {
    let c = fmap_arg(obj, name)?;
    if c.nrows() != c.ncols() {
        return Err(value_error(
            name,
            format!("expected a square k × k functional map, got {} × {}", c.nrows(), c.ncols()),
        ));
    }
    Ok(c)
}

fn check_c_fits(c: &Mat<f64>, x: &PreparedShape, y: &PreparedShape, name: &str) -> PyResult<()> {
    let (ky, kx) = (c.nrows(), c.ncols());
    if kx > x.basis.k() || ky > y.basis.k() {
        return Err(value_error(
            name,
            format!(
                "a {ky} × {kx} map (k_Y × k_X) needs {kx} eigenpairs on X and {ky} on Y; X has {} and Y {}",
                x.basis.k(),
                y.basis.k()
            ),
        ));
    }
    Ok(())
}

/// Units (see `PyPrepared`): the bindings' functional maps are between the shapes' own bases,
/// the library computes between the unit-area ones. C_input = s · C_unit with
/// s = √(area_Y / area_X) (φ_input = φ_unit / √area).
fn unit_scale(x: &PreparedShape, y: &PreparedShape) -> f64 {
    (y.area / x.area).sqrt()
}

fn scaled(c: Mat<f64>, s: f64) -> Mat<f64> {
    if s == 1.0 {
        c
    } else {
        &c * faer::Scale(s)
    }
}

/// Sizes (k_X, k_Y) from an int k (square) or a pair (k_X, k_Y).
fn sizes_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(usize, usize)> {
    if let Ok(k) = obj.extract::<usize>() {
        return Ok((k, k));
    }
    obj.extract::<(usize, usize)>()
        .map_err(|_| value_error(name, format!("expected an int k or a pair (k_X, k_Y) of sizes, got {obj}")))
}

fn check_sizes(kx: usize, ky: usize, x: &PreparedShape, y: &PreparedShape, name: &str) -> PyResult<()> {
    if kx == 0 || ky == 0 || kx > x.basis.k() || ky > y.basis.k() {
        let got = if kx == ky { format!("{kx}") } else { format!("({kx}, {ky})") };
        return Err(value_error(
            name,
            format!("{got}: need 1 ≤ k ≤ the basis sizes (X has {}, Y {})", x.basis.k(), y.basis.k()),
        ));
    }
    Ok(())
}

type MapOut<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<i64>>);

/// ICP refinement (Ovsjanikov et al. 2012) of C (k_Y × k_X, X → Y coefficients).
#[pyfunction]
#[pyo3(signature = (x, y, c, iterations=10))]
fn icp_refine<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    c: &Bound<'py, PyAny>,
    iterations: usize,
) -> PyResult<MapOut<'py>> {
    let (px, py_) = (prepared_arg(x, "X")?, prepared_arg(y, "Y")?);
    let c = fmap_arg(c, "C")?;
    check_c_fits(&c, &px, &py_, "C")?;
    let s = unit_scale(&px, &py_);
    let (c, map) = compute(py, move || {
        let o = funcorr::pointwise::IcpOptions { max_iterations: iterations };
        let c = scaled(c, 1.0 / s);
        let (c, map) =
            funcorr::pointwise::icp(px.basis.eigenvectors.as_ref(), py_.basis.eigenvectors.as_ref(), c.as_ref(), &o)?;
        Ok((scaled(c, s), map))
    })?;
    Ok((arrays::mat_out(py, c.as_ref()), arrays::index_out(py, &map)))
}

/// ZoomOut (Melzi et al. 2019) of C (k × k, X → Y coefficients) to k_final in steps of `step`.
#[pyfunction]
#[pyo3(signature = (x, y, c, k_final, step=1))]
fn zoomout_refine<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    c: &Bound<'py, PyAny>,
    k_final: usize,
    step: usize,
) -> PyResult<MapOut<'py>> {
    let (px, py_) = (prepared_arg(x, "X")?, prepared_arg(y, "Y")?);
    let c = square_fmap_arg(c, "C")?;
    check_c_fits(&c, &px, &py_, "C")?;
    if k_final < c.nrows() || k_final > px.basis.k().min(py_.basis.k()) {
        return Err(value_error(
            "k_final",
            format!("{k_final}: need {} ≤ k_final ≤ the basis sizes ({}, {})", c.nrows(), px.basis.k(), py_.basis.k()),
        ));
    }
    if step == 0 {
        return Err(value_error("step", "must be at least 1"));
    }
    let s = unit_scale(&px, &py_);
    let (c, map) = compute(py, move || {
        let o = funcorr::pointwise::ZoomOutOptions { k_final, step };
        let c = scaled(c, 1.0 / s);
        let (c, map) = funcorr::pointwise::zoomout(
            px.basis.eigenvectors.as_ref(),
            py_.basis.eigenvectors.as_ref(),
            &py_.basis.mass,
            c.as_ref(),
            &o,
        )?;
        Ok((scaled(c, s), map))
    })?;
    Ok((arrays::mat_out(py, c.as_ref()), arrays::index_out(py, &map)))
}

/// Point maps of a functional map C (k_Y × k_X, X → Y coefficients): (map_xy, map_yx); with
/// `adjoint`, map_yx by the adjoint (rows of Ψ C matched to rows of Φ).
#[pyfunction]
#[pyo3(signature = (x, y, c, adjoint=false))]
fn maps_from_fmap<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    c: &Bound<'py, PyAny>,
    adjoint: bool,
) -> PyResult<(I64s<'py>, I64s<'py>)> {
    let (px, py_) = (prepared_arg(x, "X")?, prepared_arg(y, "Y")?);
    let c = fmap_arg(c, "C")?;
    check_c_fits(&c, &px, &py_, "C")?;
    let s = unit_scale(&px, &py_);
    let (a, b) = compute(py, move || {
        let c = scaled(c, 1.0 / s);
        let (phi, psi) = (px.basis.eigenvectors.as_ref(), py_.basis.eigenvectors.as_ref());
        let map_yx = if adjoint {
            funcorr::pointwise::map_yx_from_fmap_adjoint(phi, psi, c.as_ref())?
        } else {
            funcorr::pointwise::map_yx_from_fmap(phi, psi, c.as_ref())?
        };
        Ok((funcorr::pointwise::map_from_fmap(phi, psi, c.as_ref())?, map_yx))
    })?;
    Ok((arrays::index_out(py, &a), arrays::index_out(py, &b)))
}

/// The functional map C (k_Y × k_X, X → Y coefficients) of a point map Y → X:
/// C = Ψ_{k_Y}ᵀ A_Y Π Φ_{k_X}; `k` an int (square) or (k_X, k_Y).
#[pyfunction]
fn fmap_from_map<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    map_yx: &Bound<'py, PyAny>,
    k: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (px, py_) = (prepared_arg(x, "X")?, prepared_arg(y, "Y")?);
    let map = arrays::indices(map_yx, "map_yx", px.n())?;
    if map.len() != py_.n() {
        return Err(value_error("map_yx", format!("length {} but Y has m = {} vertices", map.len(), py_.n())));
    }
    let (kx, ky) = sizes_arg(k, "k")?;
    check_sizes(kx, ky, &px, &py_, "k")?;
    let s = unit_scale(&px, &py_);
    let c = compute(py, move || {
        let c = funcorr::pointwise::fmap_from_map_yx_sizes(
            px.basis.eigenvectors.as_ref(),
            py_.basis.eigenvectors.as_ref(),
            &py_.basis.mass,
            &map,
            kx,
            ky,
        )?;
        Ok(scaled(c, s))
    })?;
    Ok(arrays::mat_out(py, c.as_ref()))
}

/// The axiomatic functional map C (k_Y × k_X, X → Y coefficients) from descriptors F (n × q) on
/// X and G (m × q) on Y: the exact minimizer of the energy of `funcorr::fmap::energy` with the
/// given weights, mask and orientation, the first column fixed to map constants to constants.
/// `k`: an int (square) or (k_X, k_Y).
#[pyfunction]
#[pyo3(signature = (x, y, f, g, k, w_descr=1.0, w_lap=0.1, w_dcomm=1.0, w_orient=0.0, mask="resolvent", orientation="preserve", fix_constant=true))]
#[allow(clippy::too_many_arguments)]
fn axiomatic_fmap<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    f: &Bound<'py, PyAny>,
    g: &Bound<'py, PyAny>,
    k: &Bound<'py, PyAny>,
    w_descr: f64,
    w_lap: f64,
    w_dcomm: f64,
    w_orient: f64,
    mask: &str,
    orientation: &str,
    fix_constant: bool,
) -> PyResult<(Bound<'py, PyArray2<f64>>, f64)> {
    use funcorr::fmap::axiomatic::{axiomatic, constant_column, spectral_side, AxiomaticOptions, ShapeData};
    use funcorr::fmap::energy::{Energy, EnergyWeights, Mask, Orientation};
    let (px, py_) = (prepared_arg(x, "X")?, prepared_arg(y, "Y")?);
    let f = arrays::matrix(f, "F")?;
    let g = arrays::matrix(g, "G")?;
    if f.nrows() != px.n() || g.nrows() != py_.n() || f.ncols() != g.ncols() || f.ncols() == 0 {
        return Err(value_error(
            "F",
            format!(
                "F is {}×{} and G {}×{}: need n × q and m × q (n = {}, m = {}, q ≥ 1)",
                f.nrows(),
                f.ncols(),
                g.nrows(),
                g.ncols(),
                px.n(),
                py_.n()
            ),
        ));
    }
    let (kx, ky) = sizes_arg(k, "k")?;
    check_sizes(kx, ky, &px, &py_, "k")?;
    for (name, w) in [("w_descr", w_descr), ("w_lap", w_lap), ("w_dcomm", w_dcomm), ("w_orient", w_orient)] {
        if !(w.is_finite() && w >= 0.0) {
            return Err(value_error(name, format!("must be finite and ≥ 0, got {w}")));
        }
    }
    let mask = match mask {
        "resolvent" => Mask::Resolvent { gamma: 0.5 },
        "standard" => Mask::Standard,
        other => return Err(value_error("mask", format!("{other:?}: expected 'resolvent' or 'standard'"))),
    };
    let orientation = match orientation {
        "preserve" => Orientation::Preserve,
        "reverse" => Orientation::Reverse,
        "ignore" => Orientation::Ignore,
        other => {
            return Err(value_error("orientation", format!("{other:?}: expected 'preserve', 'reverse' or 'ignore'")))
        }
    };
    let orient = w_orient > 0.0 && orientation != Orientation::Ignore;
    for (p, name) in [(&px, "X"), (&py_, "Y")] {
        if orient && p.triangles().is_none() {
            return Err(value_error(
                name,
                "the orientation term (w_orient > 0) needs a surface: a mesh or 3-D points with the point-cloud Laplacian",
            ));
        }
    }
    let weights =
        EnergyWeights { descriptors: w_descr, laplacian: w_lap, commutativity: w_dcomm, orientation: w_orient };
    let s = unit_scale(&px, &py_);
    let (c, energy) = compute(py, move || {
        let names: Vec<String> = (0..f.ncols()).map(|j| format!("column {j}")).collect();
        let (df, dg) = (Descriptors::new(f, names.clone())?, Descriptors::new(g, names)?);
        let (gx, gy) = if orient { (px.gradients(), py_.gradients()) } else { (None, None) };
        let sx = ShapeData { basis: &px.basis, gradients: gx, descriptors: &df, cells: None };
        let sy = ShapeData { basis: &py_.basis, gradients: gy, descriptors: &dg, cells: None };
        let (c, energy) = if kx == ky {
            let opts = AxiomaticOptions { k: kx, weights, mask, orientation, fix_constant, unit_gradients: true };
            let (c, report) = axiomatic(&sx, &sy, &opts)?;
            (c, report.energy)
        } else {
            // A rectangular map (k_Y × k_X): the same energy on k_X functions of X and k_Y of Y.
            let (comm, unit) = (w_dcomm > 0.0, true);
            let a = spectral_side(&sx, kx, comm, orient, unit, "X")?;
            let b = spectral_side(&sy, ky, comm, orient, unit, "Y")?;
            let e = Energy::new(&a, &b, &weights, mask, orientation)?;
            let c = if fix_constant {
                e.solve_with_first_column(&constant_column(&px.basis, &py_.basis, ky))?
            } else {
                e.solve()?
            };
            let v = e.value(c.as_ref());
            (c, v)
        };
        Ok((scaled(c, s), energy))
    })?;
    Ok((arrays::mat_out(py, c.as_ref()), energy))
}

/// The soft map T δ_i of vertex i of X (a function on Y, length m) of a functional map C
/// (k_Y × k_X, X → Y coefficients, between the shapes' own bases, as `funcorr match --soft`):
/// Ψ C Φ(i)ᵀ, up to the mass of vertex i.
#[pyfunction]
fn soft_map<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    c: &Bound<'py, PyAny>,
    i: usize,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (xb, yb) = (prepared_py(x, "X")?, prepared_py(y, "Y")?);
    let (px, py_) = (xb.get().inner.clone(), yb.get().inner.clone());
    let c = fmap_arg(c, "C")?;
    check_c_fits(&c, &px, &py_, "C")?;
    if i >= px.n() {
        return Err(value_error("i", format!("vertex {i} of X does not exist (n = {})", px.n())));
    }
    let (bx, by) = (xb.get().input_basis().clone(), yb.get().input_basis().clone());
    let t = compute(py, move || {
        funcorr::pointwise::soft_map_column(bx.eigenvectors.as_ref(), by.eigenvectors.as_ref(), c.as_ref(), i)
    })?;
    Ok(arrays::vec_out(py, t))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(match_shapes, m)?)?;
    m.add_function(wrap_pyfunction!(icp_refine, m)?)?;
    m.add_function(wrap_pyfunction!(zoomout_refine, m)?)?;
    m.add_function(wrap_pyfunction!(maps_from_fmap, m)?)?;
    m.add_function(wrap_pyfunction!(fmap_from_map, m)?)?;
    m.add_function(wrap_pyfunction!(axiomatic_fmap, m)?)?;
    m.add_function(wrap_pyfunction!(match_basis_size, m)?)?;
    m.add_function(wrap_pyfunction!(options::match_option_keys, m)?)?;
    m.add_function(wrap_pyfunction!(soft_map, m)?)?;
    Ok(())
}
