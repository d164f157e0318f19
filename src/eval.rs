//! Correspondence quality the way the field measures it (paper §4.1, Princeton benchmark
//! protocol of Kim et al. 2011): geodesic errors on Y normalized by √(area of Y), their mean
//! and their cumulative curve; with or without the intrinsic left–right symmetric flip.

use faer::MatRef;

use crate::error::{Error, Result};
pub use crate::geodesic::Distances;

/// Ground-truth correspondences of template points: `x[i]` on X corresponds to `y[i]` on Y, and,
/// when given, to `y_sym[i]` under the left–right flip (0-based vertex ids, as read from `.vts`
/// files with `one_based = true`).
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruth {
    /// Template points on X.
    pub x: Vec<usize>,
    /// Their counterparts on Y.
    pub y: Vec<usize>,
    /// Their mirrored counterparts on Y (symmetric evaluation), if any.
    pub y_sym: Option<Vec<usize>>,
}

impl GroundTruth {
    /// The ground truth from template lists in which None marks a template point a shape lacks
    /// (0 in a `.vts` file of a part: [`crate::io::indices::read_template_list`]): the template
    /// points present on X and on Y (and on the mirrored list of Y, when given) are kept, the
    /// others left out. Errors: lists of different lengths, no template point left.
    pub fn from_templates(x: &[Option<usize>], y: &[Option<usize>], y_sym: Option<&[Option<usize>]>) -> Result<Self> {
        if x.len() != y.len() || y_sym.is_some_and(|s| s.len() != x.len()) {
            return Err(Error::invalid("ground truth", "the template point lists have different lengths"));
        }
        let keep: Vec<usize> = (0..x.len())
            .filter(|&i| x[i].is_some() && y[i].is_some() && y_sym.is_none_or(|s| s[i].is_some()))
            .collect();
        if keep.is_empty() {
            return Err(Error::invalid("ground truth", "no template point is present on both shapes"));
        }
        let pick = |l: &[Option<usize>]| keep.iter().map(|&i| l[i].unwrap_or(0)).collect::<Vec<usize>>();
        Ok(GroundTruth { x: pick(x), y: pick(y), y_sym: y_sym.map(pick) })
    }

    fn check(&self, n: usize, m: usize) -> Result<()> {
        if self.x.len() != self.y.len()
            || self.y_sym.as_ref().is_some_and(|s| s.len() != self.x.len())
            || self.x.is_empty()
        {
            return Err(Error::invalid("ground truth", "the template point lists are empty or of different lengths"));
        }
        if self.x.iter().any(|&i| i >= n) || self.y.iter().chain(self.y_sym.iter().flatten()).any(|&j| j >= m) {
            return Err(Error::invalid("ground truth", format!("a vertex id is out of range (n = {n}, m = {m})")));
        }
        Ok(())
    }
}

/// Hard error (12) of a point-to-point map X → Y (`map_xy`, length n) at every template point:
/// d_Y(map(x_i), y_i) / √area(Y); with `y_sym`, the smaller of that and d_Y(map(x_i), y_sym_i).
///
/// Distances come from [`Distances::pair_distances`] (pairs (y_i, map(x_i))), the mirrored ones
/// from [`Distances::pair_distances_capped`] capped at the direct distance: with an
/// early-terminating solver ([`crate::geodesic::ExactGeodesics`]) only the neighbourhood of
/// each template point is explored.
pub fn hard_errors(map_xy: &[usize], gt: &GroundTruth, dist: &dyn Distances, area_y: f64) -> Result<Vec<f64>> {
    let m = dist.n_vertices();
    gt.check(map_xy.len(), m)?;
    if map_xy.iter().any(|&j| j >= m) {
        return Err(Error::invalid("map", format!("it points to a vertex ≥ m = {m}")));
    }
    if !(area_y.is_finite() && area_y > 0.0) {
        return Err(Error::invalid("area", format!("area of Y must be positive, got {area_y}")));
    }
    let norm = area_y.sqrt();
    // Distances from the true vertex to the predicted one; the mirrored distance only matters
    // below the direct one, so it is capped there.
    let pairs =
        |truth: &[usize]| -> Vec<(usize, usize)> { truth.iter().zip(&gt.x).map(|(&t, &x)| (t, map_xy[x])).collect() };
    let direct = dist.pair_distances(&pairs(&gt.y))?;
    let best = match &gt.y_sym {
        None => direct,
        Some(s) => {
            let mirrored = dist.pair_distances_capped(&pairs(s), &direct)?;
            direct.iter().zip(mirrored).map(|(a, b)| a.min(b)).collect()
        }
    };
    if let Some(i) = best.iter().position(|d| !d.is_finite()) {
        return Err(Error::invalid(
            "map",
            format!(
                "template point {i}: its true vertex {} and the mapped vertex {} of Y are not connected (infinite \
                 geodesic distance); Y has several connected components — evaluate each component on its own",
                gt.y[i], map_xy[gt.x[i]]
            ),
        ));
    }
    Ok(best.into_iter().map(|d| d / norm).collect())
}

/// Soft error (13) of a functional correspondence: `columns` (m × s) holds t_i = T δ_{x_i} for
/// every template point, and the error of point i is Σ_j d_Y(y_i, y_j) |t_ji| / (√area(Y) Σ_j |t_ji|).
/// With `y_sym`, the smaller of the direct and the mirrored error.
pub fn soft_errors(columns: MatRef<f64>, gt: &GroundTruth, dist: &dyn Distances, area_y: f64) -> Result<Vec<f64>> {
    let m = dist.n_vertices();
    gt.check(usize::MAX, m)?;
    if columns.nrows() != m || columns.ncols() != gt.x.len() {
        return Err(Error::invalid(
            "soft map",
            format!("expected {m} × {} columns, got {} × {}", gt.x.len(), columns.nrows(), columns.ncols()),
        ));
    }
    let norm = area_y.sqrt();
    let errors_to = |targets: &[usize]| -> Result<Vec<f64>> {
        let d = dist.distances_from(targets)?;
        (0..targets.len())
            .map(|i| {
                let mass: f64 = (0..m).map(|j| columns[(j, i)].abs()).sum();
                if mass.is_nan() || mass <= 0.0 || mass.is_infinite() {
                    return Err(Error::invalid("soft map", format!("column {i} is zero or not finite")));
                }
                Ok((0..m).map(|j| d[(j, i)] * columns[(j, i)].abs()).sum::<f64>() / (norm * mass))
            })
            .collect()
    };
    let direct = errors_to(&gt.y)?;
    match &gt.y_sym {
        None => Ok(direct),
        Some(s) => Ok(direct.iter().zip(errors_to(s)?).map(|(a, b)| a.min(b)).collect()),
    }
}

/// The thresholds of the cumulative curve used in the literature: r = 0, 0.005, …, 0.25.
pub fn standard_thresholds() -> Vec<f64> {
    (0..=50).map(|i| i as f64 * 0.005).collect()
}

/// Fraction of errors ≤ r for every threshold r.
pub fn cumulative_curve(errors: &[f64], thresholds: &[f64]) -> Vec<f64> {
    let n = errors.len().max(1) as f64;
    thresholds.iter().map(|r| errors.iter().filter(|e| **e <= *r + 1e-12).count() as f64 / n).collect()
}

/// Mean and the fractions at r = 0.05, 0.10, 0.25 of a set of normalized errors.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Mean error (normalized length; ×100 is the usual table unit).
    pub mean: f64,
    /// Fraction of points with error ≤ 0.05.
    pub at_005: f64,
    /// Fraction of points with error ≤ 0.10.
    pub at_010: f64,
    /// Fraction of points with error ≤ 0.25.
    pub at_025: f64,
}

/// Summary of per-point errors.
pub fn summarize(errors: &[f64]) -> Summary {
    let c = cumulative_curve(errors, &[0.05, 0.10, 0.25]);
    Summary { mean: errors.iter().sum::<f64>() / errors.len().max(1) as f64, at_005: c[0], at_010: c[1], at_025: c[2] }
}

/// The evaluation of one map: the hard errors at the template points, their summary and
/// cumulative curve (what `funcorr eval --json` prints).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Evaluation {
    /// Mean and fractions of `errors`.
    pub summary: Summary,
    /// Whether symmetric flips were allowed (the ground truth had a symmetric target).
    pub symmetric: bool,
    /// How the geodesic distances were computed.
    pub geodesics: String,
    /// The thresholds of `curve` ([`standard_thresholds`]).
    pub thresholds: Vec<f64>,
    /// Fraction of errors ≤ each threshold.
    pub curve: Vec<f64>,
    /// Hard error (12) per template point (normalized by √area(Y)).
    pub errors: Vec<f64>,
}

impl Evaluation {
    /// The hard errors (12) of `map_xy` (length n) against `gt`, with distances `dist` on Y of
    /// area `area_y`, summarized at the [`standard_thresholds`]; `geodesics` describes `dist`.
    /// Errors: those of [`hard_errors`].
    pub fn of_map(
        map_xy: &[usize],
        gt: &GroundTruth,
        dist: &dyn Distances,
        area_y: f64,
        geodesics: impl Into<String>,
    ) -> Result<Self> {
        let errors = hard_errors(map_xy, gt, dist, area_y)?;
        let thresholds = standard_thresholds();
        Ok(Evaluation {
            summary: summarize(&errors),
            symmetric: gt.y_sym.is_some(),
            geodesics: geodesics.into(),
            curve: cumulative_curve(&errors, &thresholds),
            thresholds,
            errors,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::HeatGeodesics;
    use crate::primitives::icosphere;
    use faer::Mat;

    #[test]
    fn an_evaluation_summarizes_the_hard_errors() {
        let mesh = icosphere(1);
        let g = crate::geodesic::GraphGeodesics::mesh_edges(&mesh).unwrap();
        let n = mesh.n_vertices();
        let gt = GroundTruth { x: (0..n).collect(), y: (0..n).collect(), y_sym: None };
        let ev = Evaluation::of_map(&(0..n).collect::<Vec<_>>(), &gt, &g, mesh.total_area(), "edges").unwrap();
        assert_eq!((ev.errors.len(), ev.summary.mean, ev.symmetric, ev.geodesics.as_str()), (n, 0.0, false, "edges"));
        assert!(ev.curve.iter().all(|&c| c == 1.0) && ev.curve.len() == ev.thresholds.len());
        let mut shifted: Vec<usize> = (0..n).collect();
        shifted.rotate_left(1);
        let ev = Evaluation::of_map(&shifted, &gt, &g, mesh.total_area(), "edges").unwrap();
        assert_eq!(ev.summary, summarize(&ev.errors));
        assert!(ev.summary.mean > 0.0 && ev.curve[0] < 1.0);
    }

    #[test]
    fn errors_across_components_are_errors_not_infinities() {
        // Two separate triangles: vertex 0 cannot reach vertex 3.
        let mesh = crate::shape::TriMesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]],
            vec![[0, 1, 2], [3, 4, 5]],
        )
        .unwrap();
        let g = crate::geodesic::GraphGeodesics::mesh_edges(&mesh).unwrap();
        let gt = GroundTruth { x: vec![0, 1], y: vec![0, 1], y_sym: None };
        assert!(hard_errors(&[0, 1, 2, 3, 4, 5], &gt, &g, 1.0).unwrap().iter().all(|e| *e == 0.0));
        let err = hard_errors(&[3, 1, 2, 3, 4, 5], &gt, &g, 1.0).unwrap_err().to_string();
        assert!(err.contains("not connected"), "{err}");
    }

    #[test]
    fn identity_map_has_zero_error_and_a_full_curve() {
        let mesh = icosphere(3);
        let n = mesh.n_vertices();
        let g = HeatGeodesics::new(&mesh).unwrap();
        let template: Vec<usize> = (0..n).step_by(7).collect();
        let gt = GroundTruth { x: template.clone(), y: template.clone(), y_sym: None };
        let identity: Vec<usize> = (0..n).collect();
        let e = hard_errors(&identity, &gt, &g, mesh.total_area()).unwrap();
        assert!(e.iter().all(|&v| v == 0.0));
        assert!(cumulative_curve(&e, &standard_thresholds()).iter().all(|&f| f == 1.0));
        // Soft error of deltas equals the hard error.
        let cols = Mat::from_fn(n, template.len(), |j, i| if j == template[i] { 2.0 } else { 0.0 });
        assert!(soft_errors(cols.as_ref(), &gt, &g, mesh.total_area()).unwrap().iter().all(|&v| v == 0.0));
    }

    #[test]
    fn symmetric_evaluation_accepts_the_mirror_map() {
        // Mirror z → −z on the icosphere: vertex i maps to the vertex nearest to its reflection.
        let mesh = icosphere(3);
        let n = mesh.n_vertices();
        let v = mesh.vertices();
        let mirror: Vec<usize> = (0..n)
            .map(|i| {
                let q = [v[i][0], v[i][1], -v[i][2]];
                (0..n)
                    .min_by(|&a, &b| {
                        let d = |j: usize| (0..3).map(|c| (v[j][c] - q[c]).powi(2)).sum::<f64>();
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap()
            })
            .collect();
        let g = HeatGeodesics::new(&mesh).unwrap();
        let template: Vec<usize> = (0..n).step_by(5).collect();
        let sym: Vec<usize> = template.iter().map(|&i| mirror[i]).collect();
        let area = mesh.total_area();
        let plain = GroundTruth { x: template.clone(), y: template.clone(), y_sym: None };
        let with_sym = GroundTruth { y_sym: Some(sym), ..plain.clone() };
        let e_plain = summarize(&hard_errors(&mirror, &plain, &g, area).unwrap());
        let e_sym = summarize(&hard_errors(&mirror, &with_sym, &g, area).unwrap());
        assert!(e_plain.mean > 0.1, "the mirror map is wrong without symmetry: {}", e_plain.mean);
        assert_eq!(e_sym.mean, 0.0);
        assert_eq!(e_sym.at_005, 1.0);
    }

    #[test]
    fn errors_are_normalized_by_the_square_root_of_the_area() {
        let mesh = icosphere(3);
        let g = HeatGeodesics::new(&mesh).unwrap();
        // Map everything to vertex 0; the error at a point is its distance to vertex 0 / √area.
        let n = mesh.n_vertices();
        let gt = GroundTruth { x: vec![5, 9], y: vec![5, 9], y_sym: None };
        let e = hard_errors(&vec![0; n], &gt, &g, 4.0).unwrap();
        let d = g.distances(&[5, 9]).unwrap();
        assert!((e[0] - d[(0, 0)] / 2.0).abs() < 1e-12 && (e[1] - d[(0, 1)] / 2.0).abs() < 1e-12);
    }

    /// Only the required methods: exercises the default `pair_distances*`.
    struct FullColumns<'a>(&'a crate::geodesic::ExactGeodesics);
    impl Distances for FullColumns<'_> {
        fn n_vertices(&self) -> usize {
            self.0.n()
        }
        fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
            self.0.distances(sources)
        }
    }

    #[test]
    fn early_terminated_pairs_give_the_same_errors_as_full_columns() {
        use crate::geodesic::{ExactGeodesics, GraphGeodesics};
        let mesh = crate::primitives::bumpy_sphere(3);
        let n = mesh.n_vertices();
        let exact = ExactGeodesics::new(&mesh).unwrap();
        let full = FullColumns(&exact);
        // A map that moves every vertex a few edges away, and a "mirror" ground truth.
        let edges = mesh.edges();
        let mut map: Vec<usize> = (0..n).collect();
        for _ in 0..3 {
            for &[a, b] in &edges {
                if (a + 3 * b) % 5 == 0 {
                    map.swap(a as usize, b as usize);
                }
            }
        }
        let template: Vec<usize> = (0..n).step_by(3).collect();
        let sym: Vec<usize> = template.iter().map(|&i| (i * 7 + 11) % n).collect();
        let gt = GroundTruth { x: template.clone(), y: template.clone(), y_sym: Some(sym) };
        let area = mesh.total_area();
        let a = hard_errors(&map, &gt, &exact, area).unwrap();
        let b = hard_errors(&map, &gt, &full, area).unwrap();
        assert!(a.iter().any(|&e| e > 0.0));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-12 * y.max(1e-300), "{x} vs {y}");
        }
        let pairs: Vec<(usize, usize)> = template.iter().map(|&i| (i, map[i])).collect();
        let caps = vec![0.3; pairs.len()];
        let (p, q) =
            (exact.pair_distances_capped(&pairs, &caps).unwrap(), full.pair_distances_capped(&pairs, &caps).unwrap());
        assert!(p.iter().zip(&q).all(|(x, y)| (x - y).abs() <= 1e-12));
        // Dijkstra: its own early termination agrees with its full columns.
        let dij = GraphGeodesics::mesh_edges(&mesh).unwrap();
        let cols = dij.distances(&template).unwrap();
        let got = Distances::pair_distances(&dij, &pairs).unwrap();
        for (i, &(_, t)) in pairs.iter().enumerate() {
            assert_eq!(got[i], cols[(t, i)]);
        }
        assert!(full.pair_distances(&[(0, n)]).is_err());
        assert!(full.pair_distances_capped(&[(0, 1)], &[]).is_err());
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mesh = icosphere(2);
        let g = HeatGeodesics::new(&mesh).unwrap();
        let n = mesh.n_vertices();
        let id: Vec<usize> = (0..n).collect();
        let gt = GroundTruth { x: vec![1, 2], y: vec![1], y_sym: None };
        assert!(hard_errors(&id, &gt, &g, 1.0).is_err());
        let gt = GroundTruth { x: vec![1], y: vec![n], y_sym: None };
        assert!(hard_errors(&id, &gt, &g, 1.0).is_err());
        let gt = GroundTruth { x: vec![1], y: vec![1], y_sym: None };
        assert!(hard_errors(&vec![n; n], &gt, &g, 1.0).is_err());
        assert!(hard_errors(&id, &gt, &g, -1.0).is_err());
        assert!(soft_errors(Mat::<f64>::zeros(n, 1).as_ref(), &gt, &g, 1.0).is_err());
    }
}
