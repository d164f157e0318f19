//! Spatial queries on points and vertices, shared by the layers above (Laplacians, point-cloud
//! surfaces, graph geodesics, benchmark templates, rendering): exact K nearest neighbours and
//! farthest-point sampling, of candidate vertices ([`farthest_points`]) or of all points with
//! the mass of their Voronoi cells ([`farthest_point_samples`], the samples of ZoomOut in
//! [`crate::refine`]).

use std::num::NonZero;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::shape::{PointSet, TriMesh};

/// The K nearest neighbours of every 3-D point (excluding itself) by a k-d tree (kiddo): for
/// point i, `K` pairs (squared distance, index), ascending, ties by index. The caller checks
/// 1 ≤ K < n.
pub(crate) fn knn3(points: &[[f64; 3]], k: usize) -> Vec<Vec<(f64, usize)>> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(points);
    let want = NonZero::new(k + 1).expect("k + 1 > 0");
    points
        .par_iter()
        .enumerate()
        .map(|(i, q)| {
            let mut nb: Vec<(f64, usize)> = tree
                .nearest_n::<kiddo::SquaredEuclidean>(q, want)
                .into_iter()
                .map(|nn| (nn.distance, nn.item as usize))
                .filter(|&(_, j)| j != i)
                .collect();
            nb.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            nb.truncate(k);
            nb
        })
        .collect()
}

/// For every query point, the index of the nearest of `points` (Euclidean, by a k-d tree:
/// kiddo's exact nearest neighbour). `points` must not be empty (the caller checks).
pub fn nearest3(points: &[[f64; 3]], queries: &[[f64; 3]]) -> Vec<usize> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(points);
    let one = NonZero::new(1).expect("1 > 0");
    queries.iter().map(|q| tree.nearest_n::<kiddo::SquaredEuclidean>(q, one)[0].item as usize).collect()
}

/// The K nearest neighbours of every point (excluding itself): for point i, `K` pairs
/// (squared distance, index), ascending. Exact.
///
/// d = 3 uses a k-d tree (kiddo); other dimensions use a parallel brute-force scan (kiddo's
/// dimension is a compile-time constant, and k-d trees lose their edge in high dimension).
pub fn knn(points: &PointSet, k: usize) -> Result<Vec<Vec<(f64, usize)>>> {
    let n = points.len();
    if k == 0 || k >= n {
        return Err(Error::invalid("knn", format!("K = {k} neighbours needs 1 ≤ K < n = {n}")));
    }
    let result: Vec<Vec<(f64, usize)>> = if points.dim() == 3 {
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let p = points.point(i);
                [p[0], p[1], p[2]]
            })
            .collect();
        knn3(&pts, k)
    } else {
        (0..n)
            .into_par_iter()
            .map(|i| {
                let p = points.point(i);
                let mut all: Vec<(f64, usize)> = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| (p.iter().zip(points.point(j)).map(|(a, b)| (a - b) * (a - b)).sum(), j))
                    .collect();
                let cmp = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                all.select_nth_unstable_by(k - 1, cmp);
                all.truncate(k);
                all.sort_by(cmp);
                all
            })
            .collect()
    };
    // With many coincident points a k-d tree query may return fewer than K others.
    if let Some(i) = result.iter().position(|nb| nb.len() < k) {
        return Err(Error::invalid("knn", format!("point {i} has fewer than K = {k} distinct neighbours")));
    }
    Ok(result)
}

/// Farthest-point sampling of `count` of the `candidates` (vertex ids of `mesh`) by Euclidean
/// distance, starting from the first candidate; returns positions into `candidates`.
/// Deterministic; fewer than `count` when there are fewer distinct candidates.
pub fn farthest_points(mesh: &TriMesh, candidates: &[usize], count: usize) -> Vec<usize> {
    let v = mesh.vertices();
    let d2 = |a: usize, b: usize| (0..3).map(|c| (v[a][c] - v[b][c]).powi(2)).sum::<f64>();
    let mut chosen = Vec::with_capacity(count);
    if candidates.is_empty() || count == 0 {
        return chosen;
    }
    let mut best = vec![f64::INFINITY; candidates.len()];
    let mut next = 0;
    while chosen.len() < count {
        chosen.push(next);
        let c = candidates[next];
        for (b, &p) in best.iter_mut().zip(candidates) {
            *b = b.min(d2(p, c));
        }
        let (i, far) = best.iter().enumerate().fold((0, -1.0), |acc, (i, &d)| if d > acc.1 { (i, d) } else { acc });
        if far <= 0.0 {
            break;
        }
        next = i;
    }
    chosen
}

/// A weighted subset of the vertices of a shape.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    /// Vertex ids (distinct).
    pub vertices: Vec<usize>,
    /// Weight of every sample (> 0): the vertex weight it stands for (units²).
    pub weights: Vec<f64>,
}

impl Samples {
    /// Every vertex, weighted by its mass (length n).
    pub fn all(mass: &[f64]) -> Samples {
        Samples { vertices: (0..mass.len()).collect(), weights: mass.to_vec() }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }
}

/// `count` farthest-point samples of the points (n × 3, Euclidean, deterministic: the first
/// sample is the point farthest from the centroid), each weighted by the total mass of the
/// points nearest to it (its Voronoi cell; `mass` has length n, e.g. the vertex areas A_X).
/// All points when count ≥ n.
///
/// Errors: no points, `mass.len()` ≠ n, `count` = 0.
pub fn farthest_point_samples(points: &[[f64; 3]], mass: &[f64], count: usize) -> Result<Samples> {
    let n = points.len();
    if mass.len() != n || n == 0 {
        return Err(Error::invalid("samples", format!("{n} points and {} weights", mass.len())));
    }
    if count == 0 {
        return Err(Error::invalid("samples", "need at least one sample"));
    }
    if count >= n {
        return Ok(Samples::all(mass));
    }
    let d2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
    let mut centroid = [0.0; 3];
    for p in points {
        for c in 0..3 {
            centroid[c] += p[c] / n as f64;
        }
    }
    let mut next =
        (0..n).max_by(|&a, &b| d2(&points[a], &centroid).total_cmp(&d2(&points[b], &centroid))).expect("n > 0");
    let mut best = vec![f64::INFINITY; n];
    let mut owner = vec![0usize; n];
    let mut chosen = Vec::with_capacity(count);
    while chosen.len() < count {
        let s = chosen.len();
        chosen.push(next);
        let c = points[next];
        let mut far = (0usize, -1.0f64);
        for (i, p) in points.iter().enumerate() {
            let d = d2(p, &c);
            if d < best[i] {
                best[i] = d;
                owner[i] = s;
            }
            if best[i] > far.1 {
                far = (i, best[i]);
            }
        }
        if far.1 <= 0.0 {
            break;
        }
        next = far.0;
    }
    let mut weights = vec![0.0; chosen.len()];
    for i in 0..n {
        weights[owner[i]] += mass[i];
    }
    Ok(Samples { vertices: chosen, weights })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_points_spread_out() {
        let mesh = crate::primitives::icosphere(2);
        let all: Vec<usize> = (0..mesh.n_vertices()).collect();
        let p = farthest_points(&mesh, &all, 2);
        // The second point is antipodal to the first on the unit sphere.
        let (a, b) = (mesh.vertices()[p[0]], mesh.vertices()[p[1]]);
        let d: f64 = (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt();
        assert!((d - 2.0).abs() < 1e-9, "{d}");
        // Duplicated candidates: never more distinct points than exist.
        assert_eq!(farthest_points(&mesh, &[3, 3, 3], 5), vec![0]);
        assert!(farthest_points(&mesh, &[], 5).is_empty());
    }

    #[test]
    fn voronoi_samples_carry_the_whole_mass() {
        let mesh = crate::primitives::icosphere(2);
        let mass: Vec<f64> = (0..mesh.n_vertices()).map(|i| 1.0 + (i % 3) as f64).collect();
        let s = farthest_point_samples(mesh.vertices(), &mass, 10).unwrap();
        assert_eq!(s.len(), 10);
        assert!(s.weights.iter().all(|&w| w > 0.0));
        assert!((s.weights.iter().sum::<f64>() - mass.iter().sum::<f64>()).abs() < 1e-9);
        assert_eq!(farthest_point_samples(mesh.vertices(), &mass, 10_000).unwrap(), Samples::all(&mass));
        assert!(farthest_point_samples(mesh.vertices(), &mass[1..], 10).is_err());
    }
}
