//! Durable file writes: a temporary file beside the target, synced, renamed over it, and the
//! directory synced, so that after a crash or power loss a reader finds the old or the new
//! content, never a part or an empty file.

use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically and durably: readers see the old or the new content,
/// never a part, and the new content survives a power loss once this returns.
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = parent(path);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(temp_name(&name));
    {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
    }
    std::fs::rename(&tmp, path)?;
    sync_dir(dir)
}

/// The name of the temporary file [`write()`] uses for a file named `name`.
pub fn temp_name(name: &str) -> String {
    format!(".{name}.tmp")
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
