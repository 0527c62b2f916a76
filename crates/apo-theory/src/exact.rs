//! Exact policy evaluation: values, advantages, discounted state distribution, and the mean
//! and variance of the discounted return.

use nalgebra::{DMatrix, DVector};

use crate::{Mdp, TabularPolicy, TheoryError};

/// Everything about a policy `π` on an MDP that can be computed exactly, by LU solves of
/// `S × S` linear systems. Computed once by [`Evaluation::new`].
///
/// With `R(s) = Σ_{t≥0} γ^t r(s_t, a_t, s_{t+1})` the discounted return from `s_0 = s` under
/// `π`, and `q3(s,a,s') = r(s,a,s') + γ V(s')` the value of the transition `(s, a, s')`:
///
/// | field / method        | shape       | index                  | meaning |
/// |-----------------------|-------------|------------------------|---------|
/// | `p_pi`                | `[S][S]`    | `s * S + s'`           | `P_π(s'\|s) = Σ_a π(a\|s) P(s'\|s,a)` |
/// | `r_pi`                | `[S]`       | `s`                    | `r_π(s) = Σ_a π(a\|s) Σ_s' P(s'\|s,a) r(s,a,s')` |
/// | `v`                   | `[S]`       | `s`                    | `V(s) = E[R(s)]`, solves `(I − γ P_π) V = r_π` |
/// | `q_sas`, [`Self::q3`] | `[S][A][S]` | `(s * A + a) * S + s'` | `q3(s,a,s') = r(s,a,s') + γ V(s')` |
/// | [`Self::a3`]          |             |                        | `q3(s,a,s') − V(s)` |
/// | `q`                   | `[S][A]`    | `s * A + a`            | `Q(s,a) = Σ_s' P(s'\|s,a) q3(s,a,s')` |
/// | `adv`                 | `[S][A]`    | `s * A + a`            | `A(s,a) = Q(s,a) − V(s)` |
/// | `j`                   | scalar      |                        | `J = Σ_s μ(s) V(s)` |
/// | `d`                   | `[S]`       | `s`                    | `d^π = (1 − γ) μᵀ (I − γ P_π)^{-1}` |
/// | `m2`                  | `[S]`       | `s`                    | `M(s) = E[R(s)²]` |
/// | [`Self::var_from`]    |             |                        | `Var[R(s)] = M(s) − V(s)²` |
/// | `omega`               | `[S]`       | `s`                    | `ω_π(s) = E_{a∼π,s'∼P}[q3(s,a,s')²] − V(s)²` |
/// | `return_variance`     | scalar      |                        | `Var[R(s_0)]`, `s_0 ∼ μ`: `Σ μ M − J²` |
/// | `mean_variance`       | scalar      |                        | `MV_π = Σ_s μ(s) Var[R(s)]` |
/// | `variance_mean`       | scalar      |                        | `VM_π = Σ_s μ(s) V(s)² − J²` |
///
/// `return_variance = mean_variance + variance_mean` is the law of total variance over the
/// start state. The per-state variance also satisfies the variance Bellman equation
/// `Var[R(s)] = ω_π(s) + γ² Σ_s' P_π(s'|s) Var[R(s')]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Number of states `S`.
    pub states: usize,
    /// Number of actions `A`.
    pub actions: usize,
    /// The discount `γ`.
    pub gamma: f64,
    /// `P_π(s'|s)`, `[S][S]`, index `s * S + s'`.
    pub p_pi: Vec<f64>,
    /// `r_π(s)`, expected one-step reward, `[S]`.
    pub r_pi: Vec<f64>,
    /// `V(s)`, `[S]`.
    pub v: Vec<f64>,
    /// `q3(s,a,s') = r(s,a,s') + γ V(s')`, `[S][A][S]`, index `(s * A + a) * S + s'`.
    pub q_sas: Vec<f64>,
    /// `Q(s,a)`, `[S][A]`, index `s * A + a`.
    pub q: Vec<f64>,
    /// `A(s,a) = Q(s,a) − V(s)`, `[S][A]`, index `s * A + a`.
    pub adv: Vec<f64>,
    /// `J = Σ_s μ(s) V(s)`.
    pub j: f64,
    /// Normalized discounted state distribution `d^π(s) = (1 − γ) Σ_t γ^t Pr(s_t = s)`, `[S]`.
    pub d: Vec<f64>,
    /// Second moment of the return `M(s) = E[R(s)²]`, `[S]`; solves
    /// `M(s) = Σ_a π(a|s) Σ_s' P(s'|s,a) [r² + 2γ r V(s') + γ² M(s')]` (Sobel 1982).
    pub m2: Vec<f64>,
    /// `Var[R(s_0)]` with `s_0 ∼ μ`: `Σ_s μ(s) M(s) − J²`.
    pub return_variance: f64,
    /// `MV_π = E_{s_0∼μ}[Var[R(s_0)]] = Σ_s μ(s) (M(s) − V(s)²)`.
    pub mean_variance: f64,
    /// `VM_π = Var_{s_0∼μ}[V(s_0)] = Σ_s μ(s) V(s)² − J²`.
    pub variance_mean: f64,
    /// `ω_π(s) = E_{a∼π, s'∼P}[q3(s,a,s')²] − V(s)²`, the variance of the transition value at
    /// `s`, `[S]`.
    pub omega: Vec<f64>,
}

impl Evaluation {
    /// Evaluates `policy` on `mdp` exactly.
    ///
    /// Validates both, checks their shapes agree, and solves three `S × S` systems by LU:
    /// `(I − γ P_π) V = r_π`, `(I − γ P_π)ᵀ d = (1 − γ) μ` and `(I − γ² P_π) M = b`.
    /// Returns [`TheoryError::SingularSystem`] instead of panicking if a solve fails.
    pub fn new(mdp: &Mdp, policy: &TabularPolicy) -> Result<Self, TheoryError> {
        mdp.validate()?;
        policy.validate()?;
        if mdp.states != policy.states || mdp.actions != policy.actions {
            return Err(TheoryError::ShapeMismatch {
                mdp_states: mdp.states,
                mdp_actions: mdp.actions,
                policy_states: policy.states,
                policy_actions: policy.actions,
            });
        }
        let (ns, na, gamma) = (mdp.states, mdp.actions, mdp.gamma);

        // P_π and r_π.
        let mut p_pi = vec![0.0; ns * ns];
        let mut r_pi = vec![0.0; ns];
        for s in 0..ns {
            for a in 0..na {
                let pa = policy.prob(s, a);
                if pa == 0.0 {
                    continue;
                }
                for (s2, (&p, &r)) in mdp
                    .transition_row(s, a)
                    .iter()
                    .zip(mdp.reward_row(s, a))
                    .enumerate()
                {
                    p_pi[s * ns + s2] += pa * p;
                    r_pi[s] += pa * p * r;
                }
            }
        }

        // V: (I − γ P_π) V = r_π.
        let i_minus = |scale: f64| {
            DMatrix::from_fn(ns, ns, |i, k| {
                let id = if i == k { 1.0 } else { 0.0 };
                id - scale * p_pi[i * ns + k]
            })
        };
        let a_v = i_minus(gamma);
        let v = solve(
            a_v.clone(),
            DVector::from_column_slice(&r_pi),
            "V = (I - γ P_π)^-1 r_π",
        )?;

        // d: (I − γ P_π)ᵀ d = (1 − γ) μ.
        let mu_scaled = DVector::from_iterator(ns, mdp.start.iter().map(|m| (1.0 - gamma) * m));
        let d = solve(a_v.transpose(), mu_scaled, "d = (1 - γ) (I - γ P_π)^-T μ")?;

        // q3, Q, A, ω and the right-hand side of the second-moment system.
        let mut q_sas = vec![0.0; ns * na * ns];
        let mut q = vec![0.0; ns * na];
        let mut adv = vec![0.0; ns * na];
        let mut omega = vec![0.0; ns];
        let mut b = vec![0.0; ns];
        for s in 0..ns {
            let mut eq2 = 0.0;
            for a in 0..na {
                let pa = policy.prob(s, a);
                let mut qsa = 0.0;
                for (s2, &v_next) in v.iter().enumerate() {
                    let k = mdp.index(s, a, s2);
                    let (p, r) = (mdp.transition[k], mdp.reward[k]);
                    let q3 = r + gamma * v_next;
                    q_sas[k] = q3;
                    qsa += p * q3;
                    eq2 += pa * p * q3 * q3;
                    b[s] += pa * p * (r * r + 2.0 * gamma * r * v_next);
                }
                q[s * na + a] = qsa;
                adv[s * na + a] = qsa - v[s];
            }
            omega[s] = eq2 - v[s] * v[s];
        }

        // M: (I − γ² P_π) M = b.
        let m2 = solve(
            i_minus(gamma * gamma),
            DVector::from_column_slice(&b),
            "M = (I - γ² P_π)^-1 b",
        )?;

        let mu = &mdp.start;
        let j: f64 = mu.iter().zip(&v).map(|(m, v)| m * v).sum();
        let e_m2: f64 = mu.iter().zip(&m2).map(|(m, x)| m * x).sum();
        let e_v2: f64 = mu.iter().zip(&v).map(|(m, v)| m * v * v).sum();
        let mean_variance: f64 = mu
            .iter()
            .zip(m2.iter().zip(&v))
            .map(|(m, (x, v))| m * (x - v * v))
            .sum();

        Ok(Self {
            states: ns,
            actions: na,
            gamma,
            p_pi,
            r_pi,
            v,
            q_sas,
            q,
            adv,
            j,
            d,
            m2,
            return_variance: e_m2 - j * j,
            mean_variance,
            variance_mean: e_v2 - j * j,
            omega,
        })
    }

    /// `q3(s,a,s') = r(s,a,s') + γ V(s')`.
    #[inline]
    pub fn q3(&self, s: usize, a: usize, s_next: usize) -> f64 {
        self.q_sas[(s * self.actions + a) * self.states + s_next]
    }

    /// `a3(s,a,s') = q3(s,a,s') − V(s)`.
    #[inline]
    pub fn a3(&self, s: usize, a: usize, s_next: usize) -> f64 {
        self.q3(s, a, s_next) - self.v[s]
    }

    /// `Q(s,a)`.
    #[inline]
    pub fn q_at(&self, s: usize, a: usize) -> f64 {
        self.q[s * self.actions + a]
    }

    /// `A(s,a) = Q(s,a) − V(s)`.
    #[inline]
    pub fn adv_at(&self, s: usize, a: usize) -> f64 {
        self.adv[s * self.actions + a]
    }

    /// `Var[R(s)] = M(s) − V(s)²`, the variance of the discounted return from `s_0 = s`.
    /// (May be a round-off-sized negative number when the true variance is 0.)
    #[inline]
    pub fn var_from(&self, s: usize) -> f64 {
        self.m2[s] - self.v[s] * self.v[s]
    }

    /// `E_{s_0 = s, τ∼π}[Σ_t γ^t f(s_t)]` for every state, `[S]`: the solution `x` of
    /// `(I − γ P_π) x = f` (`f` is `[S]`).
    pub fn discounted_sum(&self, f: &[f64]) -> Result<Vec<f64>, TheoryError> {
        let n = self.states;
        if f.len() != n {
            return Err(TheoryError::LengthMismatch {
                what: "discounted_sum's f",
                expected: n,
                got: f.len(),
            });
        }
        let a = DMatrix::from_fn(n, n, |i, k| {
            f64::from(u8::from(i == k)) - self.gamma * self.p_pi[i * n + k]
        });
        solve(a, DVector::from_column_slice(f), "(I − γ P_π) x = f")
    }

    /// `[Var[R(s)]]_s`, `[S]`: [`Self::var_from`] for every state.
    pub fn variances_from(&self) -> Vec<f64> {
        (0..self.states).map(|s| self.var_from(s)).collect()
    }
}

/// Solves `a x = b` by LU; an error if `a` is singular or `x` is not finite.
fn solve(a: DMatrix<f64>, b: DVector<f64>, what: &'static str) -> Result<Vec<f64>, TheoryError> {
    let x = a
        .lu()
        .solve(&b)
        .ok_or(TheoryError::SingularSystem { what })?;
    if x.iter().all(|v| v.is_finite()) {
        Ok(x.as_slice().to_vec())
    } else {
        Err(TheoryError::SingularSystem { what })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn singular_system_is_an_error_not_a_panic() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        let b = DVector::from_column_slice(&[1.0, 1.0]);
        assert_eq!(
            solve(a, b, "test"),
            Err(TheoryError::SingularSystem { what: "test" })
        );
    }

    #[test]
    fn regular_system_is_solved() {
        let a = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 3.0]);
        let b = DVector::from_column_slice(&[3.0, 5.0]);
        let x = solve(a, b, "test").unwrap();
        assert!(
            (x[0] - 0.8).abs() < 1e-12 && (x[1] - 1.4).abs() < 1e-12,
            "{x:?}"
        );
    }
}
