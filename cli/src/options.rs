//! From command-line arguments to library calls: Laplacians, bases, data and match options.

use std::path::Path;

use clap::ValueEnum;

use funcorr::laplacian::{Bandwidth, KnnOptions, Laplacian, VertexWeights};
use funcorr::shape::Shape;
use funcorr::spectral::{Basis, SpectralOptions};
use funcorr::{spectral, Error, Result};

use crate::args::{
    CacheArgs, ExtractChoice, FormChoice, InitChoice, LaplacianArgs, LaplacianChoice, MaskChoice, MethodChoice,
    OptimizerChoice, OrientationChoice, PipelineArgs, Refine, SegmentationArgs, WeightsChoice,
};
use crate::Stages;

/// Persistence segmentation of a shape (labels 1..=s, one per vertex).
pub(crate) fn persistence_labels(
    shape: &Shape,
    lap: &Laplacian,
    basis: &Basis,
    args: &SegmentationArgs,
) -> Result<Vec<u32>> {
    funcorr::descriptors::persistence::segment_labels(shape, lap, basis, &args.options())
}

/// The Laplacian and basis of a shape: read from --basis, or computed (and cached).
pub(crate) fn shape_basis(
    shape: &Shape,
    path: &Path,
    lap_args: &LaplacianArgs,
    cache: &CacheArgs,
    k: usize,
    basis_file: Option<&Path>,
    st: &mut Stages,
) -> Result<(Laplacian, Basis)> {
    let lap = st.run("laplacian", || build_laplacian(shape, path, lap_args))?;
    let basis = match basis_file {
        Some(p) => {
            let b = st.run("read basis", || spectral::load_basis(p))?;
            if b.n() != shape.n_vertices() {
                return Err(Error::invalid(
                    "--basis",
                    format!("{} has {} rows but the shape has {} vertices", p.display(), b.n(), shape.n_vertices()),
                ));
            }
            b
        }
        None => {
            let c = cache.cache();
            st.run("eigenbasis", || spectral::eigen_basis_cached(&lap, &SpectralOptions::new(k), c.as_ref(), None))?.0
        }
    };
    Ok((lap, basis))
}

/// A shape prepared for matching: its Laplacian (and surface: the mesh or the point cloud's
/// triangulation), and its basis through the cache.
pub(crate) fn prepared_shape(
    shape: Shape,
    path: &Path,
    lap_args: &LaplacianArgs,
    cache: &CacheArgs,
    k: usize,
    st: &mut Stages,
) -> Result<funcorr::PreparedShape> {
    let choice = laplacian_choice(lap_args, &shape, path)?;
    let (lap, surface) =
        st.run("laplacian", || funcorr::prepared::build_laplacian(&shape, choice).map_err(laplacian_error(path)))?;
    let c = cache.cache();
    let basis =
        st.run("eigenbasis", || spectral::eigen_basis_cached(&lap, &SpectralOptions::new(k), c.as_ref(), None))?.0;
    Ok(funcorr::PreparedShape::from_parts(shape, lap, basis, surface))
}

/// The library's Laplacian choice for the CLI's arguments and this shape (read from `path`).
/// The kNN options (--knn, --vertex-weights, --sigma) shape the kNN graph, --cloud-neighbours
/// the point-cloud Laplacian: given for a shape whose Laplacian is another one, they are
/// ignored, and a warning says so. Errors: a --sigma that is not finite and > 0 (also when
/// ignored).
pub(crate) fn laplacian_choice(
    args: &LaplacianArgs,
    shape: &Shape,
    path: &Path,
) -> Result<funcorr::prepared::LaplacianChoice> {
    use funcorr::prepared::LaplacianChoice as L;
    if let Some(s) = args.sigma {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::invalid("--sigma", format!("the kNN bandwidth σ must be finite and > 0, got {s}")));
        }
    }
    let effective = match (args.laplacian, shape) {
        (Some(c), _) => c,
        (None, Shape::Mesh(_)) => LaplacianChoice::Cotan,
        (None, Shape::Points(p)) if p.dim() == 3 => LaplacianChoice::Cloud,
        (None, Shape::Points(_)) => LaplacianChoice::Knn,
    };
    let mut ignored = Vec::new();
    if !matches!(effective, LaplacianChoice::Knn) {
        if let Some(k) = args.knn_k {
            ignored.push(format!("--knn {k}"));
        }
        if let Some(w) = args.vertex_weights {
            ignored.push(format!(
                "--vertex-weights {}",
                w.to_possible_value().map_or("?".into(), |v| v.get_name().to_string())
            ));
        }
        if let Some(s) = args.sigma {
            ignored.push(format!("--sigma {s}"));
        }
    }
    if !matches!(effective, LaplacianChoice::Cloud) {
        if let Some(k) = args.cloud_neighbours {
            ignored.push(format!("--cloud-neighbours {k}"));
        }
    }
    if !ignored.is_empty() {
        let (what, applies) = match effective {
            LaplacianChoice::Cotan => ("the cotangent Laplacian of its triangles", ""),
            LaplacianChoice::Intrinsic => ("the intrinsic Delaunay Laplacian of its triangles", ""),
            LaplacianChoice::Cloud => {
                ("the point-cloud Laplacian", "; --knn, --vertex-weights and --sigma apply to --laplacian knn")
            }
            LaplacianChoice::Knn => ("the kNN graph Laplacian", "; --cloud-neighbours applies to --laplacian cloud"),
        };
        let applies = if applies.is_empty() { "; they apply to --laplacian knn (or cloud)" } else { applies };
        eprintln!(
            "warning: {} ignored for {}: its Laplacian is {what}{applies}",
            ignored.join(", "),
            funcorr::error::escape_path(path)
        );
    }
    let knn = || {
        let d = KnnOptions::default();
        KnnOptions {
            k: args.knn_k.unwrap_or(d.k),
            vertex_weights: match args.vertex_weights {
                None => d.vertex_weights,
                Some(WeightsChoice::Identity) => VertexWeights::Identity,
                Some(WeightsChoice::Degree) => VertexWeights::Degree,
            },
            bandwidth: args.sigma.map_or(d.bandwidth, Bandwidth::Fixed),
        }
    };
    // Without --laplacian: the library's automatic choice (a cloud of fewer points than the
    // default neighbours uses them all), unless an option of the chosen kind was given.
    Ok(match (effective, args.laplacian.is_some()) {
        (LaplacianChoice::Knn, _) => L::Knn(knn()),
        (LaplacianChoice::Cotan, true) => L::Cotangent,
        (LaplacianChoice::Intrinsic, _) => L::Intrinsic,
        (LaplacianChoice::Cloud, true) => {
            L::Cloud { k: args.cloud_neighbours.unwrap_or(funcorr::cloud::DEFAULT_NEIGHBOURS) }
        }
        (LaplacianChoice::Cloud, false) => match args.cloud_neighbours {
            Some(k) => L::Cloud { k },
            None => L::Auto,
        },
        (LaplacianChoice::Cotan, false) => L::Auto,
    })
}

pub(crate) fn build_laplacian(shape: &Shape, path: &Path, args: &LaplacianArgs) -> Result<Laplacian> {
    let choice = laplacian_choice(args, shape, path)?;
    Ok(funcorr::prepared::build_laplacian(shape, choice).map_err(laplacian_error(path))?.0)
}

/// Names the option or the file in a Laplacian error: `--laplacian` for a bad choice, the kNN
/// and point-cloud options for theirs, the shape's file for a shape without a Laplacian (zero
/// area, vertices in no triangle, too few points, ...).
pub(crate) fn laplacian_error(path: &Path) -> impl Fn(Error) -> Error + '_ {
    move |e| match e {
        Error::Invalid { what, msg } if what == "laplacian" => Error::invalid("--laplacian", msg),
        Error::Invalid { what, msg } if what == "sigma" => Error::invalid("--sigma", msg),
        Error::Invalid { what, msg } if what == "knn" => Error::invalid("--knn", msg),
        Error::Invalid { what, msg } if what == "neighbours" => Error::invalid("--cloud-neighbours", msg),
        Error::Invalid { what, msg } if what == "mesh" || what == "point set" => {
            Error::parse(path, None, format!("invalid {what}: {msg}"))
        }
        e => e,
    }
}

/// Data functions F on X and G on Y from a `--data` spec (see `funcorr match --help`).
pub(crate) fn pair_data(
    spec: &str,
    x: (&Shape, &Laplacian, &Basis),
    y: (&Shape, &Laplacian, &Basis),
    seg: &SegmentationArgs,
) -> Result<(funcorr::descriptors::Descriptors, funcorr::descriptors::Descriptors)> {
    spec.parse::<funcorr::descriptors::spec::PairDataSpec>()?.standalone()?.functions(x, y, &seg.options())
}

/// Whether a `--data` spec is the paper's rich setting (many functions) rather than scarce data.
pub(crate) fn is_rich(spec: &str) -> bool {
    spec.parse::<funcorr::descriptors::spec::PairDataSpec>().is_ok_and(|s| s.is_rich())
}

/// The library options of a pipeline (defaults per method and data, see `--help`).
pub(crate) fn pipeline_options(
    p: &PipelineArgs,
    method: MethodChoice,
    rich: bool,
) -> Result<funcorr::matching::MatchOptions> {
    use funcorr::completion::{self as comp, Form, Init, Optimizer, Scaling};
    use funcorr::matching::{Extraction, MatchOptions, Method};
    let scaling: Scaling = p.scaling.into();
    let form = match p.form {
        FormChoice::Subspace => Form::Subspace,
        FormChoice::FixedRank => Form::FixedRank,
        FormChoice::LowRank => Form::LowRank,
        FormChoice::LowNorm => Form::LowNorm,
    };
    let method: Method = method.into();
    if p.k == Some(0) {
        return Err(Error::invalid("-k", "the functional map's size must be at least 1"));
    }
    // The library's defaults for this method and data; the options given override them.
    let base = MatchOptions::for_method(method, rich);
    // The form's own default weights; --mu1 … --xi override them below.
    let mut completion = funcorr::matching::completion_defaults(rich, scaling, form);
    if let Some(k) = p.k {
        completion.k = k;
    }
    if let Some(kp) = p.kprime {
        completion.k_prime = kp;
    }
    if method == Method::Completion && !(1..=completion.k_prime).contains(&completion.k) {
        let (k, kp) = (completion.k, completion.k_prime);
        let src = |given: bool, flag: &str, v: usize| {
            if given {
                format!("{flag} {v}")
            } else {
                format!("{flag} (default {v})")
            }
        };
        return Err(Error::invalid(
            if p.k.is_some() { "-k" } else { "--kprime" },
            format!(
                "the completion rank {} must be between 1 and the subspace size {}",
                src(p.k.is_some(), "-k", k),
                src(p.kprime.is_some(), "--kprime", kp)
            ),
        ));
    }
    completion.init = match p.init {
        InitChoice::Pad => Init::Pad,
        InitChoice::Svd => Init::Svd,
    };
    completion.optimizer = p.optimizer.map(|o| match o {
        OptimizerChoice::Lbfgs => Optimizer::Lbfgs,
        OptimizerChoice::Rcg => Optimizer::Rcg,
    });
    let w = &mut completion.params;
    for (slot, v) in
        [(&mut w.mu1, p.mu1), (&mut w.mu2, p.mu2), (&mut w.mu3, p.mu3), (&mut w.mu4, p.mu4), (&mut w.xi, p.xi)]
    {
        if let Some(v) = v {
            *slot = v;
        }
    }
    if completion.optimizer == Some(Optimizer::Rcg) || completion.form == Form::FixedRank {
        if p.mu4.is_some_and(|m| m != 0.0) {
            return Err(Error::invalid("--mu4", "the fixed-rank forms have no low-norm term"));
        }
        w.mu4 = 0.0;
    }
    w.mu_comm = p.completion_commutativity;
    w.k_comm = p.completion_commutativity_k;
    w.mu_prior = p.completion_prior;
    completion.optimize = comp::OptimizeOptions {
        max_iterations: p.max_iterations,
        rel_tol: p.rel_tol,
        ..comp::OptimizeOptions::default()
    };
    if let Some(samples) = p.l1_samples {
        completion.l1_sampling = comp::L1Sampling::farthest(samples);
    }
    completion.params.l1_precision =
        crate::args::l1_precision(p.l1_precision, p.l1_f32, completion.params.l1_precision);
    completion.precondition = p.precondition.into();
    completion.xi_stages = p.xi_stages;
    if let Some(stages) = p.multiscale {
        completion.multiscale = stages;
    }
    // The map that matters is the one the refinement starts from: that of the leading refine_k
    // block of C (the factors' own map without a refinement).
    let refined = match p.refine {
        Some(r) => r != Refine::None,
        None => base.refine != funcorr::matching::Refine::None,
    };
    completion.settled = settled_map(p.map_check_every, p.map_tolerance, if refined { p.refine_k } else { 0 })?;
    let commutativity = p.commutativity.unwrap_or(base.commutativity);
    if !(commutativity.is_finite() && commutativity >= 0.0) {
        return Err(Error::invalid("--commutativity", "must be finite and ≥ 0"));
    }
    let axiomatic = {
        use funcorr::fmap::energy::{EnergyWeights, Mask, Orientation};
        let mut a = base.axiomatic.clone();
        a.fit.weights = EnergyWeights {
            descriptors: p.w_descriptors,
            laplacian: p.w_laplacian,
            commutativity: p.w_commutativity,
            orientation: p.w_orientation,
        };
        a.fit.mask = match p.mask {
            MaskChoice::Resolvent => Mask::Resolvent { gamma: 0.5 },
            MaskChoice::Standard => Mask::Standard,
        };
        a.fit.orientation = match p.orientation {
            OrientationChoice::Preserve => Orientation::Preserve,
            OrientationChoice::Reverse => Orientation::Reverse,
            OrientationChoice::Ignore => Orientation::Ignore,
        };
        a.signed = p.signed;
        if let Some(c) = &p.candidates {
            a.candidates = c.clone();
        } else if let Some(k) = p.k {
            a.candidates = vec![k];
        }
        match p.refine {
            Some(Refine::None) => a.refine.k_final = 0,
            Some(Refine::Icp) if method == Method::Axiomatic => {
                return Err(Error::invalid(
                    "--refine",
                    "the axiomatic method refines with ZoomOut (or none); ICP is for the other methods",
                ))
            }
            _ => {}
        }
        if let Some(k) = p.zoomout_to {
            if p.refine != Some(Refine::None) {
                a.refine.k_final = k;
            }
        }
        if let Some(s) = p.zoomout_step {
            a.refine.step = s;
        }
        a.refine.samples = p.zoomout_samples;
        a.polish = p.polish;
        if p.near_cells == 0 {
            return Err(Error::invalid("--near-cells", "must be at least 1"));
        }
        a.near = funcorr::matching::axiomatic::NearSearch { above_pairs: p.near_above, cells: p.near_cells };
        for (flag, v) in [
            ("--w-descriptors", p.w_descriptors),
            ("--w-laplacian", p.w_laplacian),
            ("--w-commutativity", p.w_commutativity),
            ("--w-orientation", p.w_orientation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(flag, format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if a.candidates.is_empty() || a.candidates.contains(&0) {
            return Err(Error::invalid("--candidates", "need one or more sizes ≥ 1"));
        }
        if a.refine.step == 0 {
            return Err(Error::invalid("--zoomout-step", "must be at least 1"));
        }
        a
    };
    Ok(MatchOptions {
        method,
        k: p.k.unwrap_or(base.k),
        commutativity,
        completion,
        init_k: p.init_k,
        extraction: match p.extract {
            ExtractChoice::Nn => Extraction::Nn,
            ExtractChoice::Argmax => Extraction::Argmax,
            ExtractChoice::Fmap => Extraction::Fmap,
        },
        refine: match p.refine {
            None => base.refine,
            Some(Refine::None) => funcorr::matching::Refine::None,
            Some(Refine::Icp) => funcorr::matching::Refine::Icp,
            Some(Refine::Zoomout) => funcorr::matching::Refine::Zoomout,
        },
        refine_k: p.refine_k,
        icp: funcorr::pointwise::IcpOptions { max_iterations: p.icp_iterations },
        zoomout_to: p.zoomout_to.unwrap_or(base.zoomout_to),
        zoomout_step: p.zoomout_step.unwrap_or(base.zoomout_step),
        axiomatic,
        partial: funcorr::matching::partial::PartialOptions {
            mode: match (p.partial, p.no_partial) {
                (true, _) => funcorr::matching::partial::PartialMode::Always,
                (_, true) => funcorr::matching::partial::PartialMode::Never,
                _ => base.partial.mode,
            },
            ..base.partial
        },
        ..base
    })
}

/// One demand on the basis size: how many eigenpairs, who asks (e.g. "--zoomout-to (default
/// 150)") and the flag that changes it (None for a size no option sets).
pub(crate) struct Demand {
    pub(crate) size: usize,
    pub(crate) who: String,
    pub(crate) flag: Option<&'static str>,
}

/// Every demand of the options on the basis size (see [`basis_demand`]).
fn demands(p: &PipelineArgs, opts: &funcorr::matching::MatchOptions) -> Vec<Demand> {
    use funcorr::matching::{Method, Refine as R};
    let named = |given: bool, flag: &str, v: usize| {
        if given {
            format!("{flag} {v}")
        } else {
            format!("{flag} (default {v})")
        }
    };
    let mut parts = Vec::new();
    match opts.method {
        Method::Completion => {
            let kp = opts.completion.k_prime;
            parts.push(Demand { size: kp, who: named(p.kprime.is_some(), "--kprime", kp), flag: Some("--kprime") });
        }
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            let kmax = a.candidates.iter().copied().max().unwrap_or(0);
            let list = a.candidates.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(",");
            let (who, flag) = match (&p.candidates, p.k) {
                (Some(_), _) => (format!("--candidates {list}"), "--candidates"),
                (None, Some(k)) => (format!("-k {k}"), "-k"),
                (None, None) => (format!("--candidates (default {list})"), "--candidates"),
            };
            parts.push(Demand { size: kmax, who, flag: Some(flag) });
            let z = a.refine.k_final;
            parts.push(Demand {
                size: z,
                who: named(p.zoomout_to.is_some(), "--zoomout-to", z),
                flag: Some("--zoomout-to"),
            });
            let probe = a.probe.k_final;
            parts.push(Demand { size: probe, who: format!("the size selection (ZoomOut to {probe})"), flag: None });
        }
        _ => parts.push(Demand { size: opts.k, who: named(p.k.is_some(), "-k", opts.k), flag: Some("-k") }),
    }
    if opts.method != Method::Axiomatic && opts.refine == R::Zoomout {
        let z = opts.zoomout_to;
        parts.push(Demand {
            size: z,
            who: named(p.zoomout_to.is_some(), "--zoomout-to", z),
            flag: Some("--zoomout-to"),
        });
    }
    parts
}

/// The eigenpairs per shape that `funcorr match` computes, and the option that asks for the
/// most of them (e.g. "--zoomout-to (default 150)"), so that a shape with too few vertices gets
/// an error naming the option to change. Errors when --kprime is given but smaller than what
/// the other options need (the basis would silently be larger than asked).
pub(crate) fn basis_demand(p: &PipelineArgs, opts: &funcorr::matching::MatchOptions) -> Result<(usize, String)> {
    use funcorr::matching::{Method, DEFAULT_BASIS_SIZE};
    let parts = demands(p, opts);
    let (need, who) = parts.iter().max_by_key(|d| d.size).map(|d| (d.size, d.who.clone())).unwrap_or((0, "-k".into()));
    if opts.method == Method::Completion {
        return Ok((need.max(opts.basis_size()), who));
    }
    // The other methods compute --kprime eigenpairs (default 200), at least what they need.
    match p.kprime {
        Some(kp) if kp < need => Err(Error::invalid(
            "--kprime",
            format!(
                "{kp} eigenpairs per shape are fewer than the {need} that {who} needs; raise --kprime or lower {who}"
            ),
        )),
        Some(kp) => Ok((kp, format!("--kprime {kp}"))),
        None if need >= DEFAULT_BASIS_SIZE => Ok((need, who)),
        None => Ok((DEFAULT_BASIS_SIZE, format!("--kprime (default {DEFAULT_BASIS_SIZE})"))),
    }
}

/// The error for a shape of `n` vertices (read from `path`) too small for the `basis_k`
/// eigenpairs per shape that the options ask for (`basis_k ≥ n`): it names every option that
/// asks for n or more and the values that fit, or, when a size no option sets is too large
/// (the axiomatic method's size selection), another method that fits.
pub(crate) fn too_small(
    path: &Path,
    n: usize,
    p: &PipelineArgs,
    opts: &funcorr::matching::MatchOptions,
    basis_k: usize,
    demand: &str,
) -> Error {
    let most = n.saturating_sub(1);
    let mut over: Vec<Demand> = demands(p, opts).into_iter().filter(|d| d.size >= n).collect();
    if basis_k >= n && opts.method != funcorr::matching::Method::Completion && !over.iter().any(|d| d.who == demand) {
        over.insert(0, Demand { size: basis_k, who: demand.to_string(), flag: Some("--kprime") });
    }
    over.sort_by_key(|d| std::cmp::Reverse(d.size));
    let names: Vec<&str> = over.iter().map(|d| d.who.as_str()).collect();
    let file = funcorr::error::escape_path(path);
    let head = format!(
        "{file} has only n = {n} vertices, so at most {most} eigenpairs per shape, but {} ask{} for more",
        names.join(", "),
        if names.len() == 1 { "s" } else { "" }
    );
    if let Some(fixed) = over.iter().find(|d| d.flag.is_none()) {
        let kp = most.min(funcorr::matching::DEFAULT_BASIS_SIZE);
        let k = (kp / 2).clamp(1, 20);
        return Error::invalid(
            "--method",
            format!(
                "{head}; {} is not an option, so the axiomatic method needs shapes of more than {} vertices: \
                 match this pair with another method, e.g. --method fmap -k {k} --kprime {kp} --zoomout-to {kp}",
                fixed.who, fixed.size
            ),
        );
    }
    let mut flags: Vec<&str> = over.iter().filter_map(|d| d.flag).collect();
    flags.dedup();
    let fix: Vec<String> = flags.iter().map(|f| format!("{f} {most}")).collect();
    let them = if fix.len() == 1 { "it" } else { "them" };
    Error::invalid(
        flags.first().copied().unwrap_or("-k"),
        format!("{head}; lower {them} below {n}, e.g. {}", fix.join(" ")),
    )
}

/// The completion optimizer's stopping rule on the point map from --map-check-every (0: off) and
/// --map-tolerance.
pub(crate) fn settled_map(every: usize, tolerance: f64, k: usize) -> Result<Option<funcorr::completion::SettledMap>> {
    if every == 0 {
        return Ok(None);
    }
    if !(0.0..=1.0).contains(&tolerance) {
        return Err(Error::invalid("--map-tolerance", format!("must be in [0, 1], got {tolerance}")));
    }
    Ok(Some(funcorr::completion::SettledMap { every, tolerance, k }))
}
