//! Geodesic distances on triangle meshes, point clouds and graphs.
//!
//! - [`ExactGeodesics`]: exact polyhedral distances (shortest paths on the piecewise-flat
//!   surface) by window propagation, MMP as described by Surazhsky et al. 2005, with early
//!   termination for point-to-point queries ([`ExactGeodesics::pair_distances`]).
//! - [`HeatGeodesics`]: the heat method (Crane et al. 2013), a fast smooth approximation, run on
//!   the intrinsic Delaunay triangulation of the mesh (see [`HeatGeodesics`] for why).
//! - [`GraphGeodesics`]: Dijkstra on a graph: a mesh's edges (an upper bound of the geodesic
//!   distance), a point cloud's kNN graph, or any weighted graph.
//!
//! [`GeodesicMethod`] picks one of the mesh methods by name and builds it behind
//! [`Distances`], the interface the evaluation uses.
//!
//! Measured with `examples/geodesic_timing.rs` on the bundled FAUST `tr_reg_001` (5,000
//! vertices, √area = 0.759), 2 cores shared with other jobs:
//!
//! - exact single-source solve (all vertices): 0.045–0.065 s median over runs, ≈ 10⁵ windows;
//!   pairs near each other as in an evaluation (5,000 template points, predictions 0–15 edges
//!   away): 0.4–0.7 s for all 5,000, and as much again for the mirrored pairs capped at the
//!   direct distance; on TOSCA `cat0` (27,894 vertices) a full solve takes 0.8–1.1 s (the window
//!   count grows like n^1.5) and the 5,000 near pairs 0.9–1.0 s;
//! - errors of the approximations against the exact distances (5 sources spread over the body;
//!   relative error |d − d_exact| / d_exact over the vertices farther than 1 % / 10 % of √area
//!   from the source):
//!
//! | method | mean (> 1 %) | max (> 1 %) | mean (> 10 %) | max (> 10 %) |
//! | --- | --- | --- | --- | --- |
//! | Dijkstra on edges | 5.2 % | 28.6 % | 5.2 % | 12.8 % |
//! | heat method (t = h²) | 2.7 % | 18.1 % | 2.7 % | 8.1 % |
//!
//! and on TOSCA `cat0` (27,894 vertices, many obtuse triangles): Dijkstra 6.4 % / 112 % (6.2 % /
//! 31.7 %), heat method 1.6 % / 14.7 % (1.6 % / 12.5 %); before the heat method ran on the
//! intrinsic Delaunay triangulation it was 26 % / 100 % there. Over every shape of the benchmark
//! data (`examples/heat_accuracy.rs`, BENCHMARKS.md) the heat method's mean relative error is
//! 1.6–3.9 % per shape (it was 8–50 % on the TOSCA shapes before).
//!
//! Dijkstra always overestimates (paths zig-zag along edges); the heat method is smooth but
//! biased, with its largest errors near the source. On the unit icosphere with 10,242 vertices
//! the exact polyhedral distances are 0.015 % (mean) to 0.018 % (max) shorter than great-circle
//! arcs, the inscribed polyhedron being slightly smaller than the sphere.

mod distances;
mod exact;
mod graph;
mod heat;
mod intrinsic;
mod topology;

pub use distances::Distances;
pub use exact::ExactGeodesics;
pub use graph::GraphGeodesics;
pub use heat::HeatGeodesics;
pub use intrinsic::intrinsic_delaunay_laplacian;

use crate::error::{Error, Result};
use crate::shape::TriMesh;

/// Which geodesic distance to use on a mesh (e.g. for evaluation; the CLI's `--geodesics`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GeodesicMethod {
    /// Exact polyhedral distances ([`ExactGeodesics`]).
    #[default]
    Exact,
    /// The heat method ([`HeatGeodesics`]); needs a connected mesh.
    Heat,
    /// Dijkstra on the mesh's edges ([`GraphGeodesics::mesh_edges`]).
    Dijkstra,
}

impl GeodesicMethod {
    /// All methods, in the order of their names.
    pub const ALL: [GeodesicMethod; 3] = [GeodesicMethod::Exact, GeodesicMethod::Heat, GeodesicMethod::Dijkstra];

    /// The method's name: `exact`, `heat` or `dijkstra`.
    pub fn name(self) -> &'static str {
        match self {
            GeodesicMethod::Exact => "exact",
            GeodesicMethod::Heat => "heat",
            GeodesicMethod::Dijkstra => "dijkstra",
        }
    }

    /// A one-line description, for reports.
    pub fn description(self) -> &'static str {
        match self {
            GeodesicMethod::Exact => "exact polyhedral (MMP window propagation)",
            GeodesicMethod::Heat => "heat method (approximate, ~2–4% mean relative error)",
            GeodesicMethod::Dijkstra => "Dijkstra on mesh edges (upper bound, ~5% mean relative error)",
        }
    }

    /// Builds the solver for `mesh`.
    ///
    /// Errors: those of the solver's constructor (the heat method refuses meshes with several
    /// components or unreferenced vertices).
    pub fn build<'m>(self, mesh: &'m TriMesh) -> Result<Box<dyn Distances + Send + Sync + 'm>> {
        Ok(match self {
            GeodesicMethod::Exact => Box::new(ExactGeodesics::new(mesh)?),
            GeodesicMethod::Heat => Box::new(HeatGeodesics::new(mesh)?),
            GeodesicMethod::Dijkstra => Box::new(GraphGeodesics::mesh_edges(mesh)?),
        })
    }
}

impl std::fmt::Display for GeodesicMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for GeodesicMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        GeodesicMethod::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            Error::invalid("geodesic method", format!("unknown method {s:?}; expected exact, heat or dijkstra"))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::icosphere;

    #[test]
    fn methods_by_name_build_comparable_solvers() {
        let mesh = icosphere(3);
        let pairs = [(0usize, 100usize), (5, 600), (7, 7)];
        let mut results = vec![];
        for m in GeodesicMethod::ALL {
            assert_eq!(m.name().parse::<GeodesicMethod>().unwrap(), m);
            let d = m.build(&mesh).unwrap();
            assert_eq!(d.n_vertices(), mesh.n_vertices());
            results.push(d.pair_distances(&pairs).unwrap());
        }
        assert!("geodesic".parse::<GeodesicMethod>().is_err());
        let (exact, heat, dijkstra) = (&results[0], &results[1], &results[2]);
        for i in 0..2 {
            assert!((heat[i] - exact[i]).abs() < 0.05 * exact[i]);
            assert!(dijkstra[i] >= exact[i] && dijkstra[i] < 1.2 * exact[i]);
        }
        assert_eq!(exact[2], 0.0);
    }
}
