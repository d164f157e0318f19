//! Accuracy of the heat method against the exact polyhedral distances, shape by shape.
//!
//! ```sh
//! cargo run --release --example heat_accuracy -- [DIR_OR_MESH ...]
//! ```
//! Default: every `.off` mesh of `../shared/data/{faust_r, tosca_r, tosca_nonisometric_r,
//! tosca_hires}`. A directory argument means its `.off` files (sorted by name).
//!
//! Per mesh: 5 source vertices drawn at random (a fixed xorshift seed, so runs repeat); for each
//! source the exact distances ([`ExactGeodesics`], MMP) and the heat-method distances
//! ([`HeatGeodesics`], t = h²) to every vertex; the relative error |d_heat − d_exact| / d_exact
//! over all (source, vertex) pairs with d_exact > 1 % of √area. Printed as a Markdown table:
//! mean, 95th percentile and maximum of the relative error, mean ratio heat / exact, the same
//! mean error for Dijkstra on edges, the number of intrinsic flips and the heat setup time;
//! then a summary per folder and the shapes whose mean error exceeds 5 %.

use std::path::{Path, PathBuf};
use std::time::Instant;

use funcorr::geodesic::{ExactGeodesics, GraphGeodesics, HeatGeodesics};
use funcorr::shape::Shape;

/// Sources per mesh.
const SOURCES: usize = 5;
/// Pairs closer than this fraction of √area are left out (relative errors blow up near 0).
const MIN_FRACTION: f64 = 0.01;
/// Target for the mean relative error of every shape.
const TARGET: f64 = 0.05;

struct Rng(u64);
impl Rng {
    fn next(&mut self, n: usize) -> usize {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 % n as u64) as usize
    }
}

struct Row {
    folder: String,
    name: String,
    n: usize,
    mean: f64,
    p95: f64,
    max: f64,
    ratio: f64,
    dijkstra: f64,
    flips: usize,
    setup: f64,
}

fn meshes(args: &[String]) -> Vec<PathBuf> {
    let roots: Vec<PathBuf> = if args.is_empty() {
        ["faust_r", "tosca_r", "tosca_nonisometric_r", "tosca_hires"]
            .iter()
            .map(|d| Path::new("../shared/data").join(d))
            .collect()
    } else {
        args.iter().map(PathBuf::from).collect()
    };
    let mut out = vec![];
    for r in roots {
        if r.is_dir() {
            let mut v: Vec<PathBuf> =
                std::fs::read_dir(&r).map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect()).unwrap_or_default();
            v.retain(|p| p.extension().is_some_and(|e| e == "off"));
            v.sort();
            out.extend(v);
        } else {
            out.push(r);
        }
    }
    out
}

fn measure(path: &Path) -> funcorr::Result<Row> {
    let Shape::Mesh(mesh) = Shape::load(path)? else {
        return Err(funcorr::Error::invalid("mesh", format!("{} is not a triangle mesh", path.display())));
    };
    let n = mesh.n_vertices();
    let min_dist = MIN_FRACTION * mesh.total_area().sqrt();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let sources: Vec<usize> = (0..SOURCES).map(|_| rng.next(n)).collect();
    let exact = ExactGeodesics::new(&mesh)?;
    let t = Instant::now();
    let heat = HeatGeodesics::new(&mesh)?;
    let setup = t.elapsed().as_secs_f64();
    let hd = heat.distances(&sources)?;
    let dd = GraphGeodesics::mesh_edges(&mesh)?.distances(&sources)?;
    let (mut errs, mut ratio, mut dij) = (Vec::new(), 0.0, 0.0);
    for (j, &s) in sources.iter().enumerate() {
        let ex = exact.distances_from_vertex(s)?;
        for (i, &e) in ex.iter().enumerate() {
            if e > min_dist && e.is_finite() {
                errs.push((hd[(i, j)] - e).abs() / e);
                ratio += hd[(i, j)] / e;
                dij += (dd[(i, j)] - e).abs() / e;
            }
        }
    }
    let cnt = errs.len().max(1) as f64;
    let mean = errs.iter().sum::<f64>() / cnt;
    errs.sort_by(f64::total_cmp);
    let p95 = errs.get((0.95 * errs.len() as f64) as usize).copied().unwrap_or(f64::NAN);
    let max = errs.last().copied().unwrap_or(f64::NAN);
    let folder = path.parent().and_then(|p| p.file_name()).and_then(|s| s.to_str()).unwrap_or("").to_string();
    let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("").to_string();
    Ok(Row { folder, name, n, mean, p95, max, ratio: ratio / cnt, dijkstra: dij / cnt, flips: heat.flips(), setup })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let paths = meshes(&args);
    println!(
        "heat method vs exact: {SOURCES} random sources per mesh, pairs beyond {:.0} % of √area, {} threads",
        100.0 * MIN_FRACTION,
        rayon::current_num_threads()
    );
    println!();
    println!("| folder | shape | n | heat mean | p95 | max | heat / exact | Dijkstra mean | flips | heat setup |");
    println!("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    let mut rows = vec![];
    for p in &paths {
        match measure(p) {
            Ok(r) => {
                println!(
                    "| {} | {} | {} | {:.2} % | {:.2} % | {:.1} % | {:.4} | {:.2} % | {} | {:.2} s |",
                    r.folder,
                    r.name,
                    r.n,
                    100.0 * r.mean,
                    100.0 * r.p95,
                    100.0 * r.max,
                    r.ratio,
                    100.0 * r.dijkstra,
                    r.flips,
                    r.setup
                );
                rows.push(r);
            }
            Err(e) => println!("| {} | error: {e} | | | | | | | | |", p.display()),
        }
    }
    println!();
    println!("| folder | shapes | heat mean (mean over shapes) | worst shape | Dijkstra mean |");
    println!("| --- | ---: | ---: | --- | ---: |");
    let mut folders: Vec<&str> = rows.iter().map(|r| r.folder.as_str()).collect();
    folders.dedup();
    for f in folders {
        let rs: Vec<&Row> = rows.iter().filter(|r| r.folder == f).collect();
        let k = rs.len() as f64;
        let worst = rs.iter().max_by(|a, b| a.mean.total_cmp(&b.mean)).expect("a row");
        println!(
            "| {f} | {} | {:.2} % | {} {:.2} % | {:.2} % |",
            rs.len(),
            100.0 * rs.iter().map(|r| r.mean).sum::<f64>() / k,
            worst.name,
            100.0 * worst.mean,
            100.0 * rs.iter().map(|r| r.dijkstra).sum::<f64>() / k
        );
    }
    let over: Vec<String> = rows
        .iter()
        .filter(|r| r.mean > TARGET || r.mean.is_nan())
        .map(|r| format!("{}/{} ({:.2} %)", r.folder, r.name, 100.0 * r.mean))
        .collect();
    println!();
    if over.is_empty() {
        println!("all {} shapes within {:.0} % mean relative error", rows.len(), 100.0 * TARGET);
    } else {
        println!("{} of {} shapes above {:.0} %: {}", over.len(), rows.len(), 100.0 * TARGET, over.join(", "));
    }
}
