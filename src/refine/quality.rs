//! The quality of a point map X → Y, measured without ground truth (the measures the default
//! pipeline selects candidates with): orientation agreement, metric distortion on edges (both
//! also around samples only), per-vertex orientation, and the repair of mirrored parts by a
//! symmetry of Y.

use faer::MatRef;

use crate::error::{Error, Result};
use crate::shape::TriMesh;

/// Orientation agreement of a point map X → Y, in [−1, 1]: the area-weighted mean over the
/// triangles of X of the sign of ⟨n', N⟩, n' the normal of the image triangle (π(a), π(b), π(c))
/// and N the sum of Y's vertex normals at its corners (0 for a degenerate image). Near +1 for an
/// orientation-preserving map, near −1 for a mirrored one; a map mirrored on part of the shape
/// scores in between. `y_normals` are Y's unit vertex normals (length m).
pub fn orientation_agreement(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
) -> Result<f64> {
    orientation_on_faces(x, y_vertices, y_normals, map_xy, None)
}

/// [`orientation_agreement`] estimated from the triangles of X incident to the vertices
/// `centres`; `map_xy` needs to be right only on their corners ([`incident_vertices`]). Errors
/// as [`orientation_agreement`], and for a centre ≥ n.
pub fn orientation_agreement_around(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
    centres: &[usize],
) -> Result<f64> {
    let mark = centre_marks(x.n_vertices(), centres)?;
    orientation_on_faces(x, y_vertices, y_normals, map_xy, Some(&mark))
}

/// [`orientation_agreement`] over every triangle, or over those with a corner marked in `around`.
fn orientation_on_faces(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
    around: Option<&[bool]>,
) -> Result<f64> {
    let (n, m) = (x.n_vertices(), y_vertices.len());
    if map_xy.len() != n || y_normals.len() != m {
        return Err(Error::invalid(
            "map",
            format!(
                "{} entries for {n} vertices of X; {} normals for {m} vertices of Y",
                map_xy.len(),
                y_normals.len()
            ),
        ));
    }
    if map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("it points to a vertex ≥ m = {m}")));
    }
    let areas = x.face_areas();
    let (mut sum, mut total) = (0.0, 0.0);
    for (f, tri) in x.faces().iter().enumerate() {
        if around.is_some_and(|mark| !tri.iter().any(|&v| mark[v as usize])) {
            continue;
        }
        let [a, b, c] = tri.map(|v| map_xy[v as usize]);
        total += areas[f];
        if a == b || b == c || a == c {
            continue;
        }
        let (pa, pb, pc) = (y_vertices[a], y_vertices[b], y_vertices[c]);
        let u = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
        let v = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
        let nrm = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        let nsum: [f64; 3] = std::array::from_fn(|d| y_normals[a][d] + y_normals[b][d] + y_normals[c][d]);
        let dot = nrm[0] * nsum[0] + nrm[1] * nsum[1] + nrm[2] * nsum[2];
        if dot > 0.0 {
            sum += areas[f];
        } else if dot < 0.0 {
            sum -= areas[f];
        }
    }
    Ok(if total > 0.0 { sum / total } else { 0.0 })
}

/// Metric distortion of a point map X → Y on the edges of X's surface (mesh or point-cloud
/// triangulation): Σ_edges |‖y_π(i) − y_π(j)‖ − s ‖x_i − x_j‖| / Σ_edges s ‖x_i − x_j‖, with
/// s = √(area_Y / area_X) the scale between the shapes (`scale`). 0 for an isometry at the
/// resolution of the edges; a map that tears (neighbours sent far apart, as where a limb is
/// matched to the wrong one) or collapses (neighbours sent to one vertex) scores higher. The
/// chord lengths stand in for geodesic ones, exact enough at edge scale.
pub fn metric_distortion(x: &TriMesh, y_positions: &[[f64; 3]], scale: f64, map_xy: &[usize]) -> Result<f64> {
    distortion_on_edges(x, y_positions, scale, map_xy, None)
}

/// [`metric_distortion`] estimated from the edges of X incident to the vertices `centres` (e.g.
/// farthest-point samples): the same ratio, summed over those edges only. `map_xy` (length n)
/// needs to be right only on their endpoints ([`incident_vertices`]); its other entries are
/// read as vertex ids of Y but do not enter the result. Errors as [`metric_distortion`], and for
/// a centre ≥ n.
pub fn metric_distortion_around(
    x: &TriMesh,
    y_positions: &[[f64; 3]],
    scale: f64,
    map_xy: &[usize],
    centres: &[usize],
) -> Result<f64> {
    let mark = centre_marks(x.n_vertices(), centres)?;
    distortion_on_edges(x, y_positions, scale, map_xy, Some(&mark))
}

/// The vertices of X on the triangles incident to `centres` (the centres and their one-ring
/// neighbours), ascending: where [`metric_distortion_around`] and
/// [`orientation_agreement_around`] read the map. Ids ≥ n are ignored.
pub fn incident_vertices(x: &TriMesh, centres: &[usize]) -> Vec<usize> {
    let n = x.n_vertices();
    let mut mark = vec![false; n];
    centres.iter().filter(|&&v| v < n).for_each(|&v| mark[v] = true);
    let mut keep = mark.clone();
    for tri in x.faces() {
        if tri.iter().any(|&v| mark[v as usize]) {
            tri.iter().for_each(|&v| keep[v as usize] = true);
        }
    }
    (0..n).filter(|&v| keep[v]).collect()
}

/// A mask of length n, true at the `centres`.
fn centre_marks(n: usize, centres: &[usize]) -> Result<Vec<bool>> {
    if centres.iter().any(|&v| v >= n) {
        return Err(Error::invalid("centres", format!("a vertex id is ≥ n = {n}")));
    }
    let mut mark = vec![false; n];
    centres.iter().for_each(|&v| mark[v] = true);
    Ok(mark)
}

/// [`metric_distortion`] over every edge, or over the edges with an end marked in `around`.
fn distortion_on_edges(
    x: &TriMesh,
    y_positions: &[[f64; 3]],
    scale: f64,
    map_xy: &[usize],
    around: Option<&[bool]>,
) -> Result<f64> {
    let (n, m) = (x.n_vertices(), y_positions.len());
    if map_xy.len() != n || map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("need {n} entries < m = {m}")));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid("scale", format!("must be finite and > 0, got {scale}")));
    }
    let xv = x.vertices();
    let dist =
        |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let (mut num, mut den) = (0.0, 0.0);
    for e in x.edges() {
        let (i, j) = (e[0] as usize, e[1] as usize);
        if around.is_some_and(|mark| !mark[i] && !mark[j]) {
            continue;
        }
        let dx = scale * dist(xv[i], xv[j]);
        num += (dist(y_positions[map_xy[i]], y_positions[map_xy[j]]) - dx).abs();
        den += dx;
    }
    Ok(if den > 0.0 { num / den } else { 0.0 })
}

/// Per-vertex orientation of a point map X → Y, in [−1, 1] (length n): at every vertex of X the
/// area-weighted mean over its triangles of the sign of [`orientation_agreement`]'s test (+1
/// where the map preserves orientation, −1 where it mirrors, 0 where the images degenerate).
pub fn vertex_orientation(
    x: &TriMesh,
    y_vertices: &[[f64; 3]],
    y_normals: &[[f64; 3]],
    map_xy: &[usize],
) -> Result<Vec<f64>> {
    let (n, m) = (x.n_vertices(), y_vertices.len());
    if map_xy.len() != n || y_normals.len() != m || map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("need {n} entries < m = {m} and {m} normals")));
    }
    let areas = x.face_areas();
    let mut num = vec![0.0; n];
    let mut den = vec![0.0; n];
    for (f, tri) in x.faces().iter().enumerate() {
        let [a, b, c] = tri.map(|v| map_xy[v as usize]);
        let sign = if a == b || b == c || a == c {
            0.0
        } else {
            let (pa, pb, pc) = (y_vertices[a], y_vertices[b], y_vertices[c]);
            let u = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
            let v = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
            let nrm = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let d: f64 = (0..3).map(|k| nrm[k] * (y_normals[a][k] + y_normals[b][k] + y_normals[c][k])).sum();
            d.signum() * f64::from(u8::from(d != 0.0))
        };
        for &i in tri {
            num[i as usize] += areas[f] * sign;
            den[i as usize] += areas[f];
        }
    }
    Ok(num.iter().zip(&den).map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 }).collect())
}

/// A function on X low-passed to its first k eigenfunctions: Φ_k Φ_kᵀ A v (length n).
pub fn low_pass(phi: MatRef<f64>, mass: &[f64], v: &[f64], k: usize) -> Vec<f64> {
    let k = k.min(phi.ncols());
    let n = phi.nrows();
    let coef: Vec<f64> = (0..k).map(|c| (0..n).map(|i| phi[(i, c)] * mass[i] * v[i]).sum()).collect();
    (0..n).map(|i| (0..k).map(|c| phi[(i, c)] * coef[c]).sum()).collect()
}

/// Repairs the mirrored parts of a point map X → Y with the intrinsic symmetry s_Y of Y
/// (`sym_y`, length m, an orientation-reversing involution): where the map mirrors
/// (`orientation[i] < 0`, e.g. the low-passed [`vertex_orientation`]), π(i) = s_Y(π_true(i)), so
/// π_true(i) = s_Y(π(i)). Returns the repaired map and the number of vertices changed.
pub fn repair_mirrored(map_xy: &[usize], orientation: &[f64], sym_y: &[usize]) -> Result<(Vec<usize>, usize)> {
    if orientation.len() != map_xy.len()
        || map_xy.iter().any(|&j| j >= sym_y.len())
        || sym_y.iter().any(|&j| j >= sym_y.len())
    {
        return Err(Error::invalid("repair", "map, orientation and symmetry sizes do not agree"));
    }
    let mut changed = 0;
    let out = map_xy
        .iter()
        .zip(orientation)
        .map(|(&j, &o)| {
            if o < 0.0 {
                changed += 1;
                sym_y[j]
            } else {
                j
            }
        })
        .collect();
    Ok((out, changed))
}
