//! Writing output files atomically: a temporary file beside the target,
//! flushed, synced and renamed over it only once complete, so that a failed
//! or interrupted run leaves nothing half-written. The one implementation
//! behind every file this crate and the `coppertag` CLI write.

use std::fs::File;
use std::io::Write;
use std::path::Path;

use crate::error::{EvalError, Result};

fn write_err(path: &Path, source: std::io::Error) -> EvalError {
    EvalError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// Creates `path` atomically from what `fill` writes into a buffered
/// writer. The parent directory must exist.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<&mut File>) -> std::result::Result<(), String>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".coppertag-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| {
            write_err(
                path,
                std::io::Error::new(
                    e.kind(),
                    format!("cannot create a file in {}", dir.display()),
                ),
            )
        })?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        fill(&mut w).map_err(|m| write_err(path, std::io::Error::other(m)))?;
        w.flush().map_err(|e| write_err(path, e))?;
    }
    // tempfile creates 0600 files; outputs are ordinary user files.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| write_err(path, e))?;
    }
    tmp.as_file().sync_all().map_err(|e| write_err(path, e))?;
    tmp.persist(path).map_err(|e| write_err(path, e.error))?;
    Ok(())
}

/// Writes `bytes` to `path` atomically. The parent directory must exist.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes).map_err(|e| e.to_string()))
}

/// [`write_atomic`], creating the parent directories first.
pub fn write_atomic_in_new_dir(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| write_err(path, e))?;
    }
    write_atomic(path, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.txt");
        let e = write_atomic_with(&path, |_| Err("boom".into())).unwrap_err();
        assert!(e.to_string().contains("cannot write") && e.to_string().contains("boom"));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomic(&path, b"ok").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"ok");
        assert!(write_atomic(&dir.path().join("no/such/x"), b"").is_err());
        write_atomic_in_new_dir(&dir.path().join("new/x"), b"y").unwrap();
    }
}
