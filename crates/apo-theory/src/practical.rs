//! The practical APO objective (what `apo_core` optimizes) evaluated *exactly* on a tabular
//! MDP, its trust-region step, and the variants of `docs/algorithms.md` ("Variants that keep
//! the step").
//!
//! Every mean over a batch becomes an expectation over `s ∼ d^{π_j}`, `a ∼ π_j`,
//! `s' ∼ P(·|s,a)`; the advantages are `π_j`'s exact `A(s,a)` (the expectation of GAE(λ) with
//! the exact critic, whatever λ), normalized by `σ_A = sqrt(E[A²])`; `delta = A(s,a,s')`; the
//! critic is `V_{π_j}`; `max(adv)` is over the pairs with `π_j(a|s) > 0`. With
//! `ratio = π(a|s)/π_j(a|s)`:
//!
//! ```text
//! mean_surr = E[ratio · adv]
//! mv        = ω1 · E[| (ratio − 1) · delta² + 2 · ratio · delta · ω2 |]
//! bias      = 4γ · |E[log π_j − log π]| · max(adv) / (1 − γ)²
//! min_J_sq  = mean_surr² + 2 · E[V] · mean_surr where the switch is on, else 0
//! vm        = (ω1 (1 − γ²) / k) · E[adv² + 2 |adv| V] − min_J_sq
//! objective = mean_surr − k (mv + vm)
//! ```
//!
//! In [`Units::Advantage`], `delta` and `V` are divided by `σ_A`, so the objective stands for
//! `B_{k/σ_A}` in reward units; in [`Units::Reward`] for `B_k`.
//!
//! The step ([`update`]) is the trust-region step of `apo_core::trust_region`, exactly: the
//! natural gradient of the softmax logits, `x_s = g_s / (d(s) π_j(·|s))` (it solves
//! `F x = g` for the Fisher matrix `F = Σ_s d(s) (diag p_s − p_s p_sᵀ)` of the mean KL, since
//! every `g_s` sums to zero), scaled to `½ xᵀFx = δ`, then backtracking by 0.8 up to 100 tries.

use crate::bound::bound_k;
use crate::{Evaluation, Mdp, TabularPolicy, TheoryError};

/// The units of `delta`, `V` and ω2 in the penalty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// As the rewards are (the paper).
    Reward,
    /// Divided by `σ_A`.
    Advantage,
}

/// How `min_J_sq`'s switch is decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Switch {
    /// At every evaluated policy: on when `mean_surr + E[V] − bias ≥ 0` (the paper).
    Paper,
    /// At `π_j`, held for the whole line search: on when `E[V] ≥ 0`.
    Held,
    /// Always off: `min_J_sq = 0`.
    Off,
}

/// Which line-search tries are accepted inside the KL radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Acceptance {
    /// `objective ≥ objective(π_j)` (the paper).
    Improvement,
    /// Actual improvement `> 0` and `≥ ratio ·` the linear model's `ξ^i gᵀΔ`.
    Ratio(f64),
}

/// One variant of the practical APO update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variant {
    /// Probability factor k (0: TRPO's surrogate).
    pub k: f64,
    /// ω1.
    pub omega1: f64,
    /// ω2.
    pub omega2: f64,
    /// The penalty's units.
    pub units: Units,
    /// The switch.
    pub switch: Switch,
    /// The line search's acceptance.
    pub acceptance: Acceptance,
    /// The KL radius δ.
    pub max_kl: f64,
}

impl Variant {
    /// The paper's practical APO with `k`, ω1 = ω2 = 0.005 and δ = 0.02.
    pub fn paper(k: f64) -> Self {
        Self {
            k,
            omega1: 0.005,
            omega2: 0.005,
            units: Units::Reward,
            switch: Switch::Paper,
            acceptance: Acceptance::Improvement,
            max_kl: 0.02,
        }
    }

    /// The `k` of the bound `J − k·Var` (reward units) the variant stands for at `π_j`:
    /// `k`, or `k / σ_A` in advantage units.
    pub fn bound_factor(&self, sigma_a: f64) -> f64 {
        match self.units {
            Units::Reward => self.k,
            Units::Advantage => self.k / sigma_a,
        }
    }
}

/// The practical objective's terms at a candidate policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms {
    /// The objective.
    pub objective: f64,
    /// `mean_surr`.
    pub mean_surr: f64,
    /// `mv`.
    pub mean_variance: f64,
    /// `vm`.
    pub variance_mean: f64,
    /// Whether `min_J_sq`'s switch is on.
    pub switch_on: bool,
    /// `E_{d^{π_j}}[KL(π_j ‖ π)]`, the trust region's KL.
    pub mean_kl: f64,
}

/// `π_j`'s data the objective needs, computed once per update.
#[derive(Debug, Clone)]
pub struct Anchor {
    pi_j: TabularPolicy,
    ev_j: Evaluation,
    /// `σ_A = sqrt(E_{d^{π_j}, π_j}[A²])`.
    pub sigma_a: f64,
    max_adv: f64,
}

impl Anchor {
    /// Evaluates `π_j` on `mdp`.
    pub fn new(mdp: &Mdp, pi_j: &TabularPolicy) -> Result<Self, TheoryError> {
        let ev_j = Evaluation::new(mdp, pi_j)?;
        let (mut second, mut max_adv) = (0.0, f64::NEG_INFINITY);
        for s in 0..mdp.states {
            for a in 0..mdp.actions {
                let p = pi_j.prob(s, a);
                second += ev_j.d[s] * p * ev_j.adv_at(s, a).powi(2);
                if p > 0.0 {
                    max_adv = max_adv.max(ev_j.adv_at(s, a));
                }
            }
        }
        let sigma_a = second.sqrt().max(1e-12);
        Ok(Self {
            pi_j: pi_j.clone(),
            ev_j,
            sigma_a,
            max_adv: max_adv / sigma_a,
        })
    }

    /// `π_j`'s exact evaluation.
    pub fn evaluation(&self) -> &Evaluation {
        &self.ev_j
    }
}

/// The practical objective of `variant` at `pi` against `anchor`'s `π_j`.
pub fn terms(mdp: &Mdp, variant: &Variant, anchor: &Anchor, pi: &TabularPolicy) -> Terms {
    let (ev, pj) = (&anchor.ev_j, &anchor.pi_j);
    let unit = match variant.units {
        Units::Reward => 1.0,
        Units::Advantage => anchor.sigma_a,
    };
    let g = mdp.gamma;
    let (mut ms, mut mv, mut dlogp, mut spread, mut mean_v, mut mean_kl) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for s in 0..mdp.states {
        let d = ev.d[s];
        let v = ev.v[s] / unit;
        mean_v += d * v;
        mean_kl += d * pj.kl(pi, s);
        for a in 0..mdp.actions {
            let p = pj.prob(s, a);
            if p <= 0.0 {
                continue;
            }
            let w = d * p;
            let ratio = pi.prob(s, a) / p;
            let adv = ev.adv_at(s, a) / anchor.sigma_a;
            ms += w * ratio * adv;
            dlogp += w * (p.ln() - pi.prob(s, a).ln());
            spread += w * (adv * adv + 2.0 * adv.abs() * v);
            for s2 in 0..mdp.states {
                let pt = mdp.p(s, a, s2);
                if pt > 0.0 {
                    let delta = ev.a3(s, a, s2) / unit;
                    let t = (ratio - 1.0) * delta * delta + 2.0 * ratio * delta * variant.omega2;
                    mv += w * pt * t.abs();
                }
            }
        }
    }
    if variant.k == 0.0 {
        return Terms {
            objective: ms,
            mean_surr: ms,
            mean_variance: 0.0,
            variance_mean: 0.0,
            switch_on: false,
            mean_kl,
        };
    }
    let mv = variant.omega1 * mv;
    let bias = 4.0 * g * dlogp.abs() * anchor.max_adv / (1.0 - g).powi(2);
    let switch_on = match variant.switch {
        Switch::Paper => ms + mean_v - bias >= 0.0,
        // at π_j: mean_surr = E[adv] = 0 and bias = 0
        Switch::Held => mean_v >= 0.0,
        Switch::Off => false,
    };
    let min_j_sq = if switch_on {
        ms * ms + 2.0 * mean_v * ms
    } else {
        0.0
    };
    let vm = variant.omega1 * (1.0 - g * g) / variant.k * spread - min_j_sq;
    Terms {
        objective: ms - variant.k * (mv + vm),
        mean_surr: ms,
        mean_variance: mv,
        variance_mean: vm,
        switch_on,
        mean_kl,
    }
}

/// What one trust-region update did, with the exact consequences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Update {
    /// The accepted try (0: the full step), or `None` when every try was rejected.
    pub accepted: Option<usize>,
    /// The mean KL of the returned policy.
    pub kl: f64,
    /// The objective's change.
    pub objective_gain: f64,
    /// `J(π') − J(π_j)`, exact.
    pub j_gain: f64,
    /// `Var(π') − Var(π_j)` of the return, exact.
    pub variance_change: f64,
    /// `B(π') − B(π_j)` with the variant's own factor ([`Variant::bound_factor`] at `π_j`).
    pub bound_gain: f64,
    /// Whether the switch was on at the returned policy.
    pub switch_on: bool,
}

fn softmax_policy(mdp: &Mdp, logits: &[f64]) -> TabularPolicy {
    TabularPolicy::from_logits(mdp.states, mdp.actions, logits)
}

/// One trust-region update of `variant` from the softmax policy with `logits` (updated in
/// place when a try is accepted).
pub fn update(mdp: &Mdp, variant: &Variant, logits: &mut [f64]) -> Result<Update, TheoryError> {
    let pi_j = softmax_policy(mdp, logits);
    let anchor = Anchor::new(mdp, &pi_j)?;
    let f = |x: &[f64]| terms(mdp, variant, &anchor, &softmax_policy(mdp, x));
    let before = f(logits);
    // the gradient by central differences (the objective is piecewise smooth in the logits)
    let h = 1e-6;
    let mut grad = vec![0.0; logits.len()];
    for i in 0..logits.len() {
        let (mut up, mut down) = (logits.to_vec(), logits.to_vec());
        up[i] += h;
        down[i] -= h;
        grad[i] = (f(&up).objective - f(&down).objective) / (2.0 * h);
    }
    // natural gradient x_s = g_s / (d(s) p_s), and xᵀFx = Σ_s d(s) Var_{p_s}(x_s)
    let (ns, na) = (mdp.states, mdp.actions);
    let mut x = vec![0.0; logits.len()];
    let mut x_fx = 0.0;
    for s in 0..ns {
        let d = anchor.ev_j.d[s].max(1e-300);
        let (mut m1, mut m2) = (0.0, 0.0);
        for a in 0..na {
            let p = pi_j.prob(s, a).max(1e-300);
            let xi = grad[s * na + a] / (d * p);
            x[s * na + a] = xi;
            m1 += p * xi;
            m2 += p * xi * xi;
        }
        x_fx += d * (m2 - m1 * m1);
    }
    let before_bound = bound_k(&anchor.ev_j, variant.bound_factor(anchor.sigma_a));
    let unchanged = Update {
        accepted: None,
        kl: 0.0,
        objective_gain: 0.0,
        j_gain: 0.0,
        variance_change: 0.0,
        bound_gain: 0.0,
        switch_on: before.switch_on,
    };
    if !(x_fx > 0.0 && x_fx.is_finite()) {
        return Ok(unchanged);
    }
    let scale = (2.0 * variant.max_kl / x_fx).sqrt();
    let step: Vec<f64> = x.iter().map(|v| v * scale).collect();
    let predicted: f64 = grad.iter().zip(&step).map(|(g, s)| g * s).sum();
    let mut fraction = 1.0;
    for r#try in 0..100 {
        let candidate: Vec<f64> = logits
            .iter()
            .zip(&step)
            .map(|(l, s)| l + fraction * s)
            .collect();
        let after = f(&candidate);
        let actual = after.objective - before.objective;
        let improved = match variant.acceptance {
            Acceptance::Improvement => actual >= 0.0,
            Acceptance::Ratio(ratio) => actual > 0.0 && actual >= ratio * fraction * predicted,
        };
        if after.mean_kl <= variant.max_kl && improved {
            let pi = softmax_policy(mdp, &candidate);
            let ev = Evaluation::new(mdp, &pi)?;
            logits.copy_from_slice(&candidate);
            return Ok(Update {
                accepted: Some(r#try),
                kl: after.mean_kl,
                objective_gain: actual,
                j_gain: ev.j - anchor.ev_j.j,
                variance_change: ev.return_variance - anchor.ev_j.return_variance,
                bound_gain: bound_k(&ev, variant.bound_factor(anchor.sigma_a)) - before_bound,
                switch_on: after.switch_on,
            });
        }
        fraction *= 0.8;
    }
    Ok(unchanged)
}

/// What [`run`] measured over many updates.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Updates run.
    pub updates: usize,
    /// Updates whose line search accepted a try.
    pub accepted: usize,
    /// Updates that took the full step (try 0).
    pub full_steps: usize,
    /// The median KL of the accepted steps (0 when none).
    pub median_kl: f64,
    /// Accepted updates with `B' > B` beyond round-off: the surrogate's promise kept.
    pub bound_raised: usize,
    /// Accepted updates with `B' < B` beyond round-off: the surrogate's promise broken.
    pub bound_lowered: usize,
    /// The largest drop of `B` in one accepted update (0 when none).
    pub largest_drop: f64,
    /// Mean `B' − B` per update (rejected ones count 0).
    pub mean_bound_gain: f64,
    /// Mean `J' − J` per update.
    pub mean_j_gain: f64,
    /// Mean `Var' − Var` per update.
    pub mean_variance_change: f64,
    /// Accepted updates whose returned policy had the switch on.
    pub switch_on: usize,
}

/// How [`run`] changes the rewards of the random problems: `r ↦ scale · (r + offset)`.
/// A positive offset makes `V` positive, as a survival bonus does on the locomotion tasks, and
/// puts the paper's switch on at `π_j`; a scale above 1 makes the unnormalized TD errors of the
/// penalty large against the normalized advantages of the surrogate, as on Hopper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rewards {
    /// Added first.
    pub offset: f64,
    /// Then multiplied.
    pub scale: f64,
}

/// `iterations` updates of `variant` from `π_0` of each problem `seeds` of `problems`, with
/// the rewards changed by `rewards`.
pub fn run(
    problems: &crate::checks::Problems,
    seeds: std::ops::Range<u64>,
    variant: &Variant,
    iterations: usize,
    rewards: Rewards,
) -> Result<Summary, TheoryError> {
    let mut kls = Vec::new();
    let mut summary = Summary {
        updates: 0,
        accepted: 0,
        full_steps: 0,
        median_kl: 0.0,
        bound_raised: 0,
        bound_lowered: 0,
        largest_drop: 0.0,
        mean_bound_gain: 0.0,
        mean_j_gain: 0.0,
        mean_variance_change: 0.0,
        switch_on: 0,
    };
    let (mut bound_sum, mut j_sum, mut var_sum) = (0.0, 0.0, 0.0);
    for seed in seeds {
        let (mut mdp, mut logits) = problems.draw(seed);
        mdp.reward
            .iter_mut()
            .for_each(|r| *r = rewards.scale * (*r + rewards.offset));
        for _ in 0..iterations {
            let u = update(&mdp, variant, &mut logits)?;
            summary.updates += 1;
            bound_sum += u.bound_gain;
            j_sum += u.j_gain;
            var_sum += u.variance_change;
            let Some(r#try) = u.accepted else { continue };
            summary.accepted += 1;
            summary.full_steps += usize::from(r#try == 0);
            summary.switch_on += usize::from(u.switch_on);
            kls.push(u.kl);
            let tolerance = 1e-12;
            if u.bound_gain > tolerance {
                summary.bound_raised += 1;
            } else if u.bound_gain < -tolerance {
                summary.bound_lowered += 1;
                summary.largest_drop = summary.largest_drop.max(-u.bound_gain);
            }
        }
    }
    let n = summary.updates.max(1) as f64;
    summary.mean_bound_gain = bound_sum / n;
    summary.mean_j_gain = j_sum / n;
    summary.mean_variance_change = var_sum / n;
    kls.sort_by(f64::total_cmp);
    if !kls.is_empty() {
        summary.median_kl = kls[kls.len() / 2];
    }
    Ok(summary)
}

/// The variants `apo theory` compares at probability factor `k`, with their names: the paper's
/// practical APO, each variant alone, the recommended combination, and TRPO (`k = 0`).
pub fn variants(k: f64, max_kl: f64) -> Vec<(&'static str, Variant)> {
    let paper = Variant {
        max_kl,
        ..Variant::paper(k)
    };
    let ratio = Acceptance::Ratio(0.1);
    vec![
        ("paper", paper),
        (
            "units=advantage",
            Variant {
                units: Units::Advantage,
                ..paper
            },
        ),
        (
            "switch=held",
            Variant {
                switch: Switch::Held,
                ..paper
            },
        ),
        (
            "switch=off",
            Variant {
                switch: Switch::Off,
                ..paper
            },
        ),
        (
            "acceptance=ratio",
            Variant {
                acceptance: ratio,
                ..paper
            },
        ),
        (
            "advantage+off",
            Variant {
                units: Units::Advantage,
                switch: Switch::Off,
                ..paper
            },
        ),
        (
            "advantage+off+ratio",
            Variant {
                units: Units::Advantage,
                switch: Switch::Off,
                acceptance: ratio,
                ..paper
            },
        ),
        ("trpo (k=0)", Variant { k: 0.0, ..paper }),
    ]
}
