//! A shape ready for matching: the shape, its Laplacian and eigenbasis, and the surface geometry
//! the orientation-aware steps need (the mesh itself, or a point cloud's local triangulation),
//! computed once and reused by every pair the shape takes part in.
//!
//! **Units.** A prepared shape is the input shape *scaled to unit area* (the total vertex weight
//! Σ A = 1): its Laplacian's mass, its basis (λ · area, φ · √area) and its surface geometry
//! (positions / √area) are those of the scaled shape, and `area` keeps the input's total vertex
//! weight (units² for meshes and clouds). Every step of matching then sees the same numbers
//! whatever the units of the two inputs (metres, millimetres, or one of each): the functional
//! maps between two isometric shapes are orthonormal, the eigenvalues of both sides are
//! comparable, descriptor times and energies, sample spacings and search radii are relative to
//! the shape. The eigenbasis cache is keyed by the input's Laplacian, so the cached bases are
//! shared with `funcorr spectrum`. [`PreparedShape::input_basis`] gives the basis in the input's
//! units.
//!
//! **Noisy meshes.** Under [`LaplacianChoice::Auto`] a mesh rough with noise is smoothed by one
//! implicit step first ([`crate::denoise`]): its Laplacian, basis and surface (positions,
//! normals, gradients) are the smoothed mesh's, `area` is the smoothed mesh's, and
//! [`PreparedShape::denoising`] says what was done; `shape` stays the input, with the same
//! vertices, so maps are maps of the input's vertices.

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::cloud::{cloud_laplacian, CloudSurface, DEFAULT_NEIGHBOURS};
use crate::denoise::{denoise_with, Denoising};
use crate::error::{Error, Result};
use crate::laplacian::{self, KnnOptions, Laplacian};
use crate::operators::FaceGradients;
use crate::shape::{Shape, TriMesh};
use crate::spectral::{self, Basis, BasisCache, SpectralOptions};

/// Which Laplacian to build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LaplacianChoice {
    /// Cotangent for meshes — built on the smoothed geometry when the mesh is rough with noise
    /// ([`crate::denoise::denoise`]; `Cotangent` takes the mesh as it is) —, the point-cloud
    /// Laplacian for 3-D point sets, the kNN graph for other dimensions.
    #[default]
    Auto,
    /// Cotangent weights and barycentric mass (meshes).
    Cotangent,
    /// The cotangent Laplacian of the mesh's intrinsic Delaunay triangulation
    /// ([`crate::geodesic::intrinsic_delaunay_laplacian`]): non-negative weights on meshes with
    /// obtuse or sliver triangles, the cotangent Laplacian itself on Delaunay meshes (meshes).
    Intrinsic,
    /// The point-cloud Laplacian of local Delaunay fans over K neighbours (3-D points; a mesh is
    /// used as its vertices).
    Cloud {
        /// Neighbours K.
        k: usize,
    },
    /// The paper's kNN graph (eq. (1)), for any point set.
    Knn(KnnOptions),
}

/// The triangles a shape's orientation-aware steps work on: a mesh's own faces, or the local
/// triangulation of a point cloud (with its normals).
#[derive(Debug, Clone)]
pub enum Surface {
    /// The mesh.
    Mesh,
    /// A point cloud's oriented union of local Delaunay fans.
    Cloud(CloudSurface),
    /// A noisy mesh's smoothed geometry ([`crate::denoise`]; the same vertices and faces,
    /// moved), which the Laplacian was built on, and what the smoothing did.
    Denoised(TriMesh, Denoising),
}

/// Cells of [`PreparedShape::quadrature_cells`]: surfaces of more than twice as many vertices
/// integrate the fits' operators over this many cells ([`crate::cell_quadrature`]; 4 vertices
/// per cell at 52k, 67 at 840k), smaller ones exactly (every shape up to 25,000 vertices). The
/// quadrature's error depends on the cells' size against the basis' wavelengths, not on the
/// vertex count, so one count serves every size; measured together with `GRAPH_NODES` of the
/// basin search (`matching::search`, which see).
pub const QUADRATURE_CELLS: usize = 12_500;

/// The area of a shape from its Laplacian's vertex weights A (Σ A: units² for meshes and
/// clouds), as [`PreparedShape::area`] takes it: 1 when the sum is not finite and positive (the
/// Laplacian and the eigensolver reject such weights).
pub fn area_of_mass(mass: &[f64]) -> f64 {
    let total: f64 = mass.iter().sum();
    if total.is_finite() && total > 0.0 {
        total
    } else {
        1.0
    }
}

/// A shape with its Laplacian, its eigenbasis and (on demand) its surface geometry, scaled to
/// unit area (module docs, "Units").
#[derive(Debug)]
pub struct PreparedShape {
    /// The shape as loaded (input units).
    pub shape: Shape,
    /// Its Laplacian (n × n) at unit area: W as built, A / `area`.
    pub laplacian: Laplacian,
    /// Its first k eigenpairs at unit area (Φ: n × k, Φᵀ A Φ = I, Σ A = 1).
    pub basis: Basis,
    /// Total vertex weight Σ A of the input (its area in units² for meshes and clouds).
    pub area: f64,
    /// The surface at unit area (positions / √area), when there is one.
    surface: Option<Surface>,
    /// The mesh at unit area (for [`Surface::Mesh`]).
    unit_mesh: Option<TriMesh>,
    gradients: OnceLock<Option<FaceGradients>>,
    normals: OnceLock<Option<Vec<[f64; 3]>>>,
    cells: OnceLock<Option<Vec<u32>>>,
    grid: OnceLock<Option<Vec<usize>>>,
}

impl PreparedShape {
    /// The shape, its Laplacian and its basis: the one side of a pair that data specifications
    /// ([`crate::descriptors::spec::PairDataSpec::functions`]) read.
    pub fn parts(&self) -> (&Shape, &Laplacian, &Basis) {
        (&self.shape, &self.laplacian, &self.basis)
    }

    /// Builds the Laplacian of `shape` (`choice`), its first `k` eigenpairs (through `cache` when
    /// given) and, for meshes and 3-D point clouds, the surface. Errors: a Laplacian that does
    /// not fit the shape (cotangent without faces, a point-cloud Laplacian of non-3-D points),
    /// and those of the Laplacian and the eigensolver.
    pub fn new(shape: Shape, choice: LaplacianChoice, k: usize, cache: Option<&BasisCache>) -> Result<Self> {
        crate::progress::stage("laplacian")?;
        let (laplacian, surface) = build_laplacian(&shape, choice)?;
        crate::progress::stage("eigenbasis")?;
        let (basis, _) = spectral::eigen_basis_cached(&laplacian, &SpectralOptions::new(k), cache, None)?;
        let basis = if basis.k() > k { basis.truncate(k)? } else { basis };
        Ok(Self::from_parts(shape, laplacian, basis, surface))
    }

    /// Assembles a prepared shape from parts computed elsewhere in the input's units (e.g. a
    /// basis read from a file) and scales all of them to unit area (module docs): Σ A of the
    /// basis's mass is the area. A total weight that is not finite and positive is left as it
    /// is (area 1): the Laplacian and eigensolver reject such weights before this point.
    pub fn from_parts(shape: Shape, mut laplacian: Laplacian, mut basis: Basis, surface: Option<Surface>) -> Self {
        let total: f64 = basis.mass.iter().sum();
        let area = if total.is_finite() && total > 0.0 { total } else { 1.0 };
        let mut unit_mesh = None;
        let mut surface = surface;
        if area != 1.0 {
            let root = area.sqrt();
            laplacian.mass.iter_mut().for_each(|a| *a /= area);
            basis.mass.iter_mut().for_each(|a| *a /= area);
            basis.eigenvalues.iter_mut().for_each(|l| *l *= area);
            for j in 0..basis.eigenvectors.ncols() {
                basis.eigenvectors.col_as_slice_mut(j).iter_mut().for_each(|v| *v *= root);
            }
            let shrink = |p: [f64; 3]| [p[0] / root, p[1] / root, p[2] / root];
            match (&mut surface, &shape) {
                (Some(Surface::Mesh), Shape::Mesh(m)) => unit_mesh = m.map_vertices(shrink).ok(),
                (Some(Surface::Denoised(m, _)), _) => unit_mesh = m.map_vertices(shrink).ok(),
                (Some(Surface::Cloud(c)), _) => {
                    if let Ok(soup) = c.soup.map_vertices(shrink) {
                        c.soup = soup;
                    }
                }
                _ => {}
            }
        } else if let (Some(Surface::Mesh), Shape::Mesh(m)) | (Some(Surface::Denoised(m, _)), _) = (&surface, &shape) {
            unit_mesh = Some(m.clone());
        }
        PreparedShape {
            shape,
            laplacian,
            basis,
            area,
            surface,
            unit_mesh,
            gradients: OnceLock::new(),
            normals: OnceLock::new(),
            cells: OnceLock::new(),
            grid: OnceLock::new(),
        }
    }

    /// The basis in the input's units: λ / area, φ / √area, A · area (k eigenpairs, n × k; a
    /// copy).
    pub fn input_basis(&self) -> Basis {
        let (area, root) = (self.area, self.area.sqrt());
        Basis {
            eigenvalues: self.basis.eigenvalues.iter().map(|l| l / area).collect(),
            eigenvectors: faer::Mat::from_fn(self.basis.n(), self.basis.k(), |i, j| {
                self.basis.eigenvectors[(i, j)] / root
            }),
            mass: self.basis.mass.iter().map(|a| a * area).collect(),
            residuals: self.basis.residuals.clone(),
        }
    }

    /// What the denoising of a rough mesh did ([`crate::denoise`]; `None`: the shape's own
    /// geometry is used).
    pub fn denoising(&self) -> Option<&Denoising> {
        match &self.surface {
            Some(Surface::Denoised(_, report)) => Some(report),
            _ => None,
        }
    }

    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.shape.n_vertices()
    }

    /// The triangles of the surface at unit area: the mesh, or the point cloud's soup (None for
    /// abstract data or a kNN-graph Laplacian of a cloud).
    pub fn triangles(&self) -> Option<&TriMesh> {
        match &self.surface {
            Some(Surface::Mesh | Surface::Denoised(..)) => self.unit_mesh.as_ref(),
            Some(Surface::Cloud(c)) => Some(&c.soup),
            _ => None,
        }
    }

    /// Vertex positions (n × 3) of meshes and 3-D point clouds, at unit area.
    pub fn positions(&self) -> Option<&[[f64; 3]]> {
        self.triangles().map(|t| t.vertices())
    }

    /// Face gradients of the surface (computed on first use): the mesh's, or the cloud soup's
    /// with face weight ⅓ (it covers the surface three times).
    pub fn gradients(&self) -> Option<&FaceGradients> {
        self.gradients
            .get_or_init(|| {
                let w = match &self.surface {
                    Some(Surface::Cloud(_)) => 1.0 / 3.0,
                    _ => 1.0,
                };
                self.triangles().and_then(|t| FaceGradients::weighted(t, w).ok())
            })
            .as_ref()
    }

    /// Quadrature cells of the vertices (length n; computed on first use) for surfaces of more
    /// than 2 × [`QUADRATURE_CELLS`] vertices, None below: the geodesic Voronoi cells (along the
    /// edges of [`Self::triangles`]) of about [`QUADRATURE_CELLS`] well-spread vertices
    /// ([`crate::spatial::grid_samples`]); a vertex no cell reaches (a small component without
    /// a sample) is a cell of its own. The fits' operators are integrated over them
    /// ([`crate::cell_quadrature`]).
    pub fn quadrature_cells(&self) -> Option<&[u32]> {
        self.cells
            .get_or_init(|| {
                let t = self.triangles()?;
                let seeds = self.grid_vertices()?;
                let graph = crate::geodesic::GraphGeodesics::mesh_edges(t).ok()?;
                let (_, mut labels) = graph.nearest_sources(seeds).ok()?;
                for (next, l) in (seeds.len() as u32..).zip(labels.iter_mut().filter(|l| **l == u32::MAX)) {
                    *l = next;
                }
                Some(labels)
            })
            .as_deref()
    }

    /// About [`QUADRATURE_CELLS`] well-spread vertices ([`crate::spatial::grid_samples`] of
    /// [`Self::positions`]; ascending vertex ids; computed on first use) for surfaces of more than
    /// 2 × [`QUADRATURE_CELLS`] vertices, None below: the seeds of [`Self::quadrature_cells`], and
    /// the vertices among which ZoomOut's steps before its last match the samples of the other
    /// shape on large pairs ([`crate::refine::zoomout_coarse_to_fine`]).
    pub fn grid_vertices(&self) -> Option<&[usize]> {
        self.grid
            .get_or_init(|| {
                let p = self.positions()?;
                (p.len() > 2 * QUADRATURE_CELLS).then(|| crate::spatial::grid_samples(p, QUADRATURE_CELLS))
            })
            .as_deref()
    }

    /// Outward unit vertex normals (computed on first use): area-weighted for meshes, the
    /// oriented PCA normals for clouds.
    pub fn normals(&self) -> Option<&[[f64; 3]]> {
        self.normals
            .get_or_init(|| match (&self.surface, &self.unit_mesh) {
                (Some(Surface::Mesh | Surface::Denoised(..)), Some(m)) => Some(m.vertex_normals()),
                (Some(Surface::Cloud(c)), _) => Some(c.normals.clone()),
                _ => None,
            })
            .as_deref()
    }
}

/// The Laplacian of a shape for `choice`, and its surface when it has one.
pub fn build_laplacian(shape: &Shape, choice: LaplacianChoice) -> Result<(Laplacian, Option<Surface>)> {
    let cloud = |pts: &[[f64; 3]], k: usize| -> Result<(Laplacian, Option<Surface>)> {
        let (lap, surface) = cloud_laplacian(pts, k)?;
        Ok((lap, Some(Surface::Cloud(surface))))
    };
    let points3 = |shape: &Shape| -> Option<Vec<[f64; 3]>> {
        match shape {
            Shape::Mesh(m) => Some(m.vertices().to_vec()),
            Shape::Points(p) if p.dim() == 3 => {
                Some((0..p.len()).map(|i| [p.point(i)[0], p.point(i)[1], p.point(i)[2]]).collect())
            }
            Shape::Points(_) => None,
        }
    };
    match (choice, shape) {
        (LaplacianChoice::Auto, Shape::Mesh(m)) => {
            let cotan = laplacian::cotangent(m)?;
            match denoise_with(m, &cotan)? {
                (None, _) => Ok((cotan, Some(Surface::Mesh))),
                (Some(d), _) => Ok((d.laplacian, Some(Surface::Denoised(d.mesh, d.report)))),
            }
        }
        (LaplacianChoice::Cotangent, Shape::Mesh(m)) => Ok((laplacian::cotangent(m)?, Some(Surface::Mesh))),
        (LaplacianChoice::Intrinsic, Shape::Mesh(m)) => {
            Ok((crate::geodesic::intrinsic_delaunay_laplacian(m)?, Some(Surface::Mesh)))
        }
        (LaplacianChoice::Cotangent, Shape::Points(_)) => Err(Error::invalid(
            "laplacian",
            "cotan needs a triangle mesh; this shape has no faces (use the point-cloud Laplacian)",
        )),
        (LaplacianChoice::Intrinsic, Shape::Points(_)) => Err(Error::invalid(
            "laplacian",
            "intrinsic needs a triangle mesh; this shape has no faces (use the point-cloud Laplacian)",
        )),
        (LaplacianChoice::Auto, Shape::Points(p)) if p.dim() != 3 => {
            Ok((laplacian::knn_graph(p, &KnnOptions::default())?, None))
        }
        (LaplacianChoice::Auto, s) => {
            // Small clouds: as many neighbours as there are other points.
            let pts = points3(s).expect("3-D points");
            if pts.len() < 4 {
                return Err(Error::invalid(
                    "point set",
                    format!(
                        "it has {} point(s); the point-cloud Laplacian needs at least 4 points (3 neighbours of each)",
                        pts.len()
                    ),
                ));
            }
            let k = DEFAULT_NEIGHBOURS.min(pts.len() - 1);
            cloud(&pts, k)
        }
        (LaplacianChoice::Cloud { k }, s) => match points3(s) {
            Some(pts) => cloud(&pts, k),
            None => Err(Error::invalid(
                "laplacian",
                format!(
                    "the point-cloud Laplacian needs 3-D points; this shape has dimension {}",
                    s.to_point_set().dim()
                ),
            )),
        },
        (LaplacianChoice::Knn(o), s) => Ok((laplacian::knn_graph(&s.to_point_set(), &o)?, None)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::PointSet;

    /// The automatic Laplacian of a noisy mesh is built on its smoothed geometry, which the
    /// surface (positions, normals, gradients) also is; the cotangent choice and a clean mesh
    /// use the mesh as it is.
    #[test]
    fn a_noisy_mesh_is_prepared_on_its_smoothed_geometry() {
        let clean = crate::primitives::icosphere(4);
        let h = clean.mean_edge_length();
        let mut rng = crate::rng::Normal::new(11);
        let moved = clean.vertices().iter().map(|p| [0, 1, 2].map(|d| p[d] + 0.5 * h * rng.sample())).collect();
        let noisy = TriMesh::new(moved, clean.faces().to_vec()).unwrap();
        let p = PreparedShape::new(Shape::Mesh(clean.clone()), LaplacianChoice::Auto, 10, None).unwrap();
        assert!(p.denoising().is_none());
        let p = PreparedShape::new(Shape::Mesh(noisy.clone()), LaplacianChoice::Cotangent, 10, None).unwrap();
        assert!(p.denoising().is_none());
        let raw_positions = p.positions().unwrap().to_vec();
        let p = PreparedShape::new(Shape::Mesh(noisy.clone()), LaplacianChoice::Auto, 10, None).unwrap();
        let d = p.denoising().expect("smoothed").clone();
        assert!(d.roughness_before > crate::denoise::NOISY_ROUGHNESS, "{d:?}");
        let Shape::Mesh(kept) = &p.shape else { panic!("a mesh") };
        assert_eq!(kept.vertices(), noisy.vertices(), "the shape keeps its input vertices");
        // The surface is the smoothed mesh at unit area: rounder than the noisy one.
        let spread = |v: &[[f64; 3]]| {
            let r: Vec<f64> = v.iter().map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()).collect();
            let m = r.iter().sum::<f64>() / r.len() as f64;
            (r.iter().map(|x| (x - m).powi(2)).sum::<f64>() / r.len() as f64).sqrt() / m
        };
        let (smooth, raw) = (spread(p.positions().unwrap()), spread(&raw_positions));
        assert!(smooth < 0.67 * raw, "relative radial spread {smooth} smoothed, {raw} noisy");
        assert_eq!(p.normals().unwrap().len(), noisy.n_vertices());
        assert!(p.basis.eigenvalues[1] > 0.0 && p.basis.k() == 10);
    }

    #[test]
    fn clouds_of_fewer_than_four_points_say_so() {
        for n in 1..4 {
            let p = Shape::Points(PointSet::new(n, 3, (0..3 * n).map(|i| i as f64 * 0.37).collect()).unwrap());
            let e = build_laplacian(&p, LaplacianChoice::Auto).unwrap_err().to_string();
            assert!(e.contains("at least 4 points") && !e.contains("K <"), "{e}");
        }
    }
}
