//! Completion vs the baselines on faust_r pairs (issue 4 experiments, see EXPERIMENTS.md).
//!
//! ```sh
//! cargo run --release --example completion_experiments -- DATA FIRST COUNT CONFIG[,CONFIG...]
//! ```
//! - DATA: `segments` (the provided `.seg.sym` segmentation of the pair), `merged4`, `merged3`
//!   (the provided segments merged into 4 or 3 groups: repeatedly the smallest segment into the
//!   neighbour it shares most edges with, on X, the same merge applied to Y), `persistence`
//!   (persistence segments of both shapes, matched by signature), `wks` (100 WKS), `rich`
//!   (localized WKS + HKM on the provided segments).
//! - FIRST, COUNT: which pairs of `pairs.txt` (0-based).
//! - CONFIG: see `config()` below, parts joined by `+`, e.g. `fmap+icp`, `comp`, `comp+mc=1e-3+icp`.
//!
//! Prints one line per (pair, config): mean hard error ×100 with symmetric flips allowed, the
//! fraction ≤ 0.05 and ≤ 0.10, the solver iterations and seconds. Exact geodesics (MMP). Bases
//! cached in `target/exp-cache`.
//! `$FAUST_R` overrides the data folder (default ../shared/data/faust_r).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use funcorr::completion::{Form, Init, Optimizer, Scaling};
use funcorr::descriptors::{self, persistence, signatures, Descriptors};
use funcorr::eval::{hard_errors, summarize, GroundTruth};
use funcorr::io::indices::{read_index_list_file, read_labels_file};
use funcorr::laplacian::{cotangent, Laplacian};
use funcorr::matching::{self, Extraction, MatchOptions, Method, Refine};
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{eigen_basis_cached, Basis, BasisCache, SpectralOptions};
use funcorr::{Error, Result};

struct Loaded {
    mesh: TriMesh,
    lap: Laplacian,
    basis: Basis,
}

fn load(dir: &Path, name: &str, cache: &BasisCache, k: usize) -> Result<Loaded> {
    let Shape::Mesh(mesh) = Shape::load(&dir.join(format!("{name}.off")))? else {
        return Err(Error::invalid("shape", format!("{name} is not a mesh")));
    };
    let lap = cotangent(&mesh)?;
    let (basis, _) = eigen_basis_cached(&lap, &SpectralOptions::new(k), Some(cache), None)?;
    Ok(Loaded { mesh, lap, basis })
}

/// Merges the segments of `lx` into `groups` groups by adjacency on X's mesh (smallest area
/// first into the neighbour it shares most edges with); returns the label map.
fn merge_map(mesh: &TriMesh, mass: &[f64], lx: &[u32], groups: usize) -> HashMap<u32, u32> {
    let mut map: HashMap<u32, u32> = lx.iter().map(|&l| (l, l)).collect();
    let find = |map: &HashMap<u32, u32>, mut l: u32| {
        while map[&l] != l {
            l = map[&l];
        }
        l
    };
    loop {
        let mut area: HashMap<u32, f64> = HashMap::new();
        for (i, &l) in lx.iter().enumerate() {
            *area.entry(find(&map, l)).or_default() += mass[i];
        }
        if area.len() <= groups {
            return lx.iter().map(|&l| (l, find(&map, l))).collect();
        }
        let smallest = *area.iter().min_by(|a, b| a.1.total_cmp(b.1).then(a.0.cmp(b.0))).unwrap().0;
        let mut shared: HashMap<u32, usize> = HashMap::new();
        for [a, b] in mesh.edges() {
            let (ga, gb) = (find(&map, lx[a as usize]), find(&map, lx[b as usize]));
            if ga != gb && (ga == smallest || gb == smallest) {
                *shared.entry(if ga == smallest { gb } else { ga }).or_default() += 1;
            }
        }
        let Some((&target, _)) = shared.iter().max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0))) else {
            return lx.iter().map(|&l| (l, find(&map, l))).collect();
        };
        map.insert(smallest, target);
    }
}

fn data(
    kind: &str,
    dir: &Path,
    (nx, x): (&str, &Loaded),
    (ny, y): (&str, &Loaded),
) -> Result<(Descriptors, Descriptors)> {
    let seg = |s: &str| dir.join(format!("segmentation/{nx}_{ny}.{s}.seg.sym"));
    let provided = || -> Result<(Vec<u32>, Vec<u32>)> {
        Ok((read_labels_file(&seg(nx), x.basis.n())?, read_labels_file(&seg(ny), y.basis.n())?))
    };
    let common = |la: &[u32], lb: &[u32]| -> Result<(Descriptors, Descriptors)> {
        let (fa, fb) = (descriptors::segments(la)?, descriptors::segments(lb)?);
        let names: Vec<String> = fa.names.iter().filter(|n| fb.names.contains(n)).cloned().collect();
        let pick = |d: &Descriptors| {
            let cols: Vec<usize> = names.iter().map(|c| d.names.iter().position(|n| n == c).unwrap()).collect();
            Descriptors::new(faer::Mat::from_fn(d.n(), cols.len(), |i, j| d.values[(i, cols[j])]), names.clone())
        };
        Ok((pick(&fa)?, pick(&fb)?))
    };
    match kind {
        "segments" => {
            let (a, b) = provided()?;
            common(&a, &b)
        }
        "merged4" | "merged3" => {
            let groups = if kind == "merged4" { 4 } else { 3 };
            let (a, b) = provided()?;
            let map = merge_map(&x.mesh, &x.basis.mass, &a, groups);
            let ma: Vec<u32> = a.iter().map(|l| map[l]).collect();
            let mb: Vec<u32> = b.iter().map(|l| *map.get(l).unwrap_or(l)).collect();
            common(&ma, &mb)
        }
        "persistence" => {
            let sx = persistence::segment(&x.mesh.edges(), &x.basis, persistence::DEFAULT_THRESHOLD)?;
            let sy = persistence::segment(&y.mesh.edges(), &y.basis, persistence::DEFAULT_THRESHOLD)?;
            let (f, g, _) = persistence::matched_segment_indicators(&sx.labels, &x.basis, &sy.labels, &y.basis)?;
            Ok((f, g))
        }
        "wks" => Ok((signatures::wks(&x.basis, 100, true)?, signatures::wks(&y.basis, 100, true)?)),
        "rich" => {
            let (a, b) = provided()?;
            let (fs, gs) = common(&a, &b)?;
            descriptors::rich(&x.basis, &y.basis, &fs, &gs, 100, 100)
        }
        _ => Err(Error::invalid("data", format!("unknown data kind {kind}"))),
    }
}

/// A named configuration.
fn config(name: &str, q: usize) -> Result<MatchOptions> {
    // The settings these experiments were run with (eq. (5) μ_c = 1e-3, the paper's completion
    // options without the isometry prior, ICP at most 50 iterations).
    let mut o = MatchOptions {
        refine: Refine::None,
        zoomout_to: 150,
        zoomout_step: 5,
        commutativity: 1e-3,
        completion: funcorr::completion::CompletionOptions::paper(false, funcorr::completion::Scaling::Unit),
        icp: funcorr::pointwise::IcpOptions::default(),
        ..MatchOptions::for_method(Method::Fmap, false)
    };
    let mut parts = name.split('+');
    let method = parts.next().unwrap_or("");
    match method {
        "fmap" => o.method = Method::Fmap,
        "plain" => {
            // The paper's eq. (5) without commutativity at k = 250 (Figure 5's situation).
            o.method = Method::Fmap;
            o.commutativity = 0.0;
            o.k = 250;
        }
        "pokrass" => o.method = Method::Pokrass,
        "coupled" => o.method = Method::Coupled,
        "comp" | "paper" => {
            o.method = Method::Completion;
            if method == "paper" {
                o.completion.scaling = Scaling::Paper;
                o.completion.params = funcorr::completion::CompletionParams::defaults_for(Scaling::Paper);
            }
        }
        _ => return Err(Error::invalid("config", name.to_string())),
    }
    for p in parts {
        if let Some((key, v)) = p.split_once('=') {
            let x: f64 = v.parse().map_err(|_| Error::invalid("config", format!("bad value in {p}")))?;
            let c = &mut o.completion.params;
            match key {
                "k" => o.k = x as usize,
                "kp" => o.completion.k_prime = x as usize,
                "rank" => o.completion.k = x as usize,
                "comm" => o.commutativity = x,
                "mu1" => c.mu1 = x,
                "mu2" => c.mu2 = x,
                "mud" => {
                    c.mu1 = x;
                    c.mu2 = x;
                }
                "mu3" => c.mu3 = x,
                "mu4" => c.mu4 = x,
                "xi" => c.xi = x,
                "mc" => c.mu_comm = x,
                "kc" => c.k_comm = x as usize,
                "rk" => o.refine_k = x as usize,
                "init" => o.init_k = x as usize,
                "it" => o.completion.optimize.max_iterations = x as usize,
                "icp" => o.icp.max_iterations = x as usize,
                "zo" => o.zoomout_to = x as usize,
                _ => return Err(Error::invalid("config", format!("unknown key in {p}"))),
            }
            continue;
        }
        match p {
            "icp" => o.refine = Refine::Icp,
            "zo" => o.refine = Refine::Zoomout,
            "comm" => {
                o.completion.params.mu_comm = 1e-3;
                o.completion.params.k_comm = 50;
            }
            "comm2" => {
                o.completion.params.mu_comm = 1e-2;
                o.completion.params.k_comm = 50;
            }
            "svd" => o.completion.init = Init::Svd,
            "rcg" => {
                o.completion.optimizer = Some(Optimizer::Rcg);
                o.completion.params.mu4 = 0.0;
            }
            "argmax" => o.extraction = Extraction::Argmax,
            "cmap" => o.extraction = Extraction::Fmap,
            "rich" => {
                o.completion.k_prime = 50;
                o.completion.k = 30;
            }
            "fixed" => o.completion.form = Form::FixedRank,
            "r100" => o.refine_k = 100,
            "r30" => o.refine_k = 30,
            "l1x10" => o.completion.params.mu3 *= 10.0,
            "l1d10" => o.completion.params.mu3 /= 10.0,
            "dx10" => {
                o.completion.params.mu1 *= 10.0;
                o.completion.params.mu2 *= 10.0;
            }
            "dd10" => {
                o.completion.params.mu1 /= 10.0;
                o.completion.params.mu2 /= 10.0;
            }
            "xi1" => o.completion.params.xi = 1.0,
            "xi4" => o.completion.params.xi = 1e-4,
            "init20" => o.init_k = 20,
            "initq" => o.init_k = q.max(2),
            _ => return Err(Error::invalid("config", format!("unknown part {p} of {name}"))),
        }
    }
    Ok(o)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        eprintln!("usage: completion_experiments DATA FIRST COUNT CONFIG[,CONFIG...]");
        std::process::exit(2);
    }
    let (kind, first, count) = (&args[0], args[1].parse::<usize>().unwrap(), args[2].parse::<usize>().unwrap());
    let configs: Vec<&str> = args[3].split(',').collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::var_os("FAUST_R").map(PathBuf::from).unwrap_or_else(|| root.join("../shared/data/faust_r"));
    let cache = BasisCache::new(root.join("target/exp-cache"));
    let text = std::fs::read_to_string(dir.join("pairs.txt")).map_err(|e| Error::io(dir.join("pairs.txt"), e))?;
    let pairs: Vec<(String, String)> = text
        .lines()
        .filter_map(|l| {
            let mut t = l.split_whitespace();
            Some((t.next()?.to_string(), t.next()?.to_string()))
        })
        .skip(first)
        .take(count)
        .collect();
    println!(
        "# data {kind}; pairs {first}..{}; mean error x100 (symmetric), <=0.05, <=0.10, iterations, seconds",
        first + count
    );
    let mut sums: HashMap<String, (f64, usize)> = HashMap::new();
    for (nx, ny) in &pairs {
        let x = load(&dir, nx, &cache, 350)?;
        let y = load(&dir, ny, &cache, 350)?;
        let (f, g) = data(kind, &dir, (nx, &x), (ny, &y))?;
        let vts =
            |n: &str, s: &str, size: usize| read_index_list_file(&dir.join(format!("corres/{n}{s}.vts")), true, size);
        let gt = GroundTruth {
            x: vts(nx, "", x.basis.n())?,
            y: vts(ny, "", y.basis.n())?,
            y_sym: Some(vts(ny, ".sym", y.basis.n())?),
        };
        let geo = funcorr::geodesic::ExactGeodesics::new(&y.mesh)?;
        for name in &configs {
            let opts = config(name, f.q())?;
            let t = Instant::now();
            let r = matching::run_on_bases(&x.basis, &y.basis, Some((&x.lap, &y.lap)), &f, &g, &opts)?;
            let secs = t.elapsed().as_secs_f64();
            let s = summarize(&hard_errors(&r.map_xy, &gt, &geo, y.mesh.total_area())?);
            let iters = r.solver.as_ref().map_or(0, |s| s.iterations());
            println!(
                "{nx}-{ny} {name:<24} q {:>4}  mean {:>6.2}  <=.05 {:>5.1}%  <=.10 {:>5.1}%  it {:>4}  {:>6.1} s",
                f.q(),
                100.0 * s.mean,
                100.0 * s.at_005,
                100.0 * s.at_010,
                iters,
                secs
            );
            let e = sums.entry(name.to_string()).or_default();
            e.0 += 100.0 * s.mean;
            e.1 += 1;
        }
    }
    for name in &configs {
        let (s, c) = sums[*name];
        println!("# mean over {c} pairs: {name:<24} {:.2}", s / c as f64);
    }
    Ok(())
}
