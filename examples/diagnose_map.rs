//! Exploration (issue 27): where a map X → Y is right, mirrored or wrong. Renders X from the
//! front and the back, each template point coloured green (error < 5 % of √area(Y)), blue
//! (mirrored: only the symmetric error below it) or red (wrong), and prints the fractions.
//!
//! ```sh
//! cargo run --release --example diagnose_map -- X.off Y.off X.vts Y.vts Y.sym.vts map.txt out.png
//! ```

use std::path::Path;

use funcorr::geodesic::ExactGeodesics;
use funcorr::shape::Shape;
use funcorr::viz::{write_png, ColoredShape, View};
use funcorr::Result;

fn read_idx(p: &str, one: bool) -> Vec<usize> {
    std::fs::read_to_string(p)
        .unwrap()
        .split_whitespace()
        .map(|t| t.parse::<usize>().unwrap() - usize::from(one))
        .collect()
}

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let Shape::Mesh(x) = Shape::load(Path::new(&a[0]))? else { panic!() };
    let Shape::Mesh(y) = Shape::load(Path::new(&a[1]))? else { panic!() };
    let (gx, gy, gs) = (read_idx(&a[2], true), read_idx(&a[3], true), read_idx(&a[4], true));
    let map = read_idx(&a[5], false);
    let geo = ExactGeodesics::new(&y)?;
    let sa = y.total_area().sqrt();
    let d = geo.pair_distances(&gy.iter().zip(&gx).map(|(&t, &i)| (t, map[i])).collect::<Vec<_>>())?;
    let s = geo.pair_distances(&gs.iter().zip(&gx).map(|(&t, &i)| (t, map[i])).collect::<Vec<_>>())?;
    let mut class = vec![3u8; x.n_vertices()];
    let mut counts = [0usize; 3];
    for (k, &i) in gx.iter().enumerate() {
        let c = if d[k] / sa < 0.05 {
            0
        } else if s[k] / sa < 0.05 {
            1
        } else {
            2
        };
        class[i] = c;
        counts[c as usize] += 1;
    }
    let tot = gx.len() as f64;
    println!(
        "right {:.3} mirrored {:.3} wrong {:.3}; mean direct {:.2} sym {:.2}",
        counts[0] as f64 / tot,
        counts[1] as f64 / tot,
        counts[2] as f64 / tot,
        100.0 * d.iter().sum::<f64>() / tot / sa,
        100.0 * d.iter().zip(&s).map(|(a, b)| a.min(*b)).sum::<f64>() / tot / sa
    );
    let colors: Vec<[u8; 3]> = class
        .iter()
        .map(|c| match c {
            0 => [60, 200, 60],
            1 => [60, 90, 230],
            2 => [230, 50, 50],
            _ => [180, 180, 180],
        })
        .collect();
    let cx = ColoredShape { vertices: x.vertices(), faces: x.faces(), colors: &colors };
    let front = funcorr::viz::render(&cx, 600, 700, &View::new(0.0, 0.0)?)?;
    let back = funcorr::viz::render(&cx, 600, 700, &View::new(180.0, 0.0)?)?;
    let mut rgb = Vec::with_capacity(1200 * 700 * 3);
    for yy in 0..700usize {
        rgb.extend_from_slice(&front.rgb[yy * 1800..(yy + 1) * 1800]);
        rgb.extend_from_slice(&back.rgb[yy * 1800..(yy + 1) * 1800]);
    }
    let both = funcorr::viz::Image { width: 1200, height: 700, rgb };
    write_png(Path::new(&a[6]), &both)?;
    Ok(())
}
