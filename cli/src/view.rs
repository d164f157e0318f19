//! `funcorr view`: the interactive viewer page (`view.html`) of a map, from the files of a match
//! directory or from two shapes and a map file; and the `view.html` that `match` and `demo`
//! write beside their other outputs. The page itself is written by the library
//! (`funcorr::viz::html`).

#[allow(unused_imports)]
use super::*;

use funcorr::viz::html::{Field, Side, VertexErrors, Viewer, ViewerShape};

#[derive(clap::Args)]
pub(crate) struct ViewArgs {
    /// A match directory (the output of `funcorr match -o DIR`: X.ply, Y.ply, map.npy, map_yx.npy,
    /// soft_*.npy, report.json), or the source shape X and the target shape Y (with --map).
    #[arg(num_args = 1..=2, required = true, value_name = "DIR | X Y")]
    pub(crate) inputs: Vec<PathBuf>,
    /// The map X → Y: one vertex id of Y per line for every vertex of X (map.txt of `funcorr
    /// match`), or a .npy vector. Default for a match directory: DIR/map.npy.
    #[arg(long)]
    pub(crate) map: Option<PathBuf>,
    /// The map Y → X (one vertex id of X per vertex of Y, text or .npy): Y is coloured through it,
    /// as Y.ply, and a click on Y shows its image on X. Default for a match directory:
    /// DIR/map_yx.npy when present; without it, each vertex of Y takes the colour of the vertex of
    /// X whose image is nearest.
    #[arg(long)]
    pub(crate) map_yx: Option<PathBuf>,
    /// The text map files are 1-based (MATLAB).
    #[arg(long)]
    pub(crate) one_based: bool,
    /// Template points on X (1-based .vts): with --gt-target, colour X by the geodesic error of
    /// the map (the Princeton protocol of `funcorr eval`).
    #[arg(long, requires = "gt_target")]
    pub(crate) gt_source: Option<PathBuf>,
    /// Corresponding template points on Y (1-based .vts).
    #[arg(long, requires = "gt_source")]
    pub(crate) gt_target: Option<PathBuf>,
    /// Left–right mirrored template points on Y (1-based .sym.vts): allow symmetric flips.
    #[arg(long, requires = "gt_target")]
    pub(crate) gt_target_sym: Option<PathBuf>,
    /// Geodesic distances on Y for the errors.
    #[arg(long, value_enum, default_value_t = GeodesicsChoice::Exact)]
    pub(crate) geodesics: GeodesicsChoice,
    /// Top of the error colour bar, in geodesic error / √area(Y) (larger errors get its colour).
    #[arg(long, default_value_t = funcorr::viz::html::DEFAULT_ERROR_MAX)]
    pub(crate) error_max: f64,
    /// A function on X to offer as a colouring: FILE.npy (a vector, or the first column of an
    /// n × q matrix such as F.npy) or FILE.npy:COLUMN (0-based). Repeatable.
    #[arg(long, value_name = "FILE.npy[:COLUMN]")]
    pub(crate) field_x: Vec<String>,
    /// A function on Y to offer as a colouring (as --field-x), e.g. a soft map or G.npy:3.
    #[arg(long, value_name = "FILE.npy[:COLUMN]")]
    pub(crate) field_y: Vec<String>,
    /// Title of the page (default: the two shapes' names).
    #[arg(long)]
    pub(crate) title: Option<String>,
    /// Output file (default: DIR/view.html for a match directory, else ./view.html).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
}

/// A shape for the viewer: 3-D vertices, triangles, and the colours its file carries (PLY).
pub(crate) struct ViewShape {
    pub(crate) shape: Shape,
    pub(crate) vertices: Vec<[f64; 3]>,
    pub(crate) faces: Vec<[u32; 3]>,
    pub(crate) colors: Option<Vec<[u8; 3]>>,
}

impl ViewShape {
    /// A loaded shape; errors (naming `path`) for feature matrices that are not 3-D points.
    pub(crate) fn of(shape: Shape, colors: Option<Vec<[u8; 3]>>, path: &Path) -> Result<ViewShape> {
        let Some(data) = mesh_data(&shape) else {
            return Err(Error::invalid(
                "shape",
                format!(
                    "{}: the viewer draws 3-D shapes (meshes or 3-D points), not {}-dimensional features",
                    path.display(),
                    shape_dim(&shape)
                ),
            ));
        };
        Ok(ViewShape { shape, vertices: data.vertices, faces: data.faces, colors })
    }

    fn load(path: &Path) -> Result<ViewShape> {
        let is_npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if is_npy {
            return ViewShape::of(Shape::load(path)?, None, path);
        }
        let data = funcorr::io::read_mesh(path)?;
        let colors = data.colors.clone().filter(|c| c.len() == data.vertices.len());
        let shape = Shape::from_data(data).map_err(|e| Error::parse(path, None, e.to_string()))?;
        ViewShape::of(shape, colors, path)
    }

    fn viewer(&self, colors: bool) -> ViewerShape<'_> {
        ViewerShape {
            vertices: &self.vertices,
            faces: &self.faces,
            colors: if colors { self.colors.as_deref() } else { None },
        }
    }
}

fn shape_dim(s: &Shape) -> usize {
    match s {
        Shape::Mesh(_) => 3,
        Shape::Points(p) => p.dim(),
    }
}

/// The display name of a shape file: its stem.
fn stem(path: &Path) -> String {
    path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| path.display().to_string())
}

/// Reads a point map from `path`: text (one id per line, 0- or 1-based) or .npy (0-based, a
/// vector or one column); `len` entries expected (one per vertex of the source, `from`), each a
/// vertex of the target (`< targets`). Errors name the file.
pub(crate) fn read_map(path: &Path, one_based: bool, len: usize, targets: usize, from: &str) -> Result<Vec<usize>> {
    let is_npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let map = if is_npy {
        let m = funcorr::io::npy::read_npy_matrix(path)?;
        if m.cols != 1 && m.rows != 1 {
            return Err(Error::parse(
                path,
                None,
                format!("expected a vector of vertex ids, found a {} × {} matrix", m.rows, m.cols),
            ));
        }
        m.data
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                if v.fract() == 0.0 && v >= 0.0 && v < targets as f64 {
                    Ok(v as usize)
                } else {
                    Err(Error::parse(path, None, format!("entry {i} is {v}, not a vertex id in [0, {targets})")))
                }
            })
            .collect::<Result<Vec<_>>>()?
    } else {
        funcorr::io::indices::read_index_list_file(path, one_based, targets)?
    };
    if map.len() != len {
        return Err(Error::parse(
            path,
            None,
            format!("expected {len} entries (one per vertex of {from}), found {}", map.len()),
        ));
    }
    Ok(map)
}

/// A column of a .npy file as a field: `FILE.npy` or `FILE.npy:COLUMN`, with `len` rows.
fn read_field(spec: &str, len: usize, flag: &str, side: Side) -> Result<(String, Vec<f64>)> {
    let (file, column) = match spec.rsplit_once(':') {
        Some((f, c)) if !c.is_empty() && c.chars().all(|ch| ch.is_ascii_digit()) => {
            (f, c.parse::<usize>().map_err(|_| Error::invalid(flag, format!("{spec:?}: bad column")))?)
        }
        _ => (spec, 0),
    };
    let path = Path::new(file);
    let m = funcorr::io::npy::read_npy_matrix(path)?;
    let (rows, cols) = if m.cols == 1 || m.rows != 1 { (m.rows, m.cols) } else { (m.cols, 1) };
    if rows != len {
        return Err(Error::parse(
            path,
            None,
            format!(
                "{rows} rows, but {} has {len} vertices (one value per vertex) [{flag}]",
                if side == Side::X { "X" } else { "Y" }
            ),
        ));
    }
    if column >= cols {
        return Err(Error::invalid(
            flag,
            format!("{spec:?}: column {column} of a {rows} × {cols} matrix does not exist"),
        ));
    }
    let values = if m.rows == 1 && m.cols == len {
        m.data.clone()
    } else {
        (0..rows).map(|r| m.data[r * cols + column]).collect()
    };
    let name = if cols > 1 { format!("{} column {column}", stem(path)) } else { stem(path) };
    Ok((name, values))
}

/// The soft maps T δ_i a match directory holds: (i, values) for every soft_<i>.npy (m values).
fn soft_fields(dir: &Path, m: usize) -> Result<Vec<(usize, Vec<f64>)>> {
    let mut out = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries {
        let p = entry.map_err(|e| Error::io(dir, e))?.path();
        let name = p.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        let Some(i) =
            name.strip_prefix("soft_").and_then(|s| s.strip_suffix(".npy")).and_then(|s| s.parse::<usize>().ok())
        else {
            continue;
        };
        let mat = funcorr::io::npy::read_npy_matrix(&p)?;
        if mat.data.len() != m {
            return Err(Error::parse(&p, None, format!("{} values, but Y has {m} vertices", mat.data.len())));
        }
        out.push((i, mat.data));
    }
    out.sort_by_key(|f| f.0);
    Ok(out)
}

/// The name of a soft-map field of vertex i.
pub(crate) fn soft_name(i: usize) -> String {
    format!("soft map T δ_{i} on Y")
}

/// Per-vertex errors of `map_xy` against ground truth, for the heat map.
pub(crate) fn vertex_errors(
    x: &ViewShape,
    y: &ViewShape,
    y_path: &Path,
    map_xy: &[usize],
    gt: &funcorr::eval::GroundTruth,
    geodesics: GeodesicsChoice,
    error_max: f64,
) -> Result<VertexErrors> {
    let method = funcorr::geodesic::GeodesicMethod::from(geodesics);
    let surface = target_surface(&y.shape, y_path, method)?;
    let (geo, area, description) = target_distances(&y.shape, surface.as_ref(), method)?;
    let errors = funcorr::eval::hard_errors(map_xy, gt, &*geo, area)?;
    let mut ve = VertexErrors::spread(&x.vertices, gt, &errors, description)?;
    ve.max = error_max;
    Ok(ve)
}

pub(crate) fn view(args: &ViewArgs) -> Result<()> {
    if !(args.error_max.is_finite() && args.error_max > 0.0) {
        return Err(Error::invalid("--error-max", format!("{} must be a positive number", args.error_max)));
    }
    let dir = match args.inputs.as_slice() {
        [d] if d.is_dir() => Some(d.clone()),
        [p] => {
            return Err(Error::invalid(
                "view",
                format!("{} is not a match directory: give a directory written by `funcorr match -o`, or two shapes X Y with --map", p.display()),
            ))
        }
        _ => None,
    };
    // The shapes: a match directory's X.ply and Y.ply (else the paths in its report.json).
    let report: Option<serde_json::Value> = match &dir {
        Some(d) if d.join("report.json").is_file() => {
            let p = d.join("report.json");
            let text = std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))?;
            Some(serde_json::from_str(&text).map_err(|e| Error::parse(&p, None, e.to_string()))?)
        }
        _ => None,
    };
    let (x_path, y_path) = match (&dir, args.inputs.as_slice()) {
        (Some(d), _) => {
            let pick = |ply: &str, key: &str| -> Result<PathBuf> {
                let p = d.join(ply);
                if p.is_file() {
                    return Ok(p);
                }
                match report.as_ref().and_then(|r| r[key].as_str()) {
                    Some(s) => Ok(PathBuf::from(s)),
                    None => Err(Error::invalid(
                        "view",
                        format!("{} has neither {ply} nor a report.json naming the shape", d.display()),
                    )),
                }
            };
            (pick("X.ply", "x")?, pick("Y.ply", "y")?)
        }
        (None, [x, y]) => (x.clone(), y.clone()),
        _ => unreachable!("one or two inputs"),
    };
    let x = ViewShape::load(&x_path)?;
    let y = ViewShape::load(&y_path)?;
    let (n, m) = (x.vertices.len(), y.vertices.len());
    let map_path = match (&args.map, &dir) {
        (Some(p), _) => p.clone(),
        (None, Some(d)) if d.join("map.npy").is_file() => d.join("map.npy"),
        (None, Some(d)) => d.join("map.txt"),
        (None, None) => return Err(Error::invalid("--map", "give the map X → Y (map.txt) of the two shapes")),
    };
    let map_xy = read_map(&map_path, args.one_based, n, m, "X")?;
    let map_yx_path = match (&args.map_yx, &dir) {
        (Some(p), _) => Some(p.clone()),
        (None, Some(d)) if d.join("map_yx.npy").is_file() => Some(d.join("map_yx.npy")),
        _ => None,
    };
    let map_yx = map_yx_path.as_ref().map(|p| read_map(p, args.one_based, m, n, "Y")).transpose()?;
    let errors = match (&args.gt_source, &args.gt_target) {
        (Some(s), Some(t)) => {
            let gt = read_ground_truth(s, t, args.gt_target_sym.as_deref(), n, m)?;
            Some(vertex_errors(&x, &y, &y_path, &map_xy, &gt, args.geodesics, args.error_max)?)
        }
        _ => None,
    };
    let mut field_data: Vec<(String, Side, Vec<f64>, Option<usize>)> = Vec::new();
    if let Some(d) = &dir {
        for (i, values) in soft_fields(d, m)? {
            if i < n {
                field_data.push((soft_name(i), Side::Y, values, Some(i)));
            }
        }
    }
    for spec in &args.field_x {
        let (name, values) = read_field(spec, n, "--field-x", Side::X)?;
        field_data.push((format!("{name} on X"), Side::X, values, None));
    }
    for spec in &args.field_y {
        let (name, values) = read_field(spec, m, "--field-y", Side::Y)?;
        field_data.push((format!("{name} on Y"), Side::Y, values, None));
    }
    let (xn, yn) = match &report {
        Some(r) => (
            r["x"].as_str().map(|s| stem(Path::new(s))).unwrap_or_else(|| "X".into()),
            r["y"].as_str().map(|s| stem(Path::new(s))).unwrap_or_else(|| "Y".into()),
        ),
        None => (stem(&x_path), stem(&y_path)),
    };
    let method = report.as_ref().map(|r| {
        format!("method {}, data {}", r["options"]["method"].as_str().unwrap_or("?"), r["data"].as_str().unwrap_or("?"))
    });
    let mut page = Viewer::new(
        args.title.clone().unwrap_or_else(|| format!("{xn} → {yn}")),
        // A match directory's Y.ply carries the colours through map_yx: used when map_yx is not
        // there to recompute them.
        x.viewer(false),
    );
    page.x_name = xn;
    page.y = Some(y.viewer(map_yx.is_none() && dir.is_some() && args.map.is_none()));
    page.y_name = yn;
    page.map_xy = Some(&map_xy);
    page.map_yx = map_yx.as_deref();
    page.method = method;
    page.errors = errors;
    page.fields = field_data
        .iter()
        .map(|(name, side, values, mark)| Field { name: name.clone(), side: *side, values, mark: *mark })
        .collect();
    let out = match (&args.output, &dir) {
        (Some(o), _) => o.clone(),
        (None, Some(d)) => d.join("view.html"),
        (None, None) => PathBuf::from("view.html"),
    };
    let html = page.html()?;
    funcorr::io::write_atomic(&out, &html)?;
    outln!("wrote {} ({:.1} MB): open it in a browser", out.display(), html.len() as f64 / 1e6);
    Ok(())
}

/// The `view.html` of a match (`match`, `demo`): X and Y with the maps of the run, its soft maps
/// and (demo) errors. Shapes that are not 3-D (feature matrices) get no page.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_match_view(
    out: &Path,
    (x, x_name): (&Shape, &str),
    (y, y_name): (&Shape, &str),
    map_xy: &[usize],
    map_yx: &[usize],
    method: String,
    soft: &[(usize, Vec<f64>)],
    errors: Option<VertexErrors>,
) -> Result<()> {
    let (Some(dx), Some(dy)) = (mesh_data(x), mesh_data(y)) else {
        return Ok(());
    };
    let mut page = Viewer::new(
        format!("{x_name} → {y_name}"),
        ViewerShape { vertices: &dx.vertices, faces: &dx.faces, colors: None },
    );
    page.x_name = x_name.to_string();
    page.y = Some(ViewerShape { vertices: &dy.vertices, faces: &dy.faces, colors: None });
    page.y_name = y_name.to_string();
    page.map_xy = Some(map_xy);
    page.map_yx = Some(map_yx);
    page.method = Some(method);
    page.errors = errors;
    page.fields =
        soft.iter().map(|(i, t)| Field { name: soft_name(*i), side: Side::Y, values: t, mark: Some(*i) }).collect();
    page.write(&out.join("view.html"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("funcorr-view-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn maps_that_do_not_fit_are_errors_naming_the_file() {
        let d = tmp("maps");
        let p = d.join("map.txt");
        std::fs::write(&p, "0\n1\n2\n").unwrap();
        assert_eq!(read_map(&p, false, 3, 5, "X").unwrap(), vec![0, 1, 2]);
        let e = read_map(&p, false, 4, 5, "X").unwrap_err().to_string();
        assert!(e.contains("map.txt") && e.contains("expected 4 entries") && e.contains("found 3"), "{e}");
        let e = read_map(&p, false, 3, 2, "X").unwrap_err().to_string();
        assert!(e.contains("map.txt"), "{e}");
        assert!(read_map(&p, true, 3, 5, "X").is_err(), "0 in a 1-based file");
        let npy = d.join("map.npy");
        funcorr::io::npy::write_npy_vec_u64(&npy, &[4, 0, 1]).unwrap();
        assert_eq!(read_map(&npy, false, 3, 5, "X").unwrap(), vec![4, 0, 1]);
        let e = read_map(&npy, false, 3, 4, "X").unwrap_err().to_string();
        assert!(e.contains("map.npy") && e.contains("entry 0 is 4"), "{e}");
        let f = d.join("F.npy");
        funcorr::io::npy::write_npy_matrix(
            &f,
            &funcorr::io::DenseMatrix { rows: 3, cols: 2, data: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0] },
        )
        .unwrap();
        let spec = format!("{}:1", f.display());
        let (name, values) = read_field(&spec, 3, "--field-x", Side::X).unwrap();
        assert_eq!((name.as_str(), values), ("F column 1", vec![2.0, 4.0, 6.0]));
        assert_eq!(read_field(&f.display().to_string(), 3, "--field-x", Side::X).unwrap().1, vec![1.0, 3.0, 5.0]);
        assert!(read_field(&format!("{}:2", f.display()), 3, "--field-x", Side::X)
            .unwrap_err()
            .to_string()
            .contains("column 2"));
        assert!(read_field(&spec, 4, "--field-x", Side::X).unwrap_err().to_string().contains("3 rows"));
        std::fs::remove_dir_all(&d).ok();
    }
}
