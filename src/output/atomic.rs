//! Crash-safe file replacement: readers see the old file or the new one, never a torn one.

use std::fs::{self, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Files written and their bytes, for the write phase's line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Written {
    pub files: usize,
    pub bytes: u64,
}

impl Written {
    /// One file of `bytes`.
    pub fn file(bytes: usize) -> Self {
        Written {
            files: 1,
            bytes: bytes as u64,
        }
    }
}

impl std::ops::Add for Written {
    type Output = Written;
    fn add(self, o: Written) -> Written {
        Written {
            files: self.files + o.files,
            bytes: self.bytes + o.bytes,
        }
    }
}

impl std::iter::Sum for Written {
    fn sum<I: Iterator<Item = Written>>(iter: I) -> Written {
        iter.fold(Written::default(), |a, b| a + b)
    }
}

/// Two threads of one process may write files at the same time (the pid alone would let them
/// share a temporary name), so each call also takes a number of its own.
static NEXT_TEMP: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` so that a crash at any moment leaves either the previous file or
/// the complete new one under that name.
///
/// The bytes go to a hidden temporary file in the same directory (`.{file}.tmp.{pid}.{n}`; same
/// directory so that the final rename stays on one file system and is atomic), which is flushed
/// to disk before it is renamed over `path`. On any error the temporary file is removed and the
/// error names `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let fail = |e: io::Error| {
        Error::Output(format!(
            "cannot write {}: {e}; check that the output directory is writable",
            path.display()
        ))
    };
    let file_name = path.file_name().ok_or_else(|| {
        fail(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path does not end in a file name",
        ))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(file_name);
    temp_name.push(format!(
        ".tmp.{}.{}",
        std::process::id(),
        NEXT_TEMP.fetch_add(1, Ordering::Relaxed)
    ));
    let temp = dir.join(temp_name);

    let result = write_then_rename(&temp, path, bytes);
    if result.is_err() {
        // Best effort: the original error is the one worth reporting, and a temporary that
        // was never created (missing directory) cannot be removed anyway.
        let _ = fs::remove_file(&temp);
    }
    result.map_err(fail)?;
    sync_dir(&dir);
    Ok(())
}

fn write_then_rename(temp: &Path, path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut file = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(temp)?;
    file.write_all(bytes)?;
    // Without this the rename can reach the disk before the data does, and a power cut
    // would leave an empty or partial file under the final name.
    file.sync_all()?;
    drop(file);
    fs::rename(temp, path)
}

/// A file that several processes fill at offsets of their own: created at its full length
/// under a hidden temporary name beside `path` (by one process), written at offsets
/// ([`SharedFile::write_at`], by each), then renamed over `path` ([`SharedFile::commit`],
/// by one), so that readers never see it half-written. `tag` is the same on every writer
/// and distinguishes concurrent jobs (the creating process's id).
pub struct SharedFile {
    pub path: PathBuf,
    pub temp: PathBuf,
}

impl SharedFile {
    pub fn new(path: &Path, tag: u64) -> Self {
        let name = path
            .file_name()
            .map_or_else(Default::default, |f| f.to_string_lossy().into_owned());
        let dir = path.parent().unwrap_or(Path::new("."));
        SharedFile {
            path: path.to_path_buf(),
            temp: dir.join(format!(".{name}.tmp.shared.{tag}")),
        }
    }

    fn fail(&self, e: io::Error) -> Error {
        Error::Output(format!(
            "cannot write {}: {e}; check that the output directory is writable (and, on several nodes, on a file system they share)",
            self.path.display()
        ))
    }

    /// Creates the temporary at `len` bytes (one process, before any `write_at`).
    pub fn create(&self, len: u64) -> Result<()> {
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&self.temp)
            .and_then(|f| f.set_len(len).map(|_| f));
        file.map(drop).map_err(|e| self.fail(e))
    }

    /// Writes `bytes` at `offset` and flushes them to disk.
    pub fn write_at(&self, offset: u64, bytes: &[u8]) -> Result<()> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileExt;
            let file = OpenOptions::new()
                .write(true)
                .open(&self.temp)
                .map_err(|e| self.fail(e))?;
            file.write_all_at(bytes, offset)
                .and_then(|_| file.sync_data())
                .map_err(|e| self.fail(e))
        }
        #[cfg(not(unix))]
        {
            let _ = (offset, bytes);
            Err(self.fail(io::Error::other("writes at offsets need a Unix system")))
        }
    }

    /// Renames the complete temporary over `path` (one process, after every `write_at`).
    pub fn commit(&self) -> Result<()> {
        fs::rename(&self.temp, &self.path).map_err(|e| self.fail(e))?;
        sync_dir(self.path.parent().unwrap_or(Path::new(".")));
        Ok(())
    }

    /// Removes the temporary after a failure (best effort: the failure is what matters).
    pub fn discard(&self) {
        let _ = fs::remove_file(&self.temp);
    }
}

/// Makes the rename itself durable. Failure is ignored: the file is already complete and
/// in place, and some file systems refuse to sync a directory.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_shared_file_filled_at_offsets_appears_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nodes.csv");
        let f = SharedFile::new(&path, 7);
        f.create(10).unwrap();
        // The pieces in any order, as ranks finish.
        f.write_at(6, b"ghij").unwrap();
        f.write_at(0, b"abcdef").unwrap();
        assert!(!path.exists());
        f.commit().unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"abcdefghij");
        assert_eq!(entries(dir.path()), ["nodes.csv"]);
        let g = SharedFile::new(&dir.path().join("missing/nodes.csv"), 7);
        let e = g.create(3).unwrap_err();
        assert_eq!(e.exit_code(), 5);
        assert!(e.to_string().contains("missing/nodes.csv"), "{e}");
    }

    #[test]
    fn writes_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("contact.csv");
        write_atomic(&path, b"x,y\n1,2\n").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"x,y\n1,2\n");
        assert_eq!(entries(dir.path()), vec!["contact.csv".to_string()]);
    }

    #[test]
    fn replaces_an_existing_file_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        fs::write(
            &path,
            "a much longer previous content that must not survive",
        )
        .unwrap();
        write_atomic(&path, b"{}").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"{}");
        assert_eq!(entries(dir.path()), vec!["summary.json".to_string()]);
    }

    #[test]
    fn missing_directory_is_an_output_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-such-dir").join("solution.pvtu");
        let err = write_atomic(&path, b"data").unwrap_err();
        let Error::Output(msg) = &err else {
            panic!("expected Error::Output, got {err:?}");
        };
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(
            msg.contains("check that the output directory is writable"),
            "{msg}"
        );
        assert_eq!(err.exit_code(), 5);
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn failed_rename_removes_the_temporary() {
        // A non-empty directory under the final name makes the rename fail after the
        // temporary has been written: the cleanup path, not just the open, is exercised.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("history.csv");
        fs::create_dir(&path).unwrap();
        fs::write(path.join("keep"), b"").unwrap();
        let err = write_atomic(&path, b"iteration\n").unwrap_err();
        assert!(matches!(err, Error::Output(_)), "{err:?}");
        assert_eq!(entries(dir.path()), vec!["history.csv".to_string()]);
        assert_eq!(entries(&path), vec!["keep".to_string()]);
    }

    #[test]
    fn path_without_file_name_is_an_output_error() {
        let err = write_atomic(Path::new("/"), b"").unwrap_err();
        assert!(matches!(err, Error::Output(_)), "{err:?}");
    }
}
