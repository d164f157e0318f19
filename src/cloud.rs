//! Point clouds as surfaces: normals, a consistent orientation and local triangulations, from
//! which [`cloud_laplacian`] builds a Laplacian whose spectrum and mass agree with
//! the cotangent Laplacian of the sampled surface, and [`crate::operators::FaceGradients`] the
//! gradients the orientation-aware functional maps need.
//!
//! The construction follows Sharp & Crane 2020 ("A Laplacian for nonmanifold triangle meshes",
//! §5.5, robust-laplacian's point-cloud Laplacian):
//! 1. the K nearest neighbours of every point (K = 30);
//! 2. its normal by principal component analysis of the nearest [`NORMAL_NEIGHBOURS`] of them;
//! 3. the neighbours on the point's own side of the surface (oriented normals at an acute angle)
//!    projected to the tangent plane, and the triangles of their 2-D Delaunay triangulation that
//!    contain the point (its Delaunay "fan");
//! 4. the union of all fans: a triangle soup covering the surface about three times (once from
//!    each corner whose fan contains it), so its Laplacian and mass are divided by 3.
//!
//! Three choices are our own: the same-side filter of step 3 (see `same_side_neighbours`), and
//! two more. The Delaunay neighbours of the centre are found by inversion: the
//! half-plane bisectors of the Voronoi cell of the origin are x · p ≤ |p|²/2, i.e. x · q ≤ 1/2 with
//! q = p / |p|², and the non-redundant ones are the vertices of the convex hull of {0} ∪ {q}
//! (a few lines instead of a general Delaunay code). And the normals are oriented consistently
//! (Hoppe et al. 1992: propagation along a minimum spanning tree of the graph of the
//! [`ORIENTATION_NEIGHBOURS`] nearest neighbours, with a cost that also charges edges leaving the
//! tangent planes, so that it does not cross thin gaps; then per connected component the sign
//! that makes the soup's enclosed volume positive), so the fans form an oriented soup and the
//! orientation term of the functional maps works on clouds as on meshes — where the cloud
//! resolves the surface: where two sides of a thin part are closer than the sample spacing
//! (a 5k-vertex body's fingers and toes), no normal estimate from the points alone can tell them
//! apart, and a few percent of the normals stay reversed (EXPERIMENTS.md, "Point clouds").
//! Robust-laplacian then flips the soup (its "tufted cover") to intrinsic Delaunay; we keep
//! the fans as they are: each is Delaunay in its tangent plane already, and the spectra agree
//! with the mesh's to within the tolerances of the tests (see `tests` and EXPERIMENTS.md).

use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::laplacian::{cotangent, Laplacian, LaplacianKind};
use crate::shape::{TriMesh, UnionFind};

/// Default number of neighbours of the local triangulations (robust-laplacian's default).
pub const DEFAULT_NEIGHBOURS: usize = 30;

/// Neighbours whose principal components give a point's normal (at most K). Fewer than the
/// triangulation's K: on a sparse sample of a thin part (a 5k-vertex body's hands, feet and
/// limbs) 30 neighbours wrap around it, and the normals and their orientation go wrong there
/// (measured in EXPERIMENTS.md, "Point clouds": FAUST vertex clouds, 18.3 % of the normals
/// oriented against the mesh's with 30, 5.4 % with 10 for the normals and 6 for the orientation).
pub const NORMAL_NEIGHBOURS: usize = 10;

/// Neighbours along which the normals' orientation is propagated (at most K): about the valence
/// of a triangulation (6 on average by Euler's formula), so that the propagation graph follows
/// the surface rather than jumping across thin parts.
pub const ORIENTATION_NEIGHBOURS: usize = 6;

/// A point cloud's surface: consistently oriented unit normals and the union of its local
/// Delaunay fans as a triangle soup on the same points.
#[derive(Debug, Clone)]
pub struct CloudSurface {
    /// The soup: vertices are the points, faces the fans' triangles (oriented along the normals;
    /// duplicates kept).
    pub soup: TriMesh,
    /// Unit normal of every point (n × 3), consistently oriented, outward for closed surfaces.
    pub normals: Vec<[f64; 3]>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        [a[0] / l, a[1] / l, a[2] / l]
    } else {
        [0.0; 3]
    }
}

/// The eigenvector of the smallest eigenvalue of a symmetric 3 × 3 matrix (Jacobi rotations;
/// written out because a general eigensolver costs more than the whole neighbourhood here).
fn smallest_eigenvector(mut a: [[f64; 3]; 3]) -> [f64; 3] {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let scale = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= 1e-15 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J with the rotation J in the (p, q) plane.
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let i = (0..3).min_by(|&x, &y| a[x][x].total_cmp(&a[y][y])).expect("three");
    normalize([v[0][i], v[1][i], v[2][i]])
}

/// K nearest neighbours of every point (excluding itself), ascending by distance.
fn neighbours(points: &[[f64; 3]], k: usize) -> Result<Vec<Vec<usize>>> {
    let n = points.len();
    if k < 3 || k >= n {
        return Err(Error::invalid("neighbours", format!("need 3 ≤ K < n = {n}, got {k}")));
    }
    Ok(crate::spatial::knn3(points, k).into_iter().map(|nb| nb.into_iter().map(|(_, j)| j).collect()).collect())
}

/// PCA normal of point i from its neighbourhood (unit; sign arbitrary).
fn pca_normal(points: &[[f64; 3]], i: usize, nb: &[usize]) -> [f64; 3] {
    let m = (nb.len() + 1) as f64;
    let mut c = points[i];
    for &j in nb {
        for d in 0..3 {
            c[d] += points[j][d];
        }
    }
    c = [c[0] / m, c[1] / m, c[2] / m];
    let mut cov = [[0.0; 3]; 3];
    for &j in nb.iter().chain(std::iter::once(&i)) {
        let p = sub(points[j], c);
        for r in 0..3 {
            for s in 0..3 {
                cov[r][s] += p[r] * p[s];
            }
        }
    }
    smallest_eigenvector(cov)
}

/// Indices (into `q`) of the vertices of the convex hull of {0} ∪ {q}, origin excluded, by
/// Andrew's monotone chain; collinear points on the hull are dropped.
fn hull_without_origin(q: &[[f64; 2]]) -> Vec<usize> {
    let mut pts: Vec<(f64, f64, Option<usize>)> = q.iter().enumerate().map(|(i, p)| (p[0], p[1], Some(i))).collect();
    pts.push((0.0, 0.0, None));
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let turn = |o: &(f64, f64, Option<usize>), a: &(f64, f64, Option<usize>), b: &(f64, f64, Option<usize>)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut hull: Vec<(f64, f64, Option<usize>)> = Vec::with_capacity(2 * pts.len());
    // Lower hull, then upper hull without popping into the lower one.
    for p in &pts {
        while hull.len() >= 2 && turn(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(*p);
    }
    let lower = hull.len() + 1;
    for p in pts.iter().rev().skip(1) {
        while hull.len() >= lower && turn(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(*p);
    }
    hull.pop();
    let mut out: Vec<usize> = hull.into_iter().filter_map(|p| p.2).collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The Delaunay fan of point i: triangles (i, a, b) of the 2-D Delaunay triangulation of its
/// neighbours projected on the tangent plane of `normal`, counter-clockwise about the normal.
fn delaunay_fan(points: &[[f64; 3]], i: usize, nb: &[usize], normal: [f64; 3]) -> Vec<[u32; 3]> {
    // Tangent basis (u, v) with u × v = normal.
    let helper = if normal[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let u = normalize(cross(helper, normal));
    let v = cross(normal, u);
    let coords: Vec<[f64; 2]> = nb
        .iter()
        .map(|&j| {
            let d = sub(points[j], points[i]);
            [dot(d, u), dot(d, v)]
        })
        .collect();
    let scale = coords.iter().map(|c| c[0].hypot(c[1])).fold(0.0f64, f64::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return vec![];
    }
    // Inversion about the centre; coincident neighbours (|p| ≈ 0) cannot be Delaunay
    // neighbours of a distinct centre and are left out.
    let mut keep = Vec::with_capacity(nb.len());
    let mut inverted = Vec::with_capacity(nb.len());
    for (s, c) in coords.iter().enumerate() {
        let r2 = (c[0] * c[0] + c[1] * c[1]) / (scale * scale);
        if r2 > 1e-16 {
            keep.push(s);
            inverted.push([c[0] / scale / r2, c[1] / scale / r2]);
        }
    }
    let mut ring: Vec<(f64, usize)> = hull_without_origin(&inverted)
        .into_iter()
        .map(|h| (coords[keep[h]][1].atan2(coords[keep[h]][0]), keep[h]))
        .collect();
    if ring.len() < 2 {
        return vec![];
    }
    ring.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut fan = Vec::with_capacity(ring.len());
    for t in 0..ring.len() {
        let (a0, a) = ring[t];
        let (b0, b) = ring[(t + 1) % ring.len()];
        let mut gap = b0 - a0;
        if gap <= 0.0 {
            gap += std::f64::consts::TAU;
        }
        // A gap of π or more is open boundary, not a triangle.
        if gap < std::f64::consts::PI - 1e-9 && gap > 1e-12 {
            fan.push([i as u32, nb[a] as u32, nb[b] as u32]);
        }
    }
    fan
}

/// The symmetric kNN graph: j ∈ adj[i] iff j is among i's neighbours or i among j's (sorted,
/// no duplicates).
fn symmetric(nbrs: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let mut adj: Vec<Vec<usize>> = nbrs.to_vec();
    for (i, nb) in nbrs.iter().enumerate() {
        for &j in nb {
            adj[j].push(i);
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    adj
}

/// Cost of propagating a normal's sign along the kNN edge (i, j) (Hoppe et al. 1992's
/// Riemannian graph, made aware of thin gaps): 1 − |n_i · n_j| (the normals' lines differ) plus
/// (n_i · e)² + (n_j · e)² with e the unit offset p_j − p_i (the edge leaves the tangent planes).
/// Across a thin gap — two sheets of the surface closer than the neighbourhood's radius, as between
/// the legs or fingers of a body — the normals are nearly parallel lines, so Hoppe's cost alone
/// is ≈ 0 there and the propagation crosses the gap and flips the far sheet; the offset of such an
/// edge runs along both normals, which the second term charges ≈ 2. On a smooth, densely sampled
/// sheet every term is O((κ h)²) for curvature κ and spacing h.
fn propagation_cost(points: &[[f64; 3]], normals: &[[f64; 3]], i: usize, j: usize) -> f64 {
    let e = normalize(sub(points[j], points[i]));
    let (a, b) = (dot(normals[i], e), dot(normals[j], e));
    1.0 - dot(normals[i], normals[j]).abs() + a * a + b * b
}

/// Orients the normals consistently: from the point of each connected component of the kNN
/// graph with the largest x coordinate, propagation along a minimum spanning tree of
/// [`propagation_cost`], flipping a normal whenever it disagrees with its tree parent.
fn propagate_orientation(points: &[[f64; 3]], nbrs: &[Vec<usize>], normals: &mut [[f64; 3]]) {
    let n = points.len();
    let mut done = vec![false; n];
    #[derive(PartialEq)]
    struct Item(f64, usize, usize);
    impl Eq for Item {}
    impl PartialOrd for Item {
        fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Item {
        fn cmp(&self, o: &Self) -> std::cmp::Ordering {
            self.0.total_cmp(&o.0).then(o.1.cmp(&self.1)).then(o.2.cmp(&self.2))
        }
    }
    let adj = symmetric(nbrs);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| points[b][0].total_cmp(&points[a][0]).then(a.cmp(&b)));
    for &root in &order {
        if done[root] {
            continue;
        }
        // The extreme point in x: its normal points to +x on a closed surface.
        if normals[root][0] < 0.0 {
            normals[root] = [-normals[root][0], -normals[root][1], -normals[root][2]];
        }
        done[root] = true;
        let mut heap = BinaryHeap::new();
        for &j in &adj[root] {
            heap.push(Item(-propagation_cost(points, normals, root, j), j, root));
        }
        while let Some(Item(_, j, parent)) = heap.pop() {
            if done[j] {
                continue;
            }
            done[j] = true;
            if dot(normals[parent], normals[j]) < 0.0 {
                normals[j] = [-normals[j][0], -normals[j][1], -normals[j][2]];
            }
            for &k in &adj[j] {
                if !done[k] {
                    heap.push(Item(-propagation_cost(points, normals, j, k), k, j));
                }
            }
        }
    }
}

/// Consistently oriented normals of a cloud whose normals are given but whose signs cannot be
/// trusted (a scanner's or a file's normals, some of them reversed): the lines of `normals` are
/// kept, their signs are chosen by the same propagation as [`cloud_surface`]'s (a minimum spanning
/// tree of `propagation_cost` over the [`ORIENTATION_NEIGHBOURS`] nearest neighbours, from the
/// point of each component with the largest x, whose normal is made to point to +x — outward on
/// a closed surface). Any share of reversed inputs gives the same result: only the lines are used.
///
/// `points` n × 3, `normals` n × 3 (any nonzero length; returned unit length). Errors: sizes that
/// differ, fewer than [`ORIENTATION_NEIGHBOURS`] + 1 points, a non-finite coordinate, or a zero or
/// non-finite normal, naming the point.
pub fn orient_normals(points: &[[f64; 3]], normals: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
    if normals.len() != points.len() {
        return Err(Error::invalid(
            "normals",
            format!("{} normals for {} points (one per point is needed)", normals.len(), points.len()),
        ));
    }
    if let Some(i) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::invalid("points", format!("point {i} has a non-finite coordinate")));
    }
    let mut unit = Vec::with_capacity(normals.len());
    for (i, nrm) in normals.iter().enumerate() {
        let len = dot(*nrm, *nrm).sqrt();
        if !(len.is_finite() && len > 0.0) {
            return Err(Error::invalid("normals", format!("normal {i} is zero or not finite: {nrm:?}")));
        }
        unit.push([nrm[0] / len, nrm[1] / len, nrm[2] / len]);
    }
    let nbrs = neighbours(points, ORIENTATION_NEIGHBOURS)?;
    propagate_orientation(points, &nbrs, &mut unit);
    Ok(unit)
}

/// The neighbours of every point on its own side of the surface: those whose oriented normal
/// makes an acute angle with its own (n_i · n_j > 0). Across a thin gap the far sheet faces the
/// other way (n_i · n_j ≈ −1); its points project into the tangent plane near the centre and
/// would otherwise join the local triangulation, short-circuiting the two sheets. A point left
/// with fewer than 3 such neighbours keeps all of them.
fn same_side_neighbours(nbrs: &[Vec<usize>], normals: &[[f64; 3]]) -> Vec<Vec<usize>> {
    nbrs.iter()
        .enumerate()
        .map(|(i, nb)| {
            let same: Vec<usize> = nb.iter().copied().filter(|&j| dot(normals[i], normals[j]) > 0.0).collect();
            if same.len() >= 3 {
                same
            } else {
                nb.clone()
            }
        })
        .collect()
}

impl CloudSurface {
    /// Area of the surface: the soup's area / 3 (every part of the surface is covered by the fans
    /// of about three points).
    pub fn area(&self) -> f64 {
        self.soup.total_area() / 3.0
    }

    /// Geodesic distances on the cloud: shortest paths along the edges of its local
    /// triangulation (Euclidean edge lengths), the cloud counterpart of Dijkstra on mesh edges.
    /// Overestimates the surface distance by the edge-path detour, like Dijkstra on a mesh.
    pub fn geodesics(&self) -> Result<crate::geodesic::GraphGeodesics> {
        crate::geodesic::GraphGeodesics::mesh_edges(&self.soup)
    }
}

/// The surface of a point cloud (n × 3): consistently oriented normals and the union of the
/// local Delaunay fans over K nearest neighbours (module docs). Errors: fewer than K + 1 points,
/// K < 3, non-finite coordinates, a point whose neighbourhood spans no plane (all its
/// neighbours collinear or coincident), or no triangle at all.
pub fn cloud_surface(points: &[[f64; 3]], k: usize) -> Result<CloudSurface> {
    if let Some(i) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::invalid("points", format!("point {i} has a non-finite coordinate")));
    }
    let nbrs = neighbours(points, k)?;
    // The nearest neighbours come first in every list (ascending distance).
    let nearest = |count: usize| -> Vec<Vec<usize>> { nbrs.iter().map(|nb| nb[..count.min(k)].to_vec()).collect() };
    let near = nearest(NORMAL_NEIGHBOURS);
    let mut normals: Vec<[f64; 3]> =
        (0..points.len()).into_par_iter().map(|i| pca_normal(points, i, &near[i])).collect();
    propagate_orientation(points, &nearest(ORIENTATION_NEIGHBOURS), &mut normals);
    let nbrs = same_side_neighbours(&nbrs, &normals);
    let fans: Vec<Vec<[u32; 3]>> =
        (0..points.len()).into_par_iter().map(|i| delaunay_fan(points, i, &nbrs[i], normals[i])).collect();
    if let Some(i) = fans.iter().position(|f| f.is_empty()) {
        return Err(Error::invalid(
            "points",
            format!("point {i}: its {k} nearest neighbours span no plane (collinear or coincident points)"),
        ));
    }
    let faces: Vec<[u32; 3]> = fans.into_iter().flatten().collect();
    let soup = TriMesh::new(points.to_vec(), faces)?;
    // Per connected component, outward orientation: positive enclosed volume.
    let (count, labels) = {
        let mut uf = UnionFind::new(points.len());
        for f in soup.faces() {
            uf.union(f[0], f[1]);
            uf.union(f[1], f[2]);
        }
        uf.labels()
    };
    let mut volume = vec![0.0; count];
    for f in soup.faces() {
        let [a, b, c] = f.map(|v| points[v as usize]);
        volume[labels[f[0] as usize] as usize] += dot(a, cross(b, c)) / 6.0;
    }
    let flip: Vec<bool> = volume.iter().map(|&v| v < 0.0).collect();
    let faces: Vec<[u32; 3]> = soup
        .faces()
        .iter()
        .map(|&f| if flip[labels[f[0] as usize] as usize] { [f[0], f[2], f[1]] } else { f })
        .collect();
    for (i, nrm) in normals.iter_mut().enumerate() {
        if flip[labels[i] as usize] {
            *nrm = [-nrm[0], -nrm[1], -nrm[2]];
        }
    }
    Ok(CloudSurface { soup: TriMesh::new(points.to_vec(), faces)?, normals })
}

/// The point-cloud Laplacian of Sharp & Crane 2020 (robust-laplacian's): the cotangent Laplacian
/// and barycentric mass of the union of the local Delaunay fans of K nearest neighbours
/// ([`cloud_surface`]), divided by 3 because that soup covers the surface about
/// three times. Its spectrum and mass agree with the cotangent Laplacian of the sampled surface
/// (units: the coordinates'), so descriptors and maps are comparable between a mesh and a cloud.
/// Returns the Laplacian (n × n for the n points) and the surface (normals and soup, for
/// gradients and orientation). Errors: those of [`cloud_surface`] and of [`cotangent`].
pub fn cloud_laplacian(points: &[[f64; 3]], k: usize) -> Result<(Laplacian, CloudSurface)> {
    let surface = cloud_surface(points, k)?;
    let mut lap = cotangent(&surface.soup)?;
    for v in lap.w.val_mut() {
        *v /= 3.0;
    }
    for a in &mut lap.mass {
        *a /= 3.0;
    }
    lap.kind = LaplacianKind::PointCloud;
    Ok((lap, surface))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{bumpy_sphere, icosphere};

    #[test]
    fn jacobi_finds_the_smallest_eigenvector() {
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 0.1]];
        let v = smallest_eigenvector(a);
        let av: Vec<f64> = (0..3).map(|r| (0..3).map(|c| a[r][c] * v[c]).sum()).collect();
        let lambda = dot(v, [av[0], av[1], av[2]]);
        for r in 0..3 {
            assert!((av[r] - lambda * v[r]).abs() < 1e-10);
        }
        assert!(lambda < 0.1);
    }

    #[test]
    fn planar_fan_is_the_delaunay_one_ring() {
        // A centre with six neighbours on a hexagon and two far points: the fan is the six
        // hexagon triangles.
        let mut pts = vec![[0.0, 0.0, 0.0]];
        for t in 0..6 {
            let a = t as f64 * std::f64::consts::PI / 3.0;
            pts.push([a.cos(), a.sin(), 0.0]);
        }
        pts.push([3.0, 0.1, 0.0]);
        pts.push([-3.0, 0.2, 0.0]);
        let nb: Vec<usize> = (1..pts.len()).collect();
        let fan = delaunay_fan(&pts, 0, &nb, [0.0, 0.0, 1.0]);
        assert_eq!(fan.len(), 6, "{fan:?}");
        for t in &fan {
            assert!(t[1] <= 6 && t[2] <= 6);
            let nrm = cross(sub(pts[t[1] as usize], pts[0]), sub(pts[t[2] as usize], pts[0]));
            assert!(nrm[2] > 0.0, "counter-clockwise about +z");
        }
        // On a boundary (neighbours on one side only) the fan is open.
        let half: Vec<usize> = vec![1, 2, 3, 4];
        assert_eq!(delaunay_fan(&pts, 0, &half, [0.0, 0.0, 1.0]).len(), 3);
    }

    #[test]
    fn sphere_normals_point_outward_and_the_soup_covers_three_times() {
        let s = bumpy_sphere(3);
        let surf = cloud_surface(s.vertices(), DEFAULT_NEIGHBOURS).unwrap();
        let mesh_normals = s.vertex_normals();
        let agree = surf.normals.iter().zip(&mesh_normals).filter(|(a, b)| dot(**a, **b) > 0.5).count();
        assert_eq!(agree, s.n_vertices(), "every normal outward and close to the mesh's");
        let ratio = surf.soup.total_area() / s.total_area();
        assert!((ratio - 3.0).abs() < 0.15, "soup area / surface area = {ratio}");
        // Every soup triangle faces outward.
        let face_normals = surf.soup.face_normals();
        let out = face_normals.iter().enumerate().filter(|(f, nrm)| {
            let c = surf.soup.corners(*f);
            dot(**nrm, [c[0][0] + c[1][0] + c[2][0], c[0][1] + c[1][1] + c[2][1], c[0][2] + c[1][2] + c[2][2]]) > 0.0
        });
        assert_eq!(out.count(), surf.soup.n_faces());
    }

    /// Thin parts of a sparse sample: the bundled FAUST shapes (5k vertices) as vertex clouds,
    /// whose hands, feet and limbs are only a few samples across. With normals and orientation
    /// from all 30 neighbours (and Hoppe's cost alone) 17.8 % and 16.0 % of the normals came out
    /// reversed against the mesh's; with the nearest 10 / 6 and the tangent-aware cost 12.0 % and
    /// 3.2 % (measured when this test was written; EXPERIMENTS.md has all 50 shapes).
    #[test]
    fn sparse_thin_parts_keep_most_normals_oriented() {
        let (mut reversed, mut total) = (0, 0);
        for name in ["tr_reg_000", "tr_reg_001"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(format!("{name}.off"));
            let crate::shape::Shape::Mesh(m) = crate::shape::Shape::load(&path).unwrap() else { panic!("a mesh") };
            let surf = cloud_surface(m.vertices(), DEFAULT_NEIGHBOURS).unwrap();
            reversed += surf.normals.iter().zip(&m.vertex_normals()).filter(|(a, b)| dot(**a, **b) <= 0.0).count();
            total += m.n_vertices();
        }
        let share = reversed as f64 / total as f64;
        assert!(share < 0.10, "{:.1} % of the normals reversed (30-neighbour orientation: 16.9 %)", 100.0 * share);
    }

    /// On the unit sphere the cloud's area is close to the mesh's, and its edge-path geodesics
    /// are at most 1 % below the great-circle distance and overestimate it no more than Dijkstra
    /// on the mesh's own edges does.
    #[test]
    fn cloud_area_and_geodesics_match_the_surface() {
        use crate::geodesic::Distances;
        let s = icosphere(4);
        let surf = cloud_surface(s.vertices(), DEFAULT_NEIGHBOURS).unwrap();
        assert!((surf.area() / s.total_area() - 1.0).abs() < 0.05, "{} vs {}", surf.area(), s.total_area());
        let geo = surf.geodesics().unwrap();
        let d = geo.distances_from(&[0]).unwrap();
        let mesh_edges = crate::geodesic::GraphGeodesics::mesh_edges(&s).unwrap().distances_from(&[0]).unwrap();
        let p0 = s.vertices()[0];
        let r0 = dot(p0, p0).sqrt();
        let (mut worst, mut worst_mesh) = (0.0f64, 0.0f64);
        for (j, p) in s.vertices().iter().enumerate().skip(1) {
            let cos = (dot(p0, *p) / (r0 * dot(*p, *p).sqrt())).clamp(-1.0, 1.0);
            let great_circle = r0 * cos.acos();
            if great_circle > 0.5 {
                // Paths of straight chords may undercut the arc slightly (chord/arc ≥ 0.99 for
                // the fans' edges here).
                let rel = d[(j, 0)] / great_circle - 1.0;
                assert!(rel > -0.01, "a path {rel} shorter than the great circle at {j}");
                worst = worst.max(rel);
                worst_mesh = worst_mesh.max(mesh_edges[(j, 0)] / great_circle - 1.0);
            }
        }
        // The fans have more edges than the mesh: their paths are no worse than the mesh's.
        assert!(worst <= worst_mesh + 0.01, "cloud paths overestimate by up to {worst}, mesh edges by {worst_mesh}");
    }

    /// Given normals with 10 % of them reversed (seeded), the orientation makes them consistent
    /// again: on a smooth sphere every one outward, and on the bundled FAUST vertex clouds (thin
    /// hands and feet a few samples across) all but a small share.
    #[test]
    fn normals_with_a_tenth_reversed_are_oriented_consistently() {
        let reverse_a_tenth = |normals: &[[f64; 3]], seed: u64| -> (Vec<[f64; 3]>, usize) {
            let mut rng = crate::rng::Normal::new(seed);
            let mut flipped = 0;
            let out = normals
                .iter()
                .map(|&n| {
                    if rng.uniform() < 0.1 {
                        flipped += 1;
                        [-n[0], -n[1], -n[2]]
                    } else {
                        n
                    }
                })
                .collect();
            (out, flipped)
        };
        let s = bumpy_sphere(3);
        let truth = s.vertex_normals();
        let (given, flipped) = reverse_a_tenth(&truth, 1);
        assert!(flipped * 20 > truth.len() && flipped * 7 < truth.len(), "{flipped} of {} reversed", truth.len());
        let oriented = orient_normals(s.vertices(), &given).unwrap();
        assert!(oriented.iter().zip(&truth).all(|(a, b)| dot(*a, *b) > 0.999), "every normal outward, lines kept");

        let (mut reversed, mut total) = (0, 0);
        for (seed, name) in [(2, "tr_reg_000"), (3, "tr_reg_001")] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(format!("{name}.off"));
            let crate::shape::Shape::Mesh(m) = crate::shape::Shape::load(&path).unwrap() else { panic!("a mesh") };
            let truth = m.vertex_normals();
            let (given, _) = reverse_a_tenth(&truth, seed);
            let oriented = orient_normals(m.vertices(), &given).unwrap();
            reversed += oriented.iter().zip(&truth).filter(|(a, b)| dot(**a, **b) <= 0.0).count();
            total += truth.len();
        }
        let share = reversed as f64 / total as f64;
        // Measured when written: 0.14 % (a few finger and toe tips, where the kNN graph crosses
        // between the sides); 10 % before orientation.
        assert!(share < 0.01, "{:.2} % of the normals still reversed", 100.0 * share);

        let e = orient_normals(s.vertices(), &given[..10]).unwrap_err().to_string();
        assert!(e.contains("normals"), "{e}");
        let mut zero = given.clone();
        zero[7] = [0.0; 3];
        let e = orient_normals(s.vertices(), &zero).unwrap_err().to_string();
        assert!(e.contains("normal 7"), "{e}");
    }

    #[test]
    fn bad_clouds_are_errors() {
        let line: Vec<[f64; 3]> = (0..50).map(|i| [i as f64, 0.0, 0.0]).collect();
        assert!(cloud_surface(&line, 10).is_err());
        let s = icosphere(1);
        assert!(cloud_surface(s.vertices(), 2).is_err());
        assert!(cloud_surface(&s.vertices()[..5], 10).is_err());
        let mut nan = s.vertices().to_vec();
        nan[3][1] = f64::NAN;
        assert!(cloud_surface(&nan, 10).is_err());
    }

    #[test]
    fn cloud_laplacian_spectrum_matches_the_mesh() {
        use crate::spectral::{eigen_basis, SpectralOptions};
        let m = bumpy_sphere(4);
        let mesh = eigen_basis(&cotangent(&m).unwrap(), &SpectralOptions::new(20), None).unwrap().0;
        let (lap, _) = cloud_laplacian(m.vertices(), DEFAULT_NEIGHBOURS).unwrap();
        assert_eq!(lap.kind, LaplacianKind::PointCloud);
        let total: f64 = lap.mass.iter().sum();
        assert!((total / m.total_area() - 1.0).abs() < 0.03, "cloud area {total} vs {}", m.total_area());
        let cloud = eigen_basis(&lap, &SpectralOptions::new(20), None).unwrap().0;
        for i in 1..20 {
            let r = cloud.eigenvalues[i] / mesh.eigenvalues[i];
            assert!(
                (r - 1.0).abs() < 0.05,
                "eigenvalue {i}: cloud {} vs mesh {}",
                cloud.eigenvalues[i],
                mesh.eigenvalues[i]
            );
        }
    }
}
