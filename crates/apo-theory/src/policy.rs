//! Tabular stochastic policies `π(a|s)` and divergences between them.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use crate::mdp::{check_prob, check_sum};
use crate::TheoryError;

/// A stochastic policy on `S = states` states and `A = actions` actions.
///
/// `probs` is `π(a|s)`, shape `[S][A]`, index `s * A + a`; every row is a probability vector.
#[derive(Debug, Clone, PartialEq)]
pub struct TabularPolicy {
    /// Number of states `S`.
    pub states: usize,
    /// Number of actions `A`.
    pub actions: usize,
    /// `π(a|s)`, `[S][A]`, index `s * A + a`.
    pub probs: Vec<f64>,
}

impl TabularPolicy {
    /// The uniform policy `π(a|s) = 1/A`.
    ///
    /// # Panics
    /// If `states == 0` or `actions == 0`.
    pub fn uniform(states: usize, actions: usize) -> Self {
        assert!(states >= 1 && actions >= 1, "TabularPolicy: empty space");
        Self {
            states,
            actions,
            probs: vec![1.0 / actions as f64; states * actions],
        }
    }

    /// A policy from given probabilities (`[S][A]`, index `s * A + a`), validated.
    pub fn from_probs(states: usize, actions: usize, probs: Vec<f64>) -> Result<Self, TheoryError> {
        let pi = Self {
            states,
            actions,
            probs,
        };
        pi.validate()?;
        Ok(pi)
    }

    /// The deterministic policy taking action `choice[s]` in state `s` (`choice` is `[S]`).
    ///
    /// # Panics
    /// If `choice.len() != states` or an action is `≥ actions`.
    pub fn deterministic(states: usize, actions: usize, choice: &[usize]) -> Self {
        assert_eq!(
            choice.len(),
            states,
            "TabularPolicy::deterministic: one action per state"
        );
        let mut probs = vec![0.0; states * actions];
        for (s, &a) in choice.iter().enumerate() {
            assert!(
                a < actions,
                "TabularPolicy::deterministic: action {a} in state {s} is out of range"
            );
            probs[s * actions + a] = 1.0;
        }
        Self {
            states,
            actions,
            probs,
        }
    }

    /// Row-wise softmax of `logits` (`[S][A]`, index `s * A + a`):
    /// `π(a|s) = exp(z_{s,a} − max_b z_{s,b}) / Σ_b exp(z_{s,b} − max_b z_{s,b})`.
    ///
    /// Subtracting the row maximum keeps it finite for any finite logits. A logit of `−∞`
    /// gives probability 0 (as long as the row has a finite logit).
    ///
    /// # Panics
    /// If `logits.len() != states * actions`, a space is empty, or a row's maximum is not
    /// finite (NaN or `+∞` logits, or a row of only `−∞`).
    pub fn from_logits(states: usize, actions: usize, logits: &[f64]) -> Self {
        assert!(states >= 1 && actions >= 1, "TabularPolicy: empty space");
        assert_eq!(
            logits.len(),
            states * actions,
            "TabularPolicy::from_logits: logits must have length states * actions"
        );
        let mut probs = vec![0.0; states * actions];
        for (row, z) in probs.chunks_mut(actions).zip(logits.chunks(actions)) {
            let max = z.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
            assert!(
                max.is_finite() && z.iter().all(|x| !x.is_nan()),
                "TabularPolicy::from_logits: row {z:?} has no finite maximum"
            );
            for (p, &x) in row.iter_mut().zip(z) {
                *p = (x - max).exp();
            }
            let sum: f64 = row.iter().sum();
            row.iter_mut().for_each(|p| *p /= sum);
        }
        Self {
            states,
            actions,
            probs,
        }
    }

    /// A random softmax policy, deterministic given `seed`: logits `z_{s,a} ~ N(0, 1)` i.i.d.
    /// (drawn from `StdRng::seed_from_u64(seed)` in index order), `π = softmax(z / temperature)`
    /// row-wise. Small temperatures give nearly deterministic policies, large ones nearly
    /// uniform policies.
    ///
    /// # Panics
    /// If a space is empty or `temperature` is not finite and positive.
    pub fn random(states: usize, actions: usize, seed: u64, temperature: f64) -> Self {
        assert!(
            temperature.is_finite() && temperature > 0.0,
            "TabularPolicy::random: temperature must be finite and positive, got {temperature}"
        );
        let mut rng = StdRng::seed_from_u64(seed);
        let logits: Vec<f64> = (0..states * actions)
            .map(|_| rng.sample::<f64, _>(StandardNormal) / temperature)
            .collect();
        Self::from_logits(states, actions, &logits)
    }

    /// Checks non-empty spaces, the length of `probs`, and that every row is a finite,
    /// non-negative probability vector summing to 1 within [`PROB_TOL`](crate::PROB_TOL).
    pub fn validate(&self) -> Result<(), TheoryError> {
        if self.states == 0 {
            return Err(TheoryError::EmptySpace { what: "states" });
        }
        if self.actions == 0 {
            return Err(TheoryError::EmptySpace { what: "actions" });
        }
        let expected = self.states * self.actions;
        if self.probs.len() != expected {
            return Err(TheoryError::LengthMismatch {
                what: "policy probs",
                expected,
                got: self.probs.len(),
            });
        }
        for s in 0..self.states {
            let row = self.row(s);
            for (a, &p) in row.iter().enumerate() {
                check_prob(p, || format!("policy π(a={a} | s={s})"))?;
            }
            check_sum(row, || format!("policy row π(.|s={s})"))?;
        }
        Ok(())
    }

    /// `π(a|s)`.
    #[inline]
    pub fn prob(&self, s: usize, a: usize) -> f64 {
        self.probs[s * self.actions + a]
    }

    /// The row `π(.|s)`, `[A]`.
    pub fn row(&self, s: usize) -> &[f64] {
        &self.probs[s * self.actions..(s + 1) * self.actions]
    }

    /// `KL(self(.|s) ‖ other(.|s)) = Σ_a p_a ln(p_a / q_a)` with `p = self`, `q = other`.
    ///
    /// Terms with `p_a = 0` count 0; a term with `p_a > 0 = q_a` makes it `+∞`.
    ///
    /// # Panics
    /// If the policies have different shapes.
    pub fn kl(&self, other: &Self, s: usize) -> f64 {
        self.assert_same_shape(other);
        self.row(s)
            .iter()
            .zip(other.row(s))
            .map(|(&p, &q)| {
                if p <= 0.0 {
                    0.0
                } else if q <= 0.0 {
                    f64::INFINITY
                } else {
                    p * (p.ln() - q.ln())
                }
            })
            .sum()
    }

    /// `max_s KL(self(.|s) ‖ other(.|s))`.
    ///
    /// # Panics
    /// If the policies have different shapes.
    pub fn max_kl(&self, other: &Self) -> f64 {
        (0..self.states)
            .map(|s| self.kl(other, s))
            .fold(0.0, f64::max)
    }

    /// Total variation `½ Σ_a |self(a|s) − other(a|s)|`, in `[0, 1]`.
    ///
    /// # Panics
    /// If the policies have different shapes.
    pub fn tv(&self, other: &Self, s: usize) -> f64 {
        self.assert_same_shape(other);
        0.5 * self
            .row(s)
            .iter()
            .zip(other.row(s))
            .map(|(p, q)| (p - q).abs())
            .sum::<f64>()
    }

    /// `max_s TV(self(.|s), other(.|s))`.
    ///
    /// # Panics
    /// If the policies have different shapes.
    pub fn max_tv(&self, other: &Self) -> f64 {
        (0..self.states)
            .map(|s| self.tv(other, s))
            .fold(0.0, f64::max)
    }

    fn assert_same_shape(&self, other: &Self) {
        assert!(
            self.states == other.states && self.actions == other.actions,
            "TabularPolicy: shapes differ ({}x{} vs {}x{})",
            self.states,
            self.actions,
            other.states,
            other.actions
        );
    }
}
