//! The pipeline's options by name: the one table of the options of `funcorr match` (flags such
//! as `--zoomout-to`) and of `funcorr.match` (keywords such as `zoomout_to=`), how the values
//! given resolve into [`MatchOptions`] (the defaults of the method and data, then what was given),
//! their checks, and the eigenpairs per shape they ask for.
//!
//! **Names.** Every option has one key, its field name in [`MatchSettings`] and its row in
//! [`MATCH_OPTIONS`]: the Python keyword is the key, the command-line flag is `--` and the key
//! with `-` for `_` (`-k` for `k`). The front ends only translate names: they set the values
//! given with [`MatchSettings::set`] and print the errors, which name options through a
//! [`Spelling`] ([`Keywords`] for Rust and Python).
//!
//! **Adding an option** (e.g. a flag `--partial`): one row in the `match_settings!` invocation
//! below (`partial: bool,` with its documentation: the field of [`MatchSettings`], its row in
//! [`MATCH_OPTIONS`] and its arm of [`MatchSettings::set`] follow from it), its effect in
//! [`MatchSettings::resolve_as`] (a field of [`MatchOptions`] if the pipeline needs a new one) and
//! its check in [`MatchOptions::validate_as`]; then the field of the same name, with its help
//! text, in the CLI's `PipelineArgs` (`cli/src/args.rs`) and the keyword in the docstring of
//! `funcorr.match` (`python/funcorr/__init__.py`). Nothing else: the CLI hands its fields over by
//! name and Python its keywords by the table's kinds. The CLI's test
//! `every_flag_is_the_library_option_of_its_name` fails until the flag exists and sets the option
//! of its name, `python/tests/test_options.py` until the keyword is documented. A value of a new
//! kind (a file, say) needs its [`Kind`], [`Value`] and conversion here, and one arm in the CLI's
//! `settings` and in Python's `match_settings`.
//!
//! One module over 600 lines: the table, what each option means (its resolution), the checks
//! and the basis demand are one concern, the meaning of the options, changed together.
//!
//! **Defaults.** An option that is not set takes the value of
//! [`MatchOptions::for_method`] for the method and data, or the default documented on its field.

use std::fmt::Display;

use serde::{Deserialize, Serialize};

use super::axiomatic::NearSearch;
use super::partial::{PartialMode, PartialOptions};
use super::{completion_defaults, Extraction, MatchOptions, Method, Refine, AXIOMATIC_BASIS_SIZE, DEFAULT_BASIS_SIZE};
use super::{DEFAULT_COMPLETION_COMMUTATIVITY, DEFAULT_COMPLETION_COMMUTATIVITY_K};
use crate::completion::SettledMap;
use crate::completion::{Form, Init, L1Sampling, OptimizeOptions, Optimizer, Precision, Precondition, Scaling};
use crate::error::{Error, Result};
use crate::fmap::energy::{EnergyWeights, Mask, Orientation};
use crate::pointwise::IcpOptions;

/// How a front end writes the name of an option in its messages.
pub trait Spelling {
    /// The name of the option `key` (e.g. `zoomout_to`, or `--zoomout-to` on the command line).
    fn name(&self, key: &str) -> String;
    /// The option `key` with the value `value` (e.g. `zoomout_to=90`, or `--zoomout-to 90`).
    fn given(&self, key: &str, value: &dyn Display) -> String;
}

/// Options named by their keys (`zoomout_to`, `zoomout_to=90`): Rust and Python.
#[derive(Clone, Copy, Debug, Default)]
pub struct Keywords;

impl Spelling for Keywords {
    fn name(&self, key: &str) -> String {
        key.to_string()
    }
    fn given(&self, key: &str, value: &dyn Display) -> String {
        format!("{key}={value}")
    }
}

/// The kind of value an option takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A count or size ≥ 0.
    Size,
    /// A real number.
    Number,
    /// On or off.
    Flag,
    /// A list of sizes (a single size is a list of one).
    Sizes,
    /// One of these names.
    Choice(&'static [&'static str]),
}

/// One option of the table: its key and the kind of its value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OptionSpec {
    /// The key: the field of [`MatchSettings`], the Python keyword, the flag with `_` for `-`.
    pub key: &'static str,
    /// The kind of its value.
    pub kind: Kind,
}

/// A value given to an option ([`MatchSettings::set`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// For [`Kind::Size`] (and [`Kind::Sizes`]: a list of one).
    Size(usize),
    /// For [`Kind::Number`].
    Number(f64),
    /// For [`Kind::Flag`].
    Flag(bool),
    /// For [`Kind::Sizes`].
    Sizes(Vec<usize>),
    /// For [`Kind::Choice`]: one of its names (`_` may stand for `-`).
    Choice(String),
}

/// A type an option's value converts to.
trait OptionValue: Sized {
    const KIND: Kind;
    /// The value, or why it is not one of this type (the caller names the option).
    fn from_value(v: Value) -> std::result::Result<Self, String>;
    /// The value as given by name: the inverse of `from_value` (Err for a value no name gives,
    /// such as a [`Mask::Resolvent`] of another γ built in Rust).
    fn to_value(&self) -> std::result::Result<Value, String>;
}

fn expected(what: &str, v: &Value) -> String {
    format!("expected {what}, got {v:?}")
}

impl OptionValue for usize {
    const KIND: Kind = Kind::Size;
    fn from_value(v: Value) -> std::result::Result<Self, String> {
        match v {
            Value::Size(s) => Ok(s),
            v => Err(expected("a non-negative integer", &v)),
        }
    }
    fn to_value(&self) -> std::result::Result<Value, String> {
        Ok(Value::Size(*self))
    }
}

impl OptionValue for u64 {
    const KIND: Kind = Kind::Size;
    fn from_value(v: Value) -> std::result::Result<Self, String> {
        usize::from_value(v).map(|s| s as u64)
    }
    fn to_value(&self) -> std::result::Result<Value, String> {
        usize::try_from(*self).map(Value::Size).map_err(|_| format!("{self} does not fit a size"))
    }
}

impl OptionValue for f64 {
    const KIND: Kind = Kind::Number;
    fn from_value(v: Value) -> std::result::Result<Self, String> {
        match v {
            Value::Number(x) if x.is_finite() => Ok(x),
            Value::Number(x) => Err(format!("must be finite, got {x}")),
            Value::Size(s) => Ok(s as f64),
            v => Err(expected("a number", &v)),
        }
    }
    fn to_value(&self) -> std::result::Result<Value, String> {
        Ok(Value::Number(*self))
    }
}

impl OptionValue for bool {
    const KIND: Kind = Kind::Flag;
    fn from_value(v: Value) -> std::result::Result<Self, String> {
        match v {
            Value::Flag(b) => Ok(b),
            v => Err(expected("a bool", &v)),
        }
    }
    fn to_value(&self) -> std::result::Result<Value, String> {
        Ok(Value::Flag(*self))
    }
}

impl OptionValue for Vec<usize> {
    const KIND: Kind = Kind::Sizes;
    fn from_value(v: Value) -> std::result::Result<Self, String> {
        match v {
            Value::Sizes(s) => Ok(s),
            Value::Size(s) => Ok(vec![s]),
            v => Err(expected("a list of sizes", &v)),
        }
    }
    fn to_value(&self) -> std::result::Result<Value, String> {
        Ok(Value::Sizes(self.clone()))
    }
}

/// The names of the values of the enums that options choose from, in one place.
macro_rules! choices {
    ($($ty:ty { $($name:literal => $value:expr),+ $(,)? })*) => {$(
        impl OptionValue for $ty {
            const KIND: Kind = Kind::Choice(&[$($name),+]);
            fn from_value(v: Value) -> std::result::Result<Self, String> {
                let Value::Choice(s) = v else { return Err(expected("a name", &v)) };
                match s.replace('_', "-").as_str() {
                    $($name => Ok($value),)+
                    _ => Err(format!("{s:?}: expected one of {}", [$($name),+].join(", "))),
                }
            }
            fn to_value(&self) -> std::result::Result<Value, String> {
                [$($name),+]
                    .into_iter()
                    .find(|n| Self::from_value(Value::Choice(n.to_string())).as_ref() == Ok(self))
                    .map(|n| Value::Choice(n.to_string()))
                    .ok_or_else(|| format!("{self:?} has no name"))
            }
        }
    )*};
}

choices! {
    Method {
        "axiomatic" => Method::Axiomatic, "fmap" => Method::Fmap, "pokrass" => Method::Pokrass,
        "coupled" => Method::Coupled, "completion" => Method::Completion,
    }
    Form {
        "subspace" => Form::Subspace, "fixed-rank" => Form::FixedRank, "low-rank" => Form::LowRank,
        "low-norm" => Form::LowNorm,
    }
    Scaling { "unit" => Scaling::Unit, "paper" => Scaling::Paper }
    Init { "pad" => Init::Pad, "svd" => Init::Svd }
    Optimizer { "lbfgs" => Optimizer::Lbfgs, "rcg" => Optimizer::Rcg }
    Precision { "f64" => Precision::F64, "f32" => Precision::F32 }
    Precondition { "off" => Precondition::Off, "quadratic" => Precondition::Quadratic, "full" => Precondition::Full }
    Extraction { "nn" => Extraction::Nn, "argmax" => Extraction::Argmax, "fmap" => Extraction::Fmap }
    Refine { "none" => Refine::None, "icp" => Refine::Icp, "zoomout" => Refine::Zoomout }
    Orientation { "preserve" => Orientation::Preserve, "reverse" => Orientation::Reverse, "ignore" => Orientation::Ignore }
    Mask { "resolvent" => Mask::Resolvent { gamma: 0.5 }, "standard" => Mask::Standard }
}

/// [`MatchSettings`], [`MATCH_OPTIONS`] and [`MatchSettings::set`] from one list of options.
macro_rules! match_settings {
    ($($(#[doc = $doc:literal])* $key:ident: $ty:ty,)*) => {
        /// The options of the pipeline by name, each unset (`None`: the default of the method and
        /// data) or given; [`MatchSettings::resolve`] turns them into [`MatchOptions`]. Serialized
        /// (serde) as a map of the options given, by the keys of [`MATCH_OPTIONS`] and the names
        /// of their values (`{"method": "axiomatic", "zoomout_to": 90, "candidates": [20, 30]}`),
        /// so a settings file written by one front end is read back by any other.
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct MatchSettings {
            $($(#[doc = $doc])* pub $key: Option<$ty>,)*
        }

        /// Every option of [`MatchSettings`], in the order of its fields.
        pub const MATCH_OPTIONS: &[OptionSpec] =
            &[$(OptionSpec { key: stringify!($key), kind: <$ty as OptionValue>::KIND },)*];

        impl MatchSettings {
            /// Sets option `key` (a key of [`MATCH_OPTIONS`]) to `value`. Errors name the option
            /// by its key: an unknown key, a value of another kind, a name that is not one of its
            /// choices.
            pub fn set(&mut self, key: &str, value: Value) -> Result<()> {
                match key {
                    $(stringify!($key) => {
                        self.$key = Some(<$ty as OptionValue>::from_value(value).map_err(|m| Error::invalid(key, m))?);
                    })*
                    _ => return Err(Error::invalid(key, "not an option of the matching pipeline")),
                }
                Ok(())
            }

            /// The value of option `key` as given by name, None when unset. Errors: an unknown
            /// key, a value no name gives (built in Rust, not by [`MatchSettings::set`]).
            pub fn get(&self, key: &str) -> Result<Option<Value>> {
                match key {
                    $(stringify!($key) => self.$key.as_ref().map(OptionValue::to_value).transpose().map_err(|m| Error::invalid(key, m)),)*
                    _ => Err(Error::invalid(key, "not an option of the matching pipeline")),
                }
            }
        }
    };
}

match_settings! {
    /// The functional-map method (default axiomatic).
    method: Method,
    /// Form of the completion method (default subspace).
    form: Form,
    /// Size k of the baselines' functional map (default 50), the rank of the completion method
    /// (its default per data), and for the axiomatic method its one candidate size.
    k: usize,
    /// Eigenpairs per shape k': the basis size of the baselines and the axiomatic method
    /// (default 200; 128 for the axiomatic method where X cannot be a part,
    /// [`MatchSettings::basis_demand_for`]), the completion method's subspace size.
    kprime: usize,
    /// μ_c of eq. (5) (default 1e-3 for rich data, 0 for scarce data).
    commutativity: f64,
    /// Normalization of the completion method's weights (default unit).
    scaling: Scaling,
    /// μ1 of the completion method (default per scaling and form).
    mu1: f64,
    /// μ2 of the completion method.
    mu2: f64,
    /// μ3 of the completion method.
    mu3: f64,
    /// μ4 of the completion method (the fixed-rank forms: 0).
    mu4: f64,
    /// ξ of the smoothed absolute value.
    xi: f64,
    /// Weight of the completion method's commutativity term (default
    /// [`DEFAULT_COMPLETION_COMMUTATIVITY`]).
    completion_commutativity: f64,
    /// Its leading block (default [`DEFAULT_COMPLETION_COMMUTATIVITY_K`], 0: all k').
    completion_commutativity_k: usize,
    /// Weight of the completion method's axiomatic prior (default 0: off).
    completion_prior: f64,
    /// Initialization of the completion method (default pad).
    init: Init,
    /// Size of the eq. (5) map that starts the completion method (default 50).
    init_k: usize,
    /// Optimizer of the completion method (default per form).
    optimizer: Optimizer,
    /// Iteration cap of the completion optimizer (default 150).
    max_iterations: usize,
    /// Relative decrease that stops the completion optimizer.
    rel_tol: f64,
    /// Farthest-point samples of the completion method's L1 term (0: every vertex).
    l1_samples: usize,
    /// Arithmetic of the L1 products (default f32 for the subspace form, f64 for the others).
    l1_precision: Precision,
    /// `true`: the same as `l1_precision` f32 (for older scripts).
    l1_f32: bool,
    /// Preconditioner of the completion method's L-BFGS (default off).
    precondition: Precondition,
    /// Continuation stages in ξ (default 0: off).
    xi_stages: usize,
    /// Multiscale stages of the completion method (default 2).
    multiscale: usize,
    /// Check the completion method's point map every this many iterations (default 0: off).
    map_check_every: usize,
    /// Fraction of checked vertices whose image may still change (default 0.005).
    map_tolerance: f64,
    /// Point-map extraction of the completion method (default nn; the output map only with
    /// refine none, a refinement starts from C).
    extract: Extraction,
    /// Point-wise refinement (default zoomout for rich data, icp for scarce data).
    refine: Refine,
    /// Size of the map the completion method's refinement starts from (default 50).
    refine_k: usize,
    /// ICP iterations (default 10).
    icp_iterations: usize,
    /// Final size of ZoomOut (default 128 for the axiomatic method, 150 for the others).
    zoomout_to: usize,
    /// ZoomOut's size increment (default 5 for the axiomatic method, 1 for the others).
    zoomout_step: usize,
    /// Samples of the axiomatic method's ZoomOut (0: every vertex).
    zoomout_samples: usize,
    /// Rounds of the axiomatic method's bijective polish.
    polish: usize,
    /// Vertex pairs n·m above which the axiomatic method's searches are restricted.
    near_above: u64,
    /// Cells searched around each sample's image.
    near_cells: usize,
    /// Vertex pairs n·m above which the axiomatic method's map Y → X is searched near its final
    /// map X → Y (which stays exact up to `near_above`).
    near_inverse_above: u64,
    /// Vertex pairs n·m up to which the axiomatic method's final map X → Y, where it is searched
    /// near the samples' map, is made exact by a certificate (`crate::certified_search`; by
    /// default at every size).
    near_certified_up_to: u64,
    /// Vertex pairs n·m up to which the axiomatic method's map Y → X, where restricted, is
    /// searched near the preimages of the map X → Y and certified exact (default 1e10).
    near_inverse_certified_up_to: u64,
    /// X is a part of Y: true matches it with the partial path ([`super::partial`]), false as a
    /// whole shape; unset, the axiomatic method detects a part ([`super::partial::detect`]).
    partial: bool,
    /// The share of Y's area that a part X covers, in (0, 1.5], when known (unset: estimated
    /// from the heat kernels, [`super::partial`] step 0); implies the partial path.
    partial_ratio: f64,
    /// Which maps the axiomatic method looks for (default preserve).
    orientation: Orientation,
    /// Signed descriptors of the axiomatic method.
    signed: usize,
    /// Candidate sizes of the axiomatic method (default 20, 30, 40, 50, or `k` alone).
    candidates: Vec<usize>,
    /// Weight of descriptor preservation in the axiomatic energy.
    w_descriptors: f64,
    /// Weight of Laplacian commutativity in the axiomatic energy.
    w_laplacian: f64,
    /// Weight of descriptor commutativity in the axiomatic energy.
    w_commutativity: f64,
    /// Weight of the orientation term in the axiomatic energy.
    w_orientation: f64,
    /// Laplacian-commutativity mask of the axiomatic energy (default resolvent).
    mask: Mask,
}

impl Value {
    /// The value in JSON: a number, a bool, a list of numbers or a name.
    fn to_json(&self) -> serde_json::Value {
        match self {
            Value::Size(s) => (*s).into(),
            Value::Number(x) => (*x).into(),
            Value::Flag(b) => (*b).into(),
            Value::Sizes(s) => s.clone().into(),
            Value::Choice(c) => c.clone().into(),
        }
    }

    /// The value of an option of kind `kind` written in JSON, or why it is not one.
    fn from_json(kind: Kind, j: &serde_json::Value) -> std::result::Result<Value, String> {
        let size = |j: &serde_json::Value| {
            j.as_u64()
                .and_then(|s| usize::try_from(s).ok())
                .ok_or_else(|| format!("expected a non-negative integer, got {j}"))
        };
        Ok(match kind {
            Kind::Size => Value::Size(size(j)?),
            Kind::Number => Value::Number(j.as_f64().ok_or_else(|| format!("expected a number, got {j}"))?),
            Kind::Flag => Value::Flag(j.as_bool().ok_or_else(|| format!("expected true or false, got {j}"))?),
            Kind::Sizes => match j.as_array() {
                Some(a) => Value::Sizes(a.iter().map(size).collect::<std::result::Result<_, _>>()?),
                None => Value::Size(size(j)?),
            },
            Kind::Choice(_) => {
                Value::Choice(j.as_str().ok_or_else(|| format!("expected a name, got {j}"))?.to_string())
            }
        })
    }
}

impl MatchSettings {
    /// The settings of a JSON object `{key: value}` (keys of [`MATCH_OPTIONS`]; `null`: unset).
    /// Errors name the option: an unknown key, a value of another kind or out of its choices.
    pub fn from_json(object: &serde_json::Map<String, serde_json::Value>) -> Result<MatchSettings> {
        let mut s = MatchSettings::default();
        for (key, j) in object {
            let Some(spec) = MATCH_OPTIONS.iter().find(|o| o.key == key) else {
                return Err(Error::invalid(key, "not an option of the matching pipeline"));
            };
            if !j.is_null() {
                s.set(spec.key, Value::from_json(spec.kind, j).map_err(|m| Error::invalid(key, m))?)?;
            }
        }
        Ok(s)
    }

    /// The options given, as a JSON object by key (the inverse of [`MatchSettings::from_json`]).
    pub fn to_json(&self) -> Result<serde_json::Map<String, serde_json::Value>> {
        let mut m = serde_json::Map::new();
        for spec in MATCH_OPTIONS {
            if let Some(v) = self.get(spec.key)? {
                m.insert(spec.key.to_string(), v.to_json());
            }
        }
        Ok(m)
    }
}

impl Serialize for MatchSettings {
    fn serialize<S: serde::Serializer>(&self, ser: S) -> std::result::Result<S::Ok, S::Error> {
        self.to_json().map_err(serde::ser::Error::custom)?.serialize(ser)
    }
}

impl<'de> Deserialize<'de> for MatchSettings {
    fn deserialize<D: serde::Deserializer<'de>>(de: D) -> std::result::Result<Self, D::Error> {
        let object = serde_json::Map::<String, serde_json::Value>::deserialize(de)?;
        MatchSettings::from_json(&object).map_err(serde::de::Error::custom)
    }
}

/// The completion optimizer's stopping rule on the point map: checked every `every` iterations
/// (0: off) with `tolerance` in [0, 1], on the map of the leading k × k block of C (0: of the
/// factors). Errors name `map_tolerance`.
pub fn settled_map(every: usize, tolerance: f64, k: usize, sp: &dyn Spelling) -> Result<Option<SettledMap>> {
    if every == 0 {
        return Ok(None);
    }
    if !(0.0..=1.0).contains(&tolerance) {
        return Err(Error::invalid(sp.name("map_tolerance"), format!("must be in [0, 1], got {tolerance}")));
    }
    Ok(Some(SettledMap { every, tolerance, k }))
}

/// One demand of the options on the basis size: how many eigenpairs, who asks (e.g.
/// "zoomout_to (default 150)") and the option that changes it (None for a size no option sets).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Demand {
    /// Eigenpairs per shape.
    pub size: usize,
    /// Who asks, spelled.
    pub who: String,
    /// The key of the option that changes it.
    pub key: Option<&'static str>,
}

/// The eigenpairs per shape a run computes ([`MatchSettings::basis_demand`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BasisDemand {
    /// Eigenpairs per shape.
    pub size: usize,
    /// The option that asks for them, spelled (e.g. "kprime (default 200)").
    pub who: String,
    /// Its key.
    pub key: &'static str,
}

impl MatchSettings {
    /// The options for data with many functions (`rich`, [`crate::descriptors::spec::PairDataSpec::is_rich`])
    /// or few, with errors naming options by their keys ([`MatchSettings::resolve_as`]).
    pub fn resolve(&self, rich: bool) -> Result<MatchOptions> {
        self.resolve_as(rich, &Keywords)
    }

    /// The library options of these settings: [`MatchOptions::for_method`] for the method and
    /// data, the completion method's defaults for its form and scaling
    /// ([`completion_defaults`]), then every option given. `k` sets the baselines' size, the
    /// completion rank and, without `candidates`, the axiomatic method's one candidate size.
    /// Checked by [`MatchOptions::validate_as`]; errors name the option as `sp` spells it.
    pub fn resolve_as(&self, rich: bool, sp: &dyn Spelling) -> Result<MatchOptions> {
        let d = MatchOptions::default();
        let method = self.method.unwrap_or(Method::Axiomatic);
        if self.k == Some(0) {
            return Err(Error::invalid(sp.name("k"), "the functional map's size must be at least 1"));
        }
        let base = MatchOptions::for_method(method, rich);
        let mut completion =
            completion_defaults(rich, self.scaling.unwrap_or(Scaling::Unit), self.form.unwrap_or(Form::Subspace));
        if let Some(k) = self.k {
            completion.k = k;
        }
        if let Some(kp) = self.kprime {
            completion.k_prime = kp;
        }
        if method == Method::Completion && !(1..=completion.k_prime).contains(&completion.k) {
            let (k, kp) = (completion.k, completion.k_prime);
            return Err(Error::invalid(
                sp.name(if self.k.is_some() { "k" } else { "kprime" }),
                format!(
                    "the completion rank {} must be between 1 and the subspace size {}",
                    named(sp, self.k.is_some(), "k", k),
                    named(sp, self.kprime.is_some(), "kprime", kp)
                ),
            ));
        }
        completion.init = self.init.unwrap_or(Init::Pad);
        completion.optimizer = self.optimizer;
        let w = &mut completion.params;
        for (slot, v) in [
            (&mut w.mu1, self.mu1),
            (&mut w.mu2, self.mu2),
            (&mut w.mu3, self.mu3),
            (&mut w.mu4, self.mu4),
            (&mut w.xi, self.xi),
        ] {
            if let Some(v) = v {
                *slot = v;
            }
        }
        if completion.optimizer == Some(Optimizer::Rcg) || completion.form == Form::FixedRank {
            if self.mu4.is_some_and(|m| m != 0.0) {
                return Err(Error::invalid(sp.name("mu4"), "the fixed-rank forms have no low-norm term"));
            }
            w.mu4 = 0.0;
        }
        w.mu_comm = self.completion_commutativity.unwrap_or(DEFAULT_COMPLETION_COMMUTATIVITY);
        w.k_comm = self.completion_commutativity_k.unwrap_or(DEFAULT_COMPLETION_COMMUTATIVITY_K);
        w.mu_prior = self.completion_prior.unwrap_or(0.0);
        completion.optimize = OptimizeOptions {
            max_iterations: self.max_iterations.unwrap_or(d.completion.optimize.max_iterations),
            rel_tol: self.rel_tol.unwrap_or(d.completion.optimize.rel_tol),
            ..OptimizeOptions::default()
        };
        if let Some(samples) = self.l1_samples {
            completion.l1_sampling = L1Sampling::farthest(samples);
        }
        let l1_f32 = self.l1_f32 == Some(true);
        if l1_f32 && self.l1_precision.is_some() {
            return Err(Error::invalid(
                sp.name("l1_f32"),
                format!("give either {} or {}, not both", sp.name("l1_precision"), sp.name("l1_f32")),
            ));
        }
        completion.params.l1_precision = match (self.l1_precision, l1_f32) {
            (Some(p), _) => p,
            (None, true) => Precision::F32,
            (None, false) => completion.params.l1_precision,
        };
        completion.precondition = self.precondition.unwrap_or(Precondition::Off);
        completion.xi_stages = self.xi_stages.unwrap_or(0);
        if let Some(stages) = self.multiscale {
            completion.multiscale = stages;
        }
        // The map that matters is the one the refinement starts from: that of the leading
        // refine_k block of C (the factors' own map without a refinement).
        let refine_k = self.refine_k.unwrap_or(d.refine_k);
        let refined = self.refine.unwrap_or(base.refine) != Refine::None;
        completion.settled = settled_map(
            self.map_check_every.unwrap_or(d.completion.settled.map_or(0, |s| s.every)),
            self.map_tolerance.unwrap_or(d.completion.settled.map_or(0.005, |s| s.tolerance)),
            if refined { refine_k } else { 0 },
            sp,
        )?;
        let commutativity = self.commutativity.unwrap_or(base.commutativity);
        let mut a = base.axiomatic.clone();
        let dw = d.axiomatic.fit.weights;
        a.fit.weights = EnergyWeights {
            descriptors: self.w_descriptors.unwrap_or(dw.descriptors),
            laplacian: self.w_laplacian.unwrap_or(dw.laplacian),
            commutativity: self.w_commutativity.unwrap_or(dw.commutativity),
            orientation: self.w_orientation.unwrap_or(dw.orientation),
        };
        a.fit.mask = self.mask.unwrap_or(Mask::Resolvent { gamma: 0.5 });
        a.fit.orientation = self.orientation.unwrap_or(Orientation::Preserve);
        a.signed = self.signed.unwrap_or(d.axiomatic.signed);
        if let Some(c) = &self.candidates {
            a.candidates = c.clone();
        } else if let Some(k) = self.k {
            a.candidates = vec![k];
        }
        match self.refine {
            Some(Refine::None) => a.refine.k_final = 0,
            Some(Refine::Icp) if method == Method::Axiomatic => {
                return Err(Error::invalid(
                    sp.name("refine"),
                    "the axiomatic method refines with ZoomOut (or none); ICP is for the other methods",
                ))
            }
            _ => {}
        }
        if let Some(k) = self.zoomout_to {
            if self.refine != Some(Refine::None) {
                a.refine.k_final = k;
            }
        }
        if let Some(s) = self.zoomout_step {
            a.refine.step = s;
        }
        a.refine.samples = self.zoomout_samples.unwrap_or(d.axiomatic.refine.samples);
        a.polish = self.polish.unwrap_or(d.axiomatic.polish);
        a.near = NearSearch {
            above_pairs: self.near_above.unwrap_or(d.axiomatic.near.above_pairs),
            cells: self.near_cells.unwrap_or(d.axiomatic.near.cells),
            inverse_above_pairs: self.near_inverse_above.unwrap_or(d.axiomatic.near.inverse_above_pairs),
            certified_up_to: self.near_certified_up_to.unwrap_or(d.axiomatic.near.certified_up_to),
            inverse_certified_up_to: self
                .near_inverse_certified_up_to
                .unwrap_or(d.axiomatic.near.inverse_certified_up_to),
        };
        let opts = MatchOptions {
            method,
            k: self.k.unwrap_or(base.k),
            commutativity,
            completion,
            init_k: self.init_k.unwrap_or(d.init_k),
            extraction: self.extract.unwrap_or(Extraction::Nn),
            refine: self.refine.unwrap_or(base.refine),
            refine_k,
            icp: IcpOptions { max_iterations: self.icp_iterations.unwrap_or(d.icp.max_iterations) },
            zoomout_to: self.zoomout_to.unwrap_or(base.zoomout_to),
            zoomout_step: self.zoomout_step.unwrap_or(base.zoomout_step),
            axiomatic: a,
            partial: PartialOptions {
                mode: match (self.partial, self.partial_ratio) {
                    (Some(true), _) | (None, Some(_)) => PartialMode::Always,
                    (Some(false), _) => PartialMode::Never,
                    (None, None) => base.partial.mode,
                },
                ratio: self.partial_ratio.or(base.partial.ratio),
                ..base.partial
            },
            ..base
        };
        opts.validate_as(sp)?;
        Ok(opts)
    }

    /// Every demand of the options `opts` (resolved from these settings) on the basis size.
    pub fn demands(&self, opts: &MatchOptions, sp: &dyn Spelling) -> Vec<Demand> {
        let mut parts = Vec::new();
        match opts.method {
            Method::Completion => {
                let kp = opts.completion.k_prime;
                parts.push(Demand {
                    size: kp,
                    who: named(sp, self.kprime.is_some(), "kprime", kp),
                    key: Some("kprime"),
                });
            }
            Method::Axiomatic => {
                let a = &opts.axiomatic;
                let kmax = a.candidates.iter().copied().max().unwrap_or(0);
                let list = a.candidates.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(",");
                let (who, key) = match (&self.candidates, self.k) {
                    (Some(_), _) => (sp.given("candidates", &list), "candidates"),
                    (None, Some(k)) => (sp.given("k", &k), "k"),
                    (None, None) => (format!("{} (default {list})", sp.name("candidates")), "candidates"),
                };
                parts.push(Demand { size: kmax, who, key: Some(key) });
                let z = a.refine.k_final;
                parts.push(Demand {
                    size: z,
                    who: named(sp, self.zoomout_to.is_some(), "zoomout_to", z),
                    key: Some("zoomout_to"),
                });
                let probe = a.probe.k_final;
                parts.push(Demand { size: probe, who: format!("the size selection (ZoomOut to {probe})"), key: None });
            }
            _ => parts.push(Demand { size: opts.k, who: named(sp, self.k.is_some(), "k", opts.k), key: Some("k") }),
        }
        if opts.method != Method::Axiomatic && opts.refine == Refine::Zoomout {
            let z = opts.zoomout_to;
            parts.push(Demand {
                size: z,
                who: named(sp, self.zoomout_to.is_some(), "zoomout_to", z),
                key: Some("zoomout_to"),
            });
        }
        parts
    }

    /// The eigenpairs per shape that a run of `opts` (resolved from these settings) computes:
    /// what the method and its refinement need, and for the methods other than completion at
    /// least `kprime` (default [`DEFAULT_BASIS_SIZE`]); with the option that asks for the most
    /// of them, so that a shape with too few vertices gets an error naming what to change
    /// ([`MatchSettings::too_small`]). Errors when `kprime` is given but smaller than what the
    /// other options need (the basis would silently be larger than asked).
    pub fn basis_demand(&self, opts: &MatchOptions, sp: &dyn Spelling) -> Result<BasisDemand> {
        let parts = self.demands(opts, sp);
        let (need, who, key) = parts
            .iter()
            .max_by_key(|d| d.size)
            .map(|d| (d.size, d.who.clone(), d.key.unwrap_or("kprime")))
            .unwrap_or((0, sp.name("k"), "k"));
        if opts.method == Method::Completion {
            return Ok(BasisDemand { size: need.max(opts.basis_size()), who, key });
        }
        match self.kprime {
            Some(kp) if kp < need => Err(Error::invalid(
                sp.name("kprime"),
                format!(
                    "{kp} eigenpairs per shape are fewer than the {need} that {who} needs; raise {} or lower {who}",
                    sp.name("kprime")
                ),
            )),
            Some(kp) => Ok(BasisDemand { size: kp, who: sp.given("kprime", &kp), key: "kprime" }),
            None if need >= DEFAULT_BASIS_SIZE => Ok(BasisDemand { size: need, who, key }),
            None => Ok(BasisDemand {
                size: DEFAULT_BASIS_SIZE,
                who: format!("{} (default {DEFAULT_BASIS_SIZE})", sp.name("kprime")),
                key: "kprime",
            }),
        }
    }

    /// [`MatchSettings::basis_demand`] for a known pair and data: where the axiomatic method's
    /// run reads no eigenpair beyond [`AXIOMATIC_BASIS_SIZE`] (`lean`: X cannot be a part,
    /// [`super::partial::may_be_partial`] false, and the data are the default WKS recipe or
    /// given as arrays — not descriptors of the whole basis such as `wks:N` or `hks`) and
    /// `kprime` is not given, the basis holds what its sizes need, at least
    /// [`AXIOMATIC_BASIS_SIZE`] eigenpairs, instead of [`DEFAULT_BASIS_SIZE`]: the maps are those
    /// of the larger basis. The partial path's heat-kernel scale and rectangular maps read every
    /// eigenpair. Otherwise the same as [`MatchSettings::basis_demand`].
    pub fn basis_demand_for(&self, opts: &MatchOptions, sp: &dyn Spelling, lean: bool) -> Result<BasisDemand> {
        let demand = self.basis_demand(opts, sp)?;
        if opts.method != Method::Axiomatic || !lean || self.kprime.is_some() || demand.key != "kprime" {
            return Ok(demand);
        }
        let parts = self.demands(opts, sp);
        match parts.iter().max_by_key(|d| d.size) {
            Some(d) if d.size > AXIOMATIC_BASIS_SIZE => {
                Ok(BasisDemand { size: d.size, who: d.who.clone(), key: d.key.unwrap_or("kprime") })
            }
            _ => Ok(BasisDemand {
                size: AXIOMATIC_BASIS_SIZE,
                who: format!("{} (default {AXIOMATIC_BASIS_SIZE} for a whole X)", sp.name("kprime")),
                key: "kprime",
            }),
        }
    }

    /// The eigenpairs per shape of a pair whose Laplacians are built:
    /// [`MatchSettings::basis_demand_for`], lean (fewer) where X cannot be a part of Y
    /// ([`super::partial::may_be_partial`] of the shapes as loaded, `x` and `y`, with their
    /// areas Σ A) and the data are the default WKS recipe or given (`default_data`), since the
    /// partial path and descriptors such as `wks:N` read every eigenpair. Each side whose basis is
    /// still to be computed carries its name as the front end shows it (a side prepared already,
    /// with its own basis, carries None and is not checked). What `funcorr match` and
    /// `funcorr.match` decide between the Laplacians and the bases. Errors: as
    /// [`MatchSettings::basis_demand_for`], and [`MatchSettings::too_small`] for a named side
    /// with no more vertices than that.
    pub fn pair_basis_demand(
        &self,
        opts: &MatchOptions,
        sp: &dyn Spelling,
        x: (&crate::shape::Shape, f64, Option<&str>),
        y: (&crate::shape::Shape, f64, Option<&str>),
        default_data: bool,
    ) -> Result<BasisDemand> {
        let lean = default_data && !super::partial::may_be_partial(x.0, x.1, y.0, y.1, &opts.partial);
        let demand = self.basis_demand_for(opts, sp, lean)?;
        for (shape, _, name) in [x, y] {
            if let Some(name) = name.filter(|_| demand.size >= shape.n_vertices()) {
                return Err(self.too_small(name, shape.n_vertices(), opts, &demand, sp));
            }
        }
        Ok(demand)
    }

    /// The error for the shape `shape` (its name as the front end shows it) of `n` vertices,
    /// too small for the `demand.size` eigenpairs per shape that the options ask for
    /// (`demand.size ≥ n`): it names every option that asks for n or more and the values that
    /// fit, or, when a size no option sets is too large (the axiomatic method's size
    /// selection), another method that fits.
    pub fn too_small(
        &self,
        shape: &str,
        n: usize,
        opts: &MatchOptions,
        demand: &BasisDemand,
        sp: &dyn Spelling,
    ) -> Error {
        let most = n.saturating_sub(1);
        let mut over: Vec<Demand> = self.demands(opts, sp).into_iter().filter(|d| d.size >= n).collect();
        if demand.size >= n && opts.method != Method::Completion && !over.iter().any(|d| d.who == demand.who) {
            over.insert(0, Demand { size: demand.size, who: demand.who.clone(), key: Some("kprime") });
        }
        over.sort_by_key(|d| std::cmp::Reverse(d.size));
        let names: Vec<&str> = over.iter().map(|d| d.who.as_str()).collect();
        let head = format!(
            "{shape} has only n = {n} vertices, so at most {most} eigenpairs per shape, but {} ask{} for more",
            names.join(", "),
            if names.len() == 1 { "s" } else { "" }
        );
        if let Some(fixed) = over.iter().find(|d| d.key.is_none()) {
            let kp = most.min(DEFAULT_BASIS_SIZE);
            let k = (kp / 2).clamp(1, 20);
            return Error::invalid(
                sp.name("method"),
                format!(
                    "{head}; {} is not an option, so the axiomatic method needs shapes of more than {} vertices: \
                     match this pair with another method, e.g. {} {} {} {}",
                    fixed.who,
                    fixed.size,
                    sp.given("method", &"fmap"),
                    sp.given("k", &k),
                    sp.given("kprime", &kp),
                    sp.given("zoomout_to", &kp)
                ),
            );
        }
        let mut keys: Vec<&str> = over.iter().filter_map(|d| d.key).collect();
        keys.dedup();
        let fix: Vec<String> = keys.iter().map(|key| sp.given(key, &most)).collect();
        let them = if fix.len() == 1 { "it" } else { "them" };
        Error::invalid(
            sp.name(keys.first().copied().unwrap_or("k")),
            format!("{head}; lower {them} below {n}, e.g. {}", fix.join(" ")),
        )
    }
}

/// `key` as given (`--kprime 60`) or with its default (`--kprime (default 50)`).
fn named(sp: &dyn Spelling, given: bool, key: &str, v: usize) -> String {
    if given {
        sp.given(key, &v)
    } else {
        format!("{} (default {v})", sp.name(key))
    }
}

impl MatchOptions {
    /// Checks the options, naming the option at fault by its key ([`MatchOptions::validate_as`]).
    pub fn validate(&self) -> Result<()> {
        self.validate_as(&Keywords)
    }

    /// Checks the options: sizes ≥ 1, the completion rank k within the subspace size k', no
    /// low-norm term in the fixed-rank forms, the point-map tolerance in [0, 1], weights finite
    /// and ≥ 0, at least one candidate size; errors name the option as `sp` spells it.
    pub fn validate_as(&self, sp: &dyn Spelling) -> Result<()> {
        if self.k == 0 {
            return Err(Error::invalid(sp.name("k"), "the functional map's size must be at least 1"));
        }
        let c = &self.completion;
        if self.method == Method::Completion && !(1..=c.k_prime).contains(&c.k) {
            return Err(Error::invalid(
                sp.name("k"),
                format!(
                    "the completion rank {} must be between 1 and the subspace size {}",
                    sp.given("k", &c.k),
                    sp.given("kprime", &c.k_prime)
                ),
            ));
        }
        if (c.optimizer == Some(Optimizer::Rcg) || c.form == Form::FixedRank) && c.params.mu4 != 0.0 {
            return Err(Error::invalid(sp.name("mu4"), "the fixed-rank forms have no low-norm term"));
        }
        if let Some(s) = c.settled {
            settled_map(s.every, s.tolerance, s.k, sp)?;
        }
        if !(self.commutativity.is_finite() && self.commutativity >= 0.0) {
            return Err(Error::invalid(sp.name("commutativity"), "must be finite and ≥ 0"));
        }
        if self.partial.mode == PartialMode::Always && self.method != Method::Axiomatic {
            return Err(Error::invalid(
                sp.name("partial"),
                "partial matching is a path of the axiomatic method (the default); other methods match whole shapes",
            ));
        }
        if let Some(r) = self.partial.ratio {
            let most = self.partial.max_area_ratio;
            if !(r.is_finite() && r > 0.0 && r <= most) {
                return Err(Error::invalid(
                    sp.name("partial_ratio"),
                    format!("the share of Y's area a part covers must be in (0, {most}], got {r}"),
                ));
            }
            if self.partial.mode == PartialMode::Never {
                return Err(Error::invalid(
                    sp.name("partial_ratio"),
                    format!("says X is a part of Y, but {} says it is whole", sp.given("partial", &false)),
                ));
            }
        }
        let a = &self.axiomatic;
        if a.near.cells == 0 {
            return Err(Error::invalid(sp.name("near_cells"), "must be at least 1"));
        }
        let w = &a.fit.weights;
        for (key, v) in [
            ("w_descriptors", w.descriptors),
            ("w_laplacian", w.laplacian),
            ("w_commutativity", w.commutativity),
            ("w_orientation", w.orientation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(sp.name(key), format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if a.candidates.is_empty() || a.candidates.contains(&0) {
            return Err(Error::invalid(sp.name("candidates"), "need one or more sizes ≥ 1"));
        }
        if a.refine.step == 0 {
            return Err(Error::invalid(sp.name("zoomout_step"), "must be at least 1"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn json<T: Serialize>(t: &T) -> serde_json::Value {
        serde_json::to_value(t).unwrap()
    }

    /// A value of the option's kind unlike its default.
    fn example(kind: Kind) -> Value {
        match kind {
            Kind::Size => Value::Size(7),
            Kind::Number => Value::Number(0.25),
            Kind::Flag => Value::Flag(true),
            Kind::Sizes => Value::Sizes(vec![7, 9]),
            Kind::Choice(names) => Value::Choice(names[names.len() - 1].to_string()),
        }
    }

    /// The table, the fields of `MatchSettings` and `set` agree: every key of the table sets
    /// the field of its name and no other, every field has its row.
    #[test]
    fn every_option_of_the_table_sets_the_field_of_its_name() {
        // Every field by its Debug name: `Some(` once per field given.
        let fields = format!("{:?}", MatchSettings::default()).matches(": None").count();
        assert_eq!(fields, MATCH_OPTIONS.len());
        for spec in MATCH_OPTIONS {
            let mut s = MatchSettings::default();
            s.set(spec.key, example(spec.kind)).unwrap();
            let debug = format!("{s:?}");
            assert_eq!(debug.matches(": None").count(), fields - 1, "{}", spec.key);
            assert!(debug.contains(&format!(" {}: Some(", spec.key)), "{}: {debug}", spec.key);
            // Given by name, read back by name: the JSON form has this one key.
            let j = json(&s);
            assert_eq!(j.as_object().unwrap().keys().collect::<Vec<_>>(), [spec.key], "{}", spec.key);
            let back: MatchSettings = serde_json::from_value(j).unwrap();
            assert_eq!(back, s, "{}", spec.key);
        }
        let mut s = MatchSettings::default();
        assert!(s.set("zoomout-to", Value::Size(3)).unwrap_err().to_string().contains("zoomout-to"));
        let e = s.set("form", Value::Choice("low_norm".into())).and(s.set("form", Value::Choice("dense".into())));
        assert_eq!(s.form, Some(Form::LowNorm));
        assert!(e.unwrap_err().to_string().contains("expected one of subspace, fixed-rank, low-rank, low-norm"));
        assert!(s.set("k", Value::Number(2.5)).is_err());
    }

    /// A settings file: every option given round-trips, errors name the option.
    #[test]
    fn settings_round_trip_through_json_by_name() {
        let mut s = MatchSettings::default();
        for spec in MATCH_OPTIONS {
            s.set(spec.key, example(spec.kind)).unwrap();
        }
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains(r#""form":"low-norm""#) && text.contains(r#""candidates":[7,9]"#), "{text}");
        assert_eq!(serde_json::from_str::<MatchSettings>(&text).unwrap(), s);
        let j: MatchSettings = serde_json::from_str(r#"{"method": "fmap", "k": 30, "mask": null}"#).unwrap();
        assert_eq!((j.method, j.k, j.mask), (Some(Method::Fmap), Some(30), None));
        let err = |t: &str| serde_json::from_str::<MatchSettings>(t).unwrap_err().to_string();
        assert!(err(r#"{"zoomout-to": 3}"#).contains("zoomout-to: not an option"));
        assert!(err(r#"{"k": -3}"#).contains("invalid k: expected a non-negative integer, got -3"));
        assert!(err(r#"{"form": "dense"}"#).contains("expected one of subspace"));
        assert!(err(r#"{"refine": true}"#).contains("refine: expected a name"));
        assert!(err("[1, 2]").contains("expected a map"));
        // A value no name gives is an error, not a wrong file.
        let odd = MatchSettings { mask: Some(Mask::Resolvent { gamma: 0.25 }), ..Default::default() };
        assert!(serde_json::to_string(&odd).unwrap_err().to_string().contains("mask"));
    }

    /// Nothing given is the library's defaults, method by method and data by data.
    #[test]
    fn no_option_given_is_the_defaults_of_the_method() {
        assert_eq!(json(&MatchSettings::default().resolve(true).unwrap()), json(&MatchOptions::default()));
        for method in [Method::Axiomatic, Method::Fmap, Method::Pokrass, Method::Coupled, Method::Completion] {
            for rich in [true, false] {
                let s = MatchSettings { method: Some(method), ..MatchSettings::default() };
                assert_eq!(json(&s.resolve(rich).unwrap()), json(&MatchOptions::for_method(method, rich)));
            }
        }
    }

    #[test]
    fn checks_name_the_option() {
        let err = |s: MatchSettings| s.resolve(true).unwrap_err().to_string();
        let e = err(MatchSettings { method: Some(Method::Completion), k: Some(60), ..Default::default() });
        assert!(
            e.contains(
                "invalid k: the completion rank k=60 must be between 1 and the subspace size kprime (default 50)"
            ),
            "{e}"
        );
        let e = err(MatchSettings { w_orientation: Some(-1.0), ..Default::default() });
        assert!(e.contains("w_orientation: must be finite and ≥ 0"), "{e}");
        let e = err(MatchSettings { refine: Some(Refine::Icp), ..Default::default() });
        assert!(e.contains("refine: the axiomatic method refines with ZoomOut"), "{e}");
        assert!(err(MatchSettings { zoomout_step: Some(0), ..Default::default() }).contains("zoomout_step"));
        assert!(err(MatchSettings { candidates: Some(vec![]), ..Default::default() }).contains("candidates"));
        let mut o = MatchOptions::default();
        o.axiomatic.near.cells = 0;
        assert!(o.validate().unwrap_err().to_string().contains("near_cells"));
        // The basis: at least 200 eigenpairs unless kprime says otherwise, which must cover the rest.
        let s = MatchSettings::default();
        let d = s.basis_demand(&s.resolve(true).unwrap(), &Keywords).unwrap();
        assert_eq!((d.size, d.who.as_str(), d.key), (200, "kprime (default 200)", "kprime"));
        // For a pair whose X cannot be a part, with the default data: 128 (the default WKS's
        // eigenpairs), unless the sizes ask for more or kprime is given; the baselines keep 200.
        let o = s.resolve(true).unwrap();
        assert_eq!(s.basis_demand_for(&o, &Keywords, false).unwrap(), d);
        let whole = s.basis_demand_for(&o, &Keywords, true).unwrap();
        assert_eq!((whole.size, whole.who.as_str()), (128, "kprime (default 128 for a whole X)"));
        let s = MatchSettings { zoomout_to: Some(150), ..Default::default() };
        let d = s.basis_demand_for(&s.resolve(true).unwrap(), &Keywords, true).unwrap();
        assert_eq!((d.size, d.who.as_str(), d.key), (150, "zoomout_to=150", "zoomout_to"));
        for s in [
            MatchSettings { kprime: Some(150), ..Default::default() },
            MatchSettings { method: Some(Method::Fmap), ..Default::default() },
        ] {
            let o = s.resolve(true).unwrap();
            assert_eq!(s.basis_demand_for(&o, &Keywords, true).unwrap(), s.basis_demand(&o, &Keywords).unwrap());
        }
        let s = MatchSettings { kprime: Some(20), ..Default::default() };
        let e = s.basis_demand(&s.resolve(true).unwrap(), &Keywords).unwrap_err().to_string();
        assert!(
            e.contains("20 eigenpairs per shape are fewer than the 128 that zoomout_to (default 128) needs"),
            "{e}"
        );
        let s = MatchSettings { method: Some(Method::Fmap), zoomout_to: Some(300), ..Default::default() };
        let o = s.resolve(true).unwrap();
        let d = s.basis_demand(&o, &Keywords).unwrap();
        assert_eq!((d.size, d.key), (300, "zoomout_to"));
        let e = s.too_small("X", 250, &o, &d, &Keywords).to_string();
        assert!(e.contains("X has only n = 250 vertices") && e.contains("e.g. zoomout_to=249"), "{e}");
    }

    /// The eigenpairs of a pair ([`MatchSettings::pair_basis_demand`]): 128 for two whole
    /// shapes with the default data, 200 where X may be a part or the data are not the default,
    /// and the size error for a side still to be computed, not for a prepared one.
    #[test]
    fn a_pair_gets_the_eigenpairs_its_path_reads() {
        let (big, small) = (crate::primitives::icosphere(3), crate::primitives::icosphere(2));
        let (big, small) = (crate::shape::Shape::Mesh(big), crate::shape::Shape::Mesh(small));
        assert!(big.n_vertices() > 200 && small.n_vertices() < 200, "{} {}", big.n_vertices(), small.n_vertices());
        let s = MatchSettings::default();
        let o = s.resolve(true).unwrap();
        let size = |o: &MatchOptions, default_data: bool| {
            s.pair_basis_demand(o, &Keywords, (&big, 1.0, Some("X")), (&big, 1.0, Some("Y")), default_data)
                .unwrap()
                .size
        };
        assert_eq!(size(&o, true), AXIOMATIC_BASIS_SIZE);
        assert_eq!(size(&o, false), DEFAULT_BASIS_SIZE);
        let mut always = o.clone();
        always.partial.mode = PartialMode::Always;
        assert_eq!(size(&always, true), DEFAULT_BASIS_SIZE);
        // A side with fewer vertices than that: an error naming it, unless it is prepared already.
        let e = s.pair_basis_demand(&o, &Keywords, (&big, 1.0, Some("X")), (&small, 1.0, Some("Y")), false);
        assert!(e.unwrap_err().to_string().contains(&format!("Y has only n = {} vertices", small.n_vertices())));
        let d = s.pair_basis_demand(&o, &Keywords, (&big, 1.0, Some("X")), (&small, 1.0, None), false).unwrap();
        assert_eq!(d.size, DEFAULT_BASIS_SIZE);
    }
}
