//! Durable file writes: a temporary file beside the target, synced, renamed over it, and the
//! directory synced, so that after a crash or power loss a reader finds the old or the new
//! content, never a part or an empty file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `bytes` to `path` atomically and durably: readers see the old or the new content,
/// never a part, and the new content survives a power loss once this returns.
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    // apo replaces only plain files: a link (every link is the user's), a folder or a special
    // file (a pipe, socket or device: apo makes none) stays
    if let Some(kind) = not_plain(path) {
        return Err(std::io::Error::other(format!(
            "{} is {kind}; apo replaces only plain files (move it away)",
            path.display()
        )));
    }
    let dir = parent(path);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (tmp, mut file) = create_temp(dir, &name)?;
    let written = file
        .write_all(bytes)
        .and_then(|()| file.sync_all())
        .and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    sync_dir(dir)
}

/// What `path` is when something other than a plain file is there (`"a symbolic link"`, `"a
/// folder"`, `"a special file"`: a pipe, socket or device); `None` when it is a plain file or
/// missing. apo makes only plain files and folders and never links or special files, so such
/// an entry where apo writes a file is the user's.
pub fn not_plain(path: &Path) -> Option<&'static str> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    let kind = meta.file_type();
    if kind.is_symlink() {
        Some("a symbolic link")
    } else if kind.is_dir() {
        Some("a folder")
    } else if !kind.is_file() {
        Some("a special file (a pipe, socket or device)")
    } else {
        None
    }
}

/// The bytes of a file's name kept in its temporary file's name.
const TEMP_NAME_KEPT: usize = 200;

/// Temporary files made by this process so far (their names are unique with the process id).
static TEMPS: AtomicU64 = AtomicU64::new(0);

/// Creates a new temporary file for a file named `name` in `dir`: `.<name>.apo-<pid>-<n>.tmp`,
/// a name no other process or call uses, opened with `create_new` so that no existing file
/// (a user's, another apo's) is ever written over.
///
/// # Errors
/// The OS error of the creation.
pub fn create_temp(dir: &Path, name: &str) -> std::io::Result<(PathBuf, std::fs::File)> {
    // a long name is cut (at a character boundary) so that the temporary name stays within the
    // 255 bytes a file name may have
    let mut cut = name.len().min(TEMP_NAME_KEPT);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    let name = &name[..cut];
    remove_dead_temps(dir, Some(name));
    loop {
        let n = TEMPS.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.apo-{}-{n}.tmp", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(file) => return Ok((tmp, file)),
            // left by an earlier process of the same id: take the next number
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// The process id in the name of a temporary file apo made (`.<name>.apo-<pid>-<n>.tmp`).
fn temp_pid(entry: &str) -> Option<i32> {
    let inner = entry.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (_, ids) = inner.rsplit_once(".apo-")?;
    let (pid, n) = ids.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok().filter(|&p: &i32| p > 0)
}

/// Whether the process `pid` is gone (`kill(pid, 0)` says ESRCH).
fn gone(pid: i32) -> bool {
    #[cfg(unix)]
    {
        // SAFETY: signal 0 checks for the process only; nothing is sent
        let found = unsafe { libc::kill(pid, 0) } == 0;
        !found && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        false
    }
}

/// Whether `entry` is a temporary file of apo's form whose process is still running (one
/// being written at this moment).
pub fn is_live_temp(entry: &str) -> bool {
    temp_pid(entry).is_some_and(|pid| !gone(pid))
}

/// Removes from `dir` the temporary files of apo's form whose process is gone (one stopped by a
/// second signal or killed mid-write): of the file `name`, or of any file with `None`. A
/// running apo's temporary files, and every other file, stay.
pub fn remove_dead_temps(dir: &Path, name: Option<&str>) {
    let Ok(entries) = crate::removal::entry_names(dir) else {
        return;
    };
    let me = std::process::id() as i32;
    let dead: Vec<String> = entries
        .into_iter()
        .filter(|e| name.is_none_or(|n| is_temp_of(e, n)))
        .filter(|e| temp_pid(e).is_some_and(|pid| pid != me && gone(pid)))
        .collect();
    let _ = crate::removal::remove_created(dir, &dead, false);
}

/// The name of the file whose temporary file apo made `entry` is (`.<name>.apo-<pid>-<n>.tmp`);
/// `None` for any other name — `.<name>.tmp` included, which may be a user's file. Those are
/// the only temporary files apo removes.
pub fn temp_target(entry: &str) -> Option<&str> {
    let inner = entry.strip_prefix('.')?.strip_suffix(".tmp")?;
    let digits = |p: &str| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit());
    let (name, ids) = inner.rsplit_once(".apo-")?;
    let (pid, n) = ids.split_once('-')?;
    (digits(pid) && digits(n) && !name.is_empty()).then_some(name)
}

/// Whether `entry` is a temporary file apo made for a file named `name` ([`temp_target`]).
pub fn is_temp_of(entry: &str, name: &str) -> bool {
    temp_target(entry) == Some(name)
}

/// The temporary files apo made for the files `names` in `dir` ([`is_temp_of`]).
pub fn temps_of(dir: &Path, names: &[String]) -> Vec<String> {
    let Ok(entries) = crate::removal::entry_names(dir) else {
        return Vec::new();
    };
    entries
        .into_iter()
        .filter(|e| names.iter().any(|n| is_temp_of(e, n)))
        .collect()
}

/// Syncs the file at `path` (its data and metadata) to the disk.
pub fn sync_file(path: &Path) -> std::io::Result<()> {
    std::fs::File::open(path)?.sync_all()
}

/// Syncs a directory, making the creations, renames and deletions inside it durable.
pub fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// The directory holding `path` (`.` for a bare file name).
pub fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_files_have_unique_names_and_never_replace_a_file() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let (a, _) = create_temp(tmp.path(), "x.csv").expect("first");
        let (b, _) = create_temp(tmp.path(), "x.csv").expect("second");
        assert_ne!(a, b);
        for p in [&a, &b] {
            let name = p.file_name().expect("name").to_string_lossy().into_owned();
            assert!(is_temp_of(&name, "x.csv"), "{name}");
            assert!(!is_temp_of(&name, "x"), "{name}");
        }
        // a user's file of the old fixed name, or of a similar name, is not apo's
        for user in [
            ".x.csv.tmp",
            ".x.csv.mine.tmp",
            ".x.csv.apo-1.tmp",
            ".x.csv.apo-1-2-3.tmp",
            "x.csv.tmp",
            ".x.csv.apo--1.tmp",
        ] {
            assert!(!is_temp_of(user, "x.csv"), "{user}");
        }
        let target = tmp.path().join("x.csv");
        std::fs::write(tmp.path().join(".x.csv.tmp"), "user's").expect("write");
        write(&target, b"new").expect("atomic write");
        assert_eq!(std::fs::read(&target).expect("read"), b"new");
        assert_eq!(
            std::fs::read(tmp.path().join(".x.csv.tmp")).expect("read"),
            b"user's",
            "a file of the old temporary name is left alone by a write"
        );
    }

    #[test]
    fn only_the_temporary_files_of_a_process_that_is_gone_are_removed() {
        let tmp = tempfile::tempdir().expect("tempdir");
        // a process that has ended and been reaped
        let mut child = std::process::Command::new("true").spawn().expect("true");
        let dead = child.id();
        child.wait().expect("reap");
        let me = std::process::id();
        for name in [
            format!(".x.csv.apo-{dead}-0.tmp"),
            format!(".x.csv.apo-{me}-0.tmp"),
            ".x.csv.tmp".to_string(),
            format!(".y.csv.apo-{dead}-0.tmp"),
        ] {
            std::fs::write(tmp.path().join(name), "").expect("write");
        }
        remove_dead_temps(tmp.path(), Some("x.csv"));
        let left = crate::removal::entry_names(tmp.path()).expect("ls");
        assert_eq!(
            left,
            [
                ".x.csv.apo-".to_string() + &me.to_string() + "-0.tmp",
                ".x.csv.tmp".to_string(),
                format!(".y.csv.apo-{dead}-0.tmp"),
            ]
        );
        remove_dead_temps(tmp.path(), None);
        assert!(!tmp.path().join(format!(".y.csv.apo-{dead}-0.tmp")).exists());
    }
}
