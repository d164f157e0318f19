//! From command-line arguments to library calls: Laplacians, bases, data, and the match options
//! by name (the library resolves and checks them, `funcorr::matching::options`).

use std::path::Path;

use clap::ValueEnum;

use funcorr::laplacian::{Bandwidth, KnnOptions, Laplacian, VertexWeights};
use funcorr::shape::Shape;
use funcorr::spectral::{Basis, SpectralOptions};
use funcorr::{spectral, Error, Result};

use funcorr::descriptors::spec::PairDataSpec;
use funcorr::matching::options::Kind;
use funcorr::matching::{MatchSettings, Spelling, Value, MATCH_OPTIONS};

use crate::args::{
    CacheArgs, LaplacianArgs, LaplacianChoice, MethodChoice, PipelineArgs, SegmentationArgs, WeightsChoice,
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

/// A shape on its way to matching: its Laplacian and surface (the mesh or the point cloud's
/// triangulation), before its basis ([`ShapeLaplacian::prepared`]).
pub(crate) struct ShapeLaplacian {
    pub(crate) shape: Shape,
    pub(crate) laplacian: Laplacian,
    surface: Option<funcorr::prepared::Surface>,
}

impl ShapeLaplacian {
    /// The Laplacian of `shape` (read from `path`) as the arguments choose it.
    pub(crate) fn new(shape: Shape, path: &Path, lap_args: &LaplacianArgs, st: &mut Stages) -> Result<Self> {
        let choice = laplacian_choice(lap_args, &shape, path)?;
        let (laplacian, surface) =
            st.run("laplacian", || funcorr::prepared::build_laplacian(&shape, choice).map_err(laplacian_error(path)))?;
        Ok(ShapeLaplacian { shape, laplacian, surface })
    }

    /// The shape prepared for matching: its first `k` eigenpairs through the cache.
    pub(crate) fn prepared(self, cache: &CacheArgs, k: usize, st: &mut Stages) -> Result<funcorr::PreparedShape> {
        let c = cache.cache();
        let opts = SpectralOptions::new(k);
        let basis = st.run("eigenbasis", || spectral::eigen_basis_cached(&self.laplacian, &opts, c.as_ref(), None))?.0;
        Ok(funcorr::PreparedShape::from_parts(self.shape, self.laplacian, basis, self.surface))
    }
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

/// Data functions F on X and G on Y from a parsed `--data` spec (see `funcorr match --help`).
pub(crate) fn pair_data(
    spec: &PairDataSpec,
    x: (&Shape, &Laplacian, &Basis),
    y: (&Shape, &Laplacian, &Basis),
    seg: &SegmentationArgs,
) -> Result<(funcorr::descriptors::Descriptors, funcorr::descriptors::Descriptors)> {
    spec.functions(x, y, &seg.options())
}

/// The command line's names of the library's options: `--` and the key with `-` for `_`, `-k`
/// for `k`.
pub(crate) struct Flags;

impl Spelling for Flags {
    fn name(&self, key: &str) -> String {
        match key {
            "k" => "-k".to_string(),
            _ => format!("--{}", key.replace('_', "-")),
        }
    }
    fn given(&self, key: &str, value: &dyn std::fmt::Display) -> String {
        format!("{} {value}", self.name(key))
    }
}

/// The pipeline options of the command line by name (`method` and the flags of
/// [`PipelineArgs`]): each field of `PipelineArgs` is the library's option of its name
/// ([`MATCH_OPTIONS`]), handed over as its value; the library resolves and checks them
/// ([`MatchSettings::resolve_as`]).
pub(crate) fn settings(p: &PipelineArgs, method: MethodChoice) -> Result<MatchSettings> {
    let internal = |msg: String| Error::invalid("command line", msg);
    let fields = match serde_json::to_value(p) {
        Ok(serde_json::Value::Object(fields)) => fields,
        other => return Err(internal(format!("the pipeline flags did not serialize to a map: {other:?}"))),
    };
    let mut s = MatchSettings { method: Some(method.into()), ..MatchSettings::default() };
    for (key, v) in &fields {
        let spec = MATCH_OPTIONS.iter().find(|o| o.key == key).ok_or_else(|| internal(format!("no option {key}")))?;
        let value = match (spec.kind, v) {
            (_, serde_json::Value::Null) | (Kind::Flag, serde_json::Value::Bool(false)) => continue,
            (Kind::Flag, serde_json::Value::Bool(b)) => Value::Flag(*b),
            (Kind::Size, v) => Value::Size(v.as_u64().ok_or_else(|| internal(format!("{key}: {v}")))? as usize),
            (Kind::Number, v) => Value::Number(v.as_f64().ok_or_else(|| internal(format!("{key}: {v}")))?),
            (Kind::Choice(_), serde_json::Value::String(name)) => Value::Choice(name.clone()),
            (Kind::Sizes, serde_json::Value::Array(items)) => Value::Sizes(
                items
                    .iter()
                    .map(|i| i.as_u64().map(|u| u as usize))
                    .collect::<Option<_>>()
                    .ok_or_else(|| internal(format!("{key}: {v}")))?,
            ),
            (_, v) => return Err(internal(format!("{key}: {v}"))),
        };
        s.set(key, value).map_err(|e| match e {
            Error::Invalid { what, msg } => Error::invalid(Flags.name(&what), msg),
            e => e,
        })?;
    }
    // `--no-partial` is the option `partial` set to false (a flag cannot say false by itself).
    if p.no_partial {
        s.partial = Some(false);
    }
    Ok(s)
}
