//! How well a point cloud's normals (PCA over K neighbours, oriented along a spanning tree; see
//! [`funcorr::cloud`]) agree with the normals of the mesh whose vertices the cloud is: per shape,
//! the share of points whose cloud normal points against the mesh's (flipped orientation) and the
//! share within 60° of it either way.
//!
//! ```sh
//! cargo run --release --example cloud_normals -- ../shared/data/faust_r/tr_reg_0*.off
//! DUMP=out/ cargo run --release --example cloud_normals -- shape.off   # also out/shape.txt: x y z n_cloud·n_mesh
//! ```

use funcorr::shape::Shape;
use funcorr::{cloud, Error, Result};

fn main() -> Result<()> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    println!("shape\tpoints\tflipped %\twithin 60° (either sign) %");
    for path in &paths {
        let Shape::Mesh(mesh) = Shape::load(path.as_ref())? else {
            return Err(Error::invalid("shape", format!("{path}: expected a triangle mesh")));
        };
        let surf = cloud::cloud_surface(mesh.vertices(), cloud::DEFAULT_NEIGHBOURS)?;
        let reference = mesh.vertex_normals();
        let n = reference.len() as f64;
        let dots: Vec<f64> =
            surf.normals.iter().zip(&reference).map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).collect();
        if let Some(dir) = std::env::var_os("DUMP") {
            let name = std::path::Path::new(path).file_stem().unwrap().to_string_lossy().to_string();
            let text: String =
                dots.iter().zip(mesh.vertices()).map(|(d, p)| format!("{} {} {} {}\n", p[0], p[1], p[2], d)).collect();
            let out = std::path::Path::new(&dir).join(format!("{name}.txt"));
            std::fs::write(&out, text).map_err(|e| Error::io(&out, e))?;
        }
        let flipped = dots.iter().filter(|&&d| d < 0.0).count() as f64;
        let close = dots.iter().filter(|&&d| d.abs() > 0.5).count() as f64;
        println!("{path}\t{}\t{:.2}\t{:.2}", reference.len(), 100.0 * flipped / n, 100.0 * close / n);
    }
    Ok(())
}
