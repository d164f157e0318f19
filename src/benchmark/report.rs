//! Per-method summaries pooled over the pairs, their table, cumulative curves and files.

#[allow(unused_imports)]
use super::*;

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

/// Per-method results pooled over the pairs of a run.
#[derive(Debug, Clone, Serialize)]
pub struct MethodSummary {
    /// Method name.
    pub method: String,
    /// Pairs scored.
    pub pairs: usize,
    /// Pairs where the method (or the pair's data) failed; they are not in the numbers.
    pub failed: usize,
    /// Template points scored, over all pairs.
    pub points: usize,
    /// Mean and fractions over all points of all scored pairs (the Princeton protocol pools the
    /// correspondences).
    pub summary: Summary,
    /// Pooled cumulative curve at [`eval::standard_thresholds`].
    pub curve: Vec<f64>,
    /// Mean seconds per scored pair (method stages, see [`PairScore::seconds`]).
    pub seconds_per_pair: f64,
}

/// A benchmark run: all pair runs and the shapes' preparation times.
#[derive(Debug, Clone)]
pub struct Report {
    /// Data spec of the run.
    pub data: PairDataSpec,
    /// Whether symmetric flips were allowed.
    pub symmetric: bool,
    /// The geodesic solver.
    pub geodesics: GeodesicMethod,
    /// Method names in order.
    pub methods: Vec<String>,
    /// Every (pair, method), pairs in input order.
    pub runs: Vec<PairRun>,
    /// Seconds to prepare each shape (read, Laplacian, eigenbasis or cache load).
    pub shape_seconds: BTreeMap<String, f64>,
    /// Eigenpairs per shape.
    pub k: usize,
    /// Wall-clock seconds of the whole run.
    pub wall_seconds: f64,
}

/// Progress of [`run`]: (stage `"shapes"` or `"pairs"`, done, total).
pub type Progress<'a> = &'a (dyn Fn(&str, usize, usize) + Sync);

impl Report {
    /// Per-method summaries, in method order.
    pub fn summaries(&self) -> Vec<MethodSummary> {
        let thresholds = eval::standard_thresholds();
        self.methods
            .iter()
            .map(|name| {
                let runs: Vec<&PairRun> = self.runs.iter().filter(|r| &r.method == name).collect();
                let scores: Vec<&PairScore> = runs.iter().filter_map(|r| r.outcome.as_ref().ok()).collect();
                let all: Vec<f64> = scores.iter().flat_map(|s| s.errors.iter().copied()).collect();
                MethodSummary {
                    method: name.clone(),
                    pairs: scores.len(),
                    failed: runs.len() - scores.len(),
                    points: all.len(),
                    summary: eval::summarize(&all),
                    curve: eval::cumulative_curve(&all, &thresholds),
                    seconds_per_pair: scores.iter().map(|s| s.seconds).sum::<f64>() / scores.len().max(1) as f64,
                }
            })
            .collect()
    }

    /// The summary as a Markdown table: method, pairs (failed), mean error ×100, fractions at
    /// r = 0.05, 0.10, 0.25 (%), seconds per pair.
    pub fn table(&self) -> String {
        table_of(&self.summaries())
    }

    /// The plot of the pooled cumulative curves, one line per method (dashed for scarce data).
    pub fn plot(&self, title: &str) -> crate::viz::plot::LinePlot {
        plot_of(&self.data, &self.summaries(), title)
    }

    /// Writes the run to `out` (created): `pairs.csv` (one row per pair and method),
    /// `pairs.json` (the same with curves and stage times), `maps/X__Y.METHOD.txt` (0-based
    /// maps X → Y, readable by `funcorr eval`), `summary.csv`, `summary.md`, `summary.json` and
    /// `curves.png` (one line per method). Returns the paths written.
    pub fn write(&self, out: &Path, title: &str) -> Result<Vec<PathBuf>> {
        let maps = out.join("maps");
        std::fs::create_dir_all(&maps).map_err(|e| Error::io(&maps, e))?;
        let write = |name: &str, text: String| -> Result<PathBuf> {
            let p = out.join(name);
            crate::io::write_atomic(&p, text)?;
            Ok(p)
        };
        let mut written = Vec::new();
        let mut csv = String::from("source,target,method,status,q,points,mean_x100,le_0.05,le_0.10,le_0.25,seconds\n");
        let mut json_pairs = Vec::new();
        for r in &self.runs {
            match &r.outcome {
                Ok(s) => {
                    csv += &format!(
                        "{},{},{},ok,{},{},{:.4},{:.4},{:.4},{:.4},{:.3}\n",
                        r.source,
                        r.target,
                        r.method,
                        s.q,
                        s.points,
                        100.0 * s.summary.mean,
                        s.summary.at_005,
                        s.summary.at_010,
                        s.summary.at_025,
                        s.seconds
                    );
                    let map: String = s.map_xy.iter().map(|j| format!("{j}\n")).collect();
                    let p = maps.join(format!("{}__{}.{}.txt", r.source, r.target, r.method));
                    crate::io::write_atomic(&p, map)?;
                    json_pairs.push(serde_json::json!({
                        "source": r.source, "target": r.target, "method": r.method, "status": "ok",
                        "q": s.q, "points": s.points, "summary": s.summary, "curve": s.curve,
                        "seconds": s.seconds, "stages": s.stages,
                    }));
                }
                Err(msg) => {
                    csv += &format!("{},{},{},failed,,,,,,,\n", r.source, r.target, r.method);
                    json_pairs.push(serde_json::json!({
                        "source": r.source, "target": r.target, "method": r.method, "status": "failed", "error": msg,
                    }));
                }
            }
        }
        written.push(write("pairs.csv", csv)?);
        written.push(write("pairs.json", serde_json::to_string_pretty(&json_pairs).expect("plain JSON"))?);
        let summaries = self.summaries();
        let mut csv = String::from("method,pairs,failed,points,mean_x100,le_0.05,le_0.10,le_0.25,seconds_per_pair\n");
        for m in &summaries {
            csv += &format!(
                "{},{},{},{},{:.4},{:.4},{:.4},{:.4},{:.3}\n",
                m.method,
                m.pairs,
                m.failed,
                m.points,
                100.0 * m.summary.mean,
                m.summary.at_005,
                m.summary.at_010,
                m.summary.at_025,
                m.seconds_per_pair
            );
        }
        written.push(write("summary.csv", csv)?);
        written.push(write("summary.md", format!("# {title}\n\n{}", table_of(&summaries)))?);
        let json = serde_json::json!({
            "title": title, "data": self.data.to_string(), "symmetric": self.symmetric,
            "geodesics": self.geodesics.name(), "k": self.k, "wall_seconds": self.wall_seconds,
            "shape_seconds": self.shape_seconds, "thresholds": eval::standard_thresholds(), "methods": summaries,
        });
        written.push(write("summary.json", serde_json::to_string_pretty(&json).expect("plain JSON"))?);
        if summaries.iter().any(|m| m.pairs > 0) {
            let p = out.join("curves.png");
            plot_of(&self.data, &summaries, title).write_png(&p, 900, 640)?;
            written.push(p);
        }
        Ok(written)
    }
}

/// The Markdown table of [`Report::table`] from per-method summaries.
pub(crate) fn table_of(summaries: &[MethodSummary]) -> String {
    let mut s = String::from(
        "| method | pairs | mean error ×100 | ≤ 0.05 | ≤ 0.10 | ≤ 0.25 | s / pair |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for m in summaries {
        let failed = if m.failed > 0 { format!(" ({} failed)", m.failed) } else { String::new() };
        if m.pairs == 0 {
            s += &format!("| {} | 0{failed} | – | – | – | – | – |\n", m.method);
            continue;
        }
        s += &format!(
            "| {} | {}{failed} | {:.2} | {:.1}% | {:.1}% | {:.1}% | {:.2} |\n",
            m.method,
            m.pairs,
            100.0 * m.summary.mean,
            100.0 * m.summary.at_005,
            100.0 * m.summary.at_010,
            100.0 * m.summary.at_025,
            m.seconds_per_pair
        );
    }
    s
}

/// The plot of [`Report::plot`] from per-method summaries.
pub(crate) fn plot_of(data: &PairDataSpec, summaries: &[MethodSummary], title: &str) -> crate::viz::plot::LinePlot {
    let dashed = !data.is_rich();
    let curves: Vec<(String, Vec<f64>, bool, usize)> = summaries
        .iter()
        .enumerate()
        .filter(|(_, m)| m.pairs > 0)
        .map(|(i, m)| (m.method.clone(), m.curve.clone(), dashed, method_color(&m.method, i)))
        .collect();
    crate::viz::plot::cumulative_curves(title, &eval::standard_thresholds(), &curves)
}
