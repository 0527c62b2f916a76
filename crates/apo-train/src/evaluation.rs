//! Evaluation episodes during training (`eval_every`, `eval_episodes`, `eval_deterministic`).
//!
//! An [`Evaluator`] owns its own environment, made as the run's (same action mapping and time
//! limit) but seeded only by the evaluation's own stream: episode `i` of every evaluation starts
//! from `reset(derive_seed(run seed, 0, 4) + i)`, and a stochastic evaluation samples its
//! actions from `derive_seed(run seed, 0, 5)`. Every evaluation of a run therefore plays the same
//! starts (the policies of different epochs are compared on common episodes), and nothing of
//! the training streams — the rollout's environments and random numbers, the update's — is
//! touched: a run with evaluation trains exactly as the same run without it. Observations are
//! normalized with the run's current statistics, which the evaluation does not update. As in
//! training, every episode counts: one ended by a simulator instability enters the statistics
//! with the return it had reached, and is counted and flagged.

use apo_core::inference::ActBuffers;
use apo_core::EpisodeStats;
use apo_envs::{Action, Env, RunningMeanStd, Space};
use rand::rngs::StdRng;
use rand::SeedableRng;

use crate::actor::Act;
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::rollout::{episode_stats, Episode};
use crate::seed::derive_seed;

/// The seed stream of the evaluation's episode starts.
const RESET_STREAM: u64 = 4;
/// The seed stream of a stochastic evaluation's actions.
const ACTION_STREAM: u64 = 5;

/// What one evaluation measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Statistics of every episode, unstable ones included (`None` for no episode).
    pub stats: Option<EpisodeStats>,
    /// Episodes ended by a simulator instability (counted in `stats`).
    pub unstable: usize,
    /// The episodes: episode `i` is environment 0's, reset with its own seed (`nth` 0).
    pub episodes: Vec<Episode>,
}

/// Runs the evaluation episodes of a run.
pub struct Evaluator {
    env: Box<dyn Env>,
    episodes: usize,
    deterministic: bool,
    seed: u64,
    obs: Vec<f32>,
    act: ActBuffers,
}

impl Evaluator {
    /// The evaluator of `config` (its environment made from the registry), or `None` when the
    /// run does not evaluate (`eval_every = 0`).
    ///
    /// # Errors
    /// [`TrainError::Env`] when the environment cannot be made.
    pub fn new(config: &TrainConfig) -> Result<Option<Self>, TrainError> {
        if config.eval_every == 0 {
            return Ok(None);
        }
        let options = apo_envs::MakeOptions {
            fixed_reset_seed: None,
            ..config.make_options()
        };
        let env = apo_envs::make_with(&config.env, &options)?;
        Ok(Some(Self::with_env(env, config)))
    }

    /// The evaluator of `config` (`eval_episodes`, `eval_deterministic`, `seed`) on `env`, any
    /// [`Env`], registered or not (`eval_every` is not read).
    pub fn with_env(env: Box<dyn Env>, config: &TrainConfig) -> Self {
        let obs = vec![0.0; env.observation_space().flat_dim()];
        Self {
            env,
            episodes: config.eval_episodes,
            deterministic: config.eval_deterministic,
            seed: config.seed,
            obs,
            act: ActBuffers::default(),
        }
    }

    /// Plays the evaluation episodes with `actor`, normalizing observations with `normalizer`
    /// (not updated); `k` is the probability factor of the episodes' bound.
    pub fn evaluate(
        &mut self,
        actor: &mut dyn Act,
        normalizer: Option<&RunningMeanStd>,
        k: f64,
    ) -> Evaluation {
        let first = derive_seed(self.seed, 0, RESET_STREAM);
        let mut rng = StdRng::seed_from_u64(derive_seed(self.seed, 0, ACTION_STREAM));
        let mut episodes = Vec::with_capacity(self.episodes);
        let space = self.env.action_space().clone();
        for episode in 0..self.episodes {
            let seed = first.wrapping_add(episode as u64);
            self.env.reset(Some(seed), &mut self.obs);
            let (mut ret, mut len, mut judged) = (0.0, 0, false);
            loop {
                if let Some(rms) = normalizer {
                    rms.normalize(&mut self.obs);
                }
                actor.act(&self.obs, 1, self.deterministic, &mut rng, &mut self.act);
                let t = match space {
                    Space::Discrete { .. } => self.env.step(
                        Action::Discrete(self.act.env_actions[0] as usize),
                        &mut self.obs,
                    ),
                    Space::Box { .. } => self
                        .env
                        .step(Action::Continuous(&self.act.env_actions), &mut self.obs),
                };
                ret += t.reward;
                len += 1;
                judged |= t.info.success.is_some();
                if t.done() {
                    episodes.push(Episode {
                        env: 0,
                        seed,
                        nth: 0,
                        ret,
                        length: len,
                        unstable: t.info.unstable,
                        success: judged.then_some(t.info.success == Some(true) && !t.info.unstable),
                    });
                    break;
                }
            }
        }
        Evaluation {
            stats: episode_stats(&episodes, k),
            unstable: episodes.iter().filter(|e| e.unstable).count(),
            episodes,
        }
    }
}
