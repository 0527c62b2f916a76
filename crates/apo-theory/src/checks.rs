//! The checks of Theorem 1 on random tabular MDPs:
//!
//! * (a) [`check_lower_bound`]: `M_k^j(π) ≤ B_k(π)` for candidates near and far from `π_j`;
//! * (b) the same function: `M_k^j(π_j) = B_k(π_j)`;
//! * (c) [`iterate`]: exact APO iterations (each maximizes `M_k^j` over softmax policies by
//!   gradient ascent) keep `B_k` non-decreasing; the practical trust-region surrogate does not
//!   promise it;
//! * (d) [`check_selberg`]: the sampled `P(R ≥ B_k)` is at least `1 − 1/(k² V + 1)`.
//!
//! Counterexamples are results: each check returns the worst case it met.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use crate::bound::{
    bound_k, confidence, expected_gain, j_lower, max_abs, mean_variance_bound, variance_mean_bound,
    OverStates, Reading, Surrogate,
};
use crate::montecarlo::sample_returns;
use crate::{Evaluation, Mdp, TabularPolicy, TheoryError};

/// The family of random problems a check draws: `Mdp::random(states, actions, gamma, seed)`
/// and a softmax `π_j` with standard-normal logits times `temperature`, for each seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Problems {
    /// Number of states.
    pub states: usize,
    /// Number of actions.
    pub actions: usize,
    /// Discount γ.
    pub gamma: f64,
    /// Scale of `π_j`'s logits.
    pub temperature: f64,
}

impl Problems {
    /// The MDP and the logits of `π_j` for `seed`.
    pub fn draw(&self, seed: u64) -> (Mdp, Vec<f64>) {
        let mdp = Mdp::random(self.states, self.actions, self.gamma, seed);
        let mut rng = StdRng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
        let logits = normal(&mut rng, self.states * self.actions, self.temperature);
        (mdp, logits)
    }
}

fn normal(rng: &mut StdRng, n: usize, scale: f64) -> Vec<f64> {
    (0..n)
        .map(|_| scale * rng.sample::<f64, _>(StandardNormal))
        .collect()
}

fn policy(mdp: &Mdp, logits: &[f64]) -> TabularPolicy {
    TabularPolicy::from_logits(mdp.states, mdp.actions, logits)
}

/// The worst case a check met.
#[derive(Debug, Clone, PartialEq)]
pub struct Counterexample {
    /// The seed of the MDP and of `π_j`.
    pub seed: u64,
    /// The probability factor.
    pub k: f64,
    /// How far the candidate's logits were moved from `π_j`'s (0: `π_j` itself).
    pub distance: f64,
    /// `D_KL^max(π ‖ π_j)`.
    pub max_kl: f64,
    /// The surrogate's terms and the true bound.
    pub terms: Surrogate,
}

impl Counterexample {
    /// `M_k^j(π) − B_k(π)`: positive when the surrogate is not a lower bound.
    pub fn gap(&self) -> f64 {
        self.terms.m - self.terms.b
    }
}

/// What (a) and (b) found.
#[derive(Debug, Clone, PartialEq)]
pub struct LowerBoundReport {
    /// Candidates checked (π_j itself excluded).
    pub cases: usize,
    /// Candidates with `M_k^j(π) > B_k(π)` beyond the tolerance.
    pub violations: usize,
    /// Candidates whose `M_k^j(π)` or `B_k(π)` is not finite (probabilities that underflow to
    /// 0 make a KL or a log infinite): neither a pass nor a violation, a check not made.
    pub not_finite: usize,
    /// The largest `M − B` met among the candidates.
    pub worst: Option<Counterexample>,
    /// The largest `|M_k^j(π_j) − B_k(π_j)|` met.
    pub max_gap_at_pi_j: f64,
}

/// The distances of the candidates from `π_j`: their logits are `π_j`'s plus this times a
/// standard normal vector (several draws each).
pub const DISTANCES: [f64; 6] = [1e-3, 1e-2, 0.1, 0.3, 1.0, 3.0];

/// Checks (a) and (b) on `seeds` problems, for every `k` in `ks`, with `draws` candidates per
/// distance in [`DISTANCES`].
pub fn check_lower_bound(
    problems: &Problems,
    seeds: std::ops::Range<u64>,
    ks: &[f64],
    draws: usize,
    reading: Reading,
) -> Result<LowerBoundReport, TheoryError> {
    let mut report = LowerBoundReport {
        cases: 0,
        violations: 0,
        not_finite: 0,
        worst: None,
        max_gap_at_pi_j: 0.0,
    };
    for seed in seeds {
        let (mdp, logits_j) = problems.draw(seed);
        let pi_j = policy(&mdp, &logits_j);
        let ev_j = Evaluation::new(&mdp, &pi_j)?;
        let mut rng = StdRng::seed_from_u64(seed.wrapping_mul(31).wrapping_add(7));
        for &k in ks {
            let at_j = Surrogate::new(&mdp, &pi_j, &pi_j, &ev_j, k, reading)?;
            report.max_gap_at_pi_j = report.max_gap_at_pi_j.max((at_j.m - at_j.b).abs());
            for &distance in &DISTANCES {
                for _ in 0..draws {
                    let noise = normal(&mut rng, logits_j.len(), distance);
                    let logits: Vec<f64> =
                        logits_j.iter().zip(&noise).map(|(a, b)| a + b).collect();
                    let pi = policy(&mdp, &logits);
                    let terms = Surrogate::new(&mdp, &pi, &pi_j, &ev_j, k, reading)?;
                    report.cases += 1;
                    let tolerance = 1e-9 * (1.0 + terms.b.abs());
                    if !(terms.m.is_finite() && terms.b.is_finite()) {
                        report.not_finite += 1;
                        continue;
                    }
                    if terms.m - terms.b > tolerance {
                        report.violations += 1;
                    }
                    let case = Counterexample {
                        seed,
                        k,
                        distance,
                        max_kl: pi.max_kl(&pi_j),
                        terms,
                    };
                    if report.worst.as_ref().is_none_or(|w| case.gap() > w.gap()) {
                        report.worst = Some(case);
                    }
                }
            }
        }
    }
    Ok(report)
}

/// Which surrogate an iteration maximizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// `M_k^j(π)` over all softmax policies (Theorem 1's update).
    Exact,
    /// The practical surrogate `(1/(1−γ)) E_{s∼d^{π_j},a∼π}[A_{π_j}] − k (MV̄ + VM̄)` (the
    /// paper's Section 4: `MV̄ = MV_{π,π_j} − MV_{π_j} − (its √KL term)`, `VM̄ = VM_{π,π_j} −
    /// E_μ[V_{π_j}²]`), inside the trust region `E_{s∼d^{π_j}}[D_KL(π ‖ π_j)[s]] ≤ δ`.
    TrustRegion {
        /// δ.
        max_kl: f64,
        /// How `max_s |…|` in MV̄ and VM̄ is taken: [`OverStates::Average`] is the paper's
        /// practical implementation.
        over: OverStates,
    },
}

/// The value `step` maximizes for the candidate `logits` against `π_j`, or `None` outside the
/// trust region.
fn objective(
    mdp: &Mdp,
    logits: &[f64],
    pi_j: &TabularPolicy,
    ev_j: &Evaluation,
    k: f64,
    step: Step,
    reading: Reading,
) -> Result<Option<f64>, TheoryError> {
    let pi = policy(mdp, logits);
    let over = match step {
        Step::Exact => OverStates::Max,
        Step::TrustRegion { over, .. } => over,
    };
    let mv = mean_variance_bound(mdp, &pi, pi_j, ev_j, reading, over)?;
    let vm = variance_mean_bound(mdp, &pi, pi_j, ev_j, reading, over)?;
    Ok(match step {
        Step::Exact => Some(j_lower(&pi, pi_j, ev_j) - k * (mv + vm)),
        Step::TrustRegion { max_kl, .. } => {
            let mean_kl: f64 = (0..mdp.states).map(|s| ev_j.d[s] * pi.kl(pi_j, s)).sum();
            if mean_kl > max_kl {
                return Ok(None);
            }
            let g = mdp.gamma;
            let gain = expected_gain(&pi, ev_j);
            let omega_norm = max_abs(&ev_j.omega);
            let kl_term = 2.0 * g * g * reading.mu_norm.of(mdp) / (1.0 - g * g).powi(2)
                * (0.5 * pi.max_kl(pi_j)).sqrt()
                * omega_norm;
            let mean_v_sq: f64 = (0..mdp.states)
                .map(|s| mdp.start[s] * ev_j.v[s] * ev_j.v[s])
                .sum();
            let mv_bar = mv - ev_j.mean_variance - kl_term;
            let vm_bar = vm - mean_v_sq;
            Some(gain - k * (mv_bar + vm_bar))
        }
    })
}

/// Gradient ascent on `step`'s objective from `π_j`'s logits: central differences, then a
/// backtracking line search that accepts only increases (and, for the trust region, only
/// points inside it). Returns the new logits.
fn maximize(
    mdp: &Mdp,
    logits_j: &[f64],
    k: f64,
    step: Step,
    reading: Reading,
    ascent_steps: usize,
) -> Result<Vec<f64>, TheoryError> {
    let pi_j = policy(mdp, logits_j);
    let ev_j = Evaluation::new(mdp, &pi_j)?;
    // a non-finite value (a policy so peaked that a probability underflows to 0 and a KL is
    // infinite) counts as outside the feasible set
    let f = |x: &[f64]| -> Result<Option<f64>, TheoryError> {
        if !x.iter().all(|v| v.is_finite()) {
            return Ok(None);
        }
        Ok(objective(mdp, x, &pi_j, &ev_j, k, step, reading)?.filter(|v| v.is_finite()))
    };
    let mut x = logits_j.to_vec();
    let mut fx = f(&x)?.unwrap_or(f64::NEG_INFINITY);
    let h = 1e-6;
    for _ in 0..ascent_steps {
        let mut grad = vec![0.0; x.len()];
        for i in 0..x.len() {
            let (mut up, mut down) = (x.clone(), x.clone());
            up[i] += h;
            down[i] -= h;
            if let (Some(a), Some(b)) = (f(&up)?, f(&down)?) {
                grad[i] = (a - b) / (2.0 * h);
            }
        }
        let norm_g = grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        if !norm_g.is_finite() || norm_g < 1e-12 {
            break;
        }
        let mut t = 1.0 / norm_g;
        let mut moved = false;
        for _ in 0..40 {
            let y: Vec<f64> = x.iter().zip(&grad).map(|(a, g)| a + t * g).collect();
            if let Some(fy) = f(&y)? {
                if fy > fx {
                    x = y;
                    fx = fy;
                    moved = true;
                    break;
                }
            }
            t *= 0.5;
        }
        if !moved {
            break;
        }
    }
    Ok(x)
}

/// `B_k` along `iterations` updates from `π_0 = π_j` of problem `seed`, each maximizing `step`'s
/// objective by `ascent_steps` steps of gradient ascent: `[iterations + 1]` values.
pub fn iterate(
    problems: &Problems,
    seed: u64,
    k: f64,
    step: Step,
    reading: Reading,
    iterations: usize,
    ascent_steps: usize,
) -> Result<Vec<f64>, TheoryError> {
    let (mdp, mut logits) = problems.draw(seed);
    let mut bounds = vec![bound_k(&Evaluation::new(&mdp, &policy(&mdp, &logits))?, k)];
    for _ in 0..iterations {
        logits = maximize(&mdp, &logits, k, step, reading, ascent_steps)?;
        bounds.push(bound_k(&Evaluation::new(&mdp, &policy(&mdp, &logits))?, k));
    }
    Ok(bounds)
}

/// What (d) found for one MDP and policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelbergCase {
    /// The seed of the problem.
    pub seed: u64,
    /// The probability factor.
    pub k: f64,
    /// `B_k(π)`.
    pub bound: f64,
    /// `1 − 1/(k² V + 1)`.
    pub confidence: f64,
    /// The fraction of sampled returns `≥ B_k`.
    pub empirical: f64,
    /// The binomial standard error of `empirical`.
    pub stderr: f64,
}

/// (d): for each seed and `k`, the fraction of `episodes` sampled returns of `π_j` at or above
/// `B_k(π_j)`, against Selberg's confidence (returns truncated at `horizon` steps).
pub fn check_selberg(
    problems: &Problems,
    seeds: std::ops::Range<u64>,
    ks: &[f64],
    episodes: usize,
    horizon: usize,
) -> Result<Vec<SelbergCase>, TheoryError> {
    let mut cases = Vec::new();
    for seed in seeds {
        let (mdp, logits) = problems.draw(seed);
        let pi = policy(&mdp, &logits);
        let ev = Evaluation::new(&mdp, &pi)?;
        let returns = sample_returns(&mdp, &pi, episodes, horizon, seed);
        for &k in ks {
            let bound = bound_k(&ev, k);
            let empirical =
                returns.iter().filter(|&&r| r >= bound).count() as f64 / returns.len() as f64;
            cases.push(SelbergCase {
                seed,
                k,
                bound,
                confidence: confidence(&ev, k),
                empirical,
                stderr: (empirical * (1.0 - empirical) / returns.len() as f64).sqrt(),
            });
        }
    }
    Ok(cases)
}
