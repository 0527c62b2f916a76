//! The one place where apo deletes anything: [`remove_created`] removes named files and a
//! folder only once it is empty, so no folder with a user's file in it is ever removed; and it
//! never follows or removes a symbolic link: apo makes none, so every link is the user's, and
//! what it points to lies outside what apo may clean; nor a special file (a pipe, socket or
//! device), which apo never makes either. Callers name only what apo created (see
//! `run_dir` for how that is known).

use std::path::Path;

use anyhow::Context;

/// Removes the files `names` from `dir` (a name that is missing is skipped; a directory of
/// that name is left alone unless it is empty), then `dir` itself when `remove_dir` and it is
/// empty. Returns the entries left in `dir`. This is the only function through which apo
/// deletes anything: it never removes a folder with something in it.
///
/// # Errors
/// When a file exists but cannot be removed.
pub fn remove_created(
    dir: &Path,
    names: &[String],
    remove_dir: bool,
) -> anyhow::Result<Vec<String>> {
    if is_link(dir) {
        // a link in apo's place: nothing behind it is apo's; the link stays (said as left)
        let name = dir
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        return Ok(vec![name]);
    }
    for name in names {
        let path = dir.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        // apo makes no links and no special files (pipes, sockets, devices): those are the
        // user's, whatever their name
        if meta.file_type().is_symlink() || !(meta.is_dir() || meta.is_file()) {
            continue;
        }
        if meta.is_dir() {
            // only an empty one; what is inside was not listed
            let _ = std::fs::remove_dir(&path);
        } else {
            std::fs::remove_file(&path)
                .with_context(|| format!("cannot remove {}", path.display()))?;
        }
    }
    let left = match entry_names(dir) {
        Ok(left) => left,
        Err(_) => return Ok(Vec::new()),
    };
    if remove_dir && left.is_empty() {
        std::fs::remove_dir(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    Ok(left)
}

/// Whether `path` is a symbolic link (not followed): apo neither reads through nor removes one
/// where it cleans up.
pub fn is_link(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink())
}

/// The names of the entries of `dir`, sorted.
pub(crate) fn entry_names(dir: &Path) -> anyhow::Result<Vec<String>> {
    let mut names = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("cannot read {}", dir.display()))?;
    names.sort();
    Ok(names)
}
