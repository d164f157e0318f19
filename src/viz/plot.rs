//! Line plots as PNG: the cumulative error curves of the Princeton protocol (the paper's
//! Figure 7) and error-vs-parameter curves (Figures 5 and 6). Drawn with `plotters` into an RGB
//! buffer and written with [`super::write_png`]; the text uses the bundled DejaVu Sans font
//! (`assets/fonts`, see its licence there), so no system font library is needed.
//!
//! The figures of the paper are drawn here from the typed rows of the layers below: a benchmark
//! run's per-method summaries ([`benchmark_curves`], [`figure7_curves`]) and the sweep rows of
//! the sterile experiments ([`sweep_plot`]).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;

use super::Image;
use crate::benchmark::{MethodSummary, Report};
use crate::error::{Error, Result};
use crate::eval::standard_thresholds;
use crate::experiments::{Sweep, SweepMethod, SweepRow};

/// One line of a [`LinePlot`].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points (x, y) in data units, drawn in the given order; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    /// Dashed instead of solid (the paper's Figure 7 draws scarce data dashed).
    pub dashed: bool,
    /// Colour index into the plot palette; series with the same index share a colour.
    pub color: usize,
    /// Draw a dot at every point (for curves sampled at a few parameter values).
    pub markers: bool,
}

/// A plot of several lines on common axes.
#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// Title above the plot.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// x range (min, max), data units; `None` fits the data.
    pub x_range: Option<(f64, f64)>,
    /// y range (min, max), data units; `None` fits the data (from 0 when all y ≥ 0).
    pub y_range: Option<(f64, f64)>,
    /// The lines.
    pub series: Vec<Series>,
}

/// Colours of the series (Tableau 10), by [`Series::color`] modulo the length.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        // The bytes are a valid TrueType font shipped with the crate; a failure here would be a
        // packaging error, and plotters then falls back to drawing no text.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
        );
    });
}

fn fit_range(values: impl Iterator<Item = f64>, from_zero: bool) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return None;
    }
    if from_zero && lo >= 0.0 {
        lo = 0.0;
    }
    if hi - lo <= 1e-12 * hi.abs().max(1.0) {
        let pad = 0.5 * hi.abs().max(1.0);
        return Some((lo - pad, hi + pad));
    }
    let pad = 0.04 * (hi - lo);
    Some((if from_zero && lo == 0.0 { 0.0 } else { lo - pad }, hi + pad))
}

impl LinePlot {
    /// Draws the plot into a `width × height` image (pixels, each in 200..=4096).
    ///
    /// Errors when a size is out of range, there is no series or no finite point, or a given
    /// range is empty or not finite.
    pub fn draw(&self, width: u32, height: u32) -> Result<Image> {
        if !(200..=4096).contains(&width) || !(200..=4096).contains(&height) {
            return Err(Error::invalid(
                "plot size",
                format!("{width}×{height}: each side must be in 200..=4096 pixels"),
            ));
        }
        let points = || self.series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0.is_finite() && p.1.is_finite());
        if self.series.is_empty() || points().next().is_none() {
            return Err(Error::invalid("plot", format!("'{}' has no finite point to draw", self.title)));
        }
        let check = |r: (f64, f64), axis: &str| -> Result<(f64, f64)> {
            if r.0.is_finite() && r.1.is_finite() && r.0 < r.1 {
                Ok(r)
            } else {
                Err(Error::invalid("plot", format!("{axis} range {:?} is empty or not finite", r)))
            }
        };
        let xr = check(self.x_range.or_else(|| fit_range(points().map(|p| p.0), false)).expect("finite"), "x")?;
        let yr = check(self.y_range.or_else(|| fit_range(points().map(|p| p.1), true)).expect("finite"), "y")?;
        register_font();
        let mut rgb = vec![255u8; 3 * width as usize * height as usize];
        let e = |e: &dyn std::fmt::Display| Error::invalid("plot", format!("drawing '{}': {e}", self.title));
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
            root.fill(&WHITE).map_err(|x| e(&x))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(&self.title, ("sans-serif", 20))
                .margin(16)
                .x_label_area_size(48)
                .y_label_area_size(64)
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                .map_err(|x| e(&x))?;
            chart
                .configure_mesh()
                .x_desc(&self.x_label)
                .y_desc(&self.y_label)
                .label_style(("sans-serif", 14))
                .axis_desc_style(("sans-serif", 16))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|x| e(&x))?;
            for s in &self.series {
                let style = PALETTE[s.color % PALETTE.len()].stroke_width(2);
                let pts: Vec<(f64, f64)> =
                    s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
                let legend_dashed = s.dashed;
                let anno = if s.dashed {
                    chart.draw_series(DashedLineSeries::new(pts.clone(), 9, 6, style)).map_err(|x| e(&x))?
                } else {
                    chart.draw_series(LineSeries::new(pts.clone(), style)).map_err(|x| e(&x))?
                };
                anno.label(&s.label).legend(move |(x, y)| {
                    let segs: Vec<(i32, i32)> =
                        if legend_dashed { vec![(x, y), (x + 8, y)] } else { vec![(x, y), (x + 22, y)] };
                    PathElement::new(segs, style)
                });
                if s.markers {
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, PALETTE[s.color % PALETTE.len()].filled())))
                        .map_err(|x| e(&x))?;
                }
            }
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::LowerRight)
                .draw()
                .map_err(|x| e(&x))?;
            root.present().map_err(|x| e(&x))?;
        }
        Ok(Image { width, height, rgb })
    }

    /// Draws the plot ([`LinePlot::draw`]) and writes it as PNG at `path`.
    pub fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        super::write_png(path, &self.draw(width, height)?)
    }
}

/// The plot of cumulative error curves of the Princeton protocol: x the normalized geodesic
/// error r (0 … max threshold), y the percentage of correspondences with error ≤ r; one
/// [`Series`] per `(label, curve, dashed, color)`, each curve sampled at `thresholds` (fractions
/// in [0, 1], same length as `thresholds`).
pub fn cumulative_curves(title: &str, thresholds: &[f64], curves: &[(String, Vec<f64>, bool, usize)]) -> LinePlot {
    let r_max = thresholds.iter().copied().fold(0.0, f64::max);
    LinePlot {
        title: title.to_string(),
        x_label: "geodesic error".into(),
        y_label: "% correspondences".into(),
        x_range: Some((0.0, if r_max > 0.0 { r_max } else { 0.25 })),
        y_range: Some((0.0, 100.0)),
        series: curves
            .iter()
            .map(|(label, c, dashed, color)| Series {
                label: label.clone(),
                points: thresholds.iter().zip(c).map(|(&r, &f)| (r, 100.0 * f)).collect(),
                dashed: *dashed,
                color: *color,
                markers: false,
            })
            .collect(),
    }
}

/// The plot colour of a method: fixed for the four methods of funcorr (so that every plot draws
/// `fmap` in the same colour), else by position.
pub fn method_color(name: &str, position: usize) -> usize {
    match name {
        "fmap" => 0,
        "pokrass" => 1,
        "coupled" => 2,
        "completion" => 3,
        _ => 4 + position,
    }
}

/// The pooled cumulative curves of a benchmark run, one line per method that scored a pair,
/// coloured by [`method_color`]; dashed for scarce data (as the paper's Figure 7).
pub fn benchmark_curves(report: &Report, title: &str) -> LinePlot {
    summary_curves(&report.summaries(), !report.data.is_rich(), title)
}

fn summary_curves(summaries: &[MethodSummary], dashed: bool, title: &str) -> LinePlot {
    let curves: Vec<(String, Vec<f64>, bool, usize)> = summaries
        .iter()
        .enumerate()
        .filter(|(_, m)| m.pairs > 0)
        .map(|(i, m)| (m.method.clone(), m.curve.clone(), dashed, method_color(&m.method, i)))
        .collect();
    cumulative_curves(title, &standard_thresholds(), &curves)
}

/// Writes `curves.png` (900 × 640, [`benchmark_curves`]) into `dir` when a method scored a
/// pair; the path written, or None.
pub fn write_benchmark_curves(report: &Report, dir: &Path, title: &str) -> Result<Option<PathBuf>> {
    let summaries = report.summaries();
    if !summaries.iter().any(|m| m.pairs > 0) {
        return Ok(None);
    }
    let p = dir.join("curves.png");
    summary_curves(&summaries, !report.data.is_rich(), title).write_png(&p, 900, 640)?;
    Ok(Some(p))
}

/// The paper's Figure 7: the curves of several settings on one plot, labelled "method
/// (setting)", dashed where the setting's flag says so (scarce data); methods without a scored
/// pair are left out.
pub fn figure7_curves(title: &str, settings: &[(&str, bool, &[MethodSummary])]) -> LinePlot {
    let curves: Vec<(String, Vec<f64>, bool, usize)> = settings
        .iter()
        .flat_map(|&(setting, dashed, summaries)| {
            summaries.iter().filter(|m| m.pairs > 0).map(move |m| (m, setting, dashed))
        })
        .enumerate()
        .map(|(i, (m, setting, dashed))| {
            (format!("{} ({setting})", m.method), m.curve.clone(), dashed, method_color(&m.method, i))
        })
        .collect();
    cumulative_curves(title, &standard_thresholds(), &curves)
}

/// The paper's Figure 5 (soft error vs rank k) or Figure 6 (soft error vs μ3, on a log10 axis
/// with μ3 = 0 drawn one decade left of the smallest positive value; the baselines, which do
/// not depend on μ3, as flat dashed lines) from the rows of a sweep; `pair` and `q` go into the
/// title. y: mean soft error ×100.
pub fn sweep_plot(sweep: &Sweep, rows: &[SweepRow], pair: &str, q: usize) -> LinePlot {
    let rank = matches!(sweep, Sweep::Rank { .. });
    let min_pos = rows.iter().filter_map(|r| r.mu3).filter(|&m| m > 0.0).fold(f64::INFINITY, f64::min);
    let floor = if min_pos.is_finite() { min_pos.log10() - 1.0 } else { -1.0 };
    let x_of = |r: &SweepRow| -> f64 {
        if rank {
            return r.parameter;
        }
        r.mu3.map(|m| if m > 0.0 { m.log10() } else { floor }).unwrap_or(f64::NAN)
    };
    let xs: Vec<f64> = rows.iter().map(x_of).filter(|v| v.is_finite()).collect();
    let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    use SweepMethod as M;
    let series = [M::Ovsjanikov, M::Pokrass, M::Completion, M::GroundTruth]
        .iter()
        .enumerate()
        .filter_map(|(i, &m)| {
            let mine: Vec<&SweepRow> = rows.iter().filter(|r| r.method == m).collect();
            let mut points: Vec<(f64, f64)> = if !rank && m != M::Completion {
                mine.first().map(|r| vec![(lo, 100.0 * r.mean_soft_error), (hi, 100.0 * r.mean_soft_error)])?
            } else {
                mine.iter().map(|r| (x_of(r), 100.0 * r.mean_soft_error)).collect()
            };
            points.sort_by(|p, q| p.0.total_cmp(&q.0));
            let label = match m {
                M::Ovsjanikov => "Ovsjanikov et al. (5)",
                M::Pokrass => "Pokrass et al. (6)",
                M::GroundTruth => "ground-truth C0 (reference)",
                M::Completion => "matrix completion (11)",
            };
            (!points.is_empty()).then(|| Series {
                label: label.into(),
                points,
                dashed: !rank && m != M::Completion,
                color: if m == M::GroundTruth { 7 } else { i },
                markers: rank || m == M::Completion,
            })
        })
        .collect();
    LinePlot {
        title: match sweep {
            Sweep::Rank { .. } => format!("Figure 5: soft error vs rank k ({pair}, q = {q})"),
            Sweep::L1 { .. } => {
                let k = rows.first().map(|r| r.k).unwrap_or(0);
                format!("Figure 6: soft error vs μ3 ({pair}, q = {q}, k = {k})")
            }
        },
        x_label: if rank { "rank k".into() } else { "log10 μ3 (leftmost: μ3 = 0)".into() },
        y_label: "mean soft error ×100".into(),
        x_range: None,
        y_range: None,
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count_color(img: &Image, c: RGBColor) -> usize {
        img.rgb.chunks(3).filter(|p| p[0] == c.0 && p[1] == c.1 && p[2] == c.2).count()
    }

    #[test]
    fn curves_are_drawn_in_their_colours_with_text() {
        let t: Vec<f64> = (0..=50).map(|i| i as f64 * 0.005).collect();
        let rising: Vec<f64> = t.iter().map(|r| (r / 0.1).min(1.0)).collect();
        let plot = cumulative_curves(
            "test",
            &t,
            &[("a".into(), rising.clone(), false, 0), ("b".into(), rising.iter().map(|v| v * 0.5).collect(), true, 3)],
        );
        let img = plot.draw(640, 480).unwrap();
        assert_eq!((img.width, img.height, img.rgb.len()), (640, 480, 640 * 480 * 3));
        // Both lines appear in their own colours; the solid one covers more pixels than the
        // dashed one of the same length would.
        let (a, b) = (count_color(&img, PALETTE[0]), count_color(&img, PALETTE[3]));
        assert!(a > 300 && b > 100, "line pixels {a} {b}");
        // Text (the font was found): dark anti-aliased pixels outside the lines and the frame.
        let dark = img.rgb.chunks(3).filter(|p| p[0] < 100 && p[1] < 100 && p[2] < 100).count();
        assert!(dark > 500, "{dark} dark pixels");
        // No series: an error, not an empty picture.
        let empty = LinePlot { series: vec![], ..plot.clone() };
        assert!(empty.draw(640, 480).is_err());
        assert!(plot.draw(10, 480).is_err());
        let bad = LinePlot { x_range: Some((1.0, 1.0)), ..plot };
        assert!(bad.draw(640, 480).is_err());
    }

    #[test]
    fn figures_are_drawn_from_typed_rows() {
        use crate::experiments::SweepMethod as M;
        let row = |method, k: usize, mu3: Option<f64>, e: f64| SweepRow {
            method,
            parameter: mu3.unwrap_or(k as f64),
            k,
            mu3,
            mean_soft_error: e,
            seconds: 0.0,
            iterations: None,
            permutation_correct: None,
        };
        // Figure 6: the baselines flat over the μ3 range, μ3 = 0 one decade left of 1e-3.
        let rows = [
            row(M::GroundTruth, 45, None, 0.01),
            row(M::Ovsjanikov, 45, None, 0.05),
            row(M::Completion, 45, Some(0.0), 0.04),
            row(M::Completion, 45, Some(1e-3), 0.03),
            row(M::Completion, 45, Some(1e-1), 0.02),
        ];
        let p = sweep_plot(&Sweep::L1 { mu3s: vec![0.0, 1e-3, 1e-1], k: 45 }, &rows, "a → b", 50);
        assert_eq!(p.series.len(), 3, "no Pokrass rows, no Pokrass line");
        let ovs = &p.series[0];
        assert_eq!((ovs.points.as_slice(), ovs.dashed), (&[(-4.0, 5.0), (-1.0, 5.0)][..], true));
        assert_eq!(p.series[1].points[0], (-4.0, 4.0));
        assert!(p.title.contains("k = 45") && p.title.contains("a → b"));
        // Figure 7: one line per method and setting with a scored pair, colours by method.
        let summary = |method: &str, pairs| MethodSummary {
            method: method.into(),
            pairs,
            failed: 0,
            points: 0,
            summary: crate::eval::summarize(&[0.1]),
            curve: vec![0.5; standard_thresholds().len()],
            seconds_per_pair: 0.0,
        };
        let (scarce, rich) = ([summary("fmap", 2), summary("completion", 0)], [summary("completion", 2)]);
        let p = figure7_curves("t", &[("scarce", true, &scarce), ("rich", false, &rich)]);
        let labels: Vec<(&str, bool, usize)> = p.series.iter().map(|s| (s.label.as_str(), s.dashed, s.color)).collect();
        assert_eq!(labels, [("fmap (scarce)", true, 0), ("completion (rich)", false, 3)]);
    }

    #[test]
    fn ranges_fit_the_data() {
        assert_eq!(fit_range([1.0, 3.0].into_iter(), true).map(|r| r.0), Some(0.0));
        let (lo, hi) = fit_range([-1.0, 3.0, f64::NAN].into_iter(), true).unwrap();
        assert!(lo < -1.0 && hi > 3.0);
        let (lo, hi) = fit_range([2.0, 2.0].into_iter(), false).unwrap();
        assert!(lo < 2.0 && hi > 2.0);
        assert_eq!(fit_range([f64::NAN].into_iter(), false), None);
    }
}
