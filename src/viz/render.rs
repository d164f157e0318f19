//! A small software rasterizer: coloured triangle meshes and point clouds to an RGB image, and
//! PNG output — pictures like the paper's Figure 8 without a GPU or a window.
//!
//! The camera is orthographic. It looks at the centre of the shape's bounding box from the
//! direction of a [`View`] (azimuth and elevation in degrees, Y up) and is scaled so that the
//! bounding sphere about that centre spans [`FILL`] of the panel's smaller side, whatever the view.
//!
//! Triangles are z-buffered; colours and vertex normals are interpolated linearly across them
//! (Gouraud colours, per-sample shading): Lambert diffuse from a fixed light above and to the left
//! of the camera, plus ambient. Lighting is two-sided (a normal turned away from the camera is
//! flipped), so back faces seen through holes are lit too. Point clouds (no faces) are drawn as
//! small discs ("splats") of radius [`SPLAT_SPACING`] × the local nearest-neighbour spacing,
//! depth-tested as spheres and shaded with normals estimated from the nearest neighbours. Every
//! pixel averages [`SSAA`] × [`SSAA`] samples (supersampling antialiasing).
//!
//! Output is deterministic: bands of rows are drawn independently (in parallel) and, within a
//! band, triangles in index order with the first one drawn winning depth ties. Edges shared by two
//! triangles are evaluated identically for both, so meshes render without cracks.
//!
//! **Why one file (≈ 650 lines without tests).** The camera, point splatting, shading and the
//! banded rasterizer share private panel, bin and buffer types; the pieces have no other users.

use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::{PointSet, TriMesh};
use crate::spatial::knn;

/// Largest accepted image width or height, in pixels.
pub const MAX_SIZE: u32 = 16384;
/// Largest accepted pixel count width × height: 2²⁶ = 67,108,864 (64 Mi pixels, e.g. 8192 × 8192
/// or 16384 × 4096). The image is one RGB buffer of 3 bytes per pixel, so this caps it at 192 MiB
/// (16384 × 16384 would be 768 MiB, plus as much again while the PNG is written by a caller
/// holding a copy); 64 Mi pixels is already a 27-inch square print at 300 dpi. Rendering adds
/// per-thread band buffers of 2,880 bytes per image column, about 47 MB at the widest.
pub const MAX_PIXELS: u64 = 1 << 26;
/// Supersampling factor: each pixel averages `SSAA × SSAA` samples.
pub const SSAA: usize = 3;
/// Fraction of a panel's smaller side spanned by the diameter of the shape's bounding sphere.
pub const FILL: f64 = 0.92;
/// Splat radius of a point of a point cloud, as a multiple of the mean distance to its
/// [`NORMAL_NEIGHBOURS`] nearest neighbours.
pub const SPLAT_SPACING: f64 = 0.7;
/// Ambient light: the brightness of a surface facing away from the light.
pub const AMBIENT: f64 = 0.3;
/// Diffuse (Lambert) light: added to [`AMBIENT`] for a surface facing the light.
pub const DIFFUSE: f64 = 0.75;

/// Output rows per band (the unit of parallel work).
const BAND_ROWS: usize = 16;
/// Unit light direction in camera coordinates (right, up, toward the viewer): (−0.35, 0.45, 1)
/// normalized, above and to the left of the camera.
const LIGHT: [f64; 3] = [-0.30406056993414854, 0.3909350184867625, 0.8687444855261388];
/// Background colour (white).
const BACKGROUND: [u8; 3] = [255; 3];

/// A camera direction around the shape's bounding-box centre, in degrees, for Y-up shapes.
///
/// The camera sits on the unit vector `(cos e · sin a, sin e, cos e · cos a)` from the centre
/// (a = azimuth, e = elevation) and looks back at it, with +Y up on screen (at e = ±90°, the
/// screen's up is −Z / +Z). The default, azimuth 0 and elevation 0, looks along −Z with +X to the
/// right and +Y up: the front of an upright human facing +Z, as in FAUST and TOSCA.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Rotation of the camera about +Y, in degrees, counter-clockwise seen from above:
    /// 0 = camera on +Z, 90 = camera on +X, 180 = camera on −Z (the back). Any finite value.
    pub azimuth: f64,
    /// Height of the camera above the XZ plane, in degrees, in [−90, 90]: 90 looks down from +Y.
    pub elevation: f64,
}

impl Default for View {
    fn default() -> Self {
        View::FRONT
    }
}

impl std::fmt::Display for View {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{}", self.azimuth, self.elevation)
    }
}

impl View {
    /// Azimuth 0°, elevation 0°: camera on +Z looking along −Z, +X right, +Y up.
    pub const FRONT: View = View { azimuth: 0.0, elevation: 0.0 };

    /// A view from azimuth and elevation in degrees. Errors unless both are finite and the
    /// elevation is in [−90, 90].
    pub fn new(azimuth: f64, elevation: f64) -> Result<View> {
        Self::checked(azimuth, elevation, "view")
    }

    /// Parses `"azimuth,elevation"` in degrees (e.g. `"30,-10"`; spaces allowed), the syntax of
    /// the `--view` flag. Errors name `--view`.
    pub fn parse(s: &str) -> Result<View> {
        let bad = |msg: String| Error::invalid("view", msg);
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [a, e] = parts[..] else {
            return Err(bad(format!("{s:?} is not \"azimuth,elevation\" in degrees (e.g. \"30,10\")")));
        };
        let num = |t: &str, name: &str| {
            t.parse::<f64>().map_err(|_| bad(format!("{name} {t:?} in {s:?} is not a number of degrees")))
        };
        Self::checked(num(a, "azimuth")?, num(e, "elevation")?, "view")
    }

    fn checked(azimuth: f64, elevation: f64, what: &str) -> Result<View> {
        if !azimuth.is_finite() || !elevation.is_finite() {
            return Err(Error::invalid(what, format!("azimuth {azimuth} and elevation {elevation} must be finite")));
        }
        if !(-90.0..=90.0).contains(&elevation) {
            return Err(Error::invalid(what, format!("elevation {elevation}° is outside [-90, 90]")));
        }
        Ok(View { azimuth, elevation })
    }

    /// Orthonormal, right-handed camera frame: (screen right, screen up, toward the viewer).
    fn frame(&self) -> [[f64; 3]; 3] {
        let (sa, ca) = self.azimuth.to_radians().sin_cos();
        let (se, ce) = self.elevation.to_radians().sin_cos();
        let toward = [ce * sa, se, ce * ca];
        let right = [ca, 0.0, -sa];
        let up = cross(toward, right);
        [right, up, toward]
    }
}

/// A shape to draw, as plain slices: `n` vertices (units arbitrary), triangles of 0-based vertex
/// indices (empty for a point cloud, drawn as splats) and one sRGB colour per vertex (length n).
#[derive(Debug, Clone, Copy)]
pub struct ColoredShape<'a> {
    /// Vertex positions (n × 3), Y up (see [`View`]).
    pub vertices: &'a [[f64; 3]],
    /// Triangles (0-based indices `< n`); empty draws the vertices as a point cloud.
    pub faces: &'a [[u32; 3]],
    /// One 8-bit sRGB colour per vertex (length n).
    pub colors: &'a [[u8; 3]],
}

/// An 8-bit RGB image: `width × height` pixels, row-major from the top-left corner, 3 bytes per
/// pixel (`rgb.len() == 3 · width · height`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel data, row-major, R G B bytes per pixel.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The colour of pixel (x, y), x from the left, y from the top.
    ///
    /// # Panics
    /// When (x, y) is outside the image or `rgb` is shorter than `3 · width · height`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        assert!(x < self.width && y < self.height, "pixel ({x}, {y}) outside {}×{}", self.width, self.height);
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
}

/// Renders one shape filling a `width × height` image (pixels, each in 1..=[`MAX_SIZE`], at most
/// [`MAX_PIXELS`] in all) on a white background, seen from `view`.
///
/// Errors when a size is out of range, the shape has no vertex, `colors` does not have one entry
/// per vertex, a coordinate is not finite (or so large that the shape's extent overflows), or a
/// face index is out of range.
pub fn render(shape: &ColoredShape, width: u32, height: u32, view: &View) -> Result<Image> {
    check_size(width, height, 1)?;
    let (w, h) = (width as usize, height as usize);
    let panel = Panel::new(shape, "shape", 0, w, h, view)?;
    Ok(rasterize(w, h, &[panel]))
}

/// Renders X and Y side by side in one `width × height` image (pixels; width in 2..=[`MAX_SIZE`],
/// height in 1..=[`MAX_SIZE`], at most [`MAX_PIXELS`] in all): X in the left panel (⌊width/2⌋ pixels wide), Y in the right one,
/// each fitted to its own panel, both seen from `view`, on a white background.
///
/// Errors as [`render`] does, naming `X` or `Y`.
pub fn render_pair(x: &ColoredShape, y: &ColoredShape, width: u32, height: u32, view: &View) -> Result<Image> {
    check_size(width, height, 2)?;
    let (w, h) = (width as usize, height as usize);
    let left = w / 2;
    let px = Panel::new(x, "X", 0, left, h, view)?;
    let py = Panel::new(y, "Y", left, w - left, h, view)?;
    Ok(rasterize(w, h, &[px, py]))
}

/// Writes `image` as an 8-bit RGB PNG file at `path`.
///
/// Errors ([`Error::Io`] naming `path`) when the file cannot be written, and ([`Error::Invalid`])
/// when the image is empty, larger than [`MAX_SIZE`] on a side or [`MAX_PIXELS`] in all, or `rgb`
/// has the wrong length.
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let (w, h) = (image.width, image.height);
    check_size(w, h, 1).map_err(|e| Error::invalid("image", e.to_string()))?;
    if image.rgb.len() != 3 * w as usize * h as usize {
        return Err(Error::invalid(
            "image",
            format!(
                "{} bytes of pixel data for {w}×{h} RGB pixels (need {})",
                image.rgb.len(),
                3 * w as usize * h as usize
            ),
        ));
    }
    let png_error = |e: png::EncodingError| match e {
        png::EncodingError::IoError(e) => Error::io(path, e),
        other => Error::invalid("image", format!("PNG encoding of {}: {other}", path.display())),
    };
    // Whole or not at all: a run killed while encoding leaves no partial PNG.
    crate::io::write_file(path, |out| {
        let mut encoder = png::Encoder::new(out, w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(png_error)?;
        writer.write_image_data(&image.rgb).map_err(png_error)?;
        writer.finish().map_err(png_error)
    })
}

/// Checks an image size before anything is allocated: width in `min_width`..=[`MAX_SIZE`] (1 for
/// [`render`], 2 for [`render_pair`]), height in 1..=[`MAX_SIZE`], width × height at most
/// [`MAX_PIXELS`].
///
/// Errors ([`Error::Invalid`]) naming `width`, `height` or `size` (the pixel count).
pub fn check_size(width: u32, height: u32, min_width: u32) -> Result<()> {
    if !(min_width..=MAX_SIZE).contains(&width) {
        return Err(Error::invalid("width", format!("{width} pixels is outside {min_width}..={MAX_SIZE}")));
    }
    if !(1..=MAX_SIZE).contains(&height) {
        return Err(Error::invalid("height", format!("{height} pixels is outside 1..={MAX_SIZE}")));
    }
    let pixels = width as u64 * height as u64;
    if pixels > MAX_PIXELS {
        return Err(Error::invalid(
            "size",
            format!(
                "{width}×{height} is {pixels} pixels ({} MiB of RGB), more than the limit of {MAX_PIXELS} \
                 (e.g. 8192×8192)",
                (3 * pixels) >> 20
            ),
        ));
    }
    Ok(())
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// One shape projected into its panel, ready to draw.
struct Panel {
    /// First output column of the panel.
    x0: usize,
    /// Panel height in output pixels.
    h: usize,
    /// Per vertex: sample-space x (right), y (down) and depth (toward the viewer, in samples).
    pts: Vec<[f64; 3]>,
    /// Per vertex: unit normal in camera coordinates (right, up, toward the viewer); zero where
    /// undefined.
    normals: Vec<[f64; 3]>,
    /// Per vertex: colour in [0, 1].
    colors: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
    /// Per point: splat radius in samples (point clouds only).
    radii: Vec<f64>,
    /// For every band of output rows, what to draw there.
    bins: Vec<Bin>,
}

/// The faces (or points) that meet one band of output rows, in index order, and the output
/// columns [c0, c1) of the panel that they may cover (empty when c0 ≥ c1).
struct Bin {
    items: Vec<u32>,
    c0: usize,
    c1: usize,
}

impl Panel {
    fn new(shape: &ColoredShape, label: &str, x0: usize, w: usize, h: usize, view: &View) -> Result<Panel> {
        let ColoredShape { vertices, faces, colors } = *shape;
        let n = vertices.len();
        if n == 0 {
            return Err(Error::invalid(label, "it has no vertices"));
        }
        if n > u32::MAX as usize {
            return Err(Error::invalid(label, format!("{n} vertices is more than 2^32 - 1")));
        }
        if colors.len() != n {
            return Err(Error::invalid(label, format!("{} colours for {n} vertices", colors.len())));
        }
        if let Some(i) = vertices.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(Error::invalid(label, format!("vertex {i} has a non-finite coordinate {:?}", vertices[i])));
        }
        if let Some(f) = faces.iter().position(|f| f.iter().any(|&i| i as usize >= n)) {
            return Err(Error::invalid(label, format!("face {f} {:?} has a vertex index ≥ n = {n}", faces[f])));
        }

        // Centre the bounding box (halves first, so that huge coordinates do not overflow).
        let (lo, hi) = crate::shape::bounding_box(vertices);
        let centre: [f64; 3] = std::array::from_fn(|d| lo[d] / 2.0 + hi[d] / 2.0);
        let centred: Vec<[f64; 3]> = vertices.iter().map(|p| std::array::from_fn(|d| p[d] - centre[d])).collect();
        // Bounding-sphere radius, scaled by the largest |coordinate| so that squares do not overflow.
        let m = centred.iter().flatten().fold(0.0, |m: f64, c| m.max(c.abs()));
        let radius = if m > 0.0 {
            m * centred.iter().map(|q| q.map(|c| c / m)).map(|q| dot(q, q).sqrt()).fold(0.0, f64::max)
        } else {
            0.0
        };
        if !radius.is_finite() {
            return Err(Error::invalid(label, "its coordinates are too large: its extent overflows"));
        }
        let half = FILL / 2.0 * w.min(h) as f64 * SSAA as f64; // bounding-sphere radius in samples
        let scale = if radius > 0.0 && (half / radius).is_finite() { half / radius } else { half };
        let [right, up, toward] = view.frame();
        // Camera coordinates in samples: a uniform scale and a rotation, so normals computed from
        // them are the rotated normals.
        let mut cam: Vec<[f64; 3]> = centred
            .iter()
            .map(|q| {
                let q = q.map(|c| c * scale);
                [dot(right, q), dot(up, q), dot(toward, q)]
            })
            .collect();
        let (normals, radii) = if faces.is_empty() {
            let (mut radii, normals) = splat_geometry(&cam, w.min(h));
            // Shrink so that (typical) splats on the bounding sphere fit too.
            let shrink = half / (half + radii.iter().sum::<f64>() / radii.len() as f64);
            cam.iter_mut().for_each(|c| *c = c.map(|v| v * shrink));
            radii.iter_mut().for_each(|r| *r *= shrink);
            (normals, radii)
        } else {
            let mesh = TriMesh::new(cam.clone(), faces.to_vec()).map_err(|e| Error::invalid(label, e.to_string()))?;
            (mesh.vertex_normals(), Vec::new())
        };
        let (cx, cy) = (w as f64 * SSAA as f64 / 2.0, h as f64 * SSAA as f64 / 2.0);
        let pts: Vec<[f64; 3]> = cam.iter().map(|c| [cx + c[0], cy - c[1], c[2]]).collect();
        let colors = colors.iter().map(|c| c.map(|v| v as f32 / 255.0)).collect();

        let band_samples = (BAND_ROWS * SSAA) as f64;
        let n_bands = h.div_ceil(BAND_ROWS);
        let last_row = (h * SSAA) as f64 - 1.0;
        let band_range = |ylo: f64, yhi: f64| -> Option<(usize, usize)> {
            // Sample row j has its centre at j + 0.5.
            let (r0, r1) = ((ylo - 0.5).ceil().max(0.0), (yhi - 0.5).floor().min(last_row));
            (r0 <= r1).then(|| ((r0 / band_samples) as usize, (r1 / band_samples) as usize))
        };
        // Output columns [c0, c1) that a sample-space x range [xlo, xhi] touches.
        let columns = |xlo: f64, xhi: f64| {
            (
                (xlo / SSAA as f64).floor().clamp(0.0, w as f64) as usize,
                (xhi / SSAA as f64).ceil().clamp(0.0, w as f64) as usize,
            )
        };
        let mut bins: Vec<Bin> = (0..n_bands).map(|_| Bin { items: Vec::new(), c0: w, c1: 0 }).collect();
        let mut add = |k: usize, (xlo, xhi): (f64, f64), (ylo, yhi): (f64, f64)| {
            if let Some((b0, b1)) = band_range(ylo, yhi) {
                let (c0, c1) = columns(xlo, xhi);
                for b in &mut bins[b0..=b1] {
                    b.items.push(k as u32);
                    (b.c0, b.c1) = (b.c0.min(c0), b.c1.max(c1));
                }
            }
        };
        if faces.is_empty() {
            for (i, p) in pts.iter().enumerate() {
                add(i, (p[0] - radii[i], p[0] + radii[i]), (p[1] - radii[i], p[1] + radii[i]));
            }
        } else {
            for (f, tri) in faces.iter().enumerate() {
                let [a, b, c] = tri.map(|i| pts[i as usize]);
                add(
                    f,
                    (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0])),
                    (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1])),
                );
            }
        }
        Ok(Panel { x0, h, pts, normals, colors, faces: faces.to_vec(), radii, bins })
    }

    /// Draws band `band` (output rows `band · BAND_ROWS ..`) into `out`, the band's rows of an
    /// image `out_width` pixels wide.
    fn draw_band(&self, band: usize, out: &mut [u8], out_width: usize) {
        let bin = &self.bins[band];
        if bin.items.is_empty() || bin.c0 >= bin.c1 {
            return; // the image is already background there
        }
        let r0 = band * BAND_ROWS;
        let rows = BAND_ROWS.min(self.h - r0);
        let (sw, sh) = ((bin.c1 - bin.c0) * SSAA, rows * SSAA);
        let mut buf = Buffer {
            sx0: bin.c0 * SSAA,
            sy0: r0 * SSAA,
            sw,
            sh,
            depth: vec![f64::NEG_INFINITY; sw * sh],
            color: vec![BACKGROUND.map(|v| v as f32 / 255.0); sw * sh],
        };
        for &k in &bin.items {
            if self.faces.is_empty() {
                self.draw_splat(k as usize, &mut buf);
            } else {
                self.draw_triangle(k as usize, &mut buf);
            }
        }
        let norm = 1.0 / (SSAA * SSAA) as f32;
        for r in 0..rows {
            for c in 0..bin.c1 - bin.c0 {
                let mut sum = [0f32; 3];
                for j in 0..SSAA {
                    let row = (r * SSAA + j) * sw + c * SSAA;
                    for s in &buf.color[row..row + SSAA] {
                        (0..3).for_each(|d| sum[d] += s[d]);
                    }
                }
                let o = 3 * (r * out_width + self.x0 + bin.c0 + c);
                for d in 0..3 {
                    out[o + d] = (sum[d] * norm * 255.0).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }

    /// Inclusive range of sample indices whose centres (index + 0.5) lie in [lo, hi], clamped to
    /// [0, len).
    fn sample_range(lo: f64, hi: f64, len: usize) -> Option<(usize, usize)> {
        let (a, b) = ((lo - 0.5).ceil().max(0.0), (hi - 0.5).floor().min(len as f64 - 1.0));
        (a <= b).then_some((a as usize, b as usize))
    }

    /// Edge function of the directed edge i → j at (x, y): twice the signed area of (i, j, p).
    /// Computed from the lower-indexed end, so that the two triangles sharing an edge get exactly
    /// opposite values and no sample falls between them.
    fn edge(&self, i: u32, j: u32, x: f64, y: f64) -> f64 {
        let e = |a: [f64; 3], b: [f64; 3]| (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
        let (pi, pj) = (self.pts[i as usize], self.pts[j as usize]);
        if i < j {
            e(pi, pj)
        } else {
            -e(pj, pi)
        }
    }

    fn draw_triangle(&self, f: usize, buf: &mut Buffer) {
        let [ia, ib, ic] = self.faces[f];
        let [pa, pb, pc] = [ia, ib, ic].map(|i| self.pts[i as usize]);
        let area = self.edge(ia, ib, pc[0], pc[1]);
        if area == 0.0 || !area.is_finite() {
            return; // edge-on or degenerate: its neighbours cover the pixels
        }
        let xs = (pa[0].min(pb[0]).min(pc[0]), pa[0].max(pb[0]).max(pc[0]));
        let ys = (pa[1].min(pb[1]).min(pc[1]), pa[1].max(pb[1]).max(pc[1]));
        let Some((x_lo, x_hi)) = Self::sample_range(xs.0 - buf.sx0 as f64, xs.1 - buf.sx0 as f64, buf.sw) else {
            return;
        };
        let Some((y_lo, y_hi)) = Self::sample_range(ys.0 - buf.sy0 as f64, ys.1 - buf.sy0 as f64, buf.sh) else {
            return;
        };
        // Fallback normal for vertices without one: the face normal, in camera coordinates.
        let up = |p: [f64; 3]| [p[0], -p[1], p[2]];
        let face_n = {
            let (a, b, c) = (up(pa), up(pb), up(pc));
            cross([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]])
        };
        let [na, nb, nc] = [ia, ib, ic].map(|i| self.normals[i as usize]);
        let [ca, cb, cc] = [ia, ib, ic].map(|i| self.colors[i as usize]);
        let inv = 1.0 / area;
        for sy in y_lo..=y_hi {
            let y = (buf.sy0 + sy) as f64 + 0.5;
            for sx in x_lo..=x_hi {
                let x = (buf.sx0 + sx) as f64 + 0.5;
                let (wa, wb, wc) = (self.edge(ib, ic, x, y), self.edge(ic, ia, x, y), self.edge(ia, ib, x, y));
                let inside =
                    if area > 0.0 { wa >= 0.0 && wb >= 0.0 && wc >= 0.0 } else { wa <= 0.0 && wb <= 0.0 && wc <= 0.0 };
                if !inside {
                    continue;
                }
                let (la, lb, lc) = (wa * inv, wb * inv, wc * inv);
                let z = la * pa[2] + lb * pb[2] + lc * pc[2];
                let k = sy * buf.sw + sx;
                if z <= buf.depth[k] {
                    continue;
                }
                buf.depth[k] = z;
                let mut n: [f64; 3] = std::array::from_fn(|d| la * na[d] + lb * nb[d] + lc * nc[d]);
                if dot(n, n) < 1e-12 {
                    n = face_n;
                }
                let (fa, fb, fc) = (la as f32, lb as f32, lc as f32);
                let col: [f32; 3] = std::array::from_fn(|d| fa * ca[d] + fb * cb[d] + fc * cc[d]);
                buf.color[k] = shade(col, n);
            }
        }
    }

    /// A point as a small sphere of its splat radius (for the depth test), shaded with the
    /// point's estimated normal, or the sphere's where there is none.
    fn draw_splat(&self, i: usize, buf: &mut Buffer) {
        let [px, py, pz] = self.pts[i];
        let r = self.radii[i];
        let px = px - buf.sx0 as f64;
        let Some((x_lo, x_hi)) = Self::sample_range(px - r, px + r, buf.sw) else { return };
        let y0 = py - buf.sy0 as f64;
        let Some((y_lo, y_hi)) = Self::sample_range(y0 - r, y0 + r, buf.sh) else { return };
        let col = self.colors[i];
        let normal = self.normals[i];
        let has_normal = normal != [0.0; 3];
        for sy in y_lo..=y_hi {
            let dy = (sy as f64 + 0.5 - y0) / r;
            for sx in x_lo..=x_hi {
                let dx = (sx as f64 + 0.5 - px) / r;
                let q = dx * dx + dy * dy;
                if q > 1.0 {
                    continue;
                }
                let nz = (1.0 - q).sqrt();
                let z = pz + nz * r;
                let k = sy * buf.sw + sx;
                if z <= buf.depth[k] {
                    continue;
                }
                buf.depth[k] = z;
                buf.color[k] = shade(col, if has_normal { normal } else { [dx, -dy, nz] });
            }
        }
    }
}

/// Samples of one band of one panel (`sw × sh`, row-major).
struct Buffer {
    /// First sample column and row (panel sample coordinates).
    sx0: usize,
    sy0: usize,
    sw: usize,
    sh: usize,
    depth: Vec<f64>,
    color: Vec<[f32; 3]>,
}

/// Two-sided Lambert + ambient shading of colour `col` with normal `n` (camera coordinates, any
/// length but not zero).
fn shade(col: [f32; 3], n: [f64; 3]) -> [f32; 3] {
    let len = dot(n, n).sqrt();
    let cos = if len > 0.0 {
        // Two-sided: use the side of the surface that faces the viewer.
        let s = if n[2] < 0.0 { -1.0 } else { 1.0 };
        (s * dot(n, LIGHT) / len).max(0.0)
    } else {
        LIGHT[2]
    };
    let intensity = (AMBIENT + DIFFUSE * cos) as f32;
    col.map(|c| (c * intensity).min(1.0))
}

/// Neighbours used to estimate the splat radii and normals of point clouds.
pub const NORMAL_NEIGHBOURS: usize = 8;

/// Per-point splat radii (samples) and normals (camera coordinates; zero where undefined) of a
/// point cloud given in camera coordinates (samples), from the point's [`NORMAL_NEIGHBOURS`]
/// nearest neighbours. A radius is [`SPLAT_SPACING`] × the mean distance to those neighbours
/// (so splats grow where the sampling is sparse), between one pixel and 5% of the panel's
/// smaller side (`side` pixels); a normal is the least-variance direction of the point and its
/// neighbours.
fn splat_geometry(cam: &[[f64; 3]], side: usize) -> (Vec<f64>, Vec<[f64; 3]>) {
    let px = SSAA as f64;
    let (min_r, max_r) = (px, 0.05 * side as f64 * px);
    let default = (vec![(0.01 * side as f64 * px).max(min_r); cam.len()], vec![[0.0; 3]; cam.len()]);
    if cam.len() < 2 || cam.iter().all(|p| p == &cam[0]) {
        return default;
    }
    let k = NORMAL_NEIGHBOURS.min(cam.len() - 1);
    let Ok(nn) = PointSet::new(cam.len(), 3, cam.iter().flatten().copied().collect()).and_then(|ps| knn(&ps, k)) else {
        return default; // e.g. too many coincident points
    };
    let radii = nn
        .iter()
        .map(|nb| {
            let r = SPLAT_SPACING * nb.iter().map(|&(d2, _)| d2.sqrt()).sum::<f64>() / nb.len() as f64;
            if r.is_finite() {
                r.min(max_r).max(min_r)
            } else {
                min_r
            }
        })
        .collect();
    let normals = nn
        .par_iter()
        .enumerate()
        .map(|(i, nb)| {
            let pts = || std::iter::once(cam[i]).chain(nb.iter().map(|&(_, j)| cam[j]));
            let m = (k + 1) as f64;
            let mean: [f64; 3] = std::array::from_fn(|d| pts().map(|p| p[d]).sum::<f64>() / m);
            let mut c = [[0.0; 3]; 3];
            for p in pts() {
                for a in 0..3 {
                    for b in 0..3 {
                        c[a][b] += (p[a] - mean[a]) * (p[b] - mean[b]);
                    }
                }
            }
            least_variance_direction(c)
        })
        .collect();
    (radii, normals)
}

/// Unit eigenvector of the smallest eigenvalue of the symmetric 3 × 3 matrix `c` (closed-form
/// eigenvalue, then the null vector of `c − λI` from its rows); zero when undefined (isotropic or
/// degenerate spread).
fn least_variance_direction(c: [[f64; 3]; 3]) -> [f64; 3] {
    let q = (c[0][0] + c[1][1] + c[2][2]) / 3.0;
    let off = c[0][1] * c[0][1] + c[0][2] * c[0][2] + c[1][2] * c[1][2];
    let p = (((c[0][0] - q).powi(2) + (c[1][1] - q).powi(2) + (c[2][2] - q).powi(2) + 2.0 * off) / 6.0).sqrt();
    if !p.is_finite() || p <= 0.0 {
        return [0.0; 3];
    }
    let b: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| (c[i][j] - if i == j { q } else { 0.0 }) / p));
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let lambda = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    let r: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| c[i][j] - if i == j { lambda } else { 0.0 }));
    let best = [cross(r[0], r[1]), cross(r[0], r[2]), cross(r[1], r[2])]
        .into_iter()
        .max_by(|a, b| dot(*a, *a).total_cmp(&dot(*b, *b)))
        .expect("three candidates");
    let l = dot(best, best).sqrt();
    if l > 0.0 && l.is_finite() {
        best.map(|v| v / l)
    } else {
        [0.0; 3]
    }
}

/// Draws every panel into a white `w × h` image, band by band in parallel.
fn rasterize(w: usize, h: usize, panels: &[Panel]) -> Image {
    let mut rgb = BACKGROUND.repeat(w * h);
    rgb.par_chunks_mut(BAND_ROWS * w * 3).enumerate().for_each(|(band, out)| {
        for p in panels {
            p.draw_band(band, out, w);
        }
    });
    Image { width: w as u32, height: h as u32, rgb }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{bumpy_sphere, icosphere};
    use crate::shape::Shape;
    use crate::viz::{position_colors, pull_back_colors};

    fn is_background(p: [u8; 3]) -> bool {
        p == BACKGROUND
    }

    fn drawn(img: &Image) -> usize {
        (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .filter(|&(x, y)| !is_background(img.pixel(x, y)))
            .count()
    }

    #[test]
    fn render_has_the_requested_size_and_draws_the_shape() {
        let s = icosphere(3);
        let c = position_colors(s.vertices());
        let shape = ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &c };
        let img = render(&shape, 64, 48, &View::default()).unwrap();
        assert_eq!((img.width, img.height, img.rgb.len()), (64, 48, 64 * 48 * 3));
        // A disc of diameter 0.92 · 48 pixels: about π/4 · 44² ≈ 1500 pixels.
        let n = drawn(&img);
        assert!((1300..1700).contains(&n), "{n} pixels drawn");
        assert!(is_background(img.pixel(0, 0)) && is_background(img.pixel(63, 47)));
        assert!(!is_background(img.pixel(32, 24)));
        // Lit, not black: the centre faces the viewer.
        assert!(img.pixel(32, 24).iter().map(|&v| v as u32).sum::<u32>() > 150);
        assert_eq!(render(&shape, 64, 48, &View::default()).unwrap(), img, "deterministic");
        // The smallest images.
        assert_eq!(render(&shape, 1, 1, &View::FRONT).unwrap().rgb.len(), 3);
        let tiny = render_pair(&shape, &shape, 2, 1, &View::FRONT).unwrap();
        assert_eq!((tiny.width, tiny.height), (2, 1));
        assert_eq!(tiny.pixel(0, 0), tiny.pixel(1, 0));
    }

    #[test]
    fn identity_pull_back_renders_the_same_image() {
        let s = bumpy_sphere(3);
        let cx = position_colors(s.vertices());
        let identity: Vec<usize> = (0..s.n_vertices()).collect();
        let cy = pull_back_colors(&cx, &identity).unwrap();
        let view = View::new(30.0, 20.0).unwrap();
        let x = ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &cx };
        let y = ColoredShape { colors: &cy, ..x };
        assert_eq!(render(&x, 80, 60, &view).unwrap(), render(&y, 80, 60, &view).unwrap());
        // Side by side with an even width, the two panels are the same picture.
        let pair = render_pair(&x, &y, 160, 60, &view).unwrap();
        assert!(drawn(&pair) > 2000);
        for yy in 0..60 {
            for xx in 0..80 {
                assert_eq!(pair.pixel(xx, yy), pair.pixel(xx + 80, yy), "pixel ({xx}, {yy})");
            }
        }
        // And each panel is the single render at the panel's size.
        let single = render(&x, 80, 60, &view).unwrap();
        assert!((0..60).all(|yy| (0..80).all(|xx| pair.pixel(xx, yy) == single.pixel(xx, yy))));
    }

    #[test]
    fn point_cloud_renders_as_splats() {
        let s = icosphere(3);
        let c = vec![[200, 30, 30]; s.n_vertices()];
        let cloud = ColoredShape { vertices: s.vertices(), faces: &[], colors: &c };
        let img = render(&cloud, 64, 64, &View::default()).unwrap();
        let n = drawn(&img);
        // The splats overlap into (nearly) the full disc of diameter 0.92 · 64 ≈ 59 pixels.
        assert!((2200..3000).contains(&n), "{n} pixels drawn");
        let p = img.pixel(32, 32);
        assert!(p[0] > 120 && p[1] < 60 && p[2] < 60, "{p:?}");
        // One point, and coincident points, still draw a dot.
        let one = render(
            &ColoredShape { vertices: &[[1.0, 2.0, 3.0]; 3], faces: &[], colors: &c[..3] },
            20,
            20,
            &View::FRONT,
        )
        .unwrap();
        assert!(!is_background(one.pixel(10, 10)) && is_background(one.pixel(0, 0)));
        // Many coincident points among others.
        let mut v = vec![[0.0, 0.0, 0.0]; 2000];
        v.extend(s.vertices());
        let c = vec![[10, 200, 10]; v.len()];
        let img = render(&ColoredShape { vertices: &v, faces: &[], colors: &c }, 40, 40, &View::FRONT).unwrap();
        assert!(drawn(&img) > 500);
    }

    /// Colours by octant sign: red where x > 0, green where y > 0, blue where z > 0.
    fn octant_sphere() -> (TriMesh, Vec<[u8; 3]>) {
        let s = icosphere(4);
        let c = s.vertices().iter().map(|p| p.map(|v| if v > 0.0 { 255 } else { 0 })).collect();
        (s, c)
    }

    #[test]
    fn views_follow_the_documented_convention() {
        let (s, c) = octant_sphere();
        let shape = ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &c };
        let at = |view: View, x: u32, y: u32| render(&shape, 100, 100, &view).unwrap().pixel(x, y);
        let on = |v: u8| v > 90;
        // Front (camera on +Z): +X to the right, +Y up, everything seen has z > 0 (blue).
        let [r, g, b] = at(View::FRONT, 75, 25);
        assert!(on(r) && on(g) && on(b), "upper right {:?}", [r, g, b]);
        let [r, g, b] = at(View::FRONT, 25, 75);
        assert!(!on(r) && !on(g) && on(b), "lower left {:?}", [r, g, b]);
        // Azimuth 90: camera on +X, −Z to the right.
        let [r, g, b] = at(View::new(90.0, 0.0).unwrap(), 75, 25);
        assert!(on(r) && on(g) && !on(b), "{:?}", [r, g, b]);
        // Azimuth 180: camera on −Z, −X to the right.
        let [r, g, b] = at(View::new(180.0, 0.0).unwrap(), 75, 25);
        assert!(!on(r) && on(g) && !on(b), "{:?}", [r, g, b]);
        // Elevation 90: camera on +Y, +X to the right, −Z up.
        let [r, g, b] = at(View::new(0.0, 90.0).unwrap(), 75, 25);
        assert!(on(r) && on(g) && !on(b), "{:?}", [r, g, b]);
    }

    #[test]
    fn azimuth_180_mirrors_a_symmetric_shape() {
        // The icosphere is symmetric under x → −x and z → −z, so from behind (uniform colour) it
        // looks the same as from the front.
        let s = icosphere(3);
        let c = vec![[180, 180, 90]; s.n_vertices()];
        let shape = ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &c };
        let a = render(&shape, 60, 60, &View::FRONT).unwrap();
        let b = render(&shape, 60, 60, &View::new(180.0, 0.0).unwrap()).unwrap();
        let diff: u64 = a.rgb.iter().zip(&b.rgb).map(|(&p, &q)| (p as i64 - q as i64).unsigned_abs()).sum();
        assert!((diff as f64 / a.rgb.len() as f64) < 0.5, "mean difference {}", diff as f64 / a.rgb.len() as f64);
    }

    #[test]
    fn faust_front_view_is_upright() {
        let Shape::Mesh(m) = Shape::load(Path::new("data/faust/tr_reg_000.off")).unwrap() else { panic!("not a mesh") };
        let c = position_colors(m.vertices());
        let img =
            render(&ColoredShape { vertices: m.vertices(), faces: m.faces(), colors: &c }, 90, 100, &View::default())
                .unwrap();
        let (mut x0, mut x1, mut y0, mut y1) = (u32::MAX, 0, u32::MAX, 0);
        for y in 0..img.height {
            for x in 0..img.width {
                if !is_background(img.pixel(x, y)) {
                    (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                }
            }
        }
        // Standing: much taller than wide, and as tall as the fit allows.
        assert!(y1 - y0 > 80 && (y1 - y0) > 2 * (x1 - x0), "box x {x0}..{x1}, y {y0}..{y1}");
    }

    #[test]
    fn png_round_trip() {
        let s = icosphere(2);
        let c = position_colors(s.vertices());
        let img = render(&ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &c }, 37, 23, &View::FRONT)
            .unwrap();
        let dir = std::env::temp_dir().join(format!("funcorr-render-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sphere.png");
        write_png(&path, &img).unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        assert_eq!(reader.info().size(), (37, 23));
        let mut data = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut data).unwrap();
        assert_eq!((frame.color_type, frame.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        assert_eq!(&data[..frame.buffer_size()], &img.rgb[..]);
        // Unwritable paths are I/O errors naming the path.
        let bad = dir.join("no/such/dir/x.png");
        assert!(matches!(write_png(&bad, &img), Err(Error::Io { path, .. }) if path == bad));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn light_and_normal_estimates_are_unit_vectors() {
        assert!((dot(LIGHT, LIGHT) - 1.0).abs() < 1e-15);
        // Points on the tilted plane x + 2y + 3z = 0: the normal is ±(1, 2, 3)/√14.
        let plane = |u: f64, v: f64| [3.0 * u, 3.0 * v, -u - 2.0 * v];
        let pts = [plane(0.0, 0.0), plane(1.0, 0.0), plane(0.0, 1.0), plane(1.0, 1.3), plane(-0.5, 0.7)];
        let mean: [f64; 3] = std::array::from_fn(|d| pts.iter().map(|p| p[d]).sum::<f64>() / 5.0);
        let c: [[f64; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|b| pts.iter().map(|p| (p[a] - mean[a]) * (p[b] - mean[b])).sum())
        });
        let n = least_variance_direction(c);
        let expect = [1.0, 2.0, 3.0].map(|v: f64| v / 14f64.sqrt());
        assert!((dot(n, expect).abs() - 1.0).abs() < 1e-12, "{n:?}");
        assert_eq!(least_variance_direction([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), [0.0; 3]);
        assert_eq!(least_variance_direction([[0.0; 3]; 3]), [0.0; 3]);
    }

    #[test]
    fn view_parse() {
        assert_eq!(View::parse("30,-10").unwrap(), View { azimuth: 30.0, elevation: -10.0 });
        assert_eq!(View::parse(" 0 , 90 ").unwrap(), View::new(0.0, 90.0).unwrap());
        assert_eq!(View::parse(&View::new(-12.5, 3.0).unwrap().to_string()).unwrap(), View::new(-12.5, 3.0).unwrap());
        for bad in ["", "30", "a,b", "1,2,3", "nan,0", "0,inf", "0,91", "0,-90.5", "30;10"] {
            let e = View::parse(bad).unwrap_err();
            assert!(matches!(&e, Error::Invalid { what, .. } if what == "view"), "{bad:?}: {e}");
        }
        assert!(View::new(0.0, 100.0).is_err());
    }

    #[test]
    fn bad_inputs_are_errors() {
        let s = icosphere(1);
        let c = position_colors(s.vertices());
        let ok = ColoredShape { vertices: s.vertices(), faces: s.faces(), colors: &c };
        let v = View::FRONT;
        let invalid = |r: Result<Image>, what: &str| match r {
            Err(Error::Invalid { what: w, .. }) => assert_eq!(w, what),
            other => panic!("expected an invalid {what}, got {other:?}"),
        };
        invalid(render(&ok, 0, 10, &v), "width");
        invalid(render(&ok, 10, 0, &v), "height");
        invalid(render(&ok, MAX_SIZE + 1, 10, &v), "width");
        invalid(render(&ok, 10, u32::MAX, &v), "height");
        invalid(render_pair(&ok, &ok, 1, 10, &v), "width");
        // Each side within MAX_SIZE but too many pixels in all: refused before any allocation.
        invalid(render(&ok, MAX_SIZE, MAX_SIZE, &v), "size");
        invalid(render_pair(&ok, &ok, MAX_SIZE, 4097, &v), "size");
        let e = check_size(MAX_SIZE, MAX_SIZE, 1).unwrap_err().to_string();
        assert!(e.contains("268435456 pixels") && e.contains("768 MiB"), "{e}");
        assert!(check_size(8192, 8192, 1).is_ok() && check_size(MAX_SIZE, 4096, 2).is_ok());
        assert!(check_size(8193, 8192, 1).is_err());
        invalid(render(&ColoredShape { colors: &c[1..], ..ok }, 10, 10, &v), "shape");
        invalid(render(&ColoredShape { vertices: &[], faces: &[], colors: &[] }, 10, 10, &v), "shape");
        let mut nan = s.vertices().to_vec();
        nan[3][1] = f64::NAN;
        invalid(render(&ColoredShape { vertices: &nan, ..ok }, 10, 10, &v), "shape");
        invalid(render_pair(&ok, &ColoredShape { vertices: &nan, ..ok }, 10, 10, &v), "Y");
        // Huge coordinates render while the bounding sphere's radius is a finite number...
        let huge: Vec<[f64; 3]> = s.vertices().iter().map(|p| p.map(|x| x * 0.5 * f64::MAX)).collect();
        assert!(drawn(&render(&ColoredShape { vertices: &huge, ..ok }, 10, 10, &v).unwrap()) > 0);
        // ... and are errors past that.
        let mut huge = s.vertices().to_vec();
        huge[0] = [f64::MAX, 0.0, f64::MAX];
        huge[1] = [-f64::MAX, 0.0, -f64::MAX];
        invalid(render(&ColoredShape { vertices: &huge, ..ok }, 10, 10, &v), "shape");
        let mut faces = s.faces().to_vec();
        faces[5][2] = s.n_vertices() as u32;
        invalid(render_pair(&ColoredShape { faces: &faces, ..ok }, &ok, 10, 10, &v), "X");
        // Tiny but non-zero extents render (no overflow in the fit).
        let tiny: Vec<[f64; 3]> = s.vertices().iter().map(|p| p.map(|x| x * 1e-300)).collect();
        assert!(drawn(&render(&ColoredShape { vertices: &tiny, ..ok }, 10, 10, &v).unwrap()) > 0);
        // Images written as PNG must be consistent.
        let path = std::env::temp_dir().join("funcorr-render-never-written.png");
        for img in [
            Image { width: 2, height: 2, rgb: vec![0; 11] },
            Image { width: 0, height: 2, rgb: vec![] },
            Image { width: MAX_SIZE + 1, height: 1, rgb: vec![0; 3 * (MAX_SIZE as usize + 1)] },
        ] {
            assert!(matches!(write_png(&path, &img), Err(Error::Invalid { .. })), "{}×{}", img.width, img.height);
        }
        assert!(!path.exists());
    }
}
