//! A tiny seeded random number generator shared by every randomized step (eigensolver start
//! vectors, surface sampling, stochastic estimates), so results are deterministic across
//! platforms and crate versions.

/// SplitMix64 + Box–Muller normal samples. A tiny generator of our own keeps the start vectors
/// (and hence the eigenvector signs before normalization) identical across platforms and crate
/// versions, which a seeded `rand` does not promise.
pub(crate) struct Normal(u64);

impl Normal {
    pub(crate) fn new(seed: u64) -> Self {
        Normal(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    /// A uniform sample in (0, 1).
    pub(crate) fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub(crate) fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}
