//! Run directories: the files apo writes into one, the lock that keeps two trainings out of
//! the same directory, and the one place where apo removes files.
//!
//! **Ownership.** apo removes only what it can prove it created. A run directory holds a
//! marker, `.apo-run`, listing the entries apo created in it (`config.toml`, `progress.csv`,
//! `train.log`, `apo.lock`, `checkpoints`, TensorBoard's `events.out.tfevents.*` files); an
//! entry is listed only when apo created it, never when it was there before. Inside
//! `checkpoints/` apo owns the checkpoint folders it names (`latest`, `previous`,
//! `epoch-<N>`, `.tmp-*`) and, inside them, the files a checkpoint consists of; inside
//! `videos/`, the videos it names (`epoch-<N>.gif`, `render.gif`). Every removal
//! goes through [`crate::removal::remove_created`]: it deletes the named *files* (never a directory with what
//! is in it) and removes a folder only once it is empty, so a user's file anywhere under a run
//! directory survives `--force`, a failed start, a sweep re-run and checkpoint rotation.
//!
//! A directory is a run directory for `--force` only with the marker; `--resume` also takes a
//! run written before the marker existed (one with a checkpoint), and `apo report`/`summary`
//! read any directory with a valid `config.toml`.

use std::collections::BTreeSet;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use crate::run_config::RunConfig;

/// `env` as a part of a file name: the path separators of a namespaced name become `_`
/// (`ALE/Pong-v5` → `ALE_Pong-v5`), so that a run of it is one directory, not two.
pub fn env_label(env: &str) -> String {
    env.replace(['/', '\\'], "_")
}

/// The run's configuration.
pub const CONFIG: &str = "config.toml";
/// One row per epoch.
pub const PROGRESS: &str = "progress.csv";
/// The run's per-episode record.
pub const EPISODES: &str = "episodes.csv";
/// The training log.
pub const LOG: &str = "train.log";
/// The lock file held while a training runs.
pub const LOCK: &str = "apo.lock";
/// The checkpoints folder.
pub const CHECKPOINTS: &str = crate::checkpoint::FOLDER;
/// The folder of a run's videos.
pub const VIDEOS: &str = "videos";
/// TensorBoard event files start with this.
pub const EVENTS_PREFIX: &str = "events.out.tfevents.";
/// The marker of a run directory: the entries apo created in it, one per line.
pub const MARKER: &str = ".apo-run";

const MARKER_HEADER: &str =
    "# apo: the entries apo created in this folder, the only ones it will ever remove";

/// The names apo gives its files in a run directory (a file of one of these names that apo
/// did not create blocks `--force`: the new run would overwrite it).
const FIXED: [&str; 5] = [CONFIG, PROGRESS, EPISODES, LOG, CHECKPOINTS];

/// The entries listed in `dir`'s marker; `None` when `dir` has no marker.
///
/// # Errors
/// A marker that cannot be read.
pub fn created_entries(dir: &Path) -> anyhow::Result<Option<BTreeSet<String>>> {
    created_entries_in(dir, MARKER)
}

/// The entries listed in the marker file `marker` of `dir` (a run directory's `.apo-run`, a
/// report folder's `.apo-report`); `None` without one.
///
/// # Errors
/// A marker that cannot be read.
pub fn created_entries_in(dir: &Path, marker: &str) -> anyhow::Result<Option<BTreeSet<String>>> {
    let path = dir.join(marker);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(None);
    }
    let text = crate::input::read_text(&path, "the run directory's marker", 1 << 20)?;
    Ok(Some(
        text.lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            // names only: a listed path never leads out of the directory
            .filter(|l| !l.contains(['/', '\\']) && *l != "." && *l != "..")
            .map(str::to_string)
            .collect(),
    ))
}

fn write_marker(dir: &Path, entries: &BTreeSet<String>) -> anyhow::Result<()> {
    write_marker_in(dir, MARKER, entries)
}

fn write_marker_in(dir: &Path, marker: &str, entries: &BTreeSet<String>) -> anyhow::Result<()> {
    let mut text = format!("{MARKER_HEADER}\n");
    for e in entries {
        text.push_str(e);
        text.push('\n');
    }
    let path = dir.join(marker);
    crate::atomic::write(&path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Records in `dir`'s marker that apo created the entry `name` (creating the marker when it
/// is missing). Call it only for an entry this process made.
///
/// # Errors
/// When the marker cannot be read or written.
pub fn claim(dir: &Path, name: &str) -> anyhow::Result<()> {
    let mut entries = created_entries(dir)?.unwrap_or_default();
    if entries.insert(name.to_string()) || !dir.join(MARKER).exists() {
        write_marker(dir, &entries)?;
    }
    Ok(())
}

/// [`claim`]s each of `names` that does not exist in `dir` yet (call it before creating them;
/// an entry that is already there was not made by this call and is not claimed).
///
/// # Errors
/// When the marker cannot be read or written.
pub fn claim_new(dir: &Path, names: &[&str]) -> anyhow::Result<()> {
    let mut entries = created_entries(dir)?.unwrap_or_default();
    let before = entries.len();
    for name in names {
        if std::fs::symlink_metadata(dir.join(name)).is_err() {
            entries.insert((*name).to_string());
        }
    }
    if entries.len() != before || !dir.join(MARKER).exists() {
        write_marker(dir, &entries)?;
    }
    Ok(())
}

/// The run's video folder `videos/`, claimed for apo and created when it is not there yet:
/// the videos apo names there (`render.gif`, `epoch-<N>.gif`) are then apo's own, replaced by
/// each render. A `videos` that apo did not make (a user's folder, or a link) is refused: apo
/// would otherwise replace the files of the user's of those names.
///
/// # Errors
/// A `videos` apo did not make, or one that cannot be created.
pub fn own_videos(run: &Path) -> anyhow::Result<PathBuf> {
    claim_new(run, &[VIDEOS])?;
    let dir = run.join(VIDEOS);
    let listed = created_entries(run)?.unwrap_or_default();
    // apo's `videos` is a folder: a link, file or special file there is the user's
    let kind = crate::atomic::not_plain(&dir)
        .filter(|k| *k != "a folder")
        .or_else(|| {
            std::fs::symlink_metadata(&dir)
                .is_ok_and(|m| m.is_file())
                .then_some("a file")
        });
    if !listed.contains(VIDEOS) || kind.is_some() {
        bail!(
            "{} exists and was not made by apo{}; apo does not write its videos there: move it away, \
             or give `apo render` another --out",
            dir.display(),
            kind.map_or_else(String::new, |k| format!(" ({k})"))
        );
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}

/// Before apo writes the files `names` into the output folder `dir` (chosen by the user, named
/// by apo: `report.md`, …), checks that none of them exists unless an earlier apo wrote it
/// (listed in `dir/marker`), then lists them there: apo overwrites its own outputs, never a
/// user's file of the same name. Returns how each is to take its place ([`OutputPlaces`]): a
/// name that is there now (apo's earlier output) replaces that very file, any other only
/// nothing — a file that appears there, or takes the place of apo's, while apo works stays.
///
/// # Errors
/// Naming a file apo would overwrite but did not write, or when the marker cannot be written.
pub fn claim_outputs(dir: &Path, marker: &str, names: &[String]) -> anyhow::Result<OutputPlaces> {
    check_outputs(dir, marker, names)?;
    let present = names
        .iter()
        .filter_map(|n| Some((n.clone(), crate::atomic::file_id(&dir.join(n))?)))
        .collect();
    let mut listed = created_entries_in(dir, marker)?.unwrap_or_default();
    listed.extend(names.iter().cloned());
    write_marker_in(dir, marker, &listed)?;
    Ok(OutputPlaces { present })
}

/// How the outputs [`claim_outputs`] claimed take their places.
#[derive(Debug, Clone, Default)]
pub struct OutputPlaces {
    /// The names apo wrote before and finds there, with the files' device and inode: each
    /// replaces that very file only.
    present: std::collections::BTreeMap<String, (u64, u64)>,
}

impl OutputPlaces {
    /// How the output `name` takes its place: over the file apo wrote before
    /// ([`crate::atomic::Place::ReplaceOwn`]), or where nothing is.
    pub fn of(&self, name: &str) -> crate::atomic::Place {
        match self.present.get(name) {
            Some(&id) => crate::atomic::Place::ReplaceOwn { id },
            None => crate::atomic::Place::New,
        }
    }
}

/// The check of [`claim_outputs`] alone (nothing written), for a command to fail before its work.
///
/// # Errors
/// Naming a file apo would overwrite but did not write.
pub fn check_outputs(dir: &Path, marker: &str, names: &[String]) -> anyhow::Result<()> {
    let listed = created_entries_in(dir, marker)?.unwrap_or_default();
    for name in names {
        let path = dir.join(name);
        // apo writes plain files only: a link, folder or special file of a listed name is the
        // user's, put there after apo wrote its file
        if let Some(kind) = crate::atomic::not_plain(&path) {
            bail!(
                "{} is {kind}, not a file apo wrote; apo does not replace it: move it away or choose another --out",
                path.display()
            );
        }
        if !listed.contains(name) && std::fs::symlink_metadata(&path).is_ok() {
            bail!(
                "{} exists and was not written by apo (not listed in {}); apo does not overwrite it: \
                 move it away or choose another --out",
                path.display(),
                dir.join(marker).display()
            );
        }
    }
    Ok(())
}

/// The `progress.csv` of the run in `dir`, or why there is none: a folder that holds a
/// `config.toml` but no run (no marker, no checkpoint: an `apo config` output) is named so,
/// and a run without one is told apart from it. What every reader of a run's records calls
/// first (`summary`, `report`, `plot`, `sweep`).
///
/// # Errors
/// No `progress.csv`, with the cause.
pub fn progress_of(dir: &Path) -> anyhow::Result<PathBuf> {
    let path = dir.join(PROGRESS);
    if std::fs::symlink_metadata(&path).is_ok() {
        return Ok(path);
    }
    match std::fs::metadata(dir) {
        Err(e) => bail!("{}: {e}", dir.display()),
        Ok(m) if !m.is_dir() => bail!(
            "{} is not a run directory: it is not a folder",
            dir.display()
        ),
        Ok(_) => {}
    }
    if std::fs::symlink_metadata(dir.join(CONFIG)).is_err() {
        bail!(
            "{} is not a run directory: it has neither {PROGRESS} nor {CONFIG}",
            dir.display()
        );
    }
    if check_resumable(dir).is_err() {
        bail!(
            "{} holds a config.toml but no run (neither apo's marker nor a checkpoint): train one with \
             `apo train --config {} --out <new folder>`",
            dir.display(),
            dir.join(CONFIG).display()
        );
    }
    match crate::checkpoint::latest_epoch(dir) {
        Ok(Some(epoch)) if epoch > 0 => bail!(
            "{} has no {PROGRESS}, although its checkpoint is at epoch {epoch}: the record was removed",
            dir.display()
        ),
        _ => bail!(
            "{} has no {PROGRESS} yet: the run has not completed an epoch",
            dir.display()
        ),
    }
}

/// Whether `dir` is a run directory (its `config.toml` is a valid run configuration).
pub fn is_run_dir(dir: &Path) -> bool {
    RunConfig::load(&dir.join(CONFIG)).is_ok()
}

/// The configuration of the run in `dir`, as every command that reads a run loads it: a folder
/// without a `config.toml` is "not a run directory"; a run whose `config.toml` apo cannot use
/// is named as such, with the file and the key or line at fault.
///
/// # Errors
/// Naming `dir`, the file and what is wrong in it.
pub fn load_config(dir: &Path) -> anyhow::Result<RunConfig> {
    let path = dir.join(CONFIG);
    if std::fs::symlink_metadata(&path).is_err() {
        match std::fs::metadata(dir) {
            Err(e) => bail!("{} is not a run directory: {e}", dir.display()),
            Ok(m) if !m.is_dir() => bail!(
                "{} is not a run directory: it is not a folder",
                dir.display()
            ),
            Ok(_) => bail!(
                "{} is not a run directory: it has no {CONFIG}",
                dir.display()
            ),
        }
    }
    RunConfig::load(&path)
        .with_context(|| format!("the run in {} has a {CONFIG} apo cannot use", dir.display()))
}

/// Checks that `dir` holds a run that `--resume` may continue: a valid `config.toml` and either
/// apo's marker or (a run from before the marker) a checkpoint. A folder that merely holds a
/// `config.toml` (from `apo config > dir/config.toml`) is not one.
///
/// # Errors
/// Naming `dir` and what is missing.
pub fn check_resumable(dir: &Path) -> anyhow::Result<RunConfig> {
    let config = load_config(dir)?;
    let legacy = dir.join(CHECKPOINTS).join("latest").is_dir()
        || dir.join(CHECKPOINTS).join("previous").is_dir();
    if created_entries(dir)?.is_none() && !legacy {
        bail!(
            "{} is not a run directory of apo: it has a {CONFIG} but neither apo's marker {MARKER} nor a checkpoint; \
             start a run with `apo train --config {} --out <new folder>`",
            dir.display(),
            dir.join(CONFIG).display()
        );
    }
    Ok(config)
}

/// Refuses a run directory where something apo did not make sits where apo writes or
/// removes: apo makes only plain files and folders, never links or special files (pipes,
/// sockets, devices), so any of those is the user's. Checked: apo's files (`config.toml`,
/// `progress.csv`, `episodes.csv`, `train.log` and every other entry its marker lists, such as
/// the TensorBoard files) must be plain files; `checkpoints/` and `videos/` folders; every
/// checkpoint apo names in `checkpoints/` (`latest`, `previous`, `best`, `epoch-<N>`, its
/// temporary folders) a folder of plain files; every video apo names in `videos/` a plain file.
/// Checked before a resume or a `--force` touches anything, so that neither fails half-way and
/// neither replaces nor removes what is the user's.
///
/// # Errors
/// Naming the entries and what to do.
pub fn check_own_places(dir: &Path) -> anyhow::Result<()> {
    let mut wrong = Vec::new();
    let mut files: BTreeSet<String> = [CONFIG, PROGRESS, EPISODES, LOG]
        .into_iter()
        .map(str::to_string)
        .collect();
    files.extend(created_entries(dir)?.unwrap_or_default());
    for name in files.iter().filter(|n| *n != CHECKPOINTS && *n != VIDEOS) {
        if let Some(kind) = crate::atomic::not_plain(&dir.join(name)) {
            wrong.push(format!("{name} is {kind}"));
        }
    }
    for name in [CHECKPOINTS, VIDEOS] {
        match std::fs::symlink_metadata(dir.join(name)) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                let kind = crate::atomic::not_plain(&dir.join(name)).unwrap_or("a file");
                wrong.push(format!("{name} is {kind}"));
            }
            Err(_) => {}
        }
    }
    wrong.extend(crate::checkpoint::foreign_entries(&dir.join(CHECKPOINTS)));
    let videos = dir.join(VIDEOS);
    if std::fs::symlink_metadata(&videos).is_ok_and(|m| m.is_dir()) {
        for name in crate::removal::entry_names(&videos)? {
            let video = crate::atomic::temp_target(&name).unwrap_or(&name);
            if is_video_name(video, usize::MAX) {
                if let Some(kind) = crate::atomic::not_plain(&videos.join(&name)) {
                    wrong.push(format!("{VIDEOS}/{name} is {kind}"));
                }
            }
        }
    }
    if !wrong.is_empty() {
        bail!(
            "{}: {}, where apo writes its own {}; nothing was touched: move {} away",
            dir.display(),
            wrong.join(", "),
            if wrong.len() == 1 { "entry" } else { "entries" },
            if wrong.len() == 1 { "it" } else { "them" }
        );
    }
    Ok(())
}

/// Removes what apo created in the run directory `dir` (the entries of its marker, the
/// checkpoints apo wrote in `checkpoints/`, the videos it wrote in `videos/`, apo's temporary
/// files) and the marker. The lock file stays while it is held (a new process could otherwise
/// lock a new file beside it):
/// with `released`, the lock is no longer held and goes too. With `remove_dir`, `dir` goes
/// as well when nothing else is left. Returns the entries kept because apo did not create
/// them.
///
/// # Errors
/// When a file apo created cannot be removed.
pub fn remove_run_files(
    dir: &Path,
    released: bool,
    remove_dir: bool,
) -> anyhow::Result<Vec<String>> {
    let listed = created_entries(dir)?.unwrap_or_default();
    // the last epoch the run reached: apo wrote no epoch's video or checkpoint after it
    let recorded = crate::progress_csv::read_lenient(&dir.join(PROGRESS), true)
        .map_or(0, |p| p.rows.last().map_or(0, |r| r.epoch));
    let checkpointed = crate::checkpoint::latest_epoch(dir)
        .ok()
        .flatten()
        .unwrap_or(0);
    let last = recorded.max(checkpointed);
    if listed.contains(CHECKPOINTS) {
        crate::checkpoint::remove_checkpoints(&dir.join(CHECKPOINTS), last)?;
    }
    if listed.contains(VIDEOS) {
        remove_videos(&dir.join(VIDEOS), last)?;
    }
    let mut names: Vec<String> = listed
        .iter()
        .filter(|n| released || n.as_str() != LOCK)
        .cloned()
        .collect();
    names.push(MARKER.to_string());
    names.extend(crate::atomic::temps_of(dir, &names));
    let mut left = crate::removal::remove_created(dir, &names, remove_dir)?;
    left.retain(|n| n != LOCK);
    Ok(left)
}

/// Opens apo's own file `path` of a run directory with `options`, never through a symbolic
/// link (a link there would make apo write where the user did not point it): a link is an
/// error naming it.
///
/// # Errors
/// The OS's error; for a link, one that says so.
pub fn open_own(options: &mut OpenOptions, path: &Path) -> anyhow::Result<File> {
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        bail!(
            "{} is a symbolic link; apo writes its own files in a run directory only as plain files \
             (remove the link)",
            path.display()
        );
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
        // a hard link shares the file with another name: apo would write into the user's file
        if let Ok(meta) = std::fs::symlink_metadata(path) {
            if !meta.is_file() {
                bail!(
                    "{} is not a regular file (a pipe, device, socket or folder); apo writes its own \
                     files in a run directory only as plain files (remove it)",
                    path.display()
                );
            }
            if meta.nlink() > 1 {
                bail!(
                    "{} has {} names (hard links); apo writes its own files in place only when no \
                     other name shares them (remove the other link)",
                    path.display(),
                    meta.nlink()
                );
            }
        }
        // closes the gap between the check and the open (a FIFO put there in between is not
        // waited on)
        options.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    Ok(options.open(path)?)
}

/// Removes the temporary files a stopped apo left in the run directory `dir` beside its own
/// files (`.progress.csv.apo-<pid>-<n>.tmp`, …; a second signal exits mid-write): call it
/// holding the run's lock, so that no other apo is writing them.
///
/// # Errors
/// When such a file cannot be removed.
pub fn remove_stale_temps(dir: &Path) -> anyhow::Result<()> {
    let mut names: Vec<String> = created_entries(dir)?
        .unwrap_or_default()
        .into_iter()
        .collect();
    names.push(MARKER.to_string());
    let temps = crate::atomic::temps_of(dir, &names);
    crate::removal::remove_created(dir, &temps, false)?;
    Ok(())
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
        Self::acquire_at(&dir.join(LOCK), &format!("run directory {}", dir.display()))
    }

    /// Locks the file `path` (made when missing), which stands for `what` in the error when
    /// another apo holds it (a sweep's directory, …).
    ///
    /// # Errors
    /// Another apo holds the lock (naming its process), or the file cannot be opened or written.
    pub fn acquire_at(path: &Path, what: &str) -> anyhow::Result<Self> {
        let path = path.to_path_buf();
        let mut file = open_own(
            OpenOptions::new()
                .create(true)
                .truncate(false)
                .read(true)
                .write(true),
            &path,
        )
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
                    "{what} is in use by another apo process{who}; wait for it to end or stop it first"
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

/// What holds the lock of the run directory `dir` when an apo process holds it (the lock
/// file's text, `pid <n>`, or an empty one); `None` when no process holds it, or it has no
/// lock file. The probe takes a shared lock for an instant and never creates the file nor
/// follows a link.
pub fn lock_holder(dir: &Path) -> Option<String> {
    let path = dir.join(LOCK);
    if !std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
        return None;
    }
    let mut file = open_own(OpenOptions::new().read(true), &path).ok()?;
    match file.try_lock_shared() {
        Ok(()) => {
            let _ = file.unlock();
            None
        }
        Err(TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = (&mut file).take(64).read_to_string(&mut holder);
            Some(crate::input::excerpt(holder.trim()))
        }
        Err(TryLockError::Error(_)) => None,
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
    /// `force` removes what apo created in an existing *run directory* (one with apo's marker;
    /// anything else in it is kept and listed on stderr). Refuses a non-empty directory
    /// without `force`, and with it a folder without the marker or one where a file of an apo
    /// name (`config.toml`, `progress.csv`, `train.log`, `checkpoints`) was not made by apo;
    /// nothing is touched then.
    pub fn prepare(dir: &Path, force: bool) -> anyhow::Result<Self> {
        if force && crate::removal::is_link(dir) {
            let target = std::fs::read_link(dir).unwrap_or_default();
            bail!(
                "--force {}: it is a symbolic link (to {}), and --force replaces only a run directory itself — \
                 apo neither removes through a link nor writes a new run over files it cannot remove; pass the \
                 directory it points to",
                dir.display(),
                target.display()
            );
        }
        if std::fs::symlink_metadata(dir).is_err() {
            crate::input::check_name_lengths(dir, "--out")?;
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
            claim_new(dir, &[LOCK])?;
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
        // an apo stopped before it had written anything but its temporary files left only those;
        // they are apo's to remove only in a folder with apo's marker (a refused folder is
        // never touched)
        if created_entries(dir)?.is_some() {
            crate::atomic::remove_dead_temps(dir, None);
        }
        let entries = crate::removal::entry_names(dir)?;
        // a folder another apo is making a run in at this moment holds its marker, the lock file
        // the marker lists and the marker's temporary files of a running apo: the lock decides
        // between the two. Anything else of those names (a lock file without a marker that lists
        // it, one that is not a plain file, a temporary name of a process that is gone) is the
        // user's, and the folder is not empty
        let marked = created_entries(dir)?;
        let ours = |n: &String| {
            if n == MARKER {
                return true;
            }
            if n == LOCK {
                return marked.as_ref().is_some_and(|m| m.contains(LOCK))
                    && std::fs::symlink_metadata(dir.join(LOCK)).is_ok_and(|m| m.is_file());
            }
            crate::atomic::is_temp_of(n, MARKER) && crate::atomic::is_live_temp(dir, n)
        };
        if entries.iter().all(ours) {
            claim_new(dir, &[LOCK])?;
            let lock = RunLock::acquire(dir)?;
            return Ok(Self {
                dir: dir.to_path_buf(),
                created: false,
                lock: Some(lock),
            });
        }
        if !force {
            if created_entries(dir)?.is_none() {
                bail!(
                    "{} already exists and apo did not make it (no marker {MARKER}); choose another --out \
                     (apo never writes into a folder of yours)",
                    dir.display()
                );
            }
            bail!(
                "run directory {} already exists; pass --force to replace it, or --resume {} to continue it",
                dir.display(),
                dir.display()
            );
        }
        let Some(listed) = created_entries(dir)? else {
            bail!(
                "--force replaces only a run directory that apo made (one with its marker {MARKER}), and {} is not one \
                 ({} entries, e.g. `{}`); nothing in it was touched — choose another --out",
                dir.display(),
                entries.len(),
                entries.first().map_or("", String::as_str)
            );
        };
        // what the new run writes must be apo's to replace: --force keeps what is not (a link,
        // a folder of the user's), so the new run would write over it
        let foreign: Vec<&str> = FIXED
            .into_iter()
            .filter(|n| match std::fs::symlink_metadata(dir.join(n)) {
                Err(_) => false,
                // apo makes no links: every link is the user's
                Ok(meta) if meta.file_type().is_symlink() => true,
                // a folder where apo writes a file
                Ok(meta) if meta.is_dir() && *n != CHECKPOINTS => true,
                Ok(_) => !listed.contains(*n),
            })
            .collect();
        if !foreign.is_empty() {
            bail!(
                "--force: {} holds {} that apo did not create (not listed in {MARKER}, a symbolic link, or a folder \
                 where apo writes a file); the new run would overwrite it. Nothing was touched: move it away or \
                 choose another --out",
                dir.display(),
                foreign.join(", ")
            );
        }
        check_own_places(dir)?;
        let lock = RunLock::acquire(dir)?;
        let kept = remove_run_files(dir, false, false)?;
        // what apo made and is still there (the lock; `checkpoints/` holding a user's folder)
        // stays apo's
        let surviving: BTreeSet<String> = listed
            .into_iter()
            .filter(|n| std::fs::symlink_metadata(dir.join(n)).is_ok())
            .collect();
        write_marker(dir, &surviving)?;
        let kept: Vec<String> = kept.into_iter().filter(|n| n != MARKER).collect();
        if !kept.is_empty() {
            crate::warnln!(
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

    /// Undoes [`NewRunDir::prepare`] after a run failed before its first epoch: removes what
    /// apo created, and the directory itself when this run created it and nothing else is in it.
    pub fn discard(mut self) {
        drop(self.lock.take());
        if let Err(e) = remove_run_files(&self.dir, true, self.created) {
            crate::warnln!("warning: cleaning up {}: {e:#}", self.dir.display());
        }
    }
}

/// Whether `name` is a video apo wrote into the `videos/` of a run that reached epoch `last`:
/// `render.gif` (`apo render`'s default), or `epoch-<N>.gif` exactly as apo writes it (no
/// leading zero) for an epoch 1 ≤ N ≤ `last`. Any other name is the user's.
fn is_video_name(name: &str, last: usize) -> bool {
    name == "render.gif"
        || name
            .strip_prefix("epoch-")
            .and_then(|n| n.strip_suffix(".gif"))
            .and_then(|n| n.parse::<usize>().ok().filter(|e| n == e.to_string()))
            .is_some_and(|epoch| (1..=last).contains(&epoch))
}

/// Removes the videos apo wrote into the run's video folder `root` (and their temporary
/// files), then `root` when nothing else is left in it: a user's file there stays, and so does
/// the folder.
///
/// # Errors
/// When a video cannot be removed.
pub fn remove_videos(root: &Path, last: usize) -> anyhow::Result<()> {
    if crate::removal::is_link(root) {
        return Ok(());
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return Ok(());
    };
    let mut names = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let video = crate::atomic::temp_target(&name).unwrap_or(&name);
        if is_video_name(video, last) {
            names.push(name);
        }
    }
    crate::removal::remove_created(root, &names, true)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_videos_apo_names_are_removed() {
        let dir = tempfile::tempdir().expect("tempdir");
        let root = dir.path().join(VIDEOS);
        std::fs::create_dir(&root).expect("videos/");
        for name in [
            "epoch-3.gif",
            "epoch-10.gif",
            "render.gif",
            "mine.gif",
            "epoch-x.gif",
            "epoch-03.gif",
            "epoch-0.gif",
            "epoch-11.gif",
        ] {
            std::fs::write(root.join(name), b"GIF89a").expect("file");
        }
        // a run that reached epoch 10: epoch 11, epoch 0 and a leading zero are not apo's
        remove_videos(&root, 10).expect("removed");
        let mut left: Vec<_> = std::fs::read_dir(&root)
            .expect("kept: it holds files of the user")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                "epoch-0.gif",
                "epoch-03.gif",
                "epoch-11.gif",
                "epoch-x.gif",
                "mine.gif"
            ]
        );
        for name in &left {
            std::fs::remove_file(root.join(name)).expect("remove");
        }
        std::fs::write(root.join("epoch-4.gif"), b"GIF89a").expect("file");
        remove_videos(&root, 4).expect("removed");
        assert!(!root.exists(), "an emptied folder goes");
    }

    #[test]
    fn claims_list_only_entries_that_did_not_exist_and_removal_spares_the_rest() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let dir = tmp.path();
        std::fs::write(dir.join(LOG), "the user's own log").expect("write");
        claim_new(dir, &[LOG, PROGRESS]).expect("claim");
        let listed = created_entries(dir).expect("read").expect("marker");
        assert!(
            listed.contains(PROGRESS) && !listed.contains(LOG),
            "{listed:?}"
        );
        std::fs::write(dir.join(PROGRESS), "epoch\n").expect("write");
        std::fs::create_dir(dir.join("notes")).expect("mkdir");
        let left = remove_run_files(dir, true, true).expect("remove");
        assert_eq!(left, vec!["notes".to_string(), LOG.to_string()]);
        assert!(!dir.join(PROGRESS).exists() && !dir.join(MARKER).exists());
        assert_eq!(
            std::fs::read_to_string(dir.join(LOG)).expect("kept"),
            "the user's own log"
        );
    }

    #[test]
    fn a_marker_cannot_name_a_path_outside_its_directory() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let run = tmp.path().join("run");
        std::fs::create_dir(&run).expect("mkdir");
        std::fs::write(tmp.path().join("precious.txt"), "keep").expect("write");
        std::fs::write(run.join(MARKER), "../precious.txt\n..\n/etc/passwd\n").expect("write");
        remove_run_files(&run, true, false).expect("remove");
        assert!(tmp.path().join("precious.txt").exists());
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
