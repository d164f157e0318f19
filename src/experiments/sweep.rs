//! The sweeps of Figures 5 and 6 on the sterile setting ([`Sterile`]): the soft error (13) of
//! every method as the rank k (Figure 5) or the L1 weight μ3 (Figure 6) varies, one typed
//! [`SweepRow`] per point. The rows are the data; [`crate::viz::plot::sweep_plot`] draws them.

use std::time::Instant;

use serde::Serialize;

use super::Sterile;
use crate::completion::{CompletionOptions, Form, Scaling};
use crate::error::{Error, Result};
use crate::fmap::PokrassOptions;

/// What a sweep varies, and the fixed value of the other parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum Sweep {
    /// Figure 5: the ranks k (each in 1..=k'), with the L1 weight μ3 fixed.
    Rank {
        /// The ranks k.
        ks: Vec<usize>,
        /// The L1 weight μ3 (the paper's 1e-1).
        mu3: f64,
    },
    /// Figure 6: the L1 weights μ3 (finite, ≥ 0), at the rank k.
    L1 {
        /// The weights μ3.
        mu3s: Vec<f64>,
        /// The rank k (the paper's 45).
        k: usize,
    },
}

impl Sweep {
    /// `"rank"` (Figure 5) or `"l1"` (Figure 6): the stem of the output files.
    pub fn name(&self) -> &'static str {
        match self {
            Sweep::Rank { .. } => "rank",
            Sweep::L1 { .. } => "l1",
        }
    }

    /// The paper's μ1 = μ2 for the figure: 1e-8 (Figure 5) or 1e-4 (Figure 6).
    pub fn paper_mu1(&self) -> f64 {
        match self {
            Sweep::Rank { .. } => 1e-8,
            Sweep::L1 { .. } => 1e-4,
        }
    }
}

/// A method of the sweeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepMethod {
    /// The ground-truth functional map C0 (k × k), the reference line.
    GroundTruth,
    /// Eq. (5), Ovsjanikov et al.
    Ovsjanikov,
    /// Eq. (6), Pokrass et al.
    Pokrass,
    /// The completion method (11), subspace form, fixed-rank regime (μ4 = 0).
    Completion,
}

impl SweepMethod {
    /// The name in tables and files (`ground-truth`, `ovsjanikov`, `pokrass`, `completion`).
    pub fn as_str(self) -> &'static str {
        match self {
            SweepMethod::GroundTruth => "ground-truth",
            SweepMethod::Ovsjanikov => "ovsjanikov",
            SweepMethod::Pokrass => "pokrass",
            SweepMethod::Completion => "completion",
        }
    }
}

impl std::fmt::Display for SweepMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One point of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepRow {
    /// The method.
    pub method: SweepMethod,
    /// The swept value: k (Figure 5) or μ3 (Figure 6).
    pub parameter: f64,
    /// The rank k.
    pub k: usize,
    /// μ3 of the completion method (None for the other methods).
    pub mu3: Option<f64>,
    /// Mean soft error (13) over the scored template points (units of √area(Y)).
    pub mean_soft_error: f64,
    /// Seconds of the method (without the soft error).
    pub seconds: f64,
    /// Iterations of the completion optimizer.
    pub iterations: Option<u64>,
    /// Pokrass et al.: fraction of data columns the permutation matched correctly.
    pub permutation_correct: Option<f64>,
}

/// The fixed settings of a sweep (besides the sterile pair itself).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepSettings {
    /// Subspace size k' of the completion method (≤ the bases' size).
    pub kprime: usize,
    /// Weight normalization of the completion method.
    pub scaling: Scaling,
    /// μ1 (None: the paper's value for the figure, [`Sweep::paper_mu1`]).
    pub mu1: Option<f64>,
    /// μ2 (None: the paper's value for the figure, = μ1).
    pub mu2: Option<f64>,
    /// ξ of the smoothed absolute value.
    pub xi: f64,
    /// Isometry prior added to (11) (0: the paper's pure form).
    pub completion_commutativity: f64,
    /// Iteration cap of the completion optimizer.
    pub max_iterations: usize,
    /// Size of the eq. (5) map starting the completion method (capped at q by the caller).
    pub init_k: usize,
    /// Weight μ of the off-diagonal L1 prior of Pokrass et al.
    pub pokrass_mu: f64,
}

impl SweepSettings {
    /// The completion method's options at rank k and L1 weight μ3: subspace form, μ4 = 0,
    /// μ1 = μ2 = `mu1` unless set. Errors: weights the completion method rejects.
    pub fn completion_options(&self, k: usize, mu1: f64, mu3: f64) -> Result<CompletionOptions> {
        let mut o = CompletionOptions::paper(false, self.scaling);
        (o.form, o.k_prime, o.k) = (Form::Subspace, self.kprime, k);
        let p = &mut o.params;
        p.mu1 = self.mu1.unwrap_or(mu1);
        p.mu2 = self.mu2.unwrap_or(mu1);
        (p.mu3, p.mu4, p.xi, p.mu_comm) = (mu3, 0.0, self.xi, self.completion_commutativity);
        o.optimize.max_iterations = self.max_iterations;
        p.validate()?;
        Ok(o)
    }
}

/// The (method, k, μ3) of every point of `sweep`, in the order they run. Errors (naming `ks`,
/// `k` or `mu3s`): a rank outside 1..=`kprime`, a μ3 that is not finite or negative.
pub fn sweep_jobs(sweep: &Sweep, kprime: usize) -> Result<Vec<(SweepMethod, usize, f64)>> {
    use SweepMethod as M;
    let mut jobs = Vec::new();
    match sweep {
        Sweep::Rank { ks, mu3 } => {
            for &k in ks {
                if k == 0 || k > kprime {
                    return Err(Error::invalid("ks", format!("rank {k} must be in 1..={kprime}")));
                }
                jobs.extend([(M::GroundTruth, k, 0.0), (M::Ovsjanikov, k, 0.0), (M::Pokrass, k, 0.0)]);
                jobs.push((M::Completion, k, *mu3));
            }
        }
        &Sweep::L1 { ref mu3s, k } => {
            if k == 0 || k > kprime {
                return Err(Error::invalid("k", format!("rank {k} must be in 1..={kprime}")));
            }
            jobs.extend([(M::GroundTruth, k, 0.0), (M::Ovsjanikov, k, 0.0), (M::Pokrass, k, 0.0)]);
            for &m in mu3s {
                if !(m.is_finite() && m >= 0.0) {
                    return Err(Error::invalid("mu3s", format!("{m}: must be finite and ≥ 0")));
                }
                jobs.push((M::Completion, k, m));
            }
        }
    }
    Ok(jobs)
}

/// Runs `sweep` on the sterile pair `setup`: every job of [`sweep_jobs`], scored by the mean soft
/// error (13); `on_row` sees each row as it is done (for progress). The rows in job order.
pub fn run_sweep(
    setup: &Sterile,
    sweep: &Sweep,
    settings: &SweepSettings,
    on_row: &mut dyn FnMut(&SweepRow),
) -> Result<Vec<SweepRow>> {
    let jobs = sweep_jobs(sweep, settings.kprime)?;
    let q = setup.f.q();
    let mut rows = Vec::with_capacity(jobs.len());
    for (method, k, mu3) in jobs {
        let t = Instant::now();
        let (mut iterations, mut permutation_correct) = (None, None);
        let c = match method {
            SweepMethod::GroundTruth => setup.ground_truth(k)?,
            SweepMethod::Ovsjanikov => setup.ovsjanikov(k)?,
            SweepMethod::Pokrass => {
                let (c, right) = setup.pokrass(k, &PokrassOptions { mu: settings.pokrass_mu, ..Default::default() })?;
                permutation_correct = Some(right);
                c
            }
            SweepMethod::Completion => {
                let opts = settings.completion_options(k, sweep.paper_mu1(), mu3)?;
                let (c, report) = setup.completion(&opts, settings.init_k.min(q))?;
                iterations = Some(report.iterations() as u64);
                c
            }
        };
        let seconds = t.elapsed().as_secs_f64();
        let mean_soft_error = setup.mean_soft_error(c.as_ref())?;
        let parameter = if matches!(sweep, Sweep::Rank { .. }) { k as f64 } else { mu3 };
        let mu3 = (method == SweepMethod::Completion).then_some(mu3);
        let row = SweepRow { method, parameter, k, mu3, mean_soft_error, seconds, iterations, permutation_correct };
        on_row(&row);
        rows.push(row);
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jobs_follow_the_figures_and_bad_sweeps_name_the_parameter() {
        use SweepMethod as M;
        let rank = Sweep::Rank { ks: vec![10, 20], mu3: 0.1 };
        let jobs = sweep_jobs(&rank, 50).unwrap();
        assert_eq!(jobs.len(), 8);
        assert_eq!(
            jobs[..4],
            [(M::GroundTruth, 10, 0.0), (M::Ovsjanikov, 10, 0.0), (M::Pokrass, 10, 0.0), (M::Completion, 10, 0.1)]
        );
        let l1 = Sweep::L1 { mu3s: vec![0.0, 1e-2], k: 45 };
        let jobs = sweep_jobs(&l1, 50).unwrap();
        assert_eq!(jobs.iter().filter(|j| j.0 == M::Completion).map(|j| j.2).collect::<Vec<_>>(), [0.0, 1e-2]);
        assert_eq!((rank.name(), l1.name(), rank.paper_mu1(), l1.paper_mu1()), ("rank", "l1", 1e-8, 1e-4));
        for (sweep, parameter) in [
            (Sweep::Rank { ks: vec![0], mu3: 0.1 }, "ks"),
            (Sweep::Rank { ks: vec![51], mu3: 0.1 }, "ks"),
            (Sweep::L1 { mu3s: vec![0.0], k: 0 }, "k"),
            (Sweep::L1 { mu3s: vec![-1.0], k: 5 }, "mu3s"),
            (Sweep::L1 { mu3s: vec![f64::NAN], k: 5 }, "mu3s"),
        ] {
            match sweep_jobs(&sweep, 50).unwrap_err() {
                Error::Invalid { what, .. } => assert_eq!(what, parameter),
                e => panic!("{e}"),
            }
        }
        // Method names as in the files.
        assert_eq!(serde_json::to_string(&M::GroundTruth).unwrap(), "\"ground-truth\"");
        assert_eq!(M::Completion.to_string(), "completion");
    }
}
