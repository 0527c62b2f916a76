//! `episodes.csv`: one [`EpisodeRecord`] per episode that ended, training's and evaluation's,
//! as Stable-Baselines3's `Monitor` keeps one: every return statistic of a run can be
//! recomputed from it without running the run again.
//!
//! The same rules as `progress.csv`: the whole file is rewritten atomically after each epoch
//! (a crash leaves the old or the new file, never a part); training reads it whole or not at
//! all ([`EpisodeLog::resume`]) and keeps the records of the epochs its checkpoint completed;
//! the readers of finished runs ([`read_lenient`]) leave out and count what does not parse.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::ProgressRow;
pub use crate::{EpisodeRecord, Phase};
use anyhow::Context;

/// Every column of apo's episode file, in its order (the one header it has written).
pub const COLUMNS: [&str; 9] = [
    "epoch", "phase", "env", "seed", "nth", "return", "length", "unstable", "success",
];

/// The file's header, checked as every reader checks it ([`crate::input::check_header`]),
/// and a reader of its records.
fn open(path: &Path) -> anyhow::Result<(csv::StringRecord, crate::input::CsvReader)> {
    const WHAT: &str = "episode file";
    let (headers, reader) = crate::input::open_csv(path, WHAT)?;
    crate::input::check_header(path, WHAT, &headers, &[COLUMNS.to_vec()])?;
    Ok((headers, reader))
}

/// Reads an `episodes.csv` whole, as a resumed run continues it: the records of
/// [`read_lenient`], and an error where it would leave one out (one that does not parse,
/// repeats an earlier record or holds a non-finite return).
///
/// # Errors
/// A file that cannot be read, a header the readers refuse, or such a record, naming the file
/// and the line.
pub fn read(path: &Path) -> anyhow::Result<Vec<EpisodeRecord>> {
    let episodes = read_lenient(path)?;
    if let Some(first) = episodes.left_out.first() {
        anyhow::bail!("{}: {first}", path.display());
    }
    Ok(episodes.records)
}

/// An `episodes.csv` read for reporting: the records kept, and one line per record left out.
#[derive(Debug, Clone, Default)]
pub struct Episodes {
    /// The records that parse, with a finite return, in the file's order.
    pub records: Vec<EpisodeRecord>,
    /// `line <n>: <reason>` for each record left out.
    pub left_out: Vec<String>,
}

/// Reads an `episodes.csv` for reporting: a record that does not parse, holds a non-finite
/// return or repeats an earlier one (the same epoch, phase, environment, seed and episode
/// number: counted once) is left out and named in [`Episodes::left_out`].
///
/// # Errors
/// A file that cannot be read, or one of which no record parses (not an episode file).
pub fn read_lenient(path: &Path) -> anyhow::Result<Episodes> {
    let (headers, mut reader) = open(path)?;
    let mut episodes = Episodes::default();
    let mut first_error = None;
    // each record's (epoch, phase, environment, seed, episode number), and its line: an
    // evaluation's episodes differ by their seeds only
    let mut seen = BTreeMap::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        match crate::input::csv_record::<EpisodeRecord>(record, &headers) {
            Ok(r) if !r.ret.is_finite() => episodes
                .left_out
                .push(format!("line {line}: return = {}", r.ret)),
            Ok(r) => match seen.insert((r.epoch, r.phase, r.env, r.seed, r.nth), line) {
                None => episodes.records.push(r),
                Some(first) => episodes.left_out.push(format!(
                    "line {line}: repeats the record of line {first} (epoch {}, {:?}, env {}, seed {}, episode {})",
                    r.epoch, r.phase, r.env, r.seed, r.nth
                )),
            },
            Err(why) => {
                first_error.get_or_insert_with(|| format!("line {line}: {why}"));
                episodes.left_out.push(format!("line {line}: {why}"));
            }
        }
    }
    if episodes.records.is_empty() {
        if let Some(e) = first_error {
            anyhow::bail!(
                "{}: none of its {} record(s) can be read; the first: {e}",
                path.display(),
                episodes.left_out.len()
            );
        }
    }
    Ok(episodes)
}

/// The episode log of a run being trained: the records so far, written whole after each epoch.
#[derive(Debug)]
pub struct EpisodeLog {
    path: PathBuf,
    /// The file's bytes: the header and every record so far.
    bytes: Vec<u8>,
    header: bool,
    /// The records so far.
    records: usize,
}

impl EpisodeLog {
    /// A new, empty log at `path` (nothing is written until [`EpisodeLog::append`]).
    pub fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            bytes: Vec::new(),
            header: false,
            records: 0,
        }
    }

    /// The records so far.
    pub fn records(&self) -> usize {
        self.records
    }

    /// The log of a run resumed at the end of epoch `epoch`: the records of `path` up to that
    /// epoch (those after it are played again, the same); an empty log when the file is
    /// missing (a run started before runs kept one).
    ///
    /// # Errors
    /// A file that exists but cannot be read whole (a resumed run continues the record).
    pub fn resume(path: &Path, epoch: usize) -> anyhow::Result<Self> {
        let mut log = Self::new(path);
        if std::fs::symlink_metadata(path).is_err() {
            return Ok(log);
        }
        let kept: Vec<EpisodeRecord> = read(path)
            .context("the run's episode record cannot be continued; restore it, or move it away to start a new one")?
            .into_iter()
            .filter(|r| r.epoch <= epoch)
            .collect();
        log.encode(&kept)?;
        Ok(log)
    }

    fn encode(&mut self, records: &[EpisodeRecord]) -> anyhow::Result<()> {
        let mut writer = csv::WriterBuilder::new()
            .has_headers(!self.header)
            .from_writer(std::mem::take(&mut self.bytes));
        for record in records {
            writer.serialize(record)?;
        }
        self.header |= !records.is_empty();
        self.records += records.len();
        self.bytes = writer
            .into_inner()
            .map_err(|e| anyhow::anyhow!("csv: {e}"))?;
        Ok(())
    }

    /// Adds `records` and rewrites the file atomically (nothing is written while the log is
    /// empty).
    ///
    /// # Errors
    /// When the file cannot be written, naming it.
    pub fn append(&mut self, records: &[EpisodeRecord]) -> anyhow::Result<()> {
        self.encode(records)?;
        if self.bytes.is_empty() {
            return Ok(());
        }
        crate::atomic::write(&self.path, &self.bytes)
            .with_context(|| format!("cannot write {}", self.path.display()))
    }
}

/// Recomputes, from the run's `episodes.csv` in `dir` (when it has one), the return columns of
/// every row whose epoch it covers — training's and evaluation's, every episode counted, with
/// probability factor `k` — so that a report states what the episodes say whatever rule wrote
/// `progress.csv`. Returns how many rows the episodes covered (0 without the file).
///
/// # Errors
/// An `episodes.csv` that cannot be read, or holds no record that parses.
pub fn recompute_rows(rows: &mut [ProgressRow], dir: &Path, k: f64) -> anyhow::Result<usize> {
    let path = dir.join(crate::run_dir::EPISODES);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(0);
    }
    let episodes = read_lenient(&path)?;
    crate::progress_csv::warn(&path, "record(s) left out", &episodes.left_out);
    let mut by_epoch: BTreeMap<(usize, Phase), Vec<crate::Episode>> = BTreeMap::new();
    for r in &episodes.records {
        by_epoch
            .entry((r.epoch, r.phase))
            .or_default()
            .push(r.episode());
    }
    let mut covered = 0;
    for row in rows.iter_mut() {
        let train = by_epoch.get(&(row.epoch, Phase::Train));
        if let Some(train) = train {
            covered += 1;
            let unstable = train.iter().filter(|e| e.unstable).count();
            row.set_training(
                crate::episode_stats(train, k).as_ref(),
                crate::rollout::success_rate(train),
                unstable,
            );
        }
        if let Some(eval) = by_epoch.get(&(row.epoch, Phase::Eval)) {
            let unstable = eval.iter().filter(|e| e.unstable).count();
            row.set_evaluation(crate::episode_stats(eval, k).as_ref(), unstable, row.eval_s);
        }
    }
    Ok(covered)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(epoch: usize, phase: Phase, nth: usize, ret: f64, unstable: bool) -> EpisodeRecord {
        EpisodeRecord {
            epoch,
            phase,
            env: 0,
            seed: 11,
            nth,
            ret,
            length: 4,
            unstable,
            success: None,
        }
    }

    #[test]
    fn the_log_resumes_at_the_checkpoint_and_the_rows_are_recomputed_from_it() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let path = tmp.path().join("episodes.csv");
        let epoch1 = [
            record(1, Phase::Train, 0, 5.0, false),
            record(1, Phase::Train, 1, 3.0, true),
            record(1, Phase::Eval, 0, 4.0, false),
        ];
        let epoch2 = [record(2, Phase::Train, 0, 1.0, false)];
        let mut log = EpisodeLog::new(&path);
        log.append(&epoch1).expect("write");
        log.append(&epoch2).expect("write");
        let whole = std::fs::read(&path).expect("read");
        // the header the readers check is the one the log writes
        assert!(whole.starts_with(format!("{}\n", COLUMNS.join(",")).as_bytes()));
        assert_eq!(
            read(&path).expect("records"),
            [&epoch1[..], &epoch2[..]].concat()
        );
        // resumed after epoch 1: epoch 2 is played again, the same
        let mut resumed = EpisodeLog::resume(&path, 1).expect("resume");
        resumed.append(&epoch2).expect("write");
        assert_eq!(std::fs::read(&path).expect("read"), whole);
        // rows written by a rule that left the failed episode out: recomputed, every one counts
        let mut rows = vec![
            ProgressRow {
                epoch: 1,
                episodes: 1,
                ep_ret_min: Some(5.0),
                ..Default::default()
            },
            ProgressRow {
                epoch: 2,
                ..Default::default()
            },
            ProgressRow {
                epoch: 3,
                ep_ret_min: Some(9.0),
                ..Default::default()
            },
        ];
        assert_eq!(recompute_rows(&mut rows, tmp.path(), 7.0).expect("read"), 2);
        assert_eq!((rows[0].episodes, rows[0].unstable_episodes), (2, 1));
        assert_eq!(
            (rows[0].ep_ret_min, rows[0].ep_ret_mean),
            (Some(3.0), Some(4.0))
        );
        assert_eq!(
            (rows[0].eval_ret_min, rows[0].eval_unstable_episodes),
            (Some(4.0), Some(0))
        );
        // J − k·Var of returns 5 and 3: 4 − 7·1
        assert_eq!(rows[0].bound, Some(-3.0));
        assert_eq!(rows[1].ep_ret_min, Some(1.0));
        assert_eq!(
            rows[2].ep_ret_min,
            Some(9.0),
            "an epoch the record does not cover is kept"
        );
        // a run without a record is left as it is
        let other = tempfile::tempdir().expect("tempdir");
        assert_eq!(
            recompute_rows(&mut rows, other.path(), 7.0).expect("none"),
            0
        );
        // a header without apo's columns is refused by the column, by resume as by the readers
        std::fs::write(&path, "epoch,phase\n1,train\n").expect("write");
        let err = format!("{:#}", EpisodeLog::resume(&path, 1).unwrap_err());
        assert!(
            err.contains("has no `env` column") && err.contains("episodes.csv"),
            "{err}"
        );
        assert_eq!(
            format!("{:#}", read_lenient(&path).unwrap_err()),
            format!("{:#}", read(&path).unwrap_err())
        );
        // a record repeated: counted once by the readers, refused by resume, naming both lines
        let once = String::from_utf8(whole.clone()).expect("text");
        let line = once.lines().nth(1).expect("a record").to_string();
        std::fs::write(&path, format!("{once}{line}\n")).expect("write");
        let lenient = read_lenient(&path).expect("records");
        assert_eq!(lenient.records.len(), once.lines().count() - 1);
        let err = format!("{:#}", EpisodeLog::resume(&path, 9).unwrap_err());
        assert!(err.contains("repeats the record of line 2"), "{err}");
        // a record that does not parse is named by its line
        std::fs::write(
            &path,
            format!("{}\n1,train,0,7,0,x,4,false,\n", COLUMNS.join(",")),
        )
        .expect("write");
        let err = format!("{:#}", EpisodeLog::resume(&path, 1).unwrap_err());
        assert!(
            err.contains("line 2") && err.contains("episodes.csv") && err.contains("`return`"),
            "{err}"
        );
    }
}
