//! Atomic file writes: a temp file beside the target, renamed over it only when complete,
//! so a reader never sees half a file and a failure leaves nothing behind.
//!
//! `.NAME.PID.N.tmp` in the target's folder (the same file system, so the rename is
//! atomic), created exclusively; removed on every failure path, including a panic while
//! filling, by its guard's `Drop`.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use crate::error::{Error, Result};

/// Numbers temp files within this process, so that parallel writers never collide.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes a file atomically: `fill` writes into a temp file in the same folder, which is
/// renamed over `path` only on success; on failure no file is left behind.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_atomic_with(path, |out| fill(out).map_err(|e| Error::io(path, e)))
}

/// Temp files of writes in progress, for [`remove_temp_files`] on an interrupt.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes the temp files of atomic writes still in progress. For an interrupt handler
/// that then exits: an interrupted run leaves no partial file.
pub fn remove_temp_files() {
    for p in live().drain(..) {
        let _ = std::fs::remove_file(p);
    }
}

/// A temp file that removes itself unless it was renamed into place.
struct TempFile {
    path: PathBuf,
    armed: bool,
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if self.armed {
            let _ = std::fs::remove_file(&self.path);
        }
        live().retain(|p| p != &self.path);
    }
}

/// [`write_atomic`] with a `fill` that returns the library's errors.
pub(crate) fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<()>,
) -> Result<()> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::Invalid(format!("{}: not a file name", path.display())))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        let cause = if dir.exists() {
            "is not a folder"
        } else {
            "does not exist"
        };
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("cannot write: the folder {} {cause}", dir.display()),
            ),
        ));
    }
    let (file, temp) = create_temp(dir, name).map_err(|e| Error::io(path, e))?;
    let mut out = BufWriter::with_capacity(1 << 16, file);
    fill(&mut out)?;
    let file = out
        .into_inner()
        .map_err(|e| Error::io(path, e.into_error()))?;
    // No fsync: the rename already makes the write all-or-nothing for every reader and for
    // a killed process; only a power cut before write-back is left (ext4's auto_da_alloc
    // covers rename over an existing file; a new file could then be found empty).
    // An fsync of a 3 MB A4 page measured 7–14 ms here, a fifth of the 50 ms whole-run
    // goal, and batch runs would pay it per file.
    drop(file);
    std::fs::rename(&temp.path, path).map_err(|e| Error::io(path, e))?;
    let mut temp = temp;
    temp.armed = false;
    Ok(())
}

/// Creates `.NAME.PID.N.tmp` in `dir`, a name no other writer uses.
fn create_temp(dir: &Path, name: &std::ffi::OsStr) -> std::io::Result<(File, TempFile)> {
    loop {
        let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(".{}.{n}.tmp", std::process::id()));
        let path = dir.join(temp_name);
        // Registered before it exists, so an interrupt never misses it.
        live().push(path.clone());
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(f) => return Ok((f, TempFile { path, armed: true })),
            Err(e) => {
                live().retain(|p| p != &path);
                if e.kind() == std::io::ErrorKind::AlreadyExists {
                    continue;
                }
                return Err(e);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failure_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        let err = write_atomic(&target, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("out.bin"), "{err}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn success_replaces_target() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        std::fs::write(&target, b"old contents, longer").unwrap();
        write_atomic(&target, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn interrupt_cleanup_removes_temp_files_in_progress() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        write_atomic(&target, |w| {
            w.write_all(b"half")?;
            // What the Ctrl-C handler does mid-write.
            remove_temp_files();
            assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
            Ok(())
        })
        .unwrap_err();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn missing_folder_names_the_output() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("no/such/out.pbm");
        let err = write_atomic(&target, |w| w.write_all(b"x")).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("no/such/out.pbm") && msg.contains("does not exist"),
            "{msg}"
        );
    }
}
