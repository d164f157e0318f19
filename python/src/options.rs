//! Keyword options → library options: the Python spelling of `funcorr match`'s flags
//! (`--zoomout-to` is `zoomout_to=`), with the same defaults (`MatchOptions::for_method`) and the
//! same checks, errors naming the keyword. An unknown keyword is an error, not ignored.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use funcorr::completion::{Form, Init, Optimizer, Scaling};
use funcorr::matching::{Extraction, MatchOptions, Method, Refine, DEFAULT_BASIS_SIZE};

use crate::arrays::value_error;

/// Keyword options, taken one by one; `finish` rejects those left over.
pub(crate) struct Opts<'py> {
    items: Vec<(String, Bound<'py, PyAny>)>,
}

impl<'py> Opts<'py> {
    pub(crate) fn new(d: Option<&Bound<'py, PyDict>>) -> PyResult<Self> {
        let mut items = Vec::new();
        if let Some(d) = d {
            for (k, v) in d.iter() {
                let k: String = k.extract()?;
                // None means "the default", as when the keyword is not given.
                if !v.is_none() {
                    items.push((k, v));
                }
            }
        }
        Ok(Opts { items })
    }

    pub(crate) fn has(&self, key: &str) -> bool {
        self.items.iter().any(|(k, _)| k == key)
    }

    pub(crate) fn take(&mut self, key: &str) -> Option<Bound<'py, PyAny>> {
        let i = self.items.iter().position(|(k, _)| k == key)?;
        Some(self.items.remove(i).1)
    }

    pub(crate) fn usize(&mut self, key: &str) -> PyResult<Option<usize>> {
        self.take(key)
            .map(|v| {
                if v.is_instance_of::<pyo3::types::PyBool>() {
                    return Err(value_error(key, "expected a non-negative integer, got a bool"));
                }
                v.extract::<usize>().map_err(|_| value_error(key, format!("expected a non-negative integer, got {v}")))
            })
            .transpose()
    }

    pub(crate) fn f64(&mut self, key: &str) -> PyResult<Option<f64>> {
        self.take(key)
            .map(|v| {
                let x = v.extract::<f64>().map_err(|_| value_error(key, format!("expected a number, got {v}")))?;
                if !x.is_finite() {
                    return Err(value_error(key, format!("must be finite, got {x}")));
                }
                Ok(x)
            })
            .transpose()
    }

    pub(crate) fn flag(&mut self, key: &str) -> PyResult<Option<bool>> {
        self.take(key)
            .map(|v| v.extract::<bool>().map_err(|_| value_error(key, format!("expected a bool, got {v}"))))
            .transpose()
    }

    pub(crate) fn string(&mut self, key: &str) -> PyResult<Option<String>> {
        self.take(key)
            .map(|v| v.extract::<String>().map_err(|_| value_error(key, format!("expected a string, got {v}"))))
            .transpose()
    }

    pub(crate) fn sizes(&mut self, key: &str) -> PyResult<Option<Vec<usize>>> {
        self.take(key)
            .map(|v| {
                if let Ok(k) = v.extract::<usize>() {
                    return Ok(vec![k]);
                }
                v.extract::<Vec<usize>>().map_err(|_| value_error(key, format!("expected a list of sizes, got {v}")))
            })
            .transpose()
    }

    pub(crate) fn finish(self) -> PyResult<()> {
        match self.items.first() {
            None => Ok(()),
            Some((k, _)) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "unexpected keyword argument {k:?} (the options are funcorr match's flags with '_' for '-': see help(funcorr.match))"
            ))),
        }
    }
}

fn choice<T: Copy>(key: &str, v: Option<String>, default: T, table: &[(&str, T)]) -> PyResult<T> {
    let Some(v) = v else { return Ok(default) };
    table.iter().find(|(name, _)| *name == v).map(|(_, t)| *t).ok_or_else(|| {
        let names: Vec<&str> = table.iter().map(|(n, _)| *n).collect();
        value_error(key, format!("{v:?}: expected one of {}", names.join(", ")))
    })
}

/// The persistence segmentation options (`seg_function`, `threshold`, `hks_time`).
pub(crate) fn segmentation(o: &mut Opts) -> PyResult<funcorr::descriptors::persistence::SegmentationOptions> {
    use funcorr::descriptors::persistence::{SegmentFunction, SegmentationOptions};
    let d = SegmentationOptions::default();
    let function = choice(
        "seg_function",
        o.string("seg_function")?,
        d.function,
        &[("hks", SegmentFunction::Hks), ("agd", SegmentFunction::Agd)],
    )?;
    Ok(SegmentationOptions {
        function,
        threshold: o.f64("threshold")?.unwrap_or(d.threshold),
        hks_time: o.f64("hks_time")?.unwrap_or(d.hks_time),
    })
}

/// The library options of `funcorr match` for these keywords (`method` among them) and data
/// (`rich`: many functions), the eigenpairs per shape it computes, and the keyword that asks for
/// the most of them (for errors on small shapes). Follows the CLI's `pipeline_options` and
/// `basis_demand` (cli/src/options.rs) keyword for flag.
pub(crate) fn match_options(o: &mut Opts, rich: bool) -> PyResult<(MatchOptions, usize, String)> {
    use funcorr::fmap::energy::{EnergyWeights, Mask, Orientation};
    let method = choice(
        "method",
        o.string("method")?,
        Method::Axiomatic,
        &[
            ("axiomatic", Method::Axiomatic),
            ("fmap", Method::Fmap),
            ("pokrass", Method::Pokrass),
            ("coupled", Method::Coupled),
            ("completion", Method::Completion),
        ],
    )?;
    let base = MatchOptions::for_method(method, rich);
    let scaling =
        choice("scaling", o.string("scaling")?, Scaling::Unit, &[("unit", Scaling::Unit), ("paper", Scaling::Paper)])?;
    let form = choice(
        "form",
        o.string("form")?,
        Form::Subspace,
        &[
            ("subspace", Form::Subspace),
            ("fixed-rank", Form::FixedRank),
            ("fixed_rank", Form::FixedRank),
            ("low-rank", Form::LowRank),
            ("low_rank", Form::LowRank),
            ("low-norm", Form::LowNorm),
            ("low_norm", Form::LowNorm),
        ],
    )?;
    let k = o.usize("k")?;
    let kprime = o.usize("kprime")?;
    let mut completion = funcorr::matching::completion_defaults(rich, scaling, form);
    if let Some(k) = k {
        completion.k = k;
    }
    if let Some(kp) = kprime {
        completion.k_prime = kp;
    }
    if method == Method::Completion && !(1..=completion.k_prime).contains(&completion.k) {
        return Err(value_error(
            if k.is_some() { "k" } else { "kprime" },
            format!(
                "the completion rank {} must be between 1 and the subspace size kprime = {}",
                completion.k, completion.k_prime
            ),
        ));
    }
    completion.init = choice("init", o.string("init")?, Init::Pad, &[("pad", Init::Pad), ("svd", Init::Svd)])?;
    let optimizer = o.string("optimizer")?;
    completion.optimizer = match optimizer {
        None => None,
        v => Some(choice("optimizer", v, Optimizer::Lbfgs, &[("lbfgs", Optimizer::Lbfgs), ("rcg", Optimizer::Rcg)])?),
    };
    let w = &mut completion.params;
    let mu4 = o.f64("mu4")?;
    for (slot, key) in [(&mut w.mu1, "mu1"), (&mut w.mu2, "mu2"), (&mut w.mu3, "mu3"), (&mut w.xi, "xi")] {
        if let Some(v) = o.f64(key)? {
            *slot = v;
        }
    }
    if let Some(v) = mu4 {
        w.mu4 = v;
    }
    if completion.optimizer == Some(Optimizer::Rcg) || completion.form == Form::FixedRank {
        if mu4.is_some_and(|m| m != 0.0) {
            return Err(value_error("mu4", "the fixed-rank forms have no low-norm term"));
        }
        w.mu4 = 0.0;
    }
    w.mu_comm = o.f64("completion_commutativity")?.unwrap_or(funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY);
    w.k_comm = o.usize("completion_commutativity_k")?.unwrap_or(funcorr::matching::DEFAULT_COMPLETION_COMMUTATIVITY_K);
    w.mu_prior = o.f64("completion_prior")?.unwrap_or(0.0);
    let defaults = MatchOptions::default();
    completion.optimize = funcorr::completion::OptimizeOptions {
        max_iterations: o.usize("max_iterations")?.unwrap_or(defaults.completion.optimize.max_iterations),
        rel_tol: o.f64("rel_tol")?.unwrap_or(defaults.completion.optimize.rel_tol),
        ..funcorr::completion::OptimizeOptions::default()
    };
    let commutativity = o.f64("commutativity")?.unwrap_or(base.commutativity);
    if commutativity < 0.0 {
        return Err(value_error("commutativity", "must be ≥ 0"));
    }
    let refine = match o.string("refine")? {
        None => None,
        v => Some(choice(
            "refine",
            v,
            Refine::None,
            &[("none", Refine::None), ("icp", Refine::Icp), ("zoomout", Refine::Zoomout)],
        )?),
    };
    // The L1 samples and the stopping rule on the point map (EXPERIMENTS.md, "Speed options of the
    // completion method and large shapes"), as the CLI's
    // --l1-samples, --map-check-every, --map-tolerance.
    if let Some(samples) = o.usize("l1_samples")? {
        completion.l1_sampling = funcorr::completion::L1Sampling::farthest(samples);
    }
    // The CLI's --l1-precision (and its older --l1-f32).
    {
        use funcorr::completion::Precision as P;
        let default = completion.params.l1_precision;
        let precision = o.string("l1_precision")?;
        let given = precision.is_some();
        completion.params.l1_precision =
            choice("l1_precision", precision, default, &[("f64", P::F64), ("f32", P::F32)])?;
        if o.flag("l1_f32")?.unwrap_or(false) {
            if given {
                return Err(value_error("l1_f32", "give either l1_precision or l1_f32, not both"));
            }
            completion.params.l1_precision = P::F32;
        }
    }
    // The conditioning options (EXPERIMENTS.md, "Conditioning the completion problem"), as the CLI's
    // --precondition, --xi-stages, --multiscale.
    {
        use funcorr::completion::Precondition as P;
        let table = [("off", P::Off), ("quadratic", P::Quadratic), ("full", P::Full)];
        completion.precondition = choice("precondition", o.string("precondition")?, P::Off, &table)?;
    }
    completion.xi_stages = o.usize("xi_stages")?.unwrap_or(0);
    if let Some(stages) = o.usize("multiscale")? {
        completion.multiscale = stages;
    }
    let refine_k = o.usize("refine_k")?.unwrap_or(MatchOptions::default().refine_k);
    let every = o.usize("map_check_every")?.unwrap_or(0);
    let tolerance = o.f64("map_tolerance")?.unwrap_or(0.005);
    if every > 0 {
        if !(0.0..=1.0).contains(&tolerance) {
            return Err(value_error("map_tolerance", format!("must be in [0, 1], got {tolerance}")));
        }
        let refined = match refine {
            Some(r) => r != Refine::None,
            None => base.refine != funcorr::matching::Refine::None,
        };
        let k = if refined { refine_k } else { 0 };
        completion.settled = Some(funcorr::completion::SettledMap { every, tolerance, k });
    }
    let zoomout_to = o.usize("zoomout_to")?;
    let zoomout_step = o.usize("zoomout_step")?;
    let candidates = o.sizes("candidates")?;
    let axiomatic = {
        let mut a = base.axiomatic.clone();
        let dw = a.fit.weights;
        a.fit.weights = EnergyWeights {
            descriptors: o.f64("w_descriptors")?.unwrap_or(dw.descriptors),
            laplacian: o.f64("w_laplacian")?.unwrap_or(dw.laplacian),
            commutativity: o.f64("w_commutativity")?.unwrap_or(dw.commutativity),
            orientation: o.f64("w_orientation")?.unwrap_or(dw.orientation),
        };
        a.fit.mask = choice(
            "mask",
            o.string("mask")?,
            Mask::Resolvent { gamma: 0.5 },
            &[("resolvent", Mask::Resolvent { gamma: 0.5 }), ("standard", Mask::Standard)],
        )?;
        a.fit.orientation = choice(
            "orientation",
            o.string("orientation")?,
            Orientation::Preserve,
            &[("preserve", Orientation::Preserve), ("reverse", Orientation::Reverse), ("ignore", Orientation::Ignore)],
        )?;
        a.signed = o.usize("signed")?.unwrap_or(a.signed);
        if let Some(c) = &candidates {
            a.candidates = c.clone();
        } else if let Some(k) = k {
            a.candidates = vec![k];
        }
        match refine {
            Some(Refine::None) => a.refine.k_final = 0,
            Some(Refine::Icp) if method == Method::Axiomatic => {
                return Err(value_error(
                    "refine",
                    "the axiomatic method refines with ZoomOut (or none); ICP is for the other methods",
                ))
            }
            _ => {}
        }
        if let Some(kf) = zoomout_to {
            if refine != Some(Refine::None) {
                a.refine.k_final = kf;
            }
        }
        if let Some(s) = zoomout_step {
            a.refine.step = s;
        }
        a.refine.samples = o.usize("zoomout_samples")?.unwrap_or(a.refine.samples);
        a.polish = o.usize("polish")?.unwrap_or(a.polish);
        // Large pairs: --near-above, --near-cells.
        a.near.above_pairs = o.usize("near_above")?.map_or(a.near.above_pairs, |v| v as u64);
        a.near.cells = o.usize("near_cells")?.unwrap_or(a.near.cells);
        if a.near.cells == 0 {
            return Err(value_error("near_cells", "must be at least 1"));
        }
        for (key, v) in [
            ("w_descriptors", a.fit.weights.descriptors),
            ("w_laplacian", a.fit.weights.laplacian),
            ("w_commutativity", a.fit.weights.commutativity),
            ("w_orientation", a.fit.weights.orientation),
        ] {
            if v < 0.0 {
                return Err(value_error(key, format!("must be ≥ 0, got {v}")));
            }
        }
        if a.candidates.is_empty() || a.candidates.contains(&0) {
            return Err(value_error("candidates", "need one or more sizes ≥ 1"));
        }
        if a.refine.step == 0 {
            return Err(value_error("zoomout_step", "must be at least 1"));
        }
        a
    };
    let extraction = choice(
        "extract",
        o.string("extract")?,
        Extraction::Nn,
        &[("nn", Extraction::Nn), ("argmax", Extraction::Argmax), ("fmap", Extraction::Fmap)],
    )?;
    // partial=True is `--partial`, partial=False `--no-partial`; None detects.
    let partial = funcorr::matching::partial::PartialOptions {
        mode: match o.flag("partial")? {
            Some(true) => funcorr::matching::partial::PartialMode::Always,
            Some(false) => funcorr::matching::partial::PartialMode::Never,
            None => base.partial.mode,
        },
        ..base.partial
    };
    if partial.mode == funcorr::matching::partial::PartialMode::Always && method != Method::Axiomatic {
        return Err(value_error("partial", "partial matching is a path of the axiomatic method (the default)"));
    }
    let opts = MatchOptions {
        method,
        partial,
        k: k.unwrap_or(base.k),
        commutativity,
        completion,
        init_k: o.usize("init_k")?.unwrap_or(defaults.init_k),
        extraction,
        refine: refine.unwrap_or(base.refine),
        refine_k,
        icp: funcorr::pointwise::IcpOptions {
            max_iterations: o.usize("icp_iterations")?.unwrap_or(defaults.icp.max_iterations),
        },
        zoomout_to: zoomout_to.unwrap_or(base.zoomout_to),
        zoomout_step: zoomout_step.unwrap_or(base.zoomout_step),
        axiomatic,
        ..base
    };
    // Eigenpairs per shape (the CLI's basis_demand).
    let mut parts: Vec<(usize, String)> = Vec::new();
    match opts.method {
        Method::Completion => parts.push((opts.completion.k_prime, "kprime".into())),
        Method::Axiomatic => {
            let a = &opts.axiomatic;
            let kmax = a.candidates.iter().copied().max().unwrap_or(0);
            parts.push((kmax, if candidates.is_some() { "candidates" } else { "k" }.into()));
            parts.push((a.refine.k_final, "zoomout_to".into()));
            parts.push((a.probe.k_final, format!("the size selection (ZoomOut to {})", a.probe.k_final)));
        }
        _ => parts.push((opts.k, "k".into())),
    }
    if opts.method != Method::Axiomatic && opts.refine == Refine::Zoomout {
        parts.push((opts.zoomout_to, "zoomout_to".into()));
    }
    let (need, who) = parts.iter().max_by_key(|(k, _)| *k).cloned().unwrap_or((0, "k".into()));
    let basis = if opts.method == Method::Completion {
        (need.max(opts.basis_size()), who)
    } else {
        match kprime {
            Some(kp) if kp < need => {
                return Err(value_error(
                    "kprime",
                    format!(
                    "{kp} eigenpairs per shape are fewer than the {need} that {who} needs; raise kprime or lower {who}"
                ),
                ))
            }
            Some(kp) => (kp, "kprime".into()),
            None if need >= DEFAULT_BASIS_SIZE => (need, who),
            None => (DEFAULT_BASIS_SIZE, "kprime".into()),
        }
    };
    Ok((opts, basis.0, basis.1))
}
