//! Run directories: the files apo writes into one, the lock that keeps two trainings out of
//! the same directory, and `--force`, which replaces a run but never anything apo did not make.
//!
//! A run directory is one whose `config.toml` is a valid run configuration. Inside it apo
//! owns `config.toml`, `progress.csv`, `train.log`, `apo.lock`, `checkpoints/`, TensorBoard's
//! `events.out.tfevents.*` files and its own temporary files (`.<name>.tmp`); everything
//! else (a plot the user wrote there, notes) is left alone, even by `--force`.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use crate::config::RunConfig;

/// `env` as a part of a file name: the path separators of a namespaced name become `_`
/// (`ALE/Pong-v5` → `ALE_Pong-v5`), so that a run of it is one directory, not two.
pub fn env_label(env: &str) -> String {
    env.replace(['/', '\\'], "_")
}

/// The run's configuration.
pub const CONFIG: &str = "config.toml";
/// One row per epoch.
pub const PROGRESS: &str = "progress.csv";
/// The training log.
pub const LOG: &str = "train.log";
/// The lock file held while a training runs.
pub const LOCK: &str = "apo.lock";
/// The checkpoints folder.
pub const CHECKPOINTS: &str = "checkpoints";
/// TensorBoard event files start with this.
pub const EVENTS_PREFIX: &str = "events.out.tfevents.";

/// Whether apo made the entry `name` of a run directory.
fn is_run_entry(name: &str) -> bool {
    matches!(name, CONFIG | PROGRESS | LOG | LOCK | CHECKPOINTS)
        || name.starts_with(EVENTS_PREFIX)
        || [CONFIG, PROGRESS, LOG]
            .iter()
            .any(|f| name == format!(".{f}.tmp"))
}

/// Whether `dir` is a run directory (its `config.toml` is a valid run configuration).
pub fn is_run_dir(dir: &Path) -> bool {
    RunConfig::load(&dir.join(CONFIG)).is_ok()
}

/// An exclusive lock on a run directory, held while it lives (an OS file lock on
/// `apo.lock`, released by the OS also when the process dies).
#[derive(Debug)]
pub struct RunLock {
    _file: File,
}

impl RunLock {
    /// Locks `dir`; fails, naming the other process, when another apo holds it.
    pub fn acquire(dir: &Path) -> anyhow::Result<Self> {
        let path = dir.join(LOCK);
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .with_context(|| format!("cannot open the lock file {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                let who = if holder.is_empty() {
                    String::new()
                } else {
                    format!(" ({holder})")
                };
                bail!(
                    "run directory {} is in use by another apo process{who}; wait for it to end or stop it first",
                    dir.display()
                );
            }
            Err(TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("cannot lock {}", path.display()));
            }
        }
        let stamp = format!("pid {}\n", std::process::id());
        file.set_len(0)
            .and_then(|()| file.rewind())
            .and_then(|()| file.write_all(stamp.as_bytes()))
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Self { _file: file })
    }
}

/// A run directory prepared for a new run, locked.
#[derive(Debug)]
pub struct NewRunDir {
    dir: PathBuf,
    created: bool,
    lock: Option<RunLock>,
}

impl NewRunDir {
    /// Prepares `dir` for a new run: creates it, or takes an empty existing one, or with
    /// `force` empties an existing *run directory* of apo's files (anything else in it is
    /// kept and listed on stderr). Refuses a non-empty directory without `force`, and
    /// anything that is not a run directory even with it; nothing is touched then.
    pub fn prepare(dir: &Path, force: bool) -> anyhow::Result<Self> {
        if !dir.exists() {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
            let lock = RunLock::acquire(dir)?;
            return Ok(Self {
                dir: dir.to_path_buf(),
                created: true,
                lock: Some(lock),
            });
        }
        if !dir.is_dir() {
            bail!(
                "{} exists and is not a directory; choose another --out",
                dir.display()
            );
        }
        let entries = entry_names(dir)?;
        if entries.iter().all(|n| n == LOCK) {
            let lock = RunLock::acquire(dir)?;
            return Ok(Self {
                dir: dir.to_path_buf(),
                created: false,
                lock: Some(lock),
            });
        }
        if !force {
            bail!(
                "run directory {} already exists; pass --force to replace it, or --resume {} to continue it",
                dir.display(),
                dir.display()
            );
        }
        if !is_run_dir(dir) {
            bail!(
                "--force replaces only a run directory of apo (one with a valid {CONFIG}), and {} is not one \
                 ({} entries, e.g. `{}`); nothing in it was touched — choose another --out",
                dir.display(),
                entries.len(),
                entries.first().map_or("", String::as_str)
            );
        }
        let lock = RunLock::acquire(dir)?;
        let mut kept = Vec::new();
        for name in entries {
            if name == LOCK {
                continue;
            }
            if !is_run_entry(&name) {
                kept.push(name);
                continue;
            }
            let path = dir.join(&name);
            let removed = if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else {
                std::fs::remove_file(&path)
            };
            removed.with_context(|| format!("cannot remove {}", path.display()))?;
        }
        if !kept.is_empty() {
            eprintln!(
                "--force kept what apo did not create in {}: {}",
                dir.display(),
                kept.join(", ")
            );
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            created: false,
            lock: Some(lock),
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Takes the lock out, to be held by the training.
    pub fn take_lock(&mut self) -> Option<RunLock> {
        self.lock.take()
    }

    /// Undoes [`NewRunDir::prepare`] after a run failed before its first epoch: removes
    /// apo's files, and the directory itself when this run created it and nothing else is in it.
    pub fn discard(mut self) {
        drop(self.lock.take());
        let Ok(entries) = entry_names(&self.dir) else {
            return;
        };
        for name in entries.iter().filter(|n| is_run_entry(n)) {
            let path = self.dir.join(name);
            let _ = if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else {
                std::fs::remove_file(&path)
            };
        }
        if self.created {
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

fn entry_names(dir: &Path) -> anyhow::Result<Vec<String>> {
    let mut names = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("cannot read {}", dir.display()))?;
    names.sort();
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_entries_are_apos_own_files() {
        for name in [
            "config.toml",
            "progress.csv",
            "train.log",
            "apo.lock",
            "checkpoints",
            ".progress.csv.tmp",
        ] {
            assert!(is_run_entry(name), "{name}");
        }
        assert!(is_run_entry("events.out.tfevents.1700000000.host"));
        for name in [
            "thesis.txt",
            "curves.png",
            ".git",
            "config.toml.bak",
            "progress.csv.old",
        ] {
            assert!(!is_run_entry(name), "{name}");
        }
    }

    #[test]
    fn a_second_lock_on_the_same_directory_is_refused() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let first = RunLock::acquire(tmp.path()).expect("first lock");
        let err = RunLock::acquire(tmp.path()).expect_err("second lock must fail");
        assert!(
            err.to_string().contains("in use by another apo process"),
            "{err}"
        );
        assert!(
            err.to_string()
                .contains(&format!("pid {}", std::process::id())),
            "{err}"
        );
        drop(first);
        RunLock::acquire(tmp.path()).expect("free again");
    }
}
