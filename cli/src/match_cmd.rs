//! `funcorr match`: dense correspondence between two shapes, and its outputs.

use std::path::{Path, PathBuf};

use funcorr::descriptors::spec::PairDataSpec;
use funcorr::shape::Shape;
use funcorr::{Error, Result};

use crate::args::{
    CacheArgs, LaplacianArgs, MethodChoice, PipelineArgs, SegmentationArgs, DEFAULT_DATA, DEFAULT_SIZE, DEFAULT_VIEW,
};
use crate::options::{pair_data, settings, Flags, ShapeLaplacian};
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
    /// strongly symmetric shapes), 3 to 10 points such as the head, hands and feet. On a part X
    /// of Y (the partial path) they choose the basin and are pinned in the final map
    /// (`funcorr::matching::partial`, "Landmarks"). A landmark that disagrees with the others
    /// (its geodesic distances to them differ between X and Y) is named on stderr and in
    /// report.json (`landmark_check`) and used as given.
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

/// The options of `funcorr match` by name and the library options they resolve to (defaults per
/// method and data, see `--help`), for data `spec`.
pub(crate) fn match_options(
    args: &MatchArgs,
    spec: &PairDataSpec,
) -> Result<(funcorr::matching::MatchSettings, funcorr::matching::MatchOptions)> {
    let s = settings(&args.pipe, args.method)?;
    let opts = s.resolve_as(spec.is_rich(), &Flags)?;
    Ok((s, opts))
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
    let spec = args.data.parse::<PairDataSpec>()?.standalone()?;
    let (settings, mut opts) = match_options(args, &spec)?;
    if args.landmarks.is_some() && opts.method != funcorr::matching::Method::Axiomatic {
        return Err(Error::invalid(
            "--landmarks",
            "landmarks act in the default method (--method axiomatic); for the other methods give them as data, \
             --data landmarks:FILE",
        ));
    }
    let view = funcorr::viz::View::parse(&args.view)?;
    let size = parse_size(&args.size)?;
    // Options that ask for too few eigenpairs fail before any work.
    let least = settings.basis_demand_for(&opts, &Flags, true)?;
    // The output directory is created (and checked writable) before any work; it is published at
    // the end, or removed when the run fails.
    let staged = funcorr::io::staged::StagedDir::create(&args.output)?;
    // The two files are read side by side (seconds each at 10⁶ vertices).
    let (mut rx, mut ry) = (Stages { quiet: args.quiet, parts: vec![] }, Stages { quiet: args.quiet, parts: vec![] });
    let (x, y) = rayon::join(|| rx.run("read", || Shape::load(&args.x)), || ry.run("read", || Shape::load(&args.y)));
    let (x, y) = (x?, y?);
    st.parts.extend(rx.parts.into_iter().chain(ry.parts));
    // Shapes too small for the fewest eigenpairs the options may ask (the check below, with the
    // eigenpairs this pair needs, comes after the Laplacians).
    for (path, shape) in [(&args.x, &x), (&args.y, &y)] {
        if least.size >= shape.n_vertices() {
            let name = funcorr::error::escape_path(path);
            return Err(settings.too_small(&name, shape.n_vertices(), &opts, &least, &Flags));
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
    let (lx, ly) = rayon::join(
        || ShapeLaplacian::new(x, &args.x, &args.lap, &mut stx),
        || ShapeLaplacian::new(y, &args.y, &args.lap, &mut sty),
    );
    let (lx, ly) = (lx?, ly?);
    // The eigenpairs per shape: fewer where X cannot be a part and the data are the default WKS
    // (the partial path and descriptors such as wks:N read them all).
    let area = |l: &ShapeLaplacian| funcorr::prepared::area_of_mass(&l.laplacian.mass);
    let (name_x, name_y) = (funcorr::error::escape_path(&args.x), funcorr::error::escape_path(&args.y));
    let basis_k = settings
        .pair_basis_demand(
            &opts,
            &Flags,
            (&lx.shape, area(&lx), Some(&name_x)),
            (&ly.shape, area(&ly), Some(&name_y)),
            spec == PairDataSpec::WksRecipe,
        )?
        .size;
    let (px, py) =
        rayon::join(|| lx.prepared(&args.cache, basis_k, &mut stx), || ly.prepared(&args.cache, basis_k, &mut sty));
    let (px, py) = (px?, py?);
    for (path, p) in [(&args.x, &px), (&args.y, &py)] {
        warn_components(path, p);
        note_denoising(path, p, args.quiet);
    }
    st.parts.extend(stx.parts.into_iter().map(|s| format!("X {s}")));
    st.parts.extend(sty.parts.into_iter().map(|s| format!("Y {s}")));
    // A part of Y (detected or --partial) with the default WKS gets them at the same energies on
    // both shapes.
    let (f, g) =
        st.run("data", || match funcorr::matching::partial::partial_pair_data(&px, &py, &spec, &mut opts)? {
            Some(fg) => Ok(fg),
            None => pair_data(&spec, px.parts(), py.parts(), &args.seg),
        })?;
    // The data are handed over: the pipeline releases them once it has made its own (at 10⁶
    // vertices ≈ 0.34 GB per shape that the refinement would otherwise hold).
    let q = f.q();
    let r = funcorr::matching::run_owned(&px, &py, f, g, &opts)?;
    if let (Some(path), Some(check)) = (&args.landmarks, &r.landmark_check) {
        warn_landmarks(path, &opts.axiomatic.landmarks.pairs, check);
    }
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
            if let Some(cov) = &r.coverage {
                funcorr::io::npy::write_npy_vec_f64(&out.join("coverage.npy"), cov)?;
            }
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
                /// What the denoising of a rough (noisy) mesh did, for X and Y (null: the shape
                /// as it is).
                denoised: [Option<&'a funcorr::denoise::Denoising>; 2],
            }
            let report = ReportFile {
                x: args.x.display().to_string(),
                y: args.y.display().to_string(),
                data: &args.data,
                run: r.report(&opts, x.n_vertices(), y.n_vertices(), q, basis_k),
                log: &stages,
                denoised: [px.denoising(), py.denoising()],
            };
            let p = out.join("report.json");
            funcorr::io::write_atomic(&p, funcorr::io::to_json_sorted(&report)?)?;
            write_colour_transfer(
                out,
                x,
                y,
                &r.map_yx,
                r.coverage.as_deref(),
                (!args.no_render).then_some((size, &view)),
            )?;
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
    st.note(format!("q {q} | C {}×{}", r.c.nrows(), r.c.ncols()));
    st.finish();
    Ok(())
}

/// Says on stderr (unless quiet) when a mesh was rough with noise and its geometry was smoothed
/// before its Laplacian was built (`funcorr::denoise`).
pub(crate) fn note_denoising(path: &Path, p: &funcorr::PreparedShape, quiet: bool) {
    if let (Some(d), false) = (p.denoising(), quiet) {
        eprintln!(
            "note: {} is rough with noise (roughness {:.3} > {}, rougher than any clean mesh measured): its \
             Laplacian, descriptors and normals are computed on its geometry smoothed by one implicit step of time \
             {:.2} h² (roughness {:.3}, area ×{:.2}); the map is a map of its vertices (--laplacian cotan: the mesh \
             as it is)",
            funcorr::error::escape_path(path),
            d.roughness_before,
            funcorr::denoise::NOISY_ROUGHNESS,
            d.time,
            d.roughness_after,
            d.area_ratio,
        );
    }
}

/// Says on stderr which landmarks of `path` (pairs `pairs`, 0-based) disagree with the others
/// (`funcorr::matching::landmarks::LandmarkCheck`): they are used as given, and should be
/// checked.
pub(crate) fn warn_landmarks(
    path: &Path,
    pairs: &[(usize, usize)],
    check: &funcorr::matching::landmarks::LandmarkCheck,
) {
    if check.suspects.is_empty() {
        return;
    }
    let mut others: Vec<f64> =
        (0..check.discrepancy.len()).filter(|i| !check.suspects.contains(i)).map(|i| check.discrepancy[i]).collect();
    others.sort_by(|a, b| a.total_cmp(b));
    let typical = others.get(others.len() / 2).map_or(String::new(), |d| format!(" (the others: {:.0} %)", 100.0 * d));
    let listed: Vec<String> = check
        .suspects
        .iter()
        .map(|&l| {
            let (a, b) = pairs[l];
            format!("pair {} (vertex {a} → {b}, 0-based): {:.0} %", l + 1, 100.0 * check.discrepancy[l])
        })
        .collect();
    eprintln!(
        "warning: landmarks of {} that disagree with the others — their geodesic distances to the other \
         landmarks differ between X and Y by (median) {}{typical}; they are used as given: check that each is the \
         right point (report.json: landmark_check)",
        funcorr::error::escape_path(path),
        listed.join(", "),
    );
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
    use clap::{CommandFactory, Parser};
    use funcorr::matching::options::Kind;
    use funcorr::matching::{MatchOptions, MatchSettings, Method, Spelling, Value, MATCH_OPTIONS};

    fn parsed(args: &[&str]) -> MatchArgs {
        let mut line = vec!["funcorr", "match", "X", "Y", "-o", "out"];
        line.extend_from_slice(args);
        match Cli::try_parse_from(line).unwrap().command {
            Command::Match(a) => a,
            _ => unreachable!("a match command line"),
        }
    }

    fn resolved(args: &[&str]) -> MatchOptions {
        let a = parsed(args);
        let spec = a.data.parse::<PairDataSpec>().unwrap();
        match_options(&a, &spec).unwrap().1
    }

    fn json<T: serde::Serialize>(o: &T) -> serde_json::Value {
        serde_json::to_value(o).unwrap()
    }

    /// Vertex-pair counts are read as integers or as whole numbers in float notation; anything
    /// else (a fraction, a negative, beyond 2⁶⁴ − 1, not a number) is an error naming the value.
    #[test]
    fn vertex_pair_counts_take_float_notation() {
        let o =
            resolved(&["--near-above", "2e9", "--near-certified-up-to", "1e13", "--near-inverse-above", "625000000"]);
        assert_eq!(
            (o.axiomatic.near.above_pairs, o.axiomatic.near.certified_up_to, o.axiomatic.near.inverse_above_pairs),
            (2_000_000_000, 10_000_000_000_000, 625_000_000)
        );
        let o = resolved(&["--near-inverse-certified-up-to", "0"]);
        assert_eq!(o.axiomatic.near.inverse_certified_up_to, 0);
        for bad in ["1.5", "-1", "2e19", "inf", "NaN", "ten"] {
            let flag = format!("--near-above={bad}");
            let line = ["funcorr", "match", "X", "Y", "-o", "out", flag.as_str()];
            let e = Cli::try_parse_from(line).err().expect(bad).to_string();
            assert!(e.contains(bad) && e.contains("vertex pairs"), "{bad}: {e}");
        }
    }

    /// The library's defaults are what `funcorr match` runs, method by method and for scarce
    /// and rich data; an option given on the command line changes them.
    #[test]
    fn the_cli_runs_the_library_defaults() {
        assert_eq!(json(&resolved(&[])), json(&MatchOptions::default()));
        for (flag, method) in [
            ("axiomatic", Method::Axiomatic),
            ("fmap", Method::Fmap),
            ("pokrass", Method::Pokrass),
            ("coupled", Method::Coupled),
            ("completion", Method::Completion),
        ] {
            for (data, rich) in [("wks", true), ("rich", true), ("persistence", false), ("landmarks:l.txt", false)] {
                let o = resolved(&["--method", flag, "--data", data]);
                assert_eq!(json(&o), json(&MatchOptions::for_method(method, rich)), "{flag} {data}");
            }
        }
        let o = resolved(&["--polish", "0", "-k", "30"]);
        assert_eq!((o.axiomatic.polish, o.axiomatic.candidates.clone()), (0, vec![30]));
        assert_ne!(json(&o), json(&MatchOptions::default()));
    }

    /// The flags of `funcorr match` and the library's table of options (which is also the list
    /// of keywords of the Python `funcorr.match`) cannot drift apart: every option of the table
    /// is the flag of its name (`--` and the key with `-` for `_`, `-k` for `k`) with the same
    /// choices, every other flag is one of the command line's own (inputs, outputs, the shapes'
    /// preparation), and every flag sets the option of its name and no other.
    #[test]
    fn every_flag_is_the_library_option_of_its_name() {
        let cmd = Cli::command();
        let m = cmd.find_subcommand("match").expect("the match command");
        let own = [
            "x",
            "y",
            "data",
            "one_based",
            "soft",
            "landmarks",
            "view",
            "size",
            "no_render",
            "no_html",
            "output",
            "quiet",
            "function",
            "threshold",
            "hks_time",
            "laplacian",
            "cloud_neighbours",
            "knn_k",
            "vertex_weights",
            "sigma",
            "no_cache",
            "cache_dir",
            "no_partial",
            "help",
            "version",
        ];
        let mut flags: Vec<&str> =
            m.get_arguments().map(|a| a.get_id().as_str()).filter(|id| !own.contains(id)).collect();
        let mut keys: Vec<&str> = MATCH_OPTIONS.iter().map(|o| o.key).collect();
        flags.sort_unstable();
        keys.sort_unstable();
        assert_eq!(flags, keys, "the flags of match beside its own, and the library's options");
        let baseline = json(&settings(&parsed(&[]).pipe, parsed(&[]).method).unwrap());
        for spec in MATCH_OPTIONS {
            let arg = m.get_arguments().find(|a| a.get_id() == spec.key).expect("a flag");
            let spelled = match (arg.get_short(), arg.get_long()) {
                (Some(c), None) => format!("-{c}"),
                (_, Some(l)) => format!("--{l}"),
                (None, None) => unreachable!("a flag has a name"),
            };
            assert_eq!(spelled, Flags.name(spec.key), "the flag of {}", spec.key);
            let examples: Vec<(Vec<String>, Value)> = match spec.kind {
                Kind::Size => vec![(vec!["7".into()], Value::Size(7))],
                Kind::Number => vec![(vec!["0.25".into()], Value::Number(0.25))],
                Kind::Flag => vec![(vec![], Value::Flag(true))],
                Kind::Sizes => vec![(vec!["7,9".into()], Value::Sizes(vec![7, 9]))],
                Kind::Choice(names) => {
                    let shown: Vec<String> = arg
                        .get_possible_values()
                        .iter()
                        .filter(|v| !v.is_hide_set())
                        .map(|v| v.get_name().to_string())
                        .collect();
                    assert_eq!(shown, names.to_vec(), "the choices of {}", spec.key);
                    names.iter().map(|n| (vec![n.to_string()], Value::Choice(n.to_string()))).collect()
                }
            };
            for (text, value) in examples {
                let mut line = vec![spelled.clone()];
                line.extend(text.iter().cloned());
                let a = parsed(&line.iter().map(String::as_str).collect::<Vec<_>>());
                let got = json(&settings(&a.pipe, a.method).unwrap());
                let mut want = MatchSettings::default();
                want.set(spec.key, value.clone()).unwrap();
                assert_eq!(got[spec.key], json(&want)[spec.key], "{line:?}");
                // No other option changed.
                let others: Vec<&String> = got
                    .as_object()
                    .unwrap()
                    .keys()
                    .filter(|k| k.as_str() != spec.key && got[k.as_str()] != baseline[k.as_str()])
                    .collect();
                assert!(others.is_empty(), "{line:?} also set {others:?}");
            }
        }
    }

    /// `--partial` and `--no-partial` are the option `partial` true and false (unset: detected);
    /// the partial path is the axiomatic method's, so another method with `--partial` is an
    /// error naming the flag.
    #[test]
    fn partial_flags_are_the_partial_option() {
        use funcorr::matching::partial::PartialMode;
        assert_eq!(resolved(&[]).partial.mode, PartialMode::Auto);
        assert_eq!(resolved(&["--partial"]).partial.mode, PartialMode::Always);
        assert_eq!(resolved(&["--no-partial"]).partial.mode, PartialMode::Never);
        let a = parsed(&["--no-partial"]);
        assert_eq!(settings(&a.pipe, a.method).unwrap().partial, Some(false));
        assert!(Cli::try_parse_from(["funcorr", "match", "X", "Y", "-o", "o", "--partial", "--no-partial"]).is_err());
        let a = parsed(&["--partial", "--method", "fmap"]);
        let spec = a.data.parse::<PairDataSpec>().unwrap();
        let e = match_options(&a, &spec).unwrap_err().to_string();
        assert!(e.contains("--partial"), "{e}");
    }
}
