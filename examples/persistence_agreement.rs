//! Persistence-based segmentation + segment matching on FAUST pairs, compared with the provided
//! segmentations (issue 3 experiment, see EXPERIMENTS.md).
//!
//! ```sh
//! cargo run --release --example persistence_agreement                 # first 10 pairs
//! cargo run --release --example persistence_agreement -- 20           # first 20 pairs
//! cargo run --release --example persistence_agreement -- 10 --scan    # also scan HKS time and τ
//! cargo run --release --example persistence_agreement -- 10 --function agd   # segment by AGD
//! ```
//!
//! `--function` picks the segmentation function: `hks` (the default function), `agd` (average
//! geodesic distance with the heat method, the library's default), `agd-exact` (exact MMP
//! distances) or `agd-dijkstra` (edge-path distances, the AGD of the library before issue 16);
//! always with the default threshold τ. The scan prints the AGD with all three distances.
//!
//! For every pair (X, Y) of `../shared/data/faust_r/pairs.txt` (or `$FAUST_R`): segment both
//! shapes with the default function and threshold, match the segments, and take for each computed
//! segment the majority provided label (`segmentation/X_Y.S.seg.sym`) of its vertices; a matched
//! pair of segments agrees when the two majority labels are equal. Bases (k = 100) are cached in
//! `target/persistence-cache`.

use std::path::{Path, PathBuf};

use funcorr::descriptors::persistence::{
    average_geodesic_distance_with, default_function, hks_function, matched_segment_indicators,
    persistence_segmentation, DEFAULT_AGD_SOURCES, DEFAULT_THRESHOLD,
};
use funcorr::geodesic::GeodesicMethod;
use funcorr::io::indices::read_labels_file;
use funcorr::laplacian::cotangent;
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{eigen_basis_cached, Basis, BasisCache, SpectralOptions};

fn majority(seg_labels: &[u32], provided: &[u32], segment: u32) -> u32 {
    let mut counts = std::collections::BTreeMap::new();
    for (s, p) in seg_labels.iter().zip(provided) {
        if *s == segment {
            *counts.entry(*p).or_insert(0usize) += 1;
        }
    }
    counts.into_iter().max_by_key(|&(l, c)| (c, std::cmp::Reverse(l))).map(|(l, _)| l).unwrap_or(0)
}

fn load(dir: &Path, name: &str, cache: &BasisCache) -> funcorr::Result<(TriMesh, Basis)> {
    let Shape::Mesh(mesh) = Shape::load(&dir.join(format!("{name}.off")))? else {
        return Err(funcorr::Error::invalid("shape", format!("{name} is not a mesh")));
    };
    let lap = cotangent(&mesh)?;
    let (basis, _) = eigen_basis_cached(&lap, &SpectralOptions::new(100), Some(cache), None)?;
    Ok((mesh, basis))
}

fn main() -> funcorr::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count: usize = args.iter().find_map(|a| a.parse().ok()).unwrap_or(10);
    let scan = args.iter().any(|a| a == "--scan");
    let function = match args.iter().position(|a| a == "--function").map(|i| args.get(i + 1).map(String::as_str)) {
        None => "hks",
        Some(Some(f @ ("hks" | "agd" | "agd-exact" | "agd-dijkstra"))) => f,
        Some(other) => {
            return Err(funcorr::Error::invalid(
                "--function",
                format!("{other:?}: expected hks, agd, agd-exact or agd-dijkstra"),
            ))
        }
    };
    let seg_function = |mesh: &TriMesh, basis: &Basis| -> funcorr::Result<Vec<f64>> {
        match function {
            "agd" => average_geodesic_distance_with(mesh, DEFAULT_AGD_SOURCES, GeodesicMethod::Heat),
            "agd-exact" => average_geodesic_distance_with(mesh, DEFAULT_AGD_SOURCES, GeodesicMethod::Exact),
            "agd-dijkstra" => average_geodesic_distance_with(mesh, DEFAULT_AGD_SOURCES, GeodesicMethod::Dijkstra),
            _ => default_function(basis),
        }
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::var_os("FAUST_R").map(PathBuf::from).unwrap_or_else(|| root.join("../shared/data/faust_r"));
    let cache = BasisCache::new(root.join("target/persistence-cache"));
    let pairs_path = dir.join("pairs.txt");
    let text = std::fs::read_to_string(&pairs_path).map_err(|e| funcorr::Error::io(&pairs_path, e))?;
    let pairs: Vec<(String, String)> = text
        .lines()
        .filter_map(|l| {
            let mut t = l.split_whitespace();
            Some((t.next()?.to_string(), t.next()?.to_string()))
        })
        .take(count)
        .collect();

    if scan {
        // Number of segments for several HKS times (t = c / λ₁) and thresholds, and the largest
        // relative persistences, on the distinct shapes of the pairs.
        let mut names: Vec<&String> = pairs.iter().flat_map(|(a, b)| [a, b]).collect();
        names.sort();
        names.dedup();
        let taus = [0.02, 0.05, 0.1, 0.15, 0.2];
        println!("# scan: segments per shape for t = c/λ₁ (rows) and τ (columns {taus:?})");
        for name in &names {
            let (mesh, basis) = load(&dir, name, &cache)?;
            let edges = mesh.edges();
            for c in [0.1, 0.25, 0.5, 1.0, 2.0, 4.0] {
                let f = hks_function(&basis, c)?;
                let range = f.iter().copied().fold(f64::MIN, f64::max) - f.iter().copied().fold(f64::MAX, f64::min);
                let all = persistence_segmentation(mesh.n_vertices(), &edges, &f, 0.0)?;
                let mut rel: Vec<f64> = all.persistence.iter().map(|p| p / range).collect();
                rel.sort_by(|a, b| b.total_cmp(a));
                let counts: Vec<usize> = taus
                    .iter()
                    .map(|&t| persistence_segmentation(mesh.n_vertices(), &edges, &f, t).map(|s| s.n_segments()))
                    .collect::<funcorr::Result<_>>()?;
                let top: Vec<String> = rel.iter().take(9).map(|p| format!("{p:.3}")).collect();
                println!("{name} c={c:<4} segments {counts:?}  top persistence/range [{}]", top.join(" "));
            }
            for method in [GeodesicMethod::Heat, GeodesicMethod::Exact, GeodesicMethod::Dijkstra] {
                let agd = average_geodesic_distance_with(&mesh, DEFAULT_AGD_SOURCES, method)?;
                let range = agd.iter().copied().fold(f64::MIN, f64::max) - agd.iter().copied().fold(f64::MAX, f64::min);
                let all = persistence_segmentation(mesh.n_vertices(), &edges, &agd, 0.0)?;
                let mut rel: Vec<f64> = all.persistence.iter().map(|p| p / range).collect();
                rel.sort_by(|a, b| b.total_cmp(a));
                let counts: Vec<usize> = taus
                    .iter()
                    .map(|&t| persistence_segmentation(mesh.n_vertices(), &edges, &agd, t).map(|s| s.n_segments()))
                    .collect::<funcorr::Result<_>>()?;
                let top: Vec<String> = rel.iter().take(9).map(|p| format!("{p:.3}")).collect();
                println!(
                    "{name} AGD {:<8} segments {counts:?}  top persistence/range [{}]",
                    method.name(),
                    top.join(" ")
                );
            }
        }
        println!();
    }

    println!(
        "# function {function}, τ = {DEFAULT_THRESHOLD}; agreement = matched segment pairs with equal majority .seg.sym label"
    );
    println!("# peaks: matched pairs whose two peak vertices carry the same .seg.sym label");
    println!("# provided sym / nonsym: provided segments recovered by matching them with the same matcher");
    println!("#   nonsym a(b)/c: a exactly, b in the same .sym segment (left/right swaps allowed), of c");
    println!(
        "{:<24} {:>4} {:>4} {:>7} {:>6} {:>6} {:>8} {:>11}  X majority label -> Y majority label",
        "pair", "s_X", "s_Y", "agree", "rate", "peaks", "sym", "nonsym"
    );
    let (mut agree_all, mut total_all, mut peak_all) = (0usize, 0usize, 0usize);
    let (mut sym_all, mut sym_total, mut nonsym_all, mut nonsym_total) = (0usize, 0usize, 0usize, 0usize);
    let mut nonsym_upto_all = 0usize;
    for (a, b) in &pairs {
        let (mx, bx) = load(&dir, a, &cache)?;
        let (my, by) = load(&dir, b, &cache)?;
        let sx = persistence_segmentation(mx.n_vertices(), &mx.edges(), &seg_function(&mx, &bx)?, DEFAULT_THRESHOLD)?;
        let sy = persistence_segmentation(my.n_vertices(), &my.edges(), &seg_function(&my, &by)?, DEFAULT_THRESHOLD)?;
        let seg = dir.join("segmentation");
        let labels = |s: &str, k: &str, n: usize| read_labels_file(&seg.join(format!("{a}_{b}.{s}.seg.{k}")), n);
        let px = labels(a, "sym", mx.n_vertices())?;
        let py = labels(b, "sym", my.n_vertices())?;
        let (_, _, matches) = matched_segment_indicators(&sx.labels, &bx, &sy.labels, &by)?;
        // Columns of `segments` are in ascending label order: column c is label c + 1.
        let pairs_maj: Vec<(u32, u32)> = matches
            .iter()
            .map(|m| (majority(&sx.labels, &px, m.x as u32 + 1), majority(&sy.labels, &py, m.y as u32 + 1)))
            .collect();
        let agree = pairs_maj.iter().filter(|(p, q)| p == q).count();
        // Secondary measure: the provided labels at the two peaks.
        let peak_agree = matches.iter().filter(|m| px[sx.peaks[m.x]] == py[sy.peaks[m.y]]).count();
        peak_all += peak_agree;
        agree_all += agree;
        total_all += matches.len();
        // The provided segmentations themselves, matched without using their correspondence.
        // Also counted "up to symmetry": the matched .nonsym segments lie in the same .sym segment.
        let recovered = |lx: &[u32], ly: &[u32]| -> funcorr::Result<(usize, usize, usize)> {
            let (f, g, _) = matched_segment_indicators(lx, &bx, ly, &by)?;
            let label = |name: &str| -> u32 { name.trim_start_matches("segment:").parse().expect("a label") };
            let upto = f
                .names
                .iter()
                .zip(&g.names)
                .filter(|(p, q)| majority(lx, &px, label(p)) == majority(ly, &py, label(q)))
                .count();
            Ok((f.names.iter().zip(&g.names).filter(|(p, q)| p == q).count(), upto, f.q()))
        };
        let (sym_ok, _, sym_n) = recovered(&px, &py)?;
        let (nonsym_ok, nonsym_upto, nonsym_n) =
            recovered(&labels(a, "nonsym", mx.n_vertices())?, &labels(b, "nonsym", my.n_vertices())?)?;
        nonsym_upto_all += nonsym_upto;
        sym_all += sym_ok;
        sym_total += sym_n;
        nonsym_all += nonsym_ok;
        nonsym_total += nonsym_n;
        let mut desc: Vec<String> = pairs_maj.iter().map(|(p, q)| format!("{p}->{q}")).collect();
        // Area fractions of X's segments, in label order.
        let total: f64 = bx.mass.iter().sum();
        let areas: Vec<String> = (1..=sx.n_segments() as u32)
            .map(|l| {
                let a: f64 = sx.labels.iter().zip(&bx.mass).filter(|(s, _)| **s == l).map(|(_, m)| m).sum();
                format!("{:.2}", a / total)
            })
            .collect();
        desc.push(format!(" X areas [{}]", areas.join(" ")));
        println!(
            "{:<24} {:>4} {:>4} {:>3}/{:<3} {:>6.3} {:>6} {:>8} {:>11}  {}",
            format!("{a}-{b}"),
            sx.n_segments(),
            sy.n_segments(),
            agree,
            matches.len(),
            agree as f64 / matches.len() as f64,
            format!("{peak_agree}/{}", matches.len()),
            format!("{sym_ok}/{sym_n}"),
            format!("{nonsym_ok}({nonsym_upto})/{nonsym_n}"),
            desc.join(" ")
        );
    }
    println!("overall agreement: {agree_all}/{total_all} = {:.3}", agree_all as f64 / total_all as f64);
    println!("overall peak-label agreement: {peak_all}/{total_all} = {:.3}", peak_all as f64 / total_all as f64);
    println!(
        "provided segments recovered: sym {sym_all}/{sym_total}, nonsym {nonsym_all}/{nonsym_total} \
         ({nonsym_upto_all} up to left/right symmetry)"
    );
    Ok(())
}
