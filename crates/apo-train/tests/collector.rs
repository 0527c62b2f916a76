//! The collector's bootstrapping rules, against rewards-to-go computed by hand: a terminated
//! episode ends with value 0, a truncated one with V(its final observation), one cut by the
//! epoch with V(the current observation), an unstable one with 0 (even when it was also
//! truncated), and an unstable episode is kept with its return, counted and flagged. The
//! success rate counts the last step of each episode whose task judges success, an unstable
//! one as a failure.

use apo_core::flat::{from_host, unflatten};
use apo_core::inference::{HostPolicy, HostValue};
use apo_core::{ActionKind, MlpPolicyConfig, PolicyFamily, ValueConfig};
use apo_envs::{Action, Env, Space, Transition, VecEnv};
use apo_train::{Collector, HostActor};
use burn::backend::NdArray;
use std::sync::atomic::AtomicBool;

#[derive(Debug, Clone, Copy)]
enum End {
    Terminated,
    Truncated,
    /// Unstable and truncated at once: the unstable rule must win.
    Unstable,
    /// Truncated in success, after steps that were not.
    Reached,
    /// Truncated without success, one step after a step in success.
    Missed,
}

/// Plays a script: episodes of the given lengths and endings (the last one never ends),
/// reward 1 per step, observation `[steps taken in the episode]`.
struct Script {
    episodes: Vec<(usize, End)>,
    episode: usize,
    t: usize,
    space: Space,
}

impl Script {
    fn boxed(episodes: Vec<(usize, End)>) -> Box<dyn Env> {
        Box::new(Self {
            episodes,
            episode: 0,
            t: 0,
            space: Space::uniform_box(1, -1.0, 1.0),
        })
    }
}

impl Env for Script {
    fn observation_space(&self) -> &Space {
        &self.space
    }
    fn action_space(&self) -> &Space {
        &self.space
    }
    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        self.episode = if seed.is_some() { 0 } else { self.episode + 1 };
        self.t = 0;
        obs[0] = 0.0;
    }
    fn step(&mut self, _action: Action<'_>, obs: &mut [f32]) -> Transition {
        self.t += 1;
        obs[0] = self.t as f32;
        let mut step = Transition {
            reward: 1.0,
            ..Default::default()
        };
        if let Some(&(len, end)) = self.episodes.get(self.episode) {
            match end {
                End::Reached => step.info.success = Some(self.t == len),
                End::Missed => step.info.success = Some(self.t + 1 == len),
                _ => {}
            }
            if self.t == len {
                match end {
                    End::Terminated => step.terminated = true,
                    End::Truncated => step.truncated = true,
                    End::Unstable => {
                        step.truncated = true;
                        step.info.unstable = true;
                    }
                    End::Reached | End::Missed => step.truncated = true,
                }
            }
        }
        step
    }
}

/// An actor on one-dimensional observations with `V(s) = s + 4` (one linear layer, weight 1,
/// bias 4).
fn actor() -> HostActor {
    let device = Default::default();
    let action = ActionKind::Continuous { dim: 1 };
    let policy = MlpPolicyConfig::new(1, action).init::<NdArray>(&device);
    let value = unflatten(
        ValueConfig {
            observation_dim: 1,
            hidden: vec![],
        }
        .init::<NdArray>(&device),
        from_host::<NdArray>(&[1.0, 4.0], &device),
    );
    HostActor {
        policy: HostPolicy::new(&policy, action),
        value: HostValue::new(&value),
    }
}

#[test]
fn bootstrapping_rules_by_hand() {
    let envs = VecEnv::new(vec![
        Script::boxed(vec![(2, End::Terminated), (3, End::Truncated)]),
        Script::boxed(vec![(2, End::Unstable)]),
    ])
    .expect("same spaces");
    // 7 vector steps, γ = 0.5
    let mut collector = Collector::from_envs(envs, 14, 0.5, 0.97, None);
    let mut actor = actor();
    let rollout = collector
        .collect(&mut actor, 3, &AtomicBool::new(false), &mut |_| {})
        .expect("not stopped");
    #[rustfmt::skip]
    let expected = [
        // env 0: terminated after 2 steps → last value 0
        1.5, 1.0,
        // truncated after 3 → V(final obs [3]) = 7: 1 + 0.5·7, 1 + 0.5·4.5, 1 + 0.5·3.25
        2.625, 3.25, 4.5,
        // cut by the epoch after 2 → V(obs [2]) = 6
        3.0, 4.0,
        // env 1: unstable (and truncated) after 2 → 0, not V(final obs [2]) = 6
        1.5, 1.0,
        // cut by the epoch after 5 → V(obs [5]) = 9
        2.21875, 2.4375, 2.875, 3.75, 5.5,
    ];
    let ret: Vec<f64> = rollout.batch.ret.iter().map(|&r| f64::from(r)).collect();
    assert_eq!(ret.len(), expected.len());
    for (i, (got, want)) in ret.iter().zip(&expected).enumerate() {
        assert!(
            (got - want).abs() < 1e-6,
            "ret[{i}] = {got}, expected {want}"
        );
    }
    // in the order they ended: env 0's and env 1's after two steps, env 0's after five
    let returns: Vec<f64> = rollout.episodes.iter().map(|e| e.ret).collect();
    let lengths: Vec<usize> = rollout.episodes.iter().map(|e| e.length).collect();
    let flags: Vec<bool> = rollout.episodes.iter().map(|e| e.unstable).collect();
    assert_eq!(returns, vec![2.0, 2.0, 3.0]);
    assert_eq!(lengths, vec![2, 2, 3]);
    assert_eq!(flags, vec![false, true, false]);
    assert_eq!(rollout.unstable(), 1);
    assert_eq!(rollout.steps, 14);
    assert_eq!(rollout.success_rate(), None);
    // where each was played: environment, its stream's seed (the epoch's + i) and rank in it
    let places: Vec<(usize, usize)> = rollout.episodes.iter().map(|e| (e.env, e.nth)).collect();
    assert_eq!(places, vec![(0, 0), (1, 0), (0, 1)]);
    let seeds: Vec<u64> = rollout.episodes.iter().map(|e| e.seed).collect();
    assert_eq!((seeds[1], seeds[2]), (seeds[0] + 1, seeds[0]));
}

#[test]
fn the_success_rate_counts_the_last_step_of_every_judged_episode() {
    let envs = VecEnv::new(vec![
        // ends at steps 2 (success), 5 (missed), 7 (success); the one after is cut by the epoch
        Script::boxed(vec![
            (2, End::Reached),
            (3, End::Missed),
            (2, End::Reached),
            (3, End::Reached),
        ]),
        // unstable before the task judged any step (not judged), terminated (not judged),
        // missed, then cut by the epoch
        Script::boxed(vec![
            (2, End::Unstable),
            (2, End::Terminated),
            (3, End::Missed),
            (3, End::Reached),
        ]),
    ])
    .expect("same spaces");
    let mut collector = Collector::from_envs(envs, 16, 0.5, 0.97, None);
    let rollout = collector
        .collect(&mut actor(), 3, &AtomicBool::new(false), &mut |_| {})
        .expect("not stopped");
    assert_eq!(rollout.episodes.len(), 6);
    assert_eq!(rollout.unstable(), 1);
    let judged: Vec<Option<bool>> = rollout.episodes.iter().map(|e| e.success).collect();
    // by vector step: 2 (env 0, env 1), 4 (env 1), 5 (env 0), 7 (env 0, env 1)
    assert_eq!(
        judged,
        vec![Some(true), None, None, Some(false), Some(true), Some(false)]
    );
    assert_eq!(rollout.success_rate(), Some(0.5));
}

#[test]
fn an_unstable_episode_of_a_task_that_judges_success_is_a_failure() {
    let envs = VecEnv::new(vec![Script::boxed(vec![
        (2, End::Reached),
        (2, End::Unstable),
    ])])
    .expect("one env");
    let mut collector = Collector::from_envs(envs, 5, 0.5, 0.97, None);
    let rollout = collector
        .collect(&mut actor(), 3, &AtomicBool::new(false), &mut |_| {})
        .expect("not stopped");
    let ended: Vec<(f64, bool, Option<bool>)> = rollout
        .episodes
        .iter()
        .map(|e| (e.ret, e.unstable, e.success))
        .collect();
    assert_eq!(
        ended,
        vec![(2.0, false, Some(true)), (2.0, true, Some(false))]
    );
    assert_eq!(rollout.success_rate(), Some(0.5));
}

#[test]
fn without_time_limit_bootstrap_a_truncated_path_ends_at_zero() {
    let envs = VecEnv::new(vec![Script::boxed(vec![(3, End::Truncated)])]).expect("one env");
    // 5 steps, γ = 0.5; the paper's code: a path cut by the time limit is not bootstrapped
    let mut collector = Collector::from_envs(envs, 5, 0.5, 0.97, None).bootstrap_time_limit(false);
    let mut actor = actor();
    let rollout = collector
        .collect(&mut actor, 3, &AtomicBool::new(false), &mut |_| {})
        .expect("not stopped");
    #[rustfmt::skip]
    let expected = [
        // truncated after 3 → 0 (not V([3]) = 7): 1 + 0.5·0, 1 + 0.5·1, 1 + 0.5·1.5
        1.75, 1.5, 1.0,
        // cut by the epoch after 2 → still V(obs [2]) = 6
        3.0, 4.0,
    ];
    let ret: Vec<f64> = rollout.batch.ret.iter().map(|&r| f64::from(r)).collect();
    assert_eq!(ret.len(), expected.len());
    for (i, (got, want)) in ret.iter().zip(&expected).enumerate() {
        assert!(
            (got - want).abs() < 1e-6,
            "ret[{i}] = {got}, expected {want}"
        );
    }
}
