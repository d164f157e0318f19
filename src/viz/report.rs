//! The HTML report of a data set run (`index.html` beside `summary.md`): the summary table, the
//! cumulative error curves as inline SVG, and one row per pair and method, sortable, linking to
//! the pair's viewer page ([`super::html`]) — for the worst pairs of each method by default, for
//! every pair on request — so that a failed pair is two clicks away from a picture of why.
//!
//! Layout written by [`write_html_report`] into the run's directory:
//! `index.html`, `pairs/X__Y.METHOD.html` (one viewer page per chosen run) and `viewer/` (three.js
//! and the viewer's script, once for all pages).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::benchmark::{Dataset, MethodSummary, PairRun, Report};
use crate::error::{Error, Result};
use crate::shape::Shape;
use crate::viz::html::{escape, Scripts, VertexErrors, Viewer, ViewerShape};

/// Which runs get a viewer page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pages {
    /// The N runs of each method with the largest mean error (failed runs have no map and no
    /// page); 0: none.
    Worst(usize),
    /// Every run that produced a map.
    All,
}

impl std::str::FromStr for Pages {
    type Err = Error;

    /// `all` or a count N (the worst N runs of each method), the syntax of `--html`.
    fn from_str(s: &str) -> Result<Pages> {
        match s.trim() {
            "all" => Ok(Pages::All),
            t => t.parse::<usize>().map(Pages::Worst).map_err(|_| {
                Error::invalid("html", format!("{s:?}: expected `all` or a number N of pages per method (the worst N)"))
            }),
        }
    }
}

/// The relative path of the viewer page of a run: `pairs/X__Y.METHOD.html`.
pub fn page_path(run: &PairRun) -> String {
    format!("pairs/{}__{}.{}.html", run.source, run.target, run.method)
}

/// The runs (indices into `report.runs`) that get a page: see [`Pages`]. Sorted by index.
pub fn chosen_runs(report: &Report, pages: Pages) -> Vec<usize> {
    let scored = |i: &usize| report.runs[*i].outcome.is_ok();
    let mut chosen: Vec<usize> = match pages {
        Pages::All => (0..report.runs.len()).filter(scored).collect(),
        Pages::Worst(n) => {
            let mut out = Vec::new();
            for method in &report.methods {
                let mut runs: Vec<usize> =
                    (0..report.runs.len()).filter(|&i| &report.runs[i].method == method).filter(scored).collect();
                let mean = |i: usize| report.runs[i].outcome.as_ref().map(|s| s.summary.mean).unwrap_or(f64::INFINITY);
                runs.sort_by(|&a, &b| mean(b).total_cmp(&mean(a)).then(a.cmp(&b)));
                out.extend(runs.into_iter().take(n));
            }
            out
        }
    };
    chosen.sort_unstable();
    chosen
}

/// Writes `index.html`, the viewer pages of the runs chosen by `pages` and their shared scripts
/// into `out` (the run's directory; the shapes and ground truth are read again from `ds`).
/// Returns the paths written.
///
/// Errors: `Io`/`Parse` naming a shape or template file that cannot be read, `Io` naming an output
/// that cannot be written.
pub fn write_html_report(report: &Report, ds: &Dataset, out: &Path, title: &str, pages: Pages) -> Result<Vec<PathBuf>> {
    let chosen = chosen_runs(report, pages);
    let mut written = Vec::new();
    if !chosen.is_empty() {
        written.extend(crate::viz::html::write_scripts(&out.join("viewer"))?);
        let dir = out.join("pairs");
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    // Each shape is read once, however many pages show it.
    let mut shapes: BTreeMap<String, (Shape, Vec<[f64; 3]>)> = BTreeMap::new();
    let mut load = |name: &str| -> Result<()> {
        if !shapes.contains_key(name) {
            let shape = Shape::load(ds.shape_path(name)?)?;
            let v = match &shape {
                Shape::Mesh(m) => m.vertices().to_vec(),
                Shape::Points(p) if p.dim() == 3 => {
                    (0..p.len()).map(|i| std::array::from_fn(|d| p.point(i)[d])).collect()
                }
                Shape::Points(_) => Vec::new(),
            };
            shapes.insert(name.to_string(), (shape, v));
        }
        Ok(())
    };
    for &i in &chosen {
        load(&report.runs[i].source)?;
        load(&report.runs[i].target)?;
    }
    let faces = |s: &Shape| -> Vec<[u32; 3]> {
        match s {
            Shape::Mesh(m) => m.faces().to_vec(),
            Shape::Points(_) => Vec::new(),
        }
    };
    let mut links = BTreeMap::new();
    for &i in &chosen {
        let run = &report.runs[i];
        let Ok(score) = &run.outcome else { continue };
        let (sx, vx) = &shapes[&run.source];
        let (sy, vy) = &shapes[&run.target];
        if vx.is_empty() || vy.is_empty() {
            continue;
        }
        let (fx, fy) = (faces(sx), faces(sy));
        let gt = ds.ground_truth(&run.source, &run.target, vx.len(), vy.len(), report.symmetric)?;
        let mut page = Viewer::new(
            format!("{} → {} ({})", run.source, run.target, run.method),
            ViewerShape { vertices: vx, faces: &fx, colors: None },
        );
        page.x_name = run.source.clone();
        page.y = Some(ViewerShape { vertices: vy, faces: &fy, colors: None });
        page.y_name = run.target.clone();
        page.map_xy = Some(&score.map_xy);
        page.method = Some(format!("method {}, data {}", run.method, report.data));
        page.errors = Some(VertexErrors::spread(vx, &gt, &score.errors, report.geodesics.name())?);
        let rel = page_path(run);
        let path = out.join(&rel);
        crate::io::write_atomic(&path, page.html_with(Scripts::Beside("../viewer/"))?)?;
        written.push(path);
        links.insert(i, rel);
    }
    let index = out.join("index.html");
    crate::io::write_atomic(&index, index_html(report, ds, title, &links))?;
    written.push(index);
    Ok(written)
}

/// A URL path segment with everything but unreserved characters and `/` percent-encoded.
fn url_path(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~/".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Colours of the methods' curves (Tableau 10).
const PALETTE: [&str; 10] =
    ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"];

/// The cumulative error curves of the methods as an inline SVG: fraction of template points with
/// error ≤ r against r, one line per method (`thresholds` and each summary's `curve` of equal
/// length, as [`crate::eval::standard_thresholds`]).
pub fn curves_svg(summaries: &[MethodSummary], thresholds: &[f64]) -> String {
    let (w, h, left, right, top, bottom) = (640.0, 380.0, 52.0, 170.0, 14.0, 42.0);
    let r_max = thresholds.last().copied().filter(|&r| r > 0.0).unwrap_or(0.25);
    let px = |r: f64| left + (w - left - right) * r / r_max;
    let py = |f: f64| top + (h - top - bottom) * (1.0 - f);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {w} {h}\" width=\"{w}\" height=\"{h}\" \
         font-family=\"sans-serif\" font-size=\"11\" role=\"img\" aria-label=\"cumulative error curves\">\n"
    );
    for k in 0..=5 {
        let f = k as f64 / 5.0;
        s += &format!(
            "<line x1=\"{left}\" x2=\"{:.1}\" y1=\"{y:.1}\" y2=\"{y:.1}\" stroke=\"#e6e6e6\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}%</text>\n",
            w - right,
            left - 5.0,
            py(f) + 4.0,
            (100.0 * f).round(),
            y = py(f)
        );
    }
    let step = if r_max > 0.3 { 0.1 } else { 0.05 };
    let mut r = 0.0;
    while r <= r_max + 1e-9 {
        s += &format!(
            "<line x1=\"{x:.1}\" x2=\"{x:.1}\" y1=\"{top}\" y2=\"{:.1}\" stroke=\"#e6e6e6\"/>\
             <text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n",
            h - bottom,
            h - bottom + 15.0,
            (r * 1000.0).round() / 1000.0,
            x = px(r)
        );
        r += step;
    }
    s += &format!(
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">geodesic error r (/ √area)</text>\n\
         <text transform=\"translate(13 {:.1}) rotate(-90)\" text-anchor=\"middle\">% of points with error ≤ r</text>\n",
        (left + w - right) / 2.0,
        h - 6.0,
        (top + h - bottom) / 2.0
    );
    for (k, m) in summaries.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        if m.pairs > 0 && m.curve.len() == thresholds.len() {
            let pts: Vec<String> =
                thresholds.iter().zip(&m.curve).map(|(&r, &f)| format!("{:.1},{:.1}", px(r), py(f))).collect();
            s += &format!(
                "<polyline fill=\"none\" stroke=\"{color}\" stroke-width=\"2\" points=\"{}\"/>\n",
                pts.join(" ")
            );
        }
        let y = top + 10.0 + 18.0 * k as f64;
        let label = if m.pairs > 0 {
            format!("{} ({:.2})", m.method, 100.0 * m.summary.mean)
        } else {
            format!("{} (no pair)", m.method)
        };
        s += &format!(
            "<line x1=\"{:.1}\" x2=\"{:.1}\" y1=\"{y:.1}\" y2=\"{y:.1}\" stroke=\"{color}\" stroke-width=\"3\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n",
            w - right + 12.0,
            w - right + 32.0,
            w - right + 37.0,
            y + 4.0,
            escape(&label)
        );
    }
    s += "</svg>";
    s
}

/// The sort script of the pairs table: clicking a header sorts by its column (numbers by value,
/// empty cells last), again to reverse.
const SORT_JS: &str = r#"
for (const table of document.querySelectorAll('table.sortable')) {
  const heads = table.tHead.rows[0].cells;
  for (let c = 0; c < heads.length; c++) {
    heads[c].addEventListener('click', () => {
      const asc = heads[c].dataset.dir !== 'asc';
      for (const h of heads) delete h.dataset.dir;
      heads[c].dataset.dir = asc ? 'asc' : 'desc';
      const rows = [...table.tBodies[0].rows];
      const key = (r) => { const v = r.cells[c].dataset.v ?? r.cells[c].textContent; const n = parseFloat(v); return v === '' ? null : isNaN(n) ? v : n; };
      rows.sort((a, b) => {
        const x = key(a), y = key(b);
        if (x === null || y === null) return (x === null) - (y === null);
        return (x < y ? -1 : x > y ? 1 : 0) * (asc ? 1 : -1);
      });
      for (const r of rows) table.tBodies[0].appendChild(r);
    });
  }
}
"#;

const REPORT_CSS: &str = "body{font:14px/1.4 system-ui,sans-serif;margin:18px 24px;color:#222}\
h1{font-size:20px}h2{font-size:16px;margin-top:26px}\
table{border-collapse:collapse;margin:6px 0}td,th{padding:3px 10px;border-bottom:1px solid #e4e4e4;text-align:right}\
td:nth-child(-n+3),th:nth-child(-n+3){text-align:left}\
table.sortable th{cursor:pointer;user-select:none;background:#f6f6f6}\
th[data-dir=asc]::after{content:' ▲'}th[data-dir=desc]::after{content:' ▼'}\
tr.failed td{color:#a33}code{font-size:12px;background:#f4f4f4;padding:1px 4px}.note{color:#555}";

/// The `index.html` of a run: `links` maps the index of a run in `report.runs` to its page.
fn index_html(report: &Report, ds: &Dataset, title: &str, links: &BTreeMap<usize, String>) -> String {
    let summaries = report.summaries();
    let thresholds = crate::eval::standard_thresholds();
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{t}</title>\n\
         <meta name=\"generator\" content=\"{g}\">\n<style>{REPORT_CSS}</style>\n</head>\n<body>\n<h1>{t}</h1>\n",
        t = escape(title),
        g = concat!("funcorr ", env!("CARGO_PKG_VERSION"))
    );
    s += &format!(
        "<p class=\"note\">Data <code>{}</code>, hard error (12) with {} geodesics, symmetric flips {}allowed, \
         {} eigenpairs per shape; {} runs in {:.1} s. Data set <code>{}</code>. Files: \
         <a href=\"summary.md\">summary.md</a>, <a href=\"pairs.csv\">pairs.csv</a>, <a href=\"pairs.json\">pairs.json</a>, \
         <code>maps/</code>.</p>\n",
        escape(&report.data.to_string()),
        report.geodesics.name(),
        if report.symmetric { "" } else { "not " },
        report.k,
        report.runs.len(),
        report.wall_seconds,
        escape(&ds.dir().display().to_string())
    );
    s += "<h2>Summary</h2>\n<table>\n<thead><tr><th>method</th><th>pairs</th><th>failed</th><th>mean error ×100</th>\
          <th>≤ 0.05</th><th>≤ 0.10</th><th>≤ 0.25</th><th>s / pair</th></tr></thead>\n<tbody>\n";
    for m in &summaries {
        if m.pairs == 0 {
            s += &format!(
                "<tr><td>{}</td><td>0</td><td>{}</td><td>–</td><td>–</td><td>–</td><td>–</td><td>–</td></tr>\n",
                escape(&m.method),
                m.failed
            );
            continue;
        }
        s += &format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td>{:.1}%</td><td>{:.1}%</td><td>{:.1}%</td><td>{:.2}</td></tr>\n",
            escape(&m.method),
            m.pairs,
            m.failed,
            100.0 * m.summary.mean,
            100.0 * m.summary.at_005,
            100.0 * m.summary.at_010,
            100.0 * m.summary.at_025,
            m.seconds_per_pair
        );
    }
    s += "</tbody>\n</table>\n<h2>Cumulative error curves</h2>\n";
    s += &curves_svg(&summaries, &thresholds);
    let pages = links.len();
    s += &format!(
        "\n<h2>Pairs</h2>\n<p class=\"note\">One row per pair and method, worst first; click a column's header to sort \
         by it. {} of {} runs have a viewer page (X coloured by its error, click a vertex to see its image); \
         for another run, <code>funcorr view</code> makes one (hover over “command”).</p>\n",
        pages,
        report.runs.len()
    );
    s += "<table class=\"sortable\">\n<thead><tr><th>source</th><th>target</th><th>method</th><th>mean error ×100</th>\
          <th>≤ 0.05</th><th>≤ 0.10</th><th>seconds</th><th>viewer</th></tr></thead>\n<tbody>\n";
    let mut order: Vec<usize> = (0..report.runs.len()).collect();
    let mean = |i: usize| report.runs[i].outcome.as_ref().map(|s| s.summary.mean).unwrap_or(f64::INFINITY);
    order.sort_by(|&a, &b| mean(b).total_cmp(&mean(a)).then(a.cmp(&b)));
    for i in order {
        let run = &report.runs[i];
        let (src, tgt, method) = (escape(&run.source), escape(&run.target), escape(&run.method));
        match &run.outcome {
            Ok(score) => {
                let viewer = match links.get(&i) {
                    Some(rel) => format!("<a href=\"{}\">view</a>", escape(&url_path(rel))),
                    None => {
                        format!("<span title=\"{}\">command</span>", escape(&view_command(ds, run, report.symmetric)))
                    }
                };
                s += &format!(
                    "<tr><td>{src}</td><td>{tgt}</td><td>{method}</td><td data-v=\"{:.6}\">{:.2}</td><td>{:.1}%</td>\
                     <td>{:.1}%</td><td>{:.2}</td><td data-v=\"{}\">{viewer}</td></tr>\n",
                    100.0 * score.summary.mean,
                    100.0 * score.summary.mean,
                    100.0 * score.summary.at_005,
                    100.0 * score.summary.at_010,
                    score.seconds,
                    u8::from(links.contains_key(&i)),
                );
            }
            Err(msg) => {
                s += &format!(
                    "<tr class=\"failed\"><td>{src}</td><td>{tgt}</td><td>{method}</td><td data-v=\"\" title=\"{}\">failed</td>\
                     <td data-v=\"\"></td><td data-v=\"\"></td><td data-v=\"\"></td><td data-v=\"\"></td></tr>\n",
                    escape(msg)
                );
            }
        }
    }
    s += "</tbody>\n</table>\n<script>";
    s += SORT_JS;
    s += "</script>\n</body>\n</html>\n";
    s
}

/// The `index.html` of `funcorr reproduce benchmark`: the figure (`image`, a file beside the
/// page), the per-method summaries of each setting (e.g. `scarce`, `rich`; `dashed` unused here)
/// and links to each setting's own `index.html`.
pub fn settings_index_html(title: &str, settings: &[(&str, bool, &[MethodSummary])], image: &str) -> String {
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{t}</title>\n\
         <style>{REPORT_CSS}</style>\n</head>\n<body>\n<h1>{t}</h1>\n<p><img src=\"{img}\" alt=\"cumulative error curves\" \
         style=\"max-width:100%\"></p>\n",
        t = escape(title),
        img = escape(&url_path(image))
    );
    for (name, _, summaries) in settings {
        s += &format!(
            "<h2>{n} data — <a href=\"{href}\">pairs and viewers</a></h2>\n",
            n = escape(name),
            href = escape(&url_path(&format!("{name}/index.html")))
        );
        s += &format!("<pre>{}</pre>\n", escape(&crate::benchmark::table_of(summaries)));
    }
    s += "</body>\n</html>\n";
    s
}

/// The `funcorr view` command line that makes the page of a run without one (run from the
/// report's directory).
fn view_command(ds: &Dataset, run: &PairRun, symmetric: bool) -> String {
    let path = |name: &str| ds.shape_path(name).map(|p| p.display().to_string()).unwrap_or_else(|_| name.to_string());
    let corres = |name: &str, sym: bool| {
        let file = format!("{name}{}.vts", if sym { ".sym" } else { "" });
        let p = ds.dir().join("corres").join(&file);
        if p.is_file() { p } else { ds.dir().join(file) }.display().to_string()
    };
    let mut c = format!(
        "funcorr view {} {} --map maps/{}__{}.{}.txt --gt-source {} --gt-target {}",
        path(&run.source),
        path(&run.target),
        run.source,
        run.target,
        run.method,
        corres(&run.source, false),
        corres(&run.target, false)
    );
    if symmetric {
        c += &format!(" --gt-target-sym {}", corres(&run.target, true));
    }
    c += &format!(" -o {}", page_path(run));
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::benchmark::PairScore;
    use crate::eval::Summary;

    fn run(source: &str, method: &str, mean: Option<f64>) -> PairRun {
        PairRun {
            source: source.into(),
            target: "t".into(),
            method: method.into(),
            outcome: match mean {
                Some(mean) => Ok(PairScore {
                    points: 1,
                    errors: vec![mean],
                    summary: Summary { mean, at_005: 0.5, at_010: 0.7, at_025: 1.0 },
                    curve: vec![0.0; 51],
                    seconds: 1.0,
                    stages: vec![],
                    q: 3,
                    solver: None,
                    map_xy: vec![0],
                }),
                None => Err("no data".into()),
            },
        }
    }

    fn report() -> Report {
        Report {
            data: "segments".parse::<crate::descriptors::spec::PairDataSpec>().unwrap().for_dataset().unwrap(),
            symmetric: true,
            geodesics: crate::geodesic::GeodesicMethod::Exact,
            methods: vec!["a".into(), "b".into()],
            runs: vec![
                run("p", "a", Some(0.1)),
                run("p", "b", Some(0.3)),
                run("q", "a", Some(0.5)),
                run("q", "b", None),
                run("r", "a", Some(0.2)),
                run("r", "b", Some(0.05)),
            ],
            shape_seconds: Default::default(),
            k: 10,
            wall_seconds: 1.0,
        }
    }

    #[test]
    fn the_worst_runs_of_each_method_get_pages() {
        let r = report();
        assert_eq!(chosen_runs(&r, Pages::Worst(1)), vec![1, 2]);
        assert_eq!(chosen_runs(&r, Pages::Worst(2)), vec![1, 2, 4, 5]);
        assert_eq!(chosen_runs(&r, Pages::All), vec![0, 1, 2, 4, 5]);
        assert!(chosen_runs(&r, Pages::Worst(0)).is_empty());
        assert_eq!("all".parse::<Pages>().unwrap(), Pages::All);
        assert_eq!(" 7".parse::<Pages>().unwrap(), Pages::Worst(7));
        assert!("most".parse::<Pages>().unwrap_err().to_string().contains("html"));
        assert_eq!(page_path(&r.runs[1]), "pairs/p__t.b.html");
        assert_eq!(url_path("pairs/a b#c.html"), "pairs/a%20b%23c.html");
    }

    #[test]
    fn the_index_lists_every_run_worst_first_and_links_the_pages() {
        let dir = crate::io::test_util::tmp_dir("report-index");
        std::fs::write(dir.join("p.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap();
        let ds = Dataset::open(&dir).unwrap();
        let r = report();
        let links: BTreeMap<usize, String> = [(2, page_path(&r.runs[2]))].into();
        let html = index_html(&r, &ds, "a <run>", &links);
        assert!(html.contains("<title>a &lt;run&gt;</title>"));
        assert!(html.contains("<a href=\"pairs/q__t.a.html\">view</a>"));
        assert!(html.contains("funcorr view") && html.contains("--map maps/p__t.a.txt"));
        assert_eq!(html.matches("<polyline").count(), 2);
        // Rows: worst first, the failed run before all (q/b), then q/a (50.00); r/b (5.00) last.
        let rows: Vec<&str> = html.split("<tr").skip(1 + 1 + 2 + 1).collect();
        assert!(rows[0].contains("failed") && rows[0].contains("title=\"no data\""), "{}", rows[0]);
        assert!(rows[1].contains("50.00"), "{}", rows[1]);
        assert_eq!(rows.len(), 6);
        assert!(rows[5].contains("5.00"), "{}", rows[5]);
        let svg = curves_svg(&r.summaries(), &crate::eval::standard_thresholds());
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>") && svg.contains("a (26.67)"));
    }
}
