//! Durable file writes: a temporary file beside the target, synced, renamed over it, and the
//! directory synced, so that after a crash or power loss a reader finds the old or the new
//! content, never a part or an empty file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `bytes` to `path` atomically and durably: readers see the old or the new content,
/// never a part, and the new content survives a power loss once this returns. It replaces a
/// plain file only ([`Place::ReplacePlainFile`]).
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_placed(path, bytes, Place::ReplacePlainFile)
}

/// [`write()`], placed as `how` says: with [`Place::New`] nothing at `path` is ever replaced,
/// not even what appears there while the bytes are written.
pub fn write_placed(path: &Path, bytes: &[u8], how: Place) -> std::io::Result<()> {
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
        .and_then(|()| place(&tmp, path, how));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    sync_dir(dir)
}

/// How a finished file takes its place, decided at the moment it does (no window between a
/// check and the rename in which something that appeared at the target would be replaced).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// Only where nothing is: whatever is at the target then (a file, a link, anything) stays
    /// and the placement fails. For the outputs a user names without `--force`.
    New,
    /// Over a plain file or nothing: a link, a folder or a special file at the target then
    /// stays and the placement fails. For apo's own files and `--force`.
    ReplacePlainFile,
    /// Over the very file apo found there when it checked (its device and inode, from
    /// [`file_id`]) or nothing: anything else at the target then — a file put in its place
    /// meanwhile included — stays and the placement fails. For an output apo wrote before in a
    /// folder the user named.
    ReplaceOwn {
        /// The file's device and inode when apo checked it.
        id: (u64, u64),
    },
}

/// The device and inode of the plain file at `path` (not followed), which name that file
/// while it exists ([`Place::ReplaceOwn`]); `None` for anything else or nothing.
pub fn file_id(path: &Path) -> Option<(u64, u64)> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        meta.is_file().then(|| (meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        None
    }
}

/// Moves the finished temporary file `tmp` to `path` as `how` says, atomically: on Linux by
/// `renameat2` (`RENAME_NOREPLACE`; for a replacement, `RENAME_EXCHANGE` and a look at what
/// came out, swapped back unless it is a plain file), elsewhere, or on a file system without
/// those, by a hard link (which never replaces) or a check and a rename. On an error `tmp` is
/// left for the caller to remove.
///
/// # Errors
/// `AlreadyExists` when something is at `path` that `how` does not replace (naming it), or
/// the OS's error.
pub fn place(tmp: &Path, path: &Path, how: Place) -> std::io::Result<()> {
    let appeared = |what: &str| {
        std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            format!(
                "{} {what}; nothing was replaced (apo replaces an existing file only with --force, and only a \
                 plain file)",
                path.display()
            ),
        )
    };
    match rename_no_replace(tmp, path) {
        Ok(()) => return Ok(()),
        Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => return Err(e),
        Err(_) if how == Place::New => {
            return Err(appeared("exists (it appeared while apo wrote it)"))
        }
        Err(_) => {}
    }
    // what may be replaced, judged by what is found there: `None` when it may
    let refused = |at: &Path| match (not_plain(at), how) {
        (Some(kind), _) => Some(format!("is {kind}")),
        (None, Place::ReplaceOwn { id }) if file_id(at) != Some(id) => {
            Some("is not the file apo wrote there (it was replaced while apo worked)".to_string())
        }
        _ => None,
    };
    // something is there: swap, and keep the swap only when what came out may be replaced
    match exchange(tmp, path) {
        Ok(()) => match refused(tmp) {
            None => std::fs::remove_file(tmp),
            Some(why) => {
                exchange(tmp, path)?;
                Err(appeared(&why))
            }
        },
        Err(e) if unsupported(&e) => match refused(path) {
            None => std::fs::rename(tmp, path),
            Some(why) => Err(appeared(&why)),
        },
        Err(e) => Err(e),
    }
}

/// Whether `e` says the file system (or the OS) does not offer an operation.
fn unsupported(e: &std::io::Error) -> bool {
    #[cfg(target_os = "linux")]
    {
        matches!(
            e.raw_os_error(),
            Some(libc::EINVAL | libc::ENOSYS | libc::EOPNOTSUPP)
        )
    }
    #[cfg(not(target_os = "linux"))]
    {
        e.kind() == std::io::ErrorKind::Unsupported
    }
}

/// `rename(from, to)` that fails with `AlreadyExists` where anything is at `to`, at the moment
/// of the rename.
///
/// # Errors
/// `AlreadyExists`, or the OS's error.
pub fn rename_no_replace(from: &Path, to: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        match renameat2(from, to, libc::RENAME_NOREPLACE) {
            Err(e) if unsupported(&e) => {}
            done => return done,
        }
    }
    // a hard link never replaces; then the temporary name goes
    std::fs::hard_link(from, to)?;
    std::fs::remove_file(from)
}

/// Swaps the entries `a` and `b` atomically (both must exist).
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        renameat2(a, b, libc::RENAME_EXCHANGE)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (a, b);
        Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
    }
}

#[cfg(target_os = "linux")]
fn renameat2(from: &Path, to: &Path, flags: libc::c_uint) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| {
        std::ffi::CString::new(p.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))
    };
    let (from, to) = (c(from)?, c(to)?);
    // SAFETY: both are NUL-terminated strings that live through the call; AT_FDCWD makes
    // relative paths relative to the working directory, as std's rename does
    let done = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            from.as_ptr(),
            libc::AT_FDCWD,
            to.as_ptr(),
            flags,
        )
    };
    if done == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
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
/// (a user's, another apo's) is ever written over, and marked as apo's ([`MARK`]: the proof
/// by which a later apo removes it if this process dies before it does).
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
        let id = format!("{}-{n}", std::process::id());
        let tmp = dir.join(format!(".{name}.apo-{id}.tmp"));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(file) => {
                mark(&file, &id);
                return Ok((tmp, file));
            }
            // left by an earlier process of the same id: take the next number
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// The extended attribute by which apo marks its temporary files, holding `<pid>-<n>` of the
/// name: a name alone proves nothing (a user may name a file anything), so apo removes a
/// temporary file of a process that is gone only when it carries the mark its name gives.
/// On a file system without user extended attributes, nothing is marked and nothing of a
/// process that is gone is removed: its temporary file stays, the user's to remove.
pub const MARK: &str = "user.apo.temp";

/// Marks the temporary file `file` as apo's, with `id` (`<pid>-<n>`); a file system without
/// extended attributes leaves it unmarked.
fn mark(file: &std::fs::File, id: &str) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let name = std::ffi::CString::new(MARK).unwrap_or_default();
        // SAFETY: the fd is open for the call's length; name is NUL-terminated; the value is
        // `id`'s bytes with their length
        unsafe {
            libc::fsetxattr(
                file.as_raw_fd(),
                name.as_ptr(),
                id.as_ptr().cast(),
                id.len(),
                0,
            );
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (file, id);
}

/// Whether the entry `entry` of `dir` is a temporary file apo made: of apo's form, a plain
/// file (not followed), and marked ([`MARK`]) with the ids of its name.
fn proven(dir: &Path, entry: &str) -> bool {
    let Some(ids) = temp_ids(entry) else {
        return false;
    };
    let path = dir.join(entry);
    if !std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::ffi::OsStrExt;
        let (Ok(path), Ok(name)) = (
            std::ffi::CString::new(path.as_os_str().as_bytes()),
            std::ffi::CString::new(MARK),
        ) else {
            return false;
        };
        let mut value = [0u8; 64];
        // SAFETY: both strings are NUL-terminated and live through the call; `value` is a
        // buffer of the length given
        let read = unsafe {
            libc::lgetxattr(
                path.as_ptr(),
                name.as_ptr(),
                value.as_mut_ptr().cast(),
                value.len(),
            )
        };
        usize::try_from(read).is_ok_and(|n| value[..n] == *ids.as_bytes())
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}

/// The `<pid>-<n>` of a temporary file's name of apo's form (`.<name>.apo-<pid>-<n>.tmp`).
fn temp_ids(entry: &str) -> Option<&str> {
    let inner = entry.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (_, ids) = inner.rsplit_once(".apo-")?;
    Some(ids)
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

/// Whether the entry `entry` of `dir` is a temporary file apo made ([`MARK`]) whose process
/// is still running (one being written at this moment).
pub fn is_live_temp(dir: &Path, entry: &str) -> bool {
    temp_pid(entry).is_some_and(|pid| !gone(pid)) && proven(dir, entry)
}

/// Removes from `dir` the temporary files apo made ([`MARK`]) whose process is gone (one
/// stopped by a second signal or killed mid-write): of the file `name`, or of any file with
/// `None`. A running apo's temporary files, a file of the same name without apo's mark, and
/// every other file, stay.
pub fn remove_dead_temps(dir: &Path, name: Option<&str>) {
    let Ok(entries) = crate::removal::entry_names(dir) else {
        return;
    };
    let me = std::process::id() as i32;
    let dead: Vec<String> = entries
        .into_iter()
        .filter(|e| name.is_none_or(|n| is_temp_of(e, n)))
        .filter(|e| temp_pid(e).is_some_and(|pid| pid != me && gone(pid)))
        .filter(|e| proven(dir, e))
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

/// The temporary files apo made for the files `names` in `dir`: of apo's form
/// ([`is_temp_of`]) and marked as apo's ([`MARK`]).
pub fn temps_of(dir: &Path, names: &[String]) -> Vec<String> {
    let Ok(entries) = crate::removal::entry_names(dir) else {
        return Vec::new();
    };
    entries
        .into_iter()
        .filter(|e| names.iter().any(|n| is_temp_of(e, n)) && proven(dir, e))
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

    /// Rule: apo removes only the temporary files it can prove it made: of its form, of a
    /// process that is gone, and carrying its mark with the ids of the name. A user's file of
    /// the same name (unmarked, or marked with other ids) stays.
    #[test]
    fn only_the_marked_temporary_files_of_a_process_that_is_gone_are_removed() {
        let tmp = tempfile::tempdir().expect("tempdir");
        // a process that has ended and been reaped
        let mut child = std::process::Command::new("true").spawn().expect("true");
        let dead = child.id();
        child.wait().expect("reap");
        let me = std::process::id();
        let make = |name: String, marked: Option<String>| {
            let file = std::fs::File::create(tmp.path().join(&name)).expect("create");
            if let Some(id) = marked {
                mark(&file, &id);
            }
            name
        };
        let apos = make(
            format!(".x.csv.apo-{dead}-0.tmp"),
            Some(format!("{dead}-0")),
        );
        let live = make(format!(".x.csv.apo-{me}-0.tmp"), Some(format!("{me}-0")));
        let users = make(format!(".x.csv.apo-{dead}-1.tmp"), None);
        let copied = make(
            format!(".x.csv.apo-{dead}-2.tmp"),
            Some(format!("{dead}-0")),
        );
        let other = make(
            format!(".y.csv.apo-{dead}-0.tmp"),
            Some(format!("{dead}-0")),
        );
        let plain = make(".x.csv.tmp".to_string(), None);
        assert!(proven(tmp.path(), &apos) && !proven(tmp.path(), &users));
        remove_dead_temps(tmp.path(), Some("x.csv"));
        let left = crate::removal::entry_names(tmp.path()).expect("ls");
        let mut kept = vec![
            live.clone(),
            users.clone(),
            copied.clone(),
            other.clone(),
            plain,
        ];
        kept.sort();
        assert_eq!(left, kept, "only {apos} goes");
        assert!(is_live_temp(tmp.path(), &live) && !is_live_temp(tmp.path(), &users));
        assert_eq!(temps_of(tmp.path(), &["x.csv".to_string()]), [live]);
        remove_dead_temps(tmp.path(), None);
        assert!(!tmp.path().join(&other).exists());
        assert!(tmp.path().join(&users).exists() && tmp.path().join(&copied).exists());
        // the temporary file of a write is marked while it exists, and the write leaves none
        let (made, _) = create_temp(tmp.path(), "z.csv").expect("temp");
        let name = made
            .file_name()
            .expect("name")
            .to_string_lossy()
            .into_owned();
        assert!(proven(tmp.path(), &name), "{name} carries apo's mark");
    }

    /// Rule: a placement never replaces what appeared after the check: `Place::New` keeps
    /// anything at the target, `Place::ReplacePlainFile` anything but a plain file (a link, to
    /// a file or to nothing, a folder), and either way the new bytes stay in the temporary
    /// file for the caller to remove.
    #[test]
    fn a_placement_replaces_nothing_it_may_not() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let target = tmp.path().join("out.gif");
        let temp = |bytes: &[u8]| {
            let (path, mut file) = create_temp(tmp.path(), "out.gif").expect("temp");
            file.write_all(bytes).expect("write");
            path
        };
        // nothing there: either way places it
        let t = temp(b"one");
        place(&t, &target, Place::New).expect("a new file");
        assert_eq!(std::fs::read(&target).expect("read"), b"one");
        assert!(!t.exists());
        // a file there: New keeps it, ReplacePlainFile replaces it
        let t = temp(b"two");
        let err = place(&t, &target, Place::New).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::AlreadyExists, "{err}");
        assert!(
            err.to_string().contains("appeared while apo wrote it"),
            "{err}"
        );
        assert_eq!(std::fs::read(&target).expect("read"), b"one");
        assert_eq!(std::fs::read(&t).expect("the new bytes stay"), b"two");
        place(&t, &target, Place::ReplacePlainFile).expect("replaces a plain file");
        assert_eq!(std::fs::read(&target).expect("read"), b"two");
        assert!(!t.exists());
        // a link (to a file of the user's, or to nothing) or a folder: kept by both
        let theirs = tmp.path().join("theirs.txt");
        std::fs::write(&theirs, b"theirs").expect("write");
        let nowhere = tmp.path().join("nowhere");
        for what in ["a link to a file", "a dangling link", "a folder"] {
            let at = tmp.path().join(what.replace(' ', "-"));
            match what {
                "a link to a file" => std::os::unix::fs::symlink(&theirs, &at).expect("link"),
                "a dangling link" => std::os::unix::fs::symlink(&nowhere, &at).expect("link"),
                _ => std::fs::create_dir(&at).expect("mkdir"),
            }
            for how in [Place::New, Place::ReplacePlainFile] {
                let t = temp(b"new");
                let err = place(&t, &at, how).unwrap_err();
                assert_eq!(
                    err.kind(),
                    std::io::ErrorKind::AlreadyExists,
                    "{what}: {err}"
                );
                assert!(not_plain(&at).is_some(), "{what} is still there, {how:?}");
                assert_eq!(std::fs::read(&t).expect("bytes"), b"new");
                std::fs::remove_file(&t).expect("rm");
            }
        }
        assert_eq!(std::fs::read(&theirs).expect("read"), b"theirs");
        assert!(!nowhere.exists());
        // ReplaceOwn replaces the very file it found, not one put in its place meanwhile
        let own = tmp.path().join("own.csv");
        std::fs::write(&own, b"apo's").expect("write");
        let id = file_id(&own).expect("a plain file");
        let t = temp(b"next");
        place(&t, &own, Place::ReplaceOwn { id }).expect("the same file");
        assert_eq!(std::fs::read(&own).expect("read"), b"next");
        let id = file_id(&own).expect("a plain file");
        std::fs::remove_file(&own).expect("rm");
        std::fs::write(&own, b"the user's").expect("write");
        let t = temp(b"again");
        let err = place(&t, &own, Place::ReplaceOwn { id }).unwrap_err();
        assert!(
            err.to_string().contains("is not the file apo wrote there"),
            "{err}"
        );
        assert_eq!(std::fs::read(&own).expect("read"), b"the user's");
    }
}
