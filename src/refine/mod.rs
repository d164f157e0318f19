//! Point-wise refinement of functional maps: ZoomOut (Melzi et al. 2019) on vertex samples, its
//! bijective two-direction variant (the discrete solver of Ren, Melzi, Wonka, Ovsjanikov 2021
//! with bijectivity and coupling terms), a metric polish by geodesic trilateration, and the
//! quality of point maps (orientation agreement, metric distortion).
//!
//! **Conventions.** A point map π: X → Y is `map_xy` (length n, for every vertex of X a vertex of
//! Y). Its pull-back functional map `C_yx = Φᵀ A_X Π Ψ` (k_X × k_Y) takes the coefficients of a
//! function g on Y (in Ψ, m × k_Y) to those of g ∘ π on X (in Φ, n × k_X) — pyFM's `FM_12` with
//! mesh1 = Y, and the transpose direction of the C of [`crate::fmap`]. Conversely, from C_yx the
//! point map is read off by nearest neighbours ([`map_of_pullback`]; the map Y → X by
//! [`map_yx_of_pullback`], or near the preimages of a map X → Y by [`map_yx_near_map`]).
//! Estimating the map X → Y through
//! its own pull-back (rather than through the push-forward C of the opposite direction) is the
//! direction ZoomOut's analysis is for, and measurably better (EXPERIMENTS.md).
//!
//! **Samples.** ZoomOut's functional maps only need the point map on a few thousand vertices
//! (Melzi et al. §4.4): on a sample S of X with weights w (the area of each sample's Voronoi
//! cell), C_yx is the weighted least-squares solution of Φ_S C ≈ Ψ_π(S). With every vertex and
//! w = A_X this is exactly Φᵀ A_X Π Ψ.
//!
//! **Search.** Every point map is searched as a [`Scope`] says: among every vertex of Y
//! ([`Scope::Exact`]), or near a coarse map between cells of both shapes ([`Scope::Near`]) for
//! pairs of 10⁵–10⁶ vertices.
//!
//! **Files, by concern.** `pullback.rs`: pull-back maps and the point maps read off them
//! ([`pullback`], [`map_of_pullback`], [`Scope`], [`Near`]); `zoomout.rs`: ZoomOut on samples
//! ([`zoomout`]); `bijective.rs`: bijective ZoomOut and the bijective polish
//! ([`bijective_zoomout`], [`bijective_polish`]); `metric.rs`: the metric polish of a point map
//! by geodesic trilateration to anchors, combined with a spectral reading ([`metric_polish`],
//! the partial path's last step); `quality.rs`: the quality of a point map
//! ([`metric_distortion`], [`orientation_agreement`] and their estimates around samples,
//! [`vertex_orientation`], [`repair_mirrored`]).

mod bijective;
mod metric;
mod pullback;
mod quality;
mod zoomout;

pub use bijective::{
    bijective_polish, bijective_polish_pinned, bijective_zoomout, BijectiveOptions, POLISH_BIJECTIVITY,
};
pub use metric::{metric_polish, MetricPolishOptions, MetricPolished};
pub use pullback::{
    map_of_pullback, map_of_pullback_among, map_yx_near_map, map_yx_of_pullback, pullback, Near, Scope,
};
pub use quality::{
    incident_vertices, low_pass, metric_distortion, metric_distortion_around, orientation_agreement,
    orientation_agreement_around, repair_mirrored, vertex_orientation,
};
pub use zoomout::{zoomout, zoomout_coarse_to_fine, zoomout_pinned, ZoomOutOptions};

#[cfg(test)]
mod tests;
