//! Shortest paths on weighted graphs (Dijkstra): mesh edge graphs (a fast upper bound of the
//! geodesic distance on a mesh), kNN graphs of point clouds with Euclidean edge lengths, and
//! any graph given by its edges.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::{PointSet, TriMesh};

/// Graph shortest-path distances (Dijkstra) on a graph with non-negative edge lengths.
///
/// - [`GraphGeodesics::mesh_edges`]: the edge graph of a triangle mesh, lengths = 3D edge
///   lengths. Paths follow edges, so distances overestimate the surface geodesic: on FAUST
///   `tr_reg_001` (5,000 vertices), against [`super::ExactGeodesics`], by 5.2 % on average and
///   up to 29 % (vertices beyond 1 % of √area from the source; see the
///   [module documentation](super)); more on meshes with long thin triangles (up to 2× on
///   TOSCA `cat0`).
/// - [`GraphGeodesics::knn`]: the symmetric K-nearest-neighbour graph of a point set
///   (i ~ j when j is among the K nearest of i or vice versa), lengths = Euclidean distances.
/// - [`GraphGeodesics::point_edges`]: given edges between points (any dimension), lengths =
///   Euclidean distances.
/// - [`GraphGeodesics::from_edges`]: any undirected graph.
///
/// Unreachable vertices (other components) get distance `f64::INFINITY`.
pub struct GraphGeodesics {
    start: Vec<usize>,
    adj: Vec<(u32, f64)>,
}

#[derive(Clone, Copy, PartialEq)]
struct Item(f64, u32);
impl Eq for Item {}
impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

struct Work {
    dist: Vec<f64>,
    touched: Vec<u32>,
    heap: BinaryHeap<Item>,
}

impl GraphGeodesics {
    /// Graph on `n` vertices from undirected edges (i, j, length); duplicate edges are allowed
    /// (the shortest counts), self-loops are ignored.
    ///
    /// Errors: n = 0 or ≥ 2³², an index ≥ n, a length that is negative or not finite.
    pub fn from_edges(n: usize, edges: &[(usize, usize, f64)]) -> Result<Self> {
        if n == 0 || n > u32::MAX as usize {
            return Err(Error::invalid("graph", format!("{n} vertices (need 1 ≤ n < 2³²)")));
        }
        let mut start = vec![0usize; n + 1];
        for (k, &(i, j, l)) in edges.iter().enumerate() {
            if i >= n || j >= n {
                return Err(Error::invalid("edges", format!("edge {k} = ({i}, {j}) is out of range (n = {n})")));
            }
            if !(l.is_finite() && l >= 0.0) {
                return Err(Error::invalid("edges", format!("edge {k} = ({i}, {j}) has length {l}")));
            }
            if i != j {
                start[i + 1] += 1;
                start[j + 1] += 1;
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut adj = vec![(0u32, 0.0); start[n]];
        for &(i, j, l) in edges {
            if i != j {
                adj[fill[i]] = (j as u32, l);
                fill[i] += 1;
                adj[fill[j]] = (i as u32, l);
                fill[j] += 1;
            }
        }
        Ok(GraphGeodesics { start, adj })
    }

    /// The edge graph of `mesh` with Euclidean edge lengths.
    pub fn mesh_edges(mesh: &TriMesh) -> Result<Self> {
        let p = mesh.vertices();
        let edges: Vec<(usize, usize, f64)> = mesh
            .edges()
            .iter()
            .map(|&[a, b]| {
                let (a, b) = (a as usize, b as usize);
                let l =
                    ((p[a][0] - p[b][0]).powi(2) + (p[a][1] - p[b][1]).powi(2) + (p[a][2] - p[b][2]).powi(2)).sqrt();
                (a, b, l)
            })
            .collect();
        Self::from_edges(mesh.n_vertices(), &edges)
    }

    /// The graph `edges` (undirected pairs of indices into `points`, any dimension d) with
    /// Euclidean edge lengths ‖p_i − p_j‖ (in the units of the coordinates), e.g. the mesh edges
    /// or the sparsity pattern of a Laplacian on a point set.
    ///
    /// Errors: no points, an index ≥ n, a non-finite length.
    pub fn point_edges(points: &PointSet, edges: &[[u32; 2]]) -> Result<Self> {
        let n = points.len();
        let mut lengths = Vec::with_capacity(edges.len());
        for (e, &[a, b]) in edges.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            if a >= n || b >= n {
                return Err(Error::invalid("edges", format!("edge {e} = [{a}, {b}] is out of range (n = {n})")));
            }
            let (p, q) = (points.point(a), points.point(b));
            lengths.push((a, b, p.iter().zip(q).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()));
        }
        Self::from_edges(n, &lengths)
    }

    /// The symmetric K-nearest-neighbour graph of `points` (any dimension d; Euclidean edge
    /// lengths; neighbours from [`crate::spatial::knn`], a k-d tree for d = 3).
    ///
    /// Errors: those of [`crate::spatial::knn`] (K = 0 or K ≥ n, too many duplicate points).
    pub fn knn(points: &PointSet, k: usize) -> Result<Self> {
        let nbrs = crate::spatial::knn(points, k)?;
        let edges: Vec<(usize, usize, f64)> =
            nbrs.iter().enumerate().flat_map(|(i, nb)| nb.iter().map(move |&(d2, j)| (i, j, d2.sqrt()))).collect();
        Self::from_edges(points.len(), &edges)
    }

    /// The neighbours of vertex `v` and the lengths of the edges to them. Panics when v ≥ n.
    pub fn neighbours(&self, v: usize) -> &[(u32, f64)] {
        &self.adj[self.start[v]..self.start[v + 1]]
    }

    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.start.len() - 1
    }

    fn check(&self, what: &str, v: usize) -> Result<()> {
        if v >= self.n() {
            return Err(Error::invalid(what, format!("vertex {v} is out of range (n = {})", self.n())));
        }
        Ok(())
    }

    fn work(&self) -> Work {
        Work { dist: vec![f64::INFINITY; self.n()], touched: Vec::new(), heap: BinaryHeap::new() }
    }

    /// Dijkstra from `s`, stopping once every target is settled or known to be ≥ its cap.
    fn solve(&self, work: &mut Work, s: usize, targets: &[(usize, f64)]) {
        for &v in &work.touched {
            work.dist[v as usize] = f64::INFINITY;
        }
        work.touched.clear();
        work.heap.clear();
        work.dist[s] = 0.0;
        work.touched.push(s as u32);
        work.heap.push(Item(0.0, s as u32));
        // Targets before `settled` are settled: min(dist, cap) ≤ d. That stays true (d never
        // decreases, dist never increases), so each target is tested until it settles, not at
        // every step: O(n log n + #targets) rather than O(n · #targets). Stops where all are.
        let mut settled = 0;
        while let Some(Item(d, v)) = work.heap.pop() {
            let v = v as usize;
            if d > work.dist[v] {
                continue;
            }
            if !targets.is_empty() {
                while settled < targets.len() && work.dist[targets[settled].0].min(targets[settled].1) <= d {
                    settled += 1;
                }
                if settled == targets.len() {
                    break;
                }
            }
            for &(u, l) in &self.adj[self.start[v]..self.start[v + 1]] {
                let nd = d + l;
                let du = &mut work.dist[u as usize];
                if nd < *du {
                    if *du == f64::INFINITY {
                        work.touched.push(u);
                    }
                    *du = nd;
                    work.heap.push(Item(nd, u));
                }
            }
        }
    }

    /// Distances from `source` to every vertex (length n).
    pub fn distances_from_vertex(&self, source: usize) -> Result<Vec<f64>> {
        self.check("source", source)?;
        let mut w = self.work();
        self.solve(&mut w, source, &[]);
        Ok(w.dist)
    }

    /// The geodesic Voronoi partition of `sources`: for every vertex its distance to the nearest
    /// source and that source's position in `sources` (both length n; unreachable vertices get
    /// ∞ and `u32::MAX`). One Dijkstra run from all sources at once, O(n log n).
    pub fn nearest_sources(&self, sources: &[usize]) -> Result<(Vec<f64>, Vec<u32>)> {
        for &s in sources {
            self.check("source", s)?;
        }
        let n = self.n();
        let (mut dist, mut label) = (vec![f64::INFINITY; n], vec![u32::MAX; n]);
        let mut heap = BinaryHeap::new();
        for (i, &s) in sources.iter().enumerate() {
            if dist[s] > 0.0 {
                dist[s] = 0.0;
                label[s] = i as u32;
                heap.push(Item(0.0, s as u32));
            }
        }
        while let Some(Item(d, v)) = heap.pop() {
            let v = v as usize;
            if d > dist[v] {
                continue;
            }
            for &(u, l) in &self.adj[self.start[v]..self.start[v + 1]] {
                let nd = d + l;
                if nd < dist[u as usize] {
                    dist[u as usize] = nd;
                    label[u as usize] = label[v];
                    heap.push(Item(nd, u));
                }
            }
        }
        Ok((dist, label))
    }

    /// The graph of the geodesic Voronoi cells of `sources` (node t stands for `sources[t]`,
    /// which must be distinct): cells t and u are joined where an edge (a, b) of this graph runs
    /// from one to the other, by the shortest d(a) + l(a, b) + d(b) over such edges (d the
    /// distance to the cell's source), the length of the path source → a → b → source. Each of
    /// its distances is therefore the length of a path of this graph, never below this graph's
    /// distance between the two sources; it exceeds it by the detours through the sources on
    /// the way, a few cell diameters (on TOSCA david0 subdivided to 840k vertices with 50,000
    /// well-spread cells: 6.6 % on average, 16 % at worst, over 200 farthest-point samples).
    /// One Dijkstra from all sources and one pass over the edges: O(n log n). Errors: a source
    /// out of range or repeated.
    pub fn voronoi_graph(&self, sources: &[usize]) -> Result<GraphGeodesics> {
        let mut seen = vec![false; self.n()];
        for &s in sources {
            self.check("source", s)?;
            if std::mem::replace(&mut seen[s], true) {
                return Err(Error::invalid("sources", format!("vertex {s} is given twice")));
            }
        }
        let (dist, label) = self.nearest_sources(sources)?;
        let mut edges: Vec<(usize, usize, f64)> = (0..self.n())
            .into_par_iter()
            .flat_map_iter(|v| {
                let (dist, label) = (&dist, &label);
                self.adj[self.start[v]..self.start[v + 1]].iter().filter_map(move |&(u, l)| {
                    let (a, b) = (label[v], label[u as usize]);
                    (a < b && b != u32::MAX).then(|| (a as usize, b as usize, dist[v] + l + dist[u as usize]))
                })
            })
            .collect();
        // The shortest crossing of each pair of cells (sorted: the same graph in any order).
        edges.sort_unstable_by(|p, q| (p.0, p.1).cmp(&(q.0, q.1)).then(p.2.total_cmp(&q.2)));
        edges.dedup_by(|later, first| (later.0, later.1) == (first.0, first.1));
        GraphGeodesics::from_edges(sources.len(), &edges)
    }

    /// Distances from each of `sources` to every vertex: n × sources.len(), in parallel.
    pub fn distances(&self, sources: &[usize]) -> Result<faer::Mat<f64>> {
        for &s in sources {
            self.check("source", s)?;
        }
        let cols: Vec<Vec<f64>> = sources
            .par_iter()
            .map_init(
                || self.work(),
                |w, &s| {
                    if crate::progress::cancelled() {
                        return Vec::new(); // discarded: the check below fails
                    }
                    self.solve(w, s, &[]);
                    w.dist.clone()
                },
            )
            .collect();
        crate::progress::check()?;
        Ok(faer::Mat::from_fn(self.n(), sources.len(), |i, j| cols[j][i]))
    }

    /// min(d(s, t), cap) for every pair (s, t) and cap; pairs grouped by source, each group's
    /// Dijkstra stopped early, groups in parallel.
    pub fn pair_distances_capped(&self, pairs: &[(usize, usize)], caps: &[f64]) -> Result<Vec<f64>> {
        if caps.len() != pairs.len() {
            return Err(Error::invalid("caps", format!("{} caps for {} pairs", caps.len(), pairs.len())));
        }
        for &(s, t) in pairs {
            self.check("pair source", s)?;
            self.check("pair target", t)?;
        }
        if let Some(c) = caps.iter().find(|c| c.is_nan()) {
            return Err(Error::invalid("caps", format!("a cap is {c}")));
        }
        let mut order: Vec<usize> = (0..pairs.len()).collect();
        order.sort_by_key(|&i| (pairs[i].0, i));
        let groups: Vec<&[usize]> = order.chunk_by(|&a, &b| pairs[a].0 == pairs[b].0).collect();
        let results: Vec<Vec<(usize, f64)>> = groups
            .par_iter()
            .map_init(
                || (self.work(), Vec::new()),
                |(w, targets), group| {
                    if crate::progress::cancelled() {
                        return Vec::new(); // discarded: the check below fails
                    }
                    targets.clear();
                    targets.extend(group.iter().map(|&i| (pairs[i].1, caps[i])));
                    self.solve(w, pairs[group[0]].0, targets);
                    group.iter().map(|&i| (i, w.dist[pairs[i].1].min(caps[i]))).collect()
                },
            )
            .collect();
        crate::progress::check()?;
        let mut out = vec![0.0; pairs.len()];
        for (i, d) in results.into_iter().flatten() {
            out[i] = d;
        }
        Ok(out)
    }

    /// Distances d(s, t) for every pair (see [`Self::pair_distances_capped`]).
    pub fn pair_distances(&self, pairs: &[(usize, usize)]) -> Result<Vec<f64>> {
        self.pair_distances_capped(pairs, &vec![f64::INFINITY; pairs.len()])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{cycle_edges, icosphere};

    #[test]
    fn nearest_sources_partition_the_graph() {
        let g = GraphGeodesics::from_edges(10, &cycle_edges(10)).unwrap();
        let (d, l) = g.nearest_sources(&[0, 5]).unwrap();
        let all = g.distances(&[0, 5]).unwrap();
        for v in 0..10 {
            assert_eq!(d[v], all[(v, 0)].min(all[(v, 1)]));
            assert_eq!(all[(v, l[v] as usize)], d[v]);
        }
        assert!(g.nearest_sources(&[10]).is_err());
    }

    /// The Voronoi graph's distances are lengths of paths of the fine graph: never below its
    /// distances, and above them by the detours through the sources (on a 2,562-vertex sphere
    /// with 10 % of its vertices as well-spread sources: 7.8 % on average, 31 % at worst, over
    /// pairs farther apart than half the radius). Each cell's source is its own node.
    #[test]
    fn voronoi_graph_distances_bound_the_graph_distances() {
        let mesh = icosphere(4);
        let g = GraphGeodesics::mesh_edges(&mesh).unwrap();
        let sources = crate::spatial::grid_samples(mesh.vertices(), 256);
        let coarse = g.voronoi_graph(&sources).unwrap();
        assert_eq!(coarse.n(), sources.len());
        let fine = g.distances(&sources[..8]).unwrap();
        let (mut worst, mut sum, mut count) = (0.0f64, 0.0, 0);
        for a in 0..8 {
            let d = coarse.distances_from_vertex(a).unwrap();
            for (t, &s) in sources.iter().enumerate() {
                assert!(d[t] >= fine[(s, a)] * (1.0 - 1e-12), "{a} → {t}: {} < {}", d[t], fine[(s, a)]);
                if fine[(s, a)] > 0.5 {
                    let excess = d[t] / fine[(s, a)] - 1.0;
                    (worst, sum, count) = (worst.max(excess), sum + excess, count + 1);
                }
            }
        }
        let mean = sum / count as f64;
        assert!(mean > 0.0 && mean < 0.1 && worst < 0.4, "mean excess {mean}, worst {worst}");
        assert!(g.voronoi_graph(&[0, 3, 0]).is_err());
        assert!(g.voronoi_graph(&[mesh.n_vertices()]).is_err());
    }

    #[test]
    fn cycle_graph_distances() {
        let g = GraphGeodesics::from_edges(10, &cycle_edges(10)).unwrap();
        let d = g.distances_from_vertex(0).unwrap();
        for (i, &di) in d.iter().enumerate() {
            assert_eq!(di, i.min(10 - i) as f64);
        }
        assert_eq!(g.pair_distances(&[(0, 5), (3, 4), (3, 9), (2, 2)]).unwrap(), vec![5.0, 1.0, 4.0, 0.0]);
        assert_eq!(g.pair_distances_capped(&[(0, 5), (3, 4)], &[2.0, 2.0]).unwrap(), vec![2.0, 1.0]);
    }

    /// Early-stopped runs (many targets per source, repeated targets, caps below, at and above
    /// the distances, the source among its targets, a second component) give what a full run
    /// from each source gives: d(s, t).min(cap). On a 642-vertex sphere plus a disconnected
    /// edge, the same work buffers reused across sources (one rayon worker per group).
    #[test]
    fn stopped_runs_equal_full_runs() {
        let mesh = icosphere(3);
        let n = mesh.n_vertices();
        let mut edges: Vec<(usize, usize, f64)> = Vec::new();
        for f in mesh.faces() {
            for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                let (a, b) = (a as usize, b as usize);
                let (p, q) = (mesh.vertices()[a], mesh.vertices()[b]);
                edges.push((a, b, (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt()));
            }
        }
        edges.push((n, n + 1, 1.0));
        let g = GraphGeodesics::from_edges(n + 2, &edges).unwrap();
        let mut pairs = Vec::new();
        let mut caps = Vec::new();
        for s in [0, 7, 100, n] {
            for t in (0..n + 2).step_by(13).chain([s, 5, 5, n + 1]) {
                pairs.push((s, t));
                caps.push(match pairs.len() % 4 {
                    0 => f64::INFINITY,
                    1 => 0.5,
                    2 => 1.0,
                    _ => 2.5,
                });
            }
        }
        let got = g.pair_distances_capped(&pairs, &caps).unwrap();
        for ((&(s, t), &cap), &d) in pairs.iter().zip(&caps).zip(&got) {
            let full = g.distances_from_vertex(s).unwrap()[t].min(cap);
            assert_eq!(d, full, "d({s}, {t}) with cap {cap}");
        }
        assert!(got.iter().any(|d| d.is_infinite()) && got.iter().any(|&d| d > 0.0 && d < 0.5));
    }

    #[test]
    fn disconnected_and_bad_inputs() {
        let g = GraphGeodesics::from_edges(4, &[(0, 1, 1.0), (2, 3, 1.0)]).unwrap();
        assert_eq!(g.distances_from_vertex(0).unwrap(), vec![0.0, 1.0, f64::INFINITY, f64::INFINITY]);
        assert!(g.distances_from_vertex(4).is_err());
        assert!(g.pair_distances(&[(0, 4)]).is_err());
        assert!(g.pair_distances_capped(&[(0, 1)], &[]).is_err());
        assert!(GraphGeodesics::from_edges(2, &[(0, 2, 1.0)]).is_err());
        assert!(GraphGeodesics::from_edges(2, &[(0, 1, -1.0)]).is_err());
        assert!(GraphGeodesics::from_edges(2, &[(0, 1, f64::NAN)]).is_err());
        assert!(GraphGeodesics::from_edges(0, &[]).is_err());
    }

    #[test]
    fn knn_graph_on_a_sampled_circle_approximates_arc_length() {
        // 400 points on the unit circle (in R³): the 2-NN graph is the polygon, whose path
        // lengths are chords summed, just below the arc length.
        let n = 400;
        let coords: Vec<f64> = (0..n)
            .flat_map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                [t.cos(), t.sin(), 0.0]
            })
            .collect();
        let g = GraphGeodesics::knn(&PointSet::new(n, 3, coords).unwrap(), 2).unwrap();
        let d = g.distances_from_vertex(0).unwrap();
        let chord = 2.0 * (std::f64::consts::PI / n as f64).sin();
        for (i, &di) in d.iter().enumerate() {
            assert!((di - i.min(n - i) as f64 * chord).abs() < 1e-12);
        }
        assert!(GraphGeodesics::knn(&PointSet::new(3, 3, vec![0.0; 9]).unwrap(), 5).is_err());
    }

    #[test]
    fn mesh_edge_distances_bound_the_sphere_geodesic_from_above() {
        let mesh = icosphere(3);
        let g = GraphGeodesics::mesh_edges(&mesh).unwrap();
        let d = g.distances_from_vertex(0).unwrap();
        let p0 = mesh.vertices()[0];
        for (i, p) in mesh.vertices().iter().enumerate() {
            let arc = (p0[0] * p[0] + p0[1] * p[1] + p0[2] * p[2]).clamp(-1.0, 1.0).acos();
            let chord = 2.0 * (arc / 2.0).sin();
            assert!(d[i] >= chord - 1e-12);
            assert!(d[i] <= 1.3 * arc + 1e-12, "{i}: {} vs arc {arc}", d[i]);
        }
    }
}
