//! The interactive viewer page (`funcorr::viz::html`, the same writer as `funcorr view`), as an
//! HTML string for notebooks (`MatchResult.show()`, `funcorr.view`, the pyFM-style plots).

use pyo3::prelude::*;
use pyo3::types::PyList;

use funcorr::viz::html::{Field, Side, VertexErrors, Viewer, ViewerShape};

use crate::arrays::{self, value_error};
use crate::compute;
use crate::prepared::{geometry_arg, mesh_arg};

/// (n, 3) uint8 colours of a shape with `n` vertices.
fn colors_arg(obj: Option<&Bound<'_, PyAny>>, name: &str, n: usize) -> PyResult<Option<Vec<[u8; 3]>>> {
    let Some(c) = obj.filter(|c| !c.is_none()) else { return Ok(None) };
    let a: numpy::PyReadonlyArray2<u8> =
        c.extract().map_err(|_| value_error(name, "expected an (n, 3) uint8 array of RGB colours"))?;
    let a = a.as_array();
    if a.dim() != (n, 3) {
        return Err(value_error(name, format!("expected shape ({n}, 3), got {:?}", a.shape())));
    }
    Ok(Some(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect()))
}

/// A field argument: (name, side "x" | "y", values, mark or None).
type FieldArg = (String, Side, Vec<f64>, Option<usize>);

fn fields_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<FieldArg>> {
    let Some(list) = obj.filter(|o| !o.is_none()) else { return Ok(vec![]) };
    let list =
        list.cast::<PyList>().map_err(|_| value_error("fields", "expected a list of (name, side, values, mark)"))?;
    let mut out = Vec::new();
    for (k, item) in list.iter().enumerate() {
        let (name, side, values, mark): (String, String, Bound<'_, PyAny>, Option<usize>) =
            item.extract().map_err(|_| {
                value_error("fields", format!("item {k}: expected (name, 'x' or 'y', values, mark or None)"))
            })?;
        let side = match side.as_str() {
            "x" | "X" => Side::X,
            "y" | "Y" => Side::Y,
            s => return Err(value_error("fields", format!("item {k}: side {s:?} is not 'x' or 'y'"))),
        };
        let values = arrays::vector(&values, &format!("fields[{k}] ({name})"))?;
        out.push((name, side, values, mark));
    }
    Ok(out)
}

/// The argument unless it is None (absent or Python's None).
fn some<'a, 'py>(o: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    o.filter(|o| !o.is_none())
}

/// `viewer_html(x, y=None, map_xy=None, map_yx=None, ...) -> str`: the viewer page of one shape
/// or a pair; with `gt_x` and `gt_y` X is coloured by the geodesic error of `map_xy` (Y a mesh).
#[pyfunction]
#[pyo3(signature = (
    x, y=None, map_xy=None, map_yx=None, colors_x=None, colors_y=None, gt_x=None, gt_y=None,
    gt_y_sym=None, geodesics="exact", error_max=funcorr::viz::html::DEFAULT_ERROR_MAX, fields=None,
    title=None, method=None, x_name=None, y_name=None, start=None
))]
#[allow(clippy::too_many_arguments)]
fn viewer_html<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: Option<&Bound<'py, PyAny>>,
    map_xy: Option<&Bound<'py, PyAny>>,
    map_yx: Option<&Bound<'py, PyAny>>,
    colors_x: Option<&Bound<'py, PyAny>>,
    colors_y: Option<&Bound<'py, PyAny>>,
    gt_x: Option<&Bound<'py, PyAny>>,
    gt_y: Option<&Bound<'py, PyAny>>,
    gt_y_sym: Option<&Bound<'py, PyAny>>,
    geodesics: &str,
    error_max: f64,
    fields: Option<&Bound<'py, PyAny>>,
    title: Option<String>,
    method: Option<String>,
    x_name: Option<String>,
    y_name: Option<String>,
    start: Option<String>,
) -> PyResult<String> {
    let (vx, fx) = geometry_arg(x, "X")?;
    let y = some(y);
    let (vy, fy) = match y {
        Some(y) => geometry_arg(y, "Y")?,
        None => (vec![], vec![]),
    };
    let (n, m) = (vx.len(), vy.len());
    let need_y = |what: &str| value_error(what, "needs the target shape Y");
    let map_xy = match some(map_xy) {
        Some(a) => {
            if y.is_none() {
                return Err(need_y("map_xy"));
            }
            let map = arrays::indices(a, "map_xy", m)?;
            if map.len() != n {
                return Err(value_error("map_xy", format!("length {} but X has n = {n} vertices", map.len())));
            }
            Some(map)
        }
        None => None,
    };
    let map_yx = match some(map_yx) {
        Some(a) => {
            if y.is_none() {
                return Err(need_y("map_yx"));
            }
            let map = arrays::indices(a, "map_yx", n)?;
            if map.len() != m {
                return Err(value_error("map_yx", format!("length {} but Y has m = {m} vertices", map.len())));
            }
            Some(map)
        }
        None => None,
    };
    let colors_x = colors_arg(colors_x, "colors_x", n)?;
    let colors_y = colors_arg(colors_y, "colors_y", m)?;
    let gt = match (some(gt_x), some(gt_y)) {
        (Some(gx), Some(gy)) => {
            let Some(map) = &map_xy else { return Err(value_error("gt_x", "the errors need map_xy")) };
            let mesh = mesh_arg(y.ok_or_else(|| need_y("gt_y"))?, "Y")?;
            let gt = funcorr::eval::GroundTruth {
                x: arrays::indices(gx, "gt_x", n)?,
                y: arrays::indices(gy, "gt_y", m)?,
                y_sym: some(gt_y_sym).map(|s| arrays::indices(s, "gt_y_sym", m)).transpose()?,
            };
            if gt.y.len() != gt.x.len() || gt.y_sym.as_ref().is_some_and(|s| s.len() != gt.x.len()) || gt.x.is_empty() {
                return Err(value_error("gt_y", "gt_x, gt_y (and gt_y_sym) must be non-empty and of the same length"));
            }
            let how = match geodesics {
                "exact" => funcorr::geodesic::GeodesicMethod::Exact,
                "heat" => funcorr::geodesic::GeodesicMethod::Heat,
                "dijkstra" => funcorr::geodesic::GeodesicMethod::Dijkstra,
                g => return Err(value_error("geodesics", format!("{g:?}: expected 'exact', 'heat' or 'dijkstra'"))),
            };
            Some((gt, mesh, how, map.clone()))
        }
        (None, None) => None,
        _ => return Err(value_error("gt_y", "give both gt_x and gt_y (template points on X and on Y)")),
    };
    if !(error_max.is_finite() && error_max > 0.0) {
        return Err(value_error("error_max", format!("{error_max} must be positive")));
    }
    let fields = fields_arg(fields)?;
    let has_y = y.is_some();
    compute(py, move || {
        let errors = match &gt {
            Some((gt, mesh, how, map)) => {
                let d = how.build(mesh)?;
                let e = funcorr::eval::hard_errors(map, gt, &*d, mesh.total_area())?;
                let mut ve = VertexErrors::spread(&vx, gt, &e, how.description())?;
                ve.max = error_max;
                Some(ve)
            }
            None => None,
        };
        let mut page = Viewer::new(
            title.unwrap_or_else(|| if has_y { "X → Y".into() } else { "X".into() }),
            ViewerShape { vertices: &vx, faces: &fx, colors: colors_x.as_deref() },
        );
        page.x_name = x_name.unwrap_or_else(|| "X".into());
        if has_y {
            page.y = Some(ViewerShape { vertices: &vy, faces: &fy, colors: colors_y.as_deref() });
        }
        page.y_name = y_name.unwrap_or_else(|| "Y".into());
        page.map_xy = map_xy.as_deref();
        page.map_yx = map_yx.as_deref();
        page.method = method;
        page.errors = errors;
        page.start = start;
        page.fields = fields
            .iter()
            .map(|(name, side, values, mark)| Field { name: name.clone(), side: *side, values, mark: *mark })
            .collect();
        page.html()
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(viewer_html, m)?)?;
    Ok(())
}
