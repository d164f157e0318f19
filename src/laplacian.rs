//! Discrete Laplacians L = A⁻¹ W of the paper (§2, eq. (1) and (2)).
//!
//! We store the *stiffness* matrix W = D − (edge weights) (n × n, sparse, symmetric, positive
//! semi-definite, zero row sums, positive diagonal) and the vertex weights A (the diagonal
//! "mass", length n). The spectral problem is the generalized one W φ = λ A φ.
//!
//! - Triangle meshes: cotangent weights (2) with the lumped barycentric mass a_i = ⅓ Σ area.
//! - Point clouds and abstract data: a symmetric K-nearest-neighbour graph with Gaussian weights
//!   (1) and self-tuning bandwidth, vertex weights A = I (unnormalized) or A = D (random walk).
//! - Point clouds sampling a surface: the point-cloud Laplacian of Sharp & Crane 2020 is built
//!   in [`crate::cloud::cloud_laplacian`] (above this module: it needs the cloud's surface),
//!   from [`cotangent`] of the cloud's triangle soup, as [`LaplacianKind::PointCloud`].

use std::sync::{Arc, Mutex};

use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::{PointSet, TriMesh};
use crate::spatial::knn;

/// Which discretization produced a [`Laplacian`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum LaplacianKind {
    /// Cotangent weights, barycentric lumped mass (eq. (2)).
    Cotangent,
    /// Gaussian-weighted kNN graph (eq. (1)).
    Knn,
    /// A graph given by its edges.
    Graph,
    /// A point cloud's union of local Delaunay fans (Sharp & Crane 2020), cotangent weights
    /// and mass divided by 3.
    PointCloud,
    /// Cotangent weights and barycentric mass of the intrinsic Delaunay triangulation
    /// (`geodesic::intrinsic_delaunay_laplacian`).
    IntrinsicDelaunay,
}

/// Vertex weights of a graph Laplacian (paper §2): A = I or A = D.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VertexWeights {
    /// A = I: the unnormalized graph Laplacian D − W.
    Identity,
    /// A = D: the random-walk Laplacian I − D⁻¹W.
    Degree,
}

/// Gaussian bandwidth σ of the kNN graph weights (1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Bandwidth {
    /// Zelnik-Manor & Perona local scaling: w_ij = exp(−‖xᵢ−xⱼ‖² / (σᵢ σⱼ)) with σᵢ the distance
    /// from xᵢ to its K-th nearest neighbour. For σᵢ = σⱼ = σ this is (1) with 2σ² → σ².
    SelfTuning,
    /// One global σ in (1): w_ij = exp(−‖xᵢ−xⱼ‖² / 2σ²), in the units of the coordinates.
    Fixed(f64),
}

/// Options of the kNN graph Laplacian.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KnnOptions {
    /// Number of neighbours K of every point (paper: 10).
    pub k: usize,
    /// Vertex weights A.
    pub vertex_weights: VertexWeights,
    /// Bandwidth σ.
    pub bandwidth: Bandwidth,
}

impl Default for KnnOptions {
    fn default() -> Self {
        KnnOptions { k: 10, vertex_weights: VertexWeights::Identity, bandwidth: Bandwidth::SelfTuning }
    }
}

/// A discrete Laplacian L = A⁻¹ W.
#[derive(Debug, Clone)]
pub struct Laplacian {
    /// W (n × n): stiffness D − weights; symmetric PSD, zero row sums, every diagonal entry stored.
    pub w: SparseColMat<usize, f64>,
    /// A (length n): vertex weights (areas in units² for meshes), all > 0.
    pub mass: Vec<f64>,
    /// How it was built.
    pub kind: LaplacianKind,
    /// The symbolic Cholesky factorization of W's pattern, computed on first use
    /// ([`Laplacian::symbolic_cholesky`]).
    pub(crate) symbolic: SymbolicCache,
}

/// A cached symbolic Cholesky factorization with the hash of the pattern it was computed from
/// (W's fields are public: a pattern changed after the first use is detected and analysed
/// again, never factored with a stale ordering).
#[derive(Default)]
pub(crate) struct SymbolicCache(Mutex<Option<(u64, Arc<SymbolicCholesky<usize>>)>>);

impl Clone for SymbolicCache {
    fn clone(&self) -> Self {
        SymbolicCache(Mutex::new(self.0.lock().unwrap_or_else(|e| e.into_inner()).clone()))
    }
}

impl std::fmt::Debug for SymbolicCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let cached = self.0.lock().map(|g| g.is_some()).unwrap_or(false);
        write!(f, "SymbolicCache {{ cached: {cached} }}")
    }
}

/// FNV-1a, 64 bits, a stable hash (std's hashers may change between Rust releases): the hash of W's pattern ([`Laplacian::symbolic_cholesky`]) and of a
/// whole Laplacian (the basis cache's key, [`crate::spectral::BasisCache::key`]).
pub(crate) struct Fnv(pub(crate) u64);

impl Fnv {
    pub(crate) fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    pub(crate) fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// Hashes n, then the column pointers and row indices of W's pattern (each as u64 LE).
    pub(crate) fn write_pattern(&mut self, lap: &Laplacian) {
        let sym = lap.w.symbolic();
        self.write(&(lap.n() as u64).to_le_bytes());
        for &x in sym.col_ptr().iter().chain(sym.row_idx()) {
            self.write(&(x as u64).to_le_bytes());
        }
    }
}

impl Laplacian {
    /// A Laplacian from its stiffness matrix W (n × n, symmetric, every diagonal entry stored),
    /// vertex weights A (length n) and kind.
    pub fn new(w: SparseColMat<usize, f64>, mass: Vec<f64>, kind: LaplacianKind) -> Self {
        Laplacian { w, mass, kind, symbolic: SymbolicCache::default() }
    }

    /// The AMD ordering and supernodal symbolic Cholesky factorization of W's pattern, shared
    /// by every numeric factorization of W + cA or A + tW ([`crate::cholesky`]); computed once.
    pub(crate) fn symbolic_cholesky(&self) -> Result<Arc<SymbolicCholesky<usize>>> {
        let mut h = Fnv::new();
        h.write_pattern(self);
        let hash = h.0;
        let mut slot = self.symbolic.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((h, s)) = slot.as_ref() {
            if *h == hash {
                return Ok(s.clone());
            }
        }
        let s = crate::cholesky::symbolic_of(self.w.as_ref())?;
        *slot = Some((hash, s.clone()));
        Ok(s)
    }

    /// M = c_w W + c_a A (n × n, W's pattern): the eigensolver's W + sA and the smoothing
    /// step's A + tW, factored with [`Laplacian::symbolic_cholesky`].
    pub(crate) fn combination(&self, c_w: f64, c_a: f64) -> SparseColMat<usize, f64> {
        let mut m = self.w.clone();
        let sym = self.w.symbolic();
        let (cp, ri) = (sym.col_ptr(), sym.row_idx());
        let vals = m.val_mut();
        for c in 0..self.n() {
            for p in cp[c]..cp[c + 1] {
                vals[p] *= c_w;
                if ri[p] == c {
                    vals[p] += c_a * self.mass[c];
                }
            }
        }
        m
    }

    /// The same Laplacian with other vertex weights (length n), sharing the cached symbolic
    /// factorization (the pattern is W's).
    pub(crate) fn with_mass(&self, mass: Vec<f64>) -> Self {
        Laplacian { w: self.w.clone(), mass, kind: self.kind, symbolic: self.symbolic.clone() }
    }

    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.mass.len()
    }

    /// Connected components of the graph of W (i ~ j when W_ij ≠ 0, i ≠ j): (count, label of
    /// every vertex, length n, numbered 0.. in order of first appearance). The multiplicity of
    /// the eigenvalue 0; for a mesh the components of its faces, for a point cloud those of its
    /// local triangulations or kNN graph.
    pub fn components(&self) -> (usize, Vec<u32>) {
        let w = self.w.as_ref();
        let (cp, ri, val) = (w.symbolic().col_ptr(), w.symbolic().row_idx(), w.val());
        let mut uf = crate::shape::UnionFind::new(self.n());
        for j in 0..self.n() {
            for p in cp[j]..cp[j + 1] {
                if ri[p] != j && val[p] != 0.0 {
                    uf.union(ri[p] as u32, j as u32);
                }
            }
        }
        uf.labels()
    }

    /// y = W x (x, y of length n).
    pub fn apply_w(&self, x: &[f64]) -> Vec<f64> {
        let w = self.w.as_ref();
        let (cp, ri, val) = (w.symbolic().col_ptr(), w.symbolic().row_idx(), w.val());
        let mut y = vec![0.0; x.len()];
        // W is symmetric: row i of W is column i.
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            *yi = (cp[i]..cp[i + 1]).map(|p| val[p] * x[ri[p]]).sum();
        });
        y
    }
}

/// Assembles a symmetric n × n CSC matrix from `(row, col, value)` entries (duplicates summed,
/// every diagonal entry present, rows sorted within each column).
///
/// Written here rather than through faer's triplet constructor so that duplicates are summed
/// explicitly and the diagonal is always stored (the eigensolver shifts it in place).
pub(crate) fn assemble_symmetric(n: usize, mut entries: Vec<(usize, usize, f64)>) -> SparseColMat<usize, f64> {
    entries.extend((0..n).map(|i| (i, i, 0.0)));
    entries.par_sort_unstable_by_key(|&(r, c, _)| (c, r));
    let mut col_ptr = vec![0usize; n + 1];
    let mut row_idx = Vec::with_capacity(entries.len());
    let mut vals: Vec<f64> = Vec::with_capacity(entries.len());
    let mut last: Option<(usize, usize)> = None;
    for (r, c, v) in entries {
        if last == Some((r, c)) {
            *vals.last_mut().expect("a previous entry exists") += v;
        } else {
            row_idx.push(r);
            vals.push(v);
            col_ptr[c + 1] += 1;
            last = Some((r, c));
        }
    }
    for c in 0..n {
        col_ptr[c + 1] += col_ptr[c];
    }
    let sym = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    SparseColMat::new(sym, vals)
}

/// Lengths of the three edges of a triangle, opposite its corners 0, 1, 2.
fn opposite_lengths(p: [[f64; 3]; 3]) -> [f64; 3] {
    let d = |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    [d(p[1], p[2]), d(p[2], p[0]), d(p[0], p[1])]
}

/// Area of a triangle from its edge lengths (Kahan's numerically stable Heron formula).
pub(crate) fn heron(l: [f64; 3]) -> f64 {
    let mut s = l;
    s.sort_by(|a, b| b.total_cmp(a)); // a ≥ b ≥ c
    let [a, b, c] = s;
    let p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    0.25 * p.max(0.0).sqrt()
}

/// Relative size of the intrinsic mollification margin: every triangle inequality must hold with a
/// slack of at least `MOLLIFY_FACTOR × mean edge length` (Sharp & Crane 2020, as in
/// robust-laplacian).
pub const MOLLIFY_FACTOR: f64 = 1e-6;

/// A mesh whose total area is below this fraction of the area of as many equilateral triangles
/// of its mean edge length is rejected as flat (collinear or coincident vertices).
pub const ZERO_AREA_RATIO: f64 = 1e-10;

/// The triangles of `mesh` that have three distinct vertex indices, and their edge lengths
/// (opposite corners 0, 1, 2) after intrinsic mollification: when some triangle inequality holds
/// with a slack below ε = [`MOLLIFY_FACTOR`] × mean edge length, the same δ ≥ 0 is added to every
/// length so that all hold with slack ε (δ = 0 on meshes without near-degenerate triangles).
///
/// Errors: a mesh without such a triangle.
pub(crate) fn mollified_lengths(mesh: &TriMesh) -> Result<(Vec<usize>, Vec<[f64; 3]>)> {
    let faces: Vec<usize> = (0..mesh.n_faces())
        .filter(|&f| {
            let t = mesh.faces()[f];
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
        })
        .collect();
    if faces.is_empty() {
        return Err(Error::invalid("mesh", "it has no non-degenerate triangle; use a point-cloud (kNN) Laplacian"));
    }
    let lengths: Vec<[f64; 3]> = faces.iter().map(|&f| opposite_lengths(mesh.corners(f))).collect();
    let mean_len = lengths.iter().flatten().sum::<f64>() / (3 * lengths.len()) as f64;
    // Mollification repairs a few degenerate triangles; it cannot invent a surface. A mesh whose
    // triangles have (almost) no area in all — every vertex on one line or at one point — is
    // rejected: relative to equilateral triangles of the mean edge length, below 10⁻¹⁰.
    let area: f64 = lengths.iter().map(|&l| heron(l)).sum();
    let reference = lengths.len() as f64 * mean_len * mean_len * 3f64.sqrt() / 4.0;
    if area.is_nan() || area <= ZERO_AREA_RATIO * reference {
        return Err(Error::invalid(
            "mesh",
            format!(
                "its {} triangles have zero total area ({area:e}; all vertices on one line or at one point), \
                 so it has no surface Laplacian; use a point-cloud (kNN) Laplacian for such data",
                lengths.len()
            ),
        ));
    }
    let eps = MOLLIFY_FACTOR * mean_len;
    let delta = lengths
        .iter()
        .map(|l| (0..3).map(|c| eps - (l[(c + 1) % 3] + l[(c + 2) % 3] - l[c])).fold(0.0f64, f64::max))
        .fold(0.0f64, f64::max);
    let lengths = lengths.into_iter().map(|l| [l[0] + delta, l[1] + delta, l[2] + delta]).collect();
    Ok((faces, lengths))
}

/// Cotangent Laplacian of a triangle mesh (paper eq. (2)): w_ij = ½(cot αᵢⱼ + cot βᵢⱼ) and
/// a_i = ⅓ Σ (one-ring triangle areas).
///
/// Degenerate triangles: we apply *intrinsic mollification* (Sharp & Crane, "A Laplacian for
/// nonmanifold triangle meshes", 2020; the default of robust-laplacian): when some triangle's
/// edge lengths violate the triangle inequality by less than ε = 10⁻⁶ × mean edge length, a
/// constant δ is added to every edge length so that all inequalities hold with slack ε, and all
/// cotangents and areas are computed intrinsically from those lengths. On meshes without
/// (near-)degenerate triangles δ = 0 and the result is the textbook cotangent Laplacian exactly.
/// Triangles with a repeated vertex index carry no geometry and are skipped.
///
/// Errors: a vertex that belongs to no (non-skipped) triangle would have zero mass and is
/// rejected, naming the vertex.
pub fn cotangent(mesh: &TriMesh) -> Result<Laplacian> {
    let (faces, lengths) = mollified_lengths(mesh)?;
    cotangent_from_lengths(mesh.n_vertices(), faces.iter().map(|&f| mesh.faces()[f]).zip(lengths))
}

/// The cotangent Laplacian of `n` vertices and triangles given intrinsically, each by its vertex
/// indices and its edge lengths opposite corners 0, 1, 2 (all triangle inequalities holding):
/// cotangents (b² + c² − a²) / 4·area and masses ⅓ Σ area from the lengths alone.
///
/// Errors: a vertex that belongs to no triangle (zero mass), naming it.
pub(crate) fn cotangent_from_lengths(
    n: usize,
    triangles: impl Iterator<Item = ([u32; 3], [f64; 3])>,
) -> Result<Laplacian> {
    let mut mass = vec![0.0; n];
    let mut entries = Vec::with_capacity(triangles.size_hint().0 * 12);
    for (t, l) in triangles {
        let area = heron(l);
        for c in 0..3 {
            mass[t[c] as usize] += area / 3.0;
            // cot of the angle at corner c, opposite edge l[c]: (b² + c² − a²) / (4 area).
            let (a, b, cc) = (l[c], l[(c + 1) % 3], l[(c + 2) % 3]);
            let cot = if area > 0.0 { (b * b + cc * cc - a * a) / (4.0 * area) } else { 0.0 };
            let (i, j) = (t[(c + 1) % 3] as usize, t[(c + 2) % 3] as usize);
            let w = 0.5 * cot;
            entries.push((i, j, -w));
            entries.push((j, i, -w));
            entries.push((i, i, w));
            entries.push((j, j, w));
        }
    }
    if let Some(i) = mass.iter().position(|&a| a <= 0.0) {
        let count = mass.iter().filter(|&&a| a <= 0.0).count();
        return Err(Error::invalid(
            "mesh",
            format!(
                "{count} vertices (first: {i}) belong to no triangle and would have zero mass; \
                 remove unreferenced vertices or use the kNN (point cloud) Laplacian"
            ),
        ));
    }
    Ok(Laplacian::new(assemble_symmetric(n, entries), mass, LaplacianKind::Cotangent))
}

/// Laplacian of a graph given by weighted undirected edges `(i, j, w_ij)` (each edge once; w ≥ 0)
/// on `n` vertices, with vertex weights A = I or A = D.
///
/// Errors: an index ≥ n, a self-loop, a negative or non-finite weight, or (for A = D) a vertex of
/// degree zero.
pub fn graph(n: usize, edges: &[(usize, usize, f64)], vertex_weights: VertexWeights) -> Result<Laplacian> {
    if n == 0 {
        return Err(Error::invalid("graph", "it has no vertices"));
    }
    let mut degree = vec![0.0; n];
    let mut entries = Vec::with_capacity(edges.len() * 4);
    for (e, &(i, j, w)) in edges.iter().enumerate() {
        if i >= n || j >= n || i == j {
            return Err(Error::invalid(
                "graph",
                format!("edge {e} = ({i}, {j}) is out of range or a self-loop (n = {n})"),
            ));
        }
        if !(w.is_finite() && w >= 0.0) {
            return Err(Error::invalid("graph", format!("edge {e} = ({i}, {j}) has weight {w}")));
        }
        degree[i] += w;
        degree[j] += w;
        entries.extend([(i, j, -w), (j, i, -w), (i, i, w), (j, j, w)]);
    }
    let mass = match vertex_weights {
        VertexWeights::Identity => vec![1.0; n],
        VertexWeights::Degree => {
            if let Some(i) = degree.iter().position(|&d| d <= 0.0) {
                return Err(Error::invalid(
                    "graph",
                    format!("vertex {i} has degree 0, so A = D is singular; use A = I or a larger K/σ"),
                ));
            }
            degree
        }
    };
    Ok(Laplacian::new(assemble_symmetric(n, entries), mass, LaplacianKind::Graph))
}

/// Graph Laplacian of a point cloud or feature matrix (paper eq. (1)): the symmetric kNN graph
/// (i ~ j when j is among the K nearest neighbours of i or vice versa) with Gaussian weights.
///
/// Errors: K out of range, a point whose K-th neighbour coincides with it (σᵢ = 0), a fixed σ
/// that is not positive.
pub fn knn_graph(points: &PointSet, opts: &KnnOptions) -> Result<Laplacian> {
    let nbrs = knn(points, opts.k)?;
    let n = points.len();
    let sigma: Vec<f64> = match opts.bandwidth {
        Bandwidth::SelfTuning => nbrs.iter().map(|nb| nb[opts.k - 1].0.sqrt()).collect(),
        Bandwidth::Fixed(s) => {
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::invalid("sigma", format!("σ must be positive and finite, got {s}")));
            }
            vec![s * std::f64::consts::SQRT_2; n] // σᵢσⱼ = 2σ²
        }
    };
    if let Some(i) = sigma.iter().position(|&s| s <= 0.0) {
        return Err(Error::invalid(
            "points",
            format!("point {i} coincides with its {} nearest neighbours (σ = 0); remove duplicate points", opts.k),
        ));
    }
    let mut pairs: Vec<(usize, usize, f64)> =
        nbrs.iter().enumerate().flat_map(|(i, nb)| nb.iter().map(move |&(d2, j)| (i.min(j), i.max(j), d2))).collect();
    pairs.sort_unstable_by_key(|&(i, j, _)| (i, j));
    pairs.dedup_by_key(|p| (p.0, p.1));
    let edges: Vec<(usize, usize, f64)> =
        pairs.into_iter().map(|(i, j, d2)| (i, j, (-d2 / (sigma[i] * sigma[j])).exp())).collect();
    // A bandwidth far below the distances makes every weight underflow to 0: the graph would
    // have no edges and every eigenvalue 0 — an error, not a silent result.
    let mut degree = vec![0.0; n];
    for &(i, j, w) in &edges {
        degree[i] += w;
        degree[j] += w;
    }
    if let Some(i) = degree.iter().position(|&d| d.is_nan() || d <= 0.0) {
        let nearest = nbrs[i].first().map_or(0.0, |&(d2, _)| d2.sqrt());
        return Err(Error::invalid(
            "sigma",
            format!(
                "every kNN weight exp(−d²/σᵢσⱼ) of point {i} underflows to 0 (its nearest neighbour is at {nearest:e}, \
                 σᵢ = {:e}); use a bandwidth comparable to the distances, or the self-tuning default",
                sigma[i] / std::f64::consts::SQRT_2
            ),
        ));
    }
    let mut lap = graph(n, &edges, opts.vertex_weights)?;
    lap.kind = LaplacianKind::Knn;
    Ok(lap)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The symbolic factorization is computed once and shared by clones and by the unit-area
    /// copy; a pattern changed through the public field is analysed again.
    #[test]
    fn symbolic_cholesky_is_cached_and_follows_the_pattern() {
        let lap = cotangent(&crate::primitives::icosphere(2)).unwrap();
        let a = lap.symbolic_cholesky().unwrap();
        assert!(Arc::ptr_eq(&a, &lap.symbolic_cholesky().unwrap()));
        assert!(Arc::ptr_eq(&a, &lap.clone().symbolic_cholesky().unwrap()));
        assert!(Arc::ptr_eq(&a, &lap.with_mass(vec![1.0; lap.n()]).symbolic_cholesky().unwrap()));
        // Another pattern (a path graph on as many vertices) in the same Laplacian object.
        let mut other = lap.clone();
        other.w = graph(lap.n(), &(1..lap.n()).map(|i| (i - 1, i, 1.0)).collect::<Vec<_>>(), VertexWeights::Identity)
            .unwrap()
            .w;
        let b = other.symbolic_cholesky().unwrap();
        assert!(!Arc::ptr_eq(&a, &b));
        assert_ne!(a.len_val(), b.len_val());
    }
    use crate::shape::tests::square;

    #[test]
    fn components_of_the_graph_of_w() {
        let two = graph(5, &[(0, 1, 1.0), (1, 2, 0.5), (3, 4, 2.0)], VertexWeights::Identity).unwrap();
        assert_eq!(two.components(), (2, vec![0, 0, 0, 1, 1]));
        let sq = cotangent(&square()).unwrap();
        assert_eq!(sq.components().0, 1);
    }

    fn dense(w: &SparseColMat<usize, f64>) -> Vec<Vec<f64>> {
        let n = w.nrows();
        let mut d = vec![vec![0.0; n]; n];
        let s = w.as_ref();
        for c in 0..n {
            for p in s.symbolic().col_ptr()[c]..s.symbolic().col_ptr()[c + 1] {
                d[s.symbolic().row_idx()[p]][c] += s.val()[p];
            }
        }
        d
    }

    #[test]
    fn zero_area_meshes_are_rejected_not_mollified_into_a_surface() {
        let faces = vec![[0, 1, 2], [1, 2, 3]];
        let line = TriMesh::new(vec![[0., 0., 0.], [1., 0., 0.], [2., 0., 0.], [3., 0., 0.]], faces.clone()).unwrap();
        let point = TriMesh::new(vec![[1., 2., 3.]; 4], faces).unwrap();
        for m in [line, point] {
            let e = cotangent(&m).unwrap_err().to_string();
            assert!(e.contains("zero total area"), "{e}");
        }
        // One degenerate triangle among good ones is still mollified, not rejected.
        let mut v = square().vertices().to_vec();
        v.push([0.5, 0.0, 0.0]);
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3], [0, 4, 1]]).unwrap();
        assert!(cotangent(&m).is_ok());
    }

    #[test]
    fn cotangent_of_square_matches_hand_computation() {
        let l = cotangent(&square()).unwrap();
        let d = dense(&l.w);
        // Diagonal edge 0–2 is opposite two right angles: cot = 0 → weight 0.
        assert!(d[0][2].abs() < 1e-15);
        // Edge 0–1 is opposite a 45° angle in one triangle: w = ½ cot 45° = 0.5.
        assert!((d[0][1] + 0.5).abs() < 1e-15, "{}", d[0][1]);
        for row in &d {
            assert!(row.iter().sum::<f64>().abs() < 1e-14);
        }
        assert!((l.mass.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn degenerate_triangles_give_finite_laplacian() {
        // A sliver (collinear) triangle glued to a good one, plus a triangle with a repeated index.
        let m = TriMesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [2., 0., 0.], [1., 1., 0.]],
            vec![[0, 1, 2], [0, 2, 3], [1, 1, 3]],
        )
        .unwrap();
        let l = cotangent(&m).unwrap();
        assert!(l.w.val().iter().all(|v| v.is_finite()));
        assert!(l.mass.iter().all(|a| a.is_finite() && *a > 0.0));
        for row in dense(&l.w) {
            assert!(row.iter().sum::<f64>().abs() < 1e-9);
        }
    }

    #[test]
    fn unreferenced_vertex_is_an_error() {
        let m = TriMesh::new(vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [5., 5., 5.]], vec![[0, 1, 2]]).unwrap();
        let e = cotangent(&m).unwrap_err().to_string();
        assert!(e.contains("first: 3"), "{e}");
    }

    #[test]
    fn knn_matches_brute_force_and_graph_is_symmetric() {
        // Deterministic pseudo-random points.
        let mut s = 12345u64;
        let mut r = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 300;
        let c3: Vec<f64> = (0..n * 3).map(|_| r()).collect();
        let p3 = PointSet::new(n, 3, c3.clone()).unwrap();
        // The same points padded with a zero 4th coordinate take the brute-force path.
        let c4: Vec<f64> = c3.chunks(3).flat_map(|p| [p[0], p[1], p[2], 0.0]).collect();
        let p4 = PointSet::new(n, 4, c4).unwrap();
        let (a, b) = (knn(&p3, 7).unwrap(), knn(&p4, 7).unwrap());
        for i in 0..n {
            let ia: Vec<usize> = a[i].iter().map(|x| x.1).collect();
            let ib: Vec<usize> = b[i].iter().map(|x| x.1).collect();
            assert_eq!(ia, ib, "point {i}");
        }
        let l = knn_graph(&p3, &KnnOptions::default()).unwrap();
        let d = dense(&l.w);
        for i in 0..n {
            assert!(d[i].iter().sum::<f64>().abs() < 1e-12);
            for j in 0..n {
                assert_eq!(d[i][j], d[j][i]);
                if i != j {
                    assert!(d[i][j] <= 0.0);
                }
            }
        }
        let rw = knn_graph(&p3, &KnnOptions { vertex_weights: VertexWeights::Degree, ..Default::default() }).unwrap();
        for i in 0..n {
            assert!((rw.mass[i] - d[i][i]).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_graph_inputs_are_errors() {
        assert!(graph(3, &[(0, 3, 1.0)], VertexWeights::Identity).is_err());
        assert!(graph(3, &[(0, 0, 1.0)], VertexWeights::Identity).is_err());
        assert!(graph(3, &[(0, 1, f64::NAN)], VertexWeights::Identity).is_err());
        assert!(graph(3, &[(0, 1, 1.0)], VertexWeights::Degree).is_err());
        let p = PointSet::new(3, 3, vec![0.0; 9]).unwrap();
        assert!(knn_graph(&p, &KnnOptions { k: 2, ..Default::default() }).is_err());
        assert!(knn_graph(&p, &KnnOptions { k: 5, ..Default::default() }).is_err());
        // A bandwidth far below the distances: every weight underflows, an error naming sigma.
        let p = PointSet::new(4, 2, vec![0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap();
        let tiny = KnnOptions { k: 2, bandwidth: Bandwidth::Fixed(1e-300), ..Default::default() };
        assert!(matches!(knn_graph(&p, &tiny), Err(Error::Invalid { ref what, .. }) if what == "sigma"));
        assert!(knn_graph(&p, &KnnOptions { k: 2, bandwidth: Bandwidth::Fixed(1.0), ..Default::default() }).is_ok());
    }
}
