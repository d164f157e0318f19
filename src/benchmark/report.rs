//! Per-method summaries pooled over the pairs, their table, the typed records of the JSON files
//! and the files of a run (the curves are drawn by `viz::plot::benchmark_curves`).

#[allow(unused_imports)]
use super::*;

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

/// One row of `pairs.json`: a method on a pair, its score or why it failed.
#[derive(Debug, Clone, Serialize)]
pub struct PairRecord<'a> {
    /// Source shape X.
    pub source: &'a str,
    /// Target shape Y.
    pub target: &'a str,
    /// Method name.
    pub method: &'a str,
    /// `ok` or `failed`.
    pub status: &'static str,
    /// Number q of data functions (scored pairs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub q: Option<usize>,
    /// Template points scored.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
    /// Mean and fractions of the hard errors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub summary: Option<Summary>,
    /// Cumulative curve at [`eval::standard_thresholds`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve: Option<&'a [f64]>,
    /// Seconds of the method's stages.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// (stage, seconds) in order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages: Option<&'a [(String, f64)]>,
    /// Why the method failed on the pair.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<&'a str>,
    /// The solver's report (iterations, objective history) of the methods that iterate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solver: Option<&'a crate::matching::SolverReport>,
}

impl<'a> PairRecord<'a> {
    /// The record of `run`.
    pub fn of(run: &'a PairRun) -> Self {
        let (source, target, method) = (run.source.as_str(), run.target.as_str(), run.method.as_str());
        match &run.outcome {
            Ok(s) => PairRecord {
                source,
                target,
                method,
                status: "ok",
                q: Some(s.q),
                points: Some(s.points),
                summary: Some(s.summary),
                curve: Some(&s.curve),
                seconds: Some(s.seconds),
                stages: Some(&s.stages),
                error: None,
                solver: s.solver.as_ref(),
            },
            Err(msg) => PairRecord {
                source,
                target,
                method,
                status: "failed",
                q: None,
                points: None,
                summary: None,
                curve: None,
                seconds: None,
                stages: None,
                error: Some(msg),
                solver: None,
            },
        }
    }
}

/// `summary.json`: the settings of a run and its per-method summaries.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary<'a> {
    /// Title of the table and the plot.
    pub title: &'a str,
    /// The data spec, as written on the command line.
    pub data: String,
    /// Whether symmetric flips were allowed.
    pub symmetric: bool,
    /// The geodesic solver's name.
    pub geodesics: &'static str,
    /// Eigenpairs per shape.
    pub k: usize,
    /// Wall-clock seconds of the whole run.
    pub wall_seconds: f64,
    /// Seconds to prepare each shape.
    pub shape_seconds: &'a BTreeMap<String, f64>,
    /// The thresholds of the curves ([`eval::standard_thresholds`]).
    pub thresholds: Vec<f64>,
    /// Per-method summaries, in method order.
    pub methods: Vec<MethodSummary>,
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

    /// Writes the run to `out` (created): `pairs.csv` (one row per pair and method),
    /// `pairs.json` (the same with curves and stage times), `maps/X__Y.METHOD.txt` (0-based
    /// maps X → Y, readable by `funcorr eval`), `summary.csv`, `summary.md` and `summary.json`
    /// (the plot of the curves is `viz::plot::write_benchmark_curves`). Returns the paths
    /// written.
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
                }
                Err(_) => {
                    csv += &format!("{},{},{},failed,,,,,,,\n", r.source, r.target, r.method);
                }
            }
        }
        written.push(write("pairs.csv", csv)?);
        let records: Vec<PairRecord> = self.runs.iter().map(PairRecord::of).collect();
        written.push(write("pairs.json", crate::io::to_json_sorted(&records)?)?);
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
        let json = RunSummary {
            title,
            data: self.data.to_string(),
            symmetric: self.symmetric,
            geodesics: self.geodesics.name(),
            k: self.k,
            wall_seconds: self.wall_seconds,
            shape_seconds: &self.shape_seconds,
            thresholds: eval::standard_thresholds(),
            methods: summaries,
        };
        written.push(write("summary.json", crate::io::to_json_sorted(&json)?)?);
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
