//! Output files: regular files are replaced atomically, special files are written through.
//!
//! - A regular file (or a new name) is written to a temp file beside it and renamed over it
//!   only when complete, so a reader never sees half a file and a failure leaves nothing
//!   behind. The temp file is `.NAME.HOST.PID.N.tmp` in the target's folder (the same file
//!   system, so the rename is atomic), created exclusively; HOST and PID name its writer, so
//!   writers on machines sharing a file system never collide and a later run can tell the
//!   leftovers of a killed process ([`parse_temp_name`]). It is removed on every failure path,
//!   including a panic while filling, by its guard's `Drop`, and by `remove_temp_files`
//!   from the command line's signal handler.
//! - Through a symlink, the link's target is replaced and the link is kept (what `cp` and
//!   shell redirection do), with the temp file beside the target.
//! - A device, FIFO or socket (`/dev/null`, `/dev/usb/lp0`, a pipe) is opened and written
//!   straight into: renaming a regular file over it would destroy it (and `/dev/null` for
//!   the whole system, when run as root). A failed write there is still an error.

use std::ffi::{OsStr, OsString};
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The longest file name most file systems take (ext4, XFS, btrfs, tmpfs: 255 bytes).
const NAME_MAX: usize = 255;

/// How many symlinks are followed to find the file behind a link (Linux's own limit).
const MAX_LINKS: usize = 40;

/// Writes a file atomically: `fill` writes into a temp file in the same folder, which is
/// renamed over `path` only on success; on failure no file is left behind. A device, FIFO
/// or socket is written straight through; a symlink's target is replaced.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_atomic_with(path, |out| fill(out).map_err(|e| Error::io(path, e)))
}

/// The register of temp files in progress that an interrupt handler empties: only with
/// the command line (feature `cli`), which installs that handler. A library user's process
/// keeps no such list; every temp file is still removed on every failure path by its
/// guard's `Drop`, panics included.
#[cfg(feature = "cli")]
mod register {
    use std::path::PathBuf;
    use std::sync::{Mutex, MutexGuard};

    /// Temp files of writes in progress. Held while a temp file is created, so an
    /// interrupt sees every file that exists.
    static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

    /// The register, locked.
    pub fn live() -> MutexGuard<'static, Vec<PathBuf>> {
        LIVE.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Without the command line there is no register: adding and removing do nothing.
#[cfg(not(feature = "cli"))]
mod register {
    use std::path::PathBuf;

    /// Stands in for the register's guard.
    pub struct Nothing;

    impl Nothing {
        pub fn push(&mut self, _: PathBuf) {}
        pub fn retain(&mut self, _: impl FnMut(&PathBuf) -> bool) {}
    }

    /// No register.
    pub fn live() -> Nothing {
        Nothing
    }
}

use register::live;

/// Removes the temp files of atomic writes still in progress. For an interrupt handler
/// that then exits: an interrupted run leaves no partial file.
#[cfg(feature = "cli")]
pub fn remove_temp_files() {
    for p in live().drain(..) {
        let _ = std::fs::remove_file(p);
    }
}

/// Removes the temp files of writes in progress and returns the register still locked: a
/// handler that exits while holding it knows no writer creates another temp file in
/// between.
#[cfg(feature = "cli")]
pub fn remove_temp_files_and_hold() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    let mut files = live();
    for p in files.drain(..) {
        let _ = std::fs::remove_file(p);
    }
    files
}

/// A temp file that removes itself unless it was renamed into place.
struct TempFile {
    path: PathBuf,
    armed: bool,
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let mut files = live();
        if self.armed {
            let _ = std::fs::remove_file(&self.path);
        }
        files.retain(|p| p != &self.path);
    }
}

/// An output being written: a temp file to be renamed into place by
/// [`commit`](OutputFile::commit), or a special file written straight through. Dropped
/// without `commit`, a temp file is removed.
pub struct OutputFile {
    out: BufWriter<Writeback>,
    /// The name in messages (what the user gave).
    name: PathBuf,
    /// `Some((temp, target))` for an atomic replace.
    temp: Option<(TempFile, PathBuf)>,
}

impl OutputFile {
    /// Opens `path` for writing: a temp file beside the regular file (or the symlink's
    /// target) it will replace, or the device, FIFO or socket itself.
    pub fn create(path: &Path) -> Result<OutputFile> {
        let io_err = |e| Error::io(path, e);
        let target = resolve_links(path).map_err(io_err)?;
        match std::fs::metadata(&target) {
            Ok(m) if m.is_dir() => {
                return Err(Error::io(
                    path,
                    std::io::Error::other("is a folder; give a file name"),
                ))
            }
            Ok(m) if !m.is_file() => {
                // A device, FIFO or socket: write into it, never replace it. No truncate
                // (meaningless there) and no create (it exists).
                let file = OpenOptions::new()
                    .write(true)
                    .open(&target)
                    .map_err(io_err)?;
                return Ok(OutputFile {
                    out: BufWriter::with_capacity(1 << 16, Writeback::straight(file)),
                    name: path.to_path_buf(),
                    temp: None,
                });
            }
            _ => {}
        }
        let name = target
            .file_name()
            .ok_or_else(|| Error::Invalid(format!("{}: not a file name", path.display())))?;
        let dir = match target.parent() {
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
        let (file, temp) = create_temp(dir, name).map_err(io_err)?;
        // The replaced file keeps its permissions (a new one gets the umask's).
        if let Ok(m) = std::fs::metadata(&target) {
            let _ = file.set_permissions(m.permissions());
        }
        Ok(OutputFile {
            out: BufWriter::with_capacity(1 << 16, Writeback::early(file)),
            name: path.to_path_buf(),
            temp: Some((temp, target)),
        })
    }

    /// Flushes and puts the file in place (renames the temp file over the target).
    pub fn commit(self) -> Result<()> {
        let name = self.name;
        let file = self
            .out
            .into_inner()
            .map_err(|e| Error::io(&name, e.into_error()))?
            .finish()
            .map_err(|e| Error::io(&name, e))?;
        // No fsync: the rename already makes the write all-or-nothing for every reader and
        // for a killed process; only a power cut before write-back is left (ext4's
        // auto_da_alloc covers rename over an existing file; a new file could then be found
        // empty). An fsync of a 3 MB A4 page measured 7–14 ms here, a fifth of the 50 ms
        // whole-run goal, and batch runs would pay it per file.
        // (On targets without files, File is a stub with nothing to drop.)
        #[cfg_attr(not(unix), allow(clippy::drop_non_drop))]
        drop(file);
        if let Some((mut temp, target)) = self.temp {
            std::fs::rename(&temp.path, &target).map_err(|e| Error::io(&name, e))?;
            temp.armed = false;
        }
        Ok(())
    }
}

/// A file being written that, for a temp file, reserves its disk space ahead of the data, a
/// [`PREALLOC_CHUNK`] at a time (`fallocate`), and gives back what was not used when it is
/// committed.
///
/// Why: renaming over an existing file makes ext4 allocate and submit every block the new
/// file still holds as delayed allocation, inside the `rename` call (its `auto_da_alloc`
/// guard against empty files after a crash). For a 72 MB RGB PPM that took about 32 ms at
/// the very end of the run, with nothing left to overlap it. Blocks reserved by `fallocate`
/// are not delayed, so the rename has nothing to do, and write-back happens later in the
/// kernel's own threads, as it does for a new file. Where the file system cannot reserve
/// space, this is skipped (it is advice; the data's own write errors are not ignored).
struct Writeback {
    file: File,
    /// Reserve space ahead (temp files only).
    early: bool,
    /// Bytes written so far.
    written: u64,
    /// Bytes reserved so far (the file's length while it is being written).
    reserved: u64,
}

/// How far ahead of the data a temp file's space is reserved.
#[cfg(target_os = "linux")]
const PREALLOC_CHUNK: u64 = 8 << 20;

impl Writeback {
    fn early(file: File) -> Writeback {
        Writeback {
            file,
            early: true,
            written: 0,
            reserved: 0,
        }
    }

    fn straight(file: File) -> Writeback {
        Writeback {
            early: false,
            ..Writeback::early(file)
        }
    }

    /// Reserves the next chunk; stops reserving when the file system says no.
    #[cfg(target_os = "linux")]
    fn reserve(&mut self) {
        use std::os::fd::AsRawFd;
        // SAFETY: a plain system call on an open descriptor; it reads no memory of ours.
        let r = unsafe {
            libc::fallocate(
                self.file.as_raw_fd(),
                0,
                self.reserved as libc::off_t,
                PREALLOC_CHUNK as libc::off_t,
            )
        };
        if r == 0 {
            self.reserved += PREALLOC_CHUNK;
        } else {
            self.early = false;
        }
    }

    #[cfg(not(target_os = "linux"))]
    fn reserve(&mut self) {
        self.early = false;
    }

    /// The file, cut to the bytes written (the reserved space past them given back).
    fn finish(self) -> std::io::Result<File> {
        if self.reserved > self.written {
            self.file.set_len(self.written)?;
        }
        Ok(self.file)
    }
}

impl Write for Writeback {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        while self.early && self.written + buf.len() as u64 > self.reserved {
            self.reserve();
        }
        let n = self.file.write(buf)?;
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.out.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.out.write_all(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// [`write_atomic`] with a `fill` that returns the library's errors.
pub(crate) fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<()>,
) -> Result<()> {
    let mut out = OutputFile::create(path)?;
    fill(&mut out)?;
    out.commit()
}

/// The file behind `path` after following symlinks (a dangling link gives the name it
/// points to, which is then created). `path` itself when it is not a link.
fn resolve_links(path: &Path) -> std::io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&p)?;
                p = match p.parent() {
                    Some(dir) if to.is_relative() => dir.join(to),
                    _ => to,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other("too many levels of symbolic links"))
}

/// The temp name for `name`: `.NAME.HOST.PID.N.tmp`, with NAME shortened (at a character
/// boundary when it is UTF-8) so the whole fits in [`NAME_MAX`] bytes; HOST, PID and N keep
/// it unique.
fn temp_name(name: &OsStr, n: u64) -> OsString {
    let suffix = format!(".{}.{}.{n}.tmp", this_host(), std::process::id());
    let room = NAME_MAX - 1 - suffix.len();
    let mut out = OsString::from(".");
    match name.to_str() {
        Some(s) => {
            let mut end = s.len().min(room);
            while !s.is_char_boundary(end) {
                end -= 1;
            }
            out.push(&s[..end]);
        }
        None => {
            #[cfg(unix)]
            {
                use std::os::unix::ffi::OsStrExt;
                let b = name.as_bytes();
                out.push(OsStr::from_bytes(&b[..b.len().min(room)]));
            }
            #[cfg(not(unix))]
            out.push("output");
        }
    }
    out.push(suffix);
    out
}

/// The longest host name kept in a temp name (Linux's `HOST_NAME_MAX`).
const HOST_MAX: usize = 64;

/// This machine's name as it appears in temp names: the host name with every character
/// other than ASCII letters, digits and `-` turned into `_` (so a temp name splits on its
/// dots unambiguously), at most [`HOST_MAX`] bytes; `unknown` when it cannot be read.
pub fn this_host() -> String {
    #[cfg_attr(not(unix), allow(unused_mut))]
    let mut buf = [0u8; HOST_MAX + 1];
    #[cfg(unix)]
    // SAFETY: gethostname writes at most `len` bytes into the buffer we own.
    let ok = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), HOST_MAX) } == 0;
    #[cfg(not(unix))]
    let ok = false;
    let len = buf.iter().position(|&b| b == 0).unwrap_or(HOST_MAX);
    let host: String = buf[..len]
        .iter()
        .map(|&b| {
            if b.is_ascii_alphanumeric() || b == b'-' {
                b as char
            } else {
                '_'
            }
        })
        .collect();
    if ok && !host.is_empty() {
        host
    } else {
        "unknown".into()
    }
}

/// The writer of a temp file, read from its name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TempWriter {
    /// The host name, as [`this_host`] spells it.
    pub host: String,
    /// The writing process's id on that host.
    pub pid: u32,
}

/// Reads the writer from a temp file name `.NAME.HOST.PID.N.tmp`; `None` for any other name.
pub fn parse_temp_name(file_name: &OsStr) -> Option<TempWriter> {
    let s = file_name.to_string_lossy();
    let rest = s.strip_prefix('.')?.strip_suffix(".tmp")?;
    let mut parts = rest.rsplitn(4, '.');
    let n = parts.next()?;
    let pid = parts.next()?;
    let host = parts.next()?;
    let name = parts.next()?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    let host_ok = !host.is_empty()
        && host
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if name.is_empty() || !digits(n) || !digits(pid) || !host_ok {
        return None;
    }
    Some(TempWriter {
        host: host.to_string(),
        pid: pid.parse().ok()?,
    })
}

/// Creates `.NAME.HOST.PID.N.tmp` in `dir`, a name no other writer uses.
fn create_temp(dir: &Path, name: &OsStr) -> std::io::Result<(File, TempFile)> {
    // N starts from a number of this call's own (the clock and the thread, through the
    // standard library's randomly keyed hasher), so parallel writers rarely meet; the
    // exclusive create settles any clash. No counter shared across the process.
    let mut n = {
        use std::hash::{BuildHasher, Hash, Hasher};
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
        h.write_u128(now.map_or(0, |d| d.as_nanos()));
        std::thread::current().id().hash(&mut h);
        h.finish() % 1_000_000
    };
    loop {
        n += 1;
        let path = dir.join(temp_name(name, n));
        // Created and registered under the lock: an interrupt handler holding it sees every
        // temp file that exists, and none is created after it ran.
        let mut files = live();
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(f) => {
                files.push(path.clone());
                return Ok((f, TempFile { path, armed: true }));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
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
    #[cfg(feature = "cli")]
    fn interrupt_cleanup_removes_temp_files_in_progress() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        write_atomic(&target, |w| {
            w.write_all(b"half")?;
            // What the signal handler does mid-write.
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

    #[test]
    fn temp_names_fit_the_longest_legal_name() {
        for len in [1, 200, 240, 250, 255] {
            let name = "é".repeat(len / 2) + &"a".repeat(len % 2);
            let t = temp_name(OsStr::new(&name), u64::MAX);
            assert!(t.len() <= NAME_MAX, "{len}: {}", t.len());
            assert!(t.to_str().unwrap().ends_with(".tmp"));
        }
        let t = temp_name(OsStr::new("x.pbm"), 7);
        let w = parse_temp_name(&t).expect("our own temp names parse");
        assert_eq!((w.host, w.pid), (this_host(), std::process::id()));
        for other in [
            "x.pbm",
            ".x.pbm.tmp",
            ".x.1.2.tmp",
            ".x.h.p.3.tmp",
            "..h.1.2.tmp",
        ] {
            assert_eq!(parse_temp_name(OsStr::new(other)), None, "{other}");
        }
        let dotted = parse_temp_name(OsStr::new(".a.b.c.node-1.42.0.tmp")).unwrap();
        assert_eq!((dotted.host.as_str(), dotted.pid), ("node-1", 42));
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("b".repeat(250) + ".pbm");
        write_atomic(&target, |w| w.write_all(b"P4")).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"P4");
    }

    #[cfg(unix)]
    #[test]
    fn symlink_target_is_replaced_and_the_link_kept() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("sub/real.bin");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(&real, b"old").unwrap();
        let link = dir.path().join("link.bin");
        std::os::unix::fs::symlink("sub/real.bin", &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"new")).unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
        // A dangling link creates its target.
        let dangling = dir.path().join("dangling.bin");
        std::os::unix::fs::symlink("sub/new.bin", &dangling).unwrap();
        write_atomic(&dangling, |w| w.write_all(b"made")).unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("sub/new.bin")).unwrap(),
            b"made"
        );
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_written_through_not_replaced() {
        write_atomic(Path::new("/dev/null"), |w| w.write_all(b"nothing")).unwrap();
        assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
        if Path::new("/dev/full").exists() {
            let e = write_atomic(Path::new("/dev/full"), |w| w.write_all(&[0; 1 << 17]))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("/dev/full: "), "{e}");
            assert!(!std::fs::metadata("/dev/full").unwrap().is_file());
        }
    }
}
