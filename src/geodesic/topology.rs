//! Edge–face incidence of a triangle mesh for window propagation: every undirected edge with
//! its length and the list of its faces (any number: boundary edges have one, non-manifold
//! edges three or more), the faces with their vertices and edges, and per vertex whether a
//! shortest path may pass through it (saddle, boundary or non-manifold vertex).

use crate::error::{Error, Result};
use crate::shape::TriMesh;

/// Mesh connectivity used by the exact solver. Faces are the non-degenerate faces of the input,
/// renumbered 0..; lengths are computed from the 3D positions once.
pub(crate) struct Topology {
    /// Number of vertices.
    pub n: usize,
    /// Edge endpoints, `ev[e][0] < ev[e][1]`: the edge's local frame has its origin at `ev[e][0]`.
    pub ev: Vec<[u32; 2]>,
    /// Edge lengths.
    pub elen: Vec<f64>,
    /// Faces of edge e: `ef[ef_start[e]..ef_start[e + 1]]`.
    pub ef_start: Vec<u32>,
    pub ef: Vec<u32>,
    /// Face vertices.
    pub fv: Vec<[u32; 3]>,
    /// `fe[f][k]`: the edge of face f opposite its corner k.
    pub fe: Vec<[u32; 3]>,
    /// `fc[f][k]`: corner k of face f in the local frame of edge `fe[f][k]`: (x, |y|).
    pub fc: Vec<[[f64; 2]; 3]>,
    /// Faces around vertex v: `vf[vf_start[v]..vf_start[v + 1]]`.
    pub vf_start: Vec<u32>,
    pub vf: Vec<u32>,
    /// Whether geodesics can bend at the vertex: total angle ≥ 2π (up to a tolerance), a
    /// boundary vertex, or a non-manifold one.
    pub bend: Vec<bool>,
    /// Input faces skipped as degenerate (zero area or repeated vertex).
    pub skipped: Vec<usize>,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Position (x, y ≥ 0) of the point at distances `l0` from (0, 0) and `l1` from (len, 0).
pub(crate) fn place(len: f64, l0: f64, l1: f64) -> [f64; 2] {
    let x = (len * len + l0 * l0 - l1 * l1) / (2.0 * len);
    [x, (l0 * l0 - x * x).max(0.0).sqrt()]
}

/// The edges of `faces` as records (min vertex, max vertex, face, corner k opposite the edge),
/// three per face, sorted: the records of one undirected edge are adjacent, its faces ascending.
pub(crate) fn edge_records(faces: &[[u32; 3]]) -> Vec<(u32, u32, u32, u8)> {
    let mut rec: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(faces.len() * 3);
    for (f, t) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            rec.push((a.min(b), a.max(b), f as u32, k as u8));
        }
    }
    rec.sort_unstable();
    rec
}

/// Tolerance on the total angle for calling a vertex flat rather than a saddle: vertices with
/// total angle ≥ 2π − `FLAT_TOL` are treated as possible bend points (conservative; exact flat
/// vertices do not need it, but it is harmless and protects collinear configurations).
const FLAT_TOL: f64 = 1e-6;

impl Topology {
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        let n = mesh.n_vertices();
        if mesh.n_faces() >= (u32::MAX / 3) as usize {
            return Err(Error::invalid("mesh", "too many faces for the geodesic solver (≥ 2³²/3)"));
        }
        let p = mesh.vertices();
        let (lo, hi) = mesh.bounding_box();
        let diag2 = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>();
        let mut fv = Vec::with_capacity(mesh.n_faces());
        let mut skipped = Vec::new();
        for (f, t) in mesh.faces().iter().enumerate() {
            let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let x = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let area = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            let repeated = t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
            if repeated || area <= crate::shape::DEGENERATE_REL_AREA * diag2 || !area.is_finite() {
                skipped.push(f);
            } else {
                fv.push(*t);
            }
        }
        let rec = edge_records(&fv);
        let mut ev = Vec::new();
        let mut ef_start = vec![0u32];
        let mut ef = Vec::with_capacity(rec.len());
        let mut fe = vec![[0u32; 3]; fv.len()];
        for (i, r) in rec.iter().enumerate() {
            if i == 0 || (rec[i - 1].0, rec[i - 1].1) != (r.0, r.1) {
                if i > 0 {
                    ef_start.push(ef.len() as u32);
                }
                ev.push([r.0, r.1]);
            }
            fe[r.2 as usize][r.3 as usize] = (ev.len() - 1) as u32;
            ef.push(r.2);
        }
        if !rec.is_empty() {
            ef_start.push(ef.len() as u32);
        }
        let elen: Vec<f64> = ev.iter().map(|&[a, b]| dist(p[a as usize], p[b as usize])).collect();
        // Corner positions in the frames of their opposite edges.
        let fc: Vec<[[f64; 2]; 3]> = fv
            .iter()
            .zip(&fe)
            .map(|(t, es)| {
                let mut out = [[0.0; 2]; 3];
                for k in 0..3 {
                    let e = es[k] as usize;
                    let [a, b] = ev[e];
                    let c = p[t[k] as usize];
                    out[k] = place(elen[e], dist(p[a as usize], c), dist(p[b as usize], c));
                }
                out
            })
            .collect();
        // Vertex → faces.
        let mut vf_start = vec![0u32; n + 1];
        for t in &fv {
            for &v in t {
                vf_start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            vf_start[v + 1] += vf_start[v];
        }
        let mut fill = vf_start.clone();
        let mut vf = vec![0u32; fv.len() * 3];
        for (f, t) in fv.iter().enumerate() {
            for &v in t {
                vf[fill[v as usize] as usize] = f as u32;
                fill[v as usize] += 1;
            }
        }
        // Total angles, boundary / non-manifold edges, and fans per vertex.
        let mut angle = vec![0.0f64; n];
        for (f, t) in fv.iter().enumerate() {
            for k in 0..3 {
                // Corner k: law of cosines with the opposite edge and the two adjacent ones.
                let a = elen[fe[f][k] as usize];
                let b = elen[fe[f][(k + 1) % 3] as usize];
                let c = elen[fe[f][(k + 2) % 3] as usize];
                let cos = ((b * b + c * c - a * a) / (2.0 * b * c)).clamp(-1.0, 1.0);
                angle[t[k] as usize] += cos.acos();
            }
        }
        let mut bend: Vec<bool> = angle.iter().map(|&a| a >= 2.0 * std::f64::consts::PI - FLAT_TOL).collect();
        for e in 0..ev.len() {
            let count = ef_start[e + 1] - ef_start[e];
            if count != 2 {
                bend[ev[e][0] as usize] = true;
                bend[ev[e][1] as usize] = true;
            }
        }
        // Several fans (faces around v not connected through edges at v): e.g. two cones
        // touching at their apex. Local union-find over the faces of v.
        let mut local: Vec<u32> = Vec::new();
        for v in 0..n {
            let faces = &vf[vf_start[v] as usize..vf_start[v + 1] as usize];
            if bend[v] || faces.is_empty() {
                continue;
            }
            local.clear();
            local.extend(0..faces.len() as u32);
            fn root(l: &mut [u32], mut i: u32) -> u32 {
                while l[i as usize] != i {
                    i = l[i as usize];
                }
                i
            }
            // Two faces of v share an edge at v iff they share a vertex other than v.
            for i in 0..faces.len() {
                for j in i + 1..faces.len() {
                    let (ti, tj) = (fv[faces[i] as usize], fv[faces[j] as usize]);
                    if ti.iter().any(|&a| a as usize != v && tj.contains(&a)) {
                        let (ri, rj) = (root(&mut local, i as u32), root(&mut local, j as u32));
                        local[ri.max(rj) as usize] = ri.min(rj);
                    }
                }
            }
            let fans = (0..faces.len() as u32).filter(|&i| root(&mut local, i) == i).count();
            if fans > 1 {
                bend[v] = true;
            }
        }
        Ok(Topology { n, ev, elen, ef_start, ef, fv, fe, fc, vf_start, vf, bend, skipped })
    }

    /// Faces of edge e.
    pub fn edge_faces(&self, e: usize) -> &[u32] {
        &self.ef[self.ef_start[e] as usize..self.ef_start[e + 1] as usize]
    }

    /// Faces around vertex v.
    pub fn vertex_faces(&self, v: usize) -> &[u32] {
        &self.vf[self.vf_start[v] as usize..self.vf_start[v + 1] as usize]
    }

    /// Local index k of edge e in face f (`fe[f][k] == e`).
    pub fn local_edge(&self, f: usize, e: u32) -> usize {
        let es = self.fe[f];
        if es[0] == e {
            0
        } else if es[1] == e {
            1
        } else {
            2
        }
    }
}
