//! Shapes: triangle meshes, point clouds and abstract feature graphs (paper §2, "Laplacians"),
//! with the geometric quantities the rest of funcorr needs.
//!
//! Notation: a shape X has `n` vertices. Coordinates are in the file's units; areas are in those
//! units squared.

use std::path::Path;

use crate::error::{Error, Result};

mod topology;
use crate::io::{self, MeshData};

/// A triangle mesh: `n` vertices in R³ and triangles given by 0-based vertex indices.
///
/// Invariants (checked by [`TriMesh::new`]): at least one vertex, all coordinates finite,
/// all face indices `< n`. Degenerate (zero-area) triangles and unreferenced vertices are
/// allowed here and reported by [`TriMesh::degenerate_faces`] / [`TriMesh::unreferenced_vertices`];
/// the Laplacian decides what to do with them.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
}

/// A set of `n` points in R^d: a point cloud (d = 3) or the rows of an n×d feature matrix
/// (the paper's "abstract data"). Stored row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct PointSet {
    n: usize,
    d: usize,
    coords: Vec<f64>,
}

/// A shape as loaded from a file: a mesh when the file has faces, otherwise a point set.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Triangle mesh (OFF, OBJ, PLY with faces).
    Mesh(TriMesh),
    /// Point cloud or feature matrix (XYZ/CSV, PLY without faces, NPY).
    Points(PointSet),
}

/// Squared-length threshold used to call a triangle degenerate: area ≤ `DEGENERATE_REL_AREA` ×
/// (bounding-box diagonal)².
pub const DEGENERATE_REL_AREA: f64 = 1e-14;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Union-find with path halving over the elements 0..n (n < 2³²), for connected components
/// (meshes, point-cloud soups), the MSER component tree and the persistence clusters.
pub(crate) struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// n singletons.
    pub(crate) fn new(n: usize) -> Self {
        UnionFind { parent: (0..n as u32).collect() }
    }
    /// The root of the tree of `i` (halving the path to it).
    pub(crate) fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let p = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = p;
            i = p;
        }
        i
    }
    /// Whether `i` is the root of its tree.
    pub(crate) fn is_root(&self, i: u32) -> bool {
        self.parent[i as usize] == i
    }
    /// Merges the trees of `a` and `b`; the smaller root survives.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Deterministic: the smaller root wins.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }
    /// Merges the tree of root `child` into that of root `survivor`, which stays the root: for
    /// merges whose survivor the caller chooses (the elder rule of persistence, where the
    /// component with the higher peak survives). Both must be roots, and distinct.
    pub(crate) fn union_into(&mut self, child: u32, survivor: u32) {
        debug_assert!(self.is_root(child) && self.is_root(survivor) && child != survivor);
        self.parent[child as usize] = survivor;
    }
    /// Component label of every element, numbered 0.. in order of first appearance.
    pub(crate) fn labels(&mut self) -> (usize, Vec<u32>) {
        let n = self.parent.len();
        let mut map = vec![u32::MAX; n];
        let mut labels = vec![0u32; n];
        let mut count = 0u32;
        for i in 0..n as u32 {
            let r = self.find(i) as usize;
            if map[r] == u32::MAX {
                map[r] = count;
                count += 1;
            }
            labels[i as usize] = map[r];
        }
        (count as usize, labels)
    }
}

/// Compressed adjacency lists of an undirected graph on n vertices: the neighbours of i are
/// `adj[start[i]..start[i + 1]]`; self-loops are dropped, duplicates kept.
/// Errors on an index ≥ n.
pub(crate) fn adjacency(n: usize, edges: &[[u32; 2]]) -> Result<(Vec<usize>, Vec<u32>)> {
    let mut start = vec![0usize; n + 1];
    for (e, &[a, b]) in edges.iter().enumerate() {
        if a as usize >= n || b as usize >= n {
            return Err(Error::invalid("edges", format!("edge {e} = [{a}, {b}] is out of range (n = {n})")));
        }
        if a != b {
            start[a as usize + 1] += 1;
            start[b as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n]];
    for &[a, b] in edges {
        if a != b {
            adj[fill[a as usize]] = b;
            fill[a as usize] += 1;
            adj[fill[b as usize]] = a;
            fill[b as usize] += 1;
        }
    }
    Ok((start, adj))
}

/// Largest coordinate magnitude accepted: beyond it squared distances and triangle areas overflow
/// f64 (whose largest value is ≈ 1.8 · 10³⁰⁸), so every geometric quantity would be infinite.
pub const MAX_COORDINATE: f64 = 1e150;

/// Smallest non-zero extent (largest coordinate range over the dimensions) accepted: below it
/// squared distances and areas underflow to subnormal numbers or zero.
pub const MIN_EXTENT: f64 = 1e-150;

/// Checks that `n` points of dimension `d` (row-major `coords`) lie in the range where squared
/// distances are representable: every |coordinate| ≤ [`MAX_COORDINATE`] and, when they do not
/// all coincide, an extent ≥ [`MIN_EXTENT`]. `what` names the input in the error.
fn check_coordinate_range(coords: &[f64], d: usize, what: &str) -> Result<()> {
    if let Some(p) = coords.iter().position(|c| c.abs() > MAX_COORDINATE) {
        return Err(Error::invalid(
            what,
            format!(
                "point {} has coordinate {:e}, beyond ±{MAX_COORDINATE:e} where squared lengths and areas overflow; \
                 rescale the shape",
                p / d,
                coords[p]
            ),
        ));
    }
    let extent = (0..d)
        .map(|j| {
            let col = coords.iter().skip(j).step_by(d);
            let (lo, hi) = col.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &c| (lo.min(c), hi.max(c)));
            hi - lo
        })
        .fold(0.0f64, f64::max);
    if extent > 0.0 && extent < MIN_EXTENT {
        return Err(Error::invalid(
            what,
            format!(
                "its extent is {extent:e}, below {MIN_EXTENT:e} where squared lengths and areas underflow; \
                 rescale the shape"
            ),
        ));
    }
    Ok(())
}

impl TriMesh {
    /// Builds a mesh from vertices (n, each [x, y, z]) and triangles (0-based indices).
    ///
    /// Errors when there are no vertices, a coordinate is not finite, coordinates are outside
    /// the representable range (see [`MAX_COORDINATE`], [`MIN_EXTENT`]), or an index is ≥ n.
    pub fn new(vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Result<Self> {
        if vertices.is_empty() {
            return Err(Error::invalid("mesh", "it has no vertices"));
        }
        if vertices.len() > u32::MAX as usize {
            return Err(Error::invalid("mesh", "more than 2^32 - 1 vertices"));
        }
        if let Some(i) = vertices.iter().position(|v| v.iter().any(|c| !c.is_finite())) {
            return Err(Error::invalid("mesh", format!("vertex {i} has a non-finite coordinate {:?}", vertices[i])));
        }
        check_coordinate_range(vertices.as_flattened(), 3, "mesh")?;
        let n = vertices.len() as u32;
        if let Some(f) = faces.iter().position(|f| f.iter().any(|&i| i >= n)) {
            return Err(Error::invalid(
                "mesh",
                format!("face {f} has vertex index {:?} out of range (n = {n})", faces[f]),
            ));
        }
        Ok(TriMesh { vertices, faces })
    }

    /// Number of vertices `n`.
    pub fn n_vertices(&self) -> usize {
        self.vertices.len()
    }
    /// Number of triangles.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }
    /// Vertex coordinates (n × 3).
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }
    /// Triangles (0-based vertex indices).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// The three corner positions of face `f`.
    pub fn corners(&self, f: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.faces[f];
        [self.vertices[a as usize], self.vertices[b as usize], self.vertices[c as usize]]
    }

    /// Area of every triangle (length n_faces, units²).
    pub fn face_areas(&self) -> Vec<f64> {
        (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.corners(f);
                0.5 * norm(cross(sub(b, a), sub(c, a)))
            })
            .collect()
    }

    /// Barycentric vertex areas a_i = ⅓ Σ (areas of the triangles around i) (length n, units²):
    /// the lumped mass of the paper's eq. (2). Unreferenced vertices get 0.
    pub fn vertex_areas(&self) -> Vec<f64> {
        let mut a = vec![0.0; self.vertices.len()];
        for (f, area) in self.faces.iter().zip(self.face_areas()) {
            for &i in f {
                a[i as usize] += area / 3.0;
            }
        }
        a
    }

    /// Total surface area (units²).
    pub fn total_area(&self) -> f64 {
        self.face_areas().iter().sum()
    }

    /// Unit normal of every triangle (length n_faces); `[0, 0, 0]` for degenerate triangles.
    pub fn face_normals(&self) -> Vec<[f64; 3]> {
        (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.corners(f);
                let nrm = cross(sub(b, a), sub(c, a));
                let l = norm(nrm);
                if l > 0.0 {
                    [nrm[0] / l, nrm[1] / l, nrm[2] / l]
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    /// Area-weighted unit vertex normals (length n); `[0, 0, 0]` where undefined.
    pub fn vertex_normals(&self) -> Vec<[f64; 3]> {
        let mut nv = vec![[0.0; 3]; self.vertices.len()];
        for (f, tri) in self.faces.iter().enumerate() {
            let [a, b, c] = self.corners(f);
            let nrm = cross(sub(b, a), sub(c, a)); // length = 2 × area: area weighting
            for &i in tri {
                for d in 0..3 {
                    nv[i as usize][d] += nrm[d];
                }
            }
        }
        for v in &mut nv {
            let l = norm(*v);
            if l > 0.0 {
                *v = [v[0] / l, v[1] / l, v[2] / l];
            }
        }
        nv
    }

    /// Unique undirected edges `(i, j)` with `i < j`, sorted.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let mut e = self.face_edges_sorted();
        e.dedup();
        e
    }

    /// Every triangle's undirected edges `(i, j)`, `i < j`, sorted, once per triangle that uses
    /// them (degenerate edges `i = j` left out).
    fn face_edges_sorted(&self) -> Vec<[u32; 2]> {
        let mut e: Vec<[u32; 2]> = Vec::with_capacity(self.faces.len() * 3);
        for f in &self.faces {
            for c in 0..3 {
                let (i, j) = (f[c], f[(c + 1) % 3]);
                if i != j {
                    e.push([i.min(j), i.max(j)]);
                }
            }
        }
        e.sort_unstable();
        e
    }

    /// Connected components through the faces: (count, label of every vertex).
    /// An unreferenced vertex is a component of its own.
    pub fn components(&self) -> (usize, Vec<u32>) {
        let mut uf = UnionFind::new(self.vertices.len());
        for f in &self.faces {
            uf.union(f[0], f[1]);
            uf.union(f[1], f[2]);
        }
        uf.labels()
    }

    /// Boundary loops: chains of edges used by exactly one triangle, each loop as the list of its
    /// vertices in order. Non-manifold boundaries (a vertex with several outgoing boundary edges)
    /// are split deterministically; an open chain is returned as it is.
    pub fn boundary_loops(&self) -> Vec<Vec<u32>> {
        use std::collections::{HashMap, HashSet};
        // The undirected edges used once, from the sorted list of every triangle's edges (a
        // sort, not a hash map of every edge: `funcorr info` on an 840k-vertex mesh went from
        // 3.7 to 2.9 s).
        let all = self.face_edges_sorted();
        let once: HashSet<[u32; 2]> = (0..all.len())
            .filter(|&t| (t == 0 || all[t - 1] != all[t]) && all.get(t + 1) != Some(&all[t]))
            .map(|t| all[t])
            .collect();
        drop(all);
        let mut on_boundary = vec![false; self.vertices.len()];
        for e in &once {
            on_boundary[e[0] as usize] = true;
            on_boundary[e[1] as usize] = true;
        }
        // Directed boundary half-edges, in the orientation of their triangle.
        let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
        let mut starts: Vec<u32> = Vec::new();
        for f in &self.faces {
            for c in 0..3 {
                let (i, j) = (f[c], f[(c + 1) % 3]);
                if i != j && on_boundary[i as usize] && on_boundary[j as usize] && once.contains(&[i.min(j), i.max(j)])
                {
                    next.entry(i).or_default().push(j);
                    starts.push(i);
                }
            }
        }
        for v in next.values_mut() {
            v.sort_unstable();
        }
        starts.sort_unstable();
        starts.dedup();
        let mut loops = Vec::new();
        for s in starts {
            while next.get(&s).is_some_and(|v| !v.is_empty()) {
                let mut lp = vec![s];
                let mut cur = s;
                while let Some(nx) =
                    next.get_mut(&cur).and_then(|v| if v.is_empty() { None } else { Some(v.remove(0)) })
                {
                    if nx == s {
                        break;
                    }
                    lp.push(nx);
                    cur = nx;
                }
                loops.push(lp);
            }
        }
        loops
    }

    /// Indices of degenerate triangles: repeated vertex indices, or area ≤
    /// [`DEGENERATE_REL_AREA`] × (bounding-box diagonal)².
    pub fn degenerate_faces(&self) -> Vec<usize> {
        let (lo, hi) = self.bounding_box();
        let diag2 = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>();
        let tol = DEGENERATE_REL_AREA * diag2;
        let areas = self.face_areas();
        self.faces
            .iter()
            .enumerate()
            .filter(|(f, t)| t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || areas[*f] <= tol)
            .map(|(f, _)| f)
            .collect()
    }

    /// Vertices that belong to no triangle.
    pub fn unreferenced_vertices(&self) -> Vec<u32> {
        let mut used = vec![false; self.vertices.len()];
        for f in &self.faces {
            for &i in f {
                used[i as usize] = true;
            }
        }
        (0..self.vertices.len() as u32).filter(|&i| !used[i as usize]).collect()
    }

    /// Axis-aligned bounding box (min corner, max corner).
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        bounding_box(&self.vertices)
    }

    /// Mean edge length (units); 0 when there are no edges.
    pub fn mean_edge_length(&self) -> f64 {
        let e = self.edges();
        if e.is_empty() {
            return 0.0;
        }
        e.iter().map(|&[i, j]| norm(sub(self.vertices[i as usize], self.vertices[j as usize]))).sum::<f64>()
            / e.len() as f64
    }

    /// The same mesh with its vertices renumbered: new vertex i is old vertex `perm[i]`
    /// (faces follow). Errors unless `perm` is a permutation of 0..n.
    pub fn permuted(&self, perm: &[usize]) -> Result<TriMesh> {
        let n = self.vertices.len();
        let mut inv = vec![u32::MAX; n];
        for (new, &old) in perm.iter().enumerate() {
            if old >= n || inv[old] != u32::MAX {
                return Err(Error::invalid("permutation", format!("entry {new} = {old} repeats or is ≥ n = {n}")));
            }
            inv[old] = new as u32;
        }
        if perm.len() != n {
            return Err(Error::invalid("permutation", format!("{} entries for {n} vertices", perm.len())));
        }
        let vertices = perm.iter().map(|&old| self.vertices[old]).collect();
        let faces = self.faces.iter().map(|f| f.map(|v| inv[v as usize])).collect();
        TriMesh::new(vertices, faces)
    }

    /// The same connectivity with every vertex moved by `f` (e.g. a rigid motion).
    pub fn map_vertices(&self, f: impl Fn([f64; 3]) -> [f64; 3]) -> Result<TriMesh> {
        TriMesh::new(self.vertices.iter().map(|&p| f(p)).collect(), self.faces.clone())
    }

    /// `count` points drawn uniformly on the surface (triangles chosen with probability
    /// proportional to their area, uniform barycentric coordinates), deterministic for a seed:
    /// a point cloud that shares no vertex with the mesh. Errors: count = 0, or no area.
    pub fn sample_surface(&self, count: usize, seed: u64) -> Result<Vec<[f64; 3]>> {
        if count == 0 {
            return Err(Error::invalid("count", "need at least one point"));
        }
        let areas = self.face_areas();
        let mut cumulative = Vec::with_capacity(areas.len());
        let mut total = 0.0;
        for a in &areas {
            total += a;
            cumulative.push(total);
        }
        if !(total > 0.0 && total.is_finite()) {
            return Err(Error::invalid("mesh", "it has no area to sample"));
        }
        let mut rng = crate::rng::Normal::new(seed);
        Ok((0..count)
            .map(|_| {
                let t = rng.uniform() * total;
                let f = cumulative.partition_point(|&c| c < t).min(areas.len() - 1);
                let (mut u, mut v) = (rng.uniform(), rng.uniform());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let [a, b, c] = self.corners(f);
                std::array::from_fn(|d| a[d] + u * (b[d] - a[d]) + v * (c[d] - a[d]))
            })
            .collect())
    }

    /// The submesh of the faces whose three vertices are kept (`keep`: #V flags): the mesh of
    /// those faces over the vertices they use, renumbered in their order, and for every vertex
    /// of the submesh its id here. None when no face is kept. Errors: `keep` of the wrong
    /// length.
    pub fn submesh(&self, keep: &[bool]) -> Result<Option<(TriMesh, Vec<usize>)>> {
        if keep.len() != self.vertices.len() {
            return Err(Error::invalid(
                "submesh",
                format!("{} vertex flags for a mesh of {} vertices", keep.len(), self.vertices.len()),
            ));
        }
        let faces: Vec<[u32; 3]> = self.faces.iter().copied().filter(|f| f.iter().all(|&v| keep[v as usize])).collect();
        if faces.is_empty() {
            return Ok(None);
        }
        let mut new_id = vec![u32::MAX; self.vertices.len()];
        let mut old = Vec::new();
        for f in &faces {
            for &v in f {
                if new_id[v as usize] == u32::MAX {
                    new_id[v as usize] = old.len() as u32;
                    old.push(v as usize);
                }
            }
        }
        old.sort_unstable();
        for (i, &v) in old.iter().enumerate() {
            new_id[v] = i as u32;
        }
        let vertices = old.iter().map(|&v| self.vertices[v]).collect();
        let faces = faces.iter().map(|f| f.map(|v| new_id[v as usize])).collect();
        Ok(Some((TriMesh::new(vertices, faces)?, old)))
    }

    /// The vertices as a point cloud (faces dropped), as in the paper's mesh-to-point-cloud
    /// experiment.
    pub fn to_point_set(&self) -> PointSet {
        PointSet { n: self.vertices.len(), d: 3, coords: self.vertices.iter().flatten().copied().collect() }
    }
}

/// The axis-aligned bounding box (min, max) of a list of points; (+∞, −∞) when empty.
pub(crate) fn bounding_box(v: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in v {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

impl PointSet {
    /// Builds a point set from `n` rows of dimension `d` (row-major `coords`, length n·d).
    /// Errors on n = 0, d = 0, a length mismatch, a non-finite value or values outside the
    /// representable range (see [`MAX_COORDINATE`], [`MIN_EXTENT`]).
    pub fn new(n: usize, d: usize, coords: Vec<f64>) -> Result<Self> {
        if n == 0 || d == 0 {
            return Err(Error::invalid("point set", format!("it is empty ({n} points of dimension {d})")));
        }
        if n.checked_mul(d) != Some(coords.len()) {
            return Err(Error::invalid(
                "point set",
                format!("{} values for {n} points of dimension {d}", coords.len()),
            ));
        }
        if let Some(p) = coords.iter().position(|c| !c.is_finite()) {
            return Err(Error::invalid("point set", format!("point {} has a non-finite coordinate", p / d)));
        }
        check_coordinate_range(&coords, d, "point set")?;
        Ok(PointSet { n, d, coords })
    }
    /// Number of points `n`.
    pub fn len(&self) -> usize {
        self.n
    }
    /// Always false: a point set has at least one point.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
    /// Dimension `d` of every point.
    pub fn dim(&self) -> usize {
        self.d
    }
    /// Point `i` (length d).
    pub fn point(&self, i: usize) -> &[f64] {
        &self.coords[i * self.d..(i + 1) * self.d]
    }
    /// All coordinates, row-major (n × d).
    pub fn coords(&self) -> &[f64] {
        &self.coords
    }
}

impl Shape {
    /// Reads a shape from a file (OFF, OBJ, PLY, XYZ/CSV/TXT/PTS, NPY). Files with faces become
    /// meshes; files without faces (and .npy n×d matrices) become point sets.
    pub fn load(path: &Path) -> Result<Shape> {
        let is_npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if is_npy {
            let m = io::npy::read_npy_matrix(path)?;
            return PointSet::new(m.rows, m.cols, m.data)
                .map(Shape::Points)
                .map_err(|e| Error::parse(path, None, e.to_string()));
        }
        let data = io::read_mesh(path)?;
        Shape::from_data(data).map_err(|e| Error::parse(path, None, e.to_string()))
    }

    /// Builds a shape from raw file data.
    pub fn from_data(data: MeshData) -> Result<Shape> {
        if data.faces.is_empty() {
            let n = data.vertices.len();
            PointSet::new(n, 3, data.vertices.into_iter().flatten().collect()).map(Shape::Points)
        } else {
            TriMesh::new(data.vertices, data.faces).map(Shape::Mesh)
        }
    }

    /// Number of vertices / points.
    pub fn n_vertices(&self) -> usize {
        match self {
            Shape::Mesh(m) => m.n_vertices(),
            Shape::Points(p) => p.len(),
        }
    }

    /// The shape as a point set (a mesh drops its faces).
    pub fn to_point_set(&self) -> PointSet {
        match self {
            Shape::Mesh(m) => m.to_point_set(),
            Shape::Points(p) => p.clone(),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit square in the plane z = 0 split into two triangles.
    pub(crate) fn square() -> TriMesh {
        TriMesh::new(vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]], vec![[0, 1, 2], [0, 2, 3]]).unwrap()
    }

    #[test]
    fn a_submesh_keeps_the_faces_of_kept_vertices_renumbered_in_order() {
        // Square 0-1-2-3 with a fifth vertex 4 on a triangle of its own beside edge 1-2.
        let mut v = square().vertices().to_vec();
        v.push([2., 0.5, 0.]);
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]).unwrap();
        let (sub, ids) = m.submesh(&[false, true, true, true, true]).unwrap().unwrap();
        assert_eq!(ids, vec![1, 2, 4]);
        assert_eq!(sub.faces(), &[[0, 2, 1]]);
        assert_eq!(sub.vertices()[2], [2., 0.5, 0.]);
        let (all, ids) = m.submesh(&[true; 5]).unwrap().unwrap();
        assert_eq!((all, ids), (m.clone(), vec![0, 1, 2, 3, 4]));
        assert!(m.submesh(&[true, true, false, false, false]).unwrap().is_none());
        let e = m.submesh(&[true; 4]).unwrap_err().to_string();
        assert!(e.contains("4 vertex flags for a mesh of 5 vertices"), "{e}");
    }

    #[test]
    fn coordinates_whose_squares_overflow_or_underflow_are_rejected() {
        let faces = vec![[0, 1, 2]];
        let huge = TriMesh::new(vec![[0., 0., 0.], [1e300, 0., 0.], [0., 1e300, 0.]], faces.clone()).unwrap_err();
        assert!(huge.to_string().contains("overflow"), "{huge}");
        let tiny = TriMesh::new(vec![[0., 0., 0.], [1e-310, 0., 0.], [0., 1e-310, 0.]], faces).unwrap_err();
        assert!(tiny.to_string().contains("underflow"), "{tiny}");
        let cloud = PointSet::new(2, 2, vec![0.0, 0.0, 1e200, 0.0]).unwrap_err();
        assert!(cloud.to_string().contains("overflow"), "{cloud}");
        // Small but representable shapes (millimetres in kilometres) are fine.
        assert!(TriMesh::new(vec![[0., 0., 0.], [1e-100, 0., 0.], [0., 1e-100, 0.]], vec![[0, 1, 2]]).is_ok());
    }

    #[test]
    fn areas_and_normals_of_square() {
        let m = square();
        assert_eq!(m.face_areas(), vec![0.5, 0.5]);
        assert!((m.total_area() - 1.0).abs() < 1e-15);
        let a = m.vertex_areas();
        assert!((a.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!((a[0] - 1.0 / 3.0).abs() < 1e-15 && (a[1] - 1.0 / 6.0).abs() < 1e-15);
        for n in m.vertex_normals() {
            assert_eq!(n, [0., 0., 1.]);
        }
        assert_eq!(m.edges(), vec![[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]);
    }

    #[test]
    fn boundary_components_degenerate() {
        let m = square();
        let loops = m.boundary_loops();
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 4);
        // Two separate squares, one degenerate triangle and one unreferenced vertex.
        let mut v = m.vertices().to_vec();
        v.extend(m.vertices().iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
        v.push([9., 9., 9.]);
        let mut f = m.faces().to_vec();
        f.extend(m.faces().iter().map(|t| [t[0] + 4, t[1] + 4, t[2] + 4]));
        f.push([0, 1, 1]);
        let two = TriMesh::new(v, f).unwrap();
        let (nc, labels) = two.components();
        assert_eq!(nc, 3);
        assert_eq!(labels[0], labels[3]);
        assert_ne!(labels[0], labels[4]);
        assert_eq!(two.degenerate_faces(), vec![4]);
        assert_eq!(two.unreferenced_vertices(), vec![8]);
        assert_eq!(two.boundary_loops().len(), 2);
    }

    #[test]
    fn permuted_copies() {
        let m = square();
        let p = m.permuted(&[2, 0, 3, 1]).unwrap();
        assert_eq!(p.vertices()[0], m.vertices()[2]);
        assert_eq!(p.face_areas(), m.face_areas());
        assert_eq!(p.faces()[0], [1, 3, 0]); // old face [0, 1, 2]
        assert!(m.permuted(&[0, 0, 1, 2]).is_err());
        assert!(m.permuted(&[0, 1, 2]).is_err());
        assert!(m.permuted(&[0, 1, 2, 4]).is_err());
    }

    #[test]
    fn invalid_meshes_are_errors() {
        assert!(TriMesh::new(vec![], vec![]).is_err());
        assert!(TriMesh::new(vec![[0., f64::NAN, 0.]], vec![]).is_err());
        let e = TriMesh::new(vec![[0.; 3]; 3], vec![[0, 1, 3]]).unwrap_err();
        assert!(e.to_string().contains("face 0"), "{e}");
        assert!(PointSet::new(2, 3, vec![0.0; 5]).is_err());
        assert!(PointSet::new(1, 3, vec![0.0, f64::INFINITY, 0.0]).is_err());
    }
}
