//! The line reader shared by both encodings (section headers and footers, ASCII records) and
//! the locations and helpers of error messages.

use std::fmt;
use std::str::FromStr;

use crate::error::{Error, Result};

/// Where a record or a binary field lies in the file, for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Location {
    /// 1-based line number, in an ASCII file.
    Line(usize),
    /// 0-based byte offset from the start of a binary file, in a known section or between
    /// sections (None).
    Byte {
        section: Option<&'static str>,
        offset: usize,
    },
}

impl Location {
    /// The start of a message: `origin:line`, `origin: $Section at byte offset` or
    /// `origin: at byte offset`.
    fn prefix(self, origin: &str) -> String {
        match self {
            Location::Line(line) => format!("{origin}:{line}"),
            Location::Byte {
                section: Some(section),
                offset,
            } => format!("{origin}: {section} at byte {offset}"),
            Location::Byte {
                section: None,
                offset,
            } => format!("{origin}: at byte {offset}"),
        }
    }
}

impl fmt::Display for Location {
    /// `line 12` or `byte 1234`, for references to an earlier record.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, "line {line}"),
            Location::Byte { offset, .. } => write!(f, "byte {offset}"),
        }
    }
}

/// A non-blank line split into whitespace-separated fields (as bytes: only physical names
/// may hold text that is not ASCII).
pub(super) struct Record<'a> {
    pub(super) origin: &'a str,
    pub(super) location: Location,
    /// Byte offset of the start of the line.
    offset: usize,
    pub(super) text: &'a [u8],
    pub(super) fields: Vec<&'a [u8]>,
}

impl Record<'_> {
    /// The line, quoted and shortened for messages.
    pub(super) fn quoted(&self) -> String {
        format!("`{}`", shorten(&printable(self.text)))
    }

    /// Error at this line: expected …, found this line.
    pub(super) fn fail(&self, expected: impl fmt::Display) -> Error {
        fail(self.origin, self.location, expected, self.quoted())
    }

    /// Error at this line with a custom "found" part.
    pub(super) fn fail_with(&self, expected: impl fmt::Display, found: impl fmt::Display) -> Error {
        fail(self.origin, self.location, expected, found)
    }

    /// Requires exactly `count` fields.
    pub(super) fn expect_fields(&self, count: usize, what: &str) -> Result<()> {
        if self.fields.len() == count {
            Ok(())
        } else {
            Err(self.fail_with(
                format!("{what} ({count} fields)"),
                format!(
                    "{} ({} field{})",
                    self.quoted(),
                    self.fields.len(),
                    if self.fields.len() == 1 { "" } else { "s" }
                ),
            ))
        }
    }

    /// Parses field `index` (0-based) as a `T`, `what` describing it.
    pub(super) fn parse<T: FromStr>(&self, index: usize, what: &str) -> Result<T> {
        let Some(field) = self.fields.get(index) else {
            return Err(self.fail(format!("{what} as field {}", index + 1)));
        };
        let value = std::str::from_utf8(field)
            .ok()
            .and_then(|text| text.parse().ok());
        value.ok_or_else(|| {
            self.fail_with(
                format!("{what} as field {}", index + 1),
                format!("`{}` in {}", shorten(&printable(field)), self.quoted()),
            )
        })
    }

    /// Parses field `index` as a finite coordinate.
    pub(super) fn coordinate(&self, index: usize, what: &str) -> Result<f64> {
        let value: f64 = self.parse(index, what)?;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.fail_with(
                format!("{what} (finite) as field {}", index + 1),
                format!("{value} in {}", self.quoted()),
            ))
        }
    }
}

/// Reader of the lines of an ASCII or binary file, and of the binary sections through a
/// [`Cursor`](super::binary::Cursor). Keeps the byte offset of the next unread byte and the
/// 1-based number of the last line read (meaningful in ASCII files only).
pub(super) struct Reader<'a> {
    pub(super) origin: &'a str,
    pub(super) bytes: &'a [u8],
    pub(super) position: usize,
    line: usize,
    /// File-type 1: records are located by byte offset, and sections are read by a cursor.
    pub(super) binary: bool,
    /// The known section being read, for locations in binary files.
    pub(super) section: Option<&'static str>,
}

impl<'a> Reader<'a> {
    pub(super) fn new(origin: &'a str, bytes: &'a [u8]) -> Self {
        Reader {
            origin,
            bytes,
            position: 0,
            line: 0,
            binary: false,
            section: None,
        }
    }

    /// The location of the line starting at byte `offset`: that offset in a binary file, the
    /// last line read in an ASCII file.
    pub(super) fn location(&self, offset: usize) -> Location {
        if self.binary {
            Location::Byte {
                section: self.section,
                offset,
            }
        } else {
            Location::Line(self.line)
        }
    }

    /// The location of the end of the file.
    pub(super) fn end_location(&self) -> Location {
        if self.binary {
            Location::Byte {
                section: self.section,
                offset: self.bytes.len(),
            }
        } else {
            Location::Line(self.line + 1)
        }
    }

    /// The record, located again after a change of section or of file-type.
    pub(super) fn relocate(&self, record: Record<'a>) -> Record<'a> {
        if self.binary {
            Record {
                location: self.location(record.offset),
                ..record
            }
        } else {
            record
        }
    }

    /// The next line (without its `\n`) and the offset of its start, or None at the end.
    pub(super) fn next_line(&mut self) -> Option<(usize, &'a [u8])> {
        let start = self.position;
        let rest = self.bytes.get(start..).filter(|rest| !rest.is_empty())?;
        let (line, consumed) = match rest.iter().position(|&byte| byte == b'\n') {
            Some(end) => (&rest[..end], end + 1),
            None => (rest, rest.len()),
        };
        self.position += consumed;
        self.line += 1;
        Some((start, line))
    }

    /// The next non-blank line, or None at the end of the file.
    pub(super) fn next_record(&mut self) -> Option<Record<'a>> {
        while let Some((offset, line)) = self.next_line() {
            let text = line.trim_ascii();
            if !text.is_empty() {
                return Some(Record {
                    origin: self.origin,
                    location: self.location(offset),
                    offset,
                    text,
                    fields: text
                        .split(u8::is_ascii_whitespace)
                        .filter(|field| !field.is_empty())
                        .collect(),
                });
            }
        }
        None
    }

    /// The next non-blank line; at the end of the file an error expecting `expected`.
    pub(super) fn expect_record(&mut self, expected: impl fmt::Display) -> Result<Record<'a>> {
        match self.next_record() {
            Some(record) => Ok(record),
            None => Err(fail(
                self.origin,
                self.end_location(),
                expected,
                "end of file",
            )),
        }
    }

    /// Requires the line `$End<section>` (after the `\n` that ends a binary section).
    pub(super) fn expect_end(&mut self, section: &str) -> Result<()> {
        let end = format!("$End{section}");
        let record = self.expect_record(format!("`{end}`"))?;
        if record.text == end.as_bytes() {
            Ok(())
        } else {
            Err(record.fail(format!("`{end}`")))
        }
    }
}

/// `origin:line: expected …, found …` (or `origin: $Section at byte offset: …`).
pub(super) fn fail(
    origin: &str,
    location: Location,
    expected: impl fmt::Display,
    found: impl fmt::Display,
) -> Error {
    Error::InvalidMesh(format!(
        "{}: expected {expected}, found {found}",
        location.prefix(origin)
    ))
}

/// `bytes` as text for messages: invalid UTF-8 replaced by U+FFFD, control characters (as
/// found in binary data) escaped.
pub(super) fn printable(bytes: &[u8]) -> String {
    let mut text = String::new();
    for character in String::from_utf8_lossy(bytes).chars() {
        if character.is_control() {
            text.extend(character.escape_default());
        } else {
            text.push(character);
        }
    }
    text
}

/// At most 80 characters of `text` (cut at a character boundary).
pub(super) fn shorten(text: &str) -> String {
    match text.char_indices().nth(77) {
        Some((cut, _)) if text.chars().count() > 80 => format!("{}…", &text[..cut]),
        _ => text.to_string(),
    }
}
