//! Training into a run directory: [`crate::Trainer`] epoch after epoch, with the run's
//! files — `progress.csv`, `episodes.csv`, TensorBoard events and checkpoints — written after
//! each epoch, and resuming from them.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::{HostActor, TrainError, Trainer};
use anyhow::{bail, Context};
use apo_core::inference::HostPolicy;
use apo_core::{Comm, MlpPolicyConfig};
use burn::backend::NdArray;
use burn::tensor::backend::Backend;

use crate::checkpoint::{self, Shapes, TrainState, Which};
use crate::episodes_csv::EpisodeLog;
use crate::progress_csv::{self, ProgressRow};
use crate::run_config::RunConfig;
use crate::tensorboard::{row_scalars, EventWriter};
use crate::video::{EpochVideos, TENSORBOARD_VIDEO_BYTES};

/// How [`train`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrainEnd {
    /// All epochs ran.
    Finished,
    /// `stop` was raised; a checkpoint of the last completed epoch was written.
    Interrupted {
        /// Epochs completed.
        epoch: usize,
    },
}

/// Observes training progress (the CLI's progress bar).
pub trait Observer {
    /// Called during each epoch's rollout with the run's environment steps so far.
    fn steps(&mut self, _env_steps: u64) {}
    /// Called after each epoch with its row.
    fn epoch(&mut self, row: &ProgressRow, epochs: usize);
}

/// How a process takes part in a run.
#[derive(Debug, Clone)]
pub struct Launch {
    /// Continue the run from its latest checkpoint.
    pub resume: bool,
    /// Threads stepping the environments (0: the cores available; results do not depend on it).
    pub threads: usize,
    /// The ranks of a data-parallel run (one by default).
    pub comm: Comm,
}

impl Launch {
    /// A new run in one process, the environments stepped on `threads` threads.
    pub fn new(threads: usize) -> Self {
        Self {
            resume: false,
            threads,
            comm: Comm::default(),
        }
    }
}

/// The keys of a run's algorithm that scale its update (step sizes, radii, penalty weights,
/// multipliers), by their last part.
const UPDATE_SCALES: &[&str] = &[
    "lr",
    "max_kl",
    "k",
    "omega1",
    "omega2",
    "delta",
    "eps_alpha",
    "eps_eta",
    "alpha_init",
    "eta_init",
    "clip",
    "cg_damping",
    "step_epsilon",
];

/// `key = value` of each of `config`'s settings that scale the update ([`UPDATE_SCALES`]): what
/// a non-finite update names.
fn update_scales(config: &RunConfig) -> Vec<String> {
    config
        .learned_with()
        .into_iter()
        .filter(|(key, _)| {
            key.starts_with("algo.")
                && UPDATE_SCALES.contains(&key.rsplit('.').next().unwrap_or(key))
        })
        .map(|(key, value)| format!("{key} = {value}"))
        .collect()
}

/// Trains (or, with `launch.resume`, continues) the run in `run_dir` on backend `B`, as rank
/// `comm.rank()` of `comm.size()` (every rank calls it with the same arguments; rank 0 alone
/// writes the run's files, the others only read the checkpoint when resuming). A checkpoint
/// records the number of ranks and resuming with another is refused.
///
/// Resuming checks that the checkpoint and `progress.csv` agree (rows of every completed epoch,
/// with matching step counts) and refuses with the reason when they don't. An update that
/// produces a non-finite value stops the run with an error, before anything of that epoch is
/// written, keeping the last good checkpoint.
pub fn train<B: Backend>(
    config: &RunConfig,
    run_dir: &Path,
    device: &B::Device,
    launch: &Launch,
    stop: &AtomicBool,
    observer: &mut dyn Observer,
) -> anyhow::Result<TrainEnd> {
    let Launch {
        resume,
        threads,
        ref comm,
    } = *launch;
    if comm.rank() == 0 && resume {
        // what a process stopped mid-write left (the caller holds the run's lock)
        crate::run_dir::remove_stale_temps(run_dir)?;
    }
    let mut trainer = Trainer::<B, _, _>::mlp(config.train.clone(), device, threads)?;
    trainer
        .learner_mut()
        .set_kernels(config.kernels.resolve(config.backend));
    let ranks = comm.size();
    if comm.is_distributed() {
        trainer.distribute(comm.clone())?;
    }
    let writer = comm.rank() == 0;
    let shapes = Shapes::of(config, trainer.observation_dim(), trainer.action());
    let save = |trainer: &Trainer<B, _, _>, keep: bool| -> anyhow::Result<TrainState> {
        let state = TrainState::new(trainer.state().clone()).with_ranks(ranks);
        if writer {
            checkpoint::save(run_dir, trainer.learner(), &state, &shapes, keep)?;
        }
        Ok(state)
    };
    let progress_path = run_dir.join(crate::run_dir::PROGRESS);
    if writer {
        // what this run will create, recorded before it exists (the run directory's marker)
        crate::run_dir::claim_new(
            run_dir,
            &[
                crate::run_dir::PROGRESS,
                crate::run_dir::EPISODES,
                crate::run_dir::CHECKPOINTS,
            ],
        )?;
    }
    let episodes_path = run_dir.join(crate::run_dir::EPISODES);
    let mut episodes = EpisodeLog::new(&episodes_path);
    let mut rows = Vec::new();
    if resume {
        let on_disk = if writer && progress_path.exists() {
            progress_csv::read(&progress_path)?
        } else {
            Vec::new()
        };
        match checkpoint::locate(run_dir, &Which::Latest)? {
            Some(from) => {
                let state = checkpoint::load(&from, trainer.learner_mut(), &shapes, device)?;
                if state.ranks != ranks {
                    bail!(
                        "{} was written by a run on {} MPI rank(s); it continues only on as many (each rank's seeds and \
                         share of the batch depend on it): launch it with `mpirun -n {} apo train --resume …`, not {ranks}",
                        from.display(),
                        state.ranks,
                        state.ranks
                    );
                }
                if writer {
                    check_rows(&on_disk, &state, &progress_path, &from)?;
                    episodes = EpisodeLog::resume(&episodes_path, state.run.epoch)?;
                }
                rows = on_disk;
                if rows.len() > state.run.epoch {
                    tracing::info!(
                        rows = rows.len(),
                        checkpoint_epoch = state.run.epoch,
                        "progress.csv has epochs after the checkpoint; they are run again (same seed, same rows)"
                    );
                    rows.truncate(state.run.epoch);
                }
                tracing::info!(epoch = state.run.epoch, checkpoint = %from.display(), "resumed from checkpoint");
                trainer.restore(state.run).map_err(|e| match e {
                    TrainError::PastTheEnd { done, epochs } => anyhow::anyhow!(
                        "the run has {done} epochs done, more than epochs = {epochs}; pass a larger --epochs"
                    ),
                    other => other.into(),
                })?;
            }
            None if on_disk.is_empty() || !writer => {
                tracing::info!("no checkpoint and no completed epoch: the run starts from epoch 0");
            }
            None => bail!(
                "{} has {} epoch rows but there is no checkpoint ({} is missing): the run cannot continue where it \
                 stopped. Its files are kept; restore the checkpoint, or start a new run with another --out",
                progress_path.display(),
                on_disk.len(),
                checkpoint::dir(run_dir).join("latest").join("state.json").display()
            ),
        }
    }
    let mut events = writer.then(|| EventWriter::create(run_dir)).transpose()?;
    if let Some(name) = events.as_ref().and_then(|e| e.path().file_name()) {
        crate::run_dir::claim(run_dir, &name.to_string_lossy())?;
    }
    let mut videos = if writer {
        let videos = EpochVideos::new(config, run_dir)?;
        if videos.is_some() {
            crate::run_dir::own_videos(run_dir)?;
        }
        videos
    } else {
        None
    };
    let mut checkpoint_epoch = trainer.state().epoch;
    let epochs = config.train.epochs;
    // the best evaluation so far, from the rows kept (a resumed run picks up where it was)
    let metric = config.train.eval_best;
    let mut best = rows
        .iter()
        .filter_map(|r| r.evaluation(metric))
        .fold(None, |b: Option<f64>, v| Some(b.map_or(v, |b| b.max(v))));
    while !trainer.finished() {
        let report = match trainer.epoch(stop, &mut |steps| observer.steps(steps)) {
            Ok(Some(report)) => report,
            Ok(None) => {
                let state = save(&trainer, false)
                    .map_err(|e| e.context("writing the checkpoint after an interrupt"))?;
                tracing::warn!(epoch = state.run.epoch, "interrupted; checkpoint written");
                return Ok(TrainEnd::Interrupted {
                    epoch: state.run.epoch,
                });
            }
            Err(TrainError::NonFinite { epoch, what }) => {
                let kept = if checkpoint_epoch > 0 {
                    format!(
                        "The last good checkpoint (epoch {checkpoint_epoch}) is kept in {}.",
                        checkpoint::dir(run_dir).display()
                    )
                } else {
                    "No epoch had completed, so nothing was saved.".to_string()
                };
                bail!(
                    "epoch {epoch}: the update produced {what}; the run stopped without saving that epoch. {kept} \
                     The settings that scale the update, with this run's values: {}. Lower them, or check the \
                     environment's observations and rewards",
                    update_scales(config).join(", ")
                );
            }
            Err(e) => return Err(e.into()),
        };
        let row = report.row;
        let shown = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.3}"));
        tracing::info!(
            epoch = row.epoch,
            env_steps = row.env_steps,
            episodes = row.episodes,
            ret_mean = %shown(row.ep_ret_mean),
            ret_min = %shown(row.ep_ret_min),
            kl = row.kl,
            line_search = %row.line_search.as_deref().unwrap_or("-"),
            "epoch done"
        );
        if row.unstable_episodes > 0 {
            tracing::warn!(
                epoch = row.epoch,
                episodes = row.unstable_episodes,
                "episodes ended by simulator instability"
            );
        }
        observer.epoch(&row, epochs);
        rows.push(row.clone());
        if let Some(events) = &mut events {
            progress_csv::write(&progress_path, &rows)?;
            episodes.append(&report.episodes)?;
            events.scalars(row.env_steps, unix_time(), &row_scalars(&row))?;
        }
        if let Some(value) = row.evaluation(metric) {
            tracing::info!(epoch = row.epoch, ?metric, value, "evaluation");
            if best.is_none_or(|b| value > b) {
                best = Some(value);
                if writer {
                    let state = TrainState::new(trainer.state().clone()).with_ranks(ranks);
                    checkpoint::save_best(run_dir, trainer.learner(), &state, &shapes)?;
                }
            }
        }
        if let Some(videos) = videos.as_mut().filter(|v| v.due(row.epoch)) {
            // a video that fails is reported, never the end of the training
            if let Err(e) = record_video(videos, &trainer, &row, events.as_mut(), stop) {
                tracing::warn!(epoch = row.epoch, "no video of this epoch: {e:#}");
            }
        }
        // a signal seen by any rank interrupts all of them after this epoch
        let mut interrupted = [f64::from(u8::from(stop.load(Ordering::Relaxed)))];
        comm.max(&mut interrupted);
        let interrupted = interrupted[0] > 0.0;
        if let Some(due) = trainer.checkpoint_due(interrupted) {
            checkpoint_epoch = save(&trainer, due.keep)?.run.epoch;
        }
        if interrupted {
            return Ok(TrainEnd::Interrupted {
                epoch: trainer.state().epoch,
            });
        }
    }
    Ok(TrainEnd::Finished)
}

/// Records the video of the epoch of `row` with the trainer's current policy, and adds it to
/// TensorBoard's images when it is small enough.
fn record_video<B: Backend>(
    videos: &mut EpochVideos,
    trainer: &Trainer<B, MlpPolicyConfig, HostActor>,
    row: &ProgressRow,
    events: Option<&mut EventWriter>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let device = Default::default();
    let mut policy = HostPolicy::new(
        &trainer.learner().policy_on::<NdArray>(&device),
        trainer.action(),
    );
    let (path, size, result) = videos.record(
        row.epoch,
        &mut policy,
        trainer.state().normalizer.as_ref(),
        stop,
    )?;
    tracing::info!(epoch = row.epoch, video = %path.display(), returns = ?result.returns, "video");
    if let Some(events) = events {
        let context = || format!("cannot read {}", path.display());
        let length = std::fs::metadata(&path).with_context(context)?.len();
        if length <= TENSORBOARD_VIDEO_BYTES {
            let bytes = std::fs::read(&path).with_context(context)?;
            events.image(row.env_steps, unix_time(), "video/episode", size, &bytes)?;
        } else {
            tracing::info!(video = %path.display(), bytes = length, "too large for TensorBoard");
        }
    }
    Ok(())
}

/// Seconds since the Unix epoch.
fn unix_time() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// Checks that `rows` (from `progress.csv`) hold every epoch the checkpoint `state` completed.
fn check_rows(
    rows: &[ProgressRow],
    state: &TrainState,
    progress_path: &Path,
    from: &Path,
) -> anyhow::Result<()> {
    if rows.len() < state.run.epoch {
        bail!(
            "{} has {} epoch rows but the checkpoint in {} is at epoch {}: the rows of epochs {}..={} are missing \
             (was the file deleted, emptied or replaced?). Resuming would lose them; restore the file, or start a new \
             run with another --out",
            progress_path.display(),
            rows.len(),
            from.display(),
            state.run.epoch,
            rows.len() + 1,
            state.run.epoch
        );
    }
    for (i, row) in rows.iter().take(state.run.epoch).enumerate() {
        if row.epoch != i + 1 {
            bail!(
                "{}: row {} is epoch {}, expected epoch {}",
                progress_path.display(),
                i + 1,
                row.epoch,
                i + 1
            );
        }
    }
    if let Some(last) = state.run.epoch.checked_sub(1).map(|i| &rows[i]) {
        if last.env_steps != state.run.env_steps {
            bail!(
                "{} says {} environment steps after epoch {}, the checkpoint in {} says {}: they are from different runs",
                progress_path.display(),
                last.env_steps,
                state.run.epoch,
                from.display(),
                state.run.env_steps
            );
        }
    }
    Ok(())
}
