//! Checks on what users hand to apo, shared by every subcommand: files are read only when
//! they are regular files of a bounded size (a FIFO, a device or `/dev/zero` would block or
//! never end), output paths are checked before any work is done, and every error names the
//! path.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

/// The largest config, marker or manifest file apo reads (1 MiB).
pub const SMALL_FILE: u64 = 1 << 20;
/// The largest `progress.csv` apo reads (1 GiB: millions of epochs).
pub const PROGRESS_FILE: u64 = 1 << 30;

/// Checks that `path` is a regular file (links followed) of at most `max_bytes`; `what` names
/// it in the error.
///
/// # Errors
/// A missing path, a folder, a FIFO, a device or socket, or a file that is too large.
pub fn check_file(path: &Path, what: &str, max_bytes: u64) -> anyhow::Result<u64> {
    let meta = std::fs::metadata(path)
        .with_context(|| format!("cannot read {what} {}", path.display()))?;
    if meta.is_dir() {
        bail!("{what} {} is a directory, not a file", path.display());
    }
    if !meta.is_file() {
        bail!(
            "{what} {} is not a regular file (a pipe, device or socket); apo reads only files",
            path.display()
        );
    }
    if meta.len() > max_bytes {
        bail!(
            "{what} {} has {} bytes, more than the {} this file can have",
            path.display(),
            meta.len(),
            max_bytes
        );
    }
    Ok(meta.len())
}

/// Reads `path` as bytes after [`check_file`]; never more than `max_bytes`.
///
/// # Errors
/// As [`check_file`], and read errors, naming the path.
pub fn read_bytes(path: &Path, what: &str, max_bytes: u64) -> anyhow::Result<Vec<u8>> {
    check_file(path, what, max_bytes)?;
    let file = std::fs::File::open(path)
        .with_context(|| format!("cannot open {what} {}", path.display()))?;
    let mut bytes = Vec::new();
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .with_context(|| format!("cannot read {what} {}", path.display()))?;
    if bytes.len() as u64 > max_bytes {
        bail!(
            "{what} {} grew past {max_bytes} bytes while being read",
            path.display()
        );
    }
    Ok(bytes)
}

/// Reads `path` as UTF-8 text after [`check_file`].
///
/// # Errors
/// As [`read_bytes`], and text that is not UTF-8.
pub fn read_text(path: &Path, what: &str, max_bytes: u64) -> anyhow::Result<String> {
    String::from_utf8(read_bytes(path, what, max_bytes)?)
        .map_err(|_| anyhow::anyhow!("{what} {} is not UTF-8 text", path.display()))
}

/// Checks, before any work, that a file can be written at `path` by apo's output rule: its
/// folder exists and is a folder, its name fits the folder's file system ([`too_long_name`]),
/// `path` is not a folder, and an existing file there is replaced only with `replace` (the
/// user's `--force`), never when it is not a plain file (a symbolic link, a FIFO, a device).
/// `flag` names the option in the error (`--out`).
///
/// # Errors
/// Naming the flag and the path.
pub fn check_output_file(path: &Path, flag: &str, replace: bool) -> anyhow::Result<()> {
    if path.is_dir() {
        bail!("{flag} {} is a directory; give a file name", path.display());
    }
    // a link (even one to nothing) is never followed nor replaced, --force or not: apo
    // replaces only plain files, the one rule of every file it writes
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        bail!(
            "{flag} {} exists and is a symbolic link; apo replaces only plain files (with --force): \
             remove the link or name another file",
            path.display()
        );
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if !meta.is_file() {
            bail!(
                "{flag} {} exists and is not a regular file (a pipe, device or socket); apo writes only files",
                path.display()
            );
        }
        if !replace {
            bail!(
                "{flag} {} exists; apo replaces an existing file only with --force",
                path.display()
            );
        }
    }
    let parent = crate::atomic::parent(path);
    match std::fs::metadata(parent) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => bail!(
            "{flag} {}: {} is not a directory",
            path.display(),
            parent.display()
        ),
        Err(_) => bail!(
            "{flag} {}: the folder {} does not exist; create it first",
            path.display(),
            parent.display()
        ),
    }
    check_name_lengths(path, flag)?;
    check_writable(parent).with_context(|| {
        format!(
            "{flag} {}: cannot write in {}",
            path.display(),
            parent.display()
        )
    })
}

/// The first name along `path` that does not exist yet and is longer than its file system
/// takes (the limit of the nearest existing folder above it), as `(name, its length in
/// bytes, the limit)`; `None` when every new name fits. The limit is `pathconf`'s
/// `_PC_NAME_MAX` (255 on the usual Linux file systems).
pub fn too_long_name(path: &Path) -> Option<(String, usize, usize)> {
    let mut existing = path;
    let mut new = Vec::new();
    while std::fs::symlink_metadata(existing).is_err() {
        let (Some(name), Some(parent)) = (existing.file_name(), existing.parent()) else {
            break;
        };
        new.push(name);
        existing = parent;
    }
    let folder = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    let max = name_max(folder);
    new.into_iter()
        .rev()
        .find(|name| name.len() > max)
        .map(|name| (name.to_string_lossy().into_owned(), name.len(), max))
}

/// Checks, before any work, that every name of the output `path` that apo will create fits its
/// file system ([`too_long_name`]). `flag` names the option in the error.
///
/// # Errors
/// Naming the flag, the name, its length and the limit.
pub(crate) fn check_name_lengths(path: &Path, flag: &str) -> anyhow::Result<()> {
    match too_long_name(path) {
        Some((name, length, max)) => bail!(
            "{flag} {}: the name {name} is {length} bytes long; its file system takes at most {max}",
            path.display()
        ),
        None => Ok(()),
    }
}

/// The longest file name, in bytes, that the file system of the folder `dir` takes
/// (`pathconf(dir, _PC_NAME_MAX)`; 255, Linux's usual limit, where it cannot tell).
fn name_max(dir: &Path) -> usize {
    use std::os::unix::ffi::OsStrExt;
    let Ok(dir) = std::ffi::CString::new(dir.as_os_str().as_bytes()) else {
        return 255;
    };
    // SAFETY: `dir` is a NUL-terminated string that outlives the call
    let max = unsafe { libc::pathconf(dir.as_ptr(), libc::_PC_NAME_MAX) };
    usize::try_from(max).ok().filter(|&m| m > 0).unwrap_or(255)
}

/// Creates the output folder `dir` (and its parents) and checks that files can be written in
/// it, before any work; returns the folders it created. `flag` names the option in the error.
///
/// # Errors
/// When `dir` is a file or cannot be created or written, naming the flag and the path.
pub fn prepare_output_dir(dir: &Path, flag: &str) -> anyhow::Result<CreatedDirs> {
    if std::fs::symlink_metadata(dir).is_ok() && !dir.is_dir() {
        bail!("{flag} {} exists and is not a directory", dir.display());
    }
    check_name_lengths(dir, flag)?;
    let mut created = CreatedDirs::default();
    let mut missing = dir;
    while std::fs::symlink_metadata(missing).is_err() {
        created.0.push(missing.to_path_buf());
        match missing.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => missing = parent,
            _ => break,
        }
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{flag} {}: cannot create the folder", dir.display()))
        .inspect_err(|_| created.remove_if_empty())?;
    check_writable(dir)
        .with_context(|| format!("{flag} {}: cannot write in it", dir.display()))
        .inspect_err(|_| created.remove_if_empty())?;
    Ok(created)
}

/// The folders [`prepare_output_dir`] created, deepest first: a command that fails after it
/// removes them again ([`CreatedDirs::remove_if_empty`]), so that it leaves only what was there.
#[derive(Debug, Default)]
#[must_use]
pub struct CreatedDirs(Vec<PathBuf>);

impl CreatedDirs {
    /// Removes the created folders that are still empty, deepest first; a folder with anything
    /// in it stays, and so do the folders above it.
    pub fn remove_if_empty(&self) {
        for dir in &self.0 {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// Checks that a file can be created in the folder `dir` (creates and removes a probe file).
fn check_writable(dir: &Path) -> anyhow::Result<()> {
    let probe = dir.join(format!(".apo-write-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(anyhow::Error::from)?;
    // the probe is the file just created (`create_new`), so it goes by its own path, also
    // when `dir` is reached through a symbolic link
    std::fs::remove_file(&probe).with_context(|| format!("cannot remove {}", probe.display()))
}

/// Assumed memory where `/proc/meminfo` cannot be read.
const MEMORY_WITHOUT_PROC: u64 = 64 << 30;

/// This machine's physical memory in bytes (`MemTotal` of `/proc/meminfo`; 64 GiB where it
/// cannot be read).
pub fn physical_memory() -> u64 {
    let read = || -> Option<u64> {
        let text = std::fs::read_to_string("/proc/meminfo").ok()?;
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    };
    read().unwrap_or(MEMORY_WITHOUT_PROC)
}

/// The memory this process may still take, in bytes, and what sets it: the least of this
/// machine's memory ([`physical_memory`]), its control group's limit (`memory.max`, cgroup v2)
/// and, less what the process already maps, its own limits (`ulimit -v`, `RLIMIT_AS`;
/// `ulimit -d`, `RLIMIT_DATA`), which the kernel enforces by failing an allocation (Rust
/// aborts then) rather than by using swap.
pub fn memory_limit() -> (u64, String) {
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    let mut limit = (
        physical_memory(),
        format!("this machine's {:.1} GiB", gib(physical_memory())),
    );
    let mut consider = |bytes: u64, what: String| {
        if bytes < limit.0 {
            limit = (bytes, what);
        }
    };
    if let Some(max) = cgroup_memory_max() {
        consider(
            max,
            format!(
                "its control group's limit of {:.1} GiB (memory.max)",
                gib(max)
            ),
        );
    }
    // statm: the sizes in pages of the whole mapping (field 1) and of the data and stack (6)
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: Vec<u64> = statm
        .split_whitespace()
        .map(|f| f.parse().unwrap_or(0))
        .collect();
    // SAFETY: sysconf has no preconditions
    let page = u64::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap_or(4096);
    let used = |field: usize| pages.get(field).copied().unwrap_or(0).saturating_mul(page);
    for (resource, flag, field) in [
        (libc::RLIMIT_AS, "ulimit -v", 0),
        (libc::RLIMIT_DATA, "ulimit -d", 5),
    ] {
        let mut rlimit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the limit into the struct it is given, which lives here
        if unsafe { libc::getrlimit(resource, &mut rlimit) } == 0
            && rlimit.rlim_cur != libc::RLIM_INFINITY
        {
            let cap = rlimit.rlim_cur;
            consider(
                cap.saturating_sub(used(field)),
                format!(
                    "the {:.1} GiB this process has left of its limit of {:.1} GiB (`{flag}`)",
                    gib(cap.saturating_sub(used(field))),
                    gib(cap)
                ),
            );
        }
    }
    limit
}

/// The cgroup v2 memory limit of this process (`memory.max` of its group), when one is set.
fn cgroup_memory_max() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = groups.lines().find_map(|l| l.strip_prefix("0::"))?;
    let max = std::fs::read_to_string(format!("/sys/fs/cgroup{path}/memory.max")).ok()?;
    max.trim().parse().ok()
}

/// This process's resident memory in bytes (the second field of `/proc/self/statm`).
pub fn resident_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = text.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    Some(pages * u64::try_from(page).ok()?)
}

/// Checks that `bytes` fit in the memory this process may take ([`memory_limit`]); `what`
/// names the options that size it.
///
/// # Errors
/// Naming `what`, the estimate and the limit.
pub fn check_fits(bytes: f64, what: &str) -> anyhow::Result<()> {
    let (have, limit) = memory_limit();
    if bytes > have as f64 {
        bail!(
            "{what} would need about {:.1} GiB of memory, more than {limit}; lower them",
            bytes / (1u64 << 30) as f64,
        );
    }
    Ok(())
}

/// The characters of found text an error quotes ([`excerpt`]).
pub const EXCERPT_CHARS: usize = 60;

/// `text` as an error quotes it: whole when short, else its first [`EXCERPT_CHARS`]
/// characters, `…` and its length (a header of 300 MB is named, not echoed).
pub fn excerpt(text: &str) -> String {
    clip(text, EXCERPT_CHARS)
}

/// `text` cut after `chars` characters, with `…` and its length in bytes when it was longer.
pub fn clip(text: &str, chars: usize) -> String {
    match text.char_indices().nth(chars) {
        None => text.to_string(),
        Some((cut, _)) => format!("{}… ({} bytes)", &text[..cut], text.len()),
    }
}

/// Checks the header of the record file at `path` (a `what`): it must be one of the headers
/// apo has written, `versions` (newest first, each a list of columns in order). Every reader
/// of the file checks it, the one that resumes a run included, so that a header a reader
/// refuses is never read over, and a column taken out of a file is never filled in blank.
///
/// # Errors
/// Naming the file and the first column that is not apo's (by position and name, in an
/// [`excerpt`]), repeated, missing or out of its place, and the columns apo writes.
pub fn check_header(
    path: &Path,
    what: &str,
    headers: &csv::StringRecord,
    versions: &[Vec<&str>],
) -> anyhow::Result<()> {
    // an empty file has no header to check (and no records: its readers say what is missing)
    if headers.is_empty() {
        return Ok(());
    }
    let newest = versions.first().map_or(&[][..], Vec::as_slice);
    let takes = || format!("apo's {what} has the columns {}", newest.join(","));
    let mut seen = std::collections::BTreeSet::new();
    for (i, column) in headers.iter().enumerate() {
        if !newest.contains(&column) {
            bail!(
                "{}: column {} of the header, `{}`, is not a column of apo's {what}; {}",
                path.display(),
                i + 1,
                excerpt(column),
                takes()
            );
        }
        if !seen.insert(column) {
            bail!(
                "{}: the column `{column}` is in the header twice (columns {} and {})",
                path.display(),
                headers
                    .iter()
                    .position(|h| h == column)
                    .map_or(0, |p| p + 1),
                i + 1
            );
        }
    }
    if versions
        .iter()
        .any(|v| headers.iter().eq(v.iter().copied()))
    {
        return Ok(());
    }
    // the version it is closest to: the one that holds every column it has
    let closest = versions
        .iter()
        .rev()
        .find(|v| headers.iter().all(|h| v.contains(&h)))
        .map_or(newest, Vec::as_slice);
    match closest.iter().find(|c| !seen.contains(**c)) {
        Some(missing) => bail!(
            "{} is not apo's {what}: it has no `{missing}` column (a column taken out of the file is not \
             read over); {}",
            path.display(),
            takes()
        ),
        None => {
            let (i, (found, want)) = headers
                .iter()
                .zip(closest.iter().copied())
                .enumerate()
                .find(|(_, (h, c))| h != c)
                .unwrap_or((0, ("", "")));
            bail!(
                "{}: column {} of the header is `{found}` where apo writes `{want}` (the columns were reordered); {}",
                path.display(),
                i + 1,
                takes()
            )
        }
    }
}

/// A reader of one of apo's record files, read whole into memory.
pub type CsvReader = csv::Reader<std::io::Cursor<Vec<u8>>>;

/// The header of the record file at `path` (at most [`PROGRESS_FILE`] bytes; `what` names it
/// in errors) and a reader of its records.
///
/// # Errors
/// A file that cannot be read or whose header cannot.
pub fn open_csv(path: &Path, what: &str) -> anyhow::Result<(csv::StringRecord, CsvReader)> {
    let bytes = read_bytes(path, what, PROGRESS_FILE)?;
    let mut reader = csv::Reader::from_reader(std::io::Cursor::new(bytes));
    let headers = reader
        .headers()
        .map_err(|e| anyhow::anyhow!("{}: cannot read the header: {e}", path.display()))?
        .clone();
    Ok((headers, reader))
}

/// One record of a CSV file as `T`, or why not in the file's terms: the column, its value (the
/// first 40 characters) and what the column takes — how every reader of apo's record files
/// (`progress.csv`, `episodes.csv`) names a bad row, after `line <n>: `.
///
/// # Errors
/// The record could not be read or does not fit `T`.
pub fn csv_record<T: serde::de::DeserializeOwned>(
    record: csv::Result<csv::StringRecord>,
    headers: &csv::StringRecord,
) -> Result<T, String> {
    let record = record.map_err(|e| e.to_string())?;
    record.deserialize(Some(headers)).map_err(|e| {
        let csv::ErrorKind::Deserialize { err, .. } = e.kind() else {
            return e.to_string();
        };
        let Some(field) = err.field().and_then(|f| usize::try_from(f).ok()) else {
            return err.kind().to_string();
        };
        let takes = match err.kind() {
            csv::DeserializeErrorKind::ParseInt(_) => "; it takes a whole number ≥ 0",
            csv::DeserializeErrorKind::ParseFloat(_) => "; it takes a number",
            _ => "",
        };
        let value: String = record.get(field).unwrap_or("").chars().take(40).collect();
        format!(
            "column `{}` = `{value}`: {}{takes}",
            excerpt(headers.get(field).unwrap_or("?")),
            err.kind()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_bounded_regular_files_are_read() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let file = tmp.path().join("a.toml");
        std::fs::write(&file, "x = 1").expect("write");
        assert_eq!(read_text(&file, "config", 100).expect("read"), "x = 1");
        let err = read_text(&file, "config", 3).unwrap_err().to_string();
        assert!(err.contains("more than the 3"), "{err}");
        let err = read_text(tmp.path(), "config", 100)
            .unwrap_err()
            .to_string();
        assert!(err.contains("is a directory"), "{err}");
        let err = read_text(Path::new("/dev/zero"), "config", 100)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("not a regular file") && err.contains("/dev/zero"),
            "{err}"
        );
    }

    #[test]
    fn an_output_folder_prepared_and_given_up_leaves_only_what_was_there() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let deep = tmp.path().join("a/b/c");
        let created = prepare_output_dir(&deep, "--out").expect("prepared");
        assert!(deep.is_dir());
        created.remove_if_empty();
        assert!(
            !tmp.path().join("a").exists(),
            "every folder it made is gone"
        );
        // a folder with anything in it stays, and so do the folders above it
        let created = prepare_output_dir(&deep, "--out").expect("prepared");
        std::fs::write(tmp.path().join("a/b/user.txt"), "mine").expect("write");
        created.remove_if_empty();
        assert!(!deep.exists() && tmp.path().join("a/b/user.txt").is_file());
        // a folder that was there is not one it made
        let created = prepare_output_dir(&tmp.path().join("a"), "--out").expect("prepared");
        created.remove_if_empty();
        assert!(tmp.path().join("a/b/user.txt").is_file());
        // a name too long for the file system is refused before anything is made
        let long = tmp.path().join("x").join("y".repeat(300));
        let err = format!("{:#}", prepare_output_dir(&long, "--out").unwrap_err());
        assert!(
            err.contains("300 bytes long") && err.contains("--out"),
            "{err}"
        );
        assert!(!tmp.path().join("x").exists());
    }

    #[test]
    fn output_paths_are_checked_with_the_flag_and_path() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let err = check_output_file(&tmp.path().join("nodir/x.png"), "--out", true)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("--out") && err.contains("nodir") && err.contains("does not exist"),
            "{err}"
        );
        check_output_file(&tmp.path().join("x.png"), "--out", false).expect("writable");
        assert_eq!(
            std::fs::read_dir(tmp.path()).expect("ls").count(),
            0,
            "no probe left"
        );
        // an existing file: only with replace
        let existing = tmp.path().join("x.png");
        std::fs::write(&existing, "mine").expect("write");
        let err = check_output_file(&existing, "--out", false)
            .unwrap_err()
            .to_string();
        assert!(err.contains("exists") && err.contains("--force"), "{err}");
        check_output_file(&existing, "--out", true).expect("replace");
        let err = check_output_file(Path::new("/dev/null"), "--out", true)
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a regular file"), "{err}");
        std::fs::remove_file(&existing).expect("rm");
        let file = tmp.path().join("f");
        std::fs::write(&file, "").expect("write");
        let err = prepare_output_dir(&file, "--out").unwrap_err().to_string();
        assert!(err.contains("not a directory"), "{err}");
    }
}
