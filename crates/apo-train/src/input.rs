//! Checks on what users hand to apo, shared by every subcommand: files are read only when
//! they are regular files of a bounded size (a FIFO, a device or `/dev/zero` would block or
//! never end), output paths are checked before any work is done, and every error names the
//! path.

use std::io::Read;
use std::path::Path;

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
/// folder exists and is a folder, `path` is not a folder, and an existing file there is
/// replaced only with `replace` (the user's `--force`), never when it is not a plain file (a
/// symbolic link, a FIFO, a device). `flag` names the option in the error (`--out`).
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
    check_writable(parent).with_context(|| {
        format!(
            "{flag} {}: cannot write in {}",
            path.display(),
            parent.display()
        )
    })
}

/// Creates the output folder `dir` (and its parents) and checks that files can be written in
/// it, before any work. `flag` names the option in the error.
///
/// # Errors
/// When `dir` is a file or cannot be created or written, naming the flag and the path.
pub fn prepare_output_dir(dir: &Path, flag: &str) -> anyhow::Result<()> {
    if std::fs::symlink_metadata(dir).is_ok() && !dir.is_dir() {
        bail!("{flag} {} exists and is not a directory", dir.display());
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{flag} {}: cannot create the folder", dir.display()))?;
    check_writable(dir).with_context(|| format!("{flag} {}: cannot write in it", dir.display()))
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

/// This process's resident memory in bytes (the second field of `/proc/self/statm`).
pub fn resident_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = text.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    Some(pages * u64::try_from(page).ok()?)
}

/// Checks that `bytes` fit in this machine's memory; `what` names the options that size it.
///
/// # Errors
/// Naming `what`, the estimate and the machine's memory.
pub fn check_fits(bytes: f64, what: &str) -> anyhow::Result<()> {
    let have = physical_memory();
    if bytes > have as f64 {
        bail!(
            "{what} would need about {:.1} GiB of memory, more than this machine's {:.1} GiB; lower them",
            bytes / (1u64 << 30) as f64,
            have as f64 / (1u64 << 30) as f64
        );
    }
    Ok(())
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
