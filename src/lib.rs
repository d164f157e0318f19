//! # funcorr — functional correspondence between shapes
//!
//! Dense correspondence between triangle meshes, point clouds and graphs built from any
//! high-dimensional data, with functional maps; at its heart the method of *Functional
//! correspondence by matrix completion* (Kovnatsky, Bronstein, Bresson, Vandergheynst, CVPR 2015).
//!
//! Notation follows the paper: the source shape X has n vertices, the target Y has m;
//! Φ (n × k) and Ψ (m × k) are their Laplacian eigenbases, A_X and A_Y their vertex weights.
//!
//! Data flows one way through the modules:
//! [`io`] → [`shape`] → [`laplacian`] → [`spectral`] → (data terms, solvers, point-wise maps,
//! evaluation) → CLI.
//!
//! ```
//! use funcorr::{laplacian, primitives, spectral};
//! let sphere = primitives::icosphere(3); // 642 vertices on the unit sphere
//! let lap = laplacian::cotangent(&sphere).unwrap();
//! let (basis, _) = spectral::eigen_basis(&lap, &spectral::SpectralOptions::new(4), None).unwrap();
//! assert!((basis.eigenvalues[1] - 2.0).abs() < 0.05); // l(l+1) for l = 1
//! ```

pub mod alloc;
pub mod benchmark;
pub mod cell_quadrature;
pub mod certified_search;
pub(crate) mod cholesky;
pub mod cloud;
pub mod completion;
pub mod denoise;
pub mod descriptors;
pub mod error;
pub mod eval;
pub mod experiments;
pub mod fmap;
pub mod geodesic;
pub mod io;
pub mod laplacian;
pub(crate) mod linalg;
pub mod matching;
pub mod operators;
pub mod optim;
pub mod pointwise;
pub mod prepared;
pub mod primitives;
pub mod progress;
pub mod refine;
mod rng;
pub mod shape;
pub mod spatial;
pub mod spectral;
pub mod viz;

pub use error::{Error, Result};
pub use prepared::PreparedShape;
