//! Hostile edits of an input file's text, for the robustness tests of the parsers.
//!
//! The tests of `verify` and `simulate` draw edits with proptest and check that reading the
//! edited case or problem file gives `Ok` or an error, never a panic, an abort or a hang. An
//! edit is `(kind, position, choice)`: `position ∈ [0, 1)` picks the place in the text, `choice`
//! the replacement where there is one.

/// Numbers that break naive code: zero, signs, extremes, non-finite spellings, huge counts.
pub const HOSTILE_NUMBERS: [&str; 14] = [
    "0",
    "-1",
    "1e300",
    "-1e-300",
    "nan",
    "inf",
    "-inf",
    "1000000000",
    "2.5",
    "3",
    "0.0",
    "1e-12",
    "18446744073709551615",
    "-0",
];

/// Fragments that break naive expression or TOML handling.
const HOSTILE_FRAGMENTS: [&str; 12] = [
    "\"",
    "[",
    "]",
    "{",
    "=",
    "\n",
    "(",
    "1/(x-x)",
    "log(-1)",
    "sqrt(-x-1)",
    "x^1e9",
    "ñ\u{0}",
];

/// The text with the edits applied one after the other: kind 0 replaces the number nearest
/// after the position by a [`HOSTILE_NUMBERS`] entry, 1 deletes the line, 2 duplicates it,
/// 3 inserts a hostile fragment, 4 truncates the text, 5 swaps the line with the next one.
pub fn mutate(text: &str, edits: &[(u8, f64, usize)]) -> String {
    let mut text = text.to_string();
    for &(kind, position, choice) in edits {
        let characters: Vec<char> = text.chars().collect();
        let at =
            ((position.clamp(0.0, 1.0) * characters.len() as f64) as usize).min(characters.len());
        let line_start = characters[..at]
            .iter()
            .rposition(|&c| c == '\n')
            .map_or(0, |i| i + 1);
        let line_end = characters[at..]
            .iter()
            .position(|&c| c == '\n')
            .map_or(characters.len(), |i| at + i + 1);
        let collect = |range: std::ops::Range<usize>| characters[range].iter().collect::<String>();
        text = match kind % 6 {
            0 => match (at..characters.len()).find(|&i| characters[i].is_ascii_digit()) {
                Some(start) => {
                    let end = (start..characters.len())
                        .find(|&i| !(characters[i].is_ascii_digit() || characters[i] == '.'))
                        .unwrap_or(characters.len());
                    let number = HOSTILE_NUMBERS[choice % HOSTILE_NUMBERS.len()];
                    format!(
                        "{}{number}{}",
                        collect(0..start),
                        collect(end..characters.len())
                    )
                }
                None => text,
            },
            1 => format!(
                "{}{}",
                collect(0..line_start),
                collect(line_end..characters.len())
            ),
            2 => format!(
                "{}{}",
                collect(0..line_end),
                collect(line_start..characters.len())
            ),
            3 => {
                let fragment = HOSTILE_FRAGMENTS[choice % HOSTILE_FRAGMENTS.len()];
                format!(
                    "{}{fragment}{}",
                    collect(0..at),
                    collect(at..characters.len())
                )
            }
            4 => collect(0..at),
            _ => {
                let next_end = characters[line_end..]
                    .iter()
                    .position(|&c| c == '\n')
                    .map_or(characters.len(), |i| line_end + i + 1);
                format!(
                    "{}{}{}{}",
                    collect(0..line_start),
                    collect(line_end..next_end),
                    collect(line_start..line_end),
                    collect(next_end..characters.len())
                )
            }
        };
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_of_edit_does_what_it_says() {
        let text = "a = 1\nb = 22\nc = 3\n";
        assert_eq!(mutate(text, &[(0, 0.3, 2)]), "a = 1\nb = 1e300\nc = 3\n");
        assert_eq!(mutate(text, &[(1, 0.4, 0)]), "a = 1\nc = 3\n");
        assert_eq!(
            mutate(text, &[(2, 0.0, 0)]),
            "a = 1\na = 1\nb = 22\nc = 3\n"
        );
        assert_eq!(mutate(text, &[(3, 0.0, 0)]), "\"a = 1\nb = 22\nc = 3\n");
        assert_eq!(mutate(text, &[(4, 0.5, 0)]), "a = 1\nb =");
        assert_eq!(mutate(text, &[(5, 0.0, 0)]), "b = 22\na = 1\nc = 3\n");
        assert_eq!(mutate("", &[(0, 0.5, 1), (1, 0.5, 0), (5, 1.0, 0)]), "");
    }
}
