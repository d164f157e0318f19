//! From command-line arguments to library calls: Laplacians, bases, data and match options.

#[allow(unused_imports)]
use super::*;

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
    let (lap, surface) = st.run("laplacian", || {
        funcorr::prepared::build_laplacian(&shape, laplacian_choice(lap_args)).map_err(laplacian_error(path))
    })?;
    let c = cache.cache();
    let basis =
        st.run("eigenbasis", || spectral::eigen_basis_cached(&lap, &SpectralOptions::new(k), c.as_ref(), None))?.0;
    Ok(funcorr::PreparedShape::from_parts(shape, lap, basis, surface))
}

/// The library's Laplacian choice for the CLI's arguments.
pub(crate) fn laplacian_choice(args: &LaplacianArgs) -> funcorr::prepared::LaplacianChoice {
    use funcorr::prepared::LaplacianChoice as L;
    match args.laplacian {
        None => L::Auto,
        Some(LaplacianChoice::Cotan) => L::Cotangent,
        Some(LaplacianChoice::Cloud) => L::Cloud { k: args.cloud_neighbours },
        Some(LaplacianChoice::Knn) => L::Knn(KnnOptions {
            k: args.knn_k,
            vertex_weights: match args.vertex_weights {
                WeightsChoice::Identity => VertexWeights::Identity,
                WeightsChoice::Degree => VertexWeights::Degree,
            },
            bandwidth: args.sigma.map_or(Bandwidth::SelfTuning, Bandwidth::Fixed),
        }),
    }
}

pub(crate) fn build_laplacian(shape: &Shape, path: &Path, args: &LaplacianArgs) -> Result<Laplacian> {
    Ok(funcorr::prepared::build_laplacian(shape, laplacian_choice(args)).map_err(laplacian_error(path))?.0)
}

/// Names the option or the file in a Laplacian error: `--laplacian` for a bad choice, the shape's
/// file for a shape without a Laplacian (zero area, vertices in no triangle, ...).
pub(crate) fn laplacian_error(path: &Path) -> impl Fn(Error) -> Error + '_ {
    move |e| match e {
        Error::Invalid { what, msg } if what == "laplacian" => Error::invalid("--laplacian", msg),
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
        ..base
    })
}

/// The eigenpairs per shape that `funcorr match` computes, and the option that asks for the
/// most of them (e.g. "--zoomout-to (default 150)"), so that a shape with too few vertices gets
/// an error naming the option to change. Errors when --kprime is given but smaller than what
/// the other options need (the basis would silently be larger than asked).
pub(crate) fn basis_demand(p: &PipelineArgs, opts: &funcorr::matching::MatchOptions) -> Result<(usize, String)> {
    use funcorr::matching::{Method, Refine as R, DEFAULT_BASIS_SIZE};
    let named = |given: bool, flag: &str, v: usize| {
        if given {
            format!("{flag} {v}")
        } else {
            format!("{flag} (default {v})")
        }
    };
    let mut parts: Vec<(usize, String)> = Vec::new();
    match opts.method {
        Method::Completion => {
            parts.push((opts.completion.k_prime, named(p.kprime.is_some(), "--kprime", opts.completion.k_prime)));
        }
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            let kmax = a.candidates.iter().copied().max().unwrap_or(0);
            let flag = if p.candidates.is_some() { "--candidates" } else { "-k" };
            parts.push((kmax, named(p.candidates.is_some() || p.k.is_some(), flag, kmax)));
            parts.push((a.refine.k_final, named(p.zoomout_to.is_some(), "--zoomout-to", a.refine.k_final)));
            parts.push((a.probe.k_final, format!("the size selection (ZoomOut to {})", a.probe.k_final)));
        }
        _ => parts.push((opts.k, named(p.k.is_some(), "-k", opts.k))),
    }
    if opts.method != Method::Axiomatic && opts.refine == R::Zoomout {
        parts.push((opts.zoomout_to, named(p.zoomout_to.is_some(), "--zoomout-to", opts.zoomout_to)));
    }
    let (need, who) = parts.iter().max_by_key(|(k, _)| *k).cloned().unwrap_or((0, "-k".into()));
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
