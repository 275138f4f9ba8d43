//! Atomic writing of report files, and how a missing value is written in them.
//!
//! A report file is either absent, or complete with the old contents, or complete with the new
//! contents — never truncated, even if the harness is killed mid-write: the bytes go to a
//! temporary file in the same directory, which is flushed to disk (`fsync`) and then renamed
//! over the target (an atomic replacement on POSIX file systems). The writer is the solver
//! crate's [`contact_damage::io::atomic`], the one of the VTU/PVD files too.
//!
//! A number without a value (e.g. the velocity error of a k-study, whose reference is discrete;
//! a rate between two levels where one error is zero) is carried as a non-finite `f64` and never
//! written as `NaN` or `inf`: it is `null` in JSON ([`finite_or_null`]) and [`MISSING`] (an em
//! dash) in CSV cells ([`finite_or_dash`]) and in the terminal tables.

use std::path::Path;

use serde::{Serialize, Serializer};

use crate::error::InputError;

/// How a missing value is written in CSV cells and terminal tables: an em dash.
pub const MISSING: &str = "—";

/// `Some(value)` if `value` is finite, `None` for NaN and ±∞ (a missing value).
pub fn finite(value: f64) -> Option<f64> {
    value.is_finite().then_some(value)
}

/// Serde `serialize_with` helper: a finite `f64` as a number, a non-finite one as `null` (in
/// JSON) — deliberately, rather than relying on `serde_json` mapping NaN to `null`.
pub fn finite_or_null<S: Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
    finite(*value).serialize(serializer)
}

/// Serde `serialize_with` helper for a sequence: every non-finite entry becomes `null`.
pub fn finite_or_null_each<S: Serializer>(
    values: &[f64],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(values.iter().map(|&value| finite(value)))
}

/// Serde `serialize_with` helper for CSV cells: a finite `f64` as a number, a non-finite one as
/// [`MISSING`].
pub fn finite_or_dash<S: Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
    match finite(*value) {
        Some(value) => serializer.serialize_f64(value),
        None => serializer.serialize_str(MISSING),
    }
}

/// `format(value)` if `value` is finite, else [`MISSING`] (for terminal tables).
pub fn format_or_dash(value: f64, format: impl Fn(f64) -> String) -> String {
    finite(value).map_or_else(|| MISSING.to_string(), format)
}

/// Write `bytes` to `path` atomically ([`contact_damage::io::atomic::write_atomic`]: a temporary
/// file in the same directory, synced, renamed over `path`). Missing parent directories are
/// created; the error names the path and the failed action.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), InputError> {
    if let Some(directory) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(directory)
            .map_err(|source| InputError::io("creating directory", directory, source))?;
    }
    contact_damage::io::atomic::write_atomic(path, |out| out.write_all(bytes)).map_err(|error| {
        InputError::Io {
            action: error.action,
            path: error.path,
            source: error.source,
        }
    })
}

/// Serialize `value` as pretty-printed JSON (with a final newline) and write it atomically.
pub fn write_json_atomic<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), InputError> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|error| InputError::Serialize {
        path: path.to_path_buf(),
        message: error.to_string(),
    })?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

/// Serialize `value` as compact JSON (no indentation, a final newline) and write it
/// atomically: for machine-read files with long arrays, such as a restart file, where the
/// indentation of [`write_json_atomic`] (one line per number) would double the size.
pub fn write_json_compact_atomic<T: serde::Serialize>(
    path: &Path,
    value: &T,
) -> Result<(), InputError> {
    let mut bytes = serde_json::to_vec(value).map_err(|error| InputError::Serialize {
        path: path.to_path_buf(),
        message: error.to_string(),
    })?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

/// Serialize `rows` as CSV (one record per row, header from the field names of the first row,
/// as the `csv` crate does for structs) and write it atomically.
///
/// An empty slice gives an empty file (there is no row to take the header from).
pub fn write_csv_atomic<R: serde::Serialize>(path: &Path, rows: &[R]) -> Result<(), InputError> {
    let serialize_error = |error: csv::Error| InputError::Serialize {
        path: path.to_path_buf(),
        message: error.to_string(),
    };
    let mut writer = csv::Writer::from_writer(Vec::new());
    for row in rows {
        writer.serialize(row).map_err(serialize_error)?;
    }
    let bytes = writer.into_inner().map_err(|error| InputError::Serialize {
        path: path.to_path_buf(),
        message: error.to_string(),
    })?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    fn entries(directory: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(directory)
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Row {
        level: usize,
        mesh_size: f64,
        error: f64,
    }

    #[test]
    fn bytes_round_trip_and_no_temporary_file_is_left() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("nested/deeper/report.txt");
        write_atomic(&path, b"hello\nworld\n").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"hello\nworld\n");
        assert_eq!(
            entries(&scratch.path().join("nested/deeper")),
            vec!["report.txt"]
        );
    }

    #[test]
    fn existing_file_is_replaced_whole() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("report.txt");
        write_atomic(&path, &[b'x'; 1000]).unwrap();
        write_atomic(&path, b"short").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"short");
        assert_eq!(entries(scratch.path()), vec!["report.txt"]);
    }

    #[test]
    fn json_round_trips_pretty_printed() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("report.json");
        let rows = vec![
            Row {
                level: 0,
                mesh_size: 0.5,
                error: 1.25e-2,
            },
            Row {
                level: 1,
                mesh_size: 0.25,
                error: 3.125e-3,
            },
        ];
        write_json_atomic(&path, &rows).unwrap();
        let text = fs::read_to_string(&path).unwrap();
        assert!(text.contains("\n  {"), "not pretty-printed: {text}");
        assert!(text.ends_with('\n'));
        let back: Vec<Row> = serde_json::from_str(&text).unwrap();
        assert_eq!(back, rows);
    }

    #[test]
    fn compact_json_round_trips_bitwise_on_one_line() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("state.json");
        // awkward values: the shortest round-trip form must give back the same bits
        let values = vec![0.1 + 0.2, -0.0, 5e-324, f64::MAX, 1.0 / 3.0, -2.5e-300];
        write_json_compact_atomic(&path, &values).unwrap();
        let text = fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 1, "not compact: {text}");
        assert!(text.ends_with('\n'));
        let back: Vec<f64> = serde_json::from_str(&text).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&values));
    }

    #[test]
    fn csv_round_trips_with_header() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("table.csv");
        let rows = vec![
            Row {
                level: 0,
                mesh_size: 0.5,
                error: 1.25e-2,
            },
            Row {
                level: 1,
                mesh_size: 0.25,
                error: 3.125e-3,
            },
        ];
        write_csv_atomic(&path, &rows).unwrap();
        let text = fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("level,mesh_size,error\n"), "{text}");
        let mut reader = csv::Reader::from_path(&path).unwrap();
        let back: Vec<Row> = reader.deserialize().map(|row| row.unwrap()).collect();
        assert_eq!(back, rows);
        assert_eq!(entries(scratch.path()), vec!["table.csv"]);
    }

    #[test]
    fn unwritable_path_gives_an_error_naming_it() {
        let scratch = tempfile::tempdir().unwrap();
        // A regular file where a directory is needed: the parent can never be created,
        // whatever the privileges of the user running the tests.
        let blocker = scratch.path().join("not-a-directory");
        fs::write(&blocker, b"").unwrap();
        let path = blocker.join("report.json");
        let error = write_json_atomic(&path, &[1, 2, 3]).unwrap_err();
        let message = error.to_string();
        assert!(
            message.contains(&blocker.display().to_string()),
            "error does not name the path: {message}"
        );
        assert!(matches!(error, InputError::Io { .. }));
    }

    #[derive(serde::Serialize)]
    struct CsvRow {
        #[serde(serialize_with = "finite_or_dash")]
        error: f64,
        count: usize,
    }

    #[test]
    fn a_missing_value_is_a_dash_in_csv() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("table.csv");
        let rows = [0.5, f64::NAN, f64::INFINITY].map(|error| CsvRow { error, count: 1 });
        write_csv_atomic(&path, &rows).unwrap();
        let text = fs::read_to_string(&path).unwrap();
        assert_eq!(text, "error,count\n0.5,1\n—,1\n—,1\n");
    }

    #[derive(serde::Serialize)]
    struct JsonRecord {
        #[serde(serialize_with = "finite_or_null")]
        rate: f64,
        #[serde(serialize_with = "finite_or_null_each")]
        rates: Vec<f64>,
    }

    #[test]
    fn a_missing_value_is_null_in_json() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("record.json");
        let records = [
            JsonRecord {
                rate: 0.25,
                rates: vec![],
            },
            JsonRecord {
                rate: f64::NAN,
                rates: vec![1.5, f64::NAN, f64::NEG_INFINITY],
            },
        ];
        write_json_atomic(&path, &records).unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(
            json,
            serde_json::json!([
                { "rate": 0.25, "rates": [] },
                { "rate": null, "rates": [1.5, null, null] }
            ])
        );
    }

    #[test]
    fn a_missing_value_is_a_dash_in_a_table() {
        assert_eq!(format_or_dash(f64::NAN, |v| format!("{v:.2}")), "—");
        assert_eq!(format_or_dash(f64::INFINITY, |v| format!("{v:.2}")), "—");
        assert_eq!(format_or_dash(1.0 / 3.0, |v| format!("{v:.2}")), "0.33");
    }

    #[test]
    fn path_without_file_name_is_an_error() {
        let error = write_atomic(Path::new("/"), b"x").unwrap_err();
        assert!(error.to_string().contains("no file name"), "{error}");
    }
}
