//! Finite Markov decision processes with rewards `r(s, a, s')`.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::TheoryError;

/// Tolerance on the sum of a probability vector: `|Σ p − 1| ≤ PROB_TOL`.
pub const PROB_TOL: f64 = 1e-9;

/// A finite, discounted MDP.
///
/// With `S = states` and `A = actions`:
///
/// * `transition` — `P(s'|s,a)`, shape `[S][A][S]`, index `(s * A + a) * S + s'`
///   (see [`Mdp::index`]); every row `P(.|s,a)` is a probability vector;
/// * `reward` — `r(s,a,s')`, same shape and layout as `transition`; the reward is received on
///   the transition `s → s'` taken with action `a`, so it may be random given `(s, a)`;
/// * `start` — the start distribution `μ`, shape `[S]`;
/// * `gamma` — the discount `γ ∈ [0, 1)`.
///
/// The discounted return of an episode is `R = Σ_{t≥0} γ^t r(s_t, a_t, s_{t+1})`.
/// Construct with [`Mdp::new`] (validated), [`Mdp::random`] or one of the hand-made
/// instances; a struct literal is allowed too, followed by [`Mdp::validate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Mdp {
    /// Number of states `S`.
    pub states: usize,
    /// Number of actions `A` (the same in every state).
    pub actions: usize,
    /// `P(s'|s,a)`, `[S][A][S]`, index `(s * A + a) * S + s'`.
    pub transition: Vec<f64>,
    /// `r(s,a,s')`, `[S][A][S]`, index `(s * A + a) * S + s'`.
    pub reward: Vec<f64>,
    /// Start distribution `μ`, `[S]`.
    pub start: Vec<f64>,
    /// Discount `γ ∈ [0, 1)`.
    pub gamma: f64,
}

impl Mdp {
    /// Action "safe" of [`Mdp::safe_or_risky`].
    pub const SAFE_ACTION: usize = 0;
    /// Action "risky" of [`Mdp::safe_or_risky`].
    pub const RISKY_ACTION: usize = 1;
    /// Action "steady" of [`Mdp::chain_gamble`].
    pub const STEADY_ACTION: usize = 0;
    /// Action "gamble" of [`Mdp::chain_gamble`].
    pub const GAMBLE_ACTION: usize = 1;
    /// Probability that a gamble of [`Mdp::chain_gamble`] loses.
    pub const GAMBLE_LOSS_PROB: f64 = 0.1;
    /// Reward of a won gamble in [`Mdp::chain_gamble`].
    pub const GAMBLE_WIN: f64 = 2.0;
    /// Reward of a lost gamble in [`Mdp::chain_gamble`].
    pub const GAMBLE_LOSS: f64 = -8.0;

    /// Builds an MDP and [validates](Mdp::validate) it.
    ///
    /// `transition` and `reward` are `[S][A][S]` (index `(s * A + a) * S + s'`), `start` is `[S]`.
    pub fn new(
        states: usize,
        actions: usize,
        transition: Vec<f64>,
        reward: Vec<f64>,
        start: Vec<f64>,
        gamma: f64,
    ) -> Result<Self, TheoryError> {
        let mdp = Self {
            states,
            actions,
            transition,
            reward,
            start,
            gamma,
        };
        mdp.validate()?;
        Ok(mdp)
    }

    /// Flat index of `(s, a, s')` in `transition` and `reward`: `(s * A + a) * S + s'`.
    #[inline]
    pub fn index(&self, s: usize, a: usize, s_next: usize) -> usize {
        (s * self.actions + a) * self.states + s_next
    }

    /// `P(s'|s,a)`.
    #[inline]
    pub fn p(&self, s: usize, a: usize, s_next: usize) -> f64 {
        self.transition[self.index(s, a, s_next)]
    }

    /// `r(s,a,s')`.
    #[inline]
    pub fn r(&self, s: usize, a: usize, s_next: usize) -> f64 {
        self.reward[self.index(s, a, s_next)]
    }

    /// The row `P(.|s,a)`, `[S]`.
    pub fn transition_row(&self, s: usize, a: usize) -> &[f64] {
        let i = self.index(s, a, 0);
        &self.transition[i..i + self.states]
    }

    /// The row `r(s,a,.)`, `[S]`.
    pub fn reward_row(&self, s: usize, a: usize) -> &[f64] {
        let i = self.index(s, a, 0);
        &self.reward[i..i + self.states]
    }

    /// `max |r(s,a,s')|` over all entries (0 for an empty table).
    pub fn max_abs_reward(&self) -> f64 {
        self.reward.iter().fold(0.0, |m, r| m.max(r.abs()))
    }

    /// The same MDP with another start distribution `μ` (`[S]`), validated.
    pub fn with_start(&self, start: Vec<f64>) -> Result<Self, TheoryError> {
        let mdp = Self {
            start,
            ..self.clone()
        };
        mdp.validate()?;
        Ok(mdp)
    }

    /// A random MDP, deterministic given `seed`.
    ///
    /// * every row `P(.|s,a)` is Dirichlet(1, …, 1): `S` independent standard exponentials,
    ///   normalized;
    /// * every reward `r(s,a,s')` is uniform in `[-1, 1)`;
    /// * `μ(s) ∝ 0.1 + U[0, 1)`, so every state has positive start probability.
    ///
    /// The draws come from `StdRng::seed_from_u64(seed)` in that order (all transition rows in
    /// index order, then all rewards, then the start weights).
    ///
    /// # Panics
    /// If `states == 0`, `actions == 0` or `γ ∉ [0, 1)`.
    pub fn random(states: usize, actions: usize, gamma: f64, seed: u64) -> Self {
        assert!(states >= 1, "Mdp::random: states must be at least 1");
        assert!(actions >= 1, "Mdp::random: actions must be at least 1");
        assert!(
            (0.0..1.0).contains(&gamma),
            "Mdp::random: gamma = {gamma} is outside [0, 1)"
        );
        let mut rng = StdRng::seed_from_u64(seed);
        let n = states * actions * states;
        let mut transition = vec![0.0; n];
        for row in transition.chunks_mut(states) {
            for p in row.iter_mut() {
                // 1 - U lies in (0, 1], so the exponential is finite.
                let u: f64 = rng.random();
                *p = -(1.0 - u).ln();
            }
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                row.iter_mut().for_each(|p| *p /= sum);
            } else {
                // Only possible if every draw was exactly 0: fall back to uniform.
                row.iter_mut().for_each(|p| *p = 1.0 / states as f64);
            }
        }
        let reward: Vec<f64> = (0..n).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
        let mut start: Vec<f64> = (0..states).map(|_| 0.1 + rng.random::<f64>()).collect();
        let sum: f64 = start.iter().sum();
        start.iter_mut().for_each(|p| *p /= sum);
        Self {
            states,
            actions,
            transition,
            reward,
            start,
            gamma,
        }
    }

    /// Checks the MDP: non-empty spaces, `γ ∈ [0, 1)`, table lengths, finite entries,
    /// non-negative probabilities, every row `P(.|s,a)` and `μ` summing to 1 within
    /// [`PROB_TOL`]. The error names the first offending entry.
    pub fn validate(&self) -> Result<(), TheoryError> {
        let (ns, na) = (self.states, self.actions);
        if ns == 0 {
            return Err(TheoryError::EmptySpace { what: "states" });
        }
        if na == 0 {
            return Err(TheoryError::EmptySpace { what: "actions" });
        }
        if !(self.gamma.is_finite() && (0.0..1.0).contains(&self.gamma)) {
            return Err(TheoryError::InvalidGamma(self.gamma));
        }
        let n = ns * na * ns;
        check_len("transition", n, self.transition.len())?;
        check_len("reward", n, self.reward.len())?;
        check_len("start", ns, self.start.len())?;
        for s in 0..ns {
            for a in 0..na {
                let row = self.transition_row(s, a);
                for (s_next, &p) in row.iter().enumerate() {
                    let what = || format!("transition P(s'={s_next} | s={s}, a={a})");
                    check_prob(p, what)?;
                }
                check_sum(row, || format!("transition row P(.|s={s}, a={a})"))?;
                for (s_next, &r) in self.reward_row(s, a).iter().enumerate() {
                    if !r.is_finite() {
                        return Err(TheoryError::NonFinite {
                            what: format!("reward r(s={s}, a={a}, s'={s_next})"),
                            value: r,
                        });
                    }
                }
            }
        }
        for (s, &p) in self.start.iter().enumerate() {
            check_prob(p, || format!("start distribution μ(s={s})"))?;
        }
        check_sum(&self.start, || "start distribution μ".to_string())?;
        Ok(())
    }

    /// One state, one action, a self-loop with reward `reward` on every step.
    ///
    /// The return is deterministic: `V = J = reward / (1 − γ)`, variance 0.
    ///
    /// # Panics
    /// If `γ ∉ [0, 1)` or `reward` is not finite.
    pub fn single_state(reward: f64, gamma: f64) -> Self {
        Self::new(1, 1, vec![1.0], vec![reward], vec![1.0], gamma)
            .expect("Mdp::single_state: invalid reward or gamma")
    }

    /// Two states, one action, a deterministic cycle `0 → 1 → 0 → …` with reward `r0` on the
    /// step out of state 0 and `r1` on the step out of state 1; `μ = (½, ½)`.
    ///
    /// The return from each state is deterministic, `V(0) = (r0 + γ r1) / (1 − γ²)` and
    /// `V(1) = (r1 + γ r0) / (1 − γ²)`, so all of the return variance comes from the random
    /// start state: `MV_π = 0` and `VM_π = ((V(0) − V(1)) / 2)²`.
    ///
    /// # Panics
    /// If `γ ∉ [0, 1)` or a reward is not finite.
    pub fn two_state_cycle(r0: f64, r1: f64, gamma: f64) -> Self {
        // index (s * 1 + 0) * 2 + s'
        let transition = vec![0.0, 1.0, 1.0, 0.0];
        let reward = vec![0.0, r0, r1, 0.0];
        Self::new(2, 1, transition, reward, vec![0.5, 0.5], gamma)
            .expect("Mdp::two_state_cycle: invalid reward or gamma")
    }

    /// Same mean, different variance, in one step.
    ///
    /// Three states, two actions, `μ = δ_0`:
    ///
    /// * state 0 (start): action [`SAFE_ACTION`](Mdp::SAFE_ACTION) = 0 gives reward 1 and
    ///   moves to state 1; action [`RISKY_ACTION`](Mdp::RISKY_ACTION) = 1 moves to state 1 with
    ///   reward +3 or to state 2 with reward −1, with probability ½ each;
    /// * states 1 and 2: absorbing (every action self-loops) with reward 0. They differ only so
    ///   that the risky reward `r(0, 1, s')` can depend on the outcome `s'`.
    ///
    /// The return is the first reward, whatever `γ`: always-safe has `J = 1` and return
    /// variance 0, always-risky `J = 1` and return variance `½·2² + ½·2² = 4`; a policy taking
    /// the risky action with probability `p` in state 0 has `J = 1` and variance `4p`.
    ///
    /// # Panics
    /// If `γ ∉ [0, 1)`.
    pub fn safe_or_risky(gamma: f64) -> Self {
        let (ns, na) = (3, 2);
        let mut m = Self::zeroed(ns, na, gamma);
        m.start[0] = 1.0;
        let i = m.index(0, Self::SAFE_ACTION, 1);
        m.transition[i] = 1.0;
        m.reward[i] = 1.0;
        let i = m.index(0, Self::RISKY_ACTION, 1);
        m.transition[i] = 0.5;
        m.reward[i] = 3.0;
        let i = m.index(0, Self::RISKY_ACTION, 2);
        m.transition[i] = 0.5;
        m.reward[i] = -1.0;
        m.make_absorbing(1);
        m.make_absorbing(2);
        m.validate().expect("Mdp::safe_or_risky: invalid gamma");
        m
    }

    /// A chain of `length` decisions where one action is a gamble with a small probability of
    /// a large loss, and the same mean as the safe action.
    ///
    /// States come in pairs: position `i ∈ 0..=length` has states `2i` ("last step went
    /// well") and `2i + 1` ("last step was a loss"), which behave identically — the pair only
    /// lets the reward `r(s,a,s')` depend on the outcome. In total `2·(length + 1)` states, two
    /// actions, `μ = δ_0`. From either state of position `i < length`:
    ///
    /// * [`STEADY_ACTION`](Mdp::STEADY_ACTION) = 0: reward 1, move to state `2(i+1)`;
    /// * [`GAMBLE_ACTION`](Mdp::GAMBLE_ACTION) = 1: with probability
    ///   `1 − `[`GAMBLE_LOSS_PROB`](Mdp::GAMBLE_LOSS_PROB)` = 0.9` reward
    ///   [`GAMBLE_WIN`](Mdp::GAMBLE_WIN)` = +2` and move to `2(i+1)`; with probability 0.1
    ///   reward [`GAMBLE_LOSS`](Mdp::GAMBLE_LOSS)` = −8` and move to `2(i+1) + 1`.
    ///
    /// Both states of position `length` are absorbing with reward 0. Each step's reward has
    /// mean 1 under either action, and the gamble's variance is `0.9·1² + 0.1·9² = 9`. Hence
    /// *every* policy has `V(2i) = V(2i+1) = Σ_{t<length−i} γ^t` and
    /// `J = (1 − γ^length) / (1 − γ)`, while a policy gambling with probability `p` at every
    /// position has return variance `9p · Σ_{t<length} γ^{2t}`.
    ///
    /// # Panics
    /// If `length == 0` or `γ ∉ [0, 1)`.
    pub fn chain_gamble(length: usize, gamma: f64) -> Self {
        assert!(length >= 1, "Mdp::chain_gamble: length must be at least 1");
        let (ns, na) = (2 * (length + 1), 2);
        let mut m = Self::zeroed(ns, na, gamma);
        m.start[0] = 1.0;
        for i in 0..length {
            let (good, bad) = (2 * (i + 1), 2 * (i + 1) + 1);
            for s in [2 * i, 2 * i + 1] {
                let k = m.index(s, Self::STEADY_ACTION, good);
                m.transition[k] = 1.0;
                m.reward[k] = 1.0;
                let k = m.index(s, Self::GAMBLE_ACTION, good);
                m.transition[k] = 1.0 - Self::GAMBLE_LOSS_PROB;
                m.reward[k] = Self::GAMBLE_WIN;
                let k = m.index(s, Self::GAMBLE_ACTION, bad);
                m.transition[k] = Self::GAMBLE_LOSS_PROB;
                m.reward[k] = Self::GAMBLE_LOSS;
            }
        }
        m.make_absorbing(2 * length);
        m.make_absorbing(2 * length + 1);
        m.validate().expect("Mdp::chain_gamble: invalid gamma");
        m
    }

    /// All-zero tables of the right sizes (not a valid MDP until filled in).
    fn zeroed(states: usize, actions: usize, gamma: f64) -> Self {
        let n = states * actions * states;
        Self {
            states,
            actions,
            transition: vec![0.0; n],
            reward: vec![0.0; n],
            start: vec![0.0; states],
            gamma,
        }
    }

    /// Makes `s` absorbing: every action self-loops with reward 0.
    fn make_absorbing(&mut self, s: usize) {
        for a in 0..self.actions {
            for s_next in 0..self.states {
                let k = self.index(s, a, s_next);
                self.transition[k] = if s_next == s { 1.0 } else { 0.0 };
                self.reward[k] = 0.0;
            }
        }
    }
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), TheoryError> {
    if expected == got {
        Ok(())
    } else {
        Err(TheoryError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}

/// A finite, non-negative probability.
pub(crate) fn check_prob(p: f64, what: impl FnOnce() -> String) -> Result<(), TheoryError> {
    if !p.is_finite() {
        Err(TheoryError::NonFinite {
            what: what(),
            value: p,
        })
    } else if p < 0.0 {
        Err(TheoryError::NegativeProbability {
            what: what(),
            value: p,
        })
    } else {
        Ok(())
    }
}

/// A vector summing to 1 within [`PROB_TOL`].
pub(crate) fn check_sum(row: &[f64], what: impl FnOnce() -> String) -> Result<(), TheoryError> {
    let sum: f64 = row.iter().sum();
    if (sum - 1.0).abs() <= PROB_TOL {
        Ok(())
    } else {
        Err(TheoryError::NotNormalized { what: what(), sum })
    }
}
