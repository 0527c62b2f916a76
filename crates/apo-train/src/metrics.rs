//! The metrics of an epoch: one [`ProgressRow`] ([`crate::run::Run`] writes them to
//! `progress.csv`) and one [`EpisodeRecord`] per episode that ended (`episodes.csv`). The same
//! concept as `apo_core::metrics` one layer up: apo-core computes the statistics of a set of
//! episodes, this module records them per epoch, with the update's numbers beside them.
//!
//! Every episode counts: the return statistics of a row (mean, worst, best, spread, CVaR,
//! quantile, length, the bound and its confidence), of training and of evaluation alike, are
//! over every episode that ended, an episode ended by a simulator instability included with
//! the return it had reached when it ended; such an episode is also counted
//! (`unstable_episodes`, `eval_unstable_episodes`) and flagged in its record.

use apo_core::{EpisodeStats, LineSearchOutcome, UpdateReport};
use serde::{Deserialize, Serialize};

use crate::rollout::Episode;

/// Which episodes an [`EpisodeRecord`] belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The epoch's rollout (the episodes the policy learned from).
    Train,
    /// The evaluation after the epoch's update (`eval_every`).
    Eval,
}

/// One episode that ended: a row of `episodes.csv`, as Stable-Baselines3's `Monitor` keeps one,
/// from which every return statistic of a run can be recomputed without running it again.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// The epoch it was played in (from 1; an evaluation's episodes carry the epoch after
    /// whose update they were played).
    pub epoch: usize,
    /// Training rollout or evaluation.
    pub phase: Phase,
    /// The environment of the vector that played it (0 for evaluation episodes).
    pub env: usize,
    /// The seed of the reset that started the environment's stream of episodes…
    pub seed: u64,
    /// …and which episode of that stream it is (0: the first after the seeded reset).
    pub nth: usize,
    /// Its undiscounted return, up to the step that ended it.
    #[serde(rename = "return")]
    pub ret: f64,
    /// Its length in steps.
    pub length: usize,
    /// Ended by a simulator instability (counted in every statistic all the same).
    pub unstable: bool,
    /// Ended in success, for tasks that judge it (empty for the others).
    pub success: Option<bool>,
}

impl EpisodeRecord {
    /// The record of `episode`, played in `epoch` during `phase`.
    pub fn new(epoch: usize, phase: Phase, episode: &Episode) -> Self {
        Self {
            epoch,
            phase,
            env: episode.env,
            seed: episode.seed,
            nth: episode.nth,
            ret: episode.ret,
            length: episode.length,
            unstable: episode.unstable,
            success: episode.success,
        }
    }

    /// The episode the record holds.
    pub fn episode(&self) -> Episode {
        Episode {
            env: self.env,
            seed: self.seed,
            nth: self.nth,
            ret: self.ret,
            length: self.length,
            unstable: self.unstable,
            success: self.success,
        }
    }
}

/// The columns that depend on wall-clock time (everything else is reproducible).
pub const TIME_COLUMNS: [&str; 7] = [
    "steps_per_s",
    "time_s",
    "rollout_s",
    "update_pi_s",
    "update_v_s",
    "eval_s",
    "sim_s",
];

/// One epoch's row. Return statistics are empty when no episode ended in the epoch.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ProgressRow {
    /// Epoch number, from 1.
    pub epoch: usize,
    /// Environment steps so far.
    pub env_steps: u64,
    /// Episodes that ended in this epoch, those ended by a simulator instability included
    /// (also counted in `unstable_episodes`).
    pub episodes: usize,
    /// Mean return of the epoch's episodes (every one, see the module's documentation).
    pub ep_ret_mean: Option<f64>,
    /// Worst return.
    pub ep_ret_min: Option<f64>,
    /// Best return.
    pub ep_ret_max: Option<f64>,
    /// Standard deviation of the returns.
    pub ep_ret_std: Option<f64>,
    /// Lower CVaR at 10 %: mean of the worst 10 % of the epoch's returns (at least one).
    #[serde(default)]
    pub ep_ret_cvar10: Option<f64>,
    /// 10 % quantile of the epoch's returns (linear interpolation).
    #[serde(default)]
    pub ep_ret_q10: Option<f64>,
    /// Mean episode length.
    pub ep_len_mean: Option<f64>,
    /// Fraction of the epoch's episodes that ended in success, for tasks that judge it (the
    /// hand tasks; Gymnasium-Robotics' success rate).
    #[serde(default)]
    pub success_rate: Option<f64>,
    /// Empirical bound `J − k·Var`.
    pub bound: Option<f64>,
    /// Its Selberg confidence.
    pub confidence: Option<f64>,
    /// Mean KL(π_j ‖ π_{j+1}).
    pub kl: f64,
    /// Mean entropy of π_j.
    pub entropy: f64,
    /// Policy loss (−objective) before the update.
    pub loss_pi: f64,
    /// Value MSE before the update.
    pub loss_v: f64,
    /// `mean_surr` before the update.
    pub mean_surr: f64,
    /// MeanVariance term (APO/PAPO).
    pub mean_variance: Option<f64>,
    /// VarianceMean term (APO/PAPO).
    pub variance_mean: Option<f64>,
    /// Line search: `accepted:<try>`, `rejected` or `no_step` (APO/TRPO).
    pub line_search: Option<String>,
    /// Line-search tries rejected for a KL above δ (APO/TRPO).
    #[serde(default)]
    pub ls_rejected_kl: Option<usize>,
    /// Line-search tries inside δ rejected for a lower objective (APO/TRPO).
    #[serde(default)]
    pub ls_rejected_objective: Option<usize>,
    /// `min_J_sq`'s bias `4γ·|mean(logp_old − logp)|·max(adv)/(1 − γ)²` at the new policy
    /// (APO/PAPO).
    #[serde(default)]
    pub bias: Option<f64>,
    /// Whether `min_J_sq`'s switch is on at the new policy (APO/PAPO).
    #[serde(default)]
    pub min_j_sq_on: Option<bool>,
    /// Adam steps taken (proximal algorithms).
    pub pi_steps: Option<usize>,
    /// The last mean absolute ratio deviation `mean(|ratio − 1|)` measured by ESPO's stop.
    #[serde(default)]
    pub ratio_deviation: Option<f64>,
    /// V-MPO's temperature η after the update.
    #[serde(default)]
    pub eta: Option<f64>,
    /// V-MPO's Lagrange multiplier α after the update.
    #[serde(default)]
    pub alpha: Option<f64>,
    /// Episodes ended by a simulator instability in this epoch (counted in `episodes` and in
    /// every return statistic, with the return they had reached).
    pub unstable_episodes: usize,
    /// Mean return of the evaluation episodes after this epoch's update (epochs that
    /// evaluate, see `eval_every`).
    #[serde(default)]
    pub eval_ret_mean: Option<f64>,
    /// Their worst return.
    #[serde(default)]
    pub eval_ret_min: Option<f64>,
    /// Their lower CVaR at 10 %.
    #[serde(default)]
    pub eval_ret_cvar10: Option<f64>,
    /// The standard deviation of their returns.
    #[serde(default)]
    pub eval_ret_std: Option<f64>,
    /// Their mean length.
    #[serde(default)]
    pub eval_len_mean: Option<f64>,
    /// Evaluation episodes ended by a simulator instability (counted in the statistics).
    #[serde(default)]
    pub eval_unstable_episodes: Option<usize>,
    /// Environment steps per second of the run so far: `env_steps` over `time_s`, what a
    /// user waits for (rollouts, updates, evaluations and checkpoints all included).
    pub steps_per_s: f64,
    /// Wall time since the run started, seconds.
    pub time_s: f64,
    /// Wall time of the epoch's rollout, seconds.
    #[serde(default)]
    pub rollout_s: f64,
    /// Wall time of the epoch's policy update, seconds.
    #[serde(default)]
    pub update_pi_s: f64,
    /// Wall time of the epoch's value update, seconds.
    #[serde(default)]
    pub update_v_s: f64,
    /// Wall time of the epoch's evaluation, seconds.
    #[serde(default)]
    pub eval_s: f64,
    /// Wall time of the epoch's rollout inside the simulator's calls (the environments'
    /// `reset` and `step`), seconds; `rollout_s − sim_s` is the rollout's own work (policy
    /// call, sampling, normalization, buffers, the critic's values and the advantages).
    #[serde(default)]
    pub sim_s: f64,
}

/// Wall times of an epoch's phases, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EpochTimes {
    /// The rollout.
    pub rollout_s: f64,
    /// The rollout's time inside the simulator's calls.
    pub sim_s: f64,
    /// Steps per second of the run so far.
    pub steps_per_s: f64,
    /// Since the run started.
    pub time_s: f64,
}

impl ProgressRow {
    /// The row with its wall-clock columns ([`TIME_COLUMNS`]) zeroed: what two runs with the
    /// same seed must agree on.
    pub fn timeless(self) -> Self {
        Self {
            steps_per_s: 0.0,
            time_s: 0.0,
            rollout_s: 0.0,
            update_pi_s: 0.0,
            update_v_s: 0.0,
            eval_s: 0.0,
            sim_s: 0.0,
            ..self
        }
    }

    /// The row without its evaluation columns (and their time): what a run with evaluation
    /// must agree on with the same run without it.
    pub fn without_evaluation(self) -> Self {
        Self {
            eval_ret_mean: None,
            eval_ret_min: None,
            eval_ret_cvar10: None,
            eval_ret_std: None,
            eval_len_mean: None,
            eval_unstable_episodes: None,
            eval_s: 0.0,
            ..self
        }
    }

    /// Sets the evaluation columns from the evaluation episodes' statistics, the number of
    /// unstable ones and the evaluation's time.
    pub fn set_evaluation(&mut self, stats: Option<&EpisodeStats>, unstable: usize, seconds: f64) {
        self.eval_unstable_episodes = Some(unstable);
        self.eval_ret_mean = stats.map(|s| s.ret_mean);
        self.eval_ret_min = stats.map(|s| s.ret_min);
        self.eval_ret_cvar10 = stats.map(|s| s.ret_cvar10);
        self.eval_ret_std = stats.map(|s| s.ret_std);
        self.eval_len_mean = stats.map(|s| s.len_mean);
        self.eval_s = seconds;
    }

    /// The row's evaluation statistic `metric`, in epochs that evaluated.
    pub fn evaluation(&self, metric: crate::config::EvalMetric) -> Option<f64> {
        use crate::config::EvalMetric;
        match metric {
            EvalMetric::Mean => self.eval_ret_mean,
            EvalMetric::Worst => self.eval_ret_min,
            EvalMetric::Cvar10 => self.eval_ret_cvar10,
        }
    }

    /// A row from an epoch's episode statistics, success rate, unstable-episode count and
    /// update report.
    pub fn new(
        epoch: usize,
        env_steps: u64,
        stats: Option<&EpisodeStats>,
        success_rate: Option<f64>,
        unstable_episodes: usize,
        report: &UpdateReport,
        times: EpochTimes,
    ) -> Self {
        let line_search = report.line_search.map(|o| match o {
            LineSearchOutcome::Accepted { r#try } => format!("accepted:{}", r#try),
            LineSearchOutcome::Rejected => "rejected".to_string(),
            LineSearchOutcome::NoStep => "no_step".to_string(),
        });
        let mut row = Self {
            epoch,
            env_steps,
            kl: report.kl,
            entropy: report.entropy,
            loss_pi: report.loss_pi,
            loss_v: report.loss_v,
            mean_surr: report.mean_surr,
            mean_variance: report.mean_variance,
            variance_mean: report.variance_mean,
            line_search,
            ls_rejected_kl: report.rejections.map(|r| r.kl),
            ls_rejected_objective: report.rejections.map(|r| r.objective),
            bias: report.bias,
            min_j_sq_on: report.min_j_sq_on,
            pi_steps: report.proximal.map(|p| p.steps),
            ratio_deviation: report.proximal.and_then(|p| p.ratio_deviation),
            eta: report.multipliers.map(|m| m.eta),
            alpha: report.multipliers.map(|m| m.alpha),
            steps_per_s: times.steps_per_s,
            time_s: times.time_s,
            rollout_s: times.rollout_s,
            sim_s: times.sim_s,
            update_pi_s: report.policy_update_s,
            update_v_s: report.value_update_s,
            ..Self::default()
        };
        row.set_training(stats, success_rate, unstable_episodes);
        row
    }

    /// Sets the training return columns from the epoch's episode statistics (every episode
    /// counted), their success rate and the number of unstable ones.
    pub fn set_training(
        &mut self,
        stats: Option<&EpisodeStats>,
        success_rate: Option<f64>,
        unstable: usize,
    ) {
        self.episodes = stats.map_or(0, |s| s.count);
        self.ep_ret_mean = stats.map(|s| s.ret_mean);
        self.ep_ret_min = stats.map(|s| s.ret_min);
        self.ep_ret_max = stats.map(|s| s.ret_max);
        self.ep_ret_std = stats.map(|s| s.ret_std);
        self.ep_ret_cvar10 = stats.map(|s| s.ret_cvar10);
        self.ep_ret_q10 = stats.map(|s| s.ret_q10);
        self.ep_len_mean = stats.map(|s| s.len_mean);
        self.success_rate = success_rate;
        self.bound = stats.map(|s| s.bound);
        self.confidence = stats.map(|s| s.confidence);
        self.unstable_episodes = unstable;
    }
}
