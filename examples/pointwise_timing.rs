//! Timing of the functional-map → point-map conversions (issue 5 benchmark, see BENCHMARKS.md).
//!
//! ```sh
//! cargo run --release --example pointwise_timing -- X.off Y.off [X.vts Y.vts Y.sym.vts | identity]
//! ```
//! Computes 200 eigenpairs per shape (cached in `target/exp-cache`), a k = 30 functional map by
//! eq. (5) from 100 WKS, and times: nearest neighbours in the spectral embedding at k = 30 and
//! k = 200, ICP at k = 30 (10 iterations at most), ZoomOut 30 → 200 in steps of 1 and of 5.
//! With ground truth, prints the mean hard error ×100 (exact geodesics; symmetric with .vts
//! files; `identity`: same vertex ids, every 10th vertex) of each map.

use std::path::Path;
use std::time::Instant;

use funcorr::descriptors::signatures::wks;
use funcorr::eval::{hard_errors, summarize, GroundTruth};
use funcorr::fmap::{ovsjanikov, OvsjanikovOptions};
use funcorr::io::indices::read_index_list_file;
use funcorr::laplacian::cotangent;
use funcorr::pointwise::{icp, map_from_fmap, nearest_neighbors, zoomout, IcpOptions, ZoomOutOptions};
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{eigen_basis_cached, Basis, BasisCache, SpectralOptions};
use funcorr::Result;

fn load(p: &str, cache: &BasisCache) -> Result<(TriMesh, Basis)> {
    let Shape::Mesh(mesh) = Shape::load(Path::new(p))? else { panic!("{p}: not a triangle mesh") };
    let (basis, _) = eigen_basis_cached(&cotangent(&mesh)?, &SpectralOptions::new(200), Some(cache), None)?;
    Ok((mesh, basis))
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cache = BasisCache::new(root.join("target/exp-cache"));
    let (_, bx) = load(&args[0], &cache)?;
    let (my, by) = load(&args[1], &cache)?;
    println!(
        "X {} ({} vertices), Y {} ({} vertices), threads {}",
        args[0],
        bx.n(),
        args[1],
        by.n(),
        rayon::current_num_threads()
    );
    let c = ovsjanikov(
        &bx,
        &by,
        &wks(&bx, 100, true)?,
        &wks(&by, 100, true)?,
        30,
        &OvsjanikovOptions { commutativity: 1e-3 },
    )?;
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let eval = |map: &[usize]| -> Result<Option<f64>> {
        let gt = if args.get(2).map(String::as_str) == Some("identity") {
            // Same vertex ids (tosca_hires classes): every 10th vertex, no symmetric flip.
            let ids: Vec<usize> = (0..bx.n().min(by.n())).step_by(10).collect();
            GroundTruth { x: ids.clone(), y: ids, y_sym: None }
        } else if args.len() >= 5 {
            GroundTruth {
                x: read_index_list_file(Path::new(&args[2]), true, bx.n())?,
                y: read_index_list_file(Path::new(&args[3]), true, by.n())?,
                y_sym: Some(read_index_list_file(Path::new(&args[4]), true, by.n())?),
            }
        } else {
            return Ok(None);
        };
        let geo = funcorr::geodesic::ExactGeodesics::new(&my)?;
        Ok(Some(100.0 * summarize(&hard_errors(map, &gt, &geo, my.total_area())?).mean))
    };
    let time = |name: &str, f: &mut dyn FnMut() -> Result<Vec<usize>>| -> Result<()> {
        let t = Instant::now();
        let map = f()?;
        let secs = t.elapsed().as_secs_f64();
        match eval(&map)? {
            Some(e) => println!("{name:<34} {secs:>8.3} s   mean error x100 {e:.2}"),
            None => println!("{name:<34} {secs:>8.3} s"),
        }
        Ok(())
    };
    time("nearest neighbours, k = 30", &mut || map_from_fmap(phi, psi, c.as_ref()))?;
    // The embedding of the identity map at k = 200 (the cost of one ZoomOut step at its end).
    time("nearest neighbours, k = 200", &mut || nearest_neighbors(psi.subcols(0, 200), phi.subcols(0, 200)))?;
    time("ICP, k = 30 (10 iterations at most)", &mut || {
        Ok(icp(phi, psi, c.as_ref(), &IcpOptions { max_iterations: 10 })?.1)
    })?;
    // `ZOOMOUT_STEPS=5` skips the step-1 run (170 nearest-neighbour searches) on large meshes.
    let steps: Vec<usize> = std::env::var("ZOOMOUT_STEPS")
        .unwrap_or_else(|_| "1,5".into())
        .split(',')
        .map(|s| s.trim().parse().expect("ZOOMOUT_STEPS: comma-separated integers"))
        .collect();
    for step in steps {
        time(&format!("ZoomOut 30 → 200, step {step}"), &mut || {
            Ok(zoomout(phi, psi, &by.mass, c.as_ref(), &ZoomOutOptions { k_final: 200, step })?.1)
        })?;
    }
    Ok(())
}
