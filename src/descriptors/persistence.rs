//! Persistence-based segmentation of shapes and the matching of the segments of two shapes, so
//! that segment indicators can serve as the paper's "scarce" data F, G on shapes nobody annotated.
//!
//! # Segmentation
//!
//! Skraba, Ovsjanikov, Chazal, Guibas 2010, "Persistence-based segmentation of deformable
//! shapes": the maxima of a function f on the vertices seed segments, and the clustering is
//! ToMATo (Chazal, Guibas, Oudot, Skraba 2013, "Persistence-based clustering in Riemannian
//! manifolds") on the vertex graph (mesh edges, or the kNN graph of a point cloud, see
//! [`graph_edges`]):
//!
//! 1. vertices are processed by decreasing f (ties by index, so the result is deterministic);
//! 2. a vertex with no processed (higher) neighbour is a peak and starts a cluster;
//! 3. otherwise it joins the cluster of its highest neighbour (discrete gradient ascent), and every
//!    other neighbouring cluster is compared with that one: when the lower of the two peaks is less
//!    than τ·(max f − min f) above f(vertex), the lower cluster is merged into the higher one.
//!
//! The surviving clusters are exactly the peaks whose 0-dimensional persistence (prominence, by
//! the elder rule: the height of the peak above the level at which its superlevel-set component
//! joins one with a higher peak) is at least τ·(max f − min f), plus the maximum of every connected
//! component. τ is a *fraction of the range of f*, so it means the same on every shape.
//!
//! # The default function
//!
//! [`default_function`] is the scale-normalized heat kernel signature at the time
//! t = [`DEFAULT_HKS_TIME`] / λ₁ = 0.25 / λ₁ (λ₁ the first non-zero eigenvalue). At such a large
//! time the HKS is governed by the first eigenfunctions and its maxima are at the tips of the long
//! protrusions (head, hands, feet of a human), where heat is retained longest. Defining t through
//! λ₁ rather than through the largest computed eigenvalue makes it independent of the basis size
//! k: on FAUST λ₃₀ ≈ 83 λ₁, so e^{−λ_k t} < 10⁻⁹ for k ≥ 30, and the persistence values agree to
//! 10⁻⁹ between k = 30 and k = 100.
//!
//! Why 0.25 and τ = [`DEFAULT_THRESHOLD`] = 0.1 (measured on the 10 shapes of the first 10 FAUST
//! pairs, `cargo run --release --example persistence_agreement -- 10 --scan`; persistence as a
//! fraction of the range): at t = 0.25/λ₁ the five largest persistences are 1, ≥ 0.905, ≥ 0.752,
//! ≥ 0.726, ≥ 0.201 (two hands, two feet, head) and the sixth is ≤ 0.029, so every τ in
//! [0.05, 0.2] gives exactly these 5 segments on all 10 shapes; τ = 0.1 sits in the middle of the
//! gap. Larger times lose the head (at t = 1/λ₁ its persistence is 0.05–0.08, so τ = 0.1 gives 4
//! segments), smaller ones raise the noise (at t = 0.1/λ₁ the sixth peak reaches 0.055).
//!
//! [`average_geodesic_distance`] is an alternative (Skraba et al. use both), computed with the
//! heat method (before, graph distances: EXPERIMENTS.md, "The AGD function on geodesics"); on
//! the same shapes it gives 5 segments for
//! τ ∈ [0.1, 0.2] but 13 at τ = 0.05 (segment agreement with AGD: EXPERIMENTS.md).
//!
//! # Matching
//!
//! [`matched_segment_indicators`] matches the segments of two shapes (any two label vectors,
//! computed or provided) with [`super::matching::match_regions`], using the area-weighted mean of
//! 16 scale-normalized HKS and 16 scale-normalized WKS over each segment (plus its relative area)
//! as the segment's signature, and returns the indicator matrices F (n × s), G (m × s) in matched
//! order: column j of F corresponds to column j of G.

use faer::Mat;

use super::matching::{match_regions, RegionMatch};
use super::signatures::{hks, hks_times, wks};
use super::{segments, Descriptors};
use crate::error::{Error, Result};
use crate::geodesic::{Distances, GeodesicMethod, GraphGeodesics};
use crate::laplacian::Laplacian;
use crate::shape::{adjacency, PointSet, TriMesh, UnionFind};
use crate::spectral::Basis;

/// Time of the default function in units of 1/λ₁: t = `DEFAULT_HKS_TIME` / λ₁.
pub const DEFAULT_HKS_TIME: f64 = 0.25;

/// Default persistence threshold τ, as a fraction of max f − min f of the default function
/// (see the module documentation for how it was chosen).
pub const DEFAULT_THRESHOLD: f64 = 0.1;

/// Number of scale-normalized HKS times in the segment signatures of [`matching_descriptor`].
pub const MATCH_HKS: usize = 16;

/// Number of scale-normalized WKS energies in the segment signatures of [`matching_descriptor`].
pub const MATCH_WKS: usize = 16;

/// Number of farthest-point-sampled sources of [`average_geodesic_distance`] by default.
pub const DEFAULT_AGD_SOURCES: usize = 32;

/// The function whose maxima seed the persistence segments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SegmentFunction {
    /// Scale-normalized heat kernel signature at t = `hks_time` / λ₁ (maxima at protrusions).
    Hks,
    /// Average geodesic distance from [`DEFAULT_AGD_SOURCES`] farthest-point sources
    /// (heat-method geodesics on meshes, kNN-graph distances on point clouds).
    Agd,
}

/// Options of [`segment_labels`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentationOptions {
    /// The function whose maxima seed the segments.
    pub function: SegmentFunction,
    /// Persistence threshold τ as a fraction of the function's range (0–1).
    pub threshold: f64,
    /// HKS time, in units of 1/λ₁.
    pub hks_time: f64,
}

impl Default for SegmentationOptions {
    fn default() -> Self {
        SegmentationOptions { function: SegmentFunction::Hks, threshold: DEFAULT_THRESHOLD, hks_time: DEFAULT_HKS_TIME }
    }
}

/// Persistence segmentation of a shape (mesh or point set with its Laplacian `lap` and basis):
/// labels 1..=s, one per vertex (length n).
pub fn segment_labels(
    shape: &crate::shape::Shape,
    lap: &Laplacian,
    basis: &Basis,
    opts: &SegmentationOptions,
) -> Result<Vec<u32>> {
    use crate::shape::Shape;
    let edges = match shape {
        Shape::Mesh(m) => m.edges(),
        Shape::Points(_) => graph_edges(lap),
    };
    let f = match (opts.function, shape) {
        (SegmentFunction::Hks, _) => hks_function(basis, opts.hks_time)?,
        (SegmentFunction::Agd, Shape::Mesh(m)) => average_geodesic_distance(m, DEFAULT_AGD_SOURCES)?,
        (SegmentFunction::Agd, Shape::Points(p)) => average_graph_distance(p, &edges, DEFAULT_AGD_SOURCES)?,
    };
    Ok(persistence_segmentation(shape.n_vertices(), &edges, &f, opts.threshold)?.labels)
}

/// A segmentation of a shape with n vertices into s segments.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// Segment of every vertex (length n), 1-based: segment 1 has the highest peak, segment s the
    /// lowest.
    pub labels: Vec<u32>,
    /// Peak vertex (maximum of f) of every segment (length s), in label order.
    pub peaks: Vec<usize>,
    /// Persistence of every segment's peak (length s), in the units of f: the peak value minus the
    /// level at which its superlevel-set component meets one with a higher peak. The maximum of a
    /// connected component never meets a higher one; it gets f(peak) − min f (the range
    /// max f − min f for the global maximum).
    pub persistence: Vec<f64>,
}

impl Segmentation {
    /// Number of segments s.
    pub fn n_segments(&self) -> usize {
        self.peaks.len()
    }
}

/// The edges `[i, j]` (i < j, sorted) of the sparsity pattern of W: the mesh edges of a cotangent
/// Laplacian, the kNN graph of a point-cloud Laplacian. Stored off-diagonal entries count even
/// when their weight is zero (an edge opposite two right angles), since they are still edges.
pub fn graph_edges(lap: &Laplacian) -> Vec<[u32; 2]> {
    let w = lap.w.as_ref();
    let (col_ptr, row_idx) = (w.symbolic().col_ptr(), w.symbolic().row_idx());
    let mut edges = Vec::with_capacity(row_idx.len() / 2);
    for c in 0..w.ncols() {
        for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
            if r < c {
                edges.push([r as u32, c as u32]);
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Persistence-based segmentation (ToMATo) of a graph with `n` vertices and undirected `edges`
/// by the maxima of `f` (length n), keeping the peaks whose persistence is at least
/// `threshold` × (max f − min f); see the module documentation.
///
/// τ = 0 keeps every local maximum; τ = 1 keeps one segment per connected component. Peaks of
/// persistence exactly 0 (plateaus) are merged whenever τ > 0.
///
/// Errors: n = 0 or ≥ 2³², `f.len() != n`, a non-finite value of f, τ outside [0, 1], an edge index ≥ n.
pub fn persistence_segmentation(n: usize, edges: &[[u32; 2]], f: &[f64], threshold: f64) -> Result<Segmentation> {
    if n == 0 {
        return Err(Error::invalid("graph", "it has no vertices"));
    }
    if n > u32::MAX as usize {
        return Err(Error::invalid("graph", format!("{n} vertices (at most 2³² − 1)")));
    }
    if f.len() != n {
        return Err(Error::invalid("function", format!("{} values for {n} vertices", f.len())));
    }
    if let Some(i) = f.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid("function", format!("value {} at vertex {i} is not finite", f[i])));
    }
    if !(0.0..=1.0).contains(&threshold) {
        return Err(Error::invalid(
            "threshold",
            format!("τ is a fraction of the range of f and must be in [0, 1], got {threshold}"),
        ));
    }
    let (start, adj) = adjacency(n, edges)?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_unstable_by(|&a, &b| f[b].total_cmp(&f[a]).then(a.cmp(&b)));
    let mut rank = vec![0usize; n];
    for (r, &v) in order.iter().enumerate() {
        rank[v] = r;
    }
    let lo = f.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let thr = threshold * (hi - lo);
    let merges = |height: f64| height < thr || (height == 0.0 && threshold > 0.0);

    // `cluster`: the ToMATo forest (roots are the peaks of the current clusters).
    // `component`: superlevel-set components under the elder rule, for the persistence values.
    // In both, a root is the peak vertex of its tree. Vertices are processed by rank: u is
    // processed before v when rank[u] < rank[v] (before that it is a singleton in both).
    let mut cluster = UnionFind::new(n);
    let mut component = UnionFind::new(n);
    let mut persistence = vec![f64::NAN; n];
    let mut higher: Vec<usize> = Vec::new();
    let mut roots: Vec<usize> = Vec::new();
    let find = |uf: &mut UnionFind, i: usize| uf.find(i as u32) as usize;
    for &v in &order {
        higher.clear();
        higher.extend(adj[start[v]..start[v + 1]].iter().map(|&u| u as usize).filter(|&u| rank[u] < rank[v]));
        if higher.is_empty() {
            continue;
        }
        // ToMATo: join the cluster of the highest neighbour, then merge neighbouring clusters.
        let g = *higher.iter().min_by_key(|&&u| rank[u]).expect("not empty");
        let mut e = find(&mut cluster, g);
        cluster.union_into(v as u32, e as u32);
        for &u in &higher {
            let r = find(&mut cluster, u);
            if r != e {
                let (low, high) = if rank[r] < rank[e] { (e, r) } else { (r, e) };
                if merges(f[low] - f[v]) {
                    cluster.union_into(low as u32, high as u32);
                    e = high;
                }
            }
        }
        // Elder rule: the components met at v die except the one with the highest peak.
        roots.clear();
        roots.extend(higher.iter().map(|&u| find(&mut component, u)));
        roots.sort_unstable_by_key(|&r| rank[r]);
        roots.dedup();
        let oldest = roots[0];
        for &r in &roots[1..] {
            persistence[r] = f[r] - f[v];
            component.union_into(r as u32, oldest as u32);
        }
        component.union_into(v as u32, oldest as u32);
    }
    // Surviving clusters, by decreasing peak.
    let mut peaks: Vec<usize> = (0..n).filter(|&v| cluster.is_root(v as u32)).collect();
    peaks.sort_unstable_by_key(|&p| rank[p]);
    let mut label_of_root = vec![0u32; n];
    for (s, &p) in peaks.iter().enumerate() {
        label_of_root[p] = s as u32 + 1;
    }
    let labels: Vec<u32> = (0..n).map(|v| label_of_root[find(&mut cluster, v)]).collect();
    let persistence: Vec<f64> =
        peaks.iter().map(|&p| if persistence[p].is_nan() { f[p] - lo } else { persistence[p] }).collect();
    Ok(Segmentation { labels, peaks, persistence })
}

/// First non-zero eigenvalue λ₁ of a basis (λ > 1e-8 · λ_k).
fn first_nonzero_eigenvalue(basis: &Basis) -> Result<f64> {
    let lk = basis.eigenvalues.last().copied().unwrap_or(0.0);
    basis
        .eigenvalues
        .iter()
        .copied()
        .find(|&l| l > 1e-8 * lk && lk > 0.0)
        .ok_or_else(|| Error::invalid("basis", "it has no non-zero eigenvalue; compute more eigenpairs"))
}

/// The default function whose maxima seed the segments: the scale-normalized HKS at
/// t = [`DEFAULT_HKS_TIME`] / λ₁ (length n). See the module documentation.
///
/// Errors: a basis without a non-zero eigenvalue.
pub fn default_function(basis: &Basis) -> Result<Vec<f64>> {
    hks_function(basis, DEFAULT_HKS_TIME)
}

/// The scale-normalized HKS at t = `time` / λ₁ (length n), `time` > 0.
pub fn hks_function(basis: &Basis, time: f64) -> Result<Vec<f64>> {
    if !(time.is_finite() && time > 0.0) {
        return Err(Error::invalid("time", format!("the HKS time must be positive, got {time}")));
    }
    let l1 = first_nonzero_eigenvalue(basis)?;
    let h = hks(basis, &[time / l1], true)?;
    Ok(h.values.col_as_slice(0).to_vec())
}

/// [`default_function`] followed by [`persistence_segmentation`] on `edges` with threshold τ
/// (e.g. [`DEFAULT_THRESHOLD`]).
pub fn segment(edges: &[[u32; 2]], basis: &Basis, threshold: f64) -> Result<Segmentation> {
    let f = default_function(basis)?;
    persistence_segmentation(basis.n(), edges, &f, threshold)
}

/// Average graph distance of every point to `sources` farthest-point-sampled points (length n,
/// in the units of the coordinates), on the graph `edges` weighted by Euclidean edge lengths.
///
/// The first source is the point farthest from point 0; each next one is the point farthest from
/// the sources so far (deterministic). Graph distances along mesh edges overestimate geodesic
/// distances by a few percent, since paths are restricted to edges (by 6% on average on a
/// subdivided icosahedron with 2562 vertices). This is [`average_distance`] with Dijkstra on the
/// graph ([`GraphGeodesics::point_edges`]).
///
/// Errors: `sources` = 0, no points, an edge index out of range, a disconnected graph.
pub fn average_graph_distance(points: &PointSet, edges: &[[u32; 2]], sources: usize) -> Result<Vec<f64>> {
    if sources == 0 {
        return Err(Error::invalid("sources", "need at least one source"));
    }
    average_distance(&GraphGeodesics::point_edges(points, edges)?, sources)
}

/// Average distance of every vertex to `sources` farthest-point-sampled vertices (length n, in
/// the units of `d`), for any distance solver `d` on a connected shape.
///
/// The first source is the vertex farthest from vertex 0; each next one is the vertex farthest
/// from the sources so far (ties: the lowest index; deterministic).
///
/// Errors: `sources` = 0, a vertex unreachable from vertex 0, and those of the solver.
pub fn average_distance(d: &dyn Distances, sources: usize) -> Result<Vec<f64>> {
    let n = d.n_vertices();
    if sources == 0 {
        return Err(Error::invalid("sources", "need at least one source"));
    }
    if n == 0 {
        return Err(Error::invalid("shape", "it has no vertices"));
    }
    let argmax = |d: &[f64]| (0..n).fold(0, |best, i| if d[i] > d[best] { i } else { best });
    let d0 = d.distances_from(&[0])?;
    let d0 = d0.col_as_slice(0);
    if let Some(i) = d0.iter().position(|d| !d.is_finite()) {
        return Err(Error::invalid("shape", format!("it is disconnected (vertex {i} is unreachable from vertex 0)")));
    }
    let mut source = argmax(d0);
    let mut sum = vec![0.0; n];
    let mut nearest = vec![f64::INFINITY; n];
    for _ in 0..sources.min(n) {
        let col = d.distances_from(&[source])?;
        for (i, &x) in col.col_as_slice(0).iter().enumerate() {
            sum[i] += x;
            nearest[i] = nearest[i].min(x);
        }
        source = argmax(&nearest);
    }
    let count = sources.min(n) as f64;
    Ok(sum.into_iter().map(|s| s / count).collect())
}

/// Average geodesic distance (Skraba et al.'s alternative function, maxima at the extremities) of
/// every vertex of a mesh: [`average_distance`] from `sources` farthest-point samples (e.g.
/// [`DEFAULT_AGD_SOURCES`]) with the heat method ([`crate::geodesic::HeatGeodesics`], 2–4 % mean
/// error against exact distances on the benchmark shapes, and smooth), divided by √(surface
/// area) so it is scale invariant (dimensionless). Same as
/// [`average_geodesic_distance_with`] with [`GeodesicMethod::Heat`].
///
/// Errors: a mesh of zero area, several components or unreferenced vertices.
pub fn average_geodesic_distance(mesh: &TriMesh, sources: usize) -> Result<Vec<f64>> {
    average_geodesic_distance_with(mesh, sources, GeodesicMethod::Heat)
}

/// [`average_geodesic_distance`] with the distances of `method`: exact (MMP; 32 full solves, a
/// few seconds on 5,000 vertices), heat (one factorization, then two triangular solves per
/// source), or Dijkstra on the mesh edges (overestimates by about 6 %; the function used before
/// the heat method, EXPERIMENTS.md, "The AGD function on geodesics").
pub fn average_geodesic_distance_with(mesh: &TriMesh, sources: usize, method: GeodesicMethod) -> Result<Vec<f64>> {
    let area = mesh.total_area();
    if area.is_nan() || area <= 0.0 {
        return Err(Error::invalid("mesh", "it has zero area"));
    }
    let d = average_distance(method.build(mesh)?.as_ref(), sources)?;
    Ok(d.into_iter().map(|x| x / area.sqrt()).collect())
}

/// The per-vertex descriptor the segments are matched with: [`MATCH_HKS`] scale-normalized HKS
/// (at the times of [`hks_times`]) followed by [`MATCH_WKS`] scale-normalized WKS (n × 32).
pub fn matching_descriptor(basis: &Basis) -> Result<Descriptors> {
    let h = hks(basis, &hks_times(basis, MATCH_HKS)?, true)?;
    h.concat(&wks(basis, MATCH_WKS, true)?)
}

/// Matches the segments of X (`labels_x`, one label per vertex of `basis_x`) and Y (`labels_y`)
/// by their mean [`matching_descriptor`] and returns (F, G, matches): F (n × s) and G (m × s) are
/// the indicators of the matched segments in matched order (column j of F ↔ column j of G,
/// named `segment:L` with the shape's own label L), s = min(#segments of X, #segments of Y).
/// `matches[j]` gives the segments' columns in [`segments`] order (ascending labels) and the
/// signature distance.
///
/// Works for any two label vectors, computed ([`Segmentation::labels`]) or provided (label files).
/// Errors: a label vector whose length is not the basis's n, a basis too small for signatures.
pub fn matched_segment_indicators(
    labels_x: &[u32],
    basis_x: &Basis,
    labels_y: &[u32],
    basis_y: &Basis,
) -> Result<(Descriptors, Descriptors, Vec<RegionMatch>)> {
    check_labels("X", labels_x, basis_x.n())?;
    check_labels("Y", labels_y, basis_y.n())?;
    let (dx, dy) = (matching_descriptor(basis_x)?, matching_descriptor(basis_y)?);
    matched_segment_indicators_with(labels_x, &basis_x.mass, &dx, labels_y, &basis_y.mass, &dy)
}

fn check_labels(shape: &str, labels: &[u32], n: usize) -> Result<()> {
    if labels.len() != n {
        return Err(Error::invalid(
            "labels",
            format!("{} labels for shape {shape} with {n} vertices (one label per vertex)", labels.len()),
        ));
    }
    Ok(())
}

/// [`matched_segment_indicators`] with any per-vertex descriptors `dx` (n × q) and `dy` (m × q)
/// and vertex weights `mass_x`, `mass_y`.
pub fn matched_segment_indicators_with(
    labels_x: &[u32],
    mass_x: &[f64],
    dx: &Descriptors,
    labels_y: &[u32],
    mass_y: &[f64],
    dy: &Descriptors,
) -> Result<(Descriptors, Descriptors, Vec<RegionMatch>)> {
    check_labels("X", labels_x, dx.n())?;
    check_labels("Y", labels_y, dy.n())?;
    let (sx, sy) = (segments(labels_x)?, segments(labels_y)?);
    let matches = match_regions(&sx, mass_x, dx, &sy, mass_y, dy)?;
    let pick = |s: &Descriptors, cols: Vec<usize>| -> Descriptors {
        let values = Mat::from_fn(s.n(), cols.len(), |i, j| s.values[(i, cols[j])]);
        Descriptors { values, names: cols.iter().map(|&c| s.names[c].clone()).collect() }
    };
    let f = pick(&sx, matches.iter().map(|m| m.x).collect());
    let g = pick(&sy, matches.iter().map(|m| m.y).collect());
    Ok((f, g, matches))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::indices::read_labels_file;
    use crate::laplacian::cotangent;
    use crate::primitives::{icosphere, rectangle};
    use crate::shape::Shape;
    use crate::spectral::{eigen_basis, SpectralOptions};
    use std::path::{Path, PathBuf};
    use std::sync::OnceLock;

    fn path_edges(n: usize) -> Vec<[u32; 2]> {
        (0..n as u32 - 1).map(|i| [i, i + 1]).collect()
    }

    #[test]
    fn path_graph_persistence_is_exact() {
        // Maxima 5 (vertex 1), 3 (vertex 3), 8 (vertex 5), 4.5 (vertex 7); saddles 1 (v2), 2 (v4),
        // 0 (v6). Elder rule: 3 dies at 2 (persistence 1), 5 at 1 (4), 4.5 at 0 (4.5); range 8.
        let f = [0.0, 5.0, 1.0, 3.0, 2.0, 8.0, 0.0, 4.5, 0.0];
        let e = path_edges(f.len());
        let all = persistence_segmentation(9, &e, &f, 0.0).unwrap();
        assert_eq!(all.peaks, vec![5, 1, 7, 3]);
        assert_eq!(all.persistence, vec![8.0, 4.0, 4.5, 1.0]);
        assert_eq!(all.labels, vec![2, 2, 2, 4, 1, 1, 1, 3, 3]);
        // τ·range just below / above the persistence 1 of vertex 3 keeps / merges it.
        let keep = persistence_segmentation(9, &e, &f, 0.99 / 8.0).unwrap();
        assert_eq!(keep.peaks, vec![5, 1, 7, 3]);
        let merge = persistence_segmentation(9, &e, &f, 1.01 / 8.0).unwrap();
        assert_eq!(merge.peaks, vec![5, 1, 7]);
        assert_eq!(merge.labels, vec![2, 2, 2, 1, 1, 1, 1, 3, 3]);
        // Between 4 and 4.5 only the peak 5 goes (into the segment of 8, across vertex 3).
        let two = persistence_segmentation(9, &e, &f, 4.2 / 8.0).unwrap();
        assert_eq!(two.peaks, vec![5, 7]);
        assert_eq!(two.persistence, vec![8.0, 4.5]);
        assert_eq!(two.labels, vec![1, 1, 1, 1, 1, 1, 1, 2, 2]);
        let one = persistence_segmentation(9, &e, &f, 1.0).unwrap();
        assert_eq!(one.labels, vec![1; 9]);
        // Persistence does not depend on vertex numbering: reverse the path.
        let rev: Vec<f64> = f.iter().rev().copied().collect();
        let r = persistence_segmentation(9, &e, &rev, 0.0).unwrap();
        assert_eq!(r.peaks, vec![3, 7, 1, 5]);
        assert_eq!(r.persistence, vec![8.0, 4.0, 4.5, 1.0]);
    }

    #[test]
    fn survivors_are_the_peaks_above_the_threshold() {
        // Random functions on a grid graph: the ToMATo clusters are exactly the peaks whose
        // elder-rule persistence reaches τ·range, every segment is connected and contains its peak,
        // and its peak is its maximum.
        let grid = rectangle(1.0, 1.0, 24, 24);
        let edges = grid.edges();
        let n = grid.n_vertices();
        let mut s = 7u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for trial in 0..5 {
            let f: Vec<f64> = (0..n)
                .map(|i| {
                    let p = grid.vertices()[i];
                    (7.0 * p[0] + trial as f64).sin() * (5.0 * p[1]).cos() + 0.3 * rnd()
                })
                .collect();
            let range = f.iter().copied().fold(f64::MIN, f64::max) - f.iter().copied().fold(f64::MAX, f64::min);
            let all = persistence_segmentation(n, &edges, &f, 0.0).unwrap();
            for tau in [0.02, 0.05, 0.1, 0.3] {
                let seg = persistence_segmentation(n, &edges, &f, tau).unwrap();
                let want: Vec<usize> = all
                    .peaks
                    .iter()
                    .zip(&all.persistence)
                    .filter(|(_, &p)| p >= tau * range)
                    .map(|(&v, _)| v)
                    .collect();
                assert_eq!(seg.peaks, want, "trial {trial} τ {tau}");
                assert!(seg.persistence.iter().all(|&p| p >= tau * range));
                for (k, &p) in seg.peaks.iter().enumerate() {
                    assert_eq!(seg.labels[p], k as u32 + 1);
                    let max = (0..n).filter(|&i| seg.labels[i] == k as u32 + 1).map(|i| f[i]).fold(f64::MIN, f64::max);
                    assert_eq!(max, f[p]);
                    // Connected: flood fill within the segment from the peak.
                    let (start, adj) = adjacency(n, &edges).unwrap();
                    let mut seen = vec![false; n];
                    let mut stack = vec![p];
                    seen[p] = true;
                    while let Some(v) = stack.pop() {
                        for &u in &adj[start[v]..start[v + 1]] {
                            let u = u as usize;
                            if !seen[u] && seg.labels[u] == seg.labels[p] {
                                seen[u] = true;
                                stack.push(u);
                            }
                        }
                    }
                    let size = seg.labels.iter().filter(|&&l| l == k as u32 + 1).count();
                    assert_eq!(seen.iter().filter(|&&b| b).count(), size, "segment {k} is not connected");
                }
            }
        }
    }

    #[test]
    fn plateaus_and_components() {
        // A constant function on two separate paths: with τ > 0 one segment per component.
        let edges = [[0, 1], [1, 2], [3, 4]];
        let s = persistence_segmentation(5, &edges, &[1.0; 5], 0.5).unwrap();
        assert_eq!(s.labels, vec![1, 1, 1, 2, 2]);
        // A star whose leaves come first in the tie order: τ = 0 keeps the zero-persistence peaks.
        let star = [[3, 0], [3, 1], [3, 2]];
        assert_eq!(persistence_segmentation(4, &star, &[1.0; 4], 0.0).unwrap().n_segments(), 3);
        assert_eq!(persistence_segmentation(4, &star, &[1.0; 4], 0.1).unwrap().n_segments(), 1);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let e = path_edges(3);
        assert!(persistence_segmentation(3, &e, &[0.0, f64::NAN, 1.0], 0.1).is_err());
        assert!(persistence_segmentation(3, &e, &[0.0, 1.0, 2.0], 1.5).is_err());
        assert!(persistence_segmentation(3, &e, &[0.0, 1.0, 2.0], -0.1).is_err());
        assert!(persistence_segmentation(3, &e, &[0.0, 1.0, 2.0], f64::NAN).is_err());
        assert!(persistence_segmentation(3, &e, &[0.0, 1.0], 0.1).is_err());
        assert!(persistence_segmentation(3, &[[0, 3]], &[0.0, 1.0, 2.0], 0.1).is_err());
        assert!(persistence_segmentation(0, &[], &[], 0.1).is_err());
        let (mesh, basis) = bumps();
        let labels = vec![1u32; mesh.n_vertices()];
        assert!(matched_segment_indicators(&labels[1..], basis, &labels, basis).is_err());
        assert!(matched_segment_indicators(&labels, basis, &[1, 2, 3], basis).is_err());
        let e = matched_segment_indicators(&labels, basis, &[1, 2, 3], basis).unwrap_err().to_string();
        assert!(e.contains("3 labels"), "{e}");
        let pts = PointSet::new(3, 3, vec![0.0; 9]).unwrap();
        assert!(average_graph_distance(&pts, &[[0, 1]], 4).is_err()); // vertex 2 unreachable
        assert!(average_graph_distance(&pts, &path_edges(3), 0).is_err());
    }

    #[test]
    fn graph_distances_overestimate_sphere_geodesics_slightly() {
        // On the unit sphere the mean geodesic distance from any point to points spread evenly
        // over the sphere is π/2; edge paths are a few percent longer.
        let s = icosphere(4);
        let d = average_graph_distance(&s.to_point_set(), &s.edges(), DEFAULT_AGD_SOURCES).unwrap();
        let mean = d.iter().sum::<f64>() / d.len() as f64 / std::f64::consts::FRAC_PI_2;
        // Measured: 1.063 (per vertex 1.025 to 1.113, as 32 samples are not perfectly even).
        assert!(mean > 1.02 && mean < 1.10, "{mean}");
    }

    #[test]
    fn average_geodesic_distance_uses_surface_geodesics() {
        // Unit sphere: the mean over the vertices of the average distance to any sources is π/2
        // for exact geodesics; the default (heat) AGD must be close to the exact one, the edge
        // paths used before were 6 % long.
        let s = icosphere(4);
        let scale = s.total_area().sqrt() / std::f64::consts::FRAC_PI_2;
        let agd = |m: GeodesicMethod| average_geodesic_distance_with(&s, DEFAULT_AGD_SOURCES, m).unwrap();
        let (exact, heat, dijkstra) =
            (agd(GeodesicMethod::Exact), agd(GeodesicMethod::Heat), agd(GeodesicMethod::Dijkstra));
        assert_eq!(heat, average_geodesic_distance(&s, DEFAULT_AGD_SOURCES).unwrap());
        let mean = |d: &[f64]| d.iter().sum::<f64>() / d.len() as f64 * scale;
        assert!((mean(&exact) - 1.0).abs() < 0.003, "exact {}", mean(&exact));
        assert!((mean(&heat) - 1.0).abs() < 0.015, "heat {}", mean(&heat));
        assert!(mean(&dijkstra) > 1.04, "dijkstra {}", mean(&dijkstra));
        // Per vertex, the 32 sources are not perfectly even: measured 0.966–1.033 × π/2 (exact),
        // 0.963–1.019 (heat), 1.025–1.113 (Dijkstra); means 0.9994, 0.991, 1.063.
        for (name, d) in [("exact", &exact), ("heat", &heat)] {
            let (lo, hi) = d.iter().fold((f64::INFINITY, 0.0f64), |(l, h), &x| (l.min(x * scale), h.max(x * scale)));
            assert!(lo > 0.95 && hi < 1.05, "{name}: {lo}–{hi}");
        }
        // Errors: no source, a disconnected mesh.
        assert!(average_geodesic_distance(&s, 0).is_err());
        let n = s.n_vertices() as u32;
        let mut v = s.vertices().to_vec();
        v.extend(s.vertices().iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
        let mut f = s.faces().to_vec();
        f.extend(s.faces().iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
        let two = TriMesh::new(v, f).unwrap();
        for m in GeodesicMethod::ALL {
            assert!(average_geodesic_distance_with(&two, 4, m).is_err(), "{m}");
        }
    }

    #[test]
    fn graph_edges_are_the_edges_of_w() {
        let edges = [(0, 3, 1.0), (2, 1, 0.5), (1, 3, 0.0), (4, 0, 2.0)];
        let lap = crate::laplacian::graph(5, &edges, crate::laplacian::VertexWeights::Identity).unwrap();
        assert_eq!(graph_edges(&lap), vec![[0, 3], [0, 4], [1, 2], [1, 3]]);
    }

    /// Unit-sphere directions of the bumps, with their heights (all different, so the spectrum has
    /// no multiple eigenvalues).
    const BUMPS: [([f64; 3], f64); 4] =
        [([0.0, 0.0, 1.0], 0.9), ([0.94, 0.0, -0.34], 0.8), ([-0.47, 0.82, -0.33], 0.7), ([-0.47, -0.82, -0.33], 0.6)];

    /// An icosphere(4) with four Gaussian bumps pushed outwards, and its basis (k = 60).
    fn bumps() -> &'static (TriMesh, Basis) {
        static CELL: OnceLock<(TriMesh, Basis)> = OnceLock::new();
        CELL.get_or_init(|| {
            let s = icosphere(4);
            let v = s
                .vertices()
                .iter()
                .map(|p| {
                    let r = 1.0
                        + BUMPS
                            .iter()
                            .map(|(d, h)| {
                                let dot = (p[0] * d[0] + p[1] * d[1] + p[2] * d[2]).clamp(-1.0, 1.0);
                                h * (-dot.acos().powi(2) / (2.0 * 0.25f64.powi(2))).exp()
                            })
                            .sum::<f64>();
                    [r * p[0], r * p[1], r * p[2]]
                })
                .collect();
            let mesh = TriMesh::new(v, s.faces().to_vec()).unwrap();
            let basis = eigen_basis(&cotangent(&mesh).unwrap(), &SpectralOptions::new(60), None).unwrap().0;
            (mesh, basis)
        })
    }

    #[test]
    fn one_segment_per_protrusion() {
        let (mesh, basis) = bumps();
        let seg = segment(&mesh.edges(), basis, DEFAULT_THRESHOLD).unwrap();
        // The apex of every bump: the vertex farthest out along its direction.
        let apex: Vec<usize> = BUMPS
            .iter()
            .map(|(d, _)| {
                let dot = |i: usize| {
                    let p = mesh.vertices()[i];
                    p[0] * d[0] + p[1] * d[1] + p[2] * d[2]
                };
                (0..mesh.n_vertices()).max_by(|&a, &b| dot(a).total_cmp(&dot(b))).unwrap()
            })
            .collect();
        let s = seg.n_segments();
        assert!(s == BUMPS.len() || s == BUMPS.len() + 1, "{s} segments, persistence {:?}", seg.persistence);
        let mut apex_labels: Vec<u32> = apex.iter().map(|&a| seg.labels[a]).collect();
        apex_labels.sort_unstable();
        apex_labels.dedup();
        assert_eq!(apex_labels.len(), BUMPS.len(), "apexes share segments: {:?}", seg.labels);
        // Every peak of a bump segment is near its apex (within 0.3 in R³; bump width 0.25 rad).
        for &a in &apex {
            let p = seg.peaks[seg.labels[a] as usize - 1];
            let (x, y) = (mesh.vertices()[a], mesh.vertices()[p]);
            let d = ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt();
            assert!(d < 0.3, "peak {p} is {d} from apex {a}");
        }
        // Graph edges of the Laplacian are the mesh edges.
        assert_eq!(graph_edges(&cotangent(mesh).unwrap()), mesh.edges());
        // Average geodesic distance also peaks at the bumps: every apex is within 0.3 of a local max.
        let agd = average_geodesic_distance(mesh, DEFAULT_AGD_SOURCES).unwrap();
        let a = persistence_segmentation(mesh.n_vertices(), &mesh.edges(), &agd, DEFAULT_THRESHOLD).unwrap();
        let mut agd_labels: Vec<u32> = apex.iter().map(|&v| a.labels[v]).collect();
        agd_labels.sort_unstable();
        agd_labels.dedup();
        assert_eq!(agd_labels.len(), BUMPS.len(), "AGD: {} segments", a.n_segments());
    }

    fn faust(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(name)
    }
    /// The bundled FAUST pair: meshes and bases (k = 60).
    fn faust_pair() -> &'static [(TriMesh, Basis); 2] {
        static CELL: OnceLock<[(TriMesh, Basis); 2]> = OnceLock::new();
        CELL.get_or_init(|| {
            let load = |name: &str| {
                let Shape::Mesh(m) = Shape::load(&faust(name)).unwrap() else { panic!("not a mesh") };
                let b = eigen_basis(&cotangent(&m).unwrap(), &SpectralOptions::new(60), None).unwrap().0;
                (m, b)
            };
            [load("tr_reg_000.off"), load("tr_reg_001.off")]
        })
    }

    #[test]
    fn faust_default_gives_a_few_segments() {
        for ((mesh, basis), name) in faust_pair().iter().zip(["tr_reg_000", "tr_reg_001"]) {
            let seg = segment(&mesh.edges(), basis, DEFAULT_THRESHOLD).unwrap();
            let s = seg.n_segments();
            assert!((3..=8).contains(&s), "{s} segments, persistence {:?}", seg.persistence);
            // Measured: 5 segments, peaked at the head (provided label 1), the hands (10) and the
            // feet (11).
            let provided =
                read_labels_file(&faust(&format!("tr_reg_000_tr_reg_001.{name}.seg.sym")), mesh.n_vertices()).unwrap();
            let mut at_peaks: Vec<u32> = seg.peaks.iter().map(|&p| provided[p]).collect();
            at_peaks.sort_unstable();
            assert_eq!(at_peaks, vec![1, 10, 10, 11, 11], "{name}");
        }
    }

    #[test]
    fn faust_provided_segments_are_matched() {
        let [(mx, bx), (my, by)] = faust_pair();
        let lx = read_labels_file(&faust("tr_reg_000_tr_reg_001.tr_reg_000.seg.sym"), mx.n_vertices()).unwrap();
        let ly = read_labels_file(&faust("tr_reg_000_tr_reg_001.tr_reg_001.seg.sym"), my.n_vertices()).unwrap();
        let (f, g, matches) = matched_segment_indicators(&lx, bx, &ly, by).unwrap();
        assert_eq!(matches.len(), 11);
        assert_eq!((f.n(), g.n(), f.q(), g.q()), (mx.n_vertices(), my.n_vertices(), 11, 11));
        let correct = f.names.iter().zip(&g.names).filter(|(a, b)| a == b).count();
        assert!(correct >= MIN_CORRECT, "{correct} of 11 segments matched: {:?} vs {:?}", f.names, g.names);
        // Column j of F (G) is the indicator of X's (Y's) segment of match j.
        let (sx, sy) = (segments(&lx).unwrap(), segments(&ly).unwrap());
        for (j, m) in matches.iter().enumerate() {
            assert_eq!((&f.names[j], &g.names[j]), (&sx.names[m.x], &sy.names[m.y]));
            assert_eq!(f.values.col(j), sx.values.col(m.x));
            assert_eq!(g.values.col(j), sy.values.col(m.y));
        }
        // The left–right split segmentation (19 segments): symmetric parts could be swapped, but
        // on this pair they are not.
        let nx = read_labels_file(&faust("tr_reg_000_tr_reg_001.tr_reg_000.seg.nonsym"), mx.n_vertices()).unwrap();
        let ny = read_labels_file(&faust("tr_reg_000_tr_reg_001.tr_reg_001.seg.nonsym"), my.n_vertices()).unwrap();
        let (f, g, _) = matched_segment_indicators(&nx, bx, &ny, by).unwrap();
        assert_eq!(f.q(), 19);
        let correct = f.names.iter().zip(&g.names).filter(|(a, b)| a == b).count();
        assert!(correct >= MIN_CORRECT_NONSYM, "{correct} of 19 segments matched: {:?} vs {:?}", f.names, g.names);
    }

    /// Measured 11 of 11 (.seg.sym) and 19 of 19 (.seg.nonsym) with k = 30, 60 and 100; the
    /// thresholds leave a margin. See EXPERIMENTS.md.
    const MIN_CORRECT: usize = 10;
    const MIN_CORRECT_NONSYM: usize = 17;

    #[test]
    fn indicators_come_in_matched_order() {
        // Three segments with distinct descriptor values; Y numbers them differently.
        let (lx, ly) = ([1u32, 1, 2, 2, 3], [3u32, 3, 1, 1, 2]);
        let d = |v: [f64; 5]| Descriptors::new(Mat::from_fn(5, 1, |i, _| v[i]), vec!["f".into()]).unwrap();
        let (dx, dy) = (d([1.0, 1.0, 4.0, 4.0, 9.0]), d([1.1, 1.1, 4.1, 4.1, 9.1]));
        let (f, g, m) = matched_segment_indicators_with(&lx, &[1.0; 5], &dx, &ly, &[1.0; 5], &dy).unwrap();
        assert_eq!(f.names, vec!["segment:1", "segment:2", "segment:3"]);
        assert_eq!(g.names, vec!["segment:3", "segment:1", "segment:2"]);
        assert_eq!(m.iter().map(|r| (r.x, r.y)).collect::<Vec<_>>(), vec![(0, 2), (1, 0), (2, 1)]);
        assert_eq!(g.values.col_as_slice(0), &[1.0, 1.0, 0.0, 0.0, 0.0]);
        assert_eq!(f.values.col_as_slice(2), &[0.0, 0.0, 0.0, 0.0, 1.0]);
        assert!(matched_segment_indicators_with(&lx[1..], &[1.0; 5], &dx, &ly, &[1.0; 5], &dy).is_err());
    }
}
