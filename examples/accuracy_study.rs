//! Accuracy study of the matching pipelines on a data set (issue 11): every variant on every
//! pair, scored with exact geodesics on Y's mesh directly (no flip forgiven) and with the
//! left–right flip forgiven; one JSON line per (pair, variant) on stdout.
//!
//! ```sh
//! cargo run --release --example accuracy_study -- ../shared/data/faust_r 0:97 "default:" > runs/faust.jsonl
//! cargo run --release --example accuracy_study -- ../shared/data/faust_r pairs.txt \
//!     "default:;nosigned:signed=0;noorient:wo=0,signed=0" > runs/ablation.jsonl
//! CLOUD=y cargo run --release --example accuracy_study -- ../shared/data/faust_r 0:97 "default:"
//! ```
//! Arguments: the data set folder; the pairs (`start:end` of its `pairs.txt`, or a file of
//! `X Y` lines); variants `name:key=value,...` separated by `;` (keys below, everything else
//! the library defaults, i.e. `funcorr match`'s).
//!
//! Keys: `k` one candidate size (else `cands=20/30/40/50`), `wd wl wc wo` energy weights,
//! `mask=std|res`, `orient=p|r|i`, `ug=0|1` unit gradients, `signed=N`, `nd=N` WKS count,
//! `kd=N` WKS eigenpairs, `ss=N` keep every ss-th WKS, `zo=K` final ZoomOut size (0 none),
//! `zs=S` its step, `ns=N` its samples, `zp=K` probe size, `ps=S` its step, `pn=N` its
//! samples, `bij=W` the bijective ZoomOut with bijectivity weight W instead of ZoomOut,
//! `pol=N` rounds of the bijective polish (0 none), `bs=N` samples of the basin search (0:
//! none, candidates by edge distortion), `br=N` its correction rounds, `banch=N` its anchors on
//! Y, `near=P` the vertex pairs n·m above which the searches are restricted near the samples'
//! map (`--near-above`), `nc=N` its cells, `cp=0|1` the final ZoomOut continued from the
//! probe, `cz=0|1` ZoomOut coarse to fine in Y on shapes of more than 25,000 vertices.
//!
//! Landmarks (issue 28, `funcorr match --landmarks`): `lm=N` gives the pipeline N ground-truth
//! pairs, the farthest-point samples (Euclidean, on X) of the template points starting from the
//! template point at position `lmseed · 7919 mod len` (`lmseed=S`, default 0: the first), with
//! their ground-truth images; `lmw=W` their weight in the data, `lmpin=W` their sample weight in
//! ZoomOut and the polish, `lmtol=T` their tolerance in the candidates' score, `lmsig=a/b/…` the
//! widths of their bumps
//! (`funcorr::matching::landmarks::Landmarks`). The JSON line then has `"landmarks"` and
//! `"lmseed"`; `"search"` has the chosen candidate's `"landmark_error"` and whether it was made
//! from the landmarks.
//! ```sh
//! $E ../shared/data/tosca_nonisometric_r 0:2 "lm0:;lm3:lm=3;lm5:lm=5;lm10:lm=10;lm5s1:lm=5,lmseed=1"
//! ```
//!
//! Point clouds: `CLOUD=y` (Y given as its vertices), `CLOUD=both`; `RESAMPLE=N` draws N points
//! uniformly on the surface instead (vertices not shared). Errors are then measured on Y's mesh
//! through the nearest vertex of each cloud point, and the template points of X are moved to the
//! nearest cloud point. `KBASIS` sets the eigenpairs per shape (default 200).
//!
//! Perturbations (issue 27), all seeded by the shape's name (FNV-1a, mixed with `SEED`, default
//! 0), so a run is reproduced exactly by its command line:
//! - `PERTURB=x|y|both` (default `y`): the shapes that `NOISE`, `NONUNIFORM` and `OUTLIERS` act on.
//! - `NOISE=σ`: isotropic Gaussian noise, standard deviation σ × the bounding-box diagonal per
//!   coordinate, on every point of a cloud or every vertex of a mesh (a noisy mesh keeps its
//!   faces).
//! - `NONUNIFORM=1` (with `RESAMPLE=N`, on clouds): the N points are drawn with a density that
//!   grows smoothly (exponentially) by a factor 5 along a random direction across the shape,
//!   instead of uniformly.
//! - `OUTLIERS=f` (on clouds): f × (surface points) extra points, uniform in the bounding box
//!   enlarged by 10 %, appended after the surface points. They are matched like every point but
//!   are never template points of X; a point of X mapped to an outlier of Y scores through the
//!   outlier's nearest vertex.
//! - `SCALE=1`: every shape (X and Y, whatever `PERTURB`) scaled by its own factor 10^u, u uniform
//!   in [−3, 3]; `ROTATE=1`: every shape rotated by its own uniformly random rotation.
//!
//! Errors are always measured on the clean, unscaled mesh (geodesics / √area ×100): a mesh keeps
//! its vertex ids; a cloud point maps to the nearest vertex of the clean position it was sampled
//! from, and X's template vertices move to the nearest clean surface point (outliers excluded).
//! A shape smoothed before its Laplacian (`funcorr::denoise`, a noisy mesh) adds `"denoised_x"` or
//! `"denoised_y"` (its `Denoising` report). With any perturbation the JSON line gets `"perturb"` (the settings) and, with `SCALE`,
//! `"scale_x"`/`"scale_y"` (the factors).
//!
//! Reproducing the perturbed inputs (issue 27's data; `D=../shared/data/faust_r`, add `0:97`
//! for every pair):
//! ```sh
//! E="cargo run --release --example accuracy_study --"
//! CLOUD=y $E $D 0:97 "default:"                                    # mesh → vertex cloud
//! CLOUD=both $E $D 0:97 "default:"                                 # cloud → cloud
//! CLOUD=y RESAMPLE=5000 $E $D 0:97 "default:"                      # uniform resampled cloud
//! CLOUD=y RESAMPLE=5000 NONUNIFORM=1 $E $D 0:97 "default:"         # non-uniform resampled cloud
//! CLOUD=y RESAMPLE=5000 NOISE=0.005 $E $D 0:97 "default:"          # cloud, σ = 0.5 % noise
//! CLOUD=y RESAMPLE=5000 OUTLIERS=0.01 $E $D 0:97 "default:"        # cloud, 1 % outliers
//! NOISE=0.002 $E $D 0:97 "default:"                                # noisy mesh Y, σ = 0.2 %
//! NOISE=0.005 $E $D 0:97 "default:"                                # noisy mesh Y, σ = 0.5 %
//! NOISE=0.01 $E $D 0:97 "default:"                                 # noisy mesh Y, σ = 1 %
//! SCALE=1 $E $D 0:97 "default:"                                    # each shape ×10^[−3, 3]
//! SCALE=1 ROTATE=1 $E $D 0:97 "default:"                           # ... and rotated
//! ```
//! (`PERTURB=both` perturbs X as well; `CLOUD=both` makes both shapes clouds; the variables
//! combine, e.g. `CLOUD=y RESAMPLE=5000 NONUNIFORM=1 NOISE=0.005 OUTLIERS=0.01`.)

use std::io::Write;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use funcorr::benchmark::Dataset;
use funcorr::descriptors::{signatures as sig, Descriptors};
use funcorr::fmap::energy::{Mask, Orientation};
use funcorr::geodesic::{ExactGeodesics, GraphGeodesics};
use funcorr::matching::{self, MatchOptions, Method};
use funcorr::prepared::{LaplacianChoice, PreparedShape};
use funcorr::shape::{PointSet, Shape, TriMesh};
use funcorr::spectral::BasisCache;
use funcorr::{refine, Result};
use rayon::prelude::*;

#[derive(Clone, Debug)]
struct Variant {
    name: String,
    opts: MatchOptions,
    /// WKS energies, from the first `kd` eigenpairs, every `ss`-th kept.
    nd: usize,
    kd: usize,
    ss: usize,
    /// Landmarks (`lm=N`: N ground-truth pairs, `lmseed=S` which ones; 0: none).
    lm: usize,
    lm_seed: u64,
}

impl Variant {
    fn parse(spec: &str) -> Variant {
        let (name, rest) = spec.split_once(':').unwrap_or((spec, ""));
        let mut opts = MatchOptions { method: Method::Axiomatic, ..MatchOptions::default() };
        let (mut nd, mut kd, mut ss) = (100, 128, 2);
        let (mut lm, mut lm_seed) = (0, 0);
        let a = &mut opts.axiomatic;
        for kv in rest.split(',').filter(|s| !s.is_empty()) {
            let (k, val) = kv.split_once('=').expect("key=value");
            let f = || val.parse::<f64>().expect("number");
            let u = || val.parse::<usize>().expect("integer");
            match k {
                "k" => a.candidates = vec![u()],
                "cands" => a.candidates = val.split('/').map(|t| t.parse().unwrap()).collect(),
                "wd" => a.fit.weights.descriptors = f(),
                "wl" => a.fit.weights.laplacian = f(),
                "wc" => a.fit.weights.commutativity = f(),
                "wo" => a.fit.weights.orientation = f(),
                "mask" => a.fit.mask = if val == "std" { Mask::Standard } else { Mask::Resolvent { gamma: 0.5 } },
                "orient" => {
                    a.fit.orientation = match val {
                        "r" => Orientation::Reverse,
                        "i" => Orientation::Ignore,
                        _ => Orientation::Preserve,
                    }
                }
                "ug" => a.fit.unit_gradients = val == "1",
                "signed" => a.signed = u(),
                "zo" => a.refine.k_final = u(),
                "zs" => a.refine.step = u(),
                "ns" => a.refine.samples = u(),
                "zp" => a.probe.k_final = u(),
                "ps" => a.probe.step = u(),
                "pn" => a.probe.samples = u(),
                "bij" => a.bijective = f(),
                "cp" => a.continue_probe = val == "1",
                "cz" => a.coarse_zoomout = val == "1",
                "pol" => a.polish = u(),
                "bs" => a.search.samples = u(),
                "br" => a.search.rounds = u(),
                "banch" => a.search.anchors = u(),
                "near" => a.near.above_pairs = val.parse().expect("integer"),
                "nc" => a.near.cells = u(),
                "nd" => nd = u(),
                "kd" => kd = u(),
                "ss" => ss = u(),
                "lm" => lm = u(),
                "lmseed" => lm_seed = val.parse().expect("integer"),
                "lmw" => a.landmarks.weight = f(),
                "lmpin" => a.landmarks.pin_weight = f(),
                "lmtol" => a.landmarks.tolerance = f(),
                "lmsig" => a.landmarks.widths = val.split('/').map(|w| w.parse().expect("lmsig")).collect(),
                _ => panic!("unknown key {k}"),
            }
        }
        Variant { name: name.to_string(), opts, nd, kd, ss, lm, lm_seed }
    }
}

/// `count` landmarks of the pair: farthest-point samples (Euclidean, on X) of the template points
/// `gt_x`, starting from the template point at position `seed · 7919 mod len` (seed 0: the first),
/// with their ground-truth images `gt_y`. Returns (vertex of X, vertex of Y) pairs.
fn pick_landmarks(mesh: &TriMesh, gt_x: &[usize], gt_y: &[usize], count: usize, seed: u64) -> Vec<(usize, usize)> {
    let len = gt_x.len();
    let off = (seed as usize).wrapping_mul(7919) % len.max(1);
    let order: Vec<usize> = (0..len).map(|t| (t + off) % len).collect();
    let cand: Vec<usize> = order.iter().map(|&t| gt_x[t]).collect();
    funcorr::spatial::farthest_points(mesh, &cand, count).into_iter().map(|p| (cand[p], gt_y[order[p]])).collect()
}

/// WKS from the first kd eigenpairs, every ss-th of nd kept.
fn wks(p: &PreparedShape, v: &Variant) -> Result<Descriptors> {
    let b = p.basis.truncate(v.kd.min(p.basis.k()))?;
    let w = sig::wks(&b, v.nd, true)?;
    let keep: Vec<usize> = (0..w.q()).step_by(v.ss.max(1)).collect();
    Descriptors::new(
        faer::Mat::from_fn(w.n(), keep.len(), |i, j| w.values[(i, keep[j])]),
        keep.iter().map(|&j| w.names[j].clone()).collect(),
    )
}

/// A shape of the study: the prepared shape (mesh or cloud, perturbed), its clean mesh for
/// evaluation, for clouds the nearest clean mesh vertex of every cloud point and the nearest
/// clean surface point of every mesh vertex, and the random scale factor applied (1 without
/// `SCALE`).
struct StudyShape {
    prepared: PreparedShape,
    mesh: TriMesh,
    point_to_vertex: Option<Vec<usize>>,
    vertex_to_point: Option<Vec<usize>>,
    factor: f64,
}

fn nearest(reference: &[[f64; 3]], query: &[[f64; 3]]) -> Vec<usize> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(reference);
    query.iter().map(|q| tree.nearest_one::<kiddo::SquaredEuclidean>(q).item as usize).collect()
}

/// The study's inputs and their perturbations, read from the environment (see the header).
#[derive(Clone, Debug)]
struct Perturb {
    /// `CLOUD`: "" (meshes), "y" or "both".
    cloud: String,
    /// `RESAMPLE`: surface samples per cloud (0: the vertices).
    resample: usize,
    /// `PERTURB`: "x", "y" or "both", the shapes noise, non-uniform sampling and outliers act on.
    targets: String,
    /// `NOISE`: Gaussian σ as a fraction of the bounding-box diagonal.
    noise: f64,
    /// `NONUNIFORM`: density ratio 5 along a random direction instead of uniform samples.
    nonuniform: bool,
    /// `OUTLIERS`: outliers as a fraction of the surface points.
    outliers: f64,
    /// `SCALE`: every shape ×10^u, u uniform in [−3, 3].
    scale: bool,
    /// `ROTATE`: every shape randomly rotated.
    rotate: bool,
    /// `SEED`: mixed into every shape's seed.
    seed: u64,
}

/// Density ratio between the two ends of a shape in non-uniform sampling.
const DENSITY_RATIO: f64 = 5.0;

impl Perturb {
    fn from_env() -> Perturb {
        let env = |k: &str| std::env::var(k).ok().filter(|s| !s.is_empty());
        let num =
            |k: &str| env(k).map_or(0.0, |s| s.parse::<f64>().unwrap_or_else(|_| panic!("{k}={s}: not a number")));
        let flag = |k: &str| env(k).is_some_and(|s| s != "0");
        let p = Perturb {
            cloud: env("CLOUD").unwrap_or_default(),
            resample: env("RESAMPLE").map_or(0, |s| s.parse().expect("RESAMPLE=N")),
            targets: env("PERTURB").unwrap_or_else(|| "y".into()),
            noise: num("NOISE"),
            nonuniform: flag("NONUNIFORM"),
            outliers: num("OUTLIERS"),
            scale: flag("SCALE"),
            rotate: flag("ROTATE"),
            seed: env("SEED").map_or(0, |s| s.parse().expect("SEED=integer")),
        };
        assert!(["", "y", "both"].contains(&p.cloud.as_str()), "CLOUD must be y or both");
        assert!(["x", "y", "both"].contains(&p.targets.as_str()), "PERTURB must be x, y or both");
        assert!(p.noise >= 0.0 && p.outliers >= 0.0, "NOISE and OUTLIERS must be ≥ 0");
        let perturbed_cloud = [false, true].iter().any(|&t| p.perturbs(t) && p.is_cloud(t));
        if p.nonuniform {
            assert!(
                p.resample > 0 && perturbed_cloud,
                "NONUNIFORM needs RESAMPLE=N and a perturbed cloud (CLOUD, PERTURB)"
            );
        }
        if p.outliers > 0.0 {
            assert!(perturbed_cloud, "OUTLIERS needs a perturbed cloud (CLOUD, PERTURB)");
        }
        p
    }

    /// Whether the shape (X: `target` false, Y: true) is given as a point cloud.
    fn is_cloud(&self, target: bool) -> bool {
        self.cloud == "both" || (self.cloud == "y" && target)
    }

    /// Whether `NOISE`, `NONUNIFORM` and `OUTLIERS` act on the shape.
    fn perturbs(&self, target: bool) -> bool {
        self.targets == "both" || (self.targets == "y") == target
    }

    /// The settings for the JSON line; empty without any perturbation.
    fn describe(&self) -> String {
        let mut parts = Vec::new();
        if self.noise > 0.0 {
            parts.push(format!("noise={}", self.noise));
        }
        if self.nonuniform {
            parts.push(format!("nonuniform={DENSITY_RATIO}"));
        }
        if self.outliers > 0.0 {
            parts.push(format!("outliers={}", self.outliers));
        }
        let mut s = if parts.is_empty() { String::new() } else { format!("{}:{}", self.targets, parts.join(",")) };
        for (on, what) in [(self.scale, "scale"), (self.rotate, "rotate")] {
            if on {
                s += if s.is_empty() { "" } else { ";" };
                s += what;
            }
        }
        if !s.is_empty() && self.seed != 0 {
            s += &format!(";seed={}", self.seed);
        }
        s
    }
}

/// SplitMix64 with Box–Muller normals: a tiny deterministic generator (the crate's own is
/// private), the same numbers on every platform.
struct Rng(u64);

impl Rng {
    /// The generator of one random `stream` ("noise", "outliers", ...) of shape `name`: FNV-1a of
    /// both, mixed with `seed`, so each stream is independent of which others are switched on.
    fn for_shape(name: &str, stream: &str, seed: u64) -> Rng {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in name.bytes().chain([0]).chain(stream.bytes()) {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
        Rng(h ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
    }
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1).
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// Standard normal.
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Length of the bounding-box diagonal of `points`.
fn diagonal(points: &[[f64; 3]]) -> f64 {
    let (lo, hi) = bounding_box(points);
    (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt()
}

/// The axis-aligned bounding box (min, max) of `points`.
fn bounding_box(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    points.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
        (std::array::from_fn(|d| lo[d].min(p[d])), std::array::from_fn(|d| hi[d].max(p[d])))
    })
}

/// Isotropic Gaussian noise: every coordinate of every point moved by a normal sample of standard
/// deviation `sigma` (absolute units; the study passes σ × the clean bounding-box diagonal).
fn add_noise(points: &mut [[f64; 3]], sigma: f64, rng: &mut Rng) {
    for p in points {
        for c in p.iter_mut() {
            *c += sigma * rng.normal();
        }
    }
}

/// `count` points on `mesh` with a density proportional to `ratio^t`, t ∈ [0, 1] the position
/// along a random unit direction between the mesh's two extreme vertices in that direction (so
/// the density changes smoothly by `ratio` from one end to the other). Rejection sampling of the
/// mesh's uniform surface samples, hence exact for any triangle size.
fn sample_nonuniform(mesh: &TriMesh, count: usize, ratio: f64, rng: &mut Rng) -> Result<Vec<[f64; 3]>> {
    let dir = loop {
        let d = [rng.normal(), rng.normal(), rng.normal()];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if n > 1e-6 {
            break d.map(|c| c / n);
        }
    };
    let along = |p: &[f64; 3]| p[0] * dir[0] + p[1] * dir[1] + p[2] * dir[2];
    let (lo, hi) =
        mesh.vertices().iter().map(along).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(t), b.max(t)));
    let mut points = Vec::with_capacity(count);
    while points.len() < count {
        // Acceptance averages (ratio − 1) / (ratio ln ratio) ≈ 0.5 for ratio 5.
        let batch = mesh.sample_surface(2 * (count - points.len()) + 16, rng.next_u64())?;
        for p in batch {
            let t = ((along(&p) - lo) / (hi - lo)).clamp(0.0, 1.0);
            if points.len() < count && rng.uniform() < ratio.powf(t - 1.0) {
                points.push(p);
            }
        }
    }
    Ok(points)
}

/// Appends round(`fraction` × len) outliers, uniform in the bounding box of `points` enlarged by
/// 10 % (5 % of its extent beyond each face); returns how many.
fn add_outliers(points: &mut Vec<[f64; 3]>, fraction: f64, rng: &mut Rng) -> usize {
    let (lo, hi) = bounding_box(points);
    let count = (fraction * points.len() as f64).round() as usize;
    for _ in 0..count {
        points.push(std::array::from_fn(|d| lo[d] - 0.05 * (hi[d] - lo[d]) + 1.1 * (hi[d] - lo[d]) * rng.uniform()));
    }
    count
}

/// A random scale factor 10^u, u uniform in [−3, 3].
fn random_scale(rng: &mut Rng) -> f64 {
    10f64.powf(6.0 * rng.uniform() - 3.0)
}

/// A uniformly random rotation (a normalized Gaussian quaternion), as a matrix.
fn random_rotation(rng: &mut Rng) -> [[f64; 3]; 3] {
    let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
    let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    let [w, x, y, z] = q.map(|c| c / n);
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// Every point scaled by `factor` and rotated by `rotation` (about the origin).
fn transform(points: &mut [[f64; 3]], factor: f64, rotation: &[[f64; 3]; 3]) {
    for p in points {
        let q = *p;
        *p = std::array::from_fn(|i| factor * (rotation[i][0] * q[0] + rotation[i][1] * q[1] + rotation[i][2] * q[2]));
    }
}

/// Loads shape `name` (X: `target` false, Y: true), makes it a cloud if asked, perturbs it
/// (noise, non-uniform sampling, outliers, scale, rotation) and prepares it; the evaluation maps
/// are computed from the clean positions.
fn prepare(
    ds: &Dataset,
    name: &str,
    target: bool,
    pt: &Perturb,
    k: usize,
    cache: Option<&BasisCache>,
) -> Result<StudyShape> {
    let Shape::Mesh(mesh) = Shape::load(ds.shape_path(name)?)? else {
        return Err(funcorr::Error::invalid("dataset", format!("{name} is not a mesh")));
    };
    let rng = |stream: &str| Rng::for_shape(name, stream, pt.seed);
    let perturbed = pt.perturbs(target);
    let sigma = if perturbed { pt.noise * diagonal(mesh.vertices()) } else { 0.0 };
    let factor = if pt.scale { random_scale(&mut rng("scale")) } else { 1.0 };
    let rotation = if pt.rotate {
        random_rotation(&mut rng("rotate"))
    } else {
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    };
    // Noise, then scale and rotation, on a copy of the clean positions.
    let finish = |clean: &[[f64; 3]], surface: usize| {
        let mut p = clean.to_vec();
        if sigma > 0.0 {
            add_noise(&mut p[..surface], sigma, &mut rng("noise"));
        }
        transform(&mut p, factor, &rotation);
        p
    };
    if !pt.is_cloud(target) {
        let moved = finish(mesh.vertices(), mesh.n_vertices());
        let shape = TriMesh::new(moved, mesh.faces().to_vec())?;
        let prepared = PreparedShape::new(Shape::Mesh(shape), LaplacianChoice::Auto, k, cache)?;
        return Ok(StudyShape { prepared, mesh, point_to_vertex: None, vertex_to_point: None, factor });
    }
    let mut clean: Vec<[f64; 3]> = if pt.resample == 0 {
        mesh.vertices().to_vec()
    } else if perturbed && pt.nonuniform {
        sample_nonuniform(&mesh, pt.resample, DENSITY_RATIO, &mut rng("sample"))?
    } else {
        mesh.sample_surface(pt.resample, 7)?
    };
    let surface = clean.len();
    if perturbed && pt.outliers > 0.0 {
        add_outliers(&mut clean, pt.outliers, &mut rng("outliers"));
    }
    let points = finish(&clean, surface);
    let cloud = PointSet::new(points.len(), 3, points.iter().flatten().copied().collect())?;
    let prepared = PreparedShape::new(Shape::Points(cloud), LaplacianChoice::Auto, k, cache)?;
    let p2v = nearest(mesh.vertices(), &clean);
    let v2p = nearest(&clean[..surface], mesh.vertices());
    Ok(StudyShape { prepared, mesh, point_to_vertex: Some(p2v), vertex_to_point: Some(v2p), factor })
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let ds = Dataset::open(Path::new(&args[0]))?;
    let all_pairs = ds.pairs(None)?;
    let pairs: Vec<(String, String)> = if let Some((a, b)) = args[1].split_once(':') {
        let (start, end): (usize, usize) = (a.parse().unwrap(), b.parse().unwrap());
        all_pairs.into_iter().skip(start).take(end - start).collect()
    } else {
        std::fs::read_to_string(&args[1])
            .expect("pair file")
            .lines()
            .filter_map(|l| {
                l.split_once(char::is_whitespace).map(|(a, b)| (a.trim().to_string(), b.trim().to_string()))
            })
            .collect()
    };
    let variants: Vec<Variant> = args[2].split(';').filter(|s| !s.is_empty()).map(Variant::parse).collect();
    let env = |k: &str| std::env::var(k).ok();
    let kbasis: usize = env("KBASIS").map(|s| s.parse().unwrap()).unwrap_or(200);
    let pt = Perturb::from_env();
    let perturb = pt.describe();
    let cache = BasisCache::default_dir().map(BasisCache::new);
    let t = Instant::now();
    // (name, is_target) for every shape needed.
    let mut needed: Vec<(String, bool)> =
        pairs.iter().flat_map(|(x, y)| [(x.clone(), false), (y.clone(), true)]).collect();
    needed.sort();
    needed.dedup();
    let shapes: Vec<((String, bool), StudyShape)> = needed
        .par_iter()
        .map(|(n, target)| {
            let s = prepare(&ds, n, *target, &pt, kbasis, cache.as_ref()).unwrap_or_else(|e| panic!("{n}: {e}"));
            ((n.clone(), *target), s)
        })
        .collect();
    eprintln!("{} shapes prepared in {:.1} s", shapes.len(), t.elapsed().as_secs_f64());
    let get = |n: &str, target: bool| &shapes.iter().find(|s| s.0 .0 == n && s.0 .1 == target).expect("prepared").1;
    let out = Mutex::new(std::io::stdout());
    pairs.par_iter().for_each(|(xn, yn)| {
        let (x, y) = (get(xn, false), get(yn, true));
        let (n, m) = (x.mesh.n_vertices(), y.mesh.n_vertices());
        let gt = ds.ground_truth(xn, yn, n, m, true).expect("ground truth");
        let geo = ExactGeodesics::new(&y.mesh).expect("geodesics");
        let sqrt_area = y.mesh.total_area().sqrt();
        // Mean error ×100 of a map from X's points to Y's points, direct and symmetric.
        let score = |map: &[usize]| -> (f64, f64) {
            let image = |i: usize| {
                let xi = x.vertex_to_point.as_ref().map_or(i, |v| v[i]);
                let j = map[xi];
                y.point_to_vertex.as_ref().map_or(j, |p| p[j])
            };
            let to = |truth: &[usize]| -> Vec<(usize, usize)> { truth.iter().zip(&gt.x).map(|(&t, &i)| (t, image(i))).collect() };
            let direct = geo.pair_distances(&to(&gt.y)).expect("distances");
            let mirrored = geo.pair_distances_capped(&to(gt.y_sym.as_ref().expect("sym")), &direct).expect("distances");
            let k = direct.len() as f64;
            (
                100.0 * direct.iter().sum::<f64>() / k / sqrt_area,
                100.0 * direct.iter().zip(&mirrored).map(|(a, b)| a.min(*b)).sum::<f64>() / k / sqrt_area,
            )
        };
        for v in &variants {
            let t = Instant::now();
            // Ground-truth landmarks, moved to the cloud points of the vertices.
            let lm_pairs: Vec<(usize, usize)> = if v.lm > 0 {
                let to_x = |i: usize| x.vertex_to_point.as_ref().map_or(i, |p| p[i]);
                let to_y = |j: usize| y.vertex_to_point.as_ref().map_or(j, |p| p[j]);
                pick_landmarks(&x.mesh, &gt.x, &gt.y, v.lm, v.lm_seed).into_iter().map(|(i, j)| (to_x(i), to_y(j))).collect()
            } else {
                Vec::new()
            };
            let run = || -> Result<matching::MatchResult> {
                let (f, g) = (wks(&x.prepared, v)?, wks(&y.prepared, v)?);
                let mut opts = v.opts.clone();
                opts.axiomatic.landmarks.pairs = lm_pairs.clone();
                matching::run(&x.prepared, &y.prepared, &f, &g, &opts)
            };
            // LMRES=1: the map's landmark-distance residual, mean over X's vertices and the
            // landmarks of |d_X(x, a_l) − d_Y(π(x), b_l)| (edge-graph geodesics, unit area).
            let lm_residual = |map: &[usize]| -> Option<f64> {
                if lm_pairs.is_empty() || std::env::var("LMRES").is_err() {
                    return None;
                }
                let (tx, ty) = (x.prepared.triangles()?, y.prepared.triangles()?);
                let (gx, gy) = (GraphGeodesics::mesh_edges(tx).ok()?, GraphGeodesics::mesh_edges(ty).ok()?);
                let mut sum = 0.0;
                for &(a, b) in &lm_pairs {
                    let (dx, dy) = (gx.distances_from_vertex(a).ok()?, gy.distances_from_vertex(b).ok()?);
                    sum += (0..map.len()).map(|i| (dx[i] - dy[map[i]]).abs()).sum::<f64>() / map.len() as f64;
                }
                Some(sum / lm_pairs.len() as f64)
            };
            let line = match run() {
                Ok(r) => {
                    let secs = t.elapsed().as_secs_f64();
                    let (d, s) = score(&r.map_xy);
                    let (xp, yp) = (&x.prepared, &y.prepared);
                    let scale = (yp.basis.mass.iter().sum::<f64>() / xp.basis.mass.iter().sum::<f64>()).sqrt();
                    let (agree, dist) = match (xp.triangles(), yp.positions(), yp.normals()) {
                        (Some(tx), Some(py), Some(ny)) => (
                            refine::orientation_agreement(tx, py, ny, &r.map_xy).unwrap_or(f64::NAN),
                            refine::metric_distortion(tx, py, scale, &r.map_xy).unwrap_or(f64::NAN),
                        ),
                        _ => (f64::NAN, f64::NAN),
                    };
                    let chosen = r.candidates.as_ref().map_or(0, |(c, i)| c[*i].k);
                    let search = match (&r.correction, &r.candidates) {
                        (Some(c), Some((cands, i))) => format!(
                            "{{\"moved\":{},\"rounds\":{},\"start\":{:.4},\"end\":{:.4},\"corrected\":{},\"from_landmarks\":{},\"landmark_error\":{}}}",
                            c.moved,
                            c.trace.len() - 1,
                            c.trace[0],
                            c.trace.iter().copied().fold(f64::INFINITY, f64::min),
                            cands[*i].corrected_from.is_some(),
                            cands[*i].from_landmarks,
                            // JSON has no NaN: no landmarks, no error (null).
                            match cands[*i].landmark_error {
                                e if e.is_finite() => format!("{e:.4}"),
                                _ => "null".to_string(),
                            }
                        ),
                        _ => "null".to_string(),
                    };
                    let stages: Vec<String> = r.stages.iter().map(|(n, s)| format!("\"{n}\":{s:.3}")).collect();
                    let mut extra = String::new();
                    if v.lm > 0 {
                        extra += &format!(",\"landmarks\":{},\"lmseed\":{}", v.lm, v.lm_seed);
                    }
                    if let Some(res) = lm_residual(&r.map_xy) {
                        extra += &format!(",\"lmres\":{res:.5}");
                    }
                    if !perturb.is_empty() {
                        extra += &format!(",\"perturb\":\"{perturb}\"");
                    }
                    if pt.scale {
                        extra += &format!(",\"scale_x\":{:.6e},\"scale_y\":{:.6e}", x.factor, y.factor);
                    }
                    for (side, p) in [("x", xp), ("y", yp)] {
                        if let Some(d) = p.denoising() {
                            extra += &format!(",\"denoised_{side}\":{}", serde_json::to_string(d).expect("json"));
                        }
                    }
                    format!(
                        "{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"variant\":\"{}\",\"direct\":{d:.3},\"sym\":{s:.3},\"seconds\":{secs:.3},\"agree\":{agree:.3},\"distortion\":{dist:.4},\"k\":{chosen},\"search\":{search},\"stages\":{{{}}}{extra}}}",
                        v.name,
                        stages.join(",")
                    )
                }
                Err(e) => format!("{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"variant\":\"{}\",\"error\":\"{e}\"}}", v.name),
            };
            let mut o = out.lock().unwrap();
            writeln!(o, "{line}").unwrap();
            o.flush().unwrap();
        }
    });
    Ok(())
}
