//! Checkpoints: everything needed to continue a run, verified before it is used.
//!
//! A checkpoint is a directory under `checkpoints/` holding the policy and value networks
//! and both Adam states (Burn's named MessagePack recorder, full precision), `state.json`
//! (epoch, step and time counters, observation-normalizer statistics) and `manifest.json`:
//! the shapes of the networks and the size and CRC-32C of every other file. Loading checks the
//! manifest first — a flipped byte, a truncated file, or a network file copied from another
//! run is an error naming the file — and checks the shapes against the run's config before
//! Burn reads a record. Rollout randomness is reseeded from the run seed at each epoch, so no
//! RNG state has to be saved for a resumed run to reproduce an uninterrupted one.
//!
//! Writing is atomic and durable: the files go to a fresh temporary directory and are synced
//! with it; then `latest` is renamed to `previous`, the temporary directory to `latest`, the
//! parent is synced and `previous` is deleted. A crash at any point leaves `latest` or
//! `previous` complete, and [`load`] falls back to `previous` when `latest` is missing.
//! With `keep_checkpoint_every = N` every N-th epoch's checkpoint is also kept as
//! `epoch-<N>` (see [`Which`]).

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use crate::RunState;
use anyhow::{bail, Context};
use apo_core::{ActionKind, Learner, Multipliers, PolicyFamily, ShapingState};
use burn::backend::Autodiff;
use burn::module::{AutodiffModule, Module};
use burn::optim::Optimizer;
use burn::record::{FullPrecisionSettings, NamedMpkBytesRecorder, NamedMpkFileRecorder, Recorder};
use burn::tensor::backend::Backend;
use serde::{Deserialize, Serialize};

use crate::atomic;
use crate::run_config::RunConfig;

/// The checkpoint format this version writes (format 1 had no manifest; it is still read,
/// with a warning; a format-2 checkpoint without its manifest is refused).
const FORMAT: u32 = 2;

/// The network and optimizer files of a checkpoint (Burn adds `.mpk`).
const RECORDS: [&str; 4] = ["policy", "value", "policy_optim", "value_optim"];
const STATE: &str = "state.json";
const MANIFEST: &str = "manifest.json";

/// `state.json`: the format version and the run's counters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainState {
    /// Checkpoint format version.
    pub format: u32,
    /// Epochs, steps, time, observation-normalizer statistics.
    #[serde(flatten)]
    pub run: RunState,
    /// V-MPO's learned temperature and multiplier with their Adam state (written from the
    /// learner by [`save`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vmpo: Option<Multipliers>,
    /// The number of MPI ranks that trained the run (absent: 1). A run resumes only with the
    /// same number: each rank's rollout seeds and share of the batch depend on it.
    #[serde(default = "one_rank", skip_serializing_if = "is_one_rank")]
    pub ranks: usize,
    /// What the risk shaping carries from epoch to epoch (return capping's cap; absent for the
    /// other algorithms, and before the first cap), written from the learner by [`save`].
    #[serde(default, skip_serializing_if = "ShapingState::is_empty")]
    pub shaping: ShapingState,
    /// The records `episodes.csv` held when the checkpoint was written (absent in checkpoints
    /// of runs that kept no count): resuming refuses a record that has lost some.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episode_records: Option<usize>,
}

fn one_rank() -> usize {
    1
}

fn is_one_rank(ranks: &usize) -> bool {
    *ranks == 1
}

impl TrainState {
    /// The state of `run` in this version's format, trained by one process.
    pub fn new(run: RunState) -> Self {
        Self {
            format: FORMAT,
            run,
            vmpo: None,
            shaping: ShapingState::default(),
            ranks: 1,
            episode_records: None,
        }
    }

    /// The same state, of a run trained by `ranks` MPI ranks.
    pub fn with_ranks(mut self, ranks: usize) -> Self {
        self.ranks = ranks;
        self
    }

    /// The same state, with the number of records of the run's `episodes.csv`.
    pub fn with_episode_records(mut self, records: usize) -> Self {
        self.episode_records = Some(records);
        self
    }
}

/// What a checkpoint was trained with: the shapes of its networks and every config value that
/// can change what the run learns ([`RunConfig::learned_with`]); recorded in each checkpoint
/// and checked on load, so that a run stays bound to the config it was trained with.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shapes {
    /// Observation dimension (the networks' input).
    pub observation_dim: usize,
    /// The policy's action kind and size.
    pub action: ActionKind,
    /// Hidden layer sizes of both networks.
    pub hidden: Vec<usize>,
    /// Whether the observations are normalized (the normalizer is then in `state.json`).
    pub normalize_obs: bool,
    /// The config values the run learned with, by dotted key (empty in checkpoints written
    /// before runs recorded them: those are not checked).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub learned_with: BTreeMap<String, String>,
}

impl Shapes {
    /// The shapes of `config`'s networks on an environment with `observation_dim` and `action`.
    pub fn of(config: &RunConfig, observation_dim: usize, action: ActionKind) -> Self {
        Self {
            observation_dim,
            action,
            hidden: config.train.hidden.clone(),
            normalize_obs: config.train.normalize_obs,
            learned_with: config.learned_with(),
        }
    }

    /// The same shapes without the config values (the networks alone).
    fn networks(&self) -> Self {
        Self {
            learned_with: BTreeMap::new(),
            ..self.clone()
        }
    }
}

/// The keys whose values differ between what a checkpoint was trained with (`trained`) and
/// the run's config now (`now`), each as `key = now (trained with: was)`; a key on one side
/// only shows `(none)` on the other.
fn config_changes(
    trained: &BTreeMap<String, String>,
    now: &BTreeMap<String, String>,
) -> Vec<String> {
    let keys: std::collections::BTreeSet<&String> = trained.keys().chain(now.keys()).collect();
    keys.into_iter()
        .filter(|k| trained.get(*k) != now.get(*k))
        .map(|k| {
            let shown = |v: Option<&String>| v.map_or("(none)".to_string(), Clone::clone);
            format!(
                "{k} = {} (trained with: {})",
                shown(now.get(k)),
                shown(trained.get(k))
            )
        })
        .collect()
}

impl fmt::Display for Shapes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let action = match self.action {
            ActionKind::Continuous { dim } => format!("box({dim})"),
            ActionKind::Discrete { n } => format!("discrete({n})"),
        };
        write!(
            f,
            "observation dim {}, actions {action}, hidden {:?}, normalize_obs {}",
            self.observation_dim, self.hidden, self.normalize_obs
        )
    }
}

/// Size and checksum of one file of a checkpoint.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
struct FileSum {
    bytes: u64,
    crc32c: String,
}

/// `manifest.json`: the shapes and the checksum of every other file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Manifest {
    format: u32,
    shapes: Shapes,
    files: BTreeMap<String, FileSum>,
}

fn file_sum(path: &Path) -> anyhow::Result<FileSum> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(FileSum {
        bytes: bytes.len() as u64,
        crc32c: format!("{:08x}", crc32c::crc32c(&bytes)),
    })
}

type Rec = NamedMpkFileRecorder<FullPrecisionSettings>;

fn recorder() -> Rec {
    NamedMpkFileRecorder::<FullPrecisionSettings>::new()
}

/// The folder of a run directory that holds its checkpoints.
pub const FOLDER: &str = "checkpoints";

/// `checkpoints/` of a run directory.
pub fn dir(run: &Path) -> PathBuf {
    run.join(FOLDER)
}

/// Which checkpoint of a run to read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Which {
    /// The newest (`checkpoints/latest`, or `previous` after a crash during a swap).
    Latest,
    /// The one kept at this epoch (`checkpoints/epoch-<N>`, see `keep_checkpoint_every`).
    Epoch(usize),
    /// The one of the best evaluation so far (`checkpoints/best`, see `eval_every` and
    /// `eval_best`).
    Best,
}

impl std::str::FromStr for Which {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "latest" {
            return Ok(Which::Latest);
        }
        if s == "best" {
            return Ok(Which::Best);
        }
        s.trim_start_matches("epoch-")
            .parse()
            .map(Which::Epoch)
            .map_err(|_| format!("`{s}` is not a checkpoint: use `latest`, `best` (runs with eval_every) or an epoch number kept by keep_checkpoint_every"))
    }
}

fn kept_name(epoch: usize) -> String {
    format!("epoch-{epoch:06}")
}

/// Epochs of the checkpoints kept in `run` (`checkpoints/epoch-<N>`), ascending.
pub fn kept_epochs(run: &Path) -> Vec<usize> {
    let mut epochs: Vec<usize> = std::fs::read_dir(dir(run))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.strip_prefix("epoch-")?.parse().ok())
        .collect();
    epochs.sort_unstable();
    epochs
}

/// Writes a checkpoint of `learner` and `state` into `run`'s `checkpoints/latest`,
/// atomically and durably; with `keep`, also keeps a copy as `checkpoints/epoch-<N>`.
pub fn save<B: Backend, F: PolicyFamily>(
    run: &Path,
    learner: &Learner<B, F>,
    state: &TrainState,
    shapes: &Shapes,
    keep: bool,
) -> anyhow::Result<()>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    let root = own_root(run)?;
    clear_unfinished(&root)?;
    let tmp = root.join(format!(".tmp-{}", state.run.epoch));
    write_into(&tmp, learner, state, shapes)
        .with_context(|| format!("writing the checkpoint into {}", tmp.display()))?;

    swap_in(&root, &tmp, "latest", "previous")?;
    if keep {
        let kept = root.join(kept_name(state.run.epoch));
        let tmp = root.join(format!(".tmp-keep-{}", state.run.epoch));
        write_into(&tmp, learner, state, shapes)
            .with_context(|| format!("writing the checkpoint into {}", tmp.display()))?;
        swapped(&tmp, || {
            clear(&kept)?;
            rename(&tmp, &kept)?;
            Ok(atomic::sync_dir(&root)?)
        })?;
    }
    Ok(())
}

/// Renames `from` to `to`, naming both on an error.
fn rename(from: &Path, to: &Path) -> anyhow::Result<()> {
    std::fs::rename(from, to)
        .with_context(|| format!("cannot move {} to {}", from.display(), to.display()))
}

/// Puts the written checkpoint `tmp` in place as `root/name`: the one there moves aside to
/// `root/aside`, `tmp` takes its name, the directory is synced and the old one removed — a
/// crash leaves the old or the new one complete. On a failure what is left of `tmp` goes.
fn swap_in(root: &Path, tmp: &Path, name: &str, aside: &str) -> anyhow::Result<()> {
    let (target, aside) = (root.join(name), root.join(aside));
    swapped(tmp, || {
        clear(&aside)?;
        if target.exists() {
            rename(&target, &aside)?;
        }
        rename(tmp, &target)?;
        atomic::sync_dir(root)?;
        clear(&aside)
    })
}

/// Runs `swap` (the renames that put the written checkpoint `tmp` in place); when it fails,
/// removes what is left of `tmp` (the checkpoint before it stays, as `latest` or `previous`).
fn swapped(tmp: &Path, swap: impl FnOnce() -> anyhow::Result<()>) -> anyhow::Result<()> {
    let done = swap();
    if done.is_err() {
        let _ = clear(tmp);
    }
    done
}

/// Writes a checkpoint of `learner` and `state` into `run`'s `checkpoints/best` (the best
/// evaluation so far), replacing the one there atomically: a crash leaves the old or the new
/// one complete (or, between the two renames, the old one as `checkpoints/.old-best`).
pub fn save_best<B: Backend, F: PolicyFamily>(
    run: &Path,
    learner: &Learner<B, F>,
    state: &TrainState,
    shapes: &Shapes,
) -> anyhow::Result<()>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    let root = own_root(run)?;
    let tmp = root.join(".tmp-best");
    clear(&tmp)?;
    write_into(&tmp, learner, state, shapes)
        .with_context(|| format!("writing the checkpoint into {}", tmp.display()))?;
    swap_in(&root, &tmp, BEST, ".old-best")
}

/// Removes the unfinished checkpoints a stopped process left in `root` (`.tmp-<N>`,
/// `.tmp-keep-<N>`, `.tmp-best`: never read, and the run's lock says no other apo writes
/// them now).
fn clear_unfinished(root: &Path) -> anyhow::Result<()> {
    if crate::removal::is_link(root) {
        return Ok(());
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(".tmp-") && is_checkpoint_name(&name) {
            clear(&entry.path())?;
        }
    }
    Ok(())
}

/// `run`'s `checkpoints/`, created if needed; never a symbolic link (apo would otherwise write
/// and rotate checkpoints in a folder the user did not name).
///
/// # Errors
/// A link, or a folder that cannot be created.
fn own_root(run: &Path) -> anyhow::Result<PathBuf> {
    let root = dir(run);
    if crate::removal::is_link(&root) {
        bail!(
            "{} is a symbolic link; apo writes checkpoints only in a folder of its own (remove the link)",
            root.display()
        );
    }
    std::fs::create_dir_all(&root).with_context(|| format!("cannot create {}", root.display()))?;
    Ok(root)
}

/// The folder of the best evaluation's checkpoint in `checkpoints/`.
const BEST: &str = "best";

/// The files of the checkpoint folder `dir` (with the temporary files apo made for them): the
/// only files apo removes from one.
fn checkpoint_files(dir: &Path) -> Vec<String> {
    let mut files: Vec<String> = RECORDS.iter().map(|r| format!("{r}.mpk")).collect();
    files.extend([STATE.to_string(), MANIFEST.to_string()]);
    files.extend(atomic::temps_of(dir, &files));
    files
}

/// Whether `name` is a checkpoint folder apo names in `checkpoints/`: `latest`, `previous`,
/// `best`, `epoch-<N>`, or a temporary `.tmp-<N>` / `.tmp-keep-<N>` / `.tmp-best` / `.old-best`.
fn is_checkpoint_name(name: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    matches!(
        name,
        "latest" | "previous" | BEST | ".tmp-best" | ".old-best"
    ) || name.strip_prefix("epoch-").is_some_and(digits)
        || name.strip_prefix(".tmp-keep-").is_some_and(digits)
        || name.strip_prefix(".tmp-").is_some_and(digits)
}

/// What in the checkpoint folder `root` is not apo's although it has a name apo gives (see
/// `run_dir::check_own_places`): a checkpoint name that is not a folder, or an entry of a
/// checkpoint folder that is not a plain file; each as `checkpoints/<name>[/<entry>] is <kind>`.
pub(crate) fn foreign_entries(root: &Path) -> Vec<String> {
    let mut wrong = Vec::new();
    if !std::fs::symlink_metadata(root).is_ok_and(|m| m.is_dir()) {
        return wrong;
    }
    let Ok(names) = crate::removal::entry_names(root) else {
        return wrong;
    };
    for name in names.into_iter().filter(|n| is_checkpoint_name(n)) {
        let path = root.join(&name);
        match atomic::not_plain(&path) {
            Some("a folder") => {
                for entry in crate::removal::entry_names(&path).unwrap_or_default() {
                    if let Some(kind) = atomic::not_plain(&path.join(&entry)) {
                        wrong.push(format!("{FOLDER}/{name}/{entry} is {kind}"));
                    }
                }
            }
            Some(kind) => wrong.push(format!("{FOLDER}/{name} is {kind}")),
            None => wrong.push(format!("{FOLDER}/{name} is a file")),
        }
    }
    wrong
}

/// Empties the checkpoint folder `path` of a checkpoint's files and removes it. Files apo did
/// not write there are never removed: the folder is then moved aside (`<name>.kept-<N>`, with
/// a warning) so that its name is free for the new checkpoint.
fn clear(path: &Path) -> anyhow::Result<()> {
    if std::fs::symlink_metadata(path).is_err() {
        return Ok(());
    }
    let left = crate::removal::remove_created(path, &checkpoint_files(path), true)?;
    if left.is_empty() {
        return Ok(());
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let aside = (1..)
        .map(|n| atomic::parent(path).join(format!("{name}.kept-{n}")))
        .find(|p| std::fs::symlink_metadata(p).is_err())
        .unwrap_or_else(|| path.with_extension("kept"));
    std::fs::rename(path, &aside)
        .with_context(|| format!("cannot move {} aside", path.display()))?;
    tracing::warn!(
        folder = %path.display(),
        moved_to = %aside.display(),
        files = ?left,
        "a checkpoint folder held files apo did not write; they were kept"
    );
    crate::warnln!(
        "warning: {} held files apo did not write ({}); kept them in {}",
        path.display(),
        left.join(", "),
        aside.display()
    );
    Ok(())
}

/// Removes every checkpoint apo wrote in the folder `root` (a run's `checkpoints/`, of a run
/// that reached epoch `last`) and `root` itself when nothing else is in it; anything else is
/// kept — a kept `epoch-<N>` only as apo names it (`epoch-000007`) and for 1 ≤ N ≤ `last`.
///
/// # Errors
/// When a checkpoint file cannot be removed.
pub fn remove_checkpoints(root: &Path, last: usize) -> anyhow::Result<()> {
    if crate::removal::is_link(root) {
        return Ok(());
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let kept_by_apo = name
            .strip_prefix("epoch-")
            .and_then(|n| n.parse::<usize>().ok())
            .is_some_and(|epoch| (1..=last).contains(&epoch) && kept_name(epoch) == name);
        let ours = if name.starts_with("epoch-") {
            kept_by_apo
        } else {
            is_checkpoint_name(&name)
        };
        if ours && entry.file_type().is_ok_and(|t| t.is_dir()) {
            let files = checkpoint_files(&entry.path());
            crate::removal::remove_created(&entry.path(), &files, true)?;
        }
    }
    crate::removal::remove_created(root, &[], true)?;
    Ok(())
}

/// `record` in the format of the checkpoint's `.mpk` files (named MessagePack, full
/// precision), in memory.
fn encode<BK: Backend, R: burn::record::Record<BK>>(record: R) -> anyhow::Result<Vec<u8>> {
    Recorder::<BK>::record(
        &NamedMpkBytesRecorder::<FullPrecisionSettings>::new(),
        record,
        (),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))
}

/// Creates `path` (in a fresh folder) with `bytes`, synced; errors are the OS's.
fn write_synced(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut file = std::fs::File::create(path)?;
    file.write_all(bytes)?;
    file.sync_all()
}

/// Writes and syncs every file of a checkpoint into the fresh directory `tmp`; on an error
/// (a full disk), what was written of it is removed.
fn write_into<B: Backend, F: PolicyFamily>(
    tmp: &Path,
    learner: &Learner<B, F>,
    state: &TrainState,
    shapes: &Shapes,
) -> anyhow::Result<()>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    let written = write_files(tmp, learner, state, shapes);
    if written.is_err() {
        let _ = clear(tmp);
    }
    written
}

/// [`write_into`]'s work.
fn write_files<B: Backend, F: PolicyFamily>(
    tmp: &Path,
    learner: &Learner<B, F>,
    state: &TrainState,
    shapes: &Shapes,
) -> anyhow::Result<()>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    clear(tmp)?;
    std::fs::create_dir_all(tmp)?;
    let (policy, value) = learner.networks();
    let (policy_optim, value_optim) = learner.optimizers();
    // each record is encoded in memory and written by us, so that a failed write names the
    // OS's error (`No space left on device`), which Burn's file recorder reports as an
    // encoding error
    type Ad<B> = burn::backend::Autodiff<B>;
    let records: [(&str, anyhow::Result<Vec<u8>>); 4] = [
        ("policy", encode::<Ad<B>, _>(policy.clone().into_record())),
        ("value", encode::<Ad<B>, _>(value.clone().into_record())),
        ("policy_optim", encode::<Ad<B>, _>(policy_optim.to_record())),
        ("value_optim", encode::<Ad<B>, _>(value_optim.to_record())),
    ];
    for (record, encoded) in records {
        let path = tmp.join(format!("{record}.mpk"));
        let encoded = encoded.with_context(|| format!("encoding {record}"))?;
        write_synced(&path, &encoded)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    atomic::write(
        &tmp.join(STATE),
        serde_json::to_string_pretty(&TrainState {
            format: FORMAT,
            vmpo: learner.multipliers().copied(),
            shaping: *learner.shaping_state(),
            ..state.clone()
        })?
        .as_bytes(),
    )?;
    let mut files = BTreeMap::new();
    for name in RECORDS
        .iter()
        .map(|r| format!("{r}.mpk"))
        .chain([STATE.to_string()])
    {
        let path = tmp.join(&name);
        atomic::sync_file(&path)?;
        files.insert(name, file_sum(&path)?);
    }
    let manifest = Manifest {
        format: FORMAT,
        shapes: shapes.clone(),
        files,
    };
    atomic::write(
        &tmp.join(MANIFEST),
        serde_json::to_string_pretty(&manifest)?.as_bytes(),
    )?;
    Ok(())
}

/// The directory of checkpoint `which` of `run`, if there is one.
pub fn locate(run: &Path, which: &Which) -> anyhow::Result<Option<PathBuf>> {
    let root = dir(run);
    match which {
        Which::Latest => Ok([root.join("latest"), root.join("previous")]
            .into_iter()
            .find(|d| d.is_dir())),
        Which::Best => {
            let found = [root.join(BEST), root.join(".old-best")]
                .into_iter()
                .find(|d| d.is_dir());
            if found.is_none() {
                bail!(
                    "{} has no best checkpoint: it is written by runs with eval_every > 0 once an evaluation has finished episodes",
                    run.display()
                );
            }
            Ok(found)
        }
        Which::Epoch(epoch) => {
            let path = root.join(kept_name(*epoch));
            if path.is_dir() {
                return Ok(Some(path));
            }
            let kept = kept_epochs(run);
            bail!(
                "{} has no checkpoint of epoch {epoch} (kept: {})",
                run.display(),
                if kept.is_empty() {
                    "none; set keep_checkpoint_every to keep some".to_string()
                } else {
                    format!("{kept:?}")
                }
            )
        }
    }
}

/// The epoch of `run`'s latest checkpoint (`None` without one), read from its `state.json`
/// (the networks are not loaded).
///
/// # Errors
/// A checkpoint whose state cannot be read.
pub fn latest_epoch(run: &Path) -> anyhow::Result<Option<usize>> {
    let Some(from) = locate(run, &Which::Latest)? else {
        return Ok(None);
    };
    let path = from.join(STATE);
    let text = crate::input::read_text(&path, "checkpoint state", crate::input::SMALL_FILE * 64)?;
    let state: TrainState = serde_json::from_str(&text)
        .with_context(|| format!("{} is corrupt or not a checkpoint state", path.display()))?;
    Ok(Some(state.run.epoch))
}

/// Loads checkpoint `from` (a directory from [`locate`]) into `learner` after checking its
/// files against their manifest and its shapes against `shapes`; returns its counters.
pub fn load<B: Backend, F: PolicyFamily>(
    from: &Path,
    learner: &mut Learner<B, F>,
    shapes: &Shapes,
    device: &B::Device,
) -> anyhow::Result<TrainState>
where
    F::Policy<Autodiff<B>>: AutodiffModule<Autodiff<B>>,
{
    let state_path = from.join(STATE);
    let text = crate::input::read_text(
        &state_path,
        "checkpoint state",
        crate::input::SMALL_FILE * 64,
    )?;
    let manifest_path = from.join(MANIFEST);
    let has_manifest = std::fs::symlink_metadata(&manifest_path).is_ok();
    if has_manifest {
        verify(from, shapes)?;
    }
    let state: TrainState = serde_json::from_str(&text).with_context(|| {
        format!(
            "{} is corrupt or not a checkpoint state",
            state_path.display()
        )
    })?;
    match state.format {
        FORMAT if has_manifest => {}
        FORMAT => bail!(
            "{} is missing: a format-{FORMAT} checkpoint is verified against it, and without it a corrupt file \
             would go unnoticed; the checkpoint in {} cannot be used",
            manifest_path.display(),
            from.display()
        ),
        1 => {
            tracing::warn!(checkpoint = %from.display(), "format-1 checkpoint without checksums; loading it unverified")
        }
        other => bail!(
            "{} has checkpoint format {other}; this version reads 1 and {FORMAT}",
            state_path.display()
        ),
    }
    match (&state.run.normalizer, shapes.normalize_obs) {
        (Some(n), true) if n.dim() == shapes.observation_dim => {}
        (Some(n), true) => bail!(
            "{}: the observation normalizer has dimension {}, the run's environment {}",
            state_path.display(),
            n.dim(),
            shapes.observation_dim
        ),
        (None, false) => {}
        (Some(_), false) | (None, true) => bail!(
            "{}: the checkpoint {} an observation normalizer but config.toml says normalize_obs = {}",
            state_path.display(),
            if state.run.normalizer.is_some() { "has" } else { "has no" },
            shapes.normalize_obs
        ),
    }
    // Burn reads the records whole: regular files only (a format-1 checkpoint has no
    // manifest whose sizes were checked)
    for name in RECORDS {
        crate::input::check_file(
            &from.join(format!("{name}.mpk")),
            "checkpoint file",
            u64::MAX,
        )?;
    }
    let rec = recorder();
    let (policy, value) = learner.networks();
    let (policy_optim, value_optim) = learner.optimizers();
    let (policy, value, policy_optim, value_optim) = (
        policy.clone(),
        value.clone(),
        policy_optim.clone(),
        value_optim.clone(),
    );
    let loaded = no_panic(|| -> anyhow::Result<_> {
        let file = |name: &str| from.join(name);
        let corrupt = |name: &str| {
            format!(
                "{} is corrupt or from an incompatible run",
                file(&format!("{name}.mpk")).display()
            )
        };
        let policy = policy
            .load_file(file("policy"), &rec, device)
            .with_context(|| corrupt("policy"))?;
        let value = value
            .load_file(file("value"), &rec, device)
            .with_context(|| corrupt("value"))?;
        let policy_optim = policy_optim.load_record(
            rec.load(file("policy_optim"), device)
                .with_context(|| corrupt("policy_optim"))?,
        );
        let value_optim = value_optim.load_record(
            rec.load(file("value_optim"), device)
                .with_context(|| corrupt("value_optim"))?,
        );
        Ok((policy, value, policy_optim, value_optim))
    })
    .with_context(|| {
        format!(
            "the checkpoint in {} is corrupt or from an incompatible run",
            from.display()
        )
    })??;
    let (policy, value, policy_optim, value_optim) = loaded;
    // A record of other sizes loads silently in some Burn versions: check the sizes too.
    let expected = learner.family().init::<Autodiff<B>>(device).num_params();
    if policy.num_params() != expected {
        bail!(
            "{} holds {} policy parameters, the run's config needs {expected}",
            from.join("policy.mpk").display(),
            policy.num_params()
        );
    }
    match (state.vmpo, learner.multipliers().is_some()) {
        (Some(m), true) => learner.restore_multipliers(m),
        (None, false) => {}
        (Some(_), false) => bail!(
            "{} holds V-MPO's multipliers, but the run's algorithm is not V-MPO",
            state_path.display()
        ),
        (None, true) => bail!(
            "{} has no V-MPO multipliers (eta, alpha); the checkpoint is not of a V-MPO run",
            state_path.display()
        ),
    }
    if !state.shaping.is_empty() && learner.config().settings().shaping().is_none() {
        bail!(
            "{} holds a risk shaping's state (return capping's cap), but the run's algorithm shapes nothing",
            state_path.display()
        );
    }
    learner.restore_shaping_state(state.shaping);
    learner.restore(policy, value, policy_optim, value_optim);
    for (what, params) in [
        ("policy", learner.policy_params()),
        ("value", learner.value_params()),
    ] {
        if let Some(i) = params.iter().position(|p| !p.is_finite()) {
            bail!(
                "{} holds a non-finite {what} parameter (index {i}: {}); the checkpoint in {} cannot be used",
                from.join(format!("{what}.mpk")).display(),
                params[i],
                from.display()
            );
        }
    }
    Ok(state)
}

/// Checks every file of checkpoint `from` against its manifest, and the shapes.
fn verify(from: &Path, shapes: &Shapes) -> anyhow::Result<()> {
    let path = from.join(MANIFEST);
    let text = crate::input::read_text(&path, "checkpoint manifest", crate::input::SMALL_FILE)?;
    let manifest: Manifest = serde_json::from_str(&text)
        .with_context(|| format!("{} is corrupt (not a checkpoint manifest)", path.display()))?;
    if manifest.format != FORMAT {
        bail!(
            "{} is of manifest format {}; this version reads format {FORMAT}",
            path.display(),
            manifest.format
        );
    }
    for name in RECORDS
        .iter()
        .map(|r| format!("{r}.mpk"))
        .chain([STATE.to_string()])
    {
        let file = from.join(&name);
        let Some(expected) = manifest.files.get(&name) else {
            bail!(
                "{} does not list {name}; the checkpoint is corrupt",
                path.display()
            );
        };
        if std::fs::symlink_metadata(&file).is_err() {
            bail!("{} is missing from the checkpoint", file.display());
        }
        // a regular file of the listed size before it is read (bounded, and never a FIFO)
        let size = crate::input::check_file(&file, "checkpoint file", u64::MAX)?;
        let found = if size == expected.bytes {
            file_sum(&file)?
        } else {
            FileSum {
                bytes: size,
                crc32c: "(not read)".to_string(),
            }
        };
        if &found != expected {
            bail!(
                "{} is corrupt: {} bytes with CRC-32C {}, the checkpoint's manifest says {} bytes with CRC-32C {}",
                file.display(),
                found.bytes,
                found.crc32c,
                expected.bytes,
                expected.crc32c
            );
        }
    }
    // an edited config.toml is named by its keys before the networks it changed are compared
    check_learned_with(from, &manifest.shapes, shapes)?;
    if manifest.shapes.networks() != shapes.networks() {
        bail!(
            "the networks in {} ({}) do not fit this run ({}): the checkpoint is from another run or config.toml was edited",
            from.display(),
            manifest.shapes,
            shapes
        );
    }
    Ok(())
}

/// Refuses, naming the keys, a run whose config now (`now`) differs from what the checkpoint
/// in `from` was trained with (`trained`, from its manifest); a checkpoint written before runs
/// recorded their config is not checked (a warning says so).
fn check_learned_with(from: &Path, trained: &Shapes, now: &Shapes) -> anyhow::Result<()> {
    if trained.learned_with.is_empty() {
        tracing::warn!(checkpoint = %from.display(), "checkpoint written before runs recorded their config: config.toml is not checked against it");
        return Ok(());
    }
    let changes = config_changes(&trained.learned_with, &now.learned_with);
    if !changes.is_empty() {
        let run = from
            .parent()
            .and_then(Path::parent)
            .unwrap_or(from)
            .display();
        bail!(
            "{run}/config.toml differs from what the checkpoint in {} was trained with: {}. A run stays bound to the \
             config it learned with (only {} may change); to train the edited config, start a new run from it: \
             apo train --config {run}/config.toml --out <new folder>",
            from.display(),
            changes.join("; "),
            crate::run_config::RESUMABLE_KEYS.join(", ")
        );
    }
    Ok(())
}

/// Checks that `config` (the run's `config.toml`) gives every value its latest checkpoint was
/// trained with, reading only the checkpoint's manifest (for readers of results, which load no
/// network); a run without a checkpoint, or whose checkpoint predates the record, passes.
///
/// # Errors
/// A manifest that cannot be read, or the keys whose values differ.
pub fn check_bound(run: &Path, config: &RunConfig) -> anyhow::Result<()> {
    let Some(from) = locate(run, &Which::Latest)? else {
        return Ok(());
    };
    let path = from.join(MANIFEST);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(());
    }
    let text = crate::input::read_text(&path, "checkpoint manifest", crate::input::SMALL_FILE)?;
    let manifest: Manifest = serde_json::from_str(&text)
        .with_context(|| format!("{} is corrupt (not a checkpoint manifest)", path.display()))?;
    let now = Shapes {
        learned_with: config.learned_with(),
        ..manifest.shapes.clone()
    };
    check_learned_with(&from, &manifest.shapes, &now)
}

/// Runs `f`, turning a panic inside it (a malformed record deep in Burn) into an error.
fn no_panic<T>(f: impl FnOnce() -> T) -> anyhow::Result<T> {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    std::panic::set_hook(hook);
    result.map_err(|payload| {
        let message = payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown panic".to_string());
        anyhow::anyhow!("reading it failed: {message}")
    })
}

/// The epoch of a run's first checkpoint: `checkpoint_every`, or the last epoch when that
/// comes first. A run whose records stop at or before it and that has no checkpoint was
/// stopped before writing one, and starts again from epoch 0.
pub(crate) fn first_due(config: &crate::TrainConfig) -> usize {
    config.checkpoint_every.min(config.epochs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_disk_is_named_by_the_os_error() {
        // /dev/full answers every write with ENOSPC, as a full disk does
        let err = write_synced(Path::new("/dev/full"), &[0u8; 4096])
            .map_err(anyhow::Error::from)
            .context("cannot write checkpoints/.tmp-1/policy.mpk")
            .expect_err("a full device");
        let message = format!("{err:#}");
        assert!(
            message.contains("No space left on device") && message.contains("policy.mpk"),
            "{message}"
        );
    }
}
