//! Sending a job's bytes to its queue's backend: a folder (one file a job, written
//! atomically), a device file (written straight) or an AppSocket printer (TCP port 9100).

use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::time::Duration;

use super::config::Backend;
use crate::error::{Error, Result};

/// How long a socket printer may take to accept a connection or a write.
const SOCKET_TIMEOUT: Duration = Duration::from_secs(30);

impl Backend {
    /// Delivers one job's bytes; `file_name` names the file in a folder backend (the
    /// job's number and the format's extension). Returns where the bytes went.
    pub fn deliver(&self, bytes: &[u8], file_name: &str) -> Result<String> {
        match self {
            Backend::Folder(dir) => {
                let path = dir.join(file_name);
                crate::io::write_atomic(&path, |w| w.write_all(bytes))?;
                Ok(path.display().to_string())
            }
            Backend::Device(path) => {
                let mut f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(|e| Error::io(path, e))?;
                f.write_all(bytes)
                    .and_then(|_| f.flush())
                    .map_err(|e| Error::io(path, e))?;
                Ok(path.display().to_string())
            }
            Backend::Socket(addr) => {
                let name = PathBuf::from(format!("socket://{addr}"));
                let io = |e| Error::io(&name, e);
                let target = addr
                    .to_socket_addrs()
                    .map_err(io)?
                    .next()
                    .ok_or_else(|| Error::Invalid(format!("socket://{addr}: no address")))?;
                let mut s = TcpStream::connect_timeout(&target, SOCKET_TIMEOUT).map_err(io)?;
                s.set_write_timeout(Some(SOCKET_TIMEOUT)).map_err(io)?;
                s.write_all(bytes).and_then(|_| s.flush()).map_err(io)?;
                let _ = s.shutdown(std::net::Shutdown::Write);
                Ok(format!("socket://{addr}"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_gets_one_file_a_job_and_a_socket_the_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let b = Backend::Folder(dir.path().to_path_buf());
        b.deliver(b"abc", "job-1.escpos").unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("job-1.escpos")).unwrap(),
            b"abc"
        );

        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let t = std::thread::spawn(move || {
            let (mut c, _) = listener.accept().unwrap();
            let mut got = Vec::new();
            std::io::Read::read_to_end(&mut c, &mut got).unwrap();
            got
        });
        Backend::Socket(addr.to_string())
            .deliver(b"\x1b@hello", "x")
            .unwrap();
        assert_eq!(t.join().unwrap(), b"\x1b@hello");

        let missing = Backend::Device(dir.path().join("no/such/lp0"));
        assert!(missing
            .deliver(b"x", "x")
            .unwrap_err()
            .to_string()
            .contains("lp0"));
    }
}
