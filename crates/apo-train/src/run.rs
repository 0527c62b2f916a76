//! A training run in a directory: [`Run`] creates one (or resumes one from its files) and
//! trains it epoch by epoch with [`Trainer`], writing after each epoch what the run keeps —
//! `progress.csv`, `episodes.csv`, TensorBoard events, checkpoints, the best evaluation's
//! checkpoint and the epoch videos. A run stopped at any point (a stop flag, a crash, a killed
//! process) continues from its directory with [`Run::resume`], and the resumed run is
//! bit-identical to one that never stopped.
//!
//! The crate docs walk through a run stopped and resumed (story 4).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{bail, Context};
use apo_core::inference::HostPolicy;
use apo_core::{Comm, MlpPolicyConfig, PolicyFamily};
use burn::backend::Autodiff;
use burn::backend::NdArray;
use burn::module::AutodiffModule;
use burn::tensor::backend::Backend;

use crate::atomic;
use crate::checkpoint::{self, Shapes, TrainState, Which};
use crate::episodes_csv::EpisodeLog;
use crate::progress_csv::{self, ProgressRow};
use crate::run_config::RunConfig;
use crate::run_dir::{self, NewRunDir, RunLock};
use crate::tensorboard::{row_scalars, EventWriter};
use crate::video::{EpochVideos, TENSORBOARD_VIDEO_BYTES};
use crate::{Actor, HostActor, TrainConfig, TrainError, Trainer};

/// How a process takes part in a run.
#[derive(Debug, Clone)]
pub struct Launch {
    /// Threads stepping the environments (0: the cores available; results do not depend on it).
    pub threads: usize,
    /// The ranks of a data-parallel run (one by default).
    pub comm: Comm,
}

impl Launch {
    /// A run in one process, the environments stepped on `threads` threads.
    pub fn new(threads: usize) -> Self {
        Self {
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

/// What rank 0 writes after each epoch.
struct Files {
    progress: PathBuf,
    episodes: EpisodeLog,
    events: EventWriter,
    videos: Option<EpochVideos>,
}

/// A training run in a directory, on backend `B`, of a policy of family `F` acting through
/// `A`: by default the built-in MLP ([`Run::create`], [`Run::resume`]); any
/// [`PolicyFamily`] and environments through [`Run::create_with`] and [`Run::resume_with`].
/// See the [module docs](self).
///
/// In a data-parallel run every rank makes its `Run` with the same arguments; rank 0 alone
/// writes the run's files, the others only read the checkpoint when resuming. A checkpoint
/// records the number of ranks and resuming with another is refused.
pub struct Run<B: Backend, F: PolicyFamily = MlpPolicyConfig, A: Actor<B, F> = HostActor>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    config: RunConfig,
    dir: PathBuf,
    trainer: Trainer<B, F, A>,
    /// The host copy of the policy the epoch videos act with (the built-in MLP's).
    video_policy: Option<VideoPolicy<B, F, A>>,
    shapes: Shapes,
    comm: Comm,
    files: Option<Files>,
    rows: Vec<ProgressRow>,
    /// The best evaluation so far (the `best` checkpoint's).
    best: Option<f64>,
    /// The epoch of the last checkpoint written.
    checkpoint_epoch: usize,
    interrupted: bool,
    /// A new directory, removed again when the run fails before its first epoch.
    fresh: Option<NewRunDir>,
    lock: Option<RunLock>,
}

/// What makes a run's trainer: the process's part, the device, the trainer's maker and the
/// videos' policy.
struct Start<'a, B: Backend, F: PolicyFamily, A: Actor<B, F>, M>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    launch: &'a Launch,
    device: &'a B::Device,
    make: M,
    video_policy: Option<VideoPolicy<B, F, A>>,
}

/// Refuses a config whose run would not fit this machine's memory (a registered
/// environment's; the sizes of others are not known before they are made).
fn check_memory(config: &RunConfig) -> anyhow::Result<()> {
    if let Ok(spec) = apo_envs::registry::spec(&config.train.env) {
        config.check_memory(spec.observation_dim, crate::action_kind(&spec.action_space))?;
    }
    Ok(())
}

/// How the epoch videos get the policy: a host copy of the trainer's.
type VideoPolicy<B, F, A> = fn(&Trainer<B, F, A>) -> HostPolicy;

/// The host copy of the built-in MLP's policy.
fn mlp_host_policy<B: Backend>(trainer: &Trainer<B, MlpPolicyConfig, HostActor>) -> HostPolicy {
    HostPolicy::new(
        &trainer.learner().policy_on::<NdArray>(&Default::default()),
        trainer.action(),
    )
}

impl<B: Backend> Run<B> {
    /// Creates a new run of `config` with the built-in MLP policy: see [`Run::create_with`].
    ///
    /// # Errors
    /// As [`Run::create_with`].
    pub fn create(
        dir: &Path,
        config: RunConfig,
        launch: &Launch,
        device: &B::Device,
        force: bool,
    ) -> anyhow::Result<Self> {
        let make = |config, threads| Trainer::mlp(config, device, threads);
        Self::create_inner(
            dir,
            config,
            launch,
            device,
            force,
            make,
            Some(mlp_host_policy),
        )
    }

    /// Continues the run in `dir` with the built-in MLP policy: see [`Run::resume_with`].
    ///
    /// # Errors
    /// As [`Run::resume_with`].
    pub fn resume(
        dir: &Path,
        launch: &Launch,
        device: &B::Device,
        epochs: Option<usize>,
    ) -> anyhow::Result<Self> {
        let make = |config, threads| Trainer::mlp(config, device, threads);
        Self::resume_inner(dir, launch, device, epochs, make, Some(mlp_host_policy))
    }
}

impl<B: Backend, F: PolicyFamily, A: Actor<B, F>> Run<B, F, A>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    /// Creates a new run of `config` in `dir`: the directory is made (or an empty one taken;
    /// with `force`, an earlier run's files that apo made are replaced: see
    /// [`NewRunDir::prepare`]), locked, and `config.toml` written into it. Nothing is left
    /// behind when this, or the first epoch, fails.
    ///
    /// # Errors
    /// A config whose run would not fit this machine's memory, an environment that cannot be
    /// made, a directory that may not be used (naming why), a failed write.
    pub fn create_with(
        dir: &Path,
        config: RunConfig,
        launch: &Launch,
        device: &B::Device,
        force: bool,
        make: impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
    ) -> anyhow::Result<Self> {
        Self::create_inner(dir, config, launch, device, force, make, None)
    }

    fn create_inner(
        dir: &Path,
        config: RunConfig,
        launch: &Launch,
        device: &B::Device,
        force: bool,
        make: impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
        video_policy: Option<VideoPolicy<B, F, A>>,
    ) -> anyhow::Result<Self> {
        check_memory(&config)?;
        let start = Start {
            launch,
            device,
            make,
            video_policy,
        };
        if launch.comm.rank() != 0 {
            // rank 0 prepares the directory and writes its files
            return Self::open(config, dir, start, false, None, None);
        }
        let mut prepared = NewRunDir::prepare(dir, force)?;
        let lock = prepared.take_lock().context("the run directory's lock")?;
        let config_path = dir.join(run_dir::CONFIG);
        let written = run_dir::claim_new(dir, &[run_dir::CONFIG, run_dir::LOG]).and_then(|()| {
            atomic::write(&config_path, config.to_toml().as_bytes())
                .with_context(|| format!("cannot write {}", config_path.display()))
        });
        if let Err(e) = written {
            drop(lock);
            prepared.discard();
            return Err(e);
        }
        Self::open(config, dir, start, false, Some(prepared), Some(lock))
    }

    /// Continues the run in `dir` from its latest checkpoint, with the `config.toml` it was
    /// created with; `epochs` raises (or lowers) its target, which is then written into
    /// `config.toml` so that a later resume continues to it.
    ///
    /// Resuming checks that the checkpoint and `progress.csv` agree (rows of every completed
    /// epoch, with matching step counts) and refuses with the reason when they don't; epochs
    /// after the checkpoint are run again (same seeds, same rows).
    ///
    /// # Errors
    /// `dir` not a run of apo, locked by another process, a checkpoint that fails its checks
    /// (naming the file), a config edited since the checkpoint (naming the key and both values).
    pub fn resume_with(
        dir: &Path,
        launch: &Launch,
        device: &B::Device,
        epochs: Option<usize>,
        make: impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
    ) -> anyhow::Result<Self> {
        Self::resume_inner(dir, launch, device, epochs, make, None)
    }

    fn resume_inner(
        dir: &Path,
        launch: &Launch,
        device: &B::Device,
        epochs: Option<usize>,
        make: impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
        video_policy: Option<VideoPolicy<B, F, A>>,
    ) -> anyhow::Result<Self> {
        let writer = launch.comm.rank() == 0;
        let config_path = dir.join(run_dir::CONFIG);
        let mut config = run_dir::check_resumable(dir)?;
        if writer {
            run_dir::check_own_places(dir)?;
        }
        let lock = writer.then(|| RunLock::acquire(dir)).transpose()?;
        if let Some(epochs) = epochs {
            config.train.epochs = epochs;
            config.validate()?;
        }
        check_memory(&config)?;
        let start = Start {
            launch,
            device,
            make,
            video_policy,
        };
        let to_write = (epochs.is_some() && writer).then(|| config.to_toml());
        let mut run = Self::open(config, dir, start, true, None, lock)?;
        run.remake_kept()?;
        if let Some(text) = to_write {
            // the new target is part of the run: a later plain resume continues to it. Written
            // only now that the checkpoint loaded and accepted it: a refused resume writes nothing
            atomic::write(&config_path, text.as_bytes())
                .with_context(|| format!("cannot write {}", config_path.display()))?;
        }
        Ok(run)
    }

    /// The run's networks and counters, from the latest checkpoint when `resume`.
    fn open(
        config: RunConfig,
        run_dir: &Path,
        start: Start<
            '_,
            B,
            F,
            A,
            impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
        >,
        resume: bool,
        fresh: Option<NewRunDir>,
        lock: Option<RunLock>,
    ) -> anyhow::Result<Self> {
        let (comm, video_policy) = (start.launch.comm.clone(), start.video_policy);
        let opened = Self::open_files(&config, run_dir, start, resume);
        match opened {
            Ok((trainer, shapes, files, rows)) => {
                let metric = config.train.eval_best;
                // the best evaluation so far, from the rows kept (a resumed run picks up where it was)
                let best = rows
                    .iter()
                    .filter_map(|r| r.evaluation(metric))
                    .fold(None, |b: Option<f64>, v| Some(b.map_or(v, |b| b.max(v))));
                Ok(Self {
                    checkpoint_epoch: trainer.state().epoch,
                    config,
                    dir: run_dir.to_path_buf(),
                    trainer,
                    shapes,
                    comm,
                    video_policy,
                    files,
                    rows,
                    best,
                    interrupted: false,
                    fresh,
                    lock,
                })
            }
            Err(e) => {
                if let Some(fresh) = fresh {
                    drop(lock);
                    fresh.discard();
                }
                Err(e)
            }
        }
    }

    #[allow(clippy::type_complexity)]
    fn open_files(
        config: &RunConfig,
        run_dir: &Path,
        start: Start<
            '_,
            B,
            F,
            A,
            impl FnOnce(TrainConfig, usize) -> Result<Trainer<B, F, A>, TrainError>,
        >,
        resume: bool,
    ) -> anyhow::Result<(Trainer<B, F, A>, Shapes, Option<Files>, Vec<ProgressRow>)> {
        let Start {
            launch,
            device,
            make,
            video_policy,
        } = start;
        let Launch { threads, ref comm } = *launch;
        let writer = comm.rank() == 0;
        if writer && resume {
            // what a process stopped mid-write left (this process holds the run's lock)
            crate::run_dir::remove_stale_temps(run_dir)?;
        }
        if config.render_every > 0 && video_policy.is_none() {
            bail!(
                "render_every = {}: the epoch videos act through the built-in MLP's host copy; with a policy of \
                 your own set render_every = 0 (record videos with apo_train::video from your own loop)",
                config.render_every
            );
        }
        let mut trainer = make(config.train.clone(), threads)?;
        trainer
            .learner_mut()
            .set_kernels(config.kernels.resolve(config.backend));
        let ranks = comm.size();
        if comm.is_distributed() {
            trainer.distribute(comm.clone())?;
        }
        // every environment takes the same number of steps: an epoch is rounded up to whole
        // steps of all of them, which is said, never done silently
        let (steps, envs) = (config.train.steps_per_epoch, config.train.num_envs);
        let collected = (steps / ranks).div_ceil(envs) * envs * ranks;
        if collected != steps && comm.rank() == 0 {
            crate::warnln!(
                "note: each epoch collects {collected} steps: steps_per_epoch = {steps} rounded up to whole steps of \
                 the num_envs = {envs} environments{} (set a multiple of {} to collect exactly)",
                if ranks > 1 { format!(" on each of the {ranks} ranks") } else { String::new() },
                envs * ranks
            );
        }
        let shapes = Shapes::of(config, trainer.observation_dim(), trainer.action());
        let progress_path = run_dir.join(crate::run_dir::PROGRESS);
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
                        if let Some(counted) = state.episode_records.filter(|&n| n != episodes.records()) {
                            bail!(
                                "{} holds {} episode records of epochs 1..={}, the checkpoint in {} counted {counted} \
                                 (was the file deleted, emptied or edited?). Resuming would continue a record that is not \
                                 the run's; restore the file, or start a new run with another --out",
                                episodes_path.display(),
                                episodes.records(),
                                state.run.epoch,
                                from.display()
                            );
                        }
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
                // stopped before its first checkpoint was written (killed, or the disk full
                // when it was due): epoch 0 is its last checkpoint, and the rows after it are
                // run again like those after any other checkpoint (same seed, same rows)
                None if on_disk.len() <= checkpoint::first_due(&config.train) => {
                    tracing::info!(
                        rows = on_disk.len(),
                        "the run stopped before its first checkpoint: it starts again from epoch 0 (same seed, same rows)"
                    );
                    episodes = EpisodeLog::resume(&episodes_path, 0)?;
                }
                None => bail!(
                    "{} has {} epoch rows but there is no checkpoint ({} is missing, although one was due at epoch {}): \
                     the run cannot continue where it stopped. Its files are kept; restore the checkpoint, or train \
                     it again from epoch 0 in place with `apo train --config {} --out {} --force` (or into another --out)",
                    progress_path.display(),
                    on_disk.len(),
                    checkpoint::dir(run_dir).join("latest").join("state.json").display(),
                    checkpoint::first_due(&config.train),
                    run_dir.join(crate::run_dir::CONFIG).display(),
                    run_dir.display()
                ),
            }
        }
        let files = if writer {
            // what this run will create, recorded before it exists (the run directory's
            // marker), once a resumed run's checkpoint and records passed their checks: a
            // refused resume writes nothing
            crate::run_dir::claim_new(
                run_dir,
                &[
                    crate::run_dir::PROGRESS,
                    crate::run_dir::EPISODES,
                    crate::run_dir::CHECKPOINTS,
                ],
            )?;
            let events = EventWriter::create(run_dir)?;
            if let Some(name) = events.path().file_name() {
                crate::run_dir::claim(run_dir, &name.to_string_lossy())?;
            }
            let videos = EpochVideos::new(config, run_dir)?;
            if videos.is_some() {
                crate::run_dir::own_videos(run_dir)?;
            }
            Some(Files {
                progress: progress_path,
                episodes,
                events,
                videos,
            })
        } else {
            None
        };
        Ok((trainer, shapes, files, rows))
    }

    /// Trains the next epoch and writes its files (after the row is in `progress.csv`, a
    /// checkpoint when one is due); returns its row, or `None` once the run is finished or
    /// stopped. `on_steps` gets the run's environment steps during the rollout.
    ///
    /// `stop` raised (by any rank of a data-parallel run) ends the run after the current
    /// epoch — or, when it is raised during the rollout, at once, without that epoch — with a
    /// checkpoint of the last completed epoch; [`Run::interrupted`] then says so. An update
    /// that produces a non-finite value stops the run with an error, before anything of that
    /// epoch is written, keeping the last good checkpoint.
    ///
    /// # Errors
    /// A failed write, or the update's non-finite value (naming the settings that scale it).
    pub fn epoch(
        &mut self,
        stop: &AtomicBool,
        on_steps: &mut dyn FnMut(u64),
    ) -> anyhow::Result<Option<ProgressRow>> {
        let result = self.next_epoch(stop, on_steps);
        if result.is_err() && self.rows.is_empty() {
            // a new run that failed before its first epoch leaves nothing behind
            if let Some(fresh) = self.fresh.take() {
                drop(self.lock.take());
                fresh.discard();
            }
        }
        if !self.rows.is_empty() {
            self.fresh = None;
        }
        result
    }

    fn next_epoch(
        &mut self,
        stop: &AtomicBool,
        on_steps: &mut dyn FnMut(u64),
    ) -> anyhow::Result<Option<ProgressRow>> {
        if self.interrupted || self.trainer.finished() {
            return Ok(None);
        }
        let report = match self.trainer.epoch(stop, on_steps) {
            Ok(Some(report)) => report,
            Ok(None) => {
                self.checkpoint()
                    .map_err(|e| e.context("writing the checkpoint after an interrupt"))?;
                tracing::warn!(
                    epoch = self.checkpoint_epoch,
                    "interrupted; checkpoint written"
                );
                self.interrupted = true;
                return Ok(None);
            }
            Err(TrainError::NonFinite { epoch, what }) => {
                let kept = if self.checkpoint_epoch > 0 {
                    format!(
                        "The last good checkpoint (epoch {}) is kept in {}.",
                        self.checkpoint_epoch,
                        checkpoint::dir(&self.dir).display()
                    )
                } else {
                    "No epoch had completed, so nothing was saved.".to_string()
                };
                bail!(
                    "epoch {epoch}: the update produced {what}; the run stopped without saving that epoch. {kept} \
                     The settings that scale the update, with this run's values: {}. Lower them, or check the \
                     environment's observations and rewards",
                    update_scales(&self.config).join(", ")
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
        self.rows.push(row.clone());
        if let Some(files) = &mut self.files {
            progress_csv::write(&files.progress, &self.rows)?;
            files.episodes.append(&report.episodes)?;
            files
                .events
                .scalars(row.env_steps, unix_time(), &row_scalars(&row))?;
        }
        let metric = self.config.train.eval_best;
        if let Some(value) = row.evaluation(metric) {
            tracing::info!(epoch = row.epoch, ?metric, value, "evaluation");
            if self.best.is_none_or(|b| value > b) {
                self.best = Some(value);
                if self.files.is_some() {
                    let state = self.state();
                    checkpoint::save_best(&self.dir, self.trainer.learner(), &state, &self.shapes)?;
                }
            }
        }
        if let Some(files) = self.files.as_mut() {
            if let Some(videos) = files.videos.as_mut().filter(|v| v.due(row.epoch)) {
                // a video that fails is reported, never the end of the training
                let policy = self.video_policy.map(|host| host(&self.trainer));
                let recorded =
                    policy
                        .context("no host policy for the video")
                        .and_then(|mut policy| {
                            record_video(
                                videos,
                                &mut policy,
                                &self.trainer,
                                &row,
                                &mut files.events,
                                stop,
                            )
                        });
                if let Err(e) = recorded {
                    tracing::warn!(epoch = row.epoch, "no video of this epoch: {e:#}");
                }
            }
        }
        // a stop seen by any rank interrupts all of them after this epoch
        let mut interrupted = [f64::from(u8::from(stop.load(Ordering::Relaxed)))];
        self.comm.max(&mut interrupted);
        self.interrupted = interrupted[0] > 0.0;
        if let Some(due) = self.trainer.checkpoint_due(self.interrupted) {
            self.save(due.keep)?;
        }
        Ok(Some(row))
    }

    /// Writes a checkpoint of the run as it is now into `checkpoints/latest` (rank 0; the
    /// other ranks write nothing). [`Run::epoch`] writes them on the run's schedule
    /// (`checkpoint_every`) and when stopped; call it to have one at another epoch.
    ///
    /// # Errors
    /// A failed write (the previous checkpoint stays complete).
    pub fn checkpoint(&mut self) -> anyhow::Result<()> {
        self.save(false)
    }

    /// Makes the kept checkpoint (`checkpoints/epoch-<N>`) of the epoch the run resumes at
    /// when the schedule keeps one and it is missing: a stop between that epoch's two writes
    /// (`latest`, then the kept copy) leaves only `latest`, whose state the kept one holds.
    fn remake_kept(&mut self) -> anyhow::Result<()> {
        let epoch = self.trainer.state().epoch;
        let keep = self
            .trainer
            .checkpoint_due(false)
            .is_some_and(|due| due.keep);
        if self.files.is_some()
            && epoch > 0
            && keep
            && !checkpoint::kept_epochs(&self.dir).contains(&epoch)
        {
            self.save(true)?;
        }
        Ok(())
    }

    fn save(&mut self, keep: bool) -> anyhow::Result<()> {
        let state = self.state();
        if self.files.is_some() {
            checkpoint::save(
                &self.dir,
                self.trainer.learner(),
                &state,
                &self.shapes,
                keep,
            )?;
        }
        self.checkpoint_epoch = state.run.epoch;
        Ok(())
    }

    fn state(&self) -> TrainState {
        let state = TrainState::new(self.trainer.state().clone()).with_ranks(self.comm.size());
        match &self.files {
            Some(files) => state.with_episode_records(files.episodes.records()),
            None => state,
        }
    }

    /// Whether every epoch of the config has run.
    pub fn finished(&self) -> bool {
        self.trainer.finished()
    }

    /// Whether the stop flag ended the run (a checkpoint of its last epoch was written).
    pub fn interrupted(&self) -> bool {
        self.interrupted
    }

    /// Epochs completed.
    pub fn epochs_done(&self) -> usize {
        self.trainer.state().epoch
    }

    /// The run's config (as in its `config.toml`).
    pub fn config(&self) -> &RunConfig {
        &self.config
    }

    /// The run's directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The rows of the completed epochs (`progress.csv`).
    pub fn rows(&self) -> &[ProgressRow] {
        &self.rows
    }

    /// The trainer: its learner (the networks), counters and environments.
    pub fn trainer(&self) -> &Trainer<B, F, A> {
        &self.trainer
    }
}

/// Records the video of the epoch of `row` with the trainer's current policy, and adds it to
/// TensorBoard's images when it is small enough.
fn record_video<B: Backend, F: PolicyFamily, A: Actor<B, F>>(
    videos: &mut EpochVideos,
    policy: &mut HostPolicy,
    trainer: &Trainer<B, F, A>,
    row: &ProgressRow,
    events: &mut EventWriter,
    stop: &AtomicBool,
) -> anyhow::Result<()>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    let (path, size, result) =
        videos.record(row.epoch, policy, trainer.state().normalizer.as_ref(), stop)?;
    tracing::info!(epoch = row.epoch, video = %path.display(), returns = ?result.returns, "video");
    let context = || format!("cannot read {}", path.display());
    let length = std::fs::metadata(&path).with_context(context)?.len();
    if length <= TENSORBOARD_VIDEO_BYTES {
        let bytes = std::fs::read(&path).with_context(context)?;
        events.image(row.env_steps, unix_time(), "video/episode", size, &bytes)?;
    } else {
        tracing::info!(video = %path.display(), bytes = length, "too large for TensorBoard");
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
        // the epochs of 1..=checkpoint that have no row, as ranges
        let mut epochs: Vec<usize> = rows
            .iter()
            .map(|r| r.epoch)
            .filter(|&e| e <= state.run.epoch)
            .collect();
        epochs.push(state.run.epoch + 1);
        let missing: Vec<String> = progress_csv::gaps(epochs)
            .into_iter()
            .map(|(a, b)| {
                if a == b {
                    a.to_string()
                } else {
                    format!("{a}..={b}")
                }
            })
            .collect();
        bail!(
            "{} has {} epoch rows but the checkpoint in {} is at epoch {}: the rows of epoch(s) {} are missing \
             (was the file edited, emptied or replaced?). Resuming would lose them; restore the file, or start a new \
             run with another --out",
            progress_path.display(),
            rows.len(),
            from.display(),
            state.run.epoch,
            missing.join(", ")
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
