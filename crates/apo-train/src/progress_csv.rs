//! `progress.csv`: one [`ProgressRow`] per epoch.
//!
//! One reader, two uses. Every use checks the header the same way (each column one of apo's,
//! none twice, the first four there) and parses every row the same way. Training ([`read`])
//! takes the file whole or not at all: a row the readers of finished runs would leave out for
//! what it holds (one that does not parse, repeats or goes back on an epoch) is an error, since
//! resuming continues the record. The readers of
//! finished runs (`summary`, `report`, `plot`, `sweep`) use [`read_rows`]: a row that does not
//! parse, repeats or goes back on an epoch, or holds a non-finite return statistic is left out
//! and counted, and a warning names the file and the rows, so that one bad cell never turns
//! into a NaN in a table, a doubled epoch or a silently failed run; a gap in the epochs
//! (1, 2, 7) is named too, and a run's epoch count is its last epoch, not its row count.
//!
//! Both name a bad row the same way: its line, the column, the value and what the column
//! takes; an epoch outside `1..=`[`MAX_EPOCHS`](crate::config::MAX_EPOCHS) is such a value.

use std::path::Path;

pub use crate::metrics::{EpochTimes, ProgressRow, TIME_COLUMNS};

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

/// Every column of apo's progress file, in the order [`write()`] gives them.
pub fn columns() -> Vec<String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    // serializing a row writes the header first
    let bytes = match writer.serialize(ProgressRow::default()) {
        Ok(()) => writer.into_inner().unwrap_or_default(),
        Err(_) => Vec::new(),
    };
    let text = String::from_utf8_lossy(&bytes);
    text.lines()
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_string)
        .collect()
}

/// The columns the time and evaluation columns were added before: a progress file of an
/// earlier apo has the current columns without `sim_s` (the simulator's time), or without it
/// and the evaluation's columns.
const ADDED_LATER: [&[&str]; 2] = [
    &["sim_s"],
    &[
        "sim_s",
        "eval_ret_mean",
        "eval_ret_min",
        "eval_ret_cvar10",
        "eval_ret_std",
        "eval_len_mean",
        "eval_unstable_episodes",
        "eval_s",
    ],
];

/// The file's header, checked to be one apo wrote ([`crate::input::check_header`]: the
/// current columns, or an earlier apo's, [`ADDED_LATER`]), and a reader of its records.
fn open(path: &Path) -> anyhow::Result<(csv::StringRecord, crate::input::CsvReader)> {
    const WHAT: &str = "progress file";
    let (headers, reader) = crate::input::open_csv(path, WHAT)?;
    let current = columns();
    let mut versions: Vec<Vec<&str>> = vec![current.iter().map(String::as_str).collect()];
    for later in ADDED_LATER {
        versions.push(
            current
                .iter()
                .map(String::as_str)
                .filter(|c| !later.contains(c))
                .collect(),
        );
    }
    crate::input::check_header(path, WHAT, &headers, &versions)?;
    Ok((headers, reader))
}

/// Reads a `progress.csv` whole, as a resumed run continues it: the rows of [`read_lenient`],
/// and an error where it would leave a row out (one that does not parse, repeats or goes back
/// on an epoch, or holds a non-finite return statistic).
///
/// # Errors
/// A file that cannot be read, a header the readers refuse, or a row that does not parse or
/// repeats or goes back on an epoch, naming the file, the line, the column and the value.
pub fn read(path: &Path) -> anyhow::Result<Vec<ProgressRow>> {
    let progress = read_lenient(path, false)?;
    if let Some(first) = progress.left_out.first() {
        anyhow::bail!("{}: {first}", path.display());
    }
    Ok(progress.rows)
}

/// One record as a row, or why not in the file's terms: the column, its value and what the
/// column takes (an epoch outside `1..=MAX_EPOCHS` included).
fn parse_row(
    record: csv::Result<csv::StringRecord>,
    headers: &csv::StringRecord,
) -> Result<ProgressRow, String> {
    let row: ProgressRow = crate::input::csv_record(record, headers)?;
    let max = crate::config::MAX_EPOCHS;
    if !(1..=max).contains(&row.epoch) {
        return Err(format!(
            "column `epoch` = `{}`: out of range; epochs are 1..={max}",
            row.epoch
        ));
    }
    Ok(row)
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
    let (headers, mut reader) = open(path)?;
    let mut progress = Progress::default();
    let mut first_error = None;
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let row = match parse_row(record, &headers) {
            Ok(row) => row,
            Err(why) => {
                first_error.get_or_insert_with(|| format!("line {line}: {why}"));
                progress.left_out.push(format!("line {line}: {why}"));
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
                "{}: none of its {} row(s) can be read; the first: {e}",
                path.display(),
                progress.left_out.len()
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

    /// Rule: a bad row is named by its line, the column, the value and what the column takes,
    /// by both readers; an epoch outside 1..=MAX_EPOCHS is such a value, never a gap of
    /// billions of epochs nor "a repeated epoch".
    #[test]
    fn a_bad_row_is_named_by_line_column_value_and_range_by_both_readers() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("progress.csv");
        let rows: Vec<ProgressRow> = (1..=3)
            .map(|epoch| ProgressRow {
                epoch,
                env_steps: 100 * epoch as u64,
                ep_ret_mean: Some(1.0),
                ..ProgressRow::default()
            })
            .collect();
        write(&path, &rows).expect("write");
        let good = std::fs::read_to_string(&path).expect("read");
        let with_line_3 = |first: &str| {
            let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
            let rest = lines[2].split_once(',').expect("cells").1.to_string();
            lines[2] = format!("{first},{rest}");
            std::fs::write(&path, lines.join("\n") + "\n").expect("write");
        };
        for (epoch, says) in [
            (
                "0",
                "column `epoch` = `0`: out of range; epochs are 1..=1000000000",
            ),
            ("1000000001", "column `epoch` = `1000000001`: out of range"),
            (
                "18446744073709551616",
                "column `epoch` = `18446744073709551616`: number too large",
            ),
            (
                "-1",
                "column `epoch` = `-1`: invalid digit found in string; it takes a whole number ≥ 0",
            ),
        ] {
            with_line_3(epoch);
            let lenient = read_lenient(&path, false).expect("the other rows");
            assert_eq!(
                lenient.rows.iter().map(|r| r.epoch).collect::<Vec<_>>(),
                [1, 3]
            );
            assert_eq!(lenient.left_out.len(), 1);
            assert!(
                lenient.left_out[0].starts_with("line 3: ") && lenient.left_out[0].contains(says),
                "{:?}",
                lenient.left_out
            );
            assert_eq!(lenient.missing, [(2, 2)]);
            let whole = format!("{:#}", read(&path).unwrap_err());
            assert!(
                whole.contains("progress.csv: line 3: ") && whole.contains(says),
                "{whole}"
            );
        }
        let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
        let mut cells: Vec<String> = lines[1].split(',').map(str::to_string).collect();
        cells[3] = "x".into();
        lines[1] = cells.join(",");
        lines.truncate(2);
        std::fs::write(&path, lines.join("\n") + "\n").expect("write");
        let err = format!("{:#}", read_lenient(&path, false).unwrap_err());
        assert!(
            err.contains("none of its 1 row(s) can be read")
                && err.contains("line 2: column `ep_ret_mean` = `x`")
                && err.contains("it takes a number"),
            "{err}"
        );
    }
    /// Rule: one reader. A header a reader of finished runs refuses (a column that is not
    /// apo's, one given twice, a required one missing), resume refuses with the same words; and
    /// a row a reader leaves out (a repeated epoch), resume refuses, naming its line.
    #[test]
    fn what_a_reader_refuses_resume_refuses() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("progress.csv");
        let rows: Vec<ProgressRow> = (1..=3)
            .map(|epoch| ProgressRow {
                epoch,
                ep_ret_mean: Some(epoch as f64),
                ..ProgressRow::default()
            })
            .collect();
        write(&path, &rows).expect("write");
        let good = std::fs::read_to_string(&path).expect("read");
        let header = good.lines().next().expect("header").to_string();
        assert_eq!(header.split(',').collect::<Vec<_>>(), columns());
        let long = "y".repeat(100_000);
        for (edited, says) in [
            (
                header.replacen("ep_ret_mean", "ep_ret_mea", 1),
                "column 4 of the header, `ep_ret_mea`, is not a column of apo's progress file",
            ),
            (
                header.replacen("ep_ret_min", "ep_ret_mean", 1),
                "the column `ep_ret_mean` is in the header twice (columns 4 and 5)",
            ),
            (
                header.replacen("ep_ret_min", &long, 1),
                "column 5 of the header, `yyyy",
            ),
        ] {
            std::fs::write(&path, good.replacen(&header, &edited, 1)).expect("write");
            let lenient = format!("{:#}", read_lenient(&path, true).unwrap_err());
            let whole = format!("{:#}", read(&path).unwrap_err());
            assert!(lenient.contains(says), "{lenient}");
            assert_eq!(lenient, whole);
            assert!(
                whole.len() < 2_000,
                "the error quotes an excerpt: {} bytes",
                whole.len()
            );
        }
        // a column taken out (not a header any apo wrote) is refused by name; an earlier apo's
        // header (before `sim_s`) is read
        for (drop, says) in [
            ("ep_ret_min", Some("has no `ep_ret_min` column")),
            ("sim_s", None),
        ] {
            let mut lines: Vec<String> = Vec::new();
            let at = header.split(',').position(|c| c == drop).expect("a column");
            for line in good.lines() {
                let mut cells: Vec<&str> = line.split(',').collect();
                cells.remove(at);
                lines.push(cells.join(","));
            }
            std::fs::write(&path, lines.join("\n") + "\n").expect("write");
            match says {
                Some(says) => {
                    let whole = format!("{:#}", read(&path).unwrap_err());
                    assert!(whole.contains(says), "{whole}");
                    assert_eq!(
                        whole,
                        format!("{:#}", read_lenient(&path, true).unwrap_err())
                    );
                }
                None => assert_eq!(read(&path).expect("an earlier header").len(), 3),
            }
        }
        // a non-finite return statistic: left out by the readers, refused by resume
        let mut nan = rows.clone();
        nan[1].ep_ret_mean = Some(f64::NAN);
        write(&path, &nan).expect("write");
        assert_eq!(read_lenient(&path, false).expect("rows").left_out.len(), 1);
        let whole = format!("{:#}", read(&path).unwrap_err());
        assert!(
            whole.contains("line 3: epoch 2 has ep_ret_mean = NaN"),
            "{whole}"
        );
        let without: Vec<&str> = header.split(',').filter(|c| *c != "episodes").collect();
        let mut text = without.join(",") + "\n";
        for line in good.lines().skip(1) {
            let mut cells: Vec<&str> = line.split(',').collect();
            cells.remove(2);
            text += &(cells.join(",") + "\n");
        }
        std::fs::write(&path, text).expect("write");
        let whole = format!("{:#}", read(&path).unwrap_err());
        assert!(whole.contains("has no `episodes` column"), "{whole}");
        let mut lines: Vec<&str> = good.lines().collect();
        lines.insert(3, lines[2]);
        std::fs::write(&path, lines.join("\n") + "\n").expect("write");
        assert_eq!(read_lenient(&path, true).expect("rows").rows.len(), 3);
        let whole = format!("{:#}", read(&path).unwrap_err());
        assert!(
            whole.contains("line 4: epoch 2 after epoch 2 (repeated or out of order)"),
            "{whole}"
        );
    }
}
