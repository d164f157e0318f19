//! Roughness of point clouds (`funcorr::denoise::cloud_roughness`): clean and noisy clouds of the
//! given meshes, one line per (shape, cloud, σ): the vertex cloud and `RESAMPLE` (default 5000)
//! uniform surface samples, each with Gaussian noise σ × the bounding-box diagonal for σ in 0,
//! 0.2 %, 0.5 %, 1 % (seeded). Used to place the thresholds of the cloud denoising.
//!
//! ```sh
//! cargo run --release --example cloud_roughness -- ../shared/data/faust_r/shapes/tr_reg_000.off ...
//! ```

use funcorr::shape::{Shape, TriMesh};

/// xorshift64* and Box–Muller: a seeded Gaussian stream (the study's own, not the library's).
struct Gauss(u64);
impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

fn main() -> funcorr::Result<()> {
    let resample: usize = std::env::var("RESAMPLE").ok().map_or(5000, |s| s.parse().expect("RESAMPLE=N"));
    for path in std::env::args().skip(1) {
        let Shape::Mesh(mesh) = Shape::load(std::path::Path::new(&path))? else { continue };
        let mesh: TriMesh = mesh;
        let v = mesh.vertices();
        let (lo, hi) = v.iter().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
            ([0, 1, 2].map(|d| lo[d].min(p[d])), [0, 1, 2].map(|d| hi[d].max(p[d])))
        });
        let diag = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
        let clouds = [("vertices", v.to_vec()), ("resampled", mesh.sample_surface(resample, 7)?)];
        for (kind, clean) in clouds {
            for sigma in [0.0, 0.002, 0.005, 0.01] {
                let mut g = Gauss(0x9E37_79B9_7F4A_7C15 ^ clean.len() as u64);
                let pts: Vec<[f64; 3]> =
                    clean.iter().map(|p| [0, 1, 2].map(|d| p[d] + sigma * diag * g.sample())).collect();
                let r = funcorr::denoise::cloud_roughness(&pts)?;
                println!(
                    "{{\"shape\":{path:?},\"cloud\":\"{kind}\",\"n\":{},\"sigma\":{sigma},\"roughness\":{r:.4}}}",
                    pts.len()
                );
            }
        }
    }
    Ok(())
}
