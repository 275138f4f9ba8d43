//! Reading the entries of an input file (case or problem file): TOML text into its tables, an
//! expression entry, a positive number. Every error is a [`InputError::File`] naming the file
//! kind (from the caller), the file, the key (or line and column) and the problem.

use std::collections::BTreeMap;

use crate::error::{FileKind, InputError};
use crate::expr::Expr;

/// Parses TOML text into `T`; a syntax error or a missing, unknown or mistyped key is an
/// [`InputError::File`] of the given `kind` naming `origin`, the line and column, and the
/// problem.
pub fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    kind: FileKind,
    origin: &str,
) -> Result<T, InputError> {
    toml::from_str::<T>(text).map_err(|e| {
        let (line, column) = e
            .span()
            .map(|span| {
                let before = &text[..span.start.min(text.len())];
                let line = before.matches('\n').count() + 1;
                let column = before.len() - before.rfind('\n').map_or(0, |p| p + 1) + 1;
                (line, column)
            })
            .unwrap_or((0, 0));
        kind.error(
            origin,
            &format!("line {line}, column {column}"),
            e.message().to_string(),
        )
    })
}

/// Parses the expression `source` of the entry `key` in the given `variables` and `constants`;
/// an error names the file, the key and the expression.
pub fn parse_expr(
    kind: FileKind,
    origin: &str,
    key: &str,
    source: &str,
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<Expr, InputError> {
    Expr::parse(source, variables, constants)
        .map_err(|e| kind.error(origin, key, format!("`{}`: {e}", excerpt(source, e.column))))
}

/// At most [`EXCERPT`] characters of `source` around the 1-based `column`, with `…` where text
/// was left out, so that an error in a long expression does not echo all of it.
fn excerpt(source: &str, column: usize) -> String {
    let characters: Vec<char> = source.chars().collect();
    if characters.len() <= EXCERPT {
        return source.to_string();
    }
    let centre = column.saturating_sub(1).min(characters.len());
    let start = centre.saturating_sub(EXCERPT / 2);
    let end = (start + EXCERPT).min(characters.len());
    let start = end.saturating_sub(EXCERPT);
    let mut text: String = characters[start..end].iter().collect();
    if start > 0 {
        text.insert(0, '…');
    }
    if end < characters.len() {
        text.push('…');
    }
    text
}

/// Length of the excerpt of an expression shown in an error.
const EXCERPT: usize = 80;

/// Checks that the entry `key` is a finite positive number.
pub fn positive(kind: FileKind, origin: &str, key: &str, value: f64) -> Result<(), InputError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(kind.error(
            origin,
            key,
            format!(
                "must be a positive number, got {}",
                crate::number::short(value)
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Table {
        steps: usize,
    }

    #[test]
    fn a_toml_error_names_the_kind_the_file_and_the_line() {
        let text = "steps = 2\nstep = 3\n";
        let error = parse_toml::<Table>(text, FileKind::Problem, "p.toml").unwrap_err();
        let message = error.to_string();
        assert!(
            message.starts_with("problem file `p.toml`, key `line 2, column 1`:")
                && message.contains("unknown field `step`"),
            "{message}"
        );
        let error = parse_toml::<Table>(text, FileKind::Case, "c.toml").unwrap_err();
        assert!(error.to_string().starts_with("case `c.toml`, key `line 2"));
    }

    #[test]
    fn an_expression_error_names_the_key_and_the_expression() {
        let constants = BTreeMap::new();
        let error = parse_expr(
            FileKind::Case,
            "c.toml",
            "exact.beta",
            "1 + q",
            &["x"],
            &constants,
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.starts_with("case `c.toml`, key `exact.beta`: `1 + q`:")
                && error.contains("unknown variable `q`"),
            "{error}"
        );
    }

    #[test]
    fn an_error_in_a_long_expression_shows_an_excerpt_around_the_column() {
        let constants = BTreeMap::new();
        let source = format!("{} + q", vec!["x"; 100_000].join(" * 1 + "));
        let error = parse_expr(
            FileKind::Case,
            "c.toml",
            "exact.beta",
            &source,
            &["x"],
            &constants,
        )
        .unwrap_err()
        .to_string();
        assert!(error.len() < 600, "{} characters: {error}", error.len());
        assert!(error.contains('…'), "{error}");
        assert!(error.contains("terms or factors in one chain"), "{error}");
    }

    #[test]
    fn positive_refuses_zero_negative_and_nan() {
        for value in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(positive(FileKind::Case, "c.toml", "final_time", value).is_err());
        }
        positive(FileKind::Case, "c.toml", "final_time", 0.5).unwrap();
    }
}
