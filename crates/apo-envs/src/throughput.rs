//! Throughput of any environment, or of a vector of them, under random actions
//! (`apo bench env`).

use std::time::Instant;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::env::{Action, Env};
use crate::space::Space;
use crate::vector::{VecEnv, VecStep};

/// Number of random actions drawn before timing and then cycled through, so that the timed
/// loop measures the environment and not the random number generator.
const ACTION_POOL: usize = 1024;

/// Runs `steps` steps of `env` with uniformly random actions (box bounds; an infinite bound
/// is replaced by ±1), resetting whenever an episode ends, and returns environment steps per
/// second of wall time, resets included. Seeded by `seed`. Returns 0 when `steps` is 0.
pub fn steps_per_second(env: &mut dyn Env, steps: usize, seed: u64) -> f64 {
    if steps == 0 {
        return 0.0;
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let space = env.action_space().clone();
    let pool: Vec<Vec<f32>> = (0..ACTION_POOL)
        .map(|_| random_action(&space, &mut rng))
        .collect();
    let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
    env.reset(Some(seed), &mut obs);
    let start = Instant::now();
    for (i, action) in pool.iter().cycle().take(steps).enumerate() {
        let action = match space {
            Space::Discrete { .. } => Action::Discrete(action[0] as usize),
            Space::Box { .. } => Action::Continuous(action),
        };
        if env.step(action, &mut obs).done() {
            env.reset(None, &mut obs);
        }
        std::hint::black_box((i, &obs));
    }
    steps as f64 / start.elapsed().as_secs_f64()
}

/// [`steps_per_second`] for a vector of environments: `steps` environment steps in all
/// (rounded up to whole vector steps), random actions, automatic resets; environment steps
/// per second of wall time. Returns 0 when `steps` is 0.
pub fn vector_steps_per_second(envs: &mut VecEnv, steps: usize, seed: u64) -> f64 {
    if steps == 0 {
        return 0.0;
    }
    let n = envs.num_envs();
    let mut rng = StdRng::seed_from_u64(seed);
    // at least one whole vector step of actions, whatever the number of environments
    let pool: Vec<f32> = (0..ACTION_POOL.max(n))
        .flat_map(|_| random_action(envs.action_space(), &mut rng))
        .collect();
    let width = envs.act_dim() * n;
    let mut obs = vec![0.0f32; envs.obs_dim() * n];
    let mut out = vec![VecStep::default(); n];
    envs.reset(Some(seed), &mut obs);
    let rounds = steps.div_ceil(n);
    let start = Instant::now();
    for (round, actions) in pool.chunks_exact(width).cycle().take(rounds).enumerate() {
        envs.step(actions, &mut obs, &mut out);
        std::hint::black_box((round, &obs));
    }
    (rounds * n) as f64 / start.elapsed().as_secs_f64()
}

fn random_action(space: &Space, rng: &mut StdRng) -> Vec<f32> {
    match space {
        Space::Box { low, high, .. } => low
            .iter()
            .zip(high)
            .map(|(&lo, &hi)| {
                let (lo, hi) = (
                    if lo.is_finite() { lo } else { -1.0 },
                    if hi.is_finite() { hi } else { 1.0 },
                );
                if lo < hi {
                    rng.random_range(lo..=hi)
                } else {
                    lo
                }
            })
            .collect(),
        Space::Discrete { n } => vec![rng.random_range(0..(*n).max(1)) as f32],
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    use super::*;
    use crate::env::Transition;

    /// An environment that counts its steps.
    struct Counting {
        steps: Arc<AtomicUsize>,
        space: Space,
    }

    impl Env for Counting {
        fn observation_space(&self) -> &Space {
            &self.space
        }
        fn action_space(&self) -> &Space {
            &self.space
        }
        fn reset(&mut self, _: Option<u64>, obs: &mut [f32]) {
            obs.fill(0.0);
        }
        fn step(&mut self, _: Action<'_>, _: &mut [f32]) -> Transition {
            self.steps.fetch_add(1, Ordering::Relaxed);
            Transition::default()
        }
    }

    #[test]
    fn every_environment_of_a_vector_wider_than_the_action_pool_is_stepped() {
        let steps = Arc::new(AtomicUsize::new(0));
        let n = ACTION_POOL + 76;
        let envs: Vec<Box<dyn Env>> = (0..n)
            .map(|_| {
                Box::new(Counting {
                    steps: Arc::clone(&steps),
                    space: Space::uniform_box(1, -1.0, 1.0),
                }) as Box<dyn Env>
            })
            .collect();
        let mut envs = VecEnv::new(envs).expect("a vector");
        let rate = vector_steps_per_second(&mut envs, 2 * n, 0);
        assert_eq!(
            steps.load(Ordering::Relaxed),
            2 * n,
            "two vector steps of {n}"
        );
        assert!(rate.is_finite() && rate > 0.0, "{rate}");
    }
}
