//! The intrinsic Delaunay triangulation of a mesh's surface (Bobenko & Springborn 2007; Fisher,
//! Springborn, Bobenko, Schröder 2007), built by intrinsic edge flips.
//!
//! The surface is kept as it is (a piecewise-flat metric given by edge lengths) while its
//! triangulation changes: an interior edge whose two opposite angles sum to more than π is
//! replaced by the other diagonal of its two triangles, the new length measured in their planar
//! unfolding. When no such edge remains the triangulation is intrinsically Delaunay and every
//! cotangent weight ½(cot α + cot β) is ≥ 0, so the cotangent Laplacian is an M-matrix: the heat
//! step of [`super::HeatGeodesics`] then has a positive solution, as heat must be. On a mesh
//! that is already Delaunay nothing changes.
//!
//! Vertices are those of the mesh; edges may come to join the same pair of vertices twice (an
//! intrinsic triangulation need not be a simplicial complex), so edges are identified by index,
//! never by their endpoints. Boundary and non-manifold edges are never flipped.
//!
//! Besides the heat method, [`intrinsic_delaunay_laplacian`] gives the cotangent Laplacian of
//! this triangulation as a Laplacian of its own (`LaplacianChoice::Intrinsic`, `--laplacian
//! intrinsic`): for meshes with obtuse or sliver triangles, where the ordinary cotangent weights
//! go negative.

use super::topology::{edge_records, place};
use crate::error::Result;
use crate::laplacian::{cotangent_from_lengths, heron, mollified_lengths, Laplacian, LaplacianKind};
use crate::shape::TriMesh;

/// Sum of the cotangents of the two angles opposite an edge below which it is flipped. Zero in
/// exact arithmetic; the margin stops flips back and forth between the two diagonals of a
/// (nearly) cyclic quadrilateral.
const DELAUNAY_TOL: f64 = 1e-10;

/// Upper bound on the number of flips, as a multiple of the number of edges. The flip algorithm
/// terminates in exact arithmetic; the bound only guards against rounding cycles and is far
/// above the counts measured (0.3 flips per edge on TOSCA `cat0`).
const MAX_FLIPS_PER_EDGE: usize = 50;

/// An intrinsic triangulation of a mesh's vertices: triangles, their edges and edge lengths (in
/// the mesh's units).
pub(crate) struct IntrinsicTriangulation {
    /// Number of vertices n (those of the mesh).
    pub n: usize,
    /// Vertices of every triangle.
    pub faces: Vec<[u32; 3]>,
    /// `fe[f][c]`: the edge of triangle f opposite its corner c.
    fe: Vec<[u32; 3]>,
    /// Length of every edge.
    len: Vec<f64>,
    /// The two triangles of every interior manifold edge; `None` for boundary and non-manifold
    /// edges (never flipped).
    ef: Vec<Option<[u32; 2]>>,
    /// Number of flips performed.
    pub flips: usize,
}

/// Cotangent of the angle at corner c of a triangle with edge lengths `l` (opposite corners 0,
/// 1, 2): (b² + c² − a²) / (4 area).
fn cot(l: [f64; 3], c: usize) -> f64 {
    let area = heron(l);
    let (a, b, cc) = (l[c], l[(c + 1) % 3], l[(c + 2) % 3]);
    if area > 0.0 {
        (b * b + cc * cc - a * a) / (4.0 * area)
    } else {
        0.0
    }
}

impl IntrinsicTriangulation {
    /// The mesh's own triangulation (triangles with a repeated vertex skipped, lengths mollified
    /// as for [`crate::laplacian::cotangent`]), not yet flipped.
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        let (kept, lengths) = mollified_lengths(mesh)?;
        let faces: Vec<[u32; 3]> = kept.iter().map(|&f| mesh.faces()[f]).collect();
        // Edges: sorted (min, max, face, corner) records; equal endpoints = one edge.
        let rec = edge_records(&faces);
        let mut fe = vec![[0u32; 3]; faces.len()];
        let mut len = Vec::new();
        let mut ef = Vec::new();
        let mut i = 0;
        while i < rec.len() {
            let mut j = i;
            while j < rec.len() && (rec[j].0, rec[j].1) == (rec[i].0, rec[i].1) {
                j += 1;
            }
            let e = len.len() as u32;
            for r in &rec[i..j] {
                fe[r.2 as usize][r.3 as usize] = e;
            }
            len.push(lengths[rec[i].2 as usize][rec[i].3 as usize]);
            ef.push(if j - i == 2 { Some([rec[i].2, rec[i + 1].2]) } else { None });
            i = j;
        }
        Ok(IntrinsicTriangulation { n: mesh.n_vertices(), faces, fe, len, ef, flips: 0 })
    }

    /// The intrinsic Delaunay triangulation of `mesh`: [`Self::new`], then flips until every
    /// interior edge is Delaunay (up to [`DELAUNAY_TOL`]).
    pub fn delaunay(mesh: &TriMesh) -> Result<Self> {
        let mut t = Self::new(mesh)?;
        t.flip_to_delaunay();
        Ok(t)
    }

    /// Number of edges.
    pub fn n_edges(&self) -> usize {
        self.len.len()
    }

    /// Edge lengths of triangle f, opposite its corners 0, 1, 2.
    pub fn lengths(&self, f: usize) -> [f64; 3] {
        let e = self.fe[f];
        [self.len[e[0] as usize], self.len[e[1] as usize], self.len[e[2] as usize]]
    }

    #[cfg(test)]
    /// Interior edges whose cotangent weight ½(cot α + cot β) is below −[`DELAUNAY_TOL`].
    pub fn non_delaunay_edges(&self) -> usize {
        (0..self.n_edges()).filter(|&e| self.cot_sum(e).is_some_and(|s| s < -DELAUNAY_TOL)).count()
    }

    /// Corner of triangle f opposite edge e, if e occurs exactly once in f.
    fn corner_of(&self, f: usize, e: u32) -> Option<usize> {
        let es = self.fe[f];
        let mut found = None;
        for c in 0..3 {
            if es[c] == e {
                if found.is_some() {
                    return None;
                }
                found = Some(c);
            }
        }
        found
    }

    /// cot α + cot β of interior edge e (α, β the angles opposite it); `None` for a fixed edge.
    fn cot_sum(&self, e: usize) -> Option<f64> {
        let [f1, f2] = self.ef[e]?;
        let c1 = self.corner_of(f1 as usize, e as u32)?;
        let c2 = self.corner_of(f2 as usize, e as u32)?;
        Some(cot(self.lengths(f1 as usize), c1) + cot(self.lengths(f2 as usize), c2))
    }

    /// Flips non-Delaunay edges (a stack of candidates, initially all edges in order) until none
    /// is left or the flip budget is spent. Deterministic: the order depends on the input alone.
    fn flip_to_delaunay(&mut self) {
        let m = self.n_edges();
        let mut stack: Vec<u32> = (0..m as u32).rev().collect();
        let mut queued = vec![true; m];
        let budget = MAX_FLIPS_PER_EDGE * m;
        while let Some(e) = stack.pop() {
            queued[e as usize] = false;
            if !self.cot_sum(e as usize).is_some_and(|s| s < -DELAUNAY_TOL) {
                continue;
            }
            if let Some(outer) = self.flip(e) {
                self.flips += 1;
                if self.flips >= budget {
                    break;
                }
                for o in outer {
                    if !queued[o as usize] {
                        queued[o as usize] = true;
                        stack.push(o);
                    }
                }
            }
        }
    }

    /// Replaces interior edge e = (i, j), between triangles (i, j, k) and (j, i, l), by the edge
    /// (k, l). Returns the four outer edges of the quadrilateral, or `None` (nothing changed) when
    /// the flip is impossible: k = l, a triangle meeting e twice, or a quadrilateral that is not
    /// strictly convex in its unfolding.
    fn flip(&mut self, e: u32) -> Option<[u32; 4]> {
        let [f1, f2] = self.ef[e as usize]?;
        let (f1, f2) = (f1 as usize, f2 as usize);
        if f1 == f2 {
            return None;
        }
        let c1 = self.corner_of(f1, e)?;
        let c2 = self.corner_of(f2, e)?;
        let (k, i, j) = (self.faces[f1][c1], self.faces[f1][(c1 + 1) % 3], self.faces[f1][(c1 + 2) % 3]);
        let l = self.faces[f2][c2];
        if k == l {
            return None;
        }
        // Edges of f1: opposite j is (i, k), opposite i is (j, k).
        let (e_ik, e_jk) = (self.fe[f1][(c1 + 2) % 3], self.fe[f1][(c1 + 1) % 3]);
        // Edges of f2, whichever way round it lists i and j.
        let (p, q) = ((c2 + 1) % 3, (c2 + 2) % 3);
        let (e_il, e_jl) = if self.faces[f2][p] == i && self.faces[f2][q] == j {
            (self.fe[f2][q], self.fe[f2][p])
        } else if self.faces[f2][p] == j && self.faces[f2][q] == i {
            (self.fe[f2][p], self.fe[f2][q])
        } else {
            return None;
        };
        if [e_ik, e_jk, e_il, e_jl]
            .iter()
            .enumerate()
            .any(|(a, &x)| x == e || [e_ik, e_jk, e_il, e_jl][..a].contains(&x))
        {
            return None;
        }
        // Unfold: i = (0, 0), j = (L, 0), k above, l below.
        let big_l = self.len[e as usize];
        let pk = place(big_l, self.len[e_ik as usize], self.len[e_jk as usize]);
        let pl = place(big_l, self.len[e_il as usize], self.len[e_jl as usize]);
        let pl = [pl[0], -pl[1]];
        if pk[1] <= 0.0 || pl[1] >= 0.0 {
            return None;
        }
        // Strictly convex: segment k–l crosses the line of e strictly between i and j.
        let x = pk[0] + (pl[0] - pk[0]) * pk[1] / (pk[1] - pl[1]);
        let margin = 1e-9 * big_l;
        if !(x > margin && x < big_l - margin) {
            return None;
        }
        let new_len = ((pk[0] - pl[0]).powi(2) + (pk[1] - pl[1]).powi(2)).sqrt();
        let (t1, t2) = (
            [self.len[e_il as usize], self.len[e_ik as usize], new_len],
            [self.len[e_jk as usize], self.len[e_jl as usize], new_len],
        );
        if !(heron(t1) > 0.0 && heron(t2) > 0.0) {
            return None;
        }
        // f1 = (k, l, i): opposite k is (i, l), opposite l is (i, k), opposite i is e.
        // f2 = (l, k, j): opposite l is (j, k), opposite k is (j, l), opposite j is e.
        self.faces[f1] = [k, l, i];
        self.fe[f1] = [e_il, e_ik, e];
        self.faces[f2] = [l, k, j];
        self.fe[f2] = [e_jk, e_jl, e];
        self.len[e as usize] = new_len;
        let replace = |ef: &mut Option<[u32; 2]>, from: usize, to: usize| {
            if let Some(pair) = ef {
                for x in pair.iter_mut() {
                    if *x as usize == from {
                        *x = to as u32;
                        return;
                    }
                }
            }
        };
        replace(&mut self.ef[e_il as usize], f2, f1);
        replace(&mut self.ef[e_jk as usize], f1, f2);
        Some([e_ik, e_jk, e_il, e_jl])
    }

    /// The cotangent Laplacian of this triangulation (weights and barycentric masses from the
    /// intrinsic lengths). Errors: a vertex in no triangle.
    pub fn laplacian(&self) -> Result<Laplacian> {
        cotangent_from_lengths(self.n, (0..self.faces.len()).map(|f| (self.faces[f], self.lengths(f))))
    }

    /// Triangle f laid out in the plane: corner 0 at (0, 0), corner 1 at (l₂, 0), corner 2 above
    /// the x-axis (so the corners run counter-clockwise).
    pub fn layout(&self, f: usize) -> [[f64; 2]; 3] {
        let l = self.lengths(f);
        [[0.0, 0.0], [l[2], 0.0], place(l[2], l[1], l[0])]
    }
}

/// The intrinsic Delaunay Laplacian of a mesh (Bobenko & Springborn 2007): the cotangent
/// Laplacian (weights ½(cot α + cot β), barycentric lumped mass) of the mesh's intrinsic
/// Delaunay triangulation, the same surface re-triangulated by intrinsic edge flips. Every
/// weight of an interior edge is ≥ 0 (a maximum principle holds), the total mass is the mesh's
/// area, and on a mesh that is already Delaunay it equals [`crate::laplacian::cotangent`]
/// exactly. Degenerate triangles are mollified as there. Kind
/// [`LaplacianKind::IntrinsicDelaunay`].
///
/// Errors: those of [`crate::laplacian::cotangent`] (no triangle with area, vertices in no
/// triangle).
pub fn intrinsic_delaunay_laplacian(mesh: &TriMesh) -> Result<Laplacian> {
    let mut lap = IntrinsicTriangulation::delaunay(mesh)?.laplacian()?;
    lap.kind = LaplacianKind::IntrinsicDelaunay;
    Ok(lap)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::{icosphere, rectangle, sheared_grid};

    /// W as sorted (row, column, value) triplets.
    fn triplets(lap: &Laplacian) -> Vec<(usize, usize, f64)> {
        let w = lap.w.as_ref();
        let (cp, ri, val) = (w.symbolic().col_ptr(), w.symbolic().row_idx(), w.val());
        let mut t: Vec<(usize, usize, f64)> =
            (0..lap.n()).flat_map(|c| (cp[c]..cp[c + 1]).map(move |p| (ri[p], c, val[p]))).collect();
        t.sort_by_key(|a| (a.0, a.1));
        t
    }

    #[test]
    fn the_intrinsic_laplacian_is_the_cotangent_one_on_delaunay_meshes() {
        for mesh in [icosphere(3), rectangle(2.0, 1.0, 10, 7)] {
            let (a, b) = (intrinsic_delaunay_laplacian(&mesh).unwrap(), crate::laplacian::cotangent(&mesh).unwrap());
            assert_eq!(a.kind, LaplacianKind::IntrinsicDelaunay);
            assert_eq!(a.mass, b.mass);
            assert_eq!(triplets(&a), triplets(&b));
        }
    }

    #[test]
    fn the_intrinsic_laplacian_of_obtuse_triangles_is_that_of_the_delaunay_mesh() {
        // Every triangle of the sheared grid is obtuse (cells cut along their long diagonal):
        // the cotangent Laplacian has negative weights. The same parallelogram cut along the
        // short diagonals is Delaunay (acute triangles); the intrinsic Laplacian of the first
        // is the cotangent Laplacian of the second.
        let (nx, ny, s) = (12u32, 8u32, 0.8);
        let obtuse = sheared_grid(nx, ny, s);
        let cot = crate::laplacian::cotangent(&obtuse).unwrap();
        assert!(triplets(&cot).iter().any(|&(i, j, v)| i != j && v > 1e-3), "negative weights expected");
        let lap = intrinsic_delaunay_laplacian(&obtuse).unwrap();
        assert!(triplets(&lap).iter().all(|&(i, j, v)| i == j || v <= 1e-12));
        let id = |i: u32, j: u32| j * (nx + 1) + i;
        let mut f = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                f.extend([[id(i, j), id(i + 1, j), id(i, j + 1)], [id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]]);
            }
        }
        let delaunay = TriMesh::new(obtuse.vertices().to_vec(), f).unwrap();
        let reference = crate::laplacian::cotangent(&delaunay).unwrap();
        let (a, b) = (triplets(&lap), triplets(&reference));
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!((x.0, x.1), (y.0, y.1));
            assert!((x.2 - y.2).abs() < 1e-12, "{x:?} vs {y:?}");
        }
        for (x, y) in lap.mass.iter().zip(&reference.mass) {
            assert!((x - y).abs() < 1e-12);
        }
    }

    #[test]
    fn delaunay_meshes_are_left_alone() {
        for mesh in [icosphere(3), rectangle(2.0, 1.0, 10, 7)] {
            let t = IntrinsicTriangulation::delaunay(&mesh).unwrap();
            assert_eq!(t.flips, 0);
            let (a, b) = (t.laplacian().unwrap(), crate::laplacian::cotangent(&mesh).unwrap());
            assert_eq!(a.mass, b.mass);
            assert_eq!(a.w.val(), b.w.val());
        }
    }

    #[test]
    fn flips_remove_negative_weights_and_keep_the_area() {
        let mesh = sheared_grid(12, 8, 0.8);
        let t0 = IntrinsicTriangulation::new(&mesh).unwrap();
        assert!(t0.non_delaunay_edges() > 50, "{}", t0.non_delaunay_edges());
        let t = IntrinsicTriangulation::delaunay(&mesh).unwrap();
        assert!(t.flips > 0);
        assert_eq!(t.non_delaunay_edges(), 0);
        assert_eq!(t.n_edges(), t0.n_edges());
        let lap = t.laplacian().unwrap();
        let area: f64 = lap.mass.iter().sum();
        assert!((area - 12.0 * 8.0).abs() < 1e-9, "{area}");
        // Off-diagonal weights are all ≥ 0 (entries of W ≤ 0 off the diagonal).
        let w = lap.w.as_ref();
        let (cp, ri, val) = (w.symbolic().col_ptr(), w.symbolic().row_idx(), w.val());
        for c in 0..lap.n() {
            for p in cp[c]..cp[c + 1] {
                if ri[p] != c {
                    assert!(val[p] <= 1e-9, "W[{}, {c}] = {}", ri[p], val[p]);
                }
            }
        }
        // The flipped diagonals of a planar grid are the short ones, of length √((1 − s)² + 1).
        let short = (0.2f64 * 0.2 + 1.0).sqrt();
        assert!(t.len.iter().any(|&l| (l - short).abs() < 1e-12));
    }
}
