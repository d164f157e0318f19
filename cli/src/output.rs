//! The files that `match` and `demo` both write: the point maps (map.txt, map.npy), the colour
//! transfer (X.ply, Y.ply, render.png), and the one-line description of a configuration.

use std::path::Path;

use funcorr::matching::MatchOptions;
use funcorr::shape::Shape;
use funcorr::{Error, Result};

/// Geometry of a shape for writing (None for feature matrices of dimension ≠ 3).
pub(crate) fn mesh_data(shape: &Shape) -> Option<funcorr::io::MeshData> {
    match shape {
        Shape::Mesh(m) => {
            Some(funcorr::io::MeshData { vertices: m.vertices().to_vec(), faces: m.faces().to_vec(), colors: None })
        }
        Shape::Points(p) if p.dim() == 3 => Some(funcorr::io::MeshData {
            vertices: p.coords().chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
            faces: vec![],
            colors: None,
        }),
        Shape::Points(_) => None,
    }
}

/// Parses `WIDTHxHEIGHT` of a side-by-side render and checks it against the renderer's limits
/// (each side ≤ 16384, at most 2²⁶ pixels in all), so that a bad size fails before any work.
pub(crate) fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || Error::invalid("--size", format!("'{s}': expected WIDTHxHEIGHT, e.g. 1600x900"));
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (w, h) = (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?);
    funcorr::viz::render::check_size(w, h, 2).map_err(|e| match e {
        Error::Invalid { what, msg } => Error::invalid("--size", format!("'{s}': {what}: {msg}")),
        other => other,
    })?;
    Ok((w, h))
}

/// The colour-transfer outputs of a map: X coloured by position, Y by pulling the colours back
/// through `map_yx` (for a part X of Y, faded to grey where `coverage` is low); X.ply, Y.ply and
/// (unless `size` is None) render.png.
pub(crate) fn write_colour_transfer(
    out: &Path,
    x: &Shape,
    y: &Shape,
    map_yx: &[usize],
    coverage: Option<&[f64]>,
    render: Option<((u32, u32), &funcorr::viz::View)>,
) -> Result<()> {
    let (Some(mut dx), Some(mut dy)) = (mesh_data(x), mesh_data(y)) else {
        return Ok(());
    };
    let colors_x = funcorr::viz::position_colors(&dx.vertices);
    let mut colors_y = funcorr::viz::pull_back_colors(&colors_x, map_yx)
        .ok_or_else(|| Error::invalid("map", "the map Y → X points outside X"))?;
    // A part X of Y: the vertices of Y it does not cover fade to grey with their confidence.
    if let Some(cov) = coverage.filter(|c| c.len() == colors_y.len()) {
        for (c, &w) in colors_y.iter_mut().zip(cov) {
            let w = w.clamp(0.0, 1.0);
            *c = c.map(|v| (w * f64::from(v) + (1.0 - w) * 200.0).round() as u8);
        }
    }
    if let Some(((w, h), view)) = render {
        use funcorr::viz::{render_pair, write_png, ColoredShape};
        let sx = ColoredShape { vertices: &dx.vertices, faces: &dx.faces, colors: &colors_x };
        let sy = ColoredShape { vertices: &dy.vertices, faces: &dy.faces, colors: &colors_y };
        write_png(&out.join("render.png"), &render_pair(&sx, &sy, w, h, view)?)?;
    }
    dx.colors = Some(colors_x);
    dy.colors = Some(colors_y);
    funcorr::io::write_mesh(&out.join("X.ply"), &dx)?;
    funcorr::io::write_mesh(&out.join("Y.ply"), &dy)
}

/// map.txt (one vertex of Y per line, 0- or 1-based) and map.npy (0-based, u64).
pub(crate) fn write_map_files(out: &Path, map_xy: &[usize], one_based: bool) -> Result<()> {
    let base = usize::from(one_based);
    let text: String = map_xy.iter().map(|j| format!("{}\n", j + base)).collect();
    let p = out.join("map.txt");
    funcorr::io::write_atomic(&p, text)?;
    funcorr::io::npy::write_npy_vec_u64(&out.join("map.npy"), &map_xy.iter().map(|&j| j as u64).collect::<Vec<_>>())
}

/// One line saying what a match configuration does.
pub(crate) fn describe(data: &str, opts: &MatchOptions) -> String {
    use funcorr::matching::{Method, Refine as R};
    let method = match opts.method {
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            return format!(
                "data {} + {} signed, axiomatic functional maps (k = {:?}, orientation {:?}), best of the candidates after ZoomOut to {}, ZoomOut to {}{}",
                data,
                a.signed,
                a.candidates,
                a.fit.orientation,
                a.probe.k_final,
                a.refine.k_final,
                match a.polish {
                    0 => String::new(),
                    r => format!(", {r} round(s) of bijective polish"),
                }
            );
        }
        Method::Fmap if opts.commutativity > 0.0 => {
            format!("eq. (5) with Laplacian commutativity μ_c = {}, k = {}", opts.commutativity, opts.k)
        }
        Method::Fmap => format!("eq. (5), k = {}", opts.k),
        Method::Pokrass => format!("Pokrass et al. eq. (6), k = {}", opts.k),
        Method::Coupled => format!("coupled bases eq. (7), k = {}", opts.k),
        Method::Completion => format!(
            "matrix completion {:?} k' = {}, k = {}",
            opts.completion.form, opts.completion.k_prime, opts.completion.k
        ),
    };
    let refine = match opts.refine {
        R::None => "no refinement".to_string(),
        R::Icp => format!("ICP ({} iterations at most)", opts.icp.max_iterations),
        R::Zoomout => format!("ZoomOut to {} in steps of {}", opts.zoomout_to, opts.zoomout_step),
    };
    format!("data {}, {method}, {refine}", data)
}
