//! `progress.csv`: one [`ProgressRow`] per epoch.
//!
//! Two readers, one rule each. Training ([`read`]) takes the file whole or not at all: a row
//! that does not parse is an error, since resuming continues the record. The readers of
//! finished runs (`summary`, `report`, `plot`, `sweep`) use [`read_rows`]: a row that does not
//! parse, repeats or goes back on an epoch, or holds a non-finite return statistic is left out
//! and counted, and a warning names the file and the rows, so that one bad cell never turns
//! into a NaN in a table, a doubled epoch or a silently failed run; a gap in the epochs
//! (1, 2, 7) is named too, and a run's epoch count is its last epoch, not its row count.

use std::path::Path;

pub use crate::metrics::{EpochTimes, ProgressRow, TIME_COLUMNS};

/// The columns every `progress.csv` of apo has, first in its header.
const REQUIRED_COLUMNS: [&str; 4] = ["epoch", "env_steps", "episodes", "ep_ret_mean"];

/// A progress file read for reporting: the rows kept and why the others were left out.
#[derive(Debug, Clone, Default)]
pub struct Progress {
    /// The rows kept, epochs strictly increasing.
    pub rows: Vec<ProgressRow>,
    /// One line per row left out: `line <n>: <reason>`.
    pub left_out: Vec<String>,
    /// The epochs with no row kept, as inclusive ranges `(first, last)`: the gaps of the
    /// record (before its first row too), named in the warning and never read over.
    pub missing: Vec<(usize, usize)>,
}

/// The inclusive ranges of epochs from 1 that `epochs` (strictly increasing) skips.
pub fn gaps(epochs: impl IntoIterator<Item = usize>) -> Vec<(usize, usize)> {
    let mut missing = Vec::new();
    let mut next = 1;
    for epoch in epochs {
        if epoch > next {
            missing.push((next, epoch - 1));
        }
        next = epoch.saturating_add(1);
    }
    missing
}

fn open(path: &Path) -> anyhow::Result<csv::Reader<std::io::Cursor<Vec<u8>>>> {
    let bytes = crate::input::read_bytes(path, "progress file", crate::input::PROGRESS_FILE)?;
    Ok(csv::Reader::from_reader(std::io::Cursor::new(bytes)))
}

/// Reads a `progress.csv` whole: every row must parse.
///
/// # Errors
/// A file that cannot be read, or a row that does not parse, naming the file.
pub fn read(path: &Path) -> anyhow::Result<Vec<ProgressRow>> {
    open(path)?
        .deserialize()
        .collect::<Result<Vec<ProgressRow>, _>>()
        .map_err(|e| {
            anyhow::anyhow!(
                "{} is not a progress file of this version: {e}",
                path.display()
            )
        })
}

/// The first non-finite return statistic of `row`, by column name.
fn non_finite(row: &ProgressRow) -> Option<(&'static str, f64)> {
    [
        ("ep_ret_mean", row.ep_ret_mean),
        ("ep_ret_min", row.ep_ret_min),
        ("ep_ret_max", row.ep_ret_max),
        ("ep_ret_std", row.ep_ret_std),
        ("ep_ret_cvar10", row.ep_ret_cvar10),
        ("ep_ret_q10", row.ep_ret_q10),
        ("ep_len_mean", row.ep_len_mean),
        ("success_rate", row.success_rate),
        ("bound", row.bound),
        ("confidence", row.confidence),
    ]
    .into_iter()
    .find_map(|(name, v)| v.filter(|v| !v.is_finite()).map(|v| (name, v)))
}

/// Reads a `progress.csv` for reporting (see the module's documentation); with
/// `keep_non_finite`, rows with non-finite values are kept (for a reader that leaves out and
/// counts single values, as `apo plot` does).
///
/// # Errors
/// A file that cannot be read, or one of which no row parses (not a progress file).
pub fn read_lenient(path: &Path, keep_non_finite: bool) -> anyhow::Result<Progress> {
    let mut reader = open(path)?;
    let headers = reader
        .headers()
        .map_err(|e| anyhow::anyhow!("{}: cannot read the header: {e}", path.display()))?
        .clone();
    if let Some(missing) = REQUIRED_COLUMNS
        .iter()
        .find(|c| !headers.iter().any(|h| h == **c))
    {
        let shown: Vec<&str> = headers.iter().take(12).collect();
        anyhow::bail!(
            "{} is not a progress file of apo: it has no `{missing}` column; its header is `{}{}` \
             (apo's starts with {})",
            path.display(),
            shown.join(","),
            if headers.len() > 12 { ",…" } else { "" },
            REQUIRED_COLUMNS.join(",")
        );
    }
    let mut progress = Progress::default();
    let mut first_error = None;
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let row: ProgressRow = match record.and_then(|r| r.deserialize(Some(&headers))) {
            Ok(row) => row,
            Err(e) => {
                first_error.get_or_insert_with(|| e.to_string());
                progress
                    .left_out
                    .push(format!("line {line}: does not parse ({e})"));
                continue;
            }
        };
        let previous = progress.rows.last().map_or(0, |r| r.epoch);
        if row.epoch <= previous {
            progress.left_out.push(format!(
                "line {line}: epoch {} after epoch {previous} (repeated or out of order)",
                row.epoch
            ));
        } else if let Some((column, v)) = non_finite(&row).filter(|_| !keep_non_finite) {
            progress.left_out.push(format!(
                "line {line}: epoch {} has {column} = {v}",
                row.epoch
            ));
        } else {
            progress.rows.push(row);
        }
    }
    progress.missing = gaps(progress.rows.iter().map(|r| r.epoch));
    if progress.rows.is_empty() {
        if let Some(e) = first_error {
            anyhow::bail!(
                "{} is not a progress file of this version: {e}",
                path.display()
            );
        }
    }
    Ok(progress)
}

/// [`read_lenient`]'s rows, with a warning on stderr naming the rows left out.
///
/// # Errors
/// As [`read_lenient`].
pub fn read_rows(path: &Path) -> anyhow::Result<Vec<ProgressRow>> {
    warn_left_out(path, read_lenient(path, false)?)
}

/// [`read_rows`], keeping the rows with non-finite values (`apo plot` leaves out and counts
/// those values itself, and says so on the figure).
///
/// # Errors
/// As [`read_lenient`].
pub fn read_rows_with_non_finite(path: &Path) -> anyhow::Result<Vec<ProgressRow>> {
    warn_left_out(path, read_lenient(path, true)?)
}

fn warn_left_out(path: &Path, progress: Progress) -> anyhow::Result<Vec<ProgressRow>> {
    warn(path, "row(s) left out", &progress.left_out);
    let missing: Vec<String> = progress
        .missing
        .iter()
        .map(|&(a, b)| {
            if a == b {
                format!("{a}")
            } else {
                format!("{a}–{b}")
            }
        })
        .collect();
    warn(
        path,
        "epoch range(s) missing (a gap in the record)",
        &missing,
    );
    Ok(progress.rows)
}

/// Warns on stderr, once per file, about the records of `path` that a lenient reader left
/// out: how many (`what`) and the first few, one per `lines`.
pub fn warn(path: &Path, what: &str, lines: &[String]) {
    if lines.is_empty() {
        return;
    }
    const SHOWN: usize = 5;
    let more = lines.len().saturating_sub(SHOWN);
    crate::warnln!(
        "warning: {}: {} {what}: {}{}",
        path.display(),
        lines.len(),
        lines[..lines.len().min(SHOWN)].join("; "),
        if more > 0 {
            format!("; and {more} more")
        } else {
            String::new()
        }
    );
}

/// Writes `rows` to `path` atomically (the whole file is rewritten each epoch).
pub fn write(path: &Path, rows: &[ProgressRow]) -> anyhow::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    for row in rows {
        writer.serialize(row)?;
    }
    if rows.is_empty() {
        return Ok(());
    }
    let bytes = writer
        .into_inner()
        .map_err(|e| anyhow::anyhow!("csv: {e}"))?;
    crate::atomic::write(path, &bytes)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_in_the_epochs_are_named_as_ranges() {
        assert_eq!(gaps([1, 2, 7]), vec![(3, 6)]);
        assert_eq!(gaps([2, 4, 5, 9]), vec![(1, 1), (3, 3), (6, 8)]);
        assert!(gaps([1, 2, 3]).is_empty());
        assert!(gaps(std::iter::empty()).is_empty());
    }
}
