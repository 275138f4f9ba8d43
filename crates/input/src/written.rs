//! Which files of a folder a program wrote, so that it never replaces a file it did not write.
//!
//! After writing files into a folder, a program records their names and the SHA-256 of their
//! contents in [`RECORD`] in that folder (one `<hex>  <name>` line per file, the format of
//! `sha256sum`). Before it writes again, [`check_replaceable`] refuses every existing file of a
//! name it is about to write that is not recorded with its present contents: a file of the user,
//! or one of ours edited since. `--overwrite` lifts the refusal for exactly those names; files of
//! other names are never touched.

use crate::error::InputError;
use crate::output::write_atomic;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The record of the files written into a folder, in that folder.
pub const RECORD: &str = ".written.sha256";

fn digest_of(path: &Path) -> Result<String, InputError> {
    let bytes = std::fs::read(path).map_err(|e| InputError::io("reading", path, e))?;
    Ok(Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// The record of `dir`: name → SHA-256 (hex). An absent or unreadable record, or a line that
/// is not `<64 hex digits>  <name>`, records nothing.
fn read_record(dir: &Path) -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(dir.join(RECORD)).unwrap_or_default();
    text.lines()
        .filter_map(|line| {
            let (hex, name) = line.split_once("  ")?;
            let valid = hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_hexdigit());
            (valid && !name.is_empty()).then(|| (name.to_string(), hex.to_string()))
        })
        .collect()
}

/// Checks, before anything is computed, that the files `names` may be written into `dir`:
/// each is absent, or recorded in [`RECORD`] with its present contents, or `overwrite` is set.
/// The error names every file that would be replaced and `--overwrite`.
pub fn check_replaceable(dir: &Path, names: &[String], overwrite: bool) -> Result<(), InputError> {
    if overwrite {
        return Ok(());
    }
    let record = read_record(dir);
    let mut foreign = Vec::new();
    for name in names {
        let path = dir.join(name);
        match std::fs::symlink_metadata(&path) {
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => continue,
            Err(error) => return Err(InputError::io("inspecting", path, error)),
            Ok(meta) if meta.is_file() => {
                if record.get(name) == Some(&digest_of(&path)?) {
                    continue;
                }
            }
            Ok(_) => {}
        }
        foreign.push(format!("`{}`", path.display()));
    }
    if foreign.is_empty() {
        return Ok(());
    }
    let (verb, it) = if foreign.len() == 1 {
        ("was", "it")
    } else {
        ("were", "them")
    };
    Err(InputError::InvalidInput(format!(
        "{} {verb} not written by this program, or changed since: not replacing {it}; move {it} away, choose another folder, or replace {it} with --overwrite (which replaces only the names this command writes)",
        foreign.join(", "),
    )))
}

/// Records the files `written` (paths in `dir`) with their present contents in [`RECORD`],
/// keeping the entries of other names.
pub fn record(dir: &Path, written: &[PathBuf]) -> Result<(), InputError> {
    let mut record = read_record(dir);
    for path in written {
        if let Some(name) = path.file_name().and_then(|n| n.to_str()) {
            record.insert(name.to_string(), digest_of(&dir.join(name))?);
        }
    }
    let text: String = record
        .iter()
        .map(|(name, hex)| format!("{hex}  {name}\n"))
        .collect();
    write_atomic(&dir.join(RECORD), text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_recorded_unchanged_files_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let (dir, names) = (dir.path(), vec!["a.csv".to_string(), "b.md".to_string()]);
        check_replaceable(dir, &names, false).unwrap();
        std::fs::write(dir.join("a.csv"), "ours\n").unwrap();
        std::fs::write(dir.join("b.md"), "mine\n").unwrap();
        record(dir, &[dir.join("a.csv")]).unwrap();
        let error = check_replaceable(dir, &names, false)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("b.md`") && !error.contains("a.csv"),
            "{error}"
        );
        check_replaceable(dir, &names, true).unwrap();
        // ours, edited since: no longer ours
        std::fs::write(dir.join("a.csv"), "edited\n").unwrap();
        let error = check_replaceable(dir, &names[..1], false)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("a.csv`") && error.contains("--overwrite"),
            "{error}"
        );
        // a folder of that name is not replaced either
        std::fs::create_dir(dir.join("c")).unwrap();
        assert!(check_replaceable(dir, &["c".to_string()], false).is_err());
    }
}
