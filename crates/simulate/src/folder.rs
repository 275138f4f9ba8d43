//! The output folder of a run: which files in it are ours, and what a fresh run, `--overwrite`
//! and `--resume` may do with the others.
//!
//! The rule: **never delete or overwrite a file the program did not write, unless the user
//! said so.** A file counts as *ours* ([`is_output_file`]) exactly when its name is one that a
//! run writes (see [`crate::run`]):
//!
//! - `solution_NNNNNN.vtu`, `contact_NNNNNN.vtu`, `damage_NNNNNN.svg`, where `NNNNNN` is a step
//!   number of at least six decimal digits (so `solution_final.vtu` or `damage_map.svg` are
//!   *not* ours);
//! - `solution.pvd`, `contact.pvd`, `state.json`, `history.csv`, `contact_history.csv`,
//!   `contact_history.svg`;
//! - the temporaries of the atomic writers of these files, left behind by `kill -9` or a
//!   second Ctrl-C ([`is_stale_temporary`]): `.<name>.tmp.<pid>.<n>` (the one writer,
//!   `contact_damage::io::atomic`) and `.<name>.<pid>.<n>.tmp` (VTU/PVD files of earlier versions),
//!   `<name>` one of the names above and `<pid>`, `<n>` decimal numbers.
//!
//! What each mode does in the folder:
//!
//! - a **fresh run** (neither flag) refuses, before anything is computed or written, a folder
//!   that holds any file of ours — `state.json` with a hint to `--resume`, any other with its
//!   name — and a path that exists but is no folder; files of other names are left alone;
//! - **`--overwrite`** removes the files of ours (those of earlier runs, whatever their step
//!   numbers, and stale temporaries) after the problem has been built, and never touches a
//!   file of another name;
//! - **`--resume`** removes the stale temporaries (after the saved state has been checked
//!   against the problem) and keeps everything else.
//!
//! Both flags assume that no other run writes into the folder at the same time.

use crate::history::HISTORY_FILE;
use crate::pictures::{CONTACT_HISTORY_FILE, CONTACT_HISTORY_PICTURE};
use contact_input::InputError;
use std::path::{Path, PathBuf};

/// Name of the restart file.
pub const STATE_FILE: &str = "state.json";

/// The fixed names of the files of a run.
pub const FIXED_NAMES: [&str; 6] = [
    "solution.pvd",
    "contact.pvd",
    STATE_FILE,
    HISTORY_FILE,
    CONTACT_HISTORY_FILE,
    CONTACT_HISTORY_PICTURE,
];

/// Prefix and suffix of the per-step names (`solution_NNNNNN.vtu`, …).
const STEP_NAMES: [(&str, &str); 3] = [
    ("solution_", ".vtu"),
    ("contact_", ".vtu"),
    ("damage_", ".svg"),
];

fn is_number(text: &str) -> bool {
    !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit())
}

/// Whether `name` is the name of a file that a run writes (see the module documentation).
pub fn is_output_file(name: &str) -> bool {
    FIXED_NAMES.contains(&name)
        || STEP_NAMES.iter().any(|(prefix, suffix)| {
            name.strip_prefix(prefix)
                .and_then(|rest| rest.strip_suffix(suffix))
                .is_some_and(|step| step.len() >= 6 && is_number(step))
        })
}

/// Whether `name` is a temporary file of the atomic writers for one of our files:
/// `.<name>.<pid>.<n>.tmp` or `.<name>.tmp.<pid>.<n>` with [`is_output_file`]`(<name>)`.
pub fn is_stale_temporary(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.') else {
        return false;
    };
    // `.<name>.<pid>.<n>.tmp` (VTU/PVD files of earlier versions)
    if let Some(rest) = rest.strip_suffix(".tmp") {
        let mut parts = rest.rsplitn(3, '.');
        if let (Some(n), Some(pid), Some(target)) = (parts.next(), parts.next(), parts.next()) {
            if is_number(n) && is_number(pid) && is_output_file(target) {
                return true;
            }
        }
    }
    // `.<name>.tmp.<pid>.<n>` (contact_damage::io::atomic::write_atomic)
    let mut parts = rest.rsplitn(3, '.');
    if let (Some(n), Some(pid), Some(target)) = (parts.next(), parts.next(), parts.next()) {
        if let Some(target) = target.strip_suffix(".tmp") {
            return is_number(n) && is_number(pid) && is_output_file(target);
        }
    }
    false
}

/// The names in `dir` (sorted) that pass `keep`; an absent folder has none.
fn names_in(dir: &Path, keep: impl Fn(&str) -> bool) -> Result<Vec<String>, InputError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(error) => return Err(InputError::io("listing", dir, error)),
    };
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| InputError::io("listing", dir, e))?;
        // a name that is no UTF-8 is none of ours
        if let Ok(name) = entry.file_name().into_string() {
            if keep(&name) {
                names.push(name);
            }
        }
    }
    names.sort();
    Ok(names)
}

/// Checks, without touching anything, that a fresh run may write into `dir` (`what` says where
/// the folder comes from, e.g. `--out`): the path is a folder or absent, and unless
/// `overwrite` it holds no file of ours.
pub fn check_fresh(dir: &Path, what: &str, overwrite: bool) -> Result<(), InputError> {
    if dir.exists() && !dir.is_dir() {
        return Err(InputError::InvalidInput(format!(
            "output folder `{}` ({what}) exists and is not a folder; choose another --out",
            dir.display()
        )));
    }
    if overwrite {
        return Ok(());
    }
    if dir.join(STATE_FILE).exists() {
        return Err(InputError::InvalidInput(format!(
            "{} already holds a run ({STATE_FILE}): continue it with --resume or start afresh with --overwrite",
            dir.display()
        )));
    }
    let ours = names_in(dir, |name| is_output_file(name) || is_stale_temporary(name))?;
    if let Some(first) = ours.first() {
        return Err(InputError::InvalidInput(format!(
            "output folder `{}` ({what}) holds `{first}`{}, a file name this run writes, and no {STATE_FILE} of a run to continue: \
             not overwriting it; start afresh with --overwrite (which removes only such files) or choose another --out",
            dir.display(),
            match ours.len() {
                1 => String::new(),
                n => format!(" and {} more", n - 1),
            }
        )));
    }
    Ok(())
}

fn remove(dir: &Path, names: &[String]) -> Result<Vec<PathBuf>, InputError> {
    let mut removed = Vec::new();
    for name in names {
        let path = dir.join(name);
        match std::fs::remove_file(&path) {
            Ok(()) => removed.push(path),
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(error) => return Err(InputError::io("removing", path, error)),
        }
    }
    Ok(removed)
}

/// Removes every file of ours (outputs of earlier runs and stale temporaries) from `dir`;
/// returns their paths. Files of other names are kept.
pub fn remove_output(dir: &Path) -> Result<Vec<PathBuf>, InputError> {
    let names = names_in(dir, |name| is_output_file(name) || is_stale_temporary(name))?;
    remove(dir, &names)
}

/// Removes the stale temporaries ([`is_stale_temporary`]) from `dir`; returns their paths.
pub fn remove_stale_temporaries(dir: &Path) -> Result<Vec<PathBuf>, InputError> {
    let names = names_in(dir, is_stale_temporary)?;
    remove(dir, &names)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn our_names_are_exactly_the_names_a_run_writes() {
        for name in [
            "solution_000004.vtu",
            "contact_000012.vtu",
            "damage_000125.svg",
            "solution_1234567.vtu",
            "solution.pvd",
            "contact.pvd",
            "state.json",
            "history.csv",
            "contact_history.csv",
            "contact_history.svg",
        ] {
            assert!(is_output_file(name), "{name}");
        }
        for name in [
            "solution_final.vtu",
            "damage_map.svg",
            "solution_00004.vtu",
            "solution_000004.vtu.bak",
            "contact_00000a.vtu",
            "History.csv",
            "notes.txt",
            "state.json.orig",
            "solution_+00004.vtu",
        ] {
            assert!(!is_output_file(name), "{name}");
        }
    }

    #[test]
    fn stale_temporaries_are_those_of_our_writers_only() {
        for name in [
            ".solution_000004.vtu.4242.0.tmp",
            ".solution.pvd.17.3.tmp",
            ".history.csv.tmp.4242.7",
            ".state.json.tmp.1.0",
            ".damage_000006.svg.tmp.99.12",
        ] {
            assert!(is_stale_temporary(name), "{name}");
        }
        for name in [
            "solution_000004.vtu.4242.0.tmp",
            ".solution_final.vtu.4242.0.tmp",
            ".notes.txt.4242.0.tmp",
            ".solution_000004.vtu.tmp",
            ".solution_000004.vtu.x.0.tmp",
            ".history.csv.tmp.4242",
            ".history.csv.tmp..1",
            "my.tmp",
            ".tmp",
            ".history.csv.4242.0.tmp.bak",
        ] {
            assert!(!is_stale_temporary(name), "{name}");
        }
    }
}
