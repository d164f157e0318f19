//! What a benchmark pair is matched with: the shapes prepared once per data set, and the data
//! functions F, G of a pair from the run's data specification ([`PairDataSpec`], the one
//! `--data` grammar of every command).

#[allow(unused_imports)]
use super::*;
use crate::spatial::farthest_points;

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

/// The data F (n × q) on X and G (m × q) on Y of the pair (x, y) for `spec`. The data-set forms
/// are resolved here: `segments` from the data set's segmentation of the pair, `landmarks:N`
/// from the ground truth `gt`, and `rich` is localized on the data set's (symmetric) segments;
/// every other form is [`PairDataSpec::functions`] of the two shapes (persistence segments with
/// the default [`SegmentationOptions`]).
pub fn pair_data(
    ds: &Dataset,
    x: &PreparedShape,
    y: &PreparedShape,
    gt: &GroundTruth,
    spec: &PairDataSpec,
) -> Result<(Descriptors, Descriptors)> {
    let segments = |symmetric: bool| -> Result<(Descriptors, Descriptors)> {
        let suffix = if symmetric { "sym" } else { "nonsym" };
        let la = ds.segmentation(&x.name, &y.name, &x.name, x.mesh().n_vertices(), suffix)?;
        let lb = ds.segmentation(&x.name, &y.name, &y.name, y.mesh().n_vertices(), suffix)?;
        desc::matched_segments(&la, &lb)
    };
    match *spec {
        PairDataSpec::DatasetSegments { symmetric } => segments(symmetric),
        PairDataSpec::Rich(None) => {
            let (fs, gs) = segments(true)?;
            desc::rich(x.basis(), y.basis(), &fs, &gs, 100, 100)
        }
        PairDataSpec::GroundTruthLandmarks(count) => {
            let picks = farthest_points(x.mesh(), &gt.x, count);
            let xs: Vec<usize> = picks.iter().map(|&i| gt.x[i]).collect();
            let ys: Vec<usize> = picks.iter().map(|&i| gt.y[i]).collect();
            Ok((desc::landmarks(x.mesh().n_vertices(), &xs)?, desc::landmarks(y.mesh().n_vertices(), &ys)?))
        }
        _ => spec.functions(x.prepared.parts(), y.prepared.parts(), &SegmentationOptions::default()),
    }
}
