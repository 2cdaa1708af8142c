//! The spool: every acknowledged job on disk until it ends, so that a server killed with jobs
//! queued prints each of them once when it comes back.
//!
//! A job is one file, `job-ID.ipp`: a short text header (the job's number, its queue, when
//! it was created) followed by the job-creating request exactly as it came (its IPP
//! attributes: name, user, copies, options, page ranges and overrides; they are mapped
//! again through the queue's options when the job is read back) and then the document. It is
//! written to `job-ID.tmp`, fsync'd, renamed to `job-ID.ipp` and the folder fsync'd,
//! all before the Print-Job or Send-Document response is sent. When the job ends
//! (delivered, cancelled or aborted) the file is unlinked and the folder fsync'd: one atomic
//! step. A `next-id` file holds the first job number not yet handed out (reserved in blocks
//! of [`ID_BLOCK`]), so numbers continue across restarts and none is used twice.
//!
//! What a spool file holds is bounded by the server's limits: the request limit bounds each
//! file, the job limit their number.

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Job numbers are reserved this many at a time (one write of `next-id` per block).
pub const ID_BLOCK: i32 = 64;

const MAGIC: &str = "halftone-spool 1";

/// A spool folder, held by one server at a time (an exclusive lock on its `lock` file
/// while the value lives).
#[derive(Debug)]
pub struct Spool {
    dir: PathBuf,
    _lock: File,
}

/// One spooled job as read back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// Its number (job-id).
    pub id: i32,
    /// Its queue's name.
    pub queue: String,
    /// When it was created, in seconds since the Unix epoch.
    pub created: u64,
    /// The job-creating request up to the end of its attributes (IPP encoding).
    pub request: Vec<u8>,
    /// The document.
    pub document: Vec<u8>,
}

/// What a spool folder holds: the next job number and the jobs, oldest first.
#[derive(Debug, Default)]
pub struct Contents {
    /// The first job number never handed out.
    pub next_id: i32,
    /// The spooled jobs, by number.
    pub jobs: Vec<Entry>,
    /// Files that could not be read back, each one line (set aside as `job-ID.bad`).
    pub problems: Vec<String>,
}

impl Spool {
    /// Opens (creating it, mode 0700 on Unix) the spool folder `dir`; an error if another
    /// server holds it.
    pub fn open(dir: &Path) -> Result<Spool> {
        fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = fs::set_permissions(dir, fs::Permissions::from_mode(0o700));
        }
        let meta = fs::metadata(dir).map_err(|e| Error::io(dir, e))?;
        if !meta.is_dir() {
            return Err(Error::Invalid(format!(
                "{}: the spool is not a folder",
                dir.display()
            )));
        }
        let lock_path = dir.join("lock");
        let lock = fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(|e| Error::io(&lock_path, e))?;
        #[cfg(unix)]
        {
            use std::os::unix::io::AsRawFd;
            // SAFETY: flock on a descriptor this function owns; no memory is involved.
            if unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
                return Err(Error::Invalid(format!(
                    "{}: the spool is in use by another server",
                    dir.display()
                )));
            }
        }
        Ok(Spool {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn path(&self, id: i32, ext: &str) -> PathBuf {
        self.dir.join(format!("job-{id}.{ext}"))
    }

    /// Makes the folder's entries (creations, renames, removals) durable.
    fn sync_dir(&self) -> Result<()> {
        File::open(&self.dir)
            .and_then(|d| d.sync_all())
            .map_err(|e| Error::io(&self.dir, e))
    }

    /// Reads the folder: the next job number and every spooled job; temporary files of
    /// writes that never finished (jobs never acknowledged) are removed, and files that
    /// cannot be read back are renamed `job-ID.bad` and named in `problems`.
    pub fn load(&self, max_file: u64) -> Result<Contents> {
        let mut c = Contents {
            next_id: 1,
            ..Contents::default()
        };
        let counter = self.dir.join("next-id");
        match fs::read_to_string(&counter) {
            Ok(t) => match t.trim().parse::<i32>() {
                Ok(n) if n >= 1 => c.next_id = n,
                _ => c.problems.push(format!(
                    "{}: not a job number; numbering goes on after the spooled jobs",
                    counter.display()
                )),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&counter, e)),
        }
        let list = fs::read_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        for item in list {
            let item = item.map_err(|e| Error::io(&self.dir, e))?;
            let name = item.file_name();
            let name = name.to_string_lossy();
            let Some((id, ext)) = name
                .strip_prefix("job-")
                .and_then(|r| r.split_once('.'))
                .and_then(|(n, ext)| n.parse::<i32>().ok().map(|n| (n, ext)))
            else {
                continue;
            };
            let path = item.path();
            match ext {
                "tmp" => {
                    let _ = fs::remove_file(&path);
                }
                "ipp" => match read_entry(&path, id, max_file) {
                    Ok(e) => c.jobs.push(e),
                    Err(why) => {
                        c.problems.push(format!(
                            "{}: {why}; set aside as job-{id}.bad",
                            path.display()
                        ));
                        let _ = fs::rename(&path, self.path(id, "bad"));
                    }
                },
                _ => {}
            }
            // A number is never handed out twice, even one whose file was set aside.
            c.next_id = c.next_id.max(id.saturating_add(1));
        }
        c.jobs.sort_by_key(|e| e.id);
        Ok(c)
    }

    /// Writes `next-id` = `next` durably (a temporary file, fsync, rename, fsync of the folder).
    pub fn reserve_ids(&self, next: i32) -> Result<()> {
        let tmp = self.dir.join("next-id.tmp");
        let path = self.dir.join("next-id");
        write_synced(&tmp, &[format!("{next}\n").as_bytes()])?;
        fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))?;
        self.sync_dir()
    }

    /// Spools a job durably: its file is complete and on disk, under its final name, when
    /// this returns.
    pub fn write(&self, e: &Entry) -> Result<()> {
        self.write_parts(e.id, &e.queue, e.created, &e.request, &e.document)
    }

    /// As [`Spool::write`], from the parts of an entry.
    pub fn write_parts(
        &self,
        id: i32,
        queue: &str,
        created: u64,
        request: &[u8],
        document: &[u8],
    ) -> Result<()> {
        let e = Entry {
            id,
            queue: queue.to_string(),
            created,
            request: Vec::new(),
            document: Vec::new(),
        };
        let tmp = self.path(e.id, "tmp");
        let path = self.path(e.id, "ipp");
        let head = format!(
            "{MAGIC}\nid {}\nqueue {}\ncreated {}\nrequest {}\ndocument {}\n\n",
            e.id,
            e.queue,
            e.created,
            request.len(),
            document.len()
        );
        let written = write_synced(&tmp, &[head.as_bytes(), request, document])
            .and_then(|_| fs::rename(&tmp, &path).map_err(|err| Error::io(&path, err)))
            .and_then(|_| self.sync_dir());
        if written.is_err() {
            let _ = fs::remove_file(&tmp);
        }
        written
    }

    /// Removes job `id`'s file (the job has ended), durably; a job not spooled is no error.
    pub fn remove(&self, id: i32) -> Result<()> {
        let path = self.path(id, "ipp");
        match fs::remove_file(&path) {
            Ok(()) => self.sync_dir(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(Error::io(&path, e)),
        }
    }
}

/// Writes `parts` to a new file at `path` and fsyncs it.
fn write_synced(path: &Path, parts: &[&[u8]]) -> Result<()> {
    let io = |e| Error::io(path, e);
    let mut f = File::create(path).map_err(io)?;
    for p in parts {
        f.write_all(p).map_err(io)?;
    }
    f.sync_all().map_err(io)
}

/// Reads one spool file back; the error says what is wrong with it.
fn read_entry(path: &Path, id: i32, max_file: u64) -> std::result::Result<Entry, String> {
    let size = fs::metadata(path).map_err(|e| e.to_string())?.len();
    if size > max_file {
        return Err(format!("{size} bytes, over the limit of {max_file}"));
    }
    let bytes = fs::read(path).map_err(|e| e.to_string())?;
    let end = bytes
        .windows(2)
        .position(|w| w == b"\n\n")
        .ok_or("no header")?;
    let head = std::str::from_utf8(&bytes[..end]).map_err(|_| "header is not text")?;
    let mut lines = head.lines();
    if lines.next() != Some(MAGIC) {
        return Err("not a spool file of this version".into());
    }
    let mut field = |key: &str| -> std::result::Result<String, String> {
        lines
            .next()
            .and_then(|l| l.strip_prefix(key))
            .and_then(|v| v.strip_prefix(' '))
            .map(str::to_string)
            .ok_or_else(|| format!("no `{key}` line"))
    };
    let number = |v: String| v.parse::<u64>().map_err(|_| format!("bad number {v}"));
    let file_id = field("id")?;
    if file_id != id.to_string() {
        return Err(format!("holds job {file_id}"));
    }
    let queue = field("queue")?;
    let created = number(field("created")?)?;
    let request = number(field("request")?)? as usize;
    let document = number(field("document")?)? as usize;
    let body = &bytes[end + 2..];
    if body.len() != request.saturating_add(document) {
        return Err(format!(
            "truncated: {} bytes after the header, {} expected",
            body.len(),
            request.saturating_add(document)
        ));
    }
    Ok(Entry {
        id,
        queue,
        created,
        request: body[..request].to_vec(),
        document: body[request..].to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(id: i32) -> Entry {
        Entry {
            id,
            queue: "receipt".into(),
            created: 1_700_000_000,
            request: vec![2, 0, 0, 2, 0, 0, 0, 1, 3],
            document: format!("document {id}\n\nwith a blank line").into_bytes(),
        }
    }

    #[test]
    fn jobs_come_back_until_removed_and_numbers_go_on() {
        let dir = tempfile::tempdir().unwrap();
        let s = Spool::open(&dir.path().join("spool")).unwrap();
        let empty = s.load(1 << 20).unwrap();
        assert_eq!((empty.next_id, empty.jobs.len()), (1, 0));
        s.reserve_ids(1 + ID_BLOCK).unwrap();
        for id in [3, 1, 2] {
            s.write(&entry(id)).unwrap();
        }
        s.remove(2).unwrap();
        s.remove(2).unwrap();
        // A write that never finished: the job was never acknowledged.
        fs::write(s.dir().join("job-9.tmp"), b"half").unwrap();
        let c = s.load(1 << 20).unwrap();
        assert_eq!(c.jobs, vec![entry(1), entry(3)]);
        assert_eq!(c.next_id, 1 + ID_BLOCK);
        assert!(c.problems.is_empty(), "{:?}", c.problems);
        assert!(!s.dir().join("job-9.tmp").exists());

        // A number above the counter (the counter lost): numbering goes on after it.
        s.write(&entry(200)).unwrap();
        assert_eq!(s.load(1 << 20).unwrap().next_id, 201);

        // One server a spool.
        let again = Spool::open(s.dir()).unwrap_err().to_string();
        assert!(again.contains("in use by another server"), "{again}");
        drop(s);
        Spool::open(&dir.path().join("spool")).unwrap();
    }

    #[test]
    fn damaged_files_are_set_aside_with_one_line() {
        let dir = tempfile::tempdir().unwrap();
        let s = Spool::open(dir.path()).unwrap();
        s.write(&entry(4)).unwrap();
        let path = s.dir().join("job-4.ipp");
        let full = fs::read(&path).unwrap();
        fs::write(&path, &full[..full.len() - 3]).unwrap();
        fs::write(s.dir().join("job-5.ipp"), b"junk").unwrap();
        s.write(&entry(6)).unwrap();
        let c = s.load(1 << 20).unwrap();
        assert_eq!(c.jobs, vec![entry(6)]);
        assert_eq!(c.problems.len(), 2, "{:?}", c.problems);
        assert!(c.problems.iter().all(|p| !p.contains('\n')));
        assert!(c.problems.iter().any(|p| p.contains("truncated")));
        assert!(s.dir().join("job-4.bad").exists());
        assert_eq!(c.next_id, 7);
        // Over the size limit: set aside too, never read whole.
        let c = s.load(10).unwrap();
        assert!(c.jobs.is_empty());
    }
}
