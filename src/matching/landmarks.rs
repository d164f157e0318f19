//! Known corresponding points ("landmarks") in the default pipeline, for the pairs no intrinsic
//! method can decide: non-isometric shapes (a gorilla and a human) and strongly symmetric ones.
//! A few pairs (a_l on X, b_l on Y), l = 1 … L, given by the user, act in every stage a wrong
//! basin can come from:
//!
//! 1. **Data.** For every landmark, `widths.len()` landmark-centred functions on each shape,
//!    exp(−d(a_l, ·)² / 2σ²) on X and exp(−d(b_l, ·)² / 2σ²) on Y for every width σ, with d the
//!    shortest-path distance along the edges of the surface scaled to unit area
//!    ([`GraphGeodesics`]): the classical landmark descriptors of the functional-map literature,
//!    as geodesic rather than heat-kernel bumps so that they keep their place on non-isometric
//!    shapes whose spectra differ. Normalized as the other data, then scaled so that their total
//!    squared norm is `weight` times that of the other data columns: with the default 1 the
//!    landmarks weigh as much in the fits' descriptor terms as all the other data together.
//! 2. **Candidates.** Every candidate's probe map is read at the landmarks of X, and its
//!    *landmark error* (the mean geodesic distance on Y, unit area, between π(a_l) and b_l) enters
//!    the score that chooses among them, counted in units of `tolerance` against the median-scaled
//!    distortion and data misfit (a candidate that does not respect the landmarks is wrong). With
//!    the basin search, one more candidate is made from the landmarks alone: every search sample
//!    of X placed at the anchor of Y whose distances to the b_l best agree with its distances to
//!    the a_l (an L1 trilateration, `LandmarkData::trilateration_costs`), corrected by the
//!    search's rounds with that cost as their data term ([`super::search::correct`]).
//! 3. **Refinement.** The landmarks are samples of every ZoomOut (probes and final) and of the
//!    polish, with `pin_weight` times the mean sample weight, and pinned there: a_l is matched to
//!    b_l in every point-map step ([`crate::refine::zoomout_pinned`],
//!    [`crate::refine::bijective_polish_pinned`]), and in the final maps X → Y and Y → X. On
//!    shapes that are not isometric the final ZoomOut, fitted to ever finer eigenfunctions that
//!    no longer correspond, can drift from the landmarks' frame; so the functional map it starts
//!    from (the chosen candidate's probe result) and the one it ends with are compared by how
//!    well their maps of 500 samples of X repeat the distances to the landmarks
//!    (`LandmarkData::distance_residual`, which sees the whole map, not only the pins): the
//!    start is polished instead of the end when it is better by 10 % or more (up to
//!    `near.above_pairs` vertex pairs, where the maps are searched exactly). On
//!    tosca_nonisometric_r with 5 landmarks, seeds 0–2: 7.05 / 11.80 / 8.83 → 7.05 / 7.50 / 8.83;
//!    3 landmarks 12.06 / 11.60 / 11.17 → 7.57 / 7.49 / 9.57; 10 unchanged; faust_r unchanged
//!    (EXPERIMENTS.md, "The landmarks judge the final ZoomOut").
//!
//! On a part X of Y the partial path ([`super::partial`], "Landmarks") uses item 2 (the
//! landmarks' candidate and their error in the choice, which is then final) and pins them in
//! its final map; not the data of item 1 nor the pins inside its refinements.
//!
//! **Checked, not corrected** ([`LandmarkCheck`]): every run says how well the landmarks agree
//! with each other (their geodesic distances to one another on X against those on Y) and names
//! the ones that disagree; they are still used as given — the user knows the shapes, and a
//! non-isometric pair disagrees everywhere a little.
//!
//! Without landmarks (`pairs` empty) none of this runs and the pipeline is unchanged, bit for bit.

use faer::Mat;
use serde::{Deserialize, Serialize};

use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::geodesic::GraphGeodesics;
use crate::prepared::PreparedShape;
use crate::spatial::Samples;

use super::search::{mean_abs_difference, SampleDistances};

/// The user's landmarks and how strongly they act ([module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Landmarks {
    /// Known pairs (vertex of X, vertex of Y), 0-based (empty: no landmarks).
    pub pairs: Vec<(usize, usize)>,
    /// Total squared norm of the landmark functions relative to that of the other data columns
    /// (each column of unit norm before this scaling; 0: no landmark functions in the data).
    pub weight: f64,
    /// Widths σ of the geodesic bumps around every landmark, on the shapes scaled to unit area.
    pub widths: Vec<f64>,
    /// Weight of a landmark sample in ZoomOut and the polish, in units of the mean sample weight.
    pub pin_weight: f64,
    /// Landmark error (mean geodesic distance on Y at unit area) that costs as much in the
    /// candidates' score as the median distortion.
    pub tolerance: f64,
}

impl Default for Landmarks {
    fn default() -> Self {
        Landmarks { pairs: Vec::new(), weight: 1.0, widths: vec![0.1, 0.2, 0.4], pin_weight: 1.0, tolerance: 0.05 }
    }
}

impl Landmarks {
    /// Whether landmarks are given.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Checks the pairs against shapes of `n` and `m` vertices and the weights: errors name
    /// `landmarks` and the offending pair. A vertex of X given twice is an error (it cannot have
    /// two images).
    pub fn check(&self, n: usize, m: usize) -> Result<()> {
        for (t, &(i, j)) in self.pairs.iter().enumerate() {
            if i >= n || j >= m {
                return Err(Error::invalid(
                    "landmarks",
                    format!("pair {} ({i}, {j}) is out of range: X has {n} vertices, Y has {m}", t + 1),
                ));
            }
            if let Some(u) = self.pairs[..t].iter().position(|&(a, _)| a == i) {
                return Err(Error::invalid(
                    "landmarks",
                    format!("vertex {i} of X is given twice (pairs {} and {})", u + 1, t + 1),
                ));
            }
        }
        for (name, v) in [
            ("landmark weight", self.weight),
            ("landmark pin weight", self.pin_weight),
            ("landmark tolerance", self.tolerance),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(name, format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if self.tolerance == 0.0 {
            return Err(Error::invalid("landmark tolerance", "must be > 0"));
        }
        if self.widths.is_empty() || self.widths.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(Error::invalid(
                "landmark widths",
                format!("need one or more finite widths > 0, got {:?}", self.widths),
            ));
        }
        Ok(())
    }
}

/// A landmark is a suspect ([`LandmarkCheck`]) when its discrepancy is at least this (its
/// geodesic distances to the other landmarks differ between X and Y by 20 % or more, median)…
pub const SUSPECT_DISCREPANCY: f64 = 0.2;

/// … and, with four landmarks or more, at least this many times the median discrepancy of all
/// landmarks (so that shapes that are not isometric, whose landmarks all disagree somewhat, do
/// not make every landmark a suspect).
pub const SUSPECT_FACTOR: f64 = 2.0;

/// Whether the landmarks agree with each other: a landmark given at the wrong place (a slip of
/// the mouse, the left hand for the right one, a point on the other sheet where a body touches
/// itself) does not repeat on Y its geodesic distances to the others on X. The pipeline trusts
/// the landmarks as given; this only says which ones to check (`report.json`'s
/// `landmark_check`, a warning of `funcorr match` and of Python's `funcorr.match`).
///
/// Measured (EXPERIMENTS.md, "Checking the landmarks against each other"): five ground-truth
/// landmarks on every faust_r pair, one of them then moved to a random template point more than
/// 0.3 √area away — no clean set flagged, the moved landmark found on 82 of 97 pairs, no other
/// landmark flagged; tosca_r (109 pairs, thresholds not chosen there): 4 clean sets flagged (two
/// cats, two dogs), the moved one found on 90; three landmarks (the moved one cannot be told
/// from those it disagrees with): faust_r 2 clean sets / 90 moved found, tosca_r 10 / 99. On
/// faust_r_partial with five, the six pairs whose landmark lies on the other sheet of a
/// self-contact and no other.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LandmarkCheck {
    /// For every landmark l (in the order of the pairs): the median over the other landmarks k
    /// of |d_X(a_l, a_k) − d_Y(b_l, b_k)| / ((d_X + d_Y) / 2) (dimensionless; geodesics along the
    /// edges at unit area, X's in Y's units on the partial path). 0 with one landmark.
    pub discrepancy: Vec<f64>,
    /// The landmarks (indices into the pairs) whose discrepancy is at least
    /// [`SUSPECT_DISCREPANCY`] and, with four or more landmarks, [`SUSPECT_FACTOR`] times the
    /// median discrepancy; with two or three every landmark of discrepancy ≥
    /// [`SUSPECT_DISCREPANCY`] (one wrong landmark cannot be told from the ones it disagrees
    /// with).
    pub suspects: Vec<usize>,
}

/// [`LandmarkCheck`] of L landmarks from their pairwise geodesic distances on X and on Y
/// (`d_x[l][k]`, `d_y[l][k]`, L × L, in the same units). Pairs at distance 0 on both shapes
/// count as agreeing; an infinite distance (another component) as a discrepancy of 2.
pub fn landmark_check(d_x: &[Vec<f64>], d_y: &[Vec<f64>]) -> LandmarkCheck {
    let l = d_x.len();
    let relative = |a: f64, b: f64| {
        if !(a.is_finite() && b.is_finite()) {
            return if a == b { 0.0 } else { 2.0 };
        }
        let mean = 0.5 * (a + b);
        if mean > 0.0 {
            (a - b).abs() / mean
        } else {
            0.0
        }
    };
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return 0.0;
        }
        v.sort_by(|a, b| a.total_cmp(b));
        let h = v.len() / 2;
        if v.len() % 2 == 1 {
            v[h]
        } else {
            0.5 * (v[h - 1] + v[h])
        }
    };
    let discrepancy: Vec<f64> = (0..l)
        .map(|i| {
            // Both directions of a pair: the distance fields are not exactly symmetric.
            median(
                (0..l)
                    .filter(|&k| k != i)
                    .map(|k| relative(0.5 * (d_x[i][k] + d_x[k][i]), 0.5 * (d_y[i][k] + d_y[k][i])))
                    .collect(),
            )
        })
        .collect();
    let typical = median(discrepancy.clone());
    let suspects = (0..l)
        .filter(|&i| {
            let d = discrepancy[i];
            d >= SUSPECT_DISCREPANCY && (l <= 3 || d >= SUSPECT_FACTOR * typical)
        })
        .collect();
    LandmarkCheck { discrepancy, suspects }
}

/// The landmarks of a pair of prepared shapes with their geodesic distance fields.
pub(crate) struct LandmarkData {
    /// The landmarks a_l on X.
    pub xs: Vec<usize>,
    /// Their images b_l on Y.
    pub ys: Vec<usize>,
    /// d_X(a_l, ·) (n × L), unit area.
    pub dist_x: Mat<f64>,
    /// d_Y(b_l, ·) (m × L), unit area.
    pub dist_y: Mat<f64>,
}

impl LandmarkData {
    /// The distance fields of the landmarks `opts.pairs` on the surfaces of `x` and `y` (None
    /// without landmarks). Errors: pairs out of range or repeated, bad weights, shapes without a
    /// surface (abstract data: no geodesics).
    pub fn new(x: &PreparedShape, y: &PreparedShape, opts: &Landmarks) -> Result<Option<LandmarkData>> {
        if opts.is_empty() {
            return Ok(None);
        }
        opts.check(x.n(), y.n())?;
        let (Some(tx), Some(ty)) = (x.triangles(), y.triangles()) else {
            return Err(Error::invalid(
                "landmarks",
                "landmarks need shapes with a surface (meshes or 3-D point clouds) for their geodesic distances",
            ));
        };
        let (gx, gy) = rayon::join(|| GraphGeodesics::mesh_edges(tx), || GraphGeodesics::mesh_edges(ty));
        Self::from_graphs(&gx?, &gy?, opts)
    }

    /// [`LandmarkData::new`] on the edge graphs of the two surfaces, built already (X's n and
    /// Y's m vertices; at unit area). Errors: pairs out of range or repeated, bad weights.
    pub fn from_graphs(gx: &GraphGeodesics, gy: &GraphGeodesics, opts: &Landmarks) -> Result<Option<LandmarkData>> {
        if opts.is_empty() {
            return Ok(None);
        }
        opts.check(gx.n(), gy.n())?;
        let (xs, ys): (Vec<usize>, Vec<usize>) = opts.pairs.iter().copied().unzip();
        let (dx, dy) = rayon::join(|| gx.distances(&xs), || gy.distances(&ys));
        Ok(Some(LandmarkData { xs, ys, dist_x: dx?, dist_y: dy? }))
    }

    /// How well the landmarks agree with each other ([`landmark_check`] of the distances
    /// between them read off the distance fields, in the fields' units).
    pub fn check(&self) -> LandmarkCheck {
        let l = self.len();
        let d_x: Vec<Vec<f64>> = (0..l).map(|i| (0..l).map(|k| self.dist_x[(self.xs[k], i)]).collect()).collect();
        let d_y: Vec<Vec<f64>> = (0..l).map(|i| (0..l).map(|k| self.dist_y[(self.ys[k], i)]).collect()).collect();
        landmark_check(&d_x, &d_y)
    }

    /// Number of landmarks L.
    pub fn len(&self) -> usize {
        self.xs.len()
    }

    /// The pins (a_l, b_l).
    pub fn pins(&self) -> Vec<(usize, usize)> {
        self.xs.iter().copied().zip(self.ys.iter().copied()).collect()
    }

    /// F (n × q) and G (m × q), already normalized (unit columns), with the landmark bumps
    /// appended ([module docs](self), 1.): L · widths columns on each shape, normalized with the
    /// vertex weights of `x` and `y`, then scaled by √(weight · q / (L · widths)).
    pub fn functions(
        &self,
        x: &PreparedShape,
        y: &PreparedShape,
        fx: &Descriptors,
        gy: &Descriptors,
        opts: &Landmarks,
    ) -> Result<(Descriptors, Descriptors)> {
        if opts.weight == 0.0 {
            return Ok((fx.clone(), gy.clone()));
        }
        let (l, w) = (self.len(), opts.widths.len());
        let q_lm = l * w;
        let scale = if fx.q() == 0 { 1.0 } else { (opts.weight * fx.q() as f64 / q_lm as f64).sqrt() };
        let bumps = |d: &Mat<f64>, mass: &[f64]| -> Result<Descriptors> {
            let raw = Mat::from_fn(d.nrows(), q_lm, |i, c| {
                let s = opts.widths[c % w];
                let r = d[(i, c / w)];
                (-(r * r) / (2.0 * s * s)).exp()
            });
            let names = (0..q_lm).map(|c| format!("landmark {} σ {}", c / w, opts.widths[c % w])).collect();
            let unit = crate::descriptors::normalized(&Descriptors::new(raw, names)?, mass)?;
            Descriptors::new(&unit.values * faer::Scale(scale), unit.names)
        };
        let (bx, by) = (bumps(&self.dist_x, &x.basis.mass)?, bumps(&self.dist_y, &y.basis.mass)?);
        Ok((fx.concat(&bx)?, gy.concat(&by)?))
    }

    /// The landmark error of a map given by the images of the landmarks of X (`images[l]` the
    /// vertex of Y of a_l): mean_l d_Y(images[l], b_l), unit area (unreachable: ∞).
    pub fn error(&self, images: &[usize]) -> f64 {
        images.iter().enumerate().map(|(l, &j)| self.dist_y[(j, l)]).sum::<f64>() / self.len().max(1) as f64
    }

    /// The landmark-distance residual of a map of samples of X (`samples`, vertex ids of X, and
    /// their `images` on Y): mean over the samples s and the landmarks l of
    /// |d_X(s, a_l) − d_Y(π(s), b_l)| (unit area; pairs unreachable on either shape skipped; ∞
    /// when none is left). How well a whole map, not only its pins, repeats the distances to
    /// the landmarks ([module docs](self), 3.).
    pub fn distance_residual(&self, samples: &[usize], images: &[usize]) -> f64 {
        let pairs = samples
            .iter()
            .zip(images)
            .flat_map(|(&s, &j)| (0..self.len()).map(move |l| (self.dist_x[(s, l)], self.dist_y[(j, l)])));
        mean_abs_difference(pairs).unwrap_or(f64::INFINITY)
    }

    /// The trilateration costs (s × a) between the search samples of X (`sx`) and the anchors of
    /// Y (`sy`): mean_l |d_X(s_i, a_l) − d_Y(anchor, b_l)|, pairs unreachable on either shape
    /// skipped (a sample that reaches no landmark costs 0 everywhere).
    pub fn trilateration_costs(&self, sx: &SampleDistances, sy: &SampleDistances) -> Mat<f64> {
        let (xv, yv) = (&sx.samples.vertices, &sy.samples.vertices);
        Mat::from_fn(xv.len(), yv.len(), |i, a| {
            let pairs = (0..self.len()).map(|l| (self.dist_x[(xv[i], l)], self.dist_y[(yv[a], l)]));
            mean_abs_difference(pairs).unwrap_or(0.0)
        })
    }

    /// The search samples of X (`sx`) placed from their distances to the landmarks alone
    /// ([module docs](self), 2.): each at the anchor of Y (`sy`) of least trilateration cost,
    /// then corrected by the search's `rounds` with that cost as their data term
    /// ([`super::search::correct`]). Vertex ids of Y, one per sample. Errors: the correction's.
    pub fn trilaterated(&self, sx: &SampleDistances, sy: &SampleDistances, rounds: usize) -> Result<Vec<usize>> {
        let costs = self.trilateration_costs(sx, sy);
        let start = self.trilaterate(&costs, sy);
        Ok(super::search::correct(sx, sy, &start, Some(&costs), rounds)?.0)
    }

    /// For every search sample the anchor (vertex of Y) of least trilateration cost (`costs` from
    /// [`LandmarkData::trilateration_costs`]).
    pub fn trilaterate(&self, costs: &Mat<f64>, sy: &SampleDistances) -> Vec<usize> {
        (0..costs.nrows())
            .map(|i| {
                let best = (0..costs.ncols()).min_by(|&a, &b| costs[(i, a)].total_cmp(&costs[(i, b)])).unwrap_or(0);
                sy.samples.vertices[best]
            })
            .collect()
    }
}

/// `samples` with the landmark vertices `vertices` added (those not among them yet) and every
/// landmark sample weighted by at least `pin_weight` times the mean sample weight, so that the
/// pull-back maps of ZoomOut and the polish are fitted to the pins.
pub(crate) fn with_landmarks(mut samples: Samples, vertices: &[usize], pin_weight: f64) -> Samples {
    if vertices.is_empty() {
        return samples;
    }
    let mean = samples.weights.iter().sum::<f64>() / samples.len().max(1) as f64;
    let w = pin_weight * mean;
    for &v in vertices {
        match samples.vertices.iter().position(|&s| s == v) {
            Some(s) => samples.weights[s] = samples.weights[s].max(w),
            None => {
                samples.vertices.push(v);
                samples.weights.push(w);
            }
        }
    }
    samples
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::signatures::{wks_recipe, WksRecipe};
    use crate::fmap::axiomatic::AxiomaticOptions;
    use crate::fmap::energy::Orientation;
    use crate::matching::axiomatic::tests::{agreement, pair};
    use crate::matching::axiomatic::{axiomatic_pipeline, AxiomaticPipeline};

    /// Distances that agree (up to a common scale of 5 %) give no suspect; one landmark moved
    /// is the one suspect, the others are not; with three landmarks the disagreeing ones are
    /// named; a landmark on another component (infinite distance on one shape) disagrees.
    #[test]
    fn the_landmark_check_names_the_landmark_that_disagrees() {
        let points = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 2.0], [2.0, 0.3]];
        let dist = |p: &[[f64; 2]]| -> Vec<Vec<f64>> {
            p.iter()
                .map(|a| p.iter().map(|b| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()).collect())
                .collect()
        };
        let dx = dist(&points);
        let dy: Vec<Vec<f64>> = dx.iter().map(|r| r.iter().map(|d| 1.05 * d).collect()).collect();
        let c = landmark_check(&dx, &dy);
        assert!(c.suspects.is_empty() && c.discrepancy.iter().all(|d| (d - 0.05 / 1.025).abs() < 1e-12), "{c:?}");
        let mut moved = points;
        moved[3] = [-1.5, 1.8];
        let c = landmark_check(&dx, &dist(&moved));
        assert_eq!(c.suspects, vec![3], "{c:?}");
        // Three landmarks: the one moved and those it disagrees with cannot be told apart.
        let c = landmark_check(&dist(&points[..3]), &dist(&[points[0], points[1], [3.0, 3.0]]));
        assert!(c.suspects.contains(&2) && c.discrepancy[2] >= SUSPECT_DISCREPANCY, "{c:?}");
        // One landmark: nothing to compare.
        assert_eq!(
            landmark_check(&[vec![0.0]], &[vec![0.0]]),
            LandmarkCheck { discrepancy: vec![0.0], suspects: vec![] }
        );
        let mut apart = dx.clone();
        for k in 0..6 {
            if k != 5 {
                (apart[5][k], apart[k][5]) = (f64::INFINITY, f64::INFINITY);
            }
        }
        assert_eq!(landmark_check(&apart, &dx).suspects, vec![5]);
    }

    /// The pipeline asked for the wrong orientation finds the mirror image of the true map (the
    /// data cannot tell them apart); five landmarks with their true images give the true map
    /// back, and hold at their images.
    #[test]
    fn landmarks_turn_a_flipped_map_into_the_true_one() {
        let (x, y, truth, mirrored) = pair();
        let r = WksRecipe::default();
        let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
        let base = AxiomaticPipeline::default();
        let p = AxiomaticPipeline { fit: AxiomaticOptions { orientation: Orientation::Reverse, ..base.fit }, ..base };
        let flipped = axiomatic_pipeline(&x, &y, &f, &g, &p).unwrap();
        let (good, bad) = (agreement(&flipped.map_xy, &truth), agreement(&flipped.map_xy, &mirrored));
        assert!(bad > 0.95 && good < 0.1, "without landmarks: {bad} of the mirror image, {good} of the true map");
        let all: Vec<usize> = (0..x.n()).collect();
        let picks = crate::spatial::farthest_points(x.triangles().unwrap(), &all, 5);
        let pairs: Vec<(usize, usize)> = picks.iter().map(|&i| (i, truth[i])).collect();
        let with = AxiomaticPipeline { landmarks: Landmarks { pairs: pairs.clone(), ..Landmarks::default() }, ..p };
        let res = axiomatic_pipeline(&x, &y, &f, &g, &with).unwrap();
        let (good, bad) = (agreement(&res.map_xy, &truth), agreement(&res.map_xy, &mirrored));
        assert!(good > 0.9 && bad < 0.1, "with 5 landmarks: {good} of the true map, {bad} of its mirror image");
        assert!(pairs.iter().all(|&(i, j)| res.map_xy[i] == j));
        let chosen = &res.candidates[res.chosen];
        assert!(chosen.landmark_error < 0.05, "landmark error of the chosen candidate {}", chosen.landmark_error);
        assert!(res.candidates.iter().any(|c| c.from_landmarks));
    }

    #[test]
    fn bad_landmarks_are_errors() {
        let ok = Landmarks { pairs: vec![(0, 1), (2, 3)], ..Landmarks::default() };
        assert!(ok.check(4, 4).is_ok());
        let e = Landmarks { pairs: vec![(0, 1), (2, 4)], ..ok.clone() }.check(4, 4).unwrap_err().to_string();
        assert!(e.contains("landmarks") && e.contains("pair 2 (2, 4) is out of range"), "{e}");
        let e = Landmarks { pairs: vec![(0, 1), (0, 3)], ..ok.clone() }.check(4, 4).unwrap_err().to_string();
        assert!(e.contains("vertex 0 of X is given twice"), "{e}");
        let e = Landmarks { weight: f64::NAN, ..ok.clone() }.check(4, 4).unwrap_err().to_string();
        assert!(e.contains("landmark weight"), "{e}");
        let e = Landmarks { widths: vec![0.1, 0.0], ..ok.clone() }.check(4, 4).unwrap_err().to_string();
        assert!(e.contains("landmark widths"), "{e}");
        let e = Landmarks { tolerance: 0.0, ..ok }.check(4, 4).unwrap_err().to_string();
        assert!(e.contains("landmark tolerance"), "{e}");
    }

    /// The samples of ZoomOut and the polish get the landmarks, at least `pin_weight` times the
    /// mean sample weight; without landmarks they are unchanged.
    #[test]
    fn landmarks_join_the_samples() {
        let s = Samples { vertices: vec![3, 5, 9], weights: vec![1.0, 2.0, 3.0] };
        assert_eq!(with_landmarks(s.clone(), &[], 10.0), s);
        let t = with_landmarks(s, &[5, 7], 1.5);
        assert_eq!(t.vertices, vec![3, 5, 9, 7]);
        assert_eq!(t.weights, vec![1.0, 3.0, 3.0, 3.0]);
    }
}
