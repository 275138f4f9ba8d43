//! Tokens of the expression grammar (see the documentation of the `expr` module), the
//! tokenizer, and the parse error that it and the parser report.

/// Parse error: 1-based column (in characters) and what was expected or found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("column {column}: {message}")]
pub struct ExprError {
    /// 1-based column, counted in characters, of the offending token.
    pub column: usize,
    /// What was expected or found, e.g. "unknown variable `w` (known: x, y, z, t; ...)".
    pub message: String,
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum TokenKind {
    Number(f64),
    Name(String),
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    OpenParen,
    CloseParen,
    Comma,
    End,
}

#[derive(Debug, Clone)]
pub(super) struct Token {
    pub(super) kind: TokenKind,
    /// 0-based character index of the first character.
    pub(super) start: usize,
    /// 0-based character index one past the last character.
    pub(super) end: usize,
}

impl Token {
    pub(super) fn column(&self) -> usize {
        self.start + 1
    }
}

pub(super) fn tokenize(source: &str) -> Result<Vec<Token>, ExprError> {
    let chars: Vec<char> = source.chars().collect();
    let is_digit = |index: usize| chars.get(index).is_some_and(|c| c.is_ascii_digit());
    let mut tokens = Vec::new();
    let mut index = 0;
    while index < chars.len() {
        let character = chars[index];
        let start = index;
        if character.is_whitespace() {
            index += 1;
            continue;
        }
        let kind = if character.is_ascii_digit() || (character == '.' && is_digit(index + 1)) {
            while is_digit(index) {
                index += 1;
            }
            if chars.get(index) == Some(&'.') {
                index += 1;
                while is_digit(index) {
                    index += 1;
                }
            }
            // An exponent only if digits follow: `2e` is the number 2 followed by the name e.
            if matches!(chars.get(index), Some('e' | 'E')) {
                let signed = matches!(chars.get(index + 1), Some('+' | '-'));
                let first_digit = index + 1 + usize::from(signed);
                if is_digit(first_digit) {
                    index = first_digit;
                    while is_digit(index) {
                        index += 1;
                    }
                }
            }
            let text: String = chars[start..index].iter().collect();
            let value: f64 = text.parse().map_err(|_| ExprError {
                column: start + 1,
                message: format!("malformed number `{text}`"),
            })?;
            if !value.is_finite() {
                return Err(ExprError {
                    column: start + 1,
                    message: format!("number `{text}` is out of the range of f64"),
                });
            }
            TokenKind::Number(value)
        } else if character.is_ascii_alphabetic() || character == '_' {
            while chars
                .get(index)
                .is_some_and(|c| c.is_ascii_alphanumeric() || *c == '_')
            {
                index += 1;
            }
            TokenKind::Name(chars[start..index].iter().collect())
        } else {
            index += 1;
            match character {
                '+' => TokenKind::Plus,
                '-' => TokenKind::Minus,
                '*' => TokenKind::Star,
                '/' => TokenKind::Slash,
                '^' => TokenKind::Caret,
                '(' => TokenKind::OpenParen,
                ')' => TokenKind::CloseParen,
                ',' => TokenKind::Comma,
                other => {
                    let hint = match other {
                        '\u{2212}' | '\u{2013}' => " (use the ASCII minus `-`)",
                        '\u{00b7}' | '\u{00d7}' => " (use `*` for multiplication)",
                        '[' | ']' | '{' | '}' => " (use parentheses `(` `)`)",
                        _ => "",
                    };
                    return Err(ExprError {
                        column: start + 1,
                        message: format!("unexpected character `{other}`{hint}"),
                    });
                }
            }
        };
        tokens.push(Token {
            kind,
            start,
            end: index,
        });
    }
    tokens.push(Token {
        kind: TokenKind::End,
        start: chars.len(),
        end: chars.len(),
    });
    Ok(tokens)
}
