//! ShapeMSER on the bundled FAUST pair: detects maximally stable regions of the heat kernel
//! weighting on both poses, matches them, and scores the matches with the ground truth.
//!
//! ```sh
//! cargo run --release --example mser_faust                 # default options
//! cargo run --release --example mser_faust -- 0.03 0.1 0.3  # several times t = τ / λ₁
//! ```
//!
//! For every matched pair it prints the fraction of X's template points in R_X whose counterparts
//! fall in R_Y, with the ground truth and with its left-right mirror (the descriptors are
//! intrinsic, so the two sides of a human cannot be told apart).

use std::collections::BTreeSet;
use std::path::Path;

use funcorr::descriptors::mser::{matched_mser_indicators, shape_mser, HeatTime, MserOptions, Region};
use funcorr::io::indices::read_index_list_file;
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{eigen_basis, Basis, SpectralOptions};
use funcorr::{laplacian, Result};

fn load(name: &str, k: usize) -> Result<(TriMesh, Basis)> {
    let Shape::Mesh(mesh) = Shape::load(Path::new(&format!("data/faust/{name}.off")))? else {
        panic!("{name} is not a mesh")
    };
    let basis = eigen_basis(&laplacian::cotangent(&mesh)?, &SpectralOptions::new(k), None)?.0;
    Ok((mesh, basis))
}

/// Fraction of the template points in `rx` (through `gx`) whose counterparts (through `gy`) are in `ry`.
fn fraction(rx: &Region, ry: &Region, gx: &[usize], gy: &[usize]) -> f64 {
    let (inx, iny): (BTreeSet<u32>, BTreeSet<u32>) =
        (rx.vertices.iter().copied().collect(), ry.vertices.iter().copied().collect());
    let pts: Vec<usize> = (0..gx.len()).filter(|&i| inx.contains(&(gx[i] as u32))).collect();
    pts.iter().filter(|&&i| iny.contains(&(gy[i] as u32))).count() as f64 / pts.len().max(1) as f64
}

fn main() -> Result<()> {
    let taus: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("τ must be a number")).collect();
    let taus = if taus.is_empty() { vec![f64::NAN] } else { taus };
    let k = 60;
    let ((mx, bx), (my, by)) = (load("tr_reg_000", k)?, load("tr_reg_001", k)?);
    let gx = read_index_list_file(Path::new("data/faust/tr_reg_000.vts"), true, mx.n_vertices())?;
    let gy = read_index_list_file(Path::new("data/faust/tr_reg_001.vts"), true, my.n_vertices())?;
    let sy = read_index_list_file(Path::new("data/faust/tr_reg_001.sym.vts"), true, my.n_vertices())?;
    for tau in taus {
        let mut opts = MserOptions::default();
        if tau.is_finite() {
            opts.time = HeatTime::Fiedler(tau);
        }
        let (rx, _) = shape_mser(&mx, &bx, &opts)?;
        let (ry, _) = shape_mser(&my, &by, &opts)?;
        println!("{:?}: {} regions on X, {} on Y", opts.time, rx.len(), ry.len());
        for (name, r) in [("X", &rx), ("Y", &ry)] {
            for (i, reg) in r.iter().enumerate() {
                println!(
                    "  {name}{i}: {:?} area {:.3} s {:.3}",
                    reg.polarity,
                    reg.area / bx.mass.iter().sum::<f64>(),
                    reg.stability
                );
            }
        }
        let (_, _, matches) = matched_mser_indicators((&mx, &bx), (&my, &by), &opts)?;
        let (mut direct, mut either) = (0.0, 0.0);
        for p in &matches {
            let (a, b) = (fraction(&rx[p.x], &ry[p.y], &gx, &gy), fraction(&rx[p.x], &ry[p.y], &gx, &sy));
            println!("  X{} ↔ Y{} cost {:.2}: correspondence {a:.2}, mirrored {b:.2}", p.x, p.y, p.cost);
            direct += a;
            either += a.max(b);
        }
        let c = matches.len().max(1) as f64;
        println!(
            "  {} matches, mean correspondence {:.3}, up to symmetry {:.3}",
            matches.len(),
            direct / c,
            either / c
        );
    }
    Ok(())
}
