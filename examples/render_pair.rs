//! Renders two shapes side by side to a PNG, X coloured by position and Y by the identity map
//! (when X and Y have as many vertices; otherwise Y is coloured by its own position).
//!
//! ```sh
//! cargo run --release --example render_pair -- data/faust/tr_reg_000.off data/faust/tr_reg_001.off pair.png
//! cargo run --release --example render_pair -- X.off Y.off pair.png 30,10   # azimuth,elevation
//! ```
//!
//! The image is 1600 × 900 pixels; set `RENDER_SIZE=WxH` to change it.

use std::path::Path;
use std::time::Instant;

use funcorr::shape::Shape;
use funcorr::viz::{position_colors, pull_back_colors, render_pair, write_png, ColoredShape, View};
use funcorr::{Error, Result};

fn geometry(s: &Shape) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    match s {
        Shape::Mesh(m) => (m.vertices().to_vec(), m.faces().to_vec()),
        Shape::Points(p) if p.dim() == 3 => {
            ((0..p.len()).map(|i| [p.point(i)[0], p.point(i)[1], p.point(i)[2]]).collect(), vec![])
        }
        Shape::Points(p) => {
            ((0..p.len()).map(|i| std::array::from_fn(|d| p.point(i).get(d).copied().unwrap_or(0.0))).collect(), vec![])
        }
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !(3..=4).contains(&args.len()) {
        eprintln!("usage: render_pair X.off Y.off out.png [azimuth,elevation]");
        std::process::exit(2);
    }
    let view = args.get(3).map(|s| View::parse(s)).transpose()?.unwrap_or_default();
    let (width, height) = match std::env::var("RENDER_SIZE") {
        Ok(s) => {
            let bad = || Error::invalid("RENDER_SIZE", format!("{s:?} is not WxH"));
            let (w, h) = s.split_once('x').ok_or_else(bad)?;
            (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?)
        }
        Err(_) => (1600, 900),
    };
    let (vx, fx) = geometry(&Shape::load(Path::new(&args[0]))?);
    let (vy, fy) = geometry(&Shape::load(Path::new(&args[1]))?);
    let cx = position_colors(&vx);
    let cy = if vx.len() == vy.len() {
        pull_back_colors(&cx, &(0..vy.len()).collect::<Vec<_>>()).expect("identity map is in range")
    } else {
        eprintln!("X has {} vertices and Y {}: Y coloured by its own position", vx.len(), vy.len());
        position_colors(&vy)
    };
    let x = ColoredShape { vertices: &vx, faces: &fx, colors: &cx };
    let y = ColoredShape { vertices: &vy, faces: &fy, colors: &cy };
    let t = Instant::now();
    let img = render_pair(&x, &y, width, height, &view)?;
    let render_time = t.elapsed();
    write_png(Path::new(&args[2]), &img)?;
    println!(
        "{}: {width}×{height}, view {view}, {} + {} vertices, rendered in {:.1} ms",
        args[2],
        vx.len(),
        vy.len(),
        render_time.as_secs_f64() * 1e3
    );
    Ok(())
}
