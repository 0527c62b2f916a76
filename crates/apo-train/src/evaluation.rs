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
        Self {
            env,
            episodes: config.eval_episodes,
            deterministic: config.eval_deterministic,
            seed: config.seed,
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
        let plays = Plays {
            count: self.episodes,
            deterministic: self.deterministic,
            first_reset: derive_seed(self.seed, 0, RESET_STREAM),
            action_seed: derive_seed(self.seed, 0, ACTION_STREAM),
        };
        let act = &mut |obs: &[f32], deterministic, rng: &mut StdRng, out: &mut ActBuffers| {
            actor.act(obs, 1, deterministic, rng, out)
        };
        let played = play_episodes(self.env.as_mut(), act, normalizer, &plays, &mut |_, _| {
            Ok::<(), std::convert::Infallible>(())
        });
        let episodes = match played {
            Ok(episodes) => episodes,
            Err(never) => match never {},
        };
        Evaluation {
            stats: episode_stats(&episodes, k),
            unstable: episodes.iter().filter(|e| e.unstable).count(),
            episodes,
        }
    }
}

/// How [`play_episodes`] picks an action: `(obs [1, observation_dim], deterministic, rng,
/// out)`, as [`Act::act`] with one row.
pub type ActOne<'a> = dyn FnMut(&[f32], bool, &mut StdRng, &mut ActBuffers) + 'a;

/// Which episodes [`play_episodes`] plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Plays {
    /// How many.
    pub count: usize,
    /// Act with the mean (Gaussian) or most likely (categorical) action.
    pub deterministic: bool,
    /// Episode `i` starts from `reset(first_reset + i)`.
    pub first_reset: u64,
    /// Sampled actions draw from `StdRng::seed_from_u64(action_seed)`.
    pub action_seed: u64,
}

/// Where an episode is, after a reset or a step: what [`play_episodes`] shows its observer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moment {
    /// The episode, from 0.
    pub episode: usize,
    /// Steps taken in the episode.
    pub step: usize,
    /// The last step's reward (0 after a reset).
    pub reward: f64,
    /// The undiscounted return so far.
    pub ret: f64,
    /// Whether the episode ended with the last step.
    pub done: bool,
}

/// Plays the episodes `plays` names on `env`, one at a time: `act(obs [1, observation_dim],
/// deterministic, rng, out)` picks each action from the observation normalized by `normalizer`
/// (not updated), and `observe` sees the environment after each reset and each step (a video
/// draws its frames there). The one episode loop of apo: evaluation during training
/// ([`Evaluator`]), `apo eval` and `apo render` ([`crate::playback`]) and the epoch videos.
/// Every episode counts: one ended by a simulator instability is returned with the return it
/// had reached, flagged.
///
/// # Errors
/// The observer's, which stop the episodes.
pub fn play_episodes<E>(
    env: &mut dyn Env,
    act: &mut ActOne<'_>,
    normalizer: Option<&RunningMeanStd>,
    plays: &Plays,
    observe: &mut dyn FnMut(&mut dyn Env, &Moment) -> Result<(), E>,
) -> Result<Vec<Episode>, E> {
    let mut rng = StdRng::seed_from_u64(plays.action_seed);
    let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
    let mut out = ActBuffers::default();
    let mut episodes = Vec::with_capacity(plays.count);
    for episode in 0..plays.count {
        let seed = plays.first_reset.wrapping_add(episode as u64);
        env.reset(Some(seed), &mut obs);
        let (mut ret, mut length, mut judged) = (0.0, 0, false);
        let mut moment = Moment {
            episode,
            step: 0,
            reward: 0.0,
            ret,
            done: false,
        };
        observe(env, &moment)?;
        loop {
            if let Some(rms) = normalizer {
                rms.normalize(&mut obs);
            }
            act(&obs, plays.deterministic, &mut rng, &mut out);
            let t = match env.action_space() {
                Space::Discrete { .. } => {
                    env.step(Action::Discrete(out.env_actions[0] as usize), &mut obs)
                }
                Space::Box { .. } => env.step(Action::Continuous(&out.env_actions), &mut obs),
            };
            ret += t.reward;
            length += 1;
            judged |= t.info.success.is_some();
            moment = Moment {
                step: length,
                reward: t.reward,
                ret,
                done: t.done(),
                ..moment
            };
            observe(env, &moment)?;
            if t.done() {
                episodes.push(Episode {
                    env: 0,
                    seed,
                    nth: 0,
                    ret,
                    length,
                    unstable: t.info.unstable,
                    success: judged.then_some(t.info.success == Some(true) && !t.info.unstable),
                });
                break;
            }
        }
    }
    Ok(episodes)
}
