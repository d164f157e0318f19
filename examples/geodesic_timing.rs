//! Timing of the exact geodesic solver and accuracy of the approximate ones.
//!
//! ```sh
//! cargo run --release --example geodesic_timing -- [mesh.off [template.vts [template.sym.vts]]]
//! ```
//! Defaults: the bundled FAUST `data/faust/tr_reg_001.off` with its 5,000 template points
//! `tr_reg_001.vts` (and `.sym.vts`). Prints:
//! - single-source exact solves (one thread): seconds per solve;
//! - mean / max relative error of the heat method and of Dijkstra on edges against the exact
//!   distances, from 5 sources, at vertices farther than 1 % and 10 % of √area from the source;
//! - an evaluation-like batch: for every template point y_i a "predicted" vertex a short random
//!   walk away (0–15 edge steps), the exact pair distances d(y_i, pred_i) with early
//!   termination (all cores), and the same with the mirrored points capped at the direct
//!   distance, as `eval::hard_errors` does with symmetry.
//!
//! Without a template file, 5,000 vertices are drawn at random.

use std::path::{Path, PathBuf};
use std::time::Instant;

use funcorr::eval::Distances;
use funcorr::geodesic::{ExactGeodesics, GraphGeodesics, HeatGeodesics};
use funcorr::shape::{Shape, TriMesh};

struct Rng(u64);
impl Rng {
    fn next(&mut self, n: usize) -> usize {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 % n as u64) as usize
    }
}

fn relative_errors(approx: &[f64], exact: &[f64], min_dist: f64) -> (f64, f64) {
    let (mut sum, mut max, mut cnt) = (0.0, 0.0f64, 0);
    for (a, e) in approx.iter().zip(exact) {
        if *e > min_dist && e.is_finite() {
            let r = (a - e).abs() / e;
            sum += r;
            max = max.max(r);
            cnt += 1;
        }
    }
    (sum / cnt.max(1) as f64, max)
}

fn main() -> funcorr::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = PathBuf::from(args.first().map(String::as_str).unwrap_or("data/faust/tr_reg_001.off"));
    let Shape::Mesh(mesh) = Shape::load(&path)? else {
        return Err(funcorr::Error::invalid("mesh", "expected a triangle mesh"));
    };
    let n = mesh.n_vertices();
    let sqrt_area = mesh.total_area().sqrt();
    println!(
        "{}: {n} vertices, {} faces, √area = {sqrt_area:.4}, {} threads",
        path.display(),
        mesh.n_faces(),
        rayon::current_num_threads()
    );

    let t = Instant::now();
    let exact = ExactGeodesics::new(&mesh)?;
    println!(
        "exact: setup {:.4} s, {} degenerate faces skipped",
        t.elapsed().as_secs_f64(),
        exact.skipped_faces().len()
    );

    // Single-source solves, one at a time (each allocates its own work space).
    let sources: Vec<usize> = (0..5).map(|i| i * n / 5 + 17).collect();
    let mut full = vec![];
    let mut secs = vec![];
    for &s in sources.iter().chain(&sources) {
        let t = Instant::now();
        let d = exact.distances_from_vertex(s)?;
        secs.push(t.elapsed().as_secs_f64());
        if full.len() < sources.len() {
            full.push(d);
        }
    }
    secs.sort_by(f64::total_cmp);
    println!(
        "exact single-source solve: median {:.4} s, min {:.4} s, max {:.4} s (5 sources, twice each)",
        secs[secs.len() / 2],
        secs[0],
        secs[secs.len() - 1]
    );
    // Sanity: chord ≤ exact ≤ Dijkstra at every vertex, and symmetry between the sources.
    let dijkstra = GraphGeodesics::mesh_edges(&mesh)?;
    let dij_full = dijkstra.distances(&sources)?;
    let p = mesh.vertices();
    let mut violations = 0;
    for (j, d) in full.iter().enumerate() {
        for i in 0..n {
            let chord = (0..3).map(|c| (p[i][c] - p[sources[j]][c]).powi(2)).sum::<f64>().sqrt();
            if d[i] < chord * (1.0 - 1e-12) || d[i] > dij_full[(i, j)] * (1.0 + 1e-12) {
                violations += 1;
            }
        }
    }
    let mut asym: f64 = 0.0;
    for a in 0..sources.len() {
        for b in 0..a {
            let (x, y) = (full[a][sources[b]], full[b][sources[a]]);
            asym = asym.max((x - y).abs() / x.max(y));
        }
    }
    println!("  checks: {violations} vertices outside [chord, Dijkstra]; symmetry max relative difference {asym:.1e}");

    // Approximations against the exact distances.
    let t = Instant::now();
    let heat = HeatGeodesics::new(&mesh);
    let setup = t.elapsed().as_secs_f64();
    let min_dist = 0.01 * sqrt_area;
    let report = |name: &str, d: &faer::Mat<f64>| {
        for frac in [0.01, 0.1] {
            let (mut sum, mut max) = (0.0, 0.0f64);
            for (j, ex) in full.iter().enumerate() {
                let (m, x) = relative_errors(d.col_as_slice(j), ex, frac * sqrt_area);
                sum += m;
                max = max.max(x);
            }
            println!(
                "  {name:<18} beyond {:>2.0} % of √area: mean relative error {:.3} %, max {:.2} %",
                100.0 * frac,
                100.0 * sum / full.len() as f64,
                100.0 * max
            );
        }
    };
    println!("approximations vs exact (5 sources):");
    report("Dijkstra on edges", &dij_full);
    match heat {
        Ok(h) => {
            println!("  (heat method setup {setup:.2} s)");
            report("heat method", &h.distances(&sources)?);
        }
        Err(e) => println!("  heat method unavailable: {e}"),
    }

    // Evaluation-like pairs.
    let dir = path.parent().unwrap_or(Path::new("."));
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let vts = args.get(1).map(PathBuf::from).unwrap_or_else(|| dir.join(format!("{stem}.vts")));
    let vts_sym = args.get(2).map(PathBuf::from).unwrap_or_else(|| dir.join(format!("{stem}.sym.vts")));
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let truth: Vec<usize> = funcorr::io::indices::read_index_list_file(&vts, true, n)
        .unwrap_or_else(|_| (0..5000).map(|_| rng.next(n)).collect());
    let truth_sym = funcorr::io::indices::read_index_list_file(&vts_sym, true, n).ok();
    let neighbours = neighbours(&mesh);
    let predicted: Vec<usize> = truth
        .iter()
        .map(|&y| {
            let mut v = y;
            for _ in 0..rng.next(16) {
                let nb = &neighbours[v];
                v = nb[rng.next(nb.len())];
            }
            v
        })
        .collect();
    let pairs: Vec<(usize, usize)> = truth.iter().copied().zip(predicted.iter().copied()).collect();
    let t = Instant::now();
    let direct = exact.pair_distances(&pairs)?;
    let secs = t.elapsed().as_secs_f64();
    let mean_err = direct.iter().sum::<f64>() / direct.len() as f64 / sqrt_area;
    println!("exact pair distances: {} pairs in {secs:.3} s (mean normalized distance {mean_err:.4})", pairs.len());
    if let Some(sym) = &truth_sym {
        let pairs_sym: Vec<(usize, usize)> = sym.iter().copied().zip(predicted.iter().copied()).collect();
        let t = Instant::now();
        exact.pair_distances_capped(&pairs_sym, &direct)?;
        println!("  mirrored pairs capped at the direct distance: {:.3} s", t.elapsed().as_secs_f64());
        // Uncapped, the mirrored pairs are far apart: time a sample of 200.
        let t = Instant::now();
        exact.pair_distances(&pairs_sym[..200.min(pairs_sym.len())])?;
        println!(
            "  mirrored pairs uncapped (far apart): {:.4} s per pair",
            t.elapsed().as_secs_f64() / 200.min(pairs_sym.len()) as f64
        );
    }
    let t = Instant::now();
    let dij = Distances::pair_distances(&dijkstra, &pairs)?;
    let (m, x) = relative_errors(&dij, &direct, min_dist);
    println!(
        "Dijkstra pair distances: {:.3} s; relative error on these pairs: mean {:.2} %, max {:.1} %",
        t.elapsed().as_secs_f64(),
        100.0 * m,
        100.0 * x
    );
    Ok(())
}

fn neighbours(mesh: &TriMesh) -> Vec<Vec<usize>> {
    let mut nb = vec![vec![]; mesh.n_vertices()];
    for [a, b] in mesh.edges() {
        nb[a as usize].push(b as usize);
        nb[b as usize].push(a as usize);
    }
    for (i, l) in nb.iter_mut().enumerate() {
        if l.is_empty() {
            l.push(i);
        }
    }
    nb
}
