//! Input files are read only when they are regular files: a named pipe would block the program
//! until something writes to it, a device such as `/dev/zero` would be read until the memory
//! runs out, and a directory cannot be parsed. [`check_regular_file`] refuses them by name
//! before anything is opened for reading (symbolic links are followed: what they point to
//! must be a regular file).

use crate::error::InputError;
use std::path::Path;

/// What `path` is when it is not a regular file: "a directory", "a named pipe (FIFO)", …
fn kind_of(file_type: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

/// Checks that `path` (the `what` of the message: "problem file", "mesh", …) is a regular file,
/// without opening it: an error ([`InputError::InvalidInput`] naming the path and what it is)
/// for a directory, a named pipe, a device or a socket. A path that cannot be inspected (it
/// does not exist, …) passes: the read that follows reports that with its own words.
pub fn check_regular_file(path: &Path, what: &'static str) -> Result<(), InputError> {
    let Ok(metadata) = std::fs::metadata(path) else {
        return Ok(());
    };
    if metadata.is_file() {
        return Ok(());
    }
    Err(InputError::InvalidInput(format!(
        "{what} `{}` is {}: only regular files are read",
        path.display(),
        kind_of(metadata.file_type())
    )))
}

/// The bytes of the regular file `path` ([`check_regular_file`] first).
pub fn read_regular_file(path: &Path, what: &'static str) -> Result<Vec<u8>, InputError> {
    check_regular_file(path, what)?;
    std::fs::read(path).map_err(|e| InputError::io("reading", path, e))
}

/// The text of the regular file `path` ([`check_regular_file`] first).
pub fn read_regular_text(path: &Path, what: &'static str) -> Result<String, InputError> {
    check_regular_file(path, what)?;
    std::fs::read_to_string(path).map_err(|e| InputError::io("reading", path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_devices_and_pipes_are_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("regular-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let error = read_regular_text(&dir, "case file")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("is a directory") && error.contains("case file"),
            "{error}"
        );
        let error = read_regular_file(Path::new("/dev/zero"), "mesh")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("/dev/zero") && error.contains("character device"),
            "{error}"
        );
        let fifo = dir.join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        // refused before it is opened: no reader blocks waiting for a writer
        let error = read_regular_text(&fifo, "problem file")
            .unwrap_err()
            .to_string();
        assert!(error.contains("named pipe"), "{error}");
        let file = dir.join("plain.toml");
        std::fs::write(&file, "x = 1\n").unwrap();
        assert_eq!(read_regular_text(&file, "case file").unwrap(), "x = 1\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
