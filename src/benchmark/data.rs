//! What a benchmark pair is matched with: the data specification (one per run), the shapes
//! prepared once per data set, and the data functions F, G of a pair.

#[allow(unused_imports)]
use super::*;
use crate::spatial::farthest_points;

/// The data functions of a benchmark run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DataSpec {
    /// The data set's segmentation of each pair: one indicator per segment (the paper's scarce
    /// data); `symmetric` selects the `.seg.sym` labels, else `.seg.nonsym`.
    Segments {
        /// Use the `.sym` label files.
        symmetric: bool,
    },
    /// WKS descriptors (count energies from the whole basis, normalized) on each shape.
    Wks(usize),
    /// The default WKS recipe ([`sig::WksRecipe`]: 100 energies from the first 128 eigenpairs,
    /// every 2nd kept).
    WksDefault,
    /// The paper's rich data: 100 WKS + 100 heat kernel maps localized on the segments.
    Rich,
    /// Delta functions at `N` ground-truth landmarks (farthest-point samples of X's template
    /// points and their counterparts on Y).
    Landmarks(usize),
}

impl DataSpec {
    /// Whether this is the paper's rich setting (many functions) rather than scarce data.
    pub fn is_rich(self) -> bool {
        matches!(self, DataSpec::Wks(_) | DataSpec::WksDefault | DataSpec::Rich)
    }
}

impl std::fmt::Display for DataSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DataSpec::Segments { symmetric: true } => write!(f, "segments"),
            DataSpec::Segments { symmetric: false } => write!(f, "segments:nonsym"),
            DataSpec::Wks(n) => write!(f, "wks:{n}"),
            DataSpec::WksDefault => write!(f, "wks"),
            DataSpec::Rich => write!(f, "rich"),
            DataSpec::Landmarks(n) => write!(f, "landmarks:{n}"),
        }
    }
}

impl FromStr for DataSpec {
    type Err = Error;
    /// `segments`, `segments:nonsym`, `wks` (the default recipe, [`sig::WksRecipe`]), `wks:N`,
    /// `rich` or `landmarks:N` (N ≥ 1).
    fn from_str(s: &str) -> Result<Self> {
        let bad = |m: &str| Error::invalid("--data", format!("{s:?}: {m}"));
        let (kind, arg) = s.split_once(':').unwrap_or((s, ""));
        let count = || -> Result<usize> {
            arg.parse::<usize>()
                .ok()
                .filter(|&n| (1..=100_000).contains(&n))
                .ok_or_else(|| bad("expected a count in 1..=100000 after the colon, e.g. wks:100"))
        };
        match (kind, arg) {
            ("segments", "" | "sym") => Ok(DataSpec::Segments { symmetric: true }),
            ("segments", "nonsym") => Ok(DataSpec::Segments { symmetric: false }),
            ("wks", "") if !s.contains(':') => Ok(DataSpec::WksDefault),
            ("wks", _) => Ok(DataSpec::Wks(count()?)),
            ("rich", "") => Ok(DataSpec::Rich),
            ("landmarks", _) => Ok(DataSpec::Landmarks(count()?)),
            _ => Err(bad("expected segments, segments:nonsym, wks, wks:N, rich or landmarks:N")),
        }
    }
}

/// A shape of the data set ready for matching: its name, mesh, Laplacian, eigenbasis and surface
/// geometry ([`crate::prepared::PreparedShape`]).
#[derive(Debug)]
pub struct PreparedShape {
    /// Name in the data set.
    pub name: String,
    /// The mesh, its Laplacian, basis and geometry.
    pub prepared: crate::prepared::PreparedShape,
    /// Seconds to read, assemble and solve (or load from the cache).
    pub seconds: f64,
}

impl PreparedShape {
    /// The mesh.
    pub fn mesh(&self) -> &TriMesh {
        match &self.prepared.shape {
            Shape::Mesh(m) => m,
            Shape::Points(_) => unreachable!("data set shapes are meshes (checked by prepare_shape)"),
        }
    }
    /// The eigenbasis.
    pub fn basis(&self) -> &Basis {
        &self.prepared.basis
    }
}

/// Loads shape `name`, its cotangent Laplacian and `k` eigenpairs (through `cache` when given).
pub fn prepare_shape(ds: &Dataset, name: &str, k: usize, cache: Option<&BasisCache>) -> Result<PreparedShape> {
    let t = Instant::now();
    let path = ds.shape_path(name)?;
    let shape = Shape::load(path)?;
    if !matches!(shape, Shape::Mesh(_)) {
        return Err(Error::invalid("dataset", format!("{} is not a triangle mesh", path.display())));
    }
    let prepared = crate::prepared::PreparedShape::new(shape, crate::prepared::LaplacianChoice::Cotangent, k, cache)?;
    Ok(PreparedShape { name: name.to_string(), prepared, seconds: t.elapsed().as_secs_f64() })
}

/// The data F (n × q) on X and G (m × q) on Y of the pair (x, y) for `spec`.
pub fn pair_data(
    ds: &Dataset,
    x: &PreparedShape,
    y: &PreparedShape,
    gt: &GroundTruth,
    spec: DataSpec,
) -> Result<(Descriptors, Descriptors)> {
    let segments = |symmetric: bool| -> Result<(Descriptors, Descriptors)> {
        let suffix = if symmetric { "sym" } else { "nonsym" };
        let la = ds.segmentation(&x.name, &y.name, &x.name, x.mesh().n_vertices(), suffix)?;
        let lb = ds.segmentation(&x.name, &y.name, &y.name, y.mesh().n_vertices(), suffix)?;
        desc::matched_segments(&la, &lb)
    };
    match spec {
        DataSpec::Segments { symmetric } => segments(symmetric),
        DataSpec::Wks(count) => Ok((sig::wks(x.basis(), count, true)?, sig::wks(y.basis(), count, true)?)),
        DataSpec::WksDefault => {
            let r = sig::WksRecipe::default();
            Ok((sig::wks_recipe(x.basis(), &r)?, sig::wks_recipe(y.basis(), &r)?))
        }
        DataSpec::Rich => {
            let (fs, gs) = segments(true)?;
            desc::rich(x.basis(), y.basis(), &fs, &gs, 100, 100)
        }
        DataSpec::Landmarks(count) => {
            let picks = farthest_points(x.mesh(), &gt.x, count);
            let xs: Vec<usize> = picks.iter().map(|&i| gt.x[i]).collect();
            let ys: Vec<usize> = picks.iter().map(|&i| gt.y[i]).collect();
            Ok((desc::landmarks(x.mesh().n_vertices(), &xs)?, desc::landmarks(y.mesh().n_vertices(), &ys)?))
        }
    }
}
