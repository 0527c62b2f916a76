//! Monte Carlo estimates of the discounted return, to check [`Evaluation`](crate::Evaluation)
//! against.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::{Mdp, TabularPolicy};

/// Samples `n_episodes` discounted returns of `policy` on `mdp`, `[n_episodes]`.
///
/// Each episode starts from `s_0 ∼ μ` and runs exactly `horizon` steps, returning
/// `Σ_{t<horizon} γ^t r(s_t, a_t, s_{t+1})`. Truncation changes every return by at most
/// [`truncation_bound`]`(mdp, horizon) = γ^horizon · max|r| / (1 − γ)`, so it shifts the
/// mean by at most that much and the standard deviation by at most that much too.
///
/// Deterministic given `seed` (one `StdRng::seed_from_u64(seed)` for all episodes; each step
/// draws the action, then the next state, each by inverting the CDF with one uniform).
///
/// # Panics
/// If the MDP or the policy is invalid or their shapes differ.
pub fn sample_returns(
    mdp: &Mdp,
    policy: &TabularPolicy,
    n_episodes: usize,
    horizon: usize,
    seed: u64,
) -> Vec<f64> {
    if let Err(e) = mdp.validate() {
        panic!("sample_returns: invalid MDP: {e}");
    }
    if let Err(e) = policy.validate() {
        panic!("sample_returns: invalid policy: {e}");
    }
    assert!(
        mdp.states == policy.states && mdp.actions == policy.actions,
        "sample_returns: policy is {}x{}, MDP is {}x{}",
        policy.states,
        policy.actions,
        mdp.states,
        mdp.actions
    );
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n_episodes)
        .map(|_| {
            let mut s = sample_index(&mdp.start, &mut rng);
            let mut ret = 0.0;
            let mut discount = 1.0;
            for _ in 0..horizon {
                let a = sample_index(policy.row(s), &mut rng);
                let s_next = sample_index(mdp.transition_row(s, a), &mut rng);
                ret += discount * mdp.r(s, a, s_next);
                discount *= mdp.gamma;
                s = s_next;
            }
            ret
        })
        .collect()
}

/// `γ^horizon · max|r| / (1 − γ)`: the largest possible difference between a full discounted
/// return and its truncation after `horizon` steps.
pub fn truncation_bound(mdp: &Mdp, horizon: usize) -> f64 {
    let h = i32::try_from(horizon).unwrap_or(i32::MAX);
    mdp.gamma.powi(h) * mdp.max_abs_reward() / (1.0 - mdp.gamma)
}

/// Sample mean and variance of i.i.d. samples, with their standard errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleStats {
    /// Number of samples `n`.
    pub n: usize,
    /// Sample mean `x̄`.
    pub mean: f64,
    /// Unbiased sample variance `s² = Σ (x − x̄)² / (n − 1)`.
    pub variance: f64,
    /// Standard error of the mean, `sqrt(s² / n)`.
    pub mean_stderr: f64,
    /// Asymptotic standard error of the sample variance, `sqrt((m₄ − m₂²) / n)` with `m_k` the
    /// central sample moments.
    pub variance_stderr: f64,
}

impl SampleStats {
    /// Statistics of `samples` (NaN fields when there are fewer than 2 samples).
    pub fn from_samples(samples: &[f64]) -> Self {
        let n = samples.len();
        if n < 2 {
            let mean = samples.first().copied().unwrap_or(f64::NAN);
            return Self {
                n,
                mean,
                variance: f64::NAN,
                mean_stderr: f64::NAN,
                variance_stderr: f64::NAN,
            };
        }
        let nf = n as f64;
        let mean = samples.iter().sum::<f64>() / nf;
        let (mut m2, mut m4) = (0.0, 0.0);
        for &x in samples {
            let d2 = (x - mean) * (x - mean);
            m2 += d2;
            m4 += d2 * d2;
        }
        let variance = m2 / (nf - 1.0);
        let (m2, m4) = (m2 / nf, m4 / nf);
        Self {
            n,
            mean,
            variance,
            mean_stderr: (variance / nf).sqrt(),
            variance_stderr: ((m4 - m2 * m2).max(0.0) / nf).sqrt(),
        }
    }
}

/// Draws an index from the probability vector `probs` by inverting its CDF.
fn sample_index(probs: &[f64], rng: &mut StdRng) -> usize {
    let u: f64 = rng.random();
    let mut acc = 0.0;
    for (i, &p) in probs.iter().enumerate() {
        acc += p;
        if u < acc {
            return i;
        }
    }
    // Σ p may fall short of 1 by round-off: take the last index with positive probability.
    probs
        .iter()
        .rposition(|&p| p > 0.0)
        .unwrap_or(probs.len() - 1)
}
