//! `funcorr match`: dense correspondence between two shapes, and its outputs.

use std::path::{Path, PathBuf};

use funcorr::shape::Shape;
use funcorr::{Error, Result};

use crate::args::{
    CacheArgs, LaplacianArgs, MethodChoice, PipelineArgs, SegmentationArgs, DEFAULT_DATA, DEFAULT_SIZE, DEFAULT_VIEW,
};
use crate::options::{basis_demand, is_rich, pair_data, pipeline_options, prepared_shape, too_small};
use crate::output::{describe, mesh_data, parse_size, write_colour_transfer, write_map_files};
use crate::Stages;

#[derive(clap::Args)]
pub(crate) struct MatchArgs {
    /// Source shape X.
    pub(crate) x: PathBuf,
    /// Target shape Y.
    pub(crate) y: PathBuf,
    /// Corresponding data: `wks` (the default: 100 WKS energies from the first 128 eigenpairs,
    /// every 2nd kept), `wks:N` (N WKS from the whole basis), `hks:N`, `wks+hks:N` (`hks` and
    /// `wks+hks` without a count mean N = 100), `segments:X.seg,Y.seg` (labels that
    /// agree between the files), `persistence`, `mser`, `landmarks:pairs.txt` (0-based `i j`
    /// per line), `rich` (100 WKS + 100 heat kernel maps localized on the persistence segments,
    /// the paper's rich data) or `rich:X.seg,Y.seg` (on given segments), or `matrix:F.npy,G.npy`.
    #[arg(long, default_value = DEFAULT_DATA)]
    pub(crate) data: String,
    /// Functional-map method.
    #[arg(long, value_enum, default_value = "axiomatic")]
    pub(crate) method: MethodChoice,
    /// Known corresponding points: a file of 0-based vertex pairs `i j` (vertex i of X, vertex j
    /// of Y), one per line (`#` comments). They join the default pipeline as strongly weighted
    /// landmark functions, in the choice among its candidates and pinned in every refinement step
    /// (`funcorr::matching::landmarks`): for pairs no intrinsic method can decide (non-isometric or
    /// strongly symmetric shapes), 3 to 10 points such as the head, hands and feet.
    #[arg(long, value_name = "FILE")]
    pub(crate) landmarks: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) pipe: PipelineArgs,
    /// Write map.txt with 1-based vertex ids (MATLAB).
    #[arg(long)]
    pub(crate) one_based: bool,
    /// Also write the soft map T δ_i (a function on Y) of these vertices of X (comma-separated,
    /// 0-based) as soft_<i>.npy and soft_<i>.ply.
    #[arg(long, value_delimiter = ',')]
    pub(crate) soft: Vec<usize>,
    /// Camera of render.png: azimuth,elevation in degrees (0,0: looking along −Z, Y up).
    #[arg(long, default_value = DEFAULT_VIEW)]
    pub(crate) view: String,
    /// Size of render.png, WIDTHxHEIGHT pixels (each side ≤ 16384, at most 67,108,864 pixels in
    /// all, e.g. 8192x8192).
    #[arg(long, default_value = DEFAULT_SIZE)]
    pub(crate) size: String,
    /// Do not write render.png.
    #[arg(long)]
    pub(crate) no_render: bool,
    /// Do not write view.html (the interactive viewer: open it in a browser).
    #[arg(long)]
    pub(crate) no_html: bool,
    /// Output directory.
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) seg: SegmentationArgs,
    #[command(flatten)]
    pub(crate) lap: LaplacianArgs,
    #[command(flatten)]
    pub(crate) cache: CacheArgs,
    /// No timings on stderr.
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

/// The library options of `funcorr match` (defaults per method and data, see `--help`).
pub(crate) fn match_options(args: &MatchArgs) -> Result<funcorr::matching::MatchOptions> {
    pipeline_options(&args.pipe, args.method, is_rich(&args.data))
}

/// Writes a k × k (or r × c) matrix as .npy.
pub(crate) fn write_mat_npy(path: &Path, c: &faer::Mat<f64>) -> Result<()> {
    let (r, k) = (c.nrows(), c.ncols());
    let dense = funcorr::io::DenseMatrix { rows: r, cols: k, data: (0..r * k).map(|t| c[(t / k, t % k)]).collect() };
    funcorr::io::npy::write_npy_matrix(path, &dense)
}

pub(crate) fn match_shapes(args: &MatchArgs) -> Result<()> {
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    // A malformed --data fails before any work.
    args.data.parse::<funcorr::descriptors::spec::PairDataSpec>()?.standalone()?;
    let mut opts = match_options(args)?;
    if args.landmarks.is_some() && opts.method != funcorr::matching::Method::Axiomatic {
        return Err(Error::invalid(
            "--landmarks",
            "landmarks act in the default method (--method axiomatic); for the other methods give them as data, \
             --data landmarks:FILE",
        ));
    }
    let view = funcorr::viz::View::parse(&args.view)?;
    let size = parse_size(&args.size)?;
    let (basis_k, demand) = basis_demand(&args.pipe, &opts)?;
    // The output directory is created (and checked writable) before any work; it is published at
    // the end, or removed when the run fails.
    let staged = funcorr::io::staged::StagedDir::create(&args.output)?;
    let x = st.run("read", || Shape::load(&args.x))?;
    let y = st.run("read", || Shape::load(&args.y))?;
    for (path, shape) in [(&args.x, &x), (&args.y, &y)] {
        if basis_k >= shape.n_vertices() {
            return Err(too_small(path, shape.n_vertices(), &args.pipe, &opts, basis_k, &demand));
        }
    }
    if let Some(path) = &args.landmarks {
        opts.axiomatic.landmarks.pairs =
            funcorr::io::indices::read_index_pairs_file(path, false, x.n_vertices(), y.n_vertices())?;
    }
    if let Some(&bad) = args.soft.iter().find(|&&i| i >= x.n_vertices()) {
        return Err(Error::invalid("--soft", format!("vertex {bad} of X does not exist (n = {})", x.n_vertices())));
    }
    // The two shapes' Laplacians and bases are independent: prepared side by side.
    let (mut stx, mut sty) = (Stages { quiet: args.quiet, parts: vec![] }, Stages { quiet: args.quiet, parts: vec![] });
    let (px, py) = rayon::join(
        || prepared_shape(x, &args.x, &args.lap, &args.cache, basis_k, &mut stx),
        || prepared_shape(y, &args.y, &args.lap, &args.cache, basis_k, &mut sty),
    );
    let (px, py) = (px?, py?);
    for (path, p) in [(&args.x, &px), (&args.y, &py)] {
        warn_components(path, p);
    }
    st.parts.extend(stx.parts.into_iter().map(|s| format!("X {s}")));
    st.parts.extend(sty.parts.into_iter().map(|s| format!("Y {s}")));
    let (f, g) = st.run("data", || pair_data(&args.data, px.parts(), py.parts(), &args.seg))?;
    let r = funcorr::matching::run_prepared(&px, &py, &f, &g, &opts)?;
    let (x, y) = (&px.shape, &py.shape);
    // The soft maps read C (between the input bases) with the input bases.
    let input_bases = (!args.soft.is_empty()).then(|| (px.input_basis(), py.input_basis()));
    for (name, secs) in &r.stages {
        st.note(format!("{name} {secs:.3} s"));
    }
    let stages = st.parts.clone();
    st.run("write", || {
        // Everything goes into a staging directory, published whole at the end (io::staged).
        staged.write_with(|out| {
            write_map_files(out, &r.map_xy, args.one_based)?;
            funcorr::io::npy::write_npy_vec_u64(
                &out.join("map_yx.npy"),
                &r.map_yx.iter().map(|&i| i as u64).collect::<Vec<_>>(),
            )?;
            let mut soft = Vec::new();
            write_mat_npy(&out.join("C.npy"), &r.c)?;
            if r.c_method.nrows() != r.c.nrows() || opts.refine != funcorr::matching::Refine::None {
                write_mat_npy(&out.join("C_method.npy"), &r.c_method)?;
            }
            if let Some((a, b)) = &r.coefficients {
                write_mat_npy(&out.join("A.npy"), a)?;
                write_mat_npy(&out.join("B.npy"), b)?;
            }
            for (&i, (bx, by)) in args.soft.iter().zip(std::iter::repeat(input_bases.as_ref()).flatten()) {
                let t = funcorr::pointwise::soft_map_column(
                    bx.eigenvectors.as_ref(),
                    by.eigenvectors.as_ref(),
                    r.c_method.as_ref(),
                    i,
                )?;
                funcorr::io::npy::write_npy_matrix(
                    &out.join(format!("soft_{i}.npy")),
                    &funcorr::io::DenseMatrix { rows: t.len(), cols: 1, data: t.clone() },
                )?;
                if let Some(mut dy) = mesh_data(y) {
                    dy.colors = Some(funcorr::viz::diverging_colors(&t));
                    funcorr::io::write_mesh(&out.join(format!("soft_{i}.ply")), &dy)?;
                }
                soft.push((i, t));
            }
            #[derive(serde::Serialize)]
            struct ReportFile<'a> {
                x: String,
                y: String,
                data: &'a str,
                #[serde(flatten)]
                run: funcorr::matching::MatchReport<'a>,
                log: &'a [String],
            }
            let report = ReportFile {
                x: args.x.display().to_string(),
                y: args.y.display().to_string(),
                data: &args.data,
                run: r.report(&opts, x.n_vertices(), y.n_vertices(), f.q(), basis_k),
                log: &stages,
            };
            let p = out.join("report.json");
            funcorr::io::write_atomic(&p, funcorr::io::to_json_sorted(&report)?)?;
            write_colour_transfer(out, x, y, &r.map_yx, (!args.no_render).then_some((size, &view)))?;
            if !args.no_html {
                let name = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
                crate::view::write_match_view(
                    out,
                    (x, &name(&args.x)),
                    (y, &name(&args.y)),
                    &r.map_xy,
                    &r.map_yx,
                    describe(&args.data, &opts),
                    &soft,
                    None,
                )?;
            }
            Ok(())
        })
    })?;
    st.note(format!("q {} | C {}×{}", f.q(), r.c.nrows(), r.c.ncols()));
    st.finish();
    Ok(())
}

/// Says on stderr when a shape has several connected components (of its faces, or of its
/// Laplacian's graph for a point set), and what matching does with them.
pub(crate) fn warn_components(path: &Path, p: &funcorr::PreparedShape) {
    let (count, labels) = match &p.shape {
        Shape::Mesh(m) => m.components(),
        Shape::Points(_) => p.laplacian.components(),
    };
    if count < 2 {
        return;
    }
    let mut sizes = vec![0usize; count];
    for &l in &labels {
        sizes[l as usize] += 1;
    }
    sizes.sort_unstable_by_key(|&s| std::cmp::Reverse(s));
    let shown: Vec<String> = sizes.iter().take(5).map(|s| s.to_string()).collect();
    let more = if count > 5 { format!(", … ({} more)", count - 5) } else { String::new() };
    eprintln!(
        "warning: {} has {count} connected components ({}{more} vertices): they are matched as one shape; \
         the basis holds one constant function per component, and a vertex of one component may be mapped into \
         any component of the other shape (remove the small ones, or match the components separately, if that \
         is not what you want)",
        funcorr::error::escape_path(path),
        shown.join(", "),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Cli, Command};
    use clap::Parser;
    use funcorr::matching::{MatchOptions, Method};

    fn parsed(args: &[&str]) -> MatchArgs {
        let mut line = vec!["funcorr", "match", "X", "Y", "-o", "out"];
        line.extend_from_slice(args);
        match Cli::try_parse_from(line).unwrap().command {
            Command::Match(a) => a,
            _ => unreachable!("a match command line"),
        }
    }

    fn json(o: &MatchOptions) -> String {
        serde_json::to_string(o).unwrap()
    }

    /// The library's defaults are what `funcorr match` runs, method by method and for scarce
    /// and rich data; an option given on the command line changes them.
    #[test]
    fn the_cli_runs_the_library_defaults() {
        assert_eq!(json(&match_options(&parsed(&[])).unwrap()), json(&MatchOptions::default()));
        for (flag, method) in [
            ("axiomatic", Method::Axiomatic),
            ("fmap", Method::Fmap),
            ("pokrass", Method::Pokrass),
            ("coupled", Method::Coupled),
            ("completion", Method::Completion),
        ] {
            for (data, rich) in [("wks", true), ("rich", true), ("persistence", false), ("landmarks:l.txt", false)] {
                let a = parsed(&["--method", flag, "--data", data]);
                assert_eq!(
                    json(&match_options(&a).unwrap()),
                    json(&MatchOptions::for_method(method, rich)),
                    "{flag} {data}"
                );
            }
        }
        let a = parsed(&["--polish", "0", "-k", "30"]);
        let o = match_options(&a).unwrap();
        assert_eq!((o.axiomatic.polish, o.axiomatic.candidates.clone()), (0, vec![30]));
        assert_ne!(json(&o), json(&MatchOptions::default()));
    }
}
