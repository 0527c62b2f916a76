//! `progress.csv`: one [`ProgressRow`] per epoch.

use std::path::Path;

pub use apo_train::metrics::{EpochTimes, ProgressRow, TIME_COLUMNS};

/// Reads a `progress.csv`.
pub fn read(path: &Path) -> anyhow::Result<Vec<ProgressRow>> {
    let mut reader = csv::Reader::from_path(path)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    reader
        .deserialize()
        .collect::<Result<Vec<ProgressRow>, _>>()
        .map_err(|e| {
            anyhow::anyhow!(
                "{} is not a progress file of this version: {e}",
                path.display()
            )
        })
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
    crate::atomic::write(path, &bytes)?;
    Ok(())
}
