//! Synthetic shapes with known spectra, for validation and tests: icospheres (eigenvalues
//! l(l+1) on the unit sphere, multiplicity 2l+1), flat rectangles (Neumann eigenvalues
//! π²(i²/a² + j²/b²)) and cycle graphs (2 − 2cos(2πj/n)).

use std::collections::HashMap;

use crate::shape::TriMesh;

/// Unit icosphere: a subdivided icosahedron projected on the sphere of radius 1.
/// `subdivisions` s gives 10·4ˢ + 2 vertices and 20·4ˢ triangles, outward oriented.
pub fn icosphere(subdivisions: u32) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1., t, 0.],
        [1., t, 0.],
        [-1., -t, 0.],
        [1., -t, 0.],
        [0., -1., t],
        [0., 1., t],
        [0., -1., -t],
        [0., 1., -t],
        [t, 0., -1.],
        [t, 0., 1.],
        [-t, 0., -1.],
        [-t, 0., 1.],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let normalize = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    v.iter_mut().for_each(|p| *p = normalize(*p));
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut nf = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<[f64; 3]>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (v[a as usize], v[b as usize]);
                v.push(normalize([(p[0] + q[0]) / 2., (p[1] + q[1]) / 2., (p[2] + q[2]) / 2.]));
                (v.len() - 1) as u32
            })
        };
        for [a, b, c] in f {
            let (ab, bc, ca) = (midpoint(a, b, &mut v), midpoint(b, c, &mut v), midpoint(c, a, &mut v));
            nf.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = nf;
    }
    TriMesh::new(v, f).expect("icosphere is valid")
}

/// One level of midpoint subdivision: every triangle split into four by its edge midpoints.
/// The surface is unchanged (same area, same embedding), vertex i of `mesh` stays vertex i (so a
/// ground-truth correspondence of the coarse vertices still holds), and the midpoint of the
/// e-th edge of [`TriMesh::edges`] becomes vertex n + e: n + #E vertices, 4 #F faces.
/// Used to build large meshes from the benchmark shapes (BENCHMARKS.md); unlike Loop
/// subdivision it does not smooth, so distances and areas on the result equal the input's.
///
/// Errors: more than 2³² − 1 vertices in the result.
pub fn midpoint_subdivision(mesh: &TriMesh) -> crate::Result<TriMesh> {
    let edges = mesh.edges();
    let n = mesh.n_vertices();
    if n + edges.len() > u32::MAX as usize {
        return Err(crate::Error::invalid(
            "mesh",
            format!("subdividing {n} vertices and {} edges exceeds 2³² vertices", edges.len()),
        ));
    }
    let v = mesh.vertices();
    let mut vertices = Vec::with_capacity(n + edges.len());
    vertices.extend_from_slice(v);
    for [a, b] in &edges {
        let (p, q) = (v[*a as usize], v[*b as usize]);
        vertices.push([(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0]);
    }
    let mid = |a: u32, b: u32| -> u32 {
        if a == b {
            return a; // a face with a repeated vertex stays degenerate
        }
        let e = edges.binary_search(&[a.min(b), a.max(b)]).expect("every face edge is in edges()");
        (n + e) as u32
    };
    let mut faces = Vec::with_capacity(4 * mesh.n_faces());
    for &[a, b, c] in mesh.faces() {
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        faces.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
    }
    TriMesh::new(vertices, faces)
}

/// The unit icosphere pushed out by a smooth radial bump with no symmetry, then stretched
/// (1.3, 1, 0.9) along the axes: a closed surface whose Laplacian eigenvalues are simple, so
/// eigenvectors are defined up to sign only — the shape the invariance tests use.
pub fn bumpy_sphere(subdivisions: u32) -> TriMesh {
    let s = icosphere(subdivisions);
    let v = s
        .vertices()
        .iter()
        .map(|p| {
            let r = 1.0 + 0.15 * (3.0 * p[0] + 1.0).sin() * (2.0 * p[1] + 0.3).cos() + 0.1 * p[2].powi(3) + 0.05 * p[0];
            [1.3 * r * p[0], r * p[1], 0.9 * r * p[2]]
        })
        .collect();
    TriMesh::new(v, s.faces().to_vec()).expect("bumpy sphere is valid")
}

/// A bumpy sphere with exactly one symmetry, the mirror x → −x (the icosphere's vertices and
/// triangles are symmetric under it, and the bumps are even in x but break every other
/// symmetry): intrinsic descriptors cannot tell its left from its right, as on a human body.
/// Also returns the mirror map (vertex i ↦ the vertex at (−x, y, z)).
pub fn mirror_symmetric_blob(subdivisions: u32) -> (TriMesh, Vec<usize>) {
    let s = icosphere(subdivisions);
    let v: Vec<[f64; 3]> = s
        .vertices()
        .iter()
        .map(|p| {
            let r = 1.0 + 0.2 * (2.0 * p[1] + 0.3).sin() * p[2].cos() + 0.15 * p[2].powi(3) + 0.25 * p[0] * p[0] * p[1];
            [1.4 * r * p[0], r * p[1], 0.8 * r * p[2]]
        })
        .collect();
    let key = |p: [f64; 3]| [(p[0] * 1e9).round() as i64, (p[1] * 1e9).round() as i64, (p[2] * 1e9).round() as i64];
    let index: std::collections::HashMap<[i64; 3], usize> =
        s.vertices().iter().enumerate().map(|(i, &p)| (key(p), i)).collect();
    let mirror = s.vertices().iter().map(|p| index[&key([-p[0], p[1], p[2]])]).collect();
    (TriMesh::new(v, s.faces().to_vec()).expect("the blob is valid"), mirror)
}

/// Flat rectangle [0, a] × [0, b] in the plane z = 0, triangulated on a regular grid of
/// nx × ny cells ((nx+1)(ny+1) vertices), each cell split along alternating diagonals.
pub fn rectangle(a: f64, b: f64, nx: u32, ny: u32) -> TriMesh {
    let mut v = Vec::with_capacity(((nx + 1) * (ny + 1)) as usize);
    for j in 0..=ny {
        for i in 0..=nx {
            v.push([a * i as f64 / nx as f64, b * j as f64 / ny as f64, 0.0]);
        }
    }
    let id = |i: u32, j: u32| j * (nx + 1) + i;
    let mut f = Vec::with_capacity((2 * nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            let (p00, p10, p01, p11) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
            if (i + j) % 2 == 0 {
                f.extend([[p00, p10, p11], [p00, p11, p01]]);
            } else {
                f.extend([[p00, p10, p01], [p10, p11, p01]]);
            }
        }
    }
    TriMesh::new(v, f).expect("rectangle is valid")
}

/// A flat parallelogram grid with only obtuse triangles: the vertices (i + s·j, j, 0) for
/// 0 ≤ i ≤ nx, 0 ≤ j ≤ ny (unit spacing, shear s), each cell cut along its long diagonal, from
/// (i, j) to (i + 1, j + 1). For s > 0 every interior diagonal is non-Delaunay (its two opposite
/// angles sum to more than π): the worst case of a cotangent Laplacian with negative weights,
/// on a surface whose geodesic distances are Euclidean (the parallelogram is convex).
pub fn sheared_grid(nx: u32, ny: u32, shear: f64) -> TriMesh {
    let mut v = Vec::with_capacity(((nx + 1) * (ny + 1)) as usize);
    for j in 0..=ny {
        for i in 0..=nx {
            v.push([i as f64 + shear * j as f64, j as f64, 0.0]);
        }
    }
    let id = |i: u32, j: u32| j * (nx + 1) + i;
    let mut f = Vec::with_capacity((2 * nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            f.extend([[id(i, j), id(i + 1, j), id(i + 1, j + 1)], [id(i, j), id(i + 1, j + 1), id(i, j + 1)]]);
        }
    }
    TriMesh::new(v, f).expect("sheared grid is valid")
}

/// Edges of the cycle graph on n vertices, with unit weights.
pub fn cycle_edges(n: usize) -> Vec<(usize, usize, f64)> {
    (0..n).map(|i| (i, (i + 1) % n, 1.0)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_counts_and_radius() {
        let s = icosphere(2);
        assert_eq!(s.n_vertices(), 162);
        assert_eq!(s.n_faces(), 320);
        assert!(s.vertices().iter().all(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-14));
        assert!(s.boundary_loops().is_empty());
        assert_eq!(s.components().0, 1);
        // Outward orientation: normals point away from the centre.
        let n = s.vertex_normals();
        assert!(s.vertices().iter().zip(&n).all(|(p, q)| p[0] * q[0] + p[1] * q[1] + p[2] * q[2] > 0.9));
    }

    /// Midpoint subdivision keeps the area and the coarse vertices, and gives n + #E vertices
    /// and 4 #F faces (twice: 642 → 2562 → 10242 on the icosphere of level 3, like levels 4, 5).
    #[test]
    fn midpoint_subdivision_counts_and_area() {
        let mut m = bumpy_sphere(3);
        for _ in 0..2 {
            let s = midpoint_subdivision(&m).unwrap();
            assert_eq!(s.n_vertices(), m.n_vertices() + m.edges().len());
            assert_eq!(s.n_faces(), 4 * m.n_faces());
            assert_eq!(&s.vertices()[..m.n_vertices()], m.vertices());
            let (a, b) = (m.total_area(), s.total_area());
            assert!((a - b).abs() <= 1e-12 * a, "{a} vs {b}");
            assert_eq!(s.components().0, 1);
            m = s;
        }
        assert_eq!(m.n_vertices(), icosphere(5).n_vertices());
        // A mesh with a boundary: the rectangle's area and corners are kept.
        let r = rectangle(2.0, 1.0, 3, 2);
        let s = midpoint_subdivision(&r).unwrap();
        assert!((s.total_area() - 2.0).abs() < 1e-12);
        assert_eq!(s.n_vertices(), r.n_vertices() + r.edges().len());
    }

    #[test]
    fn rectangle_area() {
        let r = rectangle(2.0, 1.0, 10, 5);
        assert_eq!(r.n_vertices(), 66);
        assert!((r.total_area() - 2.0).abs() < 1e-13);
        assert_eq!(r.boundary_loops().len(), 1);
        assert_eq!(r.boundary_loops()[0].len(), 30);
    }
}
