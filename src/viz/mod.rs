//! Colours for looking at correspondences (the paper's Figure 8): X coloured by a smooth
//! function of position, Y coloured by pulling those colours back through a map, and scalar
//! functions (e.g. a transferred delta, Figures 5–6) through a colour map; [`mod@render`] draws
//! coloured meshes and point clouds to an image and writes it as PNG, without a GPU.
//! [`plot`] draws the paper's figures (line plots); it needs the default feature `plot`.
//! [`html`] writes the interactive viewer page of a map (three.js, in any browser or notebook)
//! and [`report`] the `index.html` of a data set run.

pub mod html;
#[cfg(feature = "plot")]
pub mod plot;
pub mod render;
pub mod report;

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

/// Stops of the error heat map ([`heat_color`]): (fraction of the top of the scale, sRGB colour),
/// light yellow at zero through orange and red to dark red at the top (ColorBrewer's YlOrRd
/// endpoints). Half of the colour range lies in the lowest 20 % of the scale, where most errors
/// of a good map are.
pub const HEAT_STOPS: [(f64, [u8; 3]); 5] =
    [(0.0, [255, 255, 204]), (0.1, [254, 217, 118]), (0.2, [253, 141, 60]), (0.4, [227, 26, 28]), (1.0, [128, 0, 38])];

/// Colour of a value not known (NaN) in [`heat_color`]: light grey.
pub const NO_VALUE: [u8; 3] = [190, 190, 190];

/// The error heat map: `value` in [0, `max`] through [`HEAT_STOPS`] (linear between stops),
/// values above `max` the top colour, below 0 the bottom one, NaN (no value) [`NO_VALUE`].
/// `max` must be positive (else every value gets the top colour).
pub fn heat_color(value: f64, max: f64) -> [u8; 3] {
    if value.is_nan() {
        return NO_VALUE;
    }
    let t = if max > 0.0 { (value / max).clamp(0.0, 1.0) } else { 1.0 };
    let k = HEAT_STOPS.iter().position(|&(s, _)| s >= t).unwrap_or(HEAT_STOPS.len() - 1).max(1);
    let ((s0, c0), (s1, c1)) = (HEAT_STOPS[k - 1], HEAT_STOPS[k]);
    let u = ((t - s0) / (s1 - s0)).clamp(0.0, 1.0);
    std::array::from_fn(|d| (f64::from(c0[d]) + u * (f64::from(c1[d]) - f64::from(c0[d]))).round() as u8)
}

/// [`heat_color`] of every value (n values → n colours), e.g. per-vertex geodesic errors with
/// `max` the top of the colour bar.
pub fn heat_colors(values: &[f64], max: f64) -> Vec<[u8; 3]> {
    values.iter().map(|&v| heat_color(v, max)).collect()
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

    #[test]
    fn heat_map() {
        assert_eq!(heat_color(0.0, 0.25), HEAT_STOPS[0].1);
        assert_eq!(heat_color(-1.0, 0.25), HEAT_STOPS[0].1);
        assert_eq!(heat_color(0.25, 0.25), [128, 0, 38]);
        assert_eq!(heat_color(9.0, 0.25), [128, 0, 38]);
        assert_eq!(heat_color(0.1, 0.25), [227, 26, 28]);
        assert_eq!(heat_color(f64::NAN, 0.25), NO_VALUE);
        // Halfway between the stops at 0.1 and 0.2 of the scale.
        assert_eq!(heat_color(0.0375, 0.25), [254, 179, 89]);
        // Darker (smaller channel sum) as the value grows.
        let sums: Vec<u32> =
            (0..=20).map(|i| heat_color(i as f64 * 0.0125, 0.25).iter().map(|&c| c as u32).sum()).collect();
        assert!(sums.windows(2).all(|w| w[1] < w[0]), "{sums:?}");
        assert_eq!(heat_colors(&[0.0, f64::NAN], 1.0), vec![HEAT_STOPS[0].1, NO_VALUE]);
    }
}
