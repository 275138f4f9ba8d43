//! Atomic file writing, the one writer of every output file of the workspace (VTU/PVD here, the
//! reports of `verify` and the files of `simulate` through `contact-input`).
//!
//! A file is either absent, or complete with the old contents, or complete with the new
//! contents — never truncated, even if the program is killed mid-write: the bytes go to a
//! temporary file `.<name>.tmp.<pid>.<n>` in the same directory, which is flushed to disk
//! (`fsync`) and then renamed over the target (an atomic replacement on POSIX file systems).

use std::ffi::{OsStr, OsString};
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A failed atomic write: which action failed on which path.
#[derive(Debug, thiserror::Error)]
#[error("{action} `{path}`: {source}", path = path.display())]
pub struct WriteError {
    /// What was being done: "creating directory", "writing temporary file", "replacing", ...
    pub action: &'static str,
    /// The file or directory the action was on.
    pub path: PathBuf,
    /// The underlying error.
    #[source]
    pub source: io::Error,
}

/// Distinguishes temporary files of concurrent writers within one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes the file `path` atomically with the contents that `write` produces: into a temporary
/// file in the same directory (buffered), `fsync` it, rename it over `path`, then `fsync` the
/// directory (best effort).
///
/// The directory must exist (it is not created). On failure the temporary file is removed and
/// the error names the path and the failed action.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), WriteError> {
    let file_name = path.file_name().ok_or_else(|| {
        failed("writing", path)(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path has no file name",
        ))
    })?;
    let directory = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let (temp_path, temp_file) = create_temp_file(&directory, file_name)?;
    let written = (|| {
        let mut out = BufWriter::new(temp_file);
        write(&mut out)?;
        out.into_inner()
            .map_err(io::IntoInnerError::into_error)?
            .sync_all()
    })()
    .map_err(failed("writing temporary file", &temp_path));
    if let Err(error) = written {
        let _ = fs::remove_file(&temp_path);
        return Err(error);
    }
    if let Err(source) = fs::rename(&temp_path, path) {
        let _ = fs::remove_file(&temp_path);
        return Err(failed("replacing", path)(source));
    }
    sync_directory(&directory);
    Ok(())
}

/// The error of `action` on `path`, for `map_err`.
fn failed(action: &'static str, path: &Path) -> impl FnOnce(io::Error) -> WriteError {
    let path = path.to_path_buf();
    move |source| WriteError {
        action,
        path,
        source,
    }
}

/// Create a new, empty temporary file `.<file_name>.tmp.<pid>.<n>` in `directory`
/// (exclusive creation, so two writers never share a temporary file).
fn create_temp_file(directory: &Path, file_name: &OsStr) -> Result<(PathBuf, File), WriteError> {
    let process = std::process::id();
    loop {
        let serial = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut temp_name = OsString::from(".");
        temp_name.push(file_name);
        temp_name.push(format!(".tmp.{process}.{serial}"));
        let temp_path = directory.join(temp_name);
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp_path)
        {
            Ok(file) => return Ok((temp_path, file)),
            Err(error) if error.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(source) => {
                return Err(WriteError {
                    action: "creating temporary file",
                    path: temp_path,
                    source,
                })
            }
        }
    }
}

/// Flush the directory entry of a rename to disk. Best effort: not every platform or file
/// system supports syncing a directory, and the data file itself is already synced.
fn sync_directory(directory: &Path) {
    if let Ok(handle) = File::open(directory) {
        let _ = handle.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_writer_leaves_the_old_file_and_no_temporary_file() {
        let directory = std::env::temp_dir().join(format!("atomic-test-{}", std::process::id()));
        let _ = fs::remove_dir_all(&directory);
        let path = directory.join("out.txt");
        fs::create_dir_all(&directory).unwrap();
        write_atomic(&path, |out| out.write_all(b"old")).unwrap();
        let error = write_atomic(&path, |out| {
            out.write_all(b"partial")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert_eq!(error.action, "writing temporary file");
        assert!(error.to_string().contains("disk full"), "{error}");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        let names: Vec<_> = fs::read_dir(&directory)
            .unwrap()
            .map(|entry| entry.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![OsString::from("out.txt")]);
        let missing = directory.join("no/such/dir/out.txt");
        let error = write_atomic(&missing, |out| out.write_all(b"x")).unwrap_err();
        assert_eq!(error.action, "creating temporary file");
        fs::remove_dir_all(&directory).unwrap();
    }
}
