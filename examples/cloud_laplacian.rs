//! How well the point-cloud Laplacian reproduces the mesh's: eigenvalues of the cotangent
//! Laplacian of a mesh against those of the point-cloud Laplacian of (a) its vertices and
//! (b) `count` points resampled uniformly on its surface, and the total mass (area).
//!
//! ```sh
//! cargo run --release --example cloud_laplacian -- ../shared/data/faust_r/tr_reg_000.off [k [count]]
//! ```

use funcorr::cloud::{cloud_laplacian, DEFAULT_NEIGHBOURS};
use funcorr::shape::Shape;
use funcorr::spectral::{eigen_basis, SpectralOptions};
use funcorr::{laplacian, Error, Result};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map(String::as_str).unwrap_or("data/faust/tr_reg_000.off");
    let k: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(100);
    let Shape::Mesh(mesh) = Shape::load(path.as_ref())? else {
        return Err(Error::invalid("shape", "expected a triangle mesh"));
    };
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(mesh.n_vertices());
    let opts = SpectralOptions::new(k);
    let reference = eigen_basis(&laplacian::cotangent(&mesh)?, &opts, None)?.0;
    let vertex_cloud = cloud_laplacian(mesh.vertices(), DEFAULT_NEIGHBOURS)?.0;
    let sampled = mesh.sample_surface(count, 1)?;
    let resampled = cloud_laplacian(&sampled, DEFAULT_NEIGHBOURS)?.0;
    println!("{path}: {} vertices, area {:.6}", mesh.n_vertices(), mesh.total_area());
    for (name, lap) in [("vertices as a cloud", &vertex_cloud), ("resampled cloud", &resampled)] {
        let b = eigen_basis(lap, &opts, None)?.0;
        let ratios: Vec<f64> = (1..k).map(|i| b.eigenvalues[i] / reference.eigenvalues[i]).collect();
        let mean = ratios.iter().map(|r| (r - 1.0).abs()).sum::<f64>() / ratios.len() as f64;
        let worst = ratios.iter().map(|r| (r - 1.0).abs()).fold(0.0f64, f64::max);
        println!(
            "{name} ({} points): area {:.6} ({:+.2} %), eigenvalues 2..{k}: mean |ratio − 1| {:.2} %, max {:.2} %; λ_10 ratio {:.4}, λ_{k} ratio {:.4}",
            lap.n(),
            lap.mass.iter().sum::<f64>(),
            100.0 * (lap.mass.iter().sum::<f64>() / mesh.total_area() - 1.0),
            100.0 * mean,
            100.0 * worst,
            ratios[9.min(ratios.len() - 1)],
            ratios[ratios.len() - 1]
        );
    }
    Ok(())
}
