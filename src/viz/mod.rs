//! Colours for looking at correspondences (the paper's Figure 8): X coloured by a smooth
//! function of position, Y coloured by pulling those colours back through a map, and scalar
//! functions (e.g. a transferred delta, Figures 5–6) through a colour map; [`mod@render`] draws
//! coloured meshes and point clouds to an image and writes it as PNG, without a GPU.
//! [`plot`] draws the paper's figures (line plots); it needs the default feature `plot`.

#[cfg(feature = "plot")]
pub mod plot;
pub mod render;

pub use render::{render, render_pair, write_png, ColoredShape, Image, View};

/// A smooth colouring by position: each coordinate, normalized to [0, 1] over the bounding box,
/// becomes one RGB channel (with a gamma of 0.8 to lift dark corners). One colour per vertex.
pub fn position_colors(vertices: &[[f64; 3]]) -> Vec<[u8; 3]> {
    let (lo, hi) = crate::shape::bounding_box(vertices);
    vertices
        .iter()
        .map(|p| {
            let mut c = [0u8; 3];
            for d in 0..3 {
                let range = hi[d] - lo[d];
                let t = if range > 0.0 { (p[d] - lo[d]) / range } else { 0.5 };
                c[d] = (255.0 * t.clamp(0.0, 1.0).powf(0.8)).round() as u8;
            }
            c
        })
        .collect()
}

/// Colours of Y pulled back from X through `map_yx` (for every vertex of Y, a vertex of X).
/// Errors (as `None`) when the map points outside X.
pub fn pull_back_colors(colors_x: &[[u8; 3]], map_yx: &[usize]) -> Option<Vec<[u8; 3]>> {
    map_yx.iter().map(|&i| colors_x.get(i).copied()).collect()
}

/// A scalar function through a perceptual blue–white–red colour map: values are scaled by the
/// largest absolute value, negative blue, zero white, positive red (the paper's "hot" and "cold").
pub fn diverging_colors(values: &[f64]) -> Vec<[u8; 3]> {
    let m = values.iter().filter(|v| v.is_finite()).fold(0.0f64, |a, v| a.max(v.abs()));
    values
        .iter()
        .map(|&v| {
            let t = if m > 0.0 && v.is_finite() { (v / m).clamp(-1.0, 1.0) } else { 0.0 };
            let fade = |x: f64| (255.0 * (1.0 - x)).round() as u8;
            if t >= 0.0 {
                [255, fade(t), fade(t)]
            } else {
                [fade(-t), fade(-t), 255]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours() {
        let v = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [0.5, 1.0, 1.5]];
        let c = position_colors(&v);
        assert_eq!(c[0], [0, 0, 0]);
        assert_eq!(c[1], [255, 255, 255]);
        assert!(c[2][0] > 127 && c[2][0] < 255);
        assert_eq!(pull_back_colors(&c, &[1, 0, 1]).unwrap(), vec![c[1], c[0], c[1]]);
        assert!(pull_back_colors(&c, &[3]).is_none());
        let d = diverging_colors(&[-2.0, 0.0, 1.0, f64::NAN]);
        assert_eq!(d[0], [0, 0, 255]);
        assert_eq!(d[1], [255, 255, 255]);
        assert_eq!(d[2], [255, 128, 128]);
        assert_eq!(d[3], [255, 255, 255]);
    }
}
