//! `apo theory`: the APO paper's Theorem 1 checked exactly on random tabular MDPs
//! (`apo_theory::checks`), printed as a report.

use anyhow::{bail, Context};
use apo_theory::bound::{CrossTerm, MuNorm, OverStates, Reading};
use apo_theory::checks::{
    check_lower_bound, check_selberg, iterate, Counterexample, Problems, Step,
};
use apo_theory::practical;

/// `apo theory`'s options.
#[derive(Debug, Clone, clap::Args)]
pub struct TheoryArgs {
    /// States of each random MDP; 1..=64.
    #[arg(long, default_value_t = 5, value_parser = crate::flags::count::<u64>(1, 64))]
    pub states: u64,
    /// Actions of each random MDP; 1..=16.
    #[arg(long, default_value_t = 3, value_parser = crate::flags::count::<u64>(1, 16))]
    pub actions: u64,
    /// Random MDPs (seeds 0..N) for checks (a), (b) and (d); 1..=1000000.
    #[arg(long, default_value_t = 1000, value_parser = crate::flags::count::<u64>(1, 1_000_000))]
    pub seeds: u64,
    /// Discount γ ∈ [0, 0.999] (check (d) samples episodes of about ln(1e-9)/ln γ steps).
    #[arg(long, default_value_t = 0.9)]
    pub gamma: f64,
    /// Probability factors k (comma-separated, each in [0, 1000]).
    #[arg(long, value_delimiter = ',', default_values_t = [0.1, 1.0, 7.0])]
    pub k: Vec<f64>,
    /// Scale of π_j's random logits, in [0, 4] (beyond, the policies' smallest probabilities
    /// make some of the surrogate's terms overflow and check (a) cannot be made).
    #[arg(long, default_value_t = 1.0)]
    pub temperature: f64,
    /// Candidates per distance from π_j (distances 1e-3 … 3 in logit space); 1..=1000.
    #[arg(long, default_value_t = 2, value_parser = crate::flags::count::<u64>(1, 1000))]
    pub draws: u64,
    /// How ‖μᵀ‖∞ is read: the induced norm of the row vector (Σ μ = 1) or the largest entry.
    #[arg(long, value_parser = ["induced", "max-entry"], default_value = "induced")]
    pub mu_norm: String,
    /// The MeanVariance bound's cross term: the paper's `2·E[A]·|H|max`, or `2·E[|A|]·|H|max`.
    #[arg(long, value_parser = ["paper", "absolute"], default_value = "paper")]
    pub cross_term: String,
    /// MDPs (seeds 0..N) for check (c), the iterations; 0..=100000.
    #[arg(long, default_value_t = 20, value_parser = crate::flags::count::<u64>(0, 100_000))]
    pub iteration_seeds: u64,
    /// Policy updates per run in check (c); 1..=10000.
    #[arg(long, default_value_t = 10, value_parser = crate::flags::count::<u64>(1, 10_000))]
    pub iterations: u64,
    /// Gradient-ascent steps per update in check (c); 1..=10000.
    #[arg(long, default_value_t = 20, value_parser = crate::flags::count::<u64>(1, 10_000))]
    pub ascent_steps: u64,
    /// The trust region δ of the practical surrogate in checks (c) and (e), in (0, 1].
    #[arg(long, default_value_t = 0.02)]
    pub max_kl: f64,
    /// MDPs (seeds 0..N) for check (d), Selberg's inequality; 0..=100000.
    #[arg(long, default_value_t = 50, value_parser = crate::flags::count::<u64>(0, 100_000))]
    pub selberg_seeds: u64,
    /// Sampled episodes per MDP in check (d); 1..=100000000.
    #[arg(long, default_value_t = 20_000, value_parser = crate::flags::count::<u64>(1, 100_000_000))]
    pub episodes: u64,
    /// MDPs (seeds 0..N) for check (e): the practical APO's trust-region step and its
    /// variants, evaluated exactly; 0..=100000.
    #[arg(long, default_value_t = 50, value_parser = crate::flags::count::<u64>(0, 100_000))]
    pub practical_seeds: u64,
    /// Updates per MDP in check (e); 1..=10000.
    #[arg(long, default_value_t = 10, value_parser = crate::flags::count::<u64>(1, 10_000))]
    pub practical_iterations: u64,
    /// Added to every reward in check (e) (a positive offset: positive values, as with the
    /// survival bonus of the locomotion tasks), in [−1e6, 1e6].
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub reward_offset: f64,
    /// Multiplies every reward in check (e), after the offset, in (0, 1e6].
    #[arg(long, default_value_t = 1.0)]
    pub reward_scale: f64,
    /// Run check (e) only.
    #[arg(long)]
    pub practical_only: bool,
}

impl TheoryArgs {
    fn validate(&self) -> anyhow::Result<(Problems, Reading)> {
        // every number has a finite range, chosen so that each check stays finite and bounded in
        // time: logits, steps and returns stay far from overflow, and check (d) samples at most
        // MAX_SELBERG_STEPS steps
        let within = |flag: &str, v: f64, low: f64, high: f64, open_low: bool| {
            let above = if open_low { v > low } else { v >= low };
            if v.is_finite() && above && v <= high {
                Ok(())
            } else {
                let bracket = if open_low { '(' } else { '[' };
                Err(anyhow::anyhow!(
                    "{flag} {} is out of its range {bracket}{}, {}]",
                    number(v),
                    number(low),
                    number(high)
                ))
            }
        };
        within("--gamma", self.gamma, 0.0, MAX_GAMMA, false)?;
        for &k in &self.k {
            within("--k", k, 0.0, 1000.0, false)?;
        }
        within("--temperature", self.temperature, 0.0, 4.0, false)?;
        // a run that checks nothing is not a pass
        if self.practical_only && self.practical_seeds == 0 {
            bail!("--practical-only runs check (e) only, and --practical-seeds 0 gives it no MDP: nothing would be checked (give --practical-seeds 1 or more)");
        }
        within("--reward-offset", self.reward_offset, -1e6, 1e6, false)?;
        within("--reward-scale", self.reward_scale, 0.0, 1e6, true)?;
        within("--max-kl", self.max_kl, 0.0, 1.0, true)?;
        let steps = self.selberg_seeds as f64
            * self.k.len() as f64
            * self.episodes as f64
            * selberg_horizon(self.gamma) as f64;
        // check (d) does not run with --practical-only
        if steps > MAX_SELBERG_STEPS && !self.practical_only {
            bail!(
                "check (d) would sample {steps:.3e} steps (--selberg-seeds {} × {} k × --episodes {} × horizon {} at --gamma {}), \
                 more than {MAX_SELBERG_STEPS:.0e}: lower --selberg-seeds, --episodes or --gamma",
                self.selberg_seeds,
                self.k.len(),
                self.episodes,
                selberg_horizon(self.gamma),
                self.gamma
            );
        }
        let norm = Reading {
            mu_norm: match self.mu_norm.as_str() {
                "max-entry" => MuNorm::MaxEntry,
                _ => MuNorm::Induced,
            },
            cross_term: match self.cross_term.as_str() {
                "absolute" => CrossTerm::AbsoluteAdvantage,
                _ => CrossTerm::Paper,
            },
        };
        Ok((
            Problems {
                states: self.states as usize,
                actions: self.actions as usize,
                gamma: self.gamma,
                temperature: self.temperature,
            },
            norm,
        ))
    }
}

fn describe(c: &Counterexample) -> String {
    let t = &c.terms;
    format!(
        "seed {}, k {}, logit distance {}, D_KL^max {:.3e}: J {:.6} ≥ J^l {:.6}; MV_π {:.6} vs bound MV_{{π,π_j}} {:.6}; VM_π {:.6} vs bound VM_{{π,π_j}} {:.6}; M {:.6}, B {:.6}",
        c.seed, c.k, c.distance, c.max_kl, t.j, t.j_lower, t.true_mean_variance, t.mean_variance, t.true_variance_mean, t.variance_mean, t.m, t.b
    )
}

/// The largest decrease of consecutive values, and how many steps decreased beyond `tol`.
fn drops(values: &[f64], tol: f64) -> (usize, f64) {
    values.windows(2).fold((0, 0.0), |(n, worst), w| {
        let drop = w[0] - w[1];
        (
            n + usize::from(drop > tol * (1.0 + w[0].abs())),
            worst.max(drop),
        )
    })
}

/// Runs the five checks (or only (e)) and prints the report.
pub fn run(args: &TheoryArgs) -> anyhow::Result<()> {
    let (problems, norm) = args.validate()?;
    crate::outln!(
        "Theorem 1 on random tabular MDPs: {} states, {} actions, γ {}, π_j logits × {}, k ∈ {:?}, ‖μᵀ‖∞ read as {}, MV cross term {}",
        args.states, args.actions, args.gamma, args.temperature, args.k, args.mu_norm, args.cross_term
    )?;
    if !args.practical_only {
        theorem_checks(args, &problems, norm)?;
    }
    practical_check(args, &problems)
}

/// (e): the practical trust-region step of each variant, exactly, as a table.
fn practical_check(args: &TheoryArgs, problems: &Problems) -> anyhow::Result<()> {
    if args.practical_seeds == 0 {
        return Ok(());
    }
    crate::outln!(
        "(e) the practical APO's trust-region step (δ {}), exact, {} MDPs × {} updates per variant, rewards r ↦ {} · (r + {}):",
        args.max_kl, args.practical_seeds, args.practical_iterations, args.reward_scale, args.reward_offset
    )?;
    crate::outln!(
        "    | k | variant | accepted | full steps | median KL | B raised | B lowered (largest drop) | mean ΔB | mean ΔJ | mean ΔVar | switch on |"
    )?;
    crate::outln!("    |---|---|---|---|---|---|---|---|---|---|---|")?;
    for &k in &args.k {
        for (name, variant) in practical::variants(k, args.max_kl) {
            let s = practical::run(
                problems,
                0..args.practical_seeds,
                &variant,
                args.practical_iterations as usize,
                practical::Rewards {
                    offset: args.reward_offset,
                    scale: args.reward_scale,
                },
            )
            .with_context(|| format!("check (e), {name}, k {k}"))?;
            let summary = [
                s.median_kl,
                s.largest_drop,
                s.mean_bound_gain,
                s.mean_j_gain,
                s.mean_variance_change,
            ];
            if summary.iter().any(|v| v.is_nan() || v.is_infinite()) {
                bail!(
                    "check (e), {name}, k {k}: a step's KL, bound, return or variance is not finite \
                     (--reward-offset {}, --reward-scale {}, --temperature {}); lower them",
                    args.reward_offset,
                    args.reward_scale,
                    args.temperature
                );
            }
            let pct = |n: usize| 100.0 * n as f64 / s.updates.max(1) as f64;
            crate::outln!(
                "    | {k} | {name} | {:.0} % | {:.0} % | {:.1e} | {} | {} ({:.1e}) | {:+.4} | {:+.4} | {:+.4} | {} |",
                pct(s.accepted),
                pct(s.full_steps),
                s.median_kl,
                s.bound_raised,
                s.bound_lowered,
                s.largest_drop,
                s.mean_bound_gain,
                s.mean_j_gain,
                s.mean_variance_change,
                s.switch_on
            )?;
        }
    }
    Ok(())
}

/// Checks (a) to (d).
fn theorem_checks(args: &TheoryArgs, problems: &Problems, norm: Reading) -> anyhow::Result<()> {
    let problems = *problems;

    let lb = check_lower_bound(&problems, 0..args.seeds, &args.k, args.draws as usize, norm)
        .context("check (a)")?;
    // a check whose quantities are not finite was not made: an error, never a pass
    if lb.not_finite > 0 {
        bail!(
            "check (a): {} of {} candidates have a surrogate or bound that is not finite (at --temperature {} \
             the policies' probabilities underflow to 0 and a KL divergence is infinite); lower --temperature",
            lb.not_finite,
            lb.cases,
            args.temperature
        );
    }
    crate::outln!(
        "(a) M_k^j(π) ≤ B_k(π): {} candidates on {} MDPs, {} violations",
        lb.cases,
        args.seeds,
        lb.violations
    )?;
    if let Some(w) = &lb.worst {
        crate::outln!("    largest M − B = {:.3e}: {}", w.gap(), describe(w))?;
    }
    crate::outln!(
        "(b) M_k^j(π_j) = B_k(π_j): largest |M − B| at π_j = {:.3e}",
        lb.max_gap_at_pi_j
    )?;

    for (name, step) in [
        ("exact APO (maximize M_k^j)", Step::Exact),
        (
            "trust-region surrogate, max over states",
            Step::TrustRegion {
                max_kl: args.max_kl,
                over: OverStates::Max,
            },
        ),
        (
            "trust-region surrogate, average over states (the practical APO)",
            Step::TrustRegion {
                max_kl: args.max_kl,
                over: OverStates::Average,
            },
        ),
    ] {
        let (mut steps, mut decreased, mut worst, mut gained) = (0, 0, 0.0_f64, 0.0);
        for &k in &args.k {
            for seed in 0..args.iteration_seeds {
                let bounds = iterate(
                    &problems,
                    seed,
                    k,
                    step,
                    norm,
                    args.iterations as usize,
                    args.ascent_steps as usize,
                )
                .with_context(|| format!("check (c), seed {seed}"))?;
                if let Some(b) = bounds.iter().find(|b| !b.is_finite()) {
                    bail!(
                        "check (c), {name}, seed {seed}, k {k}: the bound B_k is {b} (not finite); lower --temperature \
                         or --k"
                    );
                }
                let (n, drop) = drops(&bounds, 1e-9);
                steps += bounds.len() - 1;
                decreased += n;
                worst = worst.max(drop);
                gained += bounds[bounds.len() - 1] - bounds[0];
            }
        }
        let runs = args.k.len() as f64 * args.iteration_seeds as f64;
        if args.iteration_seeds == 0 {
            crate::outln!("(c) {name}: skipped (--iteration-seeds 0)")?;
            continue;
        }
        crate::outln!(
            "(c) {name}: B_k decreased in {decreased} of {steps} updates (largest drop {worst:.3e}); mean gain of B_k over {} updates {:.4}",
            args.iterations,
            if runs > 0.0 { gained / runs } else { 0.0 }
        )?;
    }

    if args.selberg_seeds == 0 {
        crate::outln!("(d) Selberg: skipped (--selberg-seeds 0)")?;
        return Ok(());
    }
    let horizon = selberg_horizon(args.gamma);
    let cases = check_selberg(
        &problems,
        0..args.selberg_seeds,
        &args.k,
        args.episodes as usize,
        horizon,
    )
    .context("check (d)")?;
    if let Some(c) = cases
        .iter()
        .find(|c| !(c.empirical.is_finite() && c.confidence.is_finite()))
    {
        bail!(
            "check (d): a case's probability ({}) or Selberg's bound ({}) is not finite; lower --temperature or --k",
            c.empirical,
            c.confidence
        );
    }
    let below = cases
        .iter()
        .filter(|c| c.empirical + 3.0 * c.stderr.max(1.0 / args.episodes as f64) < c.confidence)
        .count();
    let margin = cases
        .iter()
        .map(|c| c.empirical - c.confidence)
        .fold(f64::INFINITY, f64::min);
    crate::outln!(
        "(d) Selberg: P(R ≥ B_k) ≥ 1 − 1/(k²V + 1) on {} cases ({} episodes each, horizon {horizon}): {below} below by more than 3 standard errors; smallest P − bound {margin:.4}",
        cases.len(),
        args.episodes
    )?;
    Ok(())
}

/// `v` as a user reads it: scientific notation when it is very large or very small.
fn number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e5).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The largest discount `apo theory` accepts: check (d)'s horizon is then 20 713 steps.
const MAX_GAMMA: f64 = 0.999;

/// The most environment steps check (d) may sample (a few minutes on one core).
const MAX_SELBERG_STEPS: f64 = 2e9;

/// A horizon at which `γ^h < 1e-9` (the returns' truncation).
fn selberg_horizon(gamma: f64) -> usize {
    if gamma <= 0.0 {
        1
    } else {
        ((1e-9f64).ln() / gamma.ln()).ceil().max(1.0) as usize
    }
}
