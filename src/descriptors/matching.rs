//! Matching regions (segments, MSER regions) of two shapes, so that region indicators can serve as
//! corresponding data F, G on shapes nobody annotated.
//!
//! Each region R gets a signature: the area-weighted mean over R of a per-vertex descriptor D
//! (e.g. scale-normalized HKS and WKS), followed by its relative area |R| / |shape| weighted by
//! `area_weight`. Features are standardized over all regions of both shapes (zero mean, unit
//! variance per feature), the cost of a pair is the Euclidean distance of the signatures, and
//! an optimal one-to-one assignment minimizing the total cost is found with the Hungarian method
//! (`pathfinding`'s Kuhn–Munkres).

use pathfinding::kuhn_munkres::kuhn_munkres_min;
use pathfinding::matrix::Matrix;

use super::Descriptors;
use crate::error::{Error, Result};

/// A region of X matched to a region of Y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionMatch {
    /// Column of the region indicator on X.
    pub x: usize,
    /// Column of the region indicator on Y.
    pub y: usize,
    /// Signature distance (standardized units).
    pub cost: f64,
}

/// Signatures of the regions (columns of `regions`, n × R, values in [0, 1]) of a shape with
/// vertex weights `mass` (n) and per-vertex descriptor `d` (n × q): R rows of q + 1 values.
pub fn region_signatures(
    regions: &Descriptors,
    mass: &[f64],
    d: &Descriptors,
    area_weight: f64,
) -> Result<Vec<Vec<f64>>> {
    let n = regions.n();
    if mass.len() != n || d.n() != n {
        return Err(Error::invalid(
            "regions",
            format!("{} region rows, {} vertex weights and {} descriptor rows do not agree", n, mass.len(), d.n()),
        ));
    }
    let total: f64 = mass.iter().sum();
    (0..regions.q())
        .map(|r| {
            let ind = regions.values.col_as_slice(r);
            let area: f64 = ind.iter().zip(mass).map(|(w, a)| w * a).sum();
            if area <= 0.0 {
                return Err(Error::invalid("regions", format!("region {} ({}) is empty", r, regions.names[r])));
            }
            let mut sig: Vec<f64> = (0..d.q())
                .map(|j| {
                    d.values.col_as_slice(j).iter().zip(ind).zip(mass).map(|((v, w), a)| v * w * a).sum::<f64>() / area
                })
                .collect();
            sig.push(area_weight * area / total);
            Ok(sig)
        })
        .collect()
}

/// Optimal one-to-one matching of the regions of X and Y (min(R_X, R_Y) pairs) by signature
/// distance. `dx` and `dy` must be the same descriptor computed on both shapes.
pub fn match_regions(
    rx: &Descriptors,
    mass_x: &[f64],
    dx: &Descriptors,
    ry: &Descriptors,
    mass_y: &[f64],
    dy: &Descriptors,
) -> Result<Vec<RegionMatch>> {
    if dx.q() != dy.q() {
        return Err(Error::invalid("descriptors", format!("{} functions on X but {} on Y", dx.q(), dy.q())));
    }
    if rx.q() == 0 || ry.q() == 0 {
        return Err(Error::invalid("regions", "both shapes need at least one region"));
    }
    let sx = region_signatures(rx, mass_x, dx, 1.0)?;
    let sy = region_signatures(ry, mass_y, dy, 1.0)?;
    // Standardize every feature over the regions of both shapes.
    let dim = sx[0].len();
    let all: Vec<&Vec<f64>> = sx.iter().chain(&sy).collect();
    let cnt = all.len() as f64;
    let mean: Vec<f64> = (0..dim).map(|f| all.iter().map(|s| s[f]).sum::<f64>() / cnt).collect();
    let sd: Vec<f64> =
        (0..dim).map(|f| (all.iter().map(|s| (s[f] - mean[f]).powi(2)).sum::<f64>() / cnt).sqrt().max(1e-12)).collect();
    let z = |s: &Vec<f64>| -> Vec<f64> { (0..dim).map(|f| (s[f] - mean[f]) / sd[f]).collect() };
    let (zx, zy): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (sx.iter().map(z).collect(), sy.iter().map(z).collect());
    let dist = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt();
    // Kuhn–Munkres needs integer weights and no more rows than columns.
    let swap = zx.len() > zy.len();
    let (rows, cols) = if swap { (&zy, &zx) } else { (&zx, &zy) };
    const SCALE: f64 = 1e9;
    let weights = Matrix::from_fn(rows.len(), cols.len(), |(i, j)| (dist(&rows[i], &cols[j]) * SCALE).round() as i64);
    let (_, assignment) = kuhn_munkres_min(&weights);
    let mut out: Vec<RegionMatch> = assignment
        .iter()
        .enumerate()
        .map(|(i, &j)| {
            let (x, y) = if swap { (j, i) } else { (i, j) };
            RegionMatch { x, y, cost: dist(&zx[x], &zy[y]) }
        })
        .collect();
    out.sort_by_key(|m| m.x);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::segments;
    use faer::Mat;

    #[test]
    fn recovers_a_permutation_of_regions() {
        // Six vertices, three regions of different sizes and descriptor values; Y lists them in
        // another order.
        let labels_x = [1, 1, 1, 2, 2, 3];
        let labels_y = [3, 3, 3, 1, 1, 2]; // Y's region 3 is X's region 1, etc.
        let d = |v: &[f64]| Descriptors::new(Mat::from_fn(6, 1, |i, _| v[i]), vec!["f".into()]).unwrap();
        let dx = d(&[1.0, 1.1, 0.9, 5.0, 5.2, 9.0]);
        let dy = d(&[1.0, 1.0, 1.0, 5.1, 5.1, 9.1]);
        let mass = [1.0; 6];
        let m = match_regions(&segments(&labels_x).unwrap(), &mass, &dx, &segments(&labels_y).unwrap(), &mass, &dy)
            .unwrap();
        let pairs: Vec<(usize, usize)> = m.iter().map(|r| (r.x, r.y)).collect();
        assert_eq!(pairs, vec![(0, 2), (1, 0), (2, 1)]);
        // More regions on X than on Y: every Y region is used once.
        let m = match_regions(
            &segments(&labels_x).unwrap(),
            &mass,
            &dx,
            &segments(&[1, 1, 1, 1, 1, 2]).unwrap(),
            &mass,
            &dy,
        )
        .unwrap();
        assert_eq!(m.len(), 2);
        let empty = Descriptors::new(Mat::zeros(6, 1), vec!["empty".into()]).unwrap();
        assert!(match_regions(&empty, &mass, &dx, &segments(&labels_y).unwrap(), &mass, &dy).is_err());
    }
}
