//! Keyword options → the library's options by name: the keywords of `funcorr.match` are the keys
//! of the library's table (`funcorr::matching::MATCH_OPTIONS`, the flags of `funcorr match` with
//! `_` for `-`), taken here as Python values of the table's kinds and handed to the library,
//! which owns their defaults and checks (`MatchSettings::resolve`); errors name the keyword. An
//! unknown keyword is an error, not ignored.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use funcorr::matching::options::Kind;
use funcorr::matching::{MatchSettings, Value, MATCH_OPTIONS};

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
        self.take(key).map(|v| size_of(key, &v)).transpose()
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

    pub(crate) fn string(&mut self, key: &str) -> PyResult<Option<String>> {
        self.take(key).map(|v| string_of(key, &v)).transpose()
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

/// The keywords of `funcorr.match` that are options of the pipeline (every key of the
/// library's table that is given), as the library's values.
pub(crate) fn match_settings(o: &mut Opts) -> PyResult<MatchSettings> {
    let mut s = MatchSettings::default();
    for spec in MATCH_OPTIONS {
        let key = spec.key;
        let Some(v) = o.take(key) else { continue };
        let value = match spec.kind {
            Kind::Size => Value::Size(size_of(key, &v)?),
            Kind::Number => {
                Value::Number(v.extract::<f64>().map_err(|_| value_error(key, format!("expected a number, got {v}")))?)
            }
            Kind::Flag => {
                Value::Flag(v.extract::<bool>().map_err(|_| value_error(key, format!("expected a bool, got {v}")))?)
            }
            Kind::Sizes => match v.extract::<usize>() {
                Ok(k) => Value::Size(k),
                Err(_) => Value::Sizes(
                    v.extract::<Vec<usize>>()
                        .map_err(|_| value_error(key, format!("expected a list of sizes, got {v}")))?,
                ),
            },
            Kind::Choice(_) => Value::Choice(string_of(key, &v)?),
        };
        s.set(key, value).map_err(library_error)?;
    }
    Ok(s)
}

/// A library error of the options: ValueError "keyword: why" for an invalid option.
pub(crate) fn library_error(e: funcorr::Error) -> PyErr {
    match e {
        funcorr::Error::Invalid { what, msg } => value_error(&what, msg),
        e => crate::to_py(e),
    }
}

/// The keys of the library's table of pipeline options: the keywords of `funcorr.match` beside
/// `data`, `progress`, the Laplacian options, the segmentation options and `cache_dir`.
#[pyfunction]
pub(crate) fn match_option_keys() -> Vec<&'static str> {
    MATCH_OPTIONS.iter().map(|o| o.key).collect()
}

fn size_of(key: &str, v: &Bound<'_, PyAny>) -> PyResult<usize> {
    if v.is_instance_of::<pyo3::types::PyBool>() {
        return Err(value_error(key, "expected a non-negative integer, got a bool"));
    }
    v.extract::<usize>().map_err(|_| value_error(key, format!("expected a non-negative integer, got {v}")))
}

fn string_of(key: &str, v: &Bound<'_, PyAny>) -> PyResult<String> {
    v.extract::<String>().map_err(|_| value_error(key, format!("expected a string, got {v}")))
}
