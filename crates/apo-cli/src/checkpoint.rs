//! Checkpoints: everything needed to continue a run.
//!
//! A checkpoint is a directory `checkpoints/latest/` holding the policy and value networks
//! and both Adam states (Burn's named MessagePack recorder, full precision) and
//! `state.json` (epoch, step and time counters, observation-normalizer statistics).
//! Rollout randomness is reseeded from the run seed at each epoch, so no RNG state has to
//! be saved for a resumed run to reproduce an uninterrupted one.
//!
//! Writing is atomic: the files go to a fresh temporary directory, which then replaces
//! `latest` (the old one is moved to `previous` first and deleted last). A crash at any
//! point leaves `latest` or `previous` complete, and [`load`] falls back to `previous`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use apo_core::{Learner, MlpPolicyConfig, PolicyFamily};
use apo_envs::RunningMeanStd;
use burn::backend::Autodiff;
use burn::module::Module;
use burn::optim::Optimizer;
use burn::record::{FullPrecisionSettings, NamedMpkFileRecorder, Recorder};
use burn::tensor::backend::Backend;
use serde::{Deserialize, Serialize};

use crate::atomic;

const FORMAT: u32 = 1;

/// The counters saved with the networks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainState {
    /// Checkpoint format version.
    pub format: u32,
    /// Epochs completed.
    pub epoch: usize,
    /// Environment steps so far.
    pub env_steps: u64,
    /// Wall time of the run so far, seconds.
    pub elapsed_s: f64,
    /// Observation normalizer statistics, when the run normalizes observations.
    pub normalizer: Option<RunningMeanStd>,
}

type Rec = NamedMpkFileRecorder<FullPrecisionSettings>;

fn recorder() -> Rec {
    NamedMpkFileRecorder::<FullPrecisionSettings>::new()
}

/// `checkpoints/` of a run directory.
pub fn dir(run: &Path) -> PathBuf {
    run.join("checkpoints")
}

/// Writes a checkpoint of `learner` and `state` into `run`'s `checkpoints/latest`, atomically.
pub fn save<B: Backend>(run: &Path, learner: &Learner<B, MlpPolicyConfig>, state: &TrainState) -> anyhow::Result<()> {
    let root = dir(run);
    std::fs::create_dir_all(&root).with_context(|| format!("cannot create {}", root.display()))?;
    let tmp = root.join(format!(".tmp-{}", state.epoch));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)?;
    }
    std::fs::create_dir_all(&tmp)?;
    let (policy, value) = learner.networks();
    let (policy_optim, value_optim) = learner.optimizers();
    let rec = recorder();
    policy.clone().save_file(tmp.join("policy"), &rec).context("saving the policy")?;
    value.clone().save_file(tmp.join("value"), &rec).context("saving the value network")?;
    rec.record(policy_optim.to_record(), tmp.join("policy_optim")).context("saving the policy optimizer")?;
    rec.record(value_optim.to_record(), tmp.join("value_optim")).context("saving the value optimizer")?;
    atomic::write(&tmp.join("state.json"), serde_json::to_string_pretty(state)?.as_bytes())?;

    let (latest, previous) = (root.join("latest"), root.join("previous"));
    if previous.exists() {
        std::fs::remove_dir_all(&previous)?;
    }
    if latest.exists() {
        std::fs::rename(&latest, &previous)?;
    }
    std::fs::rename(&tmp, &latest)?;
    if previous.exists() {
        std::fs::remove_dir_all(&previous)?;
    }
    Ok(())
}

/// Whether `run` has a checkpoint to resume from.
pub fn exists(run: &Path) -> bool {
    let root = dir(run);
    root.join("latest").join("state.json").exists() || root.join("previous").join("state.json").exists()
}

/// Loads the checkpoint of `run` into `learner` and returns its counters.
pub fn load<B: Backend>(run: &Path, learner: &mut Learner<B, MlpPolicyConfig>, device: &B::Device) -> anyhow::Result<TrainState> {
    let root = dir(run);
    let from = [root.join("latest"), root.join("previous")]
        .into_iter()
        .find(|d| d.join("state.json").exists());
    let Some(from) = from else {
        bail!("no checkpoint in {}: the run has not completed an epoch; start it again with --force", root.display());
    };
    load_from(&from, learner, device).with_context(|| {
        format!(
            "the checkpoint in {} is corrupt or from an incompatible run; delete {} to start over",
            from.display(),
            root.display()
        )
    })
}

fn load_from<B: Backend>(from: &Path, learner: &mut Learner<B, MlpPolicyConfig>, device: &B::Device) -> anyhow::Result<TrainState> {
    let text = std::fs::read_to_string(from.join("state.json"))?;
    let state: TrainState = serde_json::from_str(&text).context("state.json")?;
    if state.format != FORMAT {
        bail!("checkpoint format {} (this version reads {FORMAT})", state.format);
    }
    let rec = recorder();
    let (policy, value) = learner.networks();
    let policy = policy.clone().load_file(from.join("policy"), &rec, device).context("policy.mpk")?;
    let value = value.clone().load_file(from.join("value"), &rec, device).context("value.mpk")?;
    let (policy_optim, value_optim) = learner.optimizers();
    let policy_optim = policy_optim
        .clone()
        .load_record(rec.load(from.join("policy_optim"), device).context("policy_optim.mpk")?);
    let value_optim = value_optim
        .clone()
        .load_record(rec.load(from.join("value_optim"), device).context("value_optim.mpk")?);
    // A record of other sizes loads silently in some Burn versions: check the shapes.
    let expected = learner.family().init::<Autodiff<B>>(device).num_params();
    if policy.num_params() != expected {
        bail!("policy has {} parameters, the config says {expected}", policy.num_params());
    }
    learner.restore(policy, value, policy_optim, value_optim);
    Ok(state)
}
