//! Noisy meshes: a measure of roughness at the sampling scale, and one implicit smoothing step
//! that brings a noisy mesh's geometry back to the smoothness of a clean one before its
//! Laplacian, basis, descriptors, normals and gradients are built.
//!
//! **Why.** Gaussian noise of σ = 0.5 % of the bounding-box diagonal on the vertices of a 5k
//! FAUST shape (0.57 mean edge lengths) multiplies its area by 1.8 and tilts every triangle: the
//! Laplacian, the descriptors and the orientation cue of the noisy mesh describe a crumpled
//! surface, and maps to it fail (faust_r, 97 pairs: mean error 13.1 against 1.86 clean,
//! EXPERIMENTS.md, "Noisy meshes"). A map needs only the vertex ids, so the geometry can be
//! cleaned first; the map is then a map of the input's vertices.
//!
//! **Roughness** ([`roughness`]): the share of its area a surface loses to one implicit
//! smoothing step at its own sampling scale, t = h² / 32 (h the mean edge length). Curvature
//! alone makes a clean surface lose little (measured on every shape of our collections: FAUST 5k
//! 0.009–0.011, 8k/15k remeshings 0.005–0.012, TOSCA 0.011–0.033, shapes cut by a plane ≤ 0.040
//! — a cut's boundary shrinks); noise makes it lose much more (FAUST 5k with σ = 0.2 / 0.5 / 1 %:
//! 0.036 / 0.124 / 0.193; TOSCA cat: 0.083 / 0.166 / 0.199). It is dimensionless and does not
//! depend on units.
//!
//! **Denoising** ([`denoise`]): a mesh rougher than [`NOISY_ROUGHNESS`] (above every clean shape
//! measured) gets **one** implicit step (A + t W) P' = A P ([`smooth_step`]; W, A the intrinsic
//! Delaunay Laplacian of the noisy mesh, whose weights are non-negative, so every new position
//! is a weighted mean of old ones), with the **smallest** time t after which it is as smooth as
//! the roughest clean shape measured, roughness ≤ [`CLEAN_ROUGHNESS`] = 0.040
//! ([`smoothing_time`]: bisection on log t). The time is thus chosen by the measured roughness,
//! as a discrepancy principle: remove what is rougher than any clean surface, nothing more.
//! Smoothing further shrinks the limbs and the map gets worse again: on 24 faust_r pairs with
//! σ = 1 % noise on Y, the target 0.030 (the roughest clean *whole* shape) took t = 1.6–3.0 h²
//! and gave a mean error 1.75× → 3.2× the clean one where 0.040 took 1.1–1.9 h² (EXPERIMENTS.md,
//! "Noisy meshes"); a time proportional to an estimate of the noise variance (4 σ̂²) smoothed
//! too little at σ = 1 % and was worse still. Iterated steps with the Laplacian rebuilt at each
//! step degraded the triangles until the eigensolver failed (18 of 39 shapes); one step on the
//! noisy mesh's Laplacian does not. The smoothed mesh's triangles are checked
//! ([`folded_faces`]: fewer than the noisy mesh's, or an error) and reported.
//!
//! Noise too weak to pass [`NOISY_ROUGHNESS`] (FAUST at σ = 0.2 %: roughness 0.036) is left
//! alone: it costs 1.34× the clean error there (24 pairs), within the 2×, and no clean
//! shape can be told from it by this measure (shapes cut by a plane reach 0.040).

use faer::Mat;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::laplacian::{self, Laplacian};
use crate::shape::TriMesh;

/// Time of the probing step of [`roughness`], in units of h² (h the mean edge length).
pub const PROBE_TIME: f64 = 1.0 / 32.0;

/// Roughness of the roughest clean shape measured (a shape cut by a plane; module docs):
/// [`denoise`] smooths a noisy mesh until its roughness is at most this.
pub const CLEAN_ROUGHNESS: f64 = 0.04;

/// Roughness above every clean shape measured, cut shapes included (0.040; module docs):
/// [`denoise`] smooths only meshes rougher than this.
pub const NOISY_ROUGHNESS: f64 = 0.05;

/// Longest smoothing time [`smoothing_time`] tries, in units of h² (FAUST at σ = 1 % reaches
/// [`CLEAN_ROUGHNESS`] by 1.1–1.9 h²).
pub const MAX_TIME: f64 = 8.0;

/// What [`denoise`] measured and did (reported in `report.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Denoising {
    /// [`roughness`] of the input.
    pub roughness_before: f64,
    /// [`roughness`] of the smoothed geometry.
    pub roughness_after: f64,
    /// Time of the smoothing step in units of h² (h the input's mean edge length).
    pub time: f64,
    /// Area of the smoothed geometry / area of the input.
    pub area_ratio: f64,
    /// [`folded_faces`] of the input and of the smoothed geometry.
    pub folded_before: usize,
    /// See `folded_before`.
    pub folded_after: usize,
}

/// A mesh [`denoise`] smoothed: the smoothed geometry (same vertices, in the same order, and
/// the same faces, moved), its intrinsic Delaunay Laplacian (n × n), and the report.
#[derive(Clone, Debug)]
pub struct Denoised {
    /// The smoothed mesh (n vertices, the input's faces).
    pub mesh: TriMesh,
    /// Its intrinsic Delaunay Laplacian ([`crate::geodesic::intrinsic_delaunay_laplacian`]).
    pub laplacian: Laplacian,
    /// What was measured and done.
    pub report: Denoising,
}

/// One implicit smoothing step: the mesh with positions P' = S P (n × 3), S = (A + t W)⁻¹ A,
/// with W and A of `lap` (a Laplacian of `mesh`, n × n, non-negative semi-definite W) and t in
/// units² (the step's time; S damps an eigenfunction of eigenvalue λ by 1 / (1 + t λ)); same
/// vertex order and faces. Errors: t not finite or negative, a Laplacian of another size, a
/// failed factorization, non-finite positions.
pub fn smooth_step(mesh: &TriMesh, lap: &Laplacian, t: f64) -> Result<TriMesh> {
    TriMesh::new(step_positions(mesh, lap, t)?, mesh.faces().to_vec())
}

/// The positions (n × 3) of [`smooth_step`].
fn step_positions(mesh: &TriMesh, lap: &Laplacian, t: f64) -> Result<Vec<[f64; 3]>> {
    if !(t.is_finite() && t >= 0.0) {
        return Err(Error::invalid("smoothing time", format!("{t} is not a finite non-negative number")));
    }
    let n = mesh.n_vertices();
    if lap.n() != n {
        return Err(Error::invalid("laplacian", format!("it has {} vertices, the mesh {n}", lap.n())));
    }
    let llt = crate::cholesky::SparseLlt::new(lap.combination(t, 1.0).as_ref(), lap.symbolic_cholesky()?)
        .map_err(|e| Error::numerical("smoothing", format!("factorization of A + tW failed: {e}")))?;
    let v = mesh.vertices();
    let mut p = Mat::from_fn(n, 3, |i, d| lap.mass[i] * v[i][d]);
    llt.solve_in_place(p.as_mut());
    let moved: Vec<[f64; 3]> = (0..n).map(|i| [p[(i, 0)], p[(i, 1)], p[(i, 2)]]).collect();
    if moved.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::numerical("smoothing", "non-finite positions after the implicit step"));
    }
    Ok(moved)
}

/// Roughness of a mesh at its sampling scale (module docs): 1 − area(S P) / area(P) for the
/// implicit step S of time [`PROBE_TIME`] · h² with the mesh's cotangent Laplacian.
/// Dimensionless, in [0, 1). Errors: those of [`crate::laplacian::cotangent`] (a mesh of zero
/// area among them) and [`smooth_step`], a mesh without edge length.
pub fn roughness(mesh: &TriMesh) -> Result<f64> {
    // The Laplacian first: its errors name what is wrong with a degenerate mesh (zero total
    // area, underflow, a vertex in no triangle).
    let lap = laplacian::cotangent(mesh)?;
    roughness_with(mesh, &lap)
}

/// [`roughness`] with the mesh's cotangent Laplacian `cotan` (n × n, from
/// [`crate::laplacian::cotangent`]) already built; the probe's factorization reuses the
/// symbolic analysis cached on `cotan` (which the eigensolver then reuses in turn).
pub fn roughness_with(mesh: &TriMesh, cotan: &Laplacian) -> Result<f64> {
    let (h, area) = scales(mesh)?;
    let probe = smooth_step(mesh, cotan, PROBE_TIME * h * h)?;
    Ok((1.0 - probe.total_area() / area).max(0.0))
}

/// Faces of `mesh` folded over: whose normal points away from the sum of its three vertices'
/// area-weighted normals (n_f · (n_a + n_b + n_c) ≤ 0), or without area. A count out of
/// `mesh.n_faces()`; 0 on a clean mesh.
pub fn folded_faces(mesh: &TriMesh) -> usize {
    let (fnrm, vn) = (mesh.face_normals(), mesh.vertex_normals());
    mesh.faces()
        .iter()
        .zip(&fnrm)
        .filter(|(f, n)| {
            let s: f64 = (0..3).map(|d| n[d] * f.iter().map(|&i| vn[i as usize][d]).sum::<f64>()).sum();
            s.is_nan() || s <= 0.0
        })
        .count()
}

/// The smallest time t (units², at most [`MAX_TIME`] h²) of one [`smooth_step`] with `lap` (a
/// Laplacian of `mesh`, n × n) after which the mesh's [`roughness`] is at most `target`, found
/// by bisection on log t to within 3 %; with it the smoothed mesh and its roughness. When
/// [`MAX_TIME`] h² does not reach the target, that time. Errors: those of [`roughness`] and
/// [`smooth_step`], a target not in (0, 1).
pub fn smoothing_time(mesh: &TriMesh, lap: &Laplacian, target: f64) -> Result<(f64, TriMesh, f64)> {
    if !(target > 0.0 && target < 1.0) {
        return Err(Error::invalid("roughness target", format!("{target} is not in (0, 1)")));
    }
    let (h, _) = scales(mesh)?;
    let at = |c: f64| -> Result<(f64, TriMesh, f64)> {
        let t = c * h * h;
        let smooth = smooth_step(mesh, lap, t)?;
        let r = roughness(&smooth)?;
        Ok((t, smooth, r))
    };
    // Bracket: double from 1/16 h² until the target is reached (or MAX_TIME).
    let (mut lo, mut hi) = (0.0, 1.0 / 16.0);
    let mut best = at(hi)?;
    while best.2 > target {
        if hi >= MAX_TIME {
            return Ok(best);
        }
        lo = hi;
        hi = (2.0 * hi).min(MAX_TIME);
        best = at(hi)?;
    }
    if lo == 0.0 {
        lo = hi / 64.0;
    }
    // Bisection on log t: the roughness decreases with t.
    while hi / lo > 1.03 {
        let mid = (lo * hi).sqrt();
        let r = at(mid)?;
        if r.2 <= target {
            hi = mid;
            best = r;
        } else {
            lo = mid;
        }
    }
    Ok(best)
}

/// Denoises `mesh` if it is rough (module docs): `Ok(None)` when its [`roughness`] is at most
/// [`NOISY_ROUGHNESS`] (the mesh is used as it is), else one implicit step on its intrinsic
/// Delaunay Laplacian with the time of [`smoothing_time`] for [`CLEAN_ROUGHNESS`], the smoothed
/// mesh's intrinsic Delaunay Laplacian and the report. Also returns the input's roughness.
/// Errors: those of [`roughness`] and [`smooth_step`], and a smoothed mesh with more folded
/// faces than the input ([`folded_faces`]: the step would have damaged the triangles).
pub fn denoise(mesh: &TriMesh) -> Result<(Option<Denoised>, f64)> {
    denoise_with(mesh, &laplacian::cotangent(mesh)?)
}

/// [`denoise`] with the mesh's cotangent Laplacian `cotan` (n × n) already built: a clean
/// mesh's caller keeps it as the shape's Laplacian, so it is assembled once.
pub fn denoise_with(mesh: &TriMesh, cotan: &Laplacian) -> Result<(Option<Denoised>, f64)> {
    let before = roughness_with(mesh, cotan)?;
    if before <= NOISY_ROUGHNESS {
        return Ok((None, before));
    }
    let (h, area) = scales(mesh)?;
    let idt = crate::geodesic::intrinsic_delaunay_laplacian(mesh)?;
    let (t, smooth, after) = smoothing_time(mesh, &idt, CLEAN_ROUGHNESS)?;
    let (folded_before, folded_after) = (folded_faces(mesh), folded_faces(&smooth));
    if folded_after > folded_before {
        return Err(Error::numerical(
            "smoothing",
            format!(
                "the smoothed mesh has {folded_after} folded faces, the noisy one {folded_before} (the cotangent \
                 Laplacian without smoothing uses the mesh as it is)"
            ),
        ));
    }
    let report = Denoising {
        roughness_before: before,
        roughness_after: after,
        time: t / (h * h),
        area_ratio: smooth.total_area() / area,
        folded_before,
        folded_after,
    };
    let laplacian = crate::geodesic::intrinsic_delaunay_laplacian(&smooth)?;
    Ok((Some(Denoised { mesh: smooth, laplacian, report }), before))
}

/// Roughness of a 3-D point cloud (n points): [`roughness`] of its local triangulations
/// ([`crate::cloud::cloud_surface`] with [`crate::cloud::DEFAULT_NEIGHBOURS`] neighbours, at most
/// n − 1), the surface its Laplacian is built on. Dimensionless. Measured on clean and noisy
/// clouds in `examples/cloud_roughness.rs` (EXPERIMENTS.md, "Noisy point clouds"); the pipeline
/// does not smooth clouds (tried there, not kept). Errors: those of
/// [`crate::cloud::cloud_surface`] and [`roughness`].
pub fn cloud_roughness(points: &[[f64; 3]]) -> Result<f64> {
    let k = crate::cloud::DEFAULT_NEIGHBOURS.min(points.len().saturating_sub(1));
    roughness(&crate::cloud::cloud_surface(points, k)?.soup)
}

/// The mean edge length h and the area of `mesh`, both finite and positive.
fn scales(mesh: &TriMesh) -> Result<(f64, f64)> {
    let (h, area) = (mesh.mean_edge_length(), mesh.total_area());
    if !(area.is_finite() && area > 0.0 && h.is_finite() && h > 0.0) {
        return Err(Error::invalid("mesh", "it has no area or no edge length: its roughness is undefined"));
    }
    Ok((h, area))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::icosphere;

    fn noisy(mesh: &TriMesh, sigma: f64, seed: u64) -> TriMesh {
        let mut rng = crate::rng::Normal::new(seed);
        let moved = mesh.vertices().iter().map(|p| [0, 1, 2].map(|d| p[d] + sigma * rng.sample())).collect();
        TriMesh::new(moved, mesh.faces().to_vec()).unwrap()
    }

    fn radial_scatter(m: &TriMesh) -> f64 {
        let r: Vec<f64> = m.vertices().iter().map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()).collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
    }

    /// A clean sphere is smooth and left alone; with noise of half an edge length it is rough,
    /// gets one step that brings it to a clean roughness, keeps its vertex count, order and
    /// faces, unfolds most folded faces, and its area and radius come back near the clean
    /// sphere's.
    #[test]
    fn noise_is_detected_and_smoothed_away() {
        let clean = icosphere(4);
        let (out, r) = denoise(&clean).unwrap();
        assert!(out.is_none() && r < 0.01, "clean sphere: roughness {r}");

        let h = clean.mean_edge_length();
        let rough = noisy(&clean, 0.5 * h, 3);
        let inflated = rough.total_area() / clean.total_area();
        assert!(inflated > 1.3, "noise inflates the area: {inflated}");
        let (out, r) = denoise(&rough).unwrap();
        assert!(r > NOISY_ROUGHNESS, "noisy sphere: roughness {r}");
        let d = out.expect("smoothed");
        let rep = &d.report;
        assert_eq!(rep.roughness_before, r);
        assert!(rep.roughness_after <= CLEAN_ROUGHNESS && rep.time > 0.0 && rep.time < MAX_TIME, "{rep:?}");
        assert_eq!(roughness(&d.mesh).unwrap(), rep.roughness_after);
        assert_eq!(d.mesh.n_vertices(), clean.n_vertices());
        assert_eq!(d.mesh.faces(), clean.faces());
        assert_eq!(d.laplacian.n(), clean.n_vertices());
        // Noise of half an edge length folds 15 % of the faces over; the step unfolds most
        // (754 → 200 when written).
        assert!(rep.folded_before > 500 && 3 * rep.folded_after < rep.folded_before, "{rep:?}");
        assert_eq!(folded_faces(&clean), 0);
        let ratio = d.mesh.total_area() / clean.total_area();
        assert!((ratio - 1.0).abs() < 0.15, "area after denoising / clean area = {ratio}");
        assert!((rep.area_ratio * inflated - ratio).abs() < 1e-9, "{rep:?}");
        // The radial scatter (the noise's normal component, σ = h / 2 before) drops by a third
        // at least (the step stops at the roughness of a clean FAUST or TOSCA shape, rougher
        // than a clean sphere's).
        let (was, is) = (radial_scatter(&rough), radial_scatter(&d.mesh));
        assert!(is < 0.67 * was, "radial scatter {is} after, {was} before (edge length {h})");
        // The time found is the smallest one: 5 % less leaves the mesh rougher than the target.
        let idt = crate::geodesic::intrinsic_delaunay_laplacian(&rough).unwrap();
        let hn = rough.mean_edge_length();
        let less = smooth_step(&rough, &idt, 0.95 * rep.time * hn * hn).unwrap();
        assert!(roughness(&less).unwrap() > CLEAN_ROUGHNESS);
    }

    /// Roughness grows with the noise and does not depend on units.
    #[test]
    fn roughness_grows_with_noise_and_does_not_depend_on_units() {
        let s = icosphere(3);
        let h = s.mean_edge_length();
        let r: Vec<f64> = [0.0, 0.2, 0.5, 1.0].iter().map(|&f| roughness(&noisy(&s, f * h, 5)).unwrap()).collect();
        assert!(r.windows(2).all(|w| w[0] < w[1]), "{r:?}");
        let m = noisy(&s, 0.3 * h, 5);
        let r = roughness(&m).unwrap();
        for k in [1e-3, 1e3] {
            let scaled = m.map_vertices(|p| [p[0] * k, p[1] * k, p[2] * k]).unwrap();
            let rs = roughness(&scaled).unwrap();
            assert!((rs - r).abs() < 1e-9, "{rs} vs {r} at ×{k}");
        }
    }

    /// A cloud's roughness grows with noise, and does not depend on units.
    #[test]
    fn cloud_roughness_grows_with_noise() {
        let s = icosphere(4);
        let h = s.mean_edge_length();
        let r: Vec<f64> =
            [0.0, 0.25, 0.5].iter().map(|&f| cloud_roughness(noisy(&s, f * h, 3).vertices()).unwrap()).collect();
        assert!(r.windows(2).all(|w| w[0] < w[1]) && r[0] < 0.02, "{r:?}");
        let big: Vec<[f64; 3]> = noisy(&s, 0.5 * h, 3).vertices().iter().map(|p| p.map(|c| c * 1e3)).collect();
        assert!((cloud_roughness(&big).unwrap() - r[2]).abs() < 1e-9);
    }

    /// A step of zero time returns the positions unchanged.
    #[test]
    fn a_step_of_zero_time_changes_nothing() {
        let m = icosphere(2);
        let lap = laplacian::cotangent(&m).unwrap();
        let same = smooth_step(&m, &lap, 0.0).unwrap();
        for (a, b) in same.vertices().iter().zip(m.vertices()) {
            assert!((0..3).all(|d| (a[d] - b[d]).abs() < 1e-12), "{a:?} {b:?}");
        }
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let m = icosphere(1);
        let lap = laplacian::cotangent(&m).unwrap();
        for t in [f64::NAN, -1.0, f64::INFINITY] {
            let e = smooth_step(&m, &lap, t).unwrap_err().to_string();
            assert!(e.contains("smoothing time"), "{e}");
        }
        let other = laplacian::cotangent(&icosphere(2)).unwrap();
        assert!(smooth_step(&m, &other, 0.1).unwrap_err().to_string().contains("vertices"));
        for target in [0.0, 1.0, f64::NAN] {
            assert!(smoothing_time(&m, &lap, target).unwrap_err().to_string().contains("roughness target"));
        }
        // Every vertex at one point: no area, no edge length; denoise says so too.
        let flat = TriMesh::new(vec![[1.0, 2.0, 3.0]; 3], vec![[0, 1, 2]]).unwrap();
        for e in [roughness(&flat).unwrap_err().to_string(), denoise(&flat).unwrap_err().to_string()] {
            assert!(e.contains("zero total area"), "{e}");
        }
    }
}
