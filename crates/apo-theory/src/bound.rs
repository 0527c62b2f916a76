//! The terms of the APO paper's surrogate `M_k^j(π) = J^l_{π,π_j} − k (MV_{π,π_j} + VM_{π,π_j})`
//! and of the bound it lower-bounds, `B_k(π) = J(π) − k V(π)`, computed exactly on a tabular MDP.
//!
//! Each function is named after its symbol and cites the paper's equation (main text, Section 3,
//! equations "value lower bound", "mv def", "vm def", "H def", "eta def"; appendix, Section "Lower
//! Probability Bound"). Notation: `π_j` is the current policy (its [`Evaluation`] `ev_j`), `π` the
//! candidate; `A_{π_j}(s,a)` and `A_{π_j}(s,a,s') = r(s,a,s') + γ V_{π_j}(s') − V_{π_j}(s)`;
//! `Ā_{π,π_j}(s) = E_{a∼π}[A_{π_j}(s,a)]`.
//!
//! [`Reading`] says how the statement is read where it leaves a choice. `‖μᵀ‖∞` is by default
//! the induced ∞-norm of the row vector `μᵀ`, which is `Σ_s μ(s) = 1`: the
//! norm under which the appendix's step `|μᵀ x| ≤ ‖μᵀ‖∞ ‖x‖∞` holds. [`MuNorm::MaxEntry`] reads
//! it as `max_s μ(s)` instead (what "‖μ‖∞" would mean for a vector), to see what that changes.

use crate::{Evaluation, Mdp, TabularPolicy, TheoryError};

/// How `‖μᵀ‖∞` is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MuNorm {
    /// The induced ∞-norm of the row vector `μᵀ`: `Σ_s |μ(s)| = 1`.
    Induced,
    /// The largest entry, `max_s μ(s)`.
    MaxEntry,
}

impl MuNorm {
    /// `‖μᵀ‖∞` of `mdp`'s start distribution.
    pub fn of(self, mdp: &Mdp) -> f64 {
        match self {
            MuNorm::Induced => mdp.start.iter().map(|m| m.abs()).sum(),
            MuNorm::MaxEntry => mdp.start.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// `max_i |x_i|` (0 for an empty slice): the ∞-norm.
pub(crate) fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m: f64, v| m.max(v.abs()))
}

/// How the MeanVariance bound's cross term `2 E_{a∼π,s'}[A_{π_j}(s,a,s')] |H|_max` is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrossTerm {
    /// As the paper writes it, `2 E[A] |H|_max`: the appendix bounds `2 E[A H]` by it, which
    /// fails where `A` and `H` are both negative (docs/theory.md has a counterexample).
    Paper,
    /// `2 E[|A|] |H|_max`, a valid bound of `2 E[A H]` since `|H| ≤ |H|_max`.
    AbsoluteAdvantage,
}

/// How the paper's statement is read where it leaves a choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reading {
    /// `‖μᵀ‖∞`.
    pub mu_norm: MuNorm,
    /// The MeanVariance bound's cross term.
    pub cross_term: CrossTerm,
}

impl Reading {
    /// The paper as written: `‖μᵀ‖∞ = 1` (the induced norm, as its Section 4 says) and its cross
    /// term.
    pub const PAPER: Reading = Reading {
        mu_norm: MuNorm::Induced,
        cross_term: CrossTerm::Paper,
    };
}

/// How the terms `max_s |…|` of `MV_{π,π_j}` and `VM_{π,π_j}` are taken over the states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverStates {
    /// The maximum, as the theorem states them.
    Max,
    /// The average under `d^{π_j}`, as the paper's practical implementation does ("taking the
    /// average of the state s instead of the maximum", Section 4).
    Average,
}

impl OverStates {
    /// `max_s x(s)` or `Σ_s d^{π_j}(s) x(s)`.
    fn aggregate(self, x: &[f64], ev_j: &Evaluation) -> f64 {
        match self {
            OverStates::Max => x.iter().copied().fold(0.0, f64::max),
            OverStates::Average => x.iter().zip(&ev_j.d).map(|(a, d)| a * d).sum(),
        }
    }
}

/// `B_k(π) = J(π) − k V(π)`, the lower probability bound of the return (Definition 1).
pub fn bound_k(ev: &Evaluation, k: f64) -> f64 {
    ev.j - k * ev.return_variance
}

/// Selberg's confidence `1 − 1/(k² V + 1)` of `B_k` (Proposition "absolute bound definition").
pub fn confidence(ev: &Evaluation, k: f64) -> f64 {
    1.0 - 1.0 / (k * k * ev.return_variance + 1.0)
}

/// `Ā_{π,π_j}(s) = E_{a∼π}[A_{π_j}(s,a)]`, `[S]`.
pub fn expected_advantage(pi: &TabularPolicy, ev_j: &Evaluation) -> Vec<f64> {
    (0..ev_j.states)
        .map(|s| {
            (0..ev_j.actions)
                .map(|a| pi.prob(s, a) * ev_j.adv_at(s, a))
                .sum()
        })
        .collect()
}

/// `ε = max_{s,a} |A_{π_j}(s,a)|` (after equation "eta def").
pub fn epsilon(ev_j: &Evaluation) -> f64 {
    max_abs(&ev_j.adv)
}

/// `ε^π = max_s |E_{a∼π}[A_{π_j}(s,a)]|` (after equation "vm def").
pub fn epsilon_pi(pi: &TabularPolicy, ev_j: &Evaluation) -> f64 {
    max_abs(&expected_advantage(pi, ev_j))
}

/// `(1/(1−γ)) E_{s∼d^{π_j}, a∼π}[A_{π_j}(s,a)]`: the first-order change of `J` (the
/// surrogate that TRPO maximizes).
pub fn expected_gain(pi: &TabularPolicy, ev_j: &Evaluation) -> f64 {
    let abar = expected_advantage(pi, ev_j);
    ev_j.d.iter().zip(&abar).map(|(d, a)| d * a).sum::<f64>() / (1.0 - ev_j.gamma)
}

/// The two parts of `J^l` and `J^u` besides `J(π_j)`: [`expected_gain`], and the KL term
/// `(1/(1−γ)) E_{s∼d^{π_j}}[(2γ ε^π/(1−γ)) √(½ D_KL(π ‖ π_j)[s])]`.
fn surrogate_parts(pi: &TabularPolicy, pi_j: &TabularPolicy, ev_j: &Evaluation) -> (f64, f64) {
    let g = ev_j.gamma;
    let eps_pi = epsilon_pi(pi, ev_j);
    let penalty: f64 = ev_j
        .d
        .iter()
        .enumerate()
        .map(|(s, d)| d * 2.0 * g * eps_pi / (1.0 - g) * (0.5 * pi.kl(pi_j, s)).sqrt())
        .sum();
    (expected_gain(pi, ev_j), penalty / (1.0 - g))
}

/// `J^l_{π,π_j} = J(π_j) + (1/(1−γ)) E_{s∼d^{π_j}, a∼π}[A_{π_j}(s,a) − (2γ ε^π/(1−γ))
/// √(½ D_KL(π ‖ π_j)[s])]` (equation "value lower bound").
pub fn j_lower(pi: &TabularPolicy, pi_j: &TabularPolicy, ev_j: &Evaluation) -> f64 {
    let (gain, penalty) = surrogate_parts(pi, pi_j, ev_j);
    ev_j.j + gain - penalty
}

/// `J^u_{π,π_j}`: `J^l` with the KL term added instead of subtracted.
pub fn j_upper(pi: &TabularPolicy, pi_j: &TabularPolicy, ev_j: &Evaluation) -> f64 {
    let (gain, penalty) = surrogate_parts(pi, pi_j, ev_j);
    ev_j.j + gain + penalty
}

/// `min(J(π))² = min_{J ∈ [J^l, J^u]} J²` (after equation "vm def"; the appendix's
/// `(min{max{0, J^l}, J^u})²`).
pub fn min_j_sq(j_l: f64, j_u: f64) -> f64 {
    j_l.max(0.0).min(j_u).powi(2)
}

/// `T(s) = E_{s_0 = s, τ∼π_j}[Σ_t γ^t Ā_{π,π_j}(s_t)]`, `[S]`: the discounted sum of the
/// expected advantage along `π_j`'s trajectories.
pub fn discounted_advantage(
    pi: &TabularPolicy,
    ev_j: &Evaluation,
) -> Result<Vec<f64>, TheoryError> {
    ev_j.discounted_sum(&expected_advantage(pi, ev_j))
}

/// `|η(s)|_max = |T(s)| + (2γε/(1−γ)²) D_KL^max(π ‖ π_j)`, `[S]` (equation "eta def").
pub fn eta_max(
    pi: &TabularPolicy,
    pi_j: &TabularPolicy,
    ev_j: &Evaluation,
) -> Result<Vec<f64>, TheoryError> {
    let g = ev_j.gamma;
    let extra = 2.0 * g * epsilon(ev_j) / (1.0 - g).powi(2) * pi.max_kl(pi_j);
    Ok(discounted_advantage(pi, ev_j)?
        .iter()
        .map(|t| t.abs() + extra)
        .collect())
}

/// `|H(s,a,s')|_max = (2γ(1+γ)ε/(1−γ)²) D_KL^max(π ‖ π_j) + |γ T(s') − T(s)|`, `[S][S]`, index
/// `s * S + s'` (equation "H def"; it does not depend on `a`).
pub fn h_max(
    pi: &TabularPolicy,
    pi_j: &TabularPolicy,
    ev_j: &Evaluation,
) -> Result<Vec<f64>, TheoryError> {
    let (g, n) = (ev_j.gamma, ev_j.states);
    let extra = 2.0 * g * (1.0 + g) * epsilon(ev_j) / (1.0 - g).powi(2) * pi.max_kl(pi_j);
    let t = discounted_advantage(pi, ev_j)?;
    Ok((0..n * n)
        .map(|i| extra + (g * t[i % n] - t[i / n]).abs())
        .collect())
}

/// `MV_{π,π_j}` (equation "mv def"):
/// `‖μᵀ‖∞/(1−γ²) · max_s |E_{a∼π,s'}[A_{π_j}(s,a,s')²] − E_{a∼π_j,s'}[A_{π_j}(s,a,s')²]
/// + E_{a∼π,s'}[|H(s,a,s')|²_max + 2 A_{π_j}(s,a,s') |H(s,a,s')|_max]| + MV_{π_j}
/// + (2γ²‖μᵀ‖∞/(1−γ²)²) √(½ D_KL^max(π ‖ π_j)) ‖Ω_{π_j}‖∞`.
///
/// `|H|_max` depends on `s'`, so its terms are taken inside the expectation over `s'`. `over`
/// says how `max_s |…|` is taken.
pub fn mean_variance_bound(
    mdp: &Mdp,
    pi: &TabularPolicy,
    pi_j: &TabularPolicy,
    ev_j: &Evaluation,
    reading: Reading,
    over: OverStates,
) -> Result<f64, TheoryError> {
    let (g, n, na) = (ev_j.gamma, ev_j.states, ev_j.actions);
    let h = h_max(pi, pi_j, ev_j)?;
    let mut per_state = Vec::with_capacity(n);
    for s in 0..n {
        let mut inner = 0.0;
        for a in 0..na {
            let (p, p_j) = (pi.prob(s, a), pi_j.prob(s, a));
            for s2 in 0..n {
                let pt = mdp.p(s, a, s2);
                let adv = ev_j.a3(s, a, s2);
                let hm = h[s * n + s2];
                let cross = match reading.cross_term {
                    CrossTerm::Paper => adv,
                    CrossTerm::AbsoluteAdvantage => adv.abs(),
                };
                inner += p * pt * (adv * adv + hm * hm + 2.0 * cross * hm) - p_j * pt * adv * adv;
            }
        }
        per_state.push(inner.abs());
    }
    let worst = over.aggregate(&per_state, ev_j);
    let mu = reading.mu_norm.of(mdp);
    let omega_norm = max_abs(&ev_j.omega);
    Ok(mu / (1.0 - g * g) * worst
        + ev_j.mean_variance
        + 2.0 * g * g * mu / (1.0 - g * g).powi(2) * (0.5 * pi.max_kl(pi_j)).sqrt() * omega_norm)
}

/// `VM_{π,π_j} = ‖μᵀ‖∞ max_s ||η(s)|²_max + 2|V_{π_j}(s)| |η(s)|_max| − min(J(π))²
/// + E_{s_0∼μ}[V_{π_j}(s_0)²]` (equation "vm def"); `over` says how `max_s |…|` is taken.
pub fn variance_mean_bound(
    mdp: &Mdp,
    pi: &TabularPolicy,
    pi_j: &TabularPolicy,
    ev_j: &Evaluation,
    reading: Reading,
    over: OverStates,
) -> Result<f64, TheoryError> {
    let eta = eta_max(pi, pi_j, ev_j)?;
    let per_state: Vec<f64> = (0..ev_j.states)
        .map(|s| (eta[s] * eta[s] + 2.0 * ev_j.v[s].abs() * eta[s]).abs())
        .collect();
    let spread = over.aggregate(&per_state, ev_j);
    let mean_v_sq: f64 = (0..ev_j.states)
        .map(|s| mdp.start[s] * ev_j.v[s] * ev_j.v[s])
        .sum();
    let min_sq = min_j_sq(j_lower(pi, pi_j, ev_j), j_upper(pi, pi_j, ev_j));
    Ok(reading.mu_norm.of(mdp) * spread - min_sq + mean_v_sq)
}

/// Every term of `M_k^j(π)` for one candidate `π`, and the true `B_k(π)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surrogate {
    /// `J(π)`, exact.
    pub j: f64,
    /// `V(π)`, exact.
    pub variance: f64,
    /// `MV_π = E_{s_0∼μ}[Var[R(s_0)]]`, exact: what `MV_{π,π_j}` bounds (Lemma "bound of MV").
    pub true_mean_variance: f64,
    /// `VM_π = Var_{s_0∼μ}[V_π(s_0)]`, exact: what `VM_{π,π_j}` bounds (Lemma "bound of VM").
    pub true_variance_mean: f64,
    /// `J^l_{π,π_j}`.
    pub j_lower: f64,
    /// `MV_{π,π_j}`.
    pub mean_variance: f64,
    /// `VM_{π,π_j}`.
    pub variance_mean: f64,
    /// `M_k^j(π) = J^l − k (MV + VM)`.
    pub m: f64,
    /// `B_k(π) = J(π) − k V(π)`.
    pub b: f64,
}

impl Surrogate {
    /// The terms for candidate `pi` against the current `pi_j` (evaluated as `ev_j`) and `k`.
    pub fn new(
        mdp: &Mdp,
        pi: &TabularPolicy,
        pi_j: &TabularPolicy,
        ev_j: &Evaluation,
        k: f64,
        reading: Reading,
    ) -> Result<Self, TheoryError> {
        let ev = Evaluation::new(mdp, pi)?;
        let j_lower = j_lower(pi, pi_j, ev_j);
        let mean_variance = mean_variance_bound(mdp, pi, pi_j, ev_j, reading, OverStates::Max)?;
        let variance_mean = variance_mean_bound(mdp, pi, pi_j, ev_j, reading, OverStates::Max)?;
        Ok(Self {
            j: ev.j,
            variance: ev.return_variance,
            true_mean_variance: ev.mean_variance,
            true_variance_mean: ev.variance_mean,
            j_lower,
            mean_variance,
            variance_mean,
            m: j_lower - k * (mean_variance + variance_mean),
            b: bound_k(&ev, k),
        })
    }
}
