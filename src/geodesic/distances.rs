//! The interface the evaluation measures errors with: distances on a shape from source vertices,
//! implemented by every geodesic solver of this module.

use faer::Mat;

use crate::error::{Error, Result};

/// Distances on the target shape Y from a set of source vertices to every vertex.
pub trait Distances {
    /// Number of vertices m of Y.
    fn n_vertices(&self) -> usize;
    /// m × sources.len() distances (in Y's units).
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>>;
    /// d(s, t) for every pair (s, t) of vertices, in Y's units (`INFINITY` when t cannot be
    /// reached from s). The default runs [`Distances::distances_from`] on the distinct sources,
    /// 64 at a time; solvers with early termination override it.
    fn pair_distances(&self, pairs: &[(usize, usize)]) -> Result<Vec<f64>> {
        let m = self.n_vertices();
        if let Some(&(s, t)) = pairs.iter().find(|&&(s, t)| s >= m || t >= m) {
            return Err(Error::invalid("pair", format!("({s}, {t}) is out of range (m = {m})")));
        }
        let mut sources: Vec<usize> = pairs.iter().map(|p| p.0).collect();
        sources.sort_unstable();
        sources.dedup();
        let mut out = vec![0.0; pairs.len()];
        for chunk in sources.chunks(64) {
            let d = self.distances_from(chunk)?;
            for (i, &(s, t)) in pairs.iter().enumerate() {
                if let Ok(j) = chunk.binary_search(&s) {
                    out[i] = d[(t, j)];
                }
            }
        }
        Ok(out)
    }
    /// min(d(s, t), cap) for every pair and its cap (`caps.len() == pairs.len()`): distances
    /// only matter below the cap, which lets early-terminating solvers stop sooner. The default
    /// takes [`Distances::pair_distances`] and caps it.
    fn pair_distances_capped(&self, pairs: &[(usize, usize)], caps: &[f64]) -> Result<Vec<f64>> {
        if caps.len() != pairs.len() {
            return Err(Error::invalid("caps", format!("{} caps for {} pairs", caps.len(), pairs.len())));
        }
        Ok(self.pair_distances(pairs)?.into_iter().zip(caps).map(|(d, &c)| d.min(c)).collect())
    }
}

impl Distances for super::HeatGeodesics {
    fn n_vertices(&self) -> usize {
        self.n()
    }
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
        self.distances(sources)
    }
}

/// Exact polyhedral distances; point-to-point queries stop early (see
/// [`super::ExactGeodesics::pair_distances`]).
impl Distances for super::ExactGeodesics {
    fn n_vertices(&self) -> usize {
        self.n()
    }
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
        self.distances(sources)
    }
    fn pair_distances(&self, pairs: &[(usize, usize)]) -> Result<Vec<f64>> {
        super::ExactGeodesics::pair_distances(self, pairs)
    }
    fn pair_distances_capped(&self, pairs: &[(usize, usize)], caps: &[f64]) -> Result<Vec<f64>> {
        super::ExactGeodesics::pair_distances_capped(self, pairs, caps)
    }
}

/// Graph (Dijkstra) distances: mesh edges, kNN graphs of point clouds, any graph; point-to-point
/// queries stop early.
impl Distances for super::GraphGeodesics {
    fn n_vertices(&self) -> usize {
        self.n()
    }
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
        self.distances(sources)
    }
    fn pair_distances(&self, pairs: &[(usize, usize)]) -> Result<Vec<f64>> {
        super::GraphGeodesics::pair_distances(self, pairs)
    }
    fn pair_distances_capped(&self, pairs: &[(usize, usize)], caps: &[f64]) -> Result<Vec<f64>> {
        super::GraphGeodesics::pair_distances_capped(self, pairs, caps)
    }
}

impl<D: Distances + ?Sized> Distances for Box<D> {
    fn n_vertices(&self) -> usize {
        (**self).n_vertices()
    }
    fn distances_from(&self, sources: &[usize]) -> Result<Mat<f64>> {
        (**self).distances_from(sources)
    }
    fn pair_distances(&self, pairs: &[(usize, usize)]) -> Result<Vec<f64>> {
        (**self).pair_distances(pairs)
    }
    fn pair_distances_capped(&self, pairs: &[(usize, usize)], caps: &[f64]) -> Result<Vec<f64>> {
        (**self).pair_distances_capped(pairs, caps)
    }
}
