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
//! `zs=S` its step, `ns=N` its samples, `zp=K` probe size, `bij=W` the bijective ZoomOut with
//! bijectivity weight W instead of ZoomOut, `pol=N` rounds of the bijective polish (0 none),
//! `bs=N` samples of the basin search (0: none, candidates by edge distortion), `br=N` its
//! correction rounds, `banch=N` its anchors on Y.
//!
//! Point clouds: `CLOUD=y` (Y given as its vertices), `CLOUD=both`; `RESAMPLE=N` draws N points
//! uniformly on the surface instead (vertices not shared). Errors are then measured on Y's mesh
//! through the nearest vertex of each cloud point, and the template points of X are moved to the
//! nearest cloud point. `KBASIS` sets the eigenpairs per shape (default 200).

use std::io::Write;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use funcorr::benchmark::Dataset;
use funcorr::descriptors::{signatures as sig, Descriptors};
use funcorr::fmap::energy::{Mask, Orientation};
use funcorr::geodesic::ExactGeodesics;
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
}

impl Variant {
    fn parse(spec: &str) -> Variant {
        let (name, rest) = spec.split_once(':').unwrap_or((spec, ""));
        let mut opts = MatchOptions { method: Method::Axiomatic, ..MatchOptions::default() };
        let (mut nd, mut kd, mut ss) = (100, 128, 2);
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
                "bij" => a.bijective = f(),
                "cp" => a.continue_probe = val == "1",
                "pol" => a.polish = u(),
                "bs" => a.search.samples = u(),
                "br" => a.search.rounds = u(),
                "banch" => a.search.anchors = u(),
                "nd" => nd = u(),
                "kd" => kd = u(),
                "ss" => ss = u(),
                _ => panic!("unknown key {k}"),
            }
        }
        Variant { name: name.to_string(), opts, nd, kd, ss }
    }
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

/// A shape of the study: the prepared shape (mesh or cloud), its mesh for evaluation, and for
/// clouds the nearest mesh vertex of every cloud point and the nearest cloud point of every
/// mesh vertex.
struct StudyShape {
    prepared: PreparedShape,
    mesh: TriMesh,
    point_to_vertex: Option<Vec<usize>>,
    vertex_to_point: Option<Vec<usize>>,
}

fn nearest(reference: &[[f64; 3]], query: &[[f64; 3]]) -> Vec<usize> {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(reference);
    query.iter().map(|q| tree.nearest_one::<kiddo::SquaredEuclidean>(q).item as usize).collect()
}

fn prepare(
    ds: &Dataset,
    name: &str,
    as_cloud: bool,
    resample: usize,
    k: usize,
    cache: Option<&BasisCache>,
) -> Result<StudyShape> {
    let Shape::Mesh(mesh) = Shape::load(ds.shape_path(name)?)? else {
        return Err(funcorr::Error::invalid("dataset", format!("{name} is not a mesh")));
    };
    if !as_cloud {
        let prepared = PreparedShape::new(Shape::Mesh(mesh.clone()), LaplacianChoice::Auto, k, cache)?;
        return Ok(StudyShape { prepared, mesh, point_to_vertex: None, vertex_to_point: None });
    }
    let points: Vec<[f64; 3]> = if resample > 0 { mesh.sample_surface(resample, 7)? } else { mesh.vertices().to_vec() };
    let cloud = PointSet::new(points.len(), 3, points.iter().flatten().copied().collect())?;
    let prepared = PreparedShape::new(Shape::Points(cloud), LaplacianChoice::Auto, k, cache)?;
    let p2v = nearest(mesh.vertices(), &points);
    let v2p = nearest(&points, mesh.vertices());
    Ok(StudyShape { prepared, mesh, point_to_vertex: Some(p2v), vertex_to_point: Some(v2p) })
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
    let cloud = env("CLOUD").unwrap_or_default();
    let resample: usize = env("RESAMPLE").map(|s| s.parse().unwrap()).unwrap_or(0);
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
            let as_cloud = cloud == "both" || (cloud == "y" && *target);
            let s = prepare(&ds, n, as_cloud, resample, kbasis, cache.as_ref()).unwrap_or_else(|e| panic!("{n}: {e}"));
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
            let run = || -> Result<matching::MatchResult> {
                let (f, g) = (wks(&x.prepared, v)?, wks(&y.prepared, v)?);
                matching::run_prepared(&x.prepared, &y.prepared, &f, &g, &v.opts)
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
                            "{{\"moved\":{},\"rounds\":{},\"start\":{:.4},\"end\":{:.4},\"corrected\":{}}}",
                            c.moved,
                            c.trace.len() - 1,
                            c.trace[0],
                            c.trace.iter().copied().fold(f64::INFINITY, f64::min),
                            cands[*i].corrected_from.is_some()
                        ),
                        _ => "null".to_string(),
                    };
                    let stages: Vec<String> = r.stages.iter().map(|(n, s)| format!("\"{n}\":{s:.3}")).collect();
                    format!(
                        "{{\"x\":\"{xn}\",\"y\":\"{yn}\",\"variant\":\"{}\",\"direct\":{d:.3},\"sym\":{s:.3},\"seconds\":{secs:.3},\"agree\":{agree:.3},\"distortion\":{dist:.4},\"k\":{chosen},\"search\":{search},\"stages\":{{{}}}}}",
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
