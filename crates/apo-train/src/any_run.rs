//! [`AnyRun`]: a [`Run`] of the built-in MLP policy on the backend its config names, chosen at
//! run time, behind one type.
//!
//! The training loop is generic over the backend. A program that picks the backend from a
//! config (the `apo` binary, its benchmarks, a user's tool) would otherwise instantiate it
//! for every backend in each of its crates; `AnyRun` instantiates it here, once per backend
//! apo-train is built with, and the program calls plain functions.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use burn::tensor::backend::Backend;

use crate::backend::{BackendKind, OnBackend};
use crate::progress_csv::ProgressRow;
use crate::run::{Launch, Run};
use crate::run_config::RunConfig;

/// A [`Run`] of the built-in MLP policy on the backend of its config (`backend`), on that
/// backend's default device. Its methods are [`Run`]'s.
pub struct AnyRun(Box<dyn Erased>);

/// What [`AnyRun`] needs of a [`Run`], without its backend in the type.
trait Erased {
    fn epoch(
        &mut self,
        stop: &AtomicBool,
        on_steps: &mut dyn FnMut(u64),
    ) -> anyhow::Result<Option<ProgressRow>>;
    fn checkpoint(&mut self) -> anyhow::Result<()>;
    fn finished(&self) -> bool;
    fn interrupted(&self) -> bool;
    fn epochs_done(&self) -> usize;
    fn config(&self) -> &RunConfig;
    fn dir(&self) -> &Path;
    fn rows(&self) -> &[ProgressRow];
}

impl<B: Backend> Erased for Run<B> {
    fn epoch(
        &mut self,
        stop: &AtomicBool,
        on_steps: &mut dyn FnMut(u64),
    ) -> anyhow::Result<Option<ProgressRow>> {
        Run::epoch(self, stop, on_steps)
    }
    fn checkpoint(&mut self) -> anyhow::Result<()> {
        Run::checkpoint(self)
    }
    fn finished(&self) -> bool {
        Run::finished(self)
    }
    fn interrupted(&self) -> bool {
        Run::interrupted(self)
    }
    fn epochs_done(&self) -> usize {
        Run::epochs_done(self)
    }
    fn config(&self) -> &RunConfig {
        Run::config(self)
    }
    fn dir(&self) -> &Path {
        Run::dir(self)
    }
    fn rows(&self) -> &[ProgressRow] {
        Run::rows(self)
    }
}

/// Creates or resumes a run on the backend [`BackendKind::dispatch`] picks.
enum Open<'a> {
    Create {
        dir: &'a Path,
        config: Box<RunConfig>,
        launch: &'a Launch,
        force: bool,
    },
    Resume {
        dir: &'a Path,
        launch: &'a Launch,
        epochs: Option<usize>,
    },
}

impl OnBackend for Open<'_> {
    type Output = anyhow::Result<AnyRun>;

    fn run<B: Backend>(self) -> anyhow::Result<AnyRun> {
        let device = B::Device::default();
        let run: Run<B> = match self {
            Open::Create {
                dir,
                config,
                launch,
                force,
            } => Run::create(dir, *config, launch, &device, force)?,
            Open::Resume {
                dir,
                launch,
                epochs,
            } => Run::resume(dir, launch, &device, epochs)?,
        };
        Ok(AnyRun(Box::new(run)))
    }
}

impl AnyRun {
    /// [`Run::create`] on the backend `config.backend` names.
    ///
    /// # Errors
    /// As [`Run::create`], or a backend this build lacks ([`BackendKind::dispatch`]).
    pub fn create(
        dir: &Path,
        config: RunConfig,
        launch: &Launch,
        force: bool,
    ) -> anyhow::Result<Self> {
        let backend = config.backend;
        backend.dispatch(Open::Create {
            dir,
            config: Box::new(config),
            launch,
            force,
        })?
    }

    /// [`Run::resume`] of the run in `dir` on `backend`, the backend of its `config.toml`
    /// (which [`crate::run_dir::check_resumable`] returns).
    ///
    /// # Errors
    /// As [`Run::resume`], or a backend this build lacks ([`BackendKind::dispatch`]).
    pub fn resume(
        backend: BackendKind,
        dir: &Path,
        launch: &Launch,
        epochs: Option<usize>,
    ) -> anyhow::Result<Self> {
        backend.dispatch(Open::Resume {
            dir,
            launch,
            epochs,
        })?
    }

    /// [`Run::epoch`].
    ///
    /// # Errors
    /// As [`Run::epoch`].
    pub fn epoch(
        &mut self,
        stop: &AtomicBool,
        on_steps: &mut dyn FnMut(u64),
    ) -> anyhow::Result<Option<ProgressRow>> {
        self.0.epoch(stop, on_steps)
    }

    /// [`Run::checkpoint`].
    ///
    /// # Errors
    /// As [`Run::checkpoint`].
    pub fn checkpoint(&mut self) -> anyhow::Result<()> {
        self.0.checkpoint()
    }

    /// [`Run::finished`].
    pub fn finished(&self) -> bool {
        self.0.finished()
    }

    /// [`Run::interrupted`].
    pub fn interrupted(&self) -> bool {
        self.0.interrupted()
    }

    /// [`Run::epochs_done`].
    pub fn epochs_done(&self) -> usize {
        self.0.epochs_done()
    }

    /// [`Run::config`].
    pub fn config(&self) -> &RunConfig {
        self.0.config()
    }

    /// [`Run::dir`].
    pub fn dir(&self) -> &Path {
        self.0.dir()
    }

    /// [`Run::rows`].
    pub fn rows(&self) -> &[ProgressRow] {
        self.0.rows()
    }
}
