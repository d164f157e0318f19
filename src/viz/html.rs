//! The interactive viewer of a correspondence: one self-contained HTML page that shows X and Y
//! side by side in linked cameras (three.js, vendored under `assets/three/` and inlined), coloured
//! by colour transfer (the colours of `X.ply`/`Y.ply`), by the per-vertex error on X when the
//! ground truth is known, or by a scalar field (a soft map T δ_i, a descriptor channel). Clicking
//! a vertex marks it and its image; hovering shows the vertex id and its error.
//!
//! The page opens from disk in any current browser and fetches nothing: the shapes, maps and
//! values are embedded as base64 typed arrays (positions `float32`, faces and maps `uint32`,
//! colours `uint8`, values `float32`; little-endian), so a pair of 10⁶-vertex meshes costs no
//! JSON parsing. Colours are computed here, with the functions of [`crate::viz`], so the page
//! shows exactly the colours of the PLY files and the PNG render; the page's script only draws.
//!
//! The page's script (`assets/viewer/viewer.js`) exposes `window.funcorr` for tests and scripts:
//! `ready` (a promise, resolved after the first frame), `pick(i, side)`, `set({...})`,
//! `view(azimuth, elevation)`, `project(i, side)`, `errorAt(i)`, `bar(mode)`, `timeFrames(k)`,
//! `snapshot()`.
//!
//! **Why one file (≈ 600 lines without tests).** The page's data (shapes, maps, colourings,
//! errors, fields) is checked, encoded and described to the script in one pass over private
//! helpers (blob list, metadata, base64); splitting it would spread one format over two files.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Error, Result};
use crate::eval::{GroundTruth, Summary};
use crate::viz::{diverging_colors, heat_color, heat_colors, position_colors, pull_back_colors};

/// three.js r146, minified UMD build (MIT; `assets/three/README.md` says where it came from).
pub const THREE_JS: &str = include_str!("../../assets/three/three.min.js");
/// three.js r146's `examples/js/controls/OrbitControls.js` (MIT).
pub const ORBIT_CONTROLS_JS: &str = include_str!("../../assets/three/OrbitControls.js");
/// The licence of three.js (MIT).
pub const THREE_LICENSE: &str = include_str!("../../assets/three/LICENSE");
/// The viewer's own script (draws, picks, hooks; reads the embedded data).
pub const VIEWER_JS: &str = include_str!("../../assets/viewer/viewer.js");
/// The viewer's style sheet.
pub const VIEWER_CSS: &str = include_str!("../../assets/viewer/viewer.css");

/// Top of the error colour bar by default: errors ≥ 0.25 (× √area(Y)) get the darkest colour,
/// the end of the cumulative curves of the literature.
pub const DEFAULT_ERROR_MAX: f64 = 0.25;

/// Colour of a shape that a colouring leaves uncoloured (e.g. X while a soft map on Y is shown).
const NEUTRAL: [u8; 3] = [200, 200, 200];

/// One shape of a viewer page: n vertices (3-D), its triangles (empty: a point cloud, drawn as
/// points) and optionally its own colours (n; default: by position for X, through the map for Y).
#[derive(Debug, Clone, Copy)]
pub struct ViewerShape<'a> {
    /// Vertex positions (n × 3).
    pub vertices: &'a [[f64; 3]],
    /// Triangles (f × 3, 0-based, each index < n); empty for a point cloud.
    pub faces: &'a [[u32; 3]],
    /// sRGB colour per vertex (n × 3) of the base colouring, or None for the default.
    pub colors: Option<&'a [[u8; 3]]>,
}

/// Which shape a value or a vertex belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The source X (n vertices).
    X,
    /// The target Y (m vertices).
    Y,
}

impl Side {
    fn key(self) -> &'static str {
        match self {
            Side::X => "x",
            Side::Y => "y",
        }
    }
}

/// A scalar function on one shape (one value per vertex), shown through the blue–white–red map
/// of [`crate::viz::diverging_colors`]: a soft map T δ_i on Y, a descriptor channel, …
#[derive(Debug, Clone)]
pub struct Field<'a> {
    /// Name in the page's colouring menu (e.g. `soft map T δ_100`).
    pub name: String,
    /// The shape it lives on.
    pub side: Side,
    /// One value per vertex of that shape (n or m); NaN shows grey.
    pub values: &'a [f64],
    /// A vertex of the other shape to mark while the field is shown (i of T δ_i), if any.
    pub mark: Option<usize>,
}

/// Geodesic errors of a map at every vertex of X, for the heat map: the errors of the template
/// points (the Princeton protocol's hard errors, [`crate::eval::hard_errors`]) spread to the
/// other vertices from the nearest template point.
#[derive(Debug, Clone, PartialEq)]
pub struct VertexErrors {
    /// Error per vertex of X (n), in units of √area(Y).
    pub values: Vec<f64>,
    /// Whether vertex i is a template point (its own error; else the nearest template point's).
    pub measured: Vec<bool>,
    /// Summary of the template points' errors (mean, fractions ≤ 0.05, 0.10, 0.25).
    pub summary: Summary,
    /// Number of template points.
    pub points: usize,
    /// Whether symmetric flips were allowed.
    pub symmetric: bool,
    /// How the geodesic distances were computed (for the page's caption).
    pub geodesics: String,
    /// Top of the colour bar ([`DEFAULT_ERROR_MAX`] by default).
    pub max: f64,
}

impl VertexErrors {
    /// Spreads the template errors `errors` (one per template point: `gt.x.len()`, as returned by
    /// [`crate::eval::hard_errors`]) to every vertex of X (`x_vertices`, n × 3): a template vertex
    /// gets the mean error of its template points, any other vertex that of the nearest template
    /// vertex (Euclidean, in X).
    ///
    /// Errors: `Invalid` naming `errors` when the lengths differ, or `ground truth` when a
    /// template vertex is not a vertex of X or there are no template points.
    pub fn spread(
        x_vertices: &[[f64; 3]],
        gt: &GroundTruth,
        errors: &[f64],
        geodesics: impl Into<String>,
    ) -> Result<VertexErrors> {
        let n = x_vertices.len();
        if errors.len() != gt.x.len() {
            return Err(Error::invalid(
                "errors",
                format!("{} errors for {} template points (one per template point)", errors.len(), gt.x.len()),
            ));
        }
        if gt.x.is_empty() {
            return Err(Error::invalid("ground truth", "no template points"));
        }
        if let Some(&bad) = gt.x.iter().find(|&&i| i >= n) {
            return Err(Error::invalid(
                "ground truth",
                format!("template vertex {bad} is not a vertex of X (n = {n})"),
            ));
        }
        let mut sum = vec![0.0; n];
        let mut count = vec![0u32; n];
        for (&i, &e) in gt.x.iter().zip(errors) {
            sum[i] += e;
            count[i] += 1;
        }
        let template: Vec<usize> = (0..n).filter(|&i| count[i] > 0).collect();
        let own: Vec<f64> = template.iter().map(|&i| sum[i] / f64::from(count[i])).collect();
        let points: Vec<[f64; 3]> = template.iter().map(|&i| x_vertices[i]).collect();
        let nearest = crate::spatial::nearest3(&points, x_vertices);
        let values =
            (0..n).map(|i| if count[i] > 0 { sum[i] / f64::from(count[i]) } else { own[nearest[i]] }).collect();
        Ok(VertexErrors {
            values,
            measured: count.iter().map(|&c| c > 0).collect(),
            summary: crate::eval::summarize(errors),
            points: errors.len(),
            symmetric: gt.y_sym.is_some(),
            geodesics: geodesics.into(),
            max: DEFAULT_ERROR_MAX,
        })
    }
}

/// A map Y → X inferred from `map_xy` (n, vertices of Y) when only that direction is known: for
/// every vertex of Y (`y_vertices`, m × 3), the vertex of X whose image is nearest (Euclidean, in
/// Y). It is the inverse of `map_xy` where `map_xy` is a bijection. Returns m vertices of X.
///
/// Errors: `Invalid` naming `map_xy` when it is empty or points outside Y.
pub fn inverse_by_nearest(map_xy: &[usize], y_vertices: &[[f64; 3]]) -> Result<Vec<usize>> {
    let m = y_vertices.len();
    if map_xy.is_empty() {
        return Err(Error::invalid("map_xy", "the map is empty"));
    }
    if let Some(&bad) = map_xy.iter().find(|&&j| j >= m) {
        return Err(Error::invalid("map_xy", format!("vertex {bad} is not a vertex of Y (m = {m})")));
    }
    // One source per image vertex (the first), so that the tree holds distinct vertices.
    let mut source = vec![usize::MAX; m];
    for (i, &j) in map_xy.iter().enumerate() {
        if source[j] == usize::MAX {
            source[j] = i;
        }
    }
    let images: Vec<usize> = (0..m).filter(|&j| source[j] != usize::MAX).collect();
    let points: Vec<[f64; 3]> = images.iter().map(|&j| y_vertices[j]).collect();
    Ok(crate::spatial::nearest3(&points, y_vertices).into_iter().map(|k| source[images[k]]).collect())
}

/// Where the page's scripts come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scripts<'a> {
    /// Inlined: the page is self-contained (≈ 0.7 MB of script per page).
    Inline,
    /// `<script src>` files written once by [`write_scripts`] into a directory, at this relative
    /// URL prefix from the page (e.g. `"../viewer/"`): for the many pages of a data set report.
    Beside(&'a str),
}

/// The script files of [`Scripts::Beside`], written into `dir` (created): `three.min.js`,
/// `OrbitControls.js`, `viewer.js` and `THREE-LICENSE.txt`. Returns the paths written.
pub fn write_scripts(dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let files = [
        ("three.min.js", THREE_JS),
        ("OrbitControls.js", ORBIT_CONTROLS_JS),
        ("viewer.js", VIEWER_JS),
        ("THREE-LICENSE.txt", THREE_LICENSE),
    ];
    files
        .iter()
        .map(|(name, text)| {
            let p = dir.join(name);
            crate::io::write_atomic(&p, text)?;
            Ok(p)
        })
        .collect()
}

/// A viewer page: one or two shapes, the maps between them and what to colour them by.
#[derive(Debug, Clone)]
pub struct Viewer<'a> {
    /// Title of the page (e.g. `tr_reg_000 → tr_reg_001`).
    pub title: String,
    /// The source X (n vertices).
    pub x: ViewerShape<'a>,
    /// Name of X shown above it (e.g. its file name).
    pub x_name: String,
    /// The target Y (m vertices), or None to show X alone.
    pub y: Option<ViewerShape<'a>>,
    /// Name of Y shown above it.
    pub y_name: String,
    /// The map X → Y (n, vertices of Y): clicking vertex i of X marks `map_xy[i]` on Y.
    pub map_xy: Option<&'a [usize]>,
    /// The map Y → X (m, vertices of X): the colours of Y (as `Y.ply`) and the clicks on Y.
    /// When None but `map_xy` is given, [`inverse_by_nearest`] stands in for the colours.
    pub map_yx: Option<&'a [usize]>,
    /// How the map was made (method and data), for the caption.
    pub method: Option<String>,
    /// Per-vertex errors on X (heat map), when the ground truth is known.
    pub errors: Option<VertexErrors>,
    /// Scalar fields offered as colourings.
    pub fields: Vec<Field<'a>>,
    /// More lines for the caption.
    pub notes: Vec<String>,
    /// The colouring shown first: `"error"` or the name of a field (default: colour transfer).
    pub start: Option<String>,
}

impl<'a> Viewer<'a> {
    /// A page showing X alone, coloured by position; set the other fields to add Y, maps, errors.
    pub fn new(title: impl Into<String>, x: ViewerShape<'a>) -> Viewer<'a> {
        Viewer {
            title: title.into(),
            x,
            x_name: "X".into(),
            y: None,
            y_name: "Y".into(),
            map_xy: None,
            map_yx: None,
            method: None,
            errors: None,
            fields: Vec::new(),
            notes: Vec::new(),
            start: None,
        }
    }

    /// Checks every length and index against the shapes. Errors: `Invalid` naming the input.
    fn check(&self) -> Result<()> {
        check_shape(&self.x, "X")?;
        let n = self.x.vertices.len();
        let m = match &self.y {
            Some(y) => {
                check_shape(y, "Y")?;
                Some(y.vertices.len())
            }
            None => None,
        };
        let need_y = |what: &str| Error::invalid(what, "needs the target shape Y");
        if let Some(map) = self.map_xy {
            let m = m.ok_or_else(|| need_y("map_xy"))?;
            check_map(map, n, m, "map_xy", "X", "Y")?;
        }
        if let Some(map) = self.map_yx {
            let m = m.ok_or_else(|| need_y("map_yx"))?;
            check_map(map, m, n, "map_yx", "Y", "X")?;
        }
        if let Some(start) = &self.start {
            let known = (start == "error" && self.errors.is_some()) || self.fields.iter().any(|f| &f.name == start);
            if !known {
                return Err(Error::invalid("start", format!("{start:?} is neither `error` (with errors) nor a field")));
            }
        }
        if let Some(e) = &self.errors {
            if e.values.len() != n || e.measured.len() != n {
                return Err(Error::invalid(
                    "errors",
                    format!("{} per-vertex errors, but X has n = {n} vertices", e.values.len()),
                ));
            }
            if !(e.max.is_finite() && e.max > 0.0) {
                return Err(Error::invalid("errors", format!("top of the colour bar {} must be positive", e.max)));
            }
        }
        for f in &self.fields {
            let len = match f.side {
                Side::X => n,
                Side::Y => m.ok_or_else(|| need_y(&f.name))?,
            };
            if f.values.len() != len {
                return Err(Error::invalid(
                    &f.name,
                    format!(
                        "{} values, but {} has {len} vertices (one value per vertex)",
                        f.values.len(),
                        f.side.key().to_uppercase()
                    ),
                ));
            }
            let other = match f.side {
                Side::X => m,
                Side::Y => Some(n),
            };
            if let (Some(i), Some(len)) = (f.mark, other) {
                if i >= len {
                    return Err(Error::invalid(&f.name, format!("marked vertex {i} does not exist ({len} vertices)")));
                }
            }
        }
        Ok(())
    }

    /// The page with inlined scripts: a self-contained HTML document.
    ///
    /// Errors: `Invalid` naming the input when a map, field, colour list or error list does not
    /// fit the shapes (lengths, indices), or a shape is empty.
    pub fn html(&self) -> Result<String> {
        self.html_with(Scripts::Inline)
    }

    /// The page, with its scripts inlined or referenced ([`Scripts`]). Errors: as [`Viewer::html`].
    pub fn html_with(&self, scripts: Scripts) -> Result<String> {
        self.check()?;
        let mut blobs: Vec<Vec<u8>> = Vec::new();
        let mut add = |bytes: Vec<u8>| -> usize {
            blobs.push(bytes);
            blobs.len() - 1
        };
        let colors_x = match self.x.colors {
            Some(c) => c.to_vec(),
            None => position_colors(self.x.vertices),
        };
        let colors_y = match (&self.y, self.map_yx, self.map_xy) {
            (Some(y), _, _) if y.colors.is_some() => y.colors.map(<[_]>::to_vec),
            (Some(_), Some(map), _) => pull_back_colors(&colors_x, map),
            (Some(y), None, Some(map)) => pull_back_colors(&colors_x, &inverse_by_nearest(map, y.vertices)?),
            (Some(y), None, None) => Some(position_colors(y.vertices)),
            (None, _, _) => None,
        };
        let mut shape_meta = |s: &ViewerShape, name: &str| -> Value {
            let positions: Vec<u8> =
                s.vertices.iter().flat_map(|p| p.iter().flat_map(|&c| (c as f32).to_le_bytes())).collect();
            let faces: Vec<u8> = s.faces.iter().flat_map(|f| f.iter().flat_map(|&i| i.to_le_bytes())).collect();
            json!({
                "name": name,
                "n": s.vertices.len(),
                "faces": s.faces.len(),
                "positions": add(positions),
                "triangles": if s.faces.is_empty() { Value::Null } else { json!(add(faces)) },
            })
        };
        let x_meta = shape_meta(&self.x, &self.x_name);
        let y_meta = self.y.as_ref().map(|y| shape_meta(y, &self.y_name));
        let rgb = |c: &[[u8; 3]]| -> Vec<u8> { c.iter().flatten().copied().collect() };
        let u32s = |v: &[usize]| -> Vec<u8> { v.iter().flat_map(|&i| (i as u32).to_le_bytes()).collect() };
        let f32s = |v: &[f64]| -> Vec<u8> { v.iter().flat_map(|&x| (x as f32).to_le_bytes()).collect() };
        let mut modes = vec![json!({
            "id": "transfer",
            "label": if self.y.is_some() { "colour transfer" } else { "colours" },
            "x": add(rgb(&colors_x)),
            "y": colors_y.as_deref().map(|c| add(rgb(c))),
        })];
        let mut bars = serde_json::Map::new();
        let mut errors_meta = Value::Null;
        if let Some(e) = &self.errors {
            let steps = 64;
            let lut: Vec<[u8; 3]> = (0..=steps).map(|k| heat_color(e.max * k as f64 / steps as f64, e.max)).collect();
            bars.insert(
                "error".into(),
                json!({
                    "min": 0.0, "max": e.max, "colors": lut,
                    "label": "geodesic error / √area(Y)",
                    "ticks": ticks(0.0, e.max),
                    "over": true,
                }),
            );
            modes.push(json!({
                "id": "error",
                "label": "error on X",
                "x": add(rgb(&heat_colors(&e.values, e.max))),
                "y": Value::Null,
                "bar": "error",
            }));
            errors_meta = json!({
                "values": add(f32s(&e.values)),
                "measured": add(e.measured.iter().map(|&b| u8::from(b)).collect()),
                "mean": e.summary.mean,
                "at_005": e.summary.at_005,
                "at_010": e.summary.at_010,
                "at_025": e.summary.at_025,
                "points": e.points,
                "symmetric": e.symmetric,
                "geodesics": e.geodesics,
                "max": e.max,
            });
        }
        let mut fields_meta = Vec::new();
        for (k, f) in self.fields.iter().enumerate() {
            let absmax = f.values.iter().filter(|v| v.is_finite()).fold(0.0f64, |a, v| a.max(v.abs()));
            let colors = diverging_colors(f.values);
            let id = format!("field{k}");
            let lut: Vec<[u8; 3]> = diverging_colors(&(-32..=32).map(f64::from).collect::<Vec<_>>());
            let bar = format!("field{k}");
            bars.insert(
                bar.clone(),
                json!({
                    "min": -absmax, "max": absmax, "colors": lut, "label": f.name,
                    "ticks": [-absmax, 0.0, absmax], "over": false,
                }),
            );
            let blob = add(rgb(&colors));
            modes.push(json!({
                "id": id,
                "label": f.name,
                "x": if f.side == Side::X { json!(blob) } else { Value::Null },
                "y": if f.side == Side::Y { json!(blob) } else { Value::Null },
                "bar": bar,
                "mark": f.mark.map(|i| json!({"side": if f.side == Side::X { "y" } else { "x" }, "vertex": i})),
            }));
            fields_meta.push(json!({"id": id, "side": f.side.key(), "values": add(f32s(f.values)), "absmax": absmax}));
        }
        let start = match self.start.as_deref() {
            Some("error") => "error".to_string(),
            Some(name) => format!("field{}", self.fields.iter().position(|f| f.name == name).unwrap_or(0)),
            None => "transfer".to_string(),
        };
        let meta = json!({
            "title": self.title,
            "start": start,
            "method": self.method,
            "x": x_meta,
            "y": y_meta,
            "map_xy": self.map_xy.map(|m| add(u32s(m))),
            "map_yx": self.map_yx.map(|m| add(u32s(m))),
            "map_yx_inferred": self.y.is_some() && self.map_yx.is_none() && self.map_xy.is_some(),
            "modes": modes,
            "bars": bars,
            "errors": errors_meta,
            "fields": fields_meta,
            "neutral": NEUTRAL,
            "notes": self.notes,
            "generator": concat!("funcorr ", env!("CARGO_PKG_VERSION")),
        });
        Ok(page(&self.title, &meta, &blobs, scripts))
    }

    /// Writes [`Viewer::html`] to `path` atomically. Errors: those of [`Viewer::html`], or `Io`
    /// naming `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, self.html()?)
    }
}

fn check_shape(s: &ViewerShape, name: &str) -> Result<()> {
    let n = s.vertices.len();
    if n == 0 {
        return Err(Error::invalid(name, "the shape has no vertices"));
    }
    if n > u32::MAX as usize {
        return Err(Error::invalid(name, format!("{n} vertices: at most 2³² − 1 can be shown")));
    }
    if let Some((k, p)) = s.vertices.iter().enumerate().find(|(_, p)| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::invalid(name, format!("vertex {k} has a coordinate that is not finite: {p:?}")));
    }
    if let Some((k, f)) = s.faces.iter().enumerate().find(|(_, f)| f.iter().any(|&i| i as usize >= n)) {
        return Err(Error::invalid(name, format!("face {k} {f:?} has a vertex index out of range [0, {n})")));
    }
    if let Some(c) = s.colors {
        if c.len() != n {
            return Err(Error::invalid(name, format!("{} colours for {n} vertices (one per vertex)", c.len())));
        }
    }
    Ok(())
}

fn check_map(map: &[usize], len: usize, targets: usize, what: &str, from: &str, to: &str) -> Result<()> {
    if map.len() != len {
        return Err(Error::invalid(
            what,
            format!("{} entries, but {from} has {len} vertices (one vertex of {to} per vertex of {from})", map.len()),
        ));
    }
    if let Some((i, &j)) = map.iter().enumerate().find(|(_, &j)| j >= targets) {
        return Err(Error::invalid(what, format!("entry {i} is {j}, not a vertex of {to} (it has {targets})")));
    }
    Ok(())
}

/// Tick values of a colour bar from `lo` to `hi`: 0.05 steps for the error scale's default.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step =
        [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0].into_iter().find(|s| (hi - lo) / s <= 6.0).unwrap_or(hi - lo);
    let mut t = Vec::new();
    let mut k = (lo / step).ceil();
    while k * step <= hi + 1e-12 {
        t.push((k * step * 1e9).round() / 1e9);
        k += 1.0;
    }
    t
}

/// Escapes text for HTML element content and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// JSON safe inside a `<script>` element: `<` written as `\u003c` (so no `</script>` and no
/// `<!--` can end or confuse the element).
pub(crate) fn script_json(v: &Value) -> String {
    v.to_string().replace('<', "\\u003c")
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Appends the standard base64 (RFC 4648, with padding) of `bytes` to `out`.
pub(crate) fn base64_into(bytes: &[u8], out: &mut String) {
    out.reserve(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let v = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(B64[((v >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
}

/// The HTML document: skeleton, metadata, data blobs, scripts.
fn page(title: &str, meta: &Value, blobs: &[Vec<u8>], scripts: Scripts) -> String {
    let data: usize = blobs.iter().map(|b| b.len().div_ceil(3) * 4 + 80).sum();
    let mut s = String::with_capacity(data + 16_384 + if scripts == Scripts::Inline { 700_000 } else { 0 });
    let title = escape(title);
    s += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
    s += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
    s += &format!("<meta name=\"generator\" content=\"{}\">\n", concat!("funcorr ", env!("CARGO_PKG_VERSION")));
    s += &format!("<title>{title}</title>\n<style>\n{VIEWER_CSS}</style>\n</head>\n<body>\n");
    s += &format!(
        "<header id=\"bar\"><h1 id=\"title\">{title}</h1><span id=\"caption\"></span></header>\n\
         <nav id=\"controls\"></nav>\n\
         <main id=\"stage\"><canvas id=\"view\" tabindex=\"0\"></canvas><div id=\"labels\"></div>\
         <div id=\"tip\" hidden></div><div id=\"colorbar\" hidden></div>\
         <div id=\"loading\">loading the shapes…</div></main>\n\
         <footer id=\"status\">click a vertex of X to see its image on Y{}; drag to orbit, wheel to zoom, \
         right-drag to pan</footer>\n",
        if meta["map_yx"].is_null() { "" } else { " (and a vertex of Y for its image on X)" }
    );
    s += "<script type=\"application/json\" id=\"funcorr-meta\">";
    s += &script_json(meta);
    s += "</script>\n";
    for (k, b) in blobs.iter().enumerate() {
        s += &format!("<script type=\"application/octet-stream\" id=\"funcorr-b{k}\">");
        base64_into(b, &mut s);
        s += "</script>\n";
    }
    match scripts {
        Scripts::Inline => {
            for js in [THREE_JS, ORBIT_CONTROLS_JS, VIEWER_JS] {
                s += "<script>\n";
                s += js;
                s += "\n</script>\n";
            }
        }
        Scripts::Beside(prefix) => {
            let prefix = escape(prefix);
            for name in ["three.min.js", "OrbitControls.js", "viewer.js"] {
                s += &format!("<script src=\"{prefix}{name}\"></script>\n");
            }
        }
    }
    s += "</body>\n</html>\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b64(bytes: &[u8]) -> String {
        let mut s = String::new();
        base64_into(bytes, &mut s);
        s
    }

    #[test]
    fn base64_is_rfc_4648() {
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(b64(input.as_bytes()), want);
        }
        assert_eq!(b64(&[0xff, 0xfe, 0xfd]), "//79");
    }

    #[test]
    fn scripts_cannot_be_closed_by_data() {
        let v = json!({"name": "</script><script>alert(1)</script>"});
        let s = script_json(&v);
        assert!(!s.contains('<'));
        assert_eq!(serde_json::from_str::<Value>(&s).unwrap(), v);
        assert_eq!(escape("a<b>&\"'"), "a&lt;b&gt;&amp;&quot;&#39;");
        for js in [THREE_JS, ORBIT_CONTROLS_JS, VIEWER_JS] {
            assert!(!js.to_ascii_lowercase().contains("</script") && !js.contains("<!--"));
        }
    }

    fn tet() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        (
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    /// The embedded blob `k` of a page, decoded.
    fn blob(html: &str, k: usize) -> Vec<u8> {
        let tag = format!("id=\"funcorr-b{k}\">");
        let start = html.find(&tag).unwrap() + tag.len();
        let text = &html[start..start + html[start..].find('<').unwrap()];
        let val = |c: u8| B64.iter().position(|&b| b == c).unwrap() as u32;
        let mut out = Vec::new();
        for q in text.as_bytes().chunks(4) {
            let pad = q.iter().filter(|&&c| c == b'=').count();
            let v = q.iter().take(4 - pad).enumerate().fold(0u32, |a, (i, &c)| a | (val(c) << (18 - 6 * i)));
            out.extend_from_slice(&v.to_be_bytes()[1..4 - pad]);
        }
        out
    }

    fn meta(html: &str) -> Value {
        let start = html.find("id=\"funcorr-meta\">").unwrap() + 18;
        serde_json::from_str(&html[start..start + html[start..].find("</script>").unwrap()]).unwrap()
    }

    #[test]
    fn a_page_embeds_the_pair_as_typed_arrays() {
        let (v, f) = tet();
        let w: Vec<[f64; 3]> = v.iter().map(|p| [p[0] + 5.0, p[1], p[2]]).collect();
        let map_xy = [1, 0, 3, 2];
        let map_yx = [1, 0, 2, 2];
        let mut page = Viewer::new("a <pair>", ViewerShape { vertices: &v, faces: &f, colors: None });
        page.y = Some(ViewerShape { vertices: &w, faces: &[], colors: None });
        page.map_xy = Some(&map_xy);
        page.map_yx = Some(&map_yx);
        let soft = [0.5, -1.0, 0.0, 0.25];
        page.fields.push(Field { name: "soft map T δ_2".into(), side: Side::Y, values: &soft, mark: Some(2) });
        let gt = GroundTruth { x: vec![0, 1, 1], y: vec![0, 1, 2], y_sym: None };
        page.errors = Some(VertexErrors::spread(&v, &gt, &[0.1, 0.2, 0.4], "exact").unwrap());
        let html = page.html().unwrap();
        assert!(html.starts_with("<!DOCTYPE html>") && html.contains("<title>a &lt;pair&gt;</title>"));
        assert!(html.contains("REVISION") || html.contains("\"146\""), "three.js inlined");
        assert_eq!(html.matches("<script src=").count(), 0);
        let m = meta(&html);
        assert_eq!(
            (m["x"]["n"].as_u64(), m["x"]["faces"].as_u64(), m["y"]["faces"].as_u64()),
            (Some(4), Some(4), Some(0))
        );
        assert!(m["y"]["triangles"].is_null(), "Y is a point cloud");
        let pos = blob(&html, m["x"]["positions"].as_u64().unwrap() as usize);
        let floats: Vec<f32> = pos.chunks(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        assert_eq!(floats, v.iter().flatten().map(|&c| c as f32).collect::<Vec<_>>());
        let tri = blob(&html, m["x"]["triangles"].as_u64().unwrap() as usize);
        assert_eq!(tri.len(), 4 * 12);
        assert_eq!(u32::from_le_bytes(tri[4..8].try_into().unwrap()), 2);
        let mx = blob(&html, m["map_xy"].as_u64().unwrap() as usize);
        assert_eq!(mx.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect::<Vec<_>>(), [1, 0, 3, 2]);
        // Colour transfer: X by position, Y pulled back through map_yx (as X.ply / Y.ply).
        let cx = position_colors(&v);
        let transfer = &m["modes"][0];
        assert_eq!(
            blob(&html, transfer["x"].as_u64().unwrap() as usize),
            cx.iter().flatten().copied().collect::<Vec<_>>()
        );
        let cy = pull_back_colors(&cx, &map_yx).unwrap();
        assert_eq!(
            blob(&html, transfer["y"].as_u64().unwrap() as usize),
            cy.iter().flatten().copied().collect::<Vec<_>>()
        );
        // Errors: vertex 1 is the mean of its two template points, 2 and 3 take the nearest's.
        let e = &m["errors"];
        let values = blob(&html, e["values"].as_u64().unwrap() as usize);
        let values: Vec<f32> = values.chunks(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        assert_eq!(values[0], 0.1);
        assert!((values[1] - 0.3).abs() < 1e-6);
        assert_eq!(blob(&html, e["measured"].as_u64().unwrap() as usize), [1, 1, 0, 0]);
        assert!((e["mean"].as_f64().unwrap() - 0.7 / 3.0).abs() < 1e-12);
        let heat = blob(&html, m["modes"][1]["x"].as_u64().unwrap() as usize);
        assert_eq!(heat[0..3], heat_color(0.1, DEFAULT_ERROR_MAX));
        assert_eq!(m["bars"]["error"]["colors"].as_array().unwrap().len(), 65);
        assert_eq!(m["modes"][2]["mark"]["vertex"].as_u64(), Some(2));
        assert_eq!(m["modes"][2]["mark"]["side"].as_str(), Some("x"));
        // Shared scripts: the page references them instead.
        let shared = page.html_with(Scripts::Beside("../viewer/")).unwrap();
        assert!(shared.contains("<script src=\"../viewer/three.min.js\"></script>"));
        assert!(shared.len() + THREE_JS.len() / 2 < html.len());
    }

    #[test]
    fn inputs_that_do_not_fit_are_errors() {
        let (v, f) = tet();
        let x = ViewerShape { vertices: &v, faces: &f, colors: None };
        let bad_map = [0, 1, 2];
        let out_of_range = [0, 1, 2, 9];
        let mut page = Viewer::new("t", x);
        page.y = Some(x);
        page.map_xy = Some(&bad_map);
        let e = page.html().unwrap_err().to_string();
        assert!(e.contains("map_xy") && e.contains("3 entries") && e.contains("4 vertices"), "{e}");
        page.map_xy = Some(&out_of_range);
        let e = page.html().unwrap_err().to_string();
        assert!(e.contains("entry 3 is 9"), "{e}");
        page.map_xy = None;
        page.map_yx = Some(&bad_map);
        assert!(page.html().unwrap_err().to_string().contains("map_yx"));
        let mut alone = Viewer::new("t", x);
        alone.map_xy = Some(&[0, 1, 2, 3]);
        assert!(alone.html().unwrap_err().to_string().contains("needs the target shape Y"));
        let faces = [[0, 1, 7]];
        let broken = Viewer::new("t", ViewerShape { vertices: &v, faces: &faces, colors: None });
        assert!(broken.html().unwrap_err().to_string().contains("face 0"));
        let short = [1.0];
        let mut field = Viewer::new("t", x);
        field.fields.push(Field { name: "F:0".into(), side: Side::X, values: &short, mark: None });
        let e = field.html().unwrap_err().to_string();
        assert!(e.contains("F:0") && e.contains("1 values"), "{e}");
        let gt = GroundTruth { x: vec![0, 9], y: vec![0, 1], y_sym: None };
        assert!(VertexErrors::spread(&v, &gt, &[0.0, 0.0], "").is_err());
        let gt = GroundTruth { x: vec![0], y: vec![0], y_sym: None };
        assert!(VertexErrors::spread(&v, &gt, &[0.0, 0.0], "").unwrap_err().to_string().contains("errors"));
    }

    #[test]
    fn the_inferred_inverse_undoes_a_bijection() {
        let (v, _) = tet();
        let map = [2, 3, 0, 1];
        assert_eq!(inverse_by_nearest(&map, &v).unwrap(), vec![2, 3, 0, 1]);
        // Vertex 3 of Y is hit by no vertex of X: it takes the source of the nearest image.
        let inv = inverse_by_nearest(&[0, 0, 1, 2], &v).unwrap();
        assert_eq!(&inv[..3], &[0, 2, 3]);
        assert!(inverse_by_nearest(&[0, 7], &v).is_err());
        assert_eq!(ticks(0.0, 0.25), vec![0.0, 0.05, 0.1, 0.15, 0.2, 0.25]);
    }
}
