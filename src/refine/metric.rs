//! Metric polish of a point map X → Y: geodesic trilateration to anchors, combined with a
//! spectral reading.
//!
//! A spectral reading of a functional map places every vertex by the low frequencies of the
//! shapes: near the truth it can leave whole regions slid by one to three edges, or laid on a
//! nearby sheet of Y (a slanted functional map of a part; near-isometries of cylinder-like
//! limbs). Distances to many points spread over the shape allow no such slide. With anchors
//! a_1 … a_A (farthest-point samples of X) and their current images π(a_j), the metric residual
//! of sending x to y is
//!
//!   E_m(x, y) = mean over the kept j of (s d_X(x, a_j) − d_Y(y, π(a_j)))² / (s d_X(x, a_j) + d_Y(y, π(a_j)) + h),
//!
//! s the scale of X's distances in Y's units (the median of d_Y(π(x), π(a_j)) / d_X(x, a_j) over
//! the current map, on the pairs beyond the median distance: no unit is assumed), h Y's mean
//! edge length, and "kept" the `keep` fraction of smallest terms (trimmed: a geodesic of a part
//! that runs around its cut, or an anchor whose image is wrong, is dropped, not averaged in).
//! The denominator makes the residual relative (a near isometry changes distances in proportion
//! to their length) without letting the nearest anchors, whose distances are mostly
//! discretization, dominate. x's own term (x an anchor, d_X = 0) is left out, so anchors move
//! with the rest.
//!
//! Each round moves every x to the candidate y of least cost, the candidates being the vertices
//! within `rings` edges of π(x) and those whose distance to the image of x's nearest anchor is
//! x's distance to it (s d_X) within ± `width` h: the annulus reaches a sheet that is near in
//! space but far along Y. Rounds first use E_m alone until no vertex moves (at most
//! `metric_rounds`; the annulus is searched in these rounds only);
//! then, when a spectral reading
//! is given (rows q_x of X's embedding and r_y of Y's: the point map is the nearest r_y to each
//! q_x), add E_s(x, y) = ‖q_x − r_y‖², each term divided by its own floor: σ_m the median of E_m
//! over X at the end of that phase (the metric's best fit), σ_s the median of E_s at the input map
//! (the spectral reading's best fit). Where the shapes agree exactly (a part cut from the same
//! mesh) σ_m is zero to round-off and the distances decide; on real pairs both count as much as
//! their own residuals allow. These rounds too stop when no vertex moves (at most `rounds`).
//!
//! This is the trilateration of the basin search (`crate::matching::search`) carried to every
//! vertex; the distances are any [`Distances`] (the partial path uses mesh-edge Dijkstra, whose
//! bias is the same on both shapes where their meshes agree; heat-method distances were no
//! better on faust_r_partial and cost four times more, EXPERIMENTS.md). Cost per round: A
//! distance fields on Y (A on X once), O(A (n + m) log m), and n · (candidates) · A terms;
//! memory (n + m) · A distances.

use faer::MatRef;
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::geodesic::{Distances, GraphGeodesics};

/// Options of [`metric_polish`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricPolishOptions {
    /// Most rounds of the first phase (the metric alone; at least 1); each round computes the
    /// anchors' distance fields on Y again.
    pub metric_rounds: usize,
    /// Most rounds of the second phase (combined with the spectral reading, when given; the
    /// whole polish when not). 0: the map is returned unchanged.
    pub rounds: usize,
    /// Candidates within this many edges of the current image (≥ 1).
    pub rings: usize,
    /// Candidates in the annulus around the image of x's nearest anchor, of half-width `width`
    /// mean edge lengths of Y (0: none).
    pub width: f64,
    /// Fraction of the smallest metric terms kept per candidate, in (0, 1].
    pub keep: f64,
}

impl Default for MetricPolishOptions {
    /// 2 rounds of the metric alone and 6 combined, 2 rings, an annulus of ± 2 edges, ¾ of the
    /// terms kept (on the cut copy of `tests/partial.rs` the metric alone puts 2/3 of the
    /// vertices right in its first round and nearly all in its second; one ring, or no annulus,
    /// left 5–10 % of the vertices on a nearby sheet; a bumpy sphere slid everywhere by one edge
    /// needs two; EXPERIMENTS.md).
    fn default() -> Self {
        MetricPolishOptions { metric_rounds: 2, rounds: 6, rings: 2, width: 2.0, keep: 0.75 }
    }
}

/// What [`metric_polish`] did (reported in `report.json` by the partial path).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MetricPolished {
    /// The polished map (length n, vertices of Y).
    #[serde(skip)]
    pub map_xy: Vec<usize>,
    /// The scale s of X's distances in Y's units, per round.
    pub scales: Vec<f64>,
    /// How many vertices moved, per round.
    pub moved: Vec<usize>,
    /// How many of the rounds used the metric alone (the first phase).
    pub metric_rounds: usize,
    /// (σ_m, σ_s): the floors the two terms were divided by (None without a spectral reading).
    pub floors: Option<(f64, f64)>,
}

/// Polishes `map_xy` (length n, vertices of Y) by geodesic trilateration to `anchors` (vertices
/// of X, at least 3), with the distances `dist_x` on X (n vertices) and `dist_y` on Y (m
/// vertices), the candidates found along the edges of `gy` (Y's graph, m vertices), combined
/// with the spectral reading `spectral` = (Q n × k, R m × k) when given (module docs).
///
/// Errors: sizes that do not match, a vertex out of range, fewer than 3 anchors, `keep` outside
/// (0, 1], `rings` = 0, a negative or non-finite `width`, non-finite spectral rows, distances
/// with no finite positive pair.
pub fn metric_polish(
    dist_x: &dyn Distances,
    dist_y: &dyn Distances,
    gy: &GraphGeodesics,
    anchors: &[usize],
    map_xy: &[usize],
    o: &MetricPolishOptions,
    spectral: Option<(MatRef<f64>, MatRef<f64>)>,
) -> Result<MetricPolished> {
    let (n, m, a) = (dist_x.n_vertices(), gy.n(), anchors.len());
    check(dist_y.n_vertices(), n, m, anchors, map_xy, o, spectral)?;
    let mut report = MetricPolished {
        map_xy: map_xy.to_vec(),
        scales: Vec::new(),
        moved: Vec::new(),
        metric_rounds: 0,
        floors: None,
    };
    if o.rounds == 0 {
        return Ok(report);
    }
    let dx = row_major(dist_x.distances_from(anchors)?.as_ref());
    let h = mean_edge(gy);
    let kept = ((o.keep * (a - 1) as f64).ceil() as usize).clamp(1, a - 1);
    let spectral_residual = |x: usize, y: usize| -> f64 {
        spectral.map_or(0.0, |(q, r)| (0..q.ncols()).map(|k| (q[(x, k)] - r[(y, k)]).powi(2)).sum())
    };
    let sigma_s = match spectral {
        Some(_) => median((0..n).into_par_iter().map(|x| spectral_residual(x, map_xy[x])).collect()),
        None => 0.0,
    };
    let mut map = std::mem::take(&mut report.map_xy);
    // Rounds of the current phase (metric alone, then combined), and whether the metric's floor
    // is to be measured at the start of the next round (the metric phase is over).
    let (mut phase, mut floors_due) = (0, false);
    // d_Y(y, π(a_j)), m × A row-major, and the image each column was computed for.
    let (mut dy, mut images) = (vec![0.0; m * a], vec![None; a]);
    loop {
        crate::progress::check()?;
        // The anchors' distance fields on Y, computed again only for the images that moved.
        let moved: Vec<usize> = (0..a).filter(|&j| images[j] != Some(map[anchors[j]])).collect();
        if !moved.is_empty() {
            let sources: Vec<usize> = moved.iter().map(|&j| map[anchors[j]]).collect();
            let fresh = dist_y.distances_from(&sources)?;
            for (c, &j) in moved.iter().enumerate() {
                for (y, &d) in fresh.col(c).iter().enumerate() {
                    dy[y * a + j] = d;
                }
                images[j] = Some(map[anchors[j]]);
            }
        }
        let s = scale(&dx, &dy, &map, a).ok_or_else(|| {
            Error::numerical("metric polish", "no vertex and anchor at a finite, positive distance on both shapes")
        })?;
        let metric = |x: usize, y: usize, terms: &mut Vec<f64>| {
            trimmed_residual(&dx[x * a..(x + 1) * a], &dy[y * a..(y + 1) * a], s, h, kept, terms)
        };
        if floors_due {
            let sigma_m = median((0..n).into_par_iter().map_init(Vec::new, |t, x| metric(x, map[x], t)).collect());
            report.floors = Some((sigma_m, sigma_s));
            floors_due = false;
        }
        // The weights of the two terms (module docs): the metric alone in the first phase.
        let (wm, ws) = match report.floors {
            Some((sm, ss)) => (1.0 / sm.max(f64::MIN_POSITIVE), 1.0 / ss.max(f64::MIN_POSITIVE)),
            None => (1.0, 0.0),
        };
        // The annulus in the metric phase only: the combined phase starts from the metric's fit.
        let by_distance = annulus_lists(&dy, m, a, if ws > 0.0 { 0.0 } else { o.width });
        let next: Vec<usize> = (0..n)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(candidates, terms): &mut (Vec<usize>, Vec<f64>), x| {
                    let row = &dx[x * a..(x + 1) * a];
                    rings_around(gy, map[x], o.rings, candidates);
                    if let Some(lists) = &by_distance {
                        annulus(row, s, o.width * h, lists, candidates);
                    }
                    let mut best = (f64::INFINITY, map[x]);
                    for &y in candidates.iter() {
                        let mut e = wm * metric(x, y, terms);
                        if ws > 0.0 {
                            e += ws * spectral_residual(x, y);
                        }
                        if e < best.0 {
                            best = (e, y);
                        }
                    }
                    best.1
                },
            )
            .collect();
        let count = next.iter().zip(&map).filter(|(p, q)| p != q).count();
        report.scales.push(s);
        report.moved.push(count);
        if report.floors.is_none() {
            report.metric_rounds += 1;
        }
        map = next;
        phase += 1;
        let cap = if spectral.is_some() && report.floors.is_none() { o.metric_rounds } else { o.rounds };
        if count == 0 || phase >= cap {
            if spectral.is_none() || report.floors.is_some() {
                break;
            }
            (phase, floors_due) = (0, true);
        }
    }
    report.map_xy = map;
    Ok(report)
}

/// The checks of [`metric_polish`]'s arguments (`my`: the vertices of Y's distances).
fn check(
    my: usize,
    n: usize,
    m: usize,
    anchors: &[usize],
    map_xy: &[usize],
    o: &MetricPolishOptions,
    spectral: Option<(MatRef<f64>, MatRef<f64>)>,
) -> Result<()> {
    if my != m {
        return Err(Error::invalid("metric polish", format!("Y's distances have {my} vertices, its graph {m}")));
    }
    if map_xy.len() != n {
        return Err(Error::invalid("map", format!("{} images for the {n} vertices of X", map_xy.len())));
    }
    if let Some(&bad) = map_xy.iter().find(|&&v| v >= m) {
        return Err(Error::invalid("map", format!("vertex {bad} of Y does not exist (m = {m})")));
    }
    if anchors.len() < 3 {
        return Err(Error::invalid("metric polish anchors", format!("need at least 3, got {}", anchors.len())));
    }
    if let Some(&bad) = anchors.iter().find(|&&v| v >= n) {
        return Err(Error::invalid("metric polish anchors", format!("vertex {bad} of X does not exist (n = {n})")));
    }
    if !(o.keep > 0.0 && o.keep <= 1.0) {
        return Err(Error::invalid("metric polish keep", format!("must be in (0, 1], got {}", o.keep)));
    }
    if o.rings == 0 {
        return Err(Error::invalid("metric polish rings", "must be at least 1"));
    }
    if o.metric_rounds == 0 {
        return Err(Error::invalid("metric polish metric_rounds", "must be at least 1"));
    }
    if !(o.width.is_finite() && o.width >= 0.0) {
        return Err(Error::invalid("metric polish width", format!("must be finite and ≥ 0, got {}", o.width)));
    }
    if let Some((q, r)) = spectral {
        if q.nrows() != n || r.nrows() != m || q.ncols() != r.ncols() {
            return Err(Error::invalid(
                "metric polish spectral reading",
                format!("rows {} × {} and {} × {} for n = {n}, m = {m}", q.nrows(), q.ncols(), r.nrows(), r.ncols()),
            ));
        }
        let finite = |x: MatRef<f64>| (0..x.ncols()).all(|j| x.col(j).iter().all(|v| v.is_finite()));
        if !(finite(q) && finite(r)) {
            return Err(Error::invalid("metric polish spectral reading", "holds NaN or infinite values"));
        }
    }
    Ok(())
}

/// The trimmed relative residual E_m of one candidate (module docs): `dx` are x's distances to
/// the anchors (X's units), `dy` the candidate's to their images, `s` the scale, `h` the floor
/// of the denominator, `kept` the number of smallest terms averaged; terms with d_X = 0 (x is
/// the anchor) or an unreachable side are left out (∞ when none is left). `terms` is scratch.
fn trimmed_residual(dx: &[f64], dy: &[f64], s: f64, h: f64, kept: usize, terms: &mut Vec<f64>) -> f64 {
    terms.clear();
    terms.extend(dx.iter().zip(dy).filter(|(p, q)| **p > 0.0 && p.is_finite() && q.is_finite()).map(|(p, q)| {
        let sp = s * p;
        (sp - q).powi(2) / (sp + q + h)
    }));
    if terms.is_empty() {
        return f64::INFINITY;
    }
    let k = kept.min(terms.len());
    if k < terms.len() {
        terms.select_nth_unstable_by(k - 1, f64::total_cmp);
    }
    terms[..k].iter().sum::<f64>() / k as f64
}

/// The median of d_Y(π(x), π(a_j)) / d_X(x, a_j) over every vertex x and anchor j whose
/// distances are finite, with d_X at least the median of the positive d_X (short distances are
/// mostly discretization). `dx` n × A and `dy` m × A, row-major. None without such a pair.
fn scale(dx: &[f64], dy: &[f64], map: &[usize], a: usize) -> Option<f64> {
    let lengths: Vec<f64> = dx.iter().copied().filter(|d| d.is_finite() && *d > 0.0).collect();
    if lengths.is_empty() {
        return None;
    }
    let floor = median(lengths);
    let ratios: Vec<f64> = map
        .iter()
        .enumerate()
        .flat_map(|(x, &y)| {
            dx[x * a..(x + 1) * a]
                .iter()
                .zip(&dy[y * a..(y + 1) * a])
                .filter(move |(p, q)| **p >= floor && p.is_finite() && q.is_finite() && **q > 0.0)
                .map(|(p, q)| q / p)
        })
        .collect();
    (!ratios.is_empty()).then(|| median(ratios))
}

/// The median (upper) of a non-empty vector; 0 for an empty one.
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, f64::total_cmp).1
}

/// For every anchor, Y's vertices by increasing distance to its image (None when `width` is 0).
/// `dy` m × A row-major.
fn annulus_lists(dy: &[f64], m: usize, a: usize, width: f64) -> Option<Vec<Vec<(f64, u32)>>> {
    (width > 0.0).then(|| {
        (0..a)
            .into_par_iter()
            .map(|j| {
                let mut v: Vec<(f64, u32)> =
                    (0..m).map(|y| (dy[y * a + j], y as u32)).filter(|(d, _)| d.is_finite()).collect();
                v.sort_unstable_by(|p, q| p.0.total_cmp(&q.0));
                v
            })
            .collect()
    })
}

/// Appends to `out` the vertices of Y whose distance to the image of x's nearest anchor (other
/// than x) is s d_X within ± `half` (`row`: x's distances to the anchors).
fn annulus(row: &[f64], s: f64, half: f64, lists: &[Vec<(f64, u32)>], out: &mut Vec<usize>) {
    let nearest =
        (0..row.len()).filter(|&j| row[j] > 0.0 && row[j].is_finite()).min_by(|&i, &j| row[i].total_cmp(&row[j]));
    let Some(j) = nearest else { return };
    let (lo, hi) = (s * row[j] - half, s * row[j] + half);
    let list = &lists[j];
    let start = list.partition_point(|p| p.0 < lo);
    out.extend(list[start..].iter().take_while(|p| p.0 <= hi).map(|p| p.1 as usize));
}

/// The vertices within `rings` edges of `v` (v first), into `out`.
fn rings_around(g: &GraphGeodesics, v: usize, rings: usize, out: &mut Vec<usize>) {
    out.clear();
    out.push(v);
    let mut start = 0;
    for _ in 0..rings {
        let end = out.len();
        for i in start..end {
            for &(u, _) in g.neighbours(out[i]) {
                let u = u as usize;
                if !out.contains(&u) {
                    out.push(u);
                }
            }
        }
        start = end;
    }
}

/// The mean edge length of a graph (0 without edges).
fn mean_edge(g: &GraphGeodesics) -> f64 {
    let (sum, count) =
        (0..g.n()).flat_map(|v| g.neighbours(v).iter()).fold((0.0, 0usize), |(s, c), &(_, l)| (s + l, c + 1));
    if count == 0 {
        0.0
    } else {
        sum / count as f64
    }
}

/// An n × A matrix as n rows of A, contiguous.
fn row_major(d: MatRef<f64>) -> Vec<f64> {
    let (n, a) = (d.nrows(), d.ncols());
    let mut out = vec![0.0; n * a];
    for j in 0..a {
        for (i, &v) in d.col(j).iter().enumerate() {
            out[i * a + j] = v;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{bumpy_sphere, icosphere};

    /// A bumpy sphere matched to itself from a map with every vertex slid by one edge: back to
    /// the identity, with the distances alone and with a spectral reading that favours the slide.
    #[test]
    fn a_slid_map_on_the_same_mesh_goes_back_to_the_identity() {
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        // The slide: every vertex sent to its neighbour in a fixed direction (about one edge).
        let slid: Vec<usize> =
            (0..n).map(|v| g.neighbours(v).iter().map(|&(u, _)| u as usize).min().unwrap()).collect();
        let anchors = crate::spatial::farthest_point_samples(x.vertices(), &vec![1.0; n], 64).unwrap().vertices;
        let o = MetricPolishOptions::default();
        let r = metric_polish(&g, &g, &g, &anchors, &slid, &o, None).unwrap();
        let exact = r.map_xy.iter().enumerate().filter(|(i, &v)| *i == v).count();
        assert!(exact as f64 >= 0.99 * n as f64, "identity on {exact} of {n}: {r:?}");
        assert!((r.scales[0] - 1.0).abs() < 0.05, "{:?}", r.scales);
        // A spectral reading whose best fit is the slid map (up to a little noise): the metric
        // still decides where the shapes agree exactly (its floor is zero to round-off).
        let h = mean_edge(&g);
        let noise = |i: usize, k: usize| 0.2 * h * (((i * 7 + k * 13) % 11) as f64 / 5.0 - 1.0);
        let q = faer::Mat::from_fn(n, 3, |i, k| x.vertices()[slid[i]][k] + noise(i, k));
        let rr = faer::Mat::from_fn(n, 3, |i, k| x.vertices()[i][k]);
        let r2 = metric_polish(&g, &g, &g, &anchors, &slid, &o, Some((q.as_ref(), rr.as_ref()))).unwrap();
        let exact2 = r2.map_xy.iter().enumerate().filter(|(i, &v)| *i == v).count();
        assert!(exact2 as f64 >= 0.99 * n as f64, "identity on {exact2} of {n}: {:?}", r2.floors);
        let (sm, ss) = r2.floors.unwrap();
        assert!(sm < 1e-12 * ss, "floors {sm:e} {ss:e}");
    }

    /// A right map stays: the identity is a fixed point of both terms.
    #[test]
    fn a_right_map_stays() {
        let x = bumpy_sphere(2);
        let n = x.n_vertices();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        let anchors = crate::spatial::farthest_point_samples(x.vertices(), &vec![1.0; n], 32).unwrap().vertices;
        let id: Vec<usize> = (0..n).collect();
        let p = faer::Mat::from_fn(n, 3, |i, k| x.vertices()[i][k]);
        let r =
            metric_polish(&g, &g, &g, &anchors, &id, &MetricPolishOptions::default(), Some((p.as_ref(), p.as_ref())))
                .unwrap();
        assert_eq!(r.map_xy, id);
        assert_eq!(r.moved[0], 0);
    }

    #[test]
    fn bad_arguments_are_errors_naming_them() {
        let x = icosphere(1);
        let n = x.n_vertices();
        let g = GraphGeodesics::mesh_edges(&x).unwrap();
        let id: Vec<usize> = (0..n).collect();
        let anchors = [0, 5, 9];
        let o = MetricPolishOptions::default();
        let err = |r: Result<MetricPolished>| r.unwrap_err().to_string();
        assert!(err(metric_polish(&g, &g, &g, &anchors, &id[..n - 1], &o, None)).contains("images"));
        let mut bad = id.clone();
        bad[3] = n;
        assert!(err(metric_polish(&g, &g, &g, &anchors, &bad, &o, None)).contains("does not exist"));
        assert!(err(metric_polish(&g, &g, &g, &[0, 1], &id, &o, None)).contains("at least 3"));
        assert!(err(metric_polish(&g, &g, &g, &[0, 1, n], &id, &o, None)).contains("anchors"));
        for (o, what) in [
            (MetricPolishOptions { keep: 0.0, ..o }, "keep"),
            (MetricPolishOptions { keep: f64::NAN, ..o }, "keep"),
            (MetricPolishOptions { rings: 0, ..o }, "rings"),
            (MetricPolishOptions { metric_rounds: 0, ..o }, "metric_rounds"),
            (MetricPolishOptions { width: -1.0, ..o }, "width"),
            (MetricPolishOptions { width: f64::INFINITY, ..o }, "width"),
        ] {
            assert!(err(metric_polish(&g, &g, &g, &anchors, &id, &o, None)).contains(what), "{what}");
        }
        let q = faer::Mat::<f64>::zeros(n, 2);
        let r = faer::Mat::<f64>::zeros(n, 3);
        assert!(err(metric_polish(&g, &g, &g, &anchors, &id, &o, Some((q.as_ref(), r.as_ref())))).contains("spectral"));
        let mut q = faer::Mat::<f64>::zeros(n, 3);
        q[(2, 1)] = f64::NAN;
        assert!(err(metric_polish(&g, &g, &g, &anchors, &id, &o, Some((q.as_ref(), r.as_ref())))).contains("NaN"));
    }
}
