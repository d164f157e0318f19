//! Partial → full matching on a partial data set (issue 28): every pair of `pairs.txt` (a part
//! `NAME_cut` and a whole target) matched by `funcorr match`'s pipeline with the partial path,
//! scored on the template points present in the part (`.vts` entries ≠ 0) with exact geodesics on
//! Y (error / √area(Y) ×100, directly and with the left–right flip forgiven), and the coverage
//! of Y checked against the truth; one JSON line per pair on stdout.
//!
//! ```sh
//! cargo run --release --example partial_study -- ../shared/data/faust_r_partial 0:97 > runs/faust_partial.jsonl
//! cargo run --release --example partial_study -- ../shared/data/tosca_r_partial 0:109 > runs/tosca_partial.jsonl
//! MODE=auto cargo run --release --example partial_study -- ../shared/data/faust_r_partial 0:10
//! DETECT=1 cargo run --release --example partial_study -- ../shared/data/faust_r 0:97   # detection only
//! ```
//! `MODE=always|auto|never` (default `always`: `--partial`); `SLOPE=s` the slope of the
//! rectangular maps (default 1); `SEEDED=n` the sample maps from distances alone probed as
//! challengers of the spectral choice (default 4; 0: none); `METRIC_ANCHORS=a` the anchors of the metric polish (default 128; 0: off); `COVERED=0` no refinement on the covered region (step 7); `FINALISTS=0` no second finalist (step 8);
//! `SCALE=area|distances` the area ratio as it is or estimated from distance-only maps
//! (default: from the heat kernels, `PartialScale::Heat`);
//! `RATIO=truth` the true covered fraction given as the area ratio (`PartialOptions::ratio`,
//! `--partial-ratio`: what a user who knows it gets); `LM=k` k landmarks from the ground truth
//! (`--landmarks`; template points far apart on X, `landmarks_of`; with `LMDROP=1` those the
//! landmark check names as suspects are dropped and the pair is run again); `KBASIS=k` the eigenpairs per shape (default 200);
//! `CLOUD=x` the parts as point clouds of their vertices. `UNITS=1` every shape in its own unit
//! (×10^u, u ∈ [−3, 3] from a hash of its name). `STRIDE=s` every s-th pair of the range;
//! `ONLY=i,j,…` these pairs of pairs.txt (0-based) instead. `DIAG=1` adds `diag`: the
//! distortion of the result and of the truth on the search's samples at the used and the true
//! ratio, their orientation, the chosen candidate and every candidate as [k, distortion,
//! orientation, data misfit, corrected distortion, corrected orientation, kind (0 fit, 1
//! corrected, 2 seeded), mean error of its sample map (as `direct`), dominance], and `map_ratio`:
//! the area ratio read off the result's and the truth's sample maps (`partial::ratio_of_map`).
//! Every line also has `finalists` (step 8, a contested choice: [candidate, final orientation,
//! chosen (0/1), error of its final map], the first choice first) and `minima` (the heat
//! energy's near-equal minima of the ratio).
//! `SCALE_ONLY=1`: no matching, the heat-kernel ratio against the covered fraction (`CURVE=1`
//! adds the energy on its coarse grid). `DETECT=1`: no matching, the detection of every shape of the
//! pairs against the pair's other shape (for whole data sets: none should be detected).
//!
//! Coverage truth: a vertex of Y is covered when its nearest template point of Y (Euclidean,
//! among the vertices of `Y.vts`) is present in X; IoU of that set and the vertices of Y whose
//! confidence is ≥ ½.

use std::io::Write;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use funcorr::benchmark::Dataset;
use funcorr::descriptors::signatures::WksRecipe;
use funcorr::geodesic::ExactGeodesics;
use funcorr::matching::partial::{self, PartialMode};
use funcorr::matching::{self, MatchOptions};
use funcorr::prepared::LaplacianChoice;
use funcorr::shape::Shape;
use funcorr::spectral::BasisCache;
use funcorr::{PreparedShape, Result};
use rayon::prelude::*;

/// 1-based template file, 0 = absent → None.
fn template(path: &Path) -> Vec<Option<usize>> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: usize = l.trim().parse().expect("an index");
            v.checked_sub(1)
        })
        .collect()
}

/// For every vertex of Y, whether X covers it: its nearest template point of Y (Euclidean) is
/// present in X. `tx`, `ty`: the template's vertices on X and on Y ([`template`]).
fn covered_truth(ym: &funcorr::shape::TriMesh, tx: &[Option<usize>], ty: &[Option<usize>]) -> Vec<bool> {
    let pv = ym.vertices();
    let tpl: Vec<(usize, bool)> = (0..ty.len()).filter_map(|i| ty[i].map(|v| (v, tx[i].is_some()))).collect();
    let tpos: Vec<[f64; 3]> = tpl.iter().map(|&(v, _)| pv[v]).collect();
    funcorr::spatial::nearest3(&tpos, pv).iter().map(|&t| tpl[t].1).collect()
}

/// The share of Y's area (vertex weights `mass`) that `covered` marks: the true area ratio.
fn covered_fraction(covered: &[bool], mass: &[f64]) -> f64 {
    (0..covered.len()).filter(|&v| covered[v]).map(|v| mass[v]).sum::<f64>() / mass.iter().sum::<f64>()
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = Path::new(&args[0]);
    let ds = Dataset::open(dir)?;
    let all = ds.pairs(None)?;
    let (a, b) = args[1].split_once(':').expect("start:end");
    let (start, end): (usize, usize) = (a.parse().unwrap(), b.parse().unwrap());
    // STRIDE=s: every s-th pair of the range (default 1).
    let stride: usize = std::env::var("STRIDE").map_or(1, |s| s.parse().expect("STRIDE"));
    let mut pairs: Vec<(String, String)> =
        all.iter().skip(start).take(end - start).step_by(stride.max(1)).cloned().collect();
    // ONLY=i,j,…: these pairs of pairs.txt (0-based) instead of the range.
    if let Ok(s) = std::env::var("ONLY") {
        pairs = s.split(',').map(|i| all[i.trim().parse::<usize>().expect("ONLY")].clone()).collect();
    }
    let mode = match std::env::var("MODE").as_deref() {
        Ok("auto") => PartialMode::Auto,
        Ok("never") => PartialMode::Never,
        _ => PartialMode::Always,
    };
    let mut opts = MatchOptions::default();
    opts.partial.mode = mode;
    if let Ok(s) = std::env::var("SLOPE") {
        opts.partial.slope = s.parse().expect("SLOPE");
    }
    match std::env::var("SCALE").as_deref() {
        Ok("area") => opts.partial.scale = partial::PartialScale::Area,
        Ok("distances") => opts.partial.scale = partial::PartialScale::Distances,
        _ => {}
    }
    if let Ok(s) = std::env::var("SEEDED") {
        opts.partial.seeded = s.parse().expect("SEEDED");
    }
    if let Ok(s) = std::env::var("METRIC_ANCHORS") {
        opts.partial.metric_anchors = s.parse().expect("METRIC_ANCHORS");
    }
    if let Ok(s) = std::env::var("COVERED") {
        opts.partial.covered = s != "0";
    }
    if let Ok(s) = std::env::var("FINALISTS") {
        opts.partial.finalists = s != "0";
    }
    let detect_only = std::env::var("DETECT").is_ok();
    // The bases of `funcorr match` (the detection's heat kernels need them as the pipeline has
    // them); `KBASIS` sets another size.
    let k: usize = std::env::var("KBASIS").map(|s| s.parse().expect("KBASIS")).unwrap_or(200);
    let cache = BasisCache::default_dir().map(BasisCache::new);
    let mut names: Vec<String> = pairs.iter().flat_map(|(x, y)| [x.clone(), y.clone()]).collect();
    names.sort();
    names.dedup();
    let t = Instant::now();
    let shapes: Vec<(String, PreparedShape)> = names
        .par_iter()
        .map(|n| {
            let mut s = Shape::load(ds.shape_path(n).expect("shape"))?;
            // UNITS=1: every shape in its own unit (×10^u, u ∈ [−3, 3] from its name).
            if std::env::var("UNITS").is_ok() {
                if let Shape::Mesh(m) = &s {
                    let f = unit_factor(n);
                    let v: Vec<[f64; 3]> = m.vertices().iter().map(|p| p.map(|c| c * f)).collect();
                    s = Shape::Mesh(funcorr::shape::TriMesh::new(v, m.faces().to_vec())?);
                }
            }
            // CLOUD=x: the parts (X, `*_cut`) as point clouds of their vertices (with `MODE`
            // always, the default: a cloud has no boundary to detect).
            if std::env::var("CLOUD").as_deref() == Ok("x") && n.ends_with("_cut") {
                if let Shape::Mesh(m) = &s {
                    let flat: Vec<f64> = m.vertices().iter().flatten().copied().collect();
                    s = Shape::Points(funcorr::shape::PointSet::new(m.n_vertices(), 3, flat)?);
                }
            }
            Ok((n.clone(), PreparedShape::new(s, LaplacianChoice::Auto, k, cache.as_ref())?))
        })
        .collect::<Result<_>>()?;
    eprintln!("{} shapes prepared in {:.1} s", shapes.len(), t.elapsed().as_secs_f64());
    let get = |n: &str| &shapes.iter().find(|s| s.0 == n).expect("prepared").1;
    let out = Mutex::new(std::io::stdout());
    let print = |line: String| {
        let mut o = out.lock().unwrap();
        writeln!(o, "{line}").unwrap();
        o.flush().unwrap();
    };
    if detect_only {
        let auto = partial::PartialOptions::default();
        pairs.par_iter().for_each(|(xn, yn)| {
            let (x, y) = (get(xn), get(yn));
            for (a, b, an, bn) in [(x, y, xn, yn), (y, x, yn, xn)] {
                let d = partial::detect(a, b, &auto);
                print(format!(
                    "{{\"x\":\"{an}\",\"y\":\"{bn}\",\"partial\":{},\"ratio\":{:.4},\"heat_ratio\":{},\"boundary\":{:?},\"reason\":\"{}\"}}",
                    d.partial,
                    d.area_ratio,
                    d.heat_ratio.map_or("null".to_string(), |r| format!("{r:.4}")),
                    d.boundary_x,
                    d.reason
                ));
            }
        });
        return Ok(());
    }
    pairs.par_iter().for_each(|(xn, yn)| {
        let (x, y) = (get(xn), get(yn));
        let Shape::Mesh(ym) = &y.shape else { panic!("Y must be a mesh") };
        let tx = template(&dir.join(format!("corres/{xn}.vts")));
        let ty = template(&dir.join(format!("corres/{yn}.vts")));
        let ts = template(&dir.join(format!("corres/{yn}.sym.vts")));
        let t = Instant::now();
        if std::env::var("SCALE_ONLY").is_ok() {
            // The heat-kernel scale estimate against the true covered fraction.
            let true_ratio = covered_fraction(&covered_truth(ym, &tx, &ty), &y.basis.mass);
            let est = partial::part_heat_scale(x, y, (0.1, 1.2), Some(x.area / y.area));
            let secs = t.elapsed().as_secs_f64();
            // CURVE=1: the coarse grid of E(r) (the energy landscape of the estimate).
            let curve: Vec<String> = match (&est, std::env::var("CURVE").is_ok()) {
                (Ok(e), true) => e.curve.iter().map(|(r, v)| format!("[{r:.4},{v:.4e}]")).collect(),
                _ => Vec::new(),
            };
            print(format!(
                "{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"area_ratio\":{:.4},\"true_ratio\":{true_ratio:.4},\"heat\":{:.4},\"energy\":{:.5},\"e0\":{:.5},\"seconds\":{secs:.2},\"curve\":[{}]}}",
                x.area / y.area,
                est.as_ref().map_or(f64::NAN, |e| e.ratio),
                est.as_ref().map_or(f64::NAN, |e| e.energy),
                est.as_ref().ok().and_then(|e| e.prior_energy).unwrap_or(f64::NAN),
                curve.join(",")
            ));
            return;
        }
        let run = || -> Result<matching::MatchResult> {
            let det = partial::detect(x, y, &opts.partial);
            let mut opts = opts.clone();
            if std::env::var("RATIO").is_ok_and(|v| v == "truth") {
                // What a user who knows the covered fraction gets (`--partial-ratio`).
                opts.partial.ratio = Some(covered_fraction(&covered_truth(ym, &tx, &ty), &y.basis.mass));
            }
            if let Ok(k) = std::env::var("LM") {
                opts.axiomatic.landmarks.pairs = landmarks_of(x, &tx, &ty, k.parse().expect("LM"));
            }
            let (f, g) = if det.partial {
                opts.partial.wks = Some(WksRecipe::default());
                partial::pair_wks(x, y, &WksRecipe::default())?
            } else {
                let r = WksRecipe::default();
                (
                    funcorr::descriptors::signatures::wks_recipe(&x.basis, &r)?,
                    funcorr::descriptors::signatures::wks_recipe(&y.basis, &r)?,
                )
            };
            let r = matching::run(x, y, &f, &g, &opts)?;
            // `LMDROP=1`: the landmarks the check names as suspects dropped, and the pair run
            // again with the others (what a user who drops them gets).
            match r.landmark_check.as_ref().filter(|c| !c.suspects.is_empty() && std::env::var("LMDROP").is_ok()) {
                Some(c) => {
                    let keep = |i: &usize| !c.suspects.contains(i);
                    let pairs = &mut opts.axiomatic.landmarks.pairs;
                    *pairs = (0..pairs.len()).filter(keep).map(|i| pairs[i]).collect();
                    matching::run(x, y, &f, &g, &opts)
                }
                None => Ok(r),
            }
        };
        let line = match run() {
            Ok(r) => {
                let secs = t.elapsed().as_secs_f64();
                let geo = ExactGeodesics::new(ym).expect("geodesics");
                let sqrt_area = ym.total_area().sqrt();
                let present: Vec<usize> = (0..tx.len()).filter(|&i| tx[i].is_some() && ty[i].is_some()).collect();
                // (truth, image) per template point present in X, for a map X → Y.
                let pairs_for = |truth: &[Option<usize>], map_xy: &[usize]| -> Vec<(usize, usize)> {
                    present.iter().map(|&i| (truth[i].unwrap_or(0), map_xy[tx[i].unwrap()])).collect()
                };
                let pairs_of = |truth: &[Option<usize>]| pairs_for(truth, &r.map_xy);
                let direct = geo.pair_distances(&pairs_of(&ty)).expect("distances");
                let mirrored = geo.pair_distances_capped(&pairs_of(&ts), &direct).expect("distances");
                let kk = direct.len() as f64;
                let d = 100.0 * direct.iter().sum::<f64>() / kk / sqrt_area;
                let s = 100.0 * direct.iter().zip(&mirrored).map(|(a, b)| a.min(*b)).sum::<f64>() / kk / sqrt_area;
                // Coverage truth through Y's template points.
                let truth = covered_truth(ym, &tx, &ty);
                let (iou, det) = match (&r.coverage, &r.partial) {
                    (Some(c), Some(det)) => {
                        let inter = (0..c.len()).filter(|&v| c[v] >= 0.5 && truth[v]).count();
                        let uni = (0..c.len()).filter(|&v| c[v] >= 0.5 || truth[v]).count();
                        (inter as f64 / uni.max(1) as f64, det.partial)
                    }
                    (_, det) => (f64::NAN, det.as_ref().is_some_and(|d| d.partial)),
                };
                // The true area ratio (the area of Y that X covers / area(Y)), and with DIAG the
                // search's distortion (X's distances scaled by the used and the true ratio) of
                // the result and of the truth on the search's samples: which of the score and
                // the search fails on a pair.
                let true_ratio = covered_fraction(&truth, &y.basis.mass);
                let diag = if std::env::var("DIAG").is_ok() {
                    let (tx_, ty_) = (x.triangles().unwrap(), y.triangles().unwrap());
                    let sx = funcorr::matching::search::SampleDistances::new(
                        tx_,
                        &x.basis.mass,
                        &funcorr::geodesic::GraphGeodesics::mesh_edges(tx_).unwrap(),
                        200,
                    )
                    .unwrap();
                    let sy = funcorr::matching::search::SampleDistances::new(
                        ty_,
                        &y.basis.mass,
                        &funcorr::geodesic::GraphGeodesics::mesh_edges(ty_).unwrap(),
                        500,
                    )
                    .unwrap();
                    // Truth of a vertex of X: the Y vertex of its nearest present template point.
                    let xt: Vec<(usize, usize)> = present.iter().map(|&i| (tx[i].unwrap(), ty[i].unwrap())).collect();
                    let xpos = x.positions().unwrap();
                    let tpos: Vec<[f64; 3]> = xt.iter().map(|&(v, _)| xpos[v]).collect();
                    let near = funcorr::spatial::nearest3(&tpos, xpos);
                    let xs = &sx.samples.vertices;
                    let true_images: Vec<usize> = xs.iter().map(|&v| xt[near[v]].1).collect();
                    let images: Vec<usize> = xs.iter().map(|&v| r.map_xy[v]).collect();
                    let used = r.partial.as_ref().and_then(|d| d.used_ratio).unwrap_or(1.0);
                    let scaled = |q: f64| {
                        let mut s2 = sx.clone();
                        s2.distances = &s2.distances * faer::Scale(q.sqrt());
                        s2
                    };
                    let (su, st) = (scaled(used), scaled(true_ratio));
                    use funcorr::matching::search::distortion as dist;
                    let nb = funcorr::matching::search::sample_neighbours(&sx, 8);
                    let (px, nx, py, ny) =
                        (x.positions().unwrap(), x.normals().unwrap(), y.positions().unwrap(), y.normals().unwrap());
                    let or = |im: &[usize]| funcorr::matching::search::orientation(px, nx, py, ny, xs, im, &nb);
                    let cands: Vec<String> = r.candidates.as_ref().map_or(Vec::new(), |(c, _)| {
                        c.iter()
                            .map(|c| {
                                let err = if c.sample_images.len() == true_images.len() {
                                    let pr: Vec<(usize, usize)> =
                                        true_images.iter().zip(&c.sample_images).map(|(&a, &b)| (a, b)).collect();
                                    let d = geo.pair_distances(&pr).expect("distances");
                                    100.0 * d.iter().sum::<f64>() / d.len() as f64 / sqrt_area
                                } else {
                                    f64::NAN
                                };
                                let ty = if c.seeded.is_some() { 2 } else if c.corrected_from.is_some() { 1 } else { 0 };
                                format!(
                                    "[{},{:.4},{:.3},{:.4},{:.4},{:.3},{ty},{err:.1},{:.2}]",
                                    c.k,
                                    c.distortion,
                                    c.orientation,
                                    c.data_misfit,
                                    c.corrected_distortion,
                                    c.corrected_orientation,
                                    c.dominance
                                )
                            })
                            .collect()
                    });
                    format!(
                        ",\"diag\":{{\"used\":[{:.4},{:.4}],\"true\":[{:.4},{:.4}],\"orient\":[{:.3},{:.3}],\"map_ratio\":[{:.4},{:.4}],\"chosen\":{},\"cands\":[{}]}}",
                        dist(&su, &sy, &images),
                        dist(&su, &sy, &true_images),
                        dist(&st, &sy, &images),
                        dist(&st, &sy, &true_images),
                        or(&images),
                        or(&true_images),
                        matching::partial::ratio_of_map(&sx, &sy, &images).unwrap_or(f64::NAN),
                        matching::partial::ratio_of_map(&sx, &sy, &true_images).unwrap_or(f64::NAN),
                        r.candidates.as_ref().map_or(0, |(_, i)| *i),
                        cands.join(",")
                    )
                } else {
                    String::new()
                };
                let chosen = r.candidates.as_ref().map_or(0, |(c, i)| c[*i].k);
                // The metric polish: seconds and vertices moved per round.
                let polish = match r.partial.as_ref().and_then(|d| d.metric_polish.as_ref()) {
                    Some(p) => {
                        let t = r.stages.iter().find(|(s, _)| s == "metric polish").map_or(0.0, |(_, t)| *t);
                        format!("{{\"seconds\":{t:.3},\"moved\":{:?},\"metric_rounds\":{}}}", p.moved, p.metric_rounds)
                    }
                    None => "null".to_string(),
                };
                let corrected = r.candidates.as_ref().is_some_and(|(c, i)| c[*i].corrected_from.is_some());
                // Both maps of a contested choice: [candidate, orientation, chosen, error].
                let finalists: Vec<String> = r
                    .partial
                    .as_ref()
                    .map_or(&[][..], |d| &d.finalists[..])
                    .iter()
                    .map(|f| {
                        let e = geo.pair_distances(&pairs_for(&ty, &f.map_xy)).expect("distances");
                        let e = 100.0 * e.iter().sum::<f64>() / e.len().max(1) as f64 / sqrt_area;
                        format!("[{},{:.3},{},{e:.3}]", f.candidate, f.orientation, u8::from(f.chosen))
                    })
                    .collect();
                // With landmarks: how well they agree (discrepancy per landmark, suspects).
                let lm_check = r.landmark_check.as_ref().map_or(String::new(), |c| {
                    format!(",\"landmark_check\":{{\"discrepancy\":{:?},\"suspects\":{:?}}}", c.discrepancy, c.suspects)
                });
                format!(
                    "{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"n\":{},\"ratio\":{:.3},\"partial\":{det},\"direct\":{d:.3},\"sym\":{s:.3},\"iou\":{iou:.3},\"points\":{},\"used\":{:.3},\"k\":{chosen},\"corrected\":{corrected},\"C\":[{},{}],\"true_ratio\":{true_ratio:.3},\"seconds\":{secs:.2},\"polish\":{polish},\"finalists\":[{}],\"minima\":{:?}{lm_check}{diag}}}",
                    x.n(),
                    x.area / y.area,
                    present.len(),
                    r.partial.as_ref().and_then(|d| d.used_ratio).unwrap_or(f64::NAN),
                    r.c.nrows(),
                    r.c.ncols(),
                    finalists.join(","),
                    r.partial.as_ref().and_then(|d| d.heat_minima.clone()).unwrap_or_default()
                )
            }
            Err(e) => format!("{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"error\":\"{e}\"}}"),
        };
        print(line);
    });
    Ok(())
}

/// `UNITS=1`: the factor 10^u of a shape, u uniform in [−3, 3] from a hash of its name (FNV-1a),
/// the same in every run.
fn unit_factor(name: &str) -> f64 {
    let h = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    10f64.powf(6.0 * (h % 1_000_003) as f64 / 1_000_003.0 - 3.0)
}

/// `LM=k`: k landmarks from the ground truth, (vertex of X, vertex of Y) of template points present
/// in both, spread over X by farthest points in space from the first present one (what a user
/// who clicks k points far apart gives).
fn landmarks_of(x: &PreparedShape, tx: &[Option<usize>], ty: &[Option<usize>], k: usize) -> Vec<(usize, usize)> {
    let present: Vec<(usize, usize)> = tx.iter().zip(ty).filter_map(|(a, b)| Some(((*a)?, (*b)?))).collect();
    let p = x.positions().expect("positions");
    let d2 = |a: usize, b: usize| (0..3).map(|c| (p[a][c] - p[b][c]).powi(2)).sum::<f64>();
    let mut pairs: Vec<(usize, usize)> = present.first().copied().into_iter().collect();
    while pairs.len() < k.min(present.len()) {
        let far = present
            .iter()
            .copied()
            .max_by(|a, b| {
                let da = pairs.iter().map(|q| d2(a.0, q.0)).fold(f64::INFINITY, f64::min);
                let db = pairs.iter().map(|q| d2(b.0, q.0)).fold(f64::INFINITY, f64::min);
                da.total_cmp(&db)
            })
            .expect("present");
        if pairs.iter().any(|q| q.0 == far.0) {
            break;
        }
        pairs.push(far);
    }
    pairs
}
